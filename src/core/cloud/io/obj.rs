//! Wavefront OBJ: `v x y z [w | r g b]` positions and `vn x y z` normals.
//!
//! Normals are taken, in this order of preference:
//! 1. from face references (`f 1//1 2//2 …`, `f 1/1/1 …`): each vertex gets the normalised sum
//!    of the normals its face corners name, if every vertex is named;
//! 2. by index, when there are exactly as many `vn` as `v` lines (the usual point-cloud export);
//! 3. otherwise the cloud has no normals.
//!
//! Faces (`f`) are kept as triangles (each polygon as a fan from its first corner). Other
//! statements (`vt`, `g`, `usemtl`, `l`, …) are ignored.

use glam::Vec3;

use super::LoadErrorKind;
use super::text::{TextLines, normal, parse_numbers, position};
use crate::core::cloud::PointCloud;

pub(super) fn read(bytes: &[u8]) -> Result<PointCloud, LoadErrorKind> {
    let mut positions: Vec<Vec3> = Vec::new();
    let mut file_normals: Vec<Vec3> = Vec::new();
    // (vertex index, normal index) pairs from face corners, 0-based.
    let mut corners: Vec<(u32, u32)> = Vec::new();
    // The current face's vertices, and the triangles of all faces.
    let mut polygon: Vec<u32> = Vec::new();
    let mut faces: Vec<[u32; 3]> = Vec::new();
    let mut lines = TextLines::new(bytes);
    while let Some(item) = lines.next_content() {
        let (line, content) = item?;
        let mut tokens = content.split_ascii_whitespace();
        match tokens.next() {
            Some("v") => {
                positions.push(position(parse_numbers(tokens, line, "at least 3")?, line)?)
            }
            Some("vn") => file_normals.push(normal(parse_numbers(tokens, line, "3")?, line)?),
            Some("f") => {
                polygon.clear();
                for corner in tokens {
                    let mut parts = corner.split('/');
                    let v = parts.next().unwrap_or("");
                    let n = parts.nth(1).unwrap_or("");
                    let v = resolve(v, positions.len(), line, "vertex")?;
                    polygon.push(v);
                    if !n.is_empty() {
                        let n = resolve(n, file_normals.len(), line, "normal")?;
                        corners.push((v, n));
                    }
                }
                super::fan(&polygon, &mut faces);
            }
            _ => {}
        }
    }
    let normals = normals_from_faces(positions.len(), &file_normals, &corners)
        .or_else(|| (file_normals.len() == positions.len()).then_some(file_normals));
    Ok(PointCloud::new(positions, normals)?.with_faces(faces)?)
}

/// Resolves a 1-based (or negative, relative) OBJ index against `count` items defined so far.
fn resolve(
    token: &str,
    count: usize,
    line: usize,
    what: &'static str,
) -> Result<u32, LoadErrorKind> {
    let index: i64 = token.parse().map_err(|_| LoadErrorKind::Syntax {
        location: super::Location::Line(line),
        message: format!(
            "expected a {what} index, found {}",
            super::text::quote(token)
        ),
    })?;
    let count_i = count as i64;
    let zero_based = if index > 0 {
        index - 1
    } else {
        count_i + index
    };
    if index == 0 || zero_based < 0 || zero_based >= count_i {
        return Err(LoadErrorKind::BadIndex {
            line,
            what,
            index,
            count,
        });
    }
    u32::try_from(zero_based)
        .map_err(|_| LoadErrorKind::Unsupported("more than 2^32 vertices".into()))
}

fn normals_from_faces(
    vertex_count: usize,
    file_normals: &[Vec3],
    corners: &[(u32, u32)],
) -> Option<Vec<Vec3>> {
    if corners.is_empty() {
        return None;
    }
    let mut sums = vec![Vec3::ZERO; vertex_count];
    let mut named = vec![false; vertex_count];
    for &(v, n) in corners {
        sums[v as usize] += file_normals[n as usize];
        named[v as usize] = true;
    }
    named
        .iter()
        .all(|&x| x)
        .then(|| sums.into_iter().map(Vec3::normalize_or_zero).collect())
}
