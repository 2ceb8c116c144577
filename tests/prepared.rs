//! Prepared files (`core::pipeline::prepared`): a surface read back is the one prepared, to
//! the bit, and runs alike; a file from another source, another version or another format,
//! a damaged one and a foreign one are refused with their own errors; no change to a file's
//! bytes makes reading it panic.

use std::ops::ControlFlow;

use bevy_point_springs::core::PointCloud;
use bevy_point_springs::core::cloud::io::read_cloud;
use bevy_point_springs::core::pipeline::prepared::{
    PREPARED_MAGIC, PreparedFileError, SourceFingerprint, decode_prepared, encode_prepared,
    read_prepared, write_prepared,
};
use bevy_point_springs::core::pipeline::{PreparedSurface, SurfaceConfig, prepare_surface};
use bevy_point_springs::core::simplify::SimplifyConfig;
use glam::Vec3;
use rand::{RngExt, SeedableRng};

#[path = "support/surfaces.rs"]
#[allow(dead_code)]
mod surfaces;
use surfaces::asset;

/// CGAL's kitten scan (5210 points, no normals: estimated), to 400 simulation points.
fn kitten() -> (PointCloud, SurfaceConfig) {
    let cloud = read_cloud(&asset("kitten.off"), None).unwrap();
    let config = SurfaceConfig {
        simplify: SimplifyConfig::target(400),
        ..SurfaceConfig::default()
    };
    (cloud, config)
}

fn prepared(cloud: &PointCloud, config: &SurfaceConfig) -> PreparedSurface {
    prepare_surface(cloud.clone(), config, &mut |_| ControlFlow::Continue(())).unwrap()
}

fn bits(v: &[Vec3]) -> Vec<[u32; 3]> {
    v.iter().map(|p| p.to_array().map(f32::to_bits)).collect()
}

/// Runs a surface 60 steps under gravity with its lowest points pinned; the dense surface's
/// positions and normals, as bits.
fn run(mut surface: PreparedSurface) -> (Vec<[u32; 3]>, Vec<[u32; 3]>) {
    let low = surface
        .network
        .positions
        .iter()
        .map(|p| p.y)
        .fold(f32::INFINITY, f32::min);
    for (i, p) in surface.network.positions.iter().enumerate() {
        if p.y < low + 0.05 {
            surface.solver.set_fixed(i, true).unwrap();
        }
    }
    for _ in 0..60 {
        surface.solver.step(1.0 / 60.0).unwrap();
    }
    surface.dense.hold(&surface.solver.masses).unwrap();
    surface.dense.follow(&surface.solver.points).unwrap();
    (
        bits(surface.dense.positions()),
        bits(surface.dense.normals()),
    )
}

#[test]
fn a_prepared_file_gives_back_the_surface_to_the_bit() {
    let (cloud, config) = kitten();
    let source = SourceFingerprint::of(&cloud, &config);
    let surface = prepared(&cloud, &config);
    let path = std::env::temp_dir().join(format!("bps-prepared-{}.psprep", std::process::id()));
    write_prepared(&path, &surface, source).unwrap();
    let again = read_prepared(&path, source).unwrap();
    let _ = std::fs::remove_file(&path);
    assert_eq!(again.network, surface.network);
    assert_eq!(again.config, surface.config);
    assert_eq!(again.normal_source, surface.normal_source);
    let (a, b) = (surface.dense.transfer(), again.dense.transfer());
    assert_eq!(bits(a.rest_positions()), bits(b.rest_positions()));
    assert_eq!(bits(a.rest_normals()), bits(b.rest_normals()));
    // Written again, the same bytes: every coefficient came back.
    assert_eq!(
        encode_prepared(&again, source).unwrap(),
        encode_prepared(&surface, source).unwrap()
    );
    // And it runs alike: the dense surface after a second under gravity, bit for bit.
    let moved = run(surface);
    assert_eq!(run(again), moved);
    let rest = bits(read_cloud(&asset("kitten.off"), None).unwrap().positions());
    assert_ne!(moved.0, rest, "the run moved the surface");
}

#[test]
fn a_prepared_file_from_another_source_is_refused() {
    let (cloud, config) = kitten();
    let source = SourceFingerprint::of(&cloud, &config);
    let bytes = encode_prepared(&prepared(&cloud, &config), source).unwrap();
    // One coordinate of one point moved by one step of its float.
    let (mut positions, normals) = cloud.clone().into_parts();
    positions[17].x = f32::from_bits(positions[17].x.to_bits() + 1);
    let nudged = PointCloud::new(positions, normals).unwrap();
    // Other settings.
    let finer = SurfaceConfig {
        simplify: SimplifyConfig::target(500),
        ..config
    };
    for other in [
        SourceFingerprint::of(&nudged, &config),
        SourceFingerprint::of(&cloud, &finer),
        SourceFingerprint::with_extra(&cloud, &config, b"pins"),
    ] {
        assert_ne!(other, source);
        match decode_prepared(&bytes, other) {
            Err(PreparedFileError::OtherSource { found, expected }) => {
                assert_eq!((found, expected), (source, other));
            }
            other => panic!("expected OtherSource, got {:?}", other.map(|_| ())),
        }
    }
    assert!(decode_prepared(&bytes, source).is_ok());
}

/// The bytes after the magic and the hash, and the hash of them put back.
fn rehashed(mut bytes: Vec<u8>, change: impl FnOnce(&mut Vec<u8>)) -> Vec<u8> {
    let start = PREPARED_MAGIC.len() + 32;
    let mut body = bytes.split_off(start);
    change(&mut body);
    bytes.truncate(PREPARED_MAGIC.len());
    bytes.extend_from_slice(blake3::hash(&body).as_bytes());
    bytes.extend(body);
    bytes
}

#[test]
fn a_prepared_file_from_another_version_or_format_is_refused() {
    let (cloud, config) = kitten();
    let source = SourceFingerprint::of(&cloud, &config);
    let bytes = encode_prepared(&prepared(&cloud, &config), source).unwrap();
    // The header starts with the crate's version, as a length and its bytes.
    let ours = env!("CARGO_PKG_VERSION");
    let start = PREPARED_MAGIC.len() + 32;
    assert_eq!(&bytes[start + 1..start + 1 + ours.len()], ours.as_bytes());
    let older = rehashed(bytes.clone(), |body| {
        let mut other = ours.as_bytes().to_vec();
        other[0] = if other[0] == b'9' { b'8' } else { b'9' };
        body[1..1 + ours.len()].copy_from_slice(&other);
    });
    match decode_prepared(&older, source) {
        Err(PreparedFileError::Version { found, ours: mine }) => {
            assert_ne!(found, mine);
            assert_eq!(mine, ours);
        }
        other => panic!("expected Version, got {:?}", other.map(|_| ())),
    }
    // Another format's magic (its last byte).
    let mut format = bytes.clone();
    format[PREPARED_MAGIC.len() - 1] ^= 0x40;
    assert!(matches!(
        decode_prepared(&format, source),
        Err(PreparedFileError::Version { .. })
    ));
    // Not a prepared file at all.
    let ply = std::fs::read(asset("sphere3203.ply")).unwrap();
    assert!(matches!(
        decode_prepared(&ply, source),
        Err(PreparedFileError::Foreign)
    ));
    assert!(matches!(
        decode_prepared(&[], source),
        Err(PreparedFileError::Foreign)
    ));
    // A missing file says so.
    let missing = read_prepared(std::path::Path::new("/nonexistent/x.psprep"), source);
    assert!(missing.is_err_and(|e| e.is_missing()));
}

#[test]
fn a_damaged_prepared_file_is_refused_and_never_panics() {
    let (cloud, config) = kitten();
    let source = SourceFingerprint::of(&cloud, &config);
    let bytes = encode_prepared(&prepared(&cloud, &config), source).unwrap();
    // Cut short, and one byte changed: the hash no longer matches.
    for cut in [bytes.len() - 1, bytes.len() / 2, PREPARED_MAGIC.len() + 5] {
        assert!(matches!(
            decode_prepared(&bytes[..cut], source),
            Err(PreparedFileError::Damaged(_))
        ));
    }
    let mut flipped = bytes.clone();
    let last = flipped.len() - 3;
    flipped[last] ^= 1;
    assert!(matches!(
        decode_prepared(&flipped, source),
        Err(PreparedFileError::Damaged(_))
    ));
    // Changes made by hand, with the hash put right: anything from an error to a surface,
    // never a panic, an endless loop or an absurd allocation.
    let mut rng = rand::rngs::Xoshiro256PlusPlus::seed_from_u64(36);
    let body_len = bytes.len() - PREPARED_MAGIC.len() - 32;
    let (mut refused, mut read) = (0, 0);
    for round in 0..300 {
        let changed = rehashed(bytes.clone(), |body| match round % 3 {
            // A few bytes anywhere.
            0 => {
                for _ in 0..rng.random_range(1..4) {
                    let at = rng.random_range(0..body_len);
                    body[at] = rng.random();
                }
            }
            // A run of bytes set to 0xff (huge lengths and indices).
            1 => {
                let at = rng.random_range(0..body_len - 8);
                body[at..at + 8].fill(0xff);
            }
            // Cut short.
            _ => body.truncate(rng.random_range(0..body_len)),
        });
        match decode_prepared(&changed, source) {
            Ok(mut surface) => {
                read += 1;
                // A surface that passed the checks steps and transfers (its numbers may be
                // odd: then an error).
                if surface.solver.step(1.0 / 60.0).is_ok() {
                    let _ = surface.dense.follow(&surface.solver.points);
                }
            }
            Err(PreparedFileError::Damaged(_) | PreparedFileError::Prepare(_)) => refused += 1,
            Err(PreparedFileError::Version { .. } | PreparedFileError::OtherSource { .. }) => {
                refused += 1;
            }
            Err(e) => panic!("unexpected: {e}"),
        }
    }
    println!("changed by hand: {refused} refused, {read} read");
    assert!(refused > 200, "{refused} refused, {read} read");
}
