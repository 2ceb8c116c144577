//! What every fuzz target checks: an input is an error or a valid result, never a panic.

use bevy_point_springs::core::cloud::io::{CloudFormat, read_cloud_from_bytes};

/// Reads `data` as `format`; a cloud read must have finite coordinates and normals.
pub fn cloud(data: &[u8], format: CloudFormat) {
    if let Ok(cloud) = read_cloud_from_bytes(data, format, "fuzz") {
        assert!(cloud.positions().iter().all(|p| p.is_finite()));
        if let Some(normals) = cloud.normals() {
            assert!(normals.iter().all(|n| n.is_finite()));
        }
        let n = cloud.len() as u32;
        assert!(cloud.faces().iter().flatten().all(|&i| i < n));
    }
}
