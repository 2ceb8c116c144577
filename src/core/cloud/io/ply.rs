//! PLY through [`ply_rs_bw`]: ASCII and binary (both endians) reading, ASCII and binary writing.
//!
//! Reading takes the `vertex` element's `x y z` (any scalar type) and its normals when all three
//! of `nx ny nz` (or `normal_x normal_y normal_z`) are present, and the `face` element's
//! `vertex_indices` (or `vertex_index`) lists when it comes after `vertex`, each polygon as a
//! fan of triangles. Other elements are skipped. Before any element is parsed, the element
//! counts are checked against the bytes after the header, so a header that claims 10^12
//! vertices is rejected without allocating for them.

use std::io::Write;

use glam::Vec3;
use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{
    Addable, ElementDef, Encoding, Header, Property, PropertyAccess, PropertyAccessResult,
    PropertyDef, PropertyType, ScalarType,
};
use ply_rs_bw::writer::Writer;

use super::{LoadErrorKind, Location};
use crate::core::cloud::PointCloud;

/// How a PLY file is encoded when written.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PlyEncoding {
    /// Human-readable text; floats are written in their shortest exact form, so a round trip
    /// is still bit-exact.
    Ascii,
    /// Binary, little endian (the common choice; smallest and fastest).
    #[default]
    BinaryLittleEndian,
    /// Binary, big endian.
    BinaryBigEndian,
}

const VERTEX: &str = "vertex";
const FACE: &str = "face";
const FACE_LIST_NAMES: [&str; 2] = ["vertex_indices", "vertex_index"];
const POSITION_NAMES: [&str; 3] = ["x", "y", "z"];
const NORMAL_NAME_SETS: [[&str; 3]; 2] = [["nx", "ny", "nz"], ["normal_x", "normal_y", "normal_z"]];

/// One vertex as read: position and normal slots, in `f64` so range checks see the true value.
#[derive(Debug, Clone, Copy)]
struct PlyVertex {
    values: [f64; 6],
}

/// The slot (0..6) a property name fills, given which normal names the file uses.
fn slot(name: &str) -> Option<usize> {
    POSITION_NAMES
        .iter()
        .chain(NORMAL_NAME_SETS.iter().flatten())
        .position(|&n| n == name)
        .map(|i| if i < 3 { i } else { 3 + (i - 3) % 3 })
}

impl PropertyAccess for PlyVertex {
    fn new() -> Self {
        Self { values: [0.0; 6] }
    }

    fn set_property(&mut self, name: &str, property: Property) -> PropertyAccessResult {
        let Some(slot) = slot(name) else {
            return PropertyAccessResult::Ignored;
        };
        let value = match property {
            Property::Char(v) => f64::from(v),
            Property::UChar(v) => f64::from(v),
            Property::Short(v) => f64::from(v),
            Property::UShort(v) => f64::from(v),
            Property::Int(v) => f64::from(v),
            Property::UInt(v) => f64::from(v),
            Property::Float(v) => f64::from(v),
            Property::Double(v) => v,
            _ => return PropertyAccessResult::Ignored,
        };
        self.values[slot] = value;
        PropertyAccessResult::Set
    }
}

/// One face: its corners as written.
#[derive(Debug, Clone, Default)]
struct PlyFace {
    corners: Vec<i64>,
}

impl PropertyAccess for PlyFace {
    fn new() -> Self {
        Self::default()
    }

    fn set_property(&mut self, name: &str, property: Property) -> PropertyAccessResult {
        if !FACE_LIST_NAMES.contains(&name) {
            return PropertyAccessResult::Ignored;
        }
        self.corners = match property {
            Property::ListChar(v) => v.into_iter().map(i64::from).collect(),
            Property::ListUChar(v) => v.into_iter().map(i64::from).collect(),
            Property::ListShort(v) => v.into_iter().map(i64::from).collect(),
            Property::ListUShort(v) => v.into_iter().map(i64::from).collect(),
            Property::ListInt(v) => v.into_iter().map(i64::from).collect(),
            Property::ListUInt(v) => v.into_iter().map(i64::from).collect(),
            _ => return PropertyAccessResult::Ignored,
        };
        PropertyAccessResult::Set
    }
}

/// An element read only to move past it.
#[derive(Debug, Clone, Copy)]
struct Skipped;

impl PropertyAccess for Skipped {
    fn new() -> Self {
        Self
    }
}

fn scalar_size(t: &ScalarType) -> u64 {
    match t {
        ScalarType::Char | ScalarType::UChar => 1,
        ScalarType::Short | ScalarType::UShort => 2,
        ScalarType::Int | ScalarType::UInt | ScalarType::Float => 4,
        ScalarType::Double => 8,
    }
}

/// Fewest payload bytes one element can take, and whether every element takes exactly that.
fn min_element_bytes(def: &ElementDef, encoding: Encoding) -> (u64, bool) {
    let mut bytes = 0;
    let mut fixed = true;
    for p in def.properties.values() {
        bytes += match (&encoding, &p.data_type) {
            // A value and a separator; an empty list is its count and a separator.
            (Encoding::Ascii, _) => 2,
            (_, PropertyType::Scalar(t)) => scalar_size(t),
            (_, PropertyType::List(count, _)) => {
                fixed = false;
                scalar_size(count)
            }
        };
    }
    (bytes.max(1), fixed && encoding != Encoding::Ascii)
}

/// Byte offset just after the `end_header` line, if there is one.
fn payload_offset(bytes: &[u8]) -> Option<usize> {
    const END: &[u8] = b"end_header";
    let at = bytes.windows(END.len()).position(|w| w == END)?;
    let newline = bytes[at..].iter().position(|&b| b == b'\n')?;
    Some(at + newline + 1)
}

fn ply_error(e: &ply_rs_bw::parser::ParseError) -> LoadErrorKind {
    // The parser's message continues with grammar details over several lines; the first line
    // says what failed, and callers add the offending text.
    let message = e.to_string();
    LoadErrorKind::Ply {
        line: e.line(),
        message: message.lines().next().unwrap_or_default().trim().to_owned(),
    }
}

pub(super) fn read(bytes: &[u8]) -> Result<PointCloud, LoadErrorKind> {
    if bytes.is_empty() {
        return Err(LoadErrorKind::Empty);
    }
    let mut reader = Reader::new(bytes);
    let header = Parser::<Skipped>::new()
        .read_header(&mut reader)
        .map_err(|e| ply_error(&e))?;
    let Some(vertex_def) = header.elements.get(VERTEX) else {
        return Err(LoadErrorKind::Missing(
            "PLY: no `vertex` element in the header".into(),
        ));
    };
    let scalar = |name: &str| {
        vertex_def
            .properties
            .get(name)
            .is_some_and(|p| matches!(p.data_type, PropertyType::Scalar(_)))
    };
    if let Some(missing) = POSITION_NAMES.iter().find(|n| !scalar(n)) {
        return Err(LoadErrorKind::Missing(format!(
            "PLY: the vertex element has no scalar `{missing}` property"
        )));
    }
    let has_normals = NORMAL_NAME_SETS
        .iter()
        .any(|set| set.iter().all(|n| scalar(n)));

    // The faces are read when they come after the vertices.
    let names: Vec<&str> = header.elements.values().map(|d| d.name.as_str()).collect();
    let face_at = names.iter().position(|&n| n == FACE).filter(|&f| {
        names
            .iter()
            .position(|&n| n == VERTEX)
            .is_some_and(|v| f > v)
    });
    let last = face_at.map_or(VERTEX, |_| FACE);
    check_counts(&header, bytes, last)?;

    for def in header.elements.values() {
        if def.name == VERTEX {
            break;
        }
        Parser::<Skipped>::new()
            .read_payload_for_element(&mut reader, def, &header)
            .map_err(|e| element_error(&e, def, bytes))?;
    }
    let vertices = Parser::<PlyVertex>::new()
        .read_payload_for_element(&mut reader, vertex_def, &header)
        .map_err(|e| element_error(&e, vertex_def, bytes))?;
    let cloud = convert(&vertices, has_normals, &header)?;
    if face_at.is_none() {
        return Ok(cloud);
    }
    let mut faces = Vec::new();
    for def in header
        .elements
        .values()
        .skip_while(|d| d.name != VERTEX)
        .skip(1)
    {
        if def.name != FACE {
            Parser::<Skipped>::new()
                .read_payload_for_element(&mut reader, def, &header)
                .map_err(|e| element_error(&e, def, bytes))?;
            continue;
        }
        let read = Parser::<PlyFace>::new()
            .read_payload_for_element(&mut reader, def, &header)
            .map_err(|e| element_error(&e, def, bytes))?;
        faces = triangles(&read, cloud.len())?;
        break;
    }
    Ok(cloud.with_faces(faces)?)
}

/// Checks every element's count, up to the `last` element read, against the bytes the file
/// has after its header: a count far beyond them is a corrupt header, one a little beyond a
/// truncated file.
fn check_counts(header: &Header, bytes: &[u8], last: &str) -> Result<(), LoadErrorKind> {
    let payload_bytes = payload_offset(bytes).map_or(0, |o| bytes.len() - o) as u64;
    let mut needed: u64 = 0;
    for def in header.elements.values() {
        let (min, fixed) = min_element_bytes(def, header.encoding);
        let declared = def.count as u64;
        let available = payload_bytes.saturating_sub(needed);
        let max = available / min;
        if declared > max {
            // A count far beyond what the bytes can hold is a corrupt header, rejected before
            // reading; one a little beyond is a truncated file. Fixed-size binary records tell
            // exactly how many are complete; otherwise the parser finds where the data ends.
            if declared > max.saturating_mul(super::TRUNCATION_FACTOR) {
                return Err(LoadErrorKind::CountTooLarge {
                    element: def.name.clone(),
                    declared,
                    payload_bytes,
                    max,
                });
            }
            if fixed {
                return Err(LoadErrorKind::Truncated {
                    element: def.name.clone(),
                    declared,
                    found: Some(max),
                });
            }
        }
        needed = needed.saturating_add(declared.saturating_mul(min));
        if def.name == last {
            break;
        }
    }
    Ok(())
}

/// The faces' triangles (each polygon a fan), checking that every corner names a vertex.
fn triangles(faces: &[PlyFace], vertices: usize) -> Result<Vec<[u32; 3]>, LoadErrorKind> {
    let mut out = Vec::with_capacity(faces.len());
    let mut corners = Vec::new();
    for (index, face) in faces.iter().enumerate() {
        corners.clear();
        for &c in &face.corners {
            if !(0..vertices as i64).contains(&c) {
                return Err(LoadErrorKind::Syntax {
                    location: Location::Element {
                        name: format!("{FACE} (0-based)"),
                        index,
                    },
                    message: format!("corner {c} names no vertex (the file has {vertices})"),
                });
            }
            corners.push(c as u32);
        }
        super::fan(&corners, &mut out);
    }
    Ok(out)
}

/// Maps a payload error; for ASCII files the offending line is quoted so the message shows
/// what could not be read (e.g. `nan`, which the PLY grammar does not accept).
fn element_error(
    e: &ply_rs_bw::parser::ParseError,
    def: &ElementDef,
    bytes: &[u8],
) -> LoadErrorKind {
    if e.kind() == std::io::ErrorKind::UnexpectedEof {
        return LoadErrorKind::Truncated {
            element: def.name.clone(),
            declared: def.count as u64,
            found: None,
        };
    }
    let mut kind = ply_error(e);
    if let (LoadErrorKind::Ply { message, .. }, Some(line)) = (&mut kind, e.line()) {
        let text = bytes
            .split(|&b| b == b'\n')
            .nth(line.saturating_sub(1))
            .map(String::from_utf8_lossy);
        if let Some(text) = text {
            message.push_str(&format!(
                " ({} {})",
                def.name,
                super::text::quote(text.trim())
            ));
        }
    }
    kind
}

fn convert(
    vertices: &[PlyVertex],
    has_normals: bool,
    header: &Header,
) -> Result<PointCloud, LoadErrorKind> {
    let mut positions = Vec::with_capacity(vertices.len());
    let mut normals = Vec::with_capacity(if has_normals { vertices.len() } else { 0 });
    let location = |index| Location::Element {
        name: format!(
            "{VERTEX}{}",
            if header.encoding == Encoding::Ascii {
                " (0-based)"
            } else {
                ""
            }
        ),
        index,
    };
    for (i, v) in vertices.iter().enumerate() {
        let c = |slot: usize, what| super::coordinate(v.values[slot], what, || location(i));
        positions.push(Vec3::new(
            c(0, "coordinate")?,
            c(1, "coordinate")?,
            c(2, "coordinate")?,
        ));
        if has_normals {
            let what = "normal component";
            normals.push(Vec3::new(c(3, what)?, c(4, what)?, c(5, what)?));
        }
    }
    Ok(PointCloud::new(positions, has_normals.then_some(normals))?)
}

/// One vertex as written.
#[derive(Debug, Clone, Copy)]
struct OutVertex([f32; 6]);

impl PropertyAccess for OutVertex {
    fn new() -> Self {
        Self([0.0; 6])
    }

    fn get_float(&self, name: &str) -> Option<f32> {
        let i = ["x", "y", "z", "nx", "ny", "nz"]
            .iter()
            .position(|&n| n == name)?;
        Some(self.0[i])
    }
}

pub(super) fn write<W: Write>(
    out: &mut W,
    cloud: &PointCloud,
    encoding: PlyEncoding,
) -> std::io::Result<()> {
    let mut header = Header::new();
    header.encoding = match encoding {
        PlyEncoding::Ascii => Encoding::Ascii,
        PlyEncoding::BinaryLittleEndian => Encoding::BinaryLittleEndian,
        PlyEncoding::BinaryBigEndian => Encoding::BinaryBigEndian,
    };
    header.comments.push(format!(
        "written by bevy_point_springs {}",
        env!("CARGO_PKG_VERSION")
    ));
    let mut def = ElementDef::new(VERTEX.to_owned());
    def.count = cloud.len();
    let names: &[&str] = if cloud.normals().is_some() {
        &["x", "y", "z", "nx", "ny", "nz"]
    } else {
        &["x", "y", "z"]
    };
    for name in names {
        def.properties.add(PropertyDef::new(
            (*name).to_owned(),
            PropertyType::Scalar(ScalarType::Float),
        ));
    }
    let normals = cloud.normals();
    let elements: Vec<OutVertex> = cloud
        .positions()
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let n = normals.map_or(Vec3::ZERO, |n| n[i]);
            OutVertex([p.x, p.y, p.z, n.x, n.y, n.z])
        })
        .collect();
    header.elements.add(def.clone());
    let writer = Writer::<OutVertex>::new();
    writer.write_header(out, &header)?;
    writer.write_payload_of_element(out, &elements, &def, &header)?;
    Ok(())
}
