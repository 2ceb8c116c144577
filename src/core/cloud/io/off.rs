//! OFF (Object File Format): the vertex list and the faces (each polygon as a fan of
//! triangles from its first corner); edge counts are ignored.
//!
//! Accepts the keyword variants `OFF`, `NOFF` (normals after the position), `COFF`, `CNOFF`,
//! `STOFF`… (extra per-vertex values are ignored), counts on the keyword line or the next one,
//! and `#` comments. Binary OFF and 4-D / n-D OFF are reported as unsupported.

use super::LoadErrorKind;
use super::text::{TextLines, normal, parse_count, parse_numbers, position, quote};
use crate::core::cloud::PointCloud;

/// Fewest bytes one ASCII vertex line can take: `0 0 0\n`.
const MIN_VERTEX_LINE_BYTES: u64 = 6;

/// Fewest bytes one ASCII face line can take: `3 0 1 2\n`.
const MIN_FACE_LINE_BYTES: u64 = 8;

pub(super) fn read(bytes: &[u8]) -> Result<PointCloud, LoadErrorKind> {
    let mut lines = TextLines::new(bytes);
    let Some(first) = lines.next_content() else {
        return Err(LoadErrorKind::Empty);
    };
    let (line, header) = first?;
    let mut tokens = header.split_ascii_whitespace();
    let keyword = tokens.next().unwrap_or("");
    let Some(prefix) = keyword.strip_suffix("OFF") else {
        return Err(LoadErrorKind::Syntax {
            location: super::Location::Line(line),
            message: format!("expected the OFF keyword, found {}", quote(keyword)),
        });
    };
    if prefix.contains('4') || prefix.contains('n') {
        return Err(LoadErrorKind::Unsupported(format!(
            "{keyword}: only 3-D OFF files are read"
        )));
    }
    let has_normals = prefix.contains('N');
    let mut rest: Vec<&str> = tokens.collect();
    if rest
        .first()
        .is_some_and(|t| t.eq_ignore_ascii_case("BINARY"))
    {
        return Err(LoadErrorKind::Unsupported("binary OFF".into()));
    }
    let mut count_line = line;
    if rest.is_empty() {
        let Some(next) = lines.next_content() else {
            return Err(LoadErrorKind::Missing(
                "the OFF header has no vertex count".into(),
            ));
        };
        let (l, counts) = next?;
        count_line = l;
        rest = counts.split_ascii_whitespace().collect();
    }
    let declared = parse_count(rest.first().copied().unwrap_or(""), count_line, "vertex")?;
    let payload_bytes = lines.remaining_bytes() as u64;
    let max = payload_bytes / MIN_VERTEX_LINE_BYTES;
    // A count beyond what the bytes can hold is either a truncated file (reported as such
    // once the lines run out) or, when far beyond, a corrupt header, rejected before reading.
    if declared > max.saturating_mul(super::TRUNCATION_FACTOR) {
        return Err(LoadErrorKind::CountTooLarge {
            element: "vertex".into(),
            declared,
            payload_bytes,
            max,
        });
    }
    // Bounded by the file size, whatever the header says.
    let capacity = declared.min(max) as usize;
    let mut positions = Vec::with_capacity(capacity);
    let mut normals = Vec::with_capacity(if has_normals { capacity } else { 0 });
    let expected = if has_normals {
        "at least 6"
    } else {
        "at least 3"
    };
    while (positions.len() as u64) < declared {
        let Some(item) = lines.next_content() else {
            return Err(LoadErrorKind::Truncated {
                element: "vertex".into(),
                declared,
                found: Some(positions.len() as u64),
            });
        };
        let (line, content) = item?;
        let tokens = content.split_ascii_whitespace();
        if has_normals {
            let v: [f64; 6] = parse_numbers(tokens, line, expected)?;
            positions.push(position([v[0], v[1], v[2]], line)?);
            normals.push(normal([v[3], v[4], v[5]], line)?);
        } else {
            let v: [f64; 3] = parse_numbers(tokens, line, expected)?;
            positions.push(position(v, line)?);
        }
    }
    let count = positions.len();
    let cloud = PointCloud::new(positions, has_normals.then_some(normals))?;
    let faces = read_faces(&mut lines, rest.get(1).copied(), count_line, count)?;
    Ok(cloud.with_faces(faces)?)
}

/// The faces after the vertices, as triangles; none when the header declares none.
fn read_faces(
    lines: &mut TextLines,
    declared: Option<&str>,
    count_line: usize,
    vertices: usize,
) -> Result<Vec<[u32; 3]>, LoadErrorKind> {
    let declared = match declared {
        Some(token) => parse_count(token, count_line, "face")?,
        None => 0,
    };
    let payload_bytes = lines.remaining_bytes() as u64;
    let max = payload_bytes / MIN_FACE_LINE_BYTES;
    if declared > max.saturating_mul(super::TRUNCATION_FACTOR) {
        return Err(LoadErrorKind::CountTooLarge {
            element: "face".into(),
            declared,
            payload_bytes,
            max,
        });
    }
    let mut triangles = Vec::with_capacity(declared.min(max) as usize);
    let mut corners = Vec::new();
    for read in 0..declared {
        let Some(item) = lines.next_content() else {
            return Err(LoadErrorKind::Truncated {
                element: "face".into(),
                declared,
                found: Some(read),
            });
        };
        let (line, content) = item?;
        let mut tokens = content.split_ascii_whitespace();
        let size = parse_count(tokens.next().unwrap_or(""), line, "corner")?;
        corners.clear();
        for token in tokens.by_ref().take(size.min(vertices as u64) as usize) {
            let index = parse_count(token, line, "vertex index")?;
            if index >= vertices as u64 {
                return Err(LoadErrorKind::BadCorner {
                    line,
                    index,
                    count: vertices,
                });
            }
            corners.push(index as u32);
        }
        if (corners.len() as u64) < size {
            return Err(LoadErrorKind::ColumnCount {
                line,
                expected: format!("1 + {size}"),
                found: 1 + corners.len(),
            });
        }
        super::fan(&corners, &mut triangles);
    }
    Ok(triangles)
}
