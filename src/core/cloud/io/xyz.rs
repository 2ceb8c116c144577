//! XYZ and PWN: one point a line, `x y z` or `x y z nx ny nz`, whitespace-separated.
//!
//! Blank lines and `#` comments are skipped. Every data line must have the column count of the
//! first one (3 or 6).

use glam::Vec3;

use super::LoadErrorKind;
use super::text::{TextLines, normal, parse_numbers, position};
use crate::core::cloud::PointCloud;

pub(super) fn read(bytes: &[u8]) -> Result<PointCloud, LoadErrorKind> {
    let mut positions = Vec::new();
    let mut normals: Vec<Vec3> = Vec::new();
    let mut columns: Option<usize> = None;
    let mut lines = TextLines::new(bytes);
    while let Some(item) = lines.next_content() {
        let (line, content) = item?;
        let found = content.split_ascii_whitespace().count();
        let expected = match columns {
            Some(c) => c,
            None if found == 3 || found == 6 => found,
            None => {
                return Err(LoadErrorKind::ColumnCount {
                    line,
                    expected: "3 or 6".into(),
                    found,
                });
            }
        };
        if found != expected {
            return Err(LoadErrorKind::ColumnCount {
                line,
                expected: format!("{expected} (as on the first line)"),
                found,
            });
        }
        columns = Some(expected);
        let v: [f64; 6] = if expected == 6 {
            parse_numbers(content.split_ascii_whitespace(), line, "6")?
        } else {
            let p: [f64; 3] = parse_numbers(content.split_ascii_whitespace(), line, "3")?;
            [p[0], p[1], p[2], 0.0, 0.0, 0.0]
        };
        positions.push(position([v[0], v[1], v[2]], line)?);
        if expected == 6 {
            normals.push(normal([v[3], v[4], v[5]], line)?);
        }
    }
    let normals = (columns == Some(6)).then_some(normals);
    Ok(PointCloud::new(positions, normals)?)
}
