//! Reading and writing point clouds.
//!
//! | format | read | write | contents |
//! |---|---|---|---|
//! | PLY (`.ply`) | ASCII, binary little and big endian ([ply-rs-bw]) | ASCII, binary | `vertex` element: `x y z` (any scalar type), normals as `nx ny nz` or `normal_x normal_y normal_z`; `face` element's `vertex_indices` |
//! | XYZ (`.xyz`), PWN (`.pwn`) | yes | — | one point a line: `x y z` or `x y z nx ny nz` |
//! | OFF (`.off`) | yes | — | vertices (`OFF`, `NOFF` with normals, `COFF`…) and faces (polygons as fans) |
//! | OBJ (`.obj`) | yes | — | `v` lines; `vn` lines paired by index or through `f v//vn` references; `f` faces |
//!
//! Faces are kept as triangles ([`PointCloud::faces`], each polygon a fan from its first
//! corner): the network uses them as the surface's connectivity where the simulation points'
//! rings leave holes, and a file without normals gets its faces' normals.
//!
//! The format is chosen from the extension ([`CloudFormat::from_path`]) unless given.
//! Every malformed file gives a [`LoadError`] that names the file and the line or element;
//! no input makes a reader panic, and no reader allocates more than the file's size can justify
//! (a header that claims more elements than the file has bytes for is rejected up front).
//!
//! [ply-rs-bw]: https://crates.io/crates/ply-rs-bw

mod obj;
mod off;
mod ply;
mod text;
mod xyz;

use std::fmt;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::str::FromStr;

use crate::core::cloud::{CloudError, PointCloud};

pub use ply::PlyEncoding;

/// Point-cloud file formats understood by [`read_cloud`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum CloudFormat {
    /// Stanford PLY, ASCII or binary.
    Ply,
    /// Whitespace-separated `x y z [nx ny nz]` lines.
    Xyz,
    /// Points with normals, `x y z nx ny nz` lines (CGAL's `.pwn`); read like [`CloudFormat::Xyz`].
    Pwn,
    /// Object File Format; vertices and faces.
    Off,
    /// Wavefront OBJ; `v`, `vn` and `f` lines.
    Obj,
}

impl CloudFormat {
    /// Every format, in a stable order.
    pub const ALL: [CloudFormat; 5] = [Self::Ply, Self::Xyz, Self::Pwn, Self::Off, Self::Obj];

    /// The lower-case name, which is also the usual file extension.
    pub fn name(self) -> &'static str {
        match self {
            Self::Ply => "ply",
            Self::Xyz => "xyz",
            Self::Pwn => "pwn",
            Self::Off => "off",
            Self::Obj => "obj",
        }
    }

    /// The format named by a path's extension (case-insensitive), if any.
    pub fn from_path(path: &Path) -> Option<Self> {
        path.extension()?.to_str()?.parse().ok()
    }
}

impl fmt::Display for CloudFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A format name that is not one of [`CloudFormat::ALL`].
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown point-cloud format {0:?} (expected ply, xyz, pwn, off or obj)")]
pub struct UnknownFormat(pub String);

impl FromStr for CloudFormat {
    type Err = UnknownFormat;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .into_iter()
            .find(|f| f.name().eq_ignore_ascii_case(s))
            .ok_or_else(|| UnknownFormat(s.to_owned()))
    }
}

/// Where in a file a problem was found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Location {
    /// A 1-based line number (text formats, ASCII PLY).
    Line(usize),
    /// A 0-based element index within a named PLY element (binary PLY).
    Element {
        /// The element's name, e.g. `vertex`.
        name: String,
        /// Its index.
        index: usize,
    },
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Line(line) => write!(f, "line {line}"),
            Self::Element { name, index } => write!(f, "{name} {index}"),
        }
    }
}

/// What is wrong with a point-cloud file. Wrapped in a [`LoadError`] naming the file.
#[derive(Debug, thiserror::Error)]
pub enum LoadErrorKind {
    /// The file could not be read.
    #[error("cannot read: {0}")]
    Io(#[from] std::io::Error),
    /// No format was given and the extension names none.
    #[error(
        "cannot tell the format from the extension {extension:?}; name one of ply, xyz, pwn, off, obj"
    )]
    UnknownFormat {
        /// The extension found, if any.
        extension: Option<String>,
    },
    /// The file holds no points.
    #[error("the file holds no points")]
    Empty,
    /// A line of a text format is not valid UTF-8 text (binary garbage).
    #[error("line {line}: not text (invalid UTF-8)")]
    NotText {
        /// 1-based line number.
        line: usize,
    },
    /// Something that does not parse.
    #[error("{location}: {message}")]
    Syntax {
        /// Where.
        location: Location,
        /// What was expected.
        message: String,
    },
    /// A text line with the wrong number of values.
    #[error("line {line}: expected {expected} numbers, found {found}")]
    ColumnCount {
        /// 1-based line number.
        line: usize,
        /// What the format (or the file's first line) requires, e.g. `"3 or 6"`.
        expected: String,
        /// How many were there.
        found: usize,
    },
    /// A NaN or infinite coordinate.
    #[error("{location}: {what} {value} is not finite")]
    NonFinite {
        /// Where.
        location: Location,
        /// `"coordinate"` or `"normal component"`.
        what: &'static str,
        /// The value read.
        value: f64,
    },
    /// A coordinate beyond ±[`MAX_ABS_COORDINATE`](crate::core::cloud::MAX_ABS_COORDINATE).
    #[error("{location}: coordinate {value:e} is out of range (limit ±{limit:e})")]
    OutOfRange {
        /// Where.
        location: Location,
        /// The value read.
        value: f64,
        /// The limit.
        limit: f32,
    },
    /// A header declares more elements than the file has bytes for.
    #[error(
        "the header declares {declared} {element} elements, but the {payload_bytes} bytes after it can hold at most {max}"
    )]
    CountTooLarge {
        /// The element, e.g. `vertex`.
        element: String,
        /// Declared count.
        declared: u64,
        /// Bytes available for the payload.
        payload_bytes: u64,
        /// Largest count those bytes could hold.
        max: u64,
    },
    /// The file ends before the declared number of elements.
    #[error("the file ends before its {declared} declared {element} elements are complete{}", found_suffix(*.found))]
    Truncated {
        /// The element, e.g. `vertex`.
        element: String,
        /// Declared count.
        declared: u64,
        /// Complete elements present, when known.
        found: Option<u64>,
    },
    /// A PLY structure problem reported by the PLY parser.
    #[error("PLY: {message}")]
    Ply {
        /// 1-based line of the problem when the parser knows it.
        line: Option<usize>,
        /// The parser's message.
        message: String,
    },
    /// Something required is missing (a PLY vertex element, an `x` property…).
    #[error("{0}")]
    Missing(String),
    /// A valid file using a feature this reader does not support.
    #[error("unsupported: {0}")]
    Unsupported(String),
    /// An OBJ face refers to a vertex or normal that does not exist.
    #[error("line {line}: {what} index {index} is out of range (1..={count})")]
    BadIndex {
        /// 1-based line number.
        line: usize,
        /// `"vertex"` or `"normal"`.
        what: &'static str,
        /// The index as written.
        index: i64,
        /// How many exist at that point.
        count: usize,
    },
    /// An OFF face names a vertex the file does not have (OFF counts from 0).
    #[error(
        "line {line}: face corner {index} names no vertex (the file has {count}, numbered from 0)"
    )]
    BadCorner {
        /// 1-based line number.
        line: usize,
        /// The index as written.
        index: u64,
        /// How many vertices the file has.
        count: usize,
    },
    /// The arrays read do not form a valid cloud.
    #[error(transparent)]
    Cloud(#[from] CloudError),
}

/// Appends the triangles of a polygon (its corners in order) as a fan from its first corner,
/// leaving out triangles that name a point twice.
pub(super) fn fan(corners: &[u32], triangles: &mut Vec<[u32; 3]>) {
    let Some((&first, rest)) = corners.split_first() else {
        return;
    };
    triangles.extend(
        rest.windows(2)
            .map(|w| [first, w[0], w[1]])
            .filter(|&[a, b, c]| a != b && b != c && c != a),
    );
}

fn found_suffix(found: Option<u64>) -> String {
    found.map_or_else(String::new, |n| format!(" (found {n})"))
}

/// A point-cloud file that could not be read, with the file named.
#[derive(Debug, thiserror::Error)]
#[error("{source_name}: {kind}")]
pub struct LoadError {
    /// The file (or the name given for in-memory data).
    pub source_name: String,
    /// What is wrong.
    pub kind: LoadErrorKind,
}

/// A point cloud that could not be written.
#[derive(Debug, thiserror::Error)]
#[error("{path}: cannot write: {source}")]
pub struct SaveError {
    /// The file.
    pub path: PathBuf,
    /// The underlying I/O error.
    pub source: std::io::Error,
}

/// Reads a point cloud from `path`, in `format` or the format its extension names.
pub fn read_cloud(path: &Path, format: Option<CloudFormat>) -> Result<PointCloud, LoadError> {
    let source_name = path.display().to_string();
    let err = |kind| LoadError {
        source_name: source_name.clone(),
        kind,
    };
    let format = match format.or_else(|| CloudFormat::from_path(path)) {
        Some(f) => f,
        None => {
            return Err(err(LoadErrorKind::UnknownFormat {
                extension: path.extension().map(|e| e.to_string_lossy().into_owned()),
            }));
        }
    };
    let bytes = std::fs::read(path).map_err(|e| err(LoadErrorKind::Io(e)))?;
    parse_cloud(&bytes, format).map_err(err)
}

/// Reads a point cloud from bytes in memory; `source_name` names it in errors.
pub fn read_cloud_from_bytes(
    bytes: &[u8],
    format: CloudFormat,
    source_name: &str,
) -> Result<PointCloud, LoadError> {
    parse_cloud(bytes, format).map_err(|kind| LoadError {
        source_name: source_name.to_owned(),
        kind,
    })
}

fn parse_cloud(bytes: &[u8], format: CloudFormat) -> Result<PointCloud, LoadErrorKind> {
    let cloud = match format {
        CloudFormat::Ply => ply::read(bytes)?,
        CloudFormat::Xyz | CloudFormat::Pwn => xyz::read(bytes)?,
        CloudFormat::Off => off::read(bytes)?,
        CloudFormat::Obj => obj::read(bytes)?,
    };
    if cloud.is_empty() {
        return Err(LoadErrorKind::Empty);
    }
    Ok(cloud)
}

/// Writes `cloud` as PLY (positions as `float x y z`, normals as `float nx ny nz` when present).
/// The file is written beside `path` and renamed into place once complete, so a failed write
/// never leaves a truncated file, and an old file at `path` stays as it was until then.
pub fn write_ply(path: &Path, cloud: &PointCloud, encoding: PlyEncoding) -> Result<(), SaveError> {
    write_atomically(path, |mut out| write_ply_to(&mut out, cloud, encoding))
}

/// Any error, from [`write_atomically_to_path`]'s writer or from the file system.
pub type BoxedError = Box<dyn std::error::Error + Send + Sync>;

/// A temporary file beside `path` (in its folder, so that renaming it onto `path` is atomic),
/// ending in `suffix`, readable like a file `File::create` makes (the umask still applies),
/// not 0600.
fn temp_beside(path: &Path, suffix: &str) -> std::io::Result<tempfile::NamedTempFile> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let mut builder = tempfile::Builder::new();
    builder.prefix(".point-springs-").suffix(suffix);
    #[cfg(unix)]
    builder.permissions(std::os::unix::fs::PermissionsExt::from_mode(0o644));
    builder.tempfile_in(dir)
}

/// The bytes of a tagged binary file: `magic` (its format's name and version), then `value`
/// in postcard's encoding (snapshots, saved games).
pub fn encode_tagged<T: serde::Serialize>(value: &T, magic: &[u8]) -> Vec<u8> {
    let mut bytes = magic.to_vec();
    // Encoding into a growing Vec fails only where serde would (no type written so can).
    bytes.extend(postcard::to_stdvec(value).expect("the value always encodes"));
    bytes
}

/// Why [`decode_tagged`] refused the bytes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum TaggedError {
    /// They do not start with the format's magic bytes.
    Foreign,
    /// They are cut short, damaged, or go on after the value.
    Damaged(String),
}

/// Decodes what [`encode_tagged`] wrote: anything but `magic` and one whole value is an
/// error, and the decoder allocates no more than the bytes can fill.
pub fn decode_tagged<T: serde::de::DeserializeOwned>(
    bytes: &[u8],
    magic: &[u8],
) -> Result<T, TaggedError> {
    let body = bytes.strip_prefix(magic).ok_or(TaggedError::Foreign)?;
    let (value, rest) =
        postcard::take_from_bytes::<T>(body).map_err(|e| TaggedError::Damaged(e.to_string()))?;
    if !rest.is_empty() {
        return Err(TaggedError::Damaged(format!(
            "{} bytes after the end",
            rest.len()
        )));
    }
    Ok(value)
}

/// Writes a file through `write` into a temporary file in `path`'s directory, flushed to
/// disk, then renamed to `path`; on any failure the temporary file is removed and `path` is
/// untouched.
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<(), SaveError> {
    let err = |source| SaveError {
        path: path.to_owned(),
        source,
    };
    let mut file = temp_beside(path, ".tmp").map_err(err)?;
    {
        let mut out = std::io::BufWriter::new(file.as_file_mut());
        write(&mut out).map_err(err)?;
        out.flush().map_err(err)?;
    }
    file.as_file().sync_all().map_err(err)?;
    file.persist(path).map_err(|e| err(e.error))?;
    Ok(())
}

/// [`write_atomically`] for writers that insist on opening a path of their own (plotters'
/// backends, an image encoder): `write` gets a temporary path in `path`'s folder with
/// `path`'s extension (which such writers read the format from); once it succeeds the file
/// is renamed to `path`. On any failure the temporary file is removed and `path` is
/// untouched; `write`'s own error comes back as it was.
pub fn write_atomically_to_path(
    path: &Path,
    write: impl FnOnce(&Path) -> Result<(), BoxedError>,
) -> Result<(), BoxedError> {
    let err = |source| SaveError {
        path: path.to_owned(),
        source,
    };
    let suffix = path
        .extension()
        .map(|e| format!(".{}", e.to_string_lossy()))
        .unwrap_or_default();
    let file = temp_beside(path, &suffix).map_err(err)?;
    write(file.path())?;
    file.persist(path).map_err(|e| err(e.error))?;
    Ok(())
}

/// Writes `cloud` as PLY to any writer.
pub fn write_ply_to<W: Write>(
    out: &mut W,
    cloud: &PointCloud,
    encoding: PlyEncoding,
) -> std::io::Result<()> {
    ply::write(out, cloud, encoding)
}

/// A header's element count up to this many times what the bytes after it can hold is read
/// and reported as a truncated file; beyond it, the header is reported as corrupt without
/// reading anything.
pub(crate) const TRUNCATION_FACTOR: u64 = 2;

/// Converts a value read from a file to an `f32` coordinate, checking it.
pub(crate) fn coordinate(
    value: f64,
    what: &'static str,
    location: impl FnOnce() -> Location,
) -> Result<f32, LoadErrorKind> {
    use crate::core::cloud::MAX_ABS_COORDINATE;
    if !value.is_finite() {
        return Err(LoadErrorKind::NonFinite {
            location: location(),
            what,
            value,
        });
    }
    if value.abs() > f64::from(MAX_ABS_COORDINATE) {
        return Err(LoadErrorKind::OutOfRange {
            location: location(),
            value,
            limit: MAX_ABS_COORDINATE,
        });
    }
    Ok(value as f32)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn format_from_extension_and_name() {
        assert_eq!(
            CloudFormat::from_path(Path::new("a/b.PLY")),
            Some(CloudFormat::Ply)
        );
        assert_eq!(
            CloudFormat::from_path(Path::new("x.pwn")),
            Some(CloudFormat::Pwn)
        );
        assert_eq!(CloudFormat::from_path(Path::new("x.txt")), None);
        assert_eq!(CloudFormat::from_path(Path::new("noext")), None);
        assert_eq!("OBJ".parse::<CloudFormat>(), Ok(CloudFormat::Obj));
        assert!("las".parse::<CloudFormat>().is_err());
    }

    #[test]
    fn a_failed_write_leaves_the_old_file_and_no_other() {
        let dir = std::env::temp_dir().join(format!("point-springs-atomic-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("cloud.ply");
        std::fs::write(&path, b"the old file").unwrap();
        // Half written, then the disk fills up.
        let e = write_atomically(&path, |out| {
            out.write_all(b"half a new fi")?;
            Err(std::io::Error::other("no space left on device"))
        })
        .unwrap_err();
        assert_eq!(e.path, path);
        assert_eq!(std::fs::read(&path).unwrap(), b"the old file");
        assert_eq!(
            std::fs::read_dir(&dir).unwrap().count(),
            1,
            "a temporary file is left"
        );
        // A whole write replaces it.
        write_atomically(&path, |out| out.write_all(b"the new file")).unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"the new file");
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_writer_given_a_path_writes_beside_it_and_renames() {
        let dir =
            std::env::temp_dir().join(format!("point-springs-to-path-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("picture.png");
        std::fs::write(&path, b"the old picture").unwrap();
        // The writer sees a path in the same folder with the same extension, and fails.
        let e = write_atomically_to_path(&path, |tmp| {
            assert_eq!(tmp.parent(), Some(dir.as_path()));
            assert_eq!(tmp.extension(), path.extension());
            std::fs::write(tmp, b"half a pic")?;
            Err("the encoder gave up".into())
        })
        .unwrap_err();
        assert_eq!(e.to_string(), "the encoder gave up");
        assert_eq!(std::fs::read(&path).unwrap(), b"the old picture");
        assert_eq!(
            std::fs::read_dir(&dir).unwrap().count(),
            1,
            "a temporary file is left"
        );
        write_atomically_to_path(&path, |tmp| Ok(std::fs::write(tmp, b"the new picture")?))
            .unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"the new picture");
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn unknown_extension_is_a_typed_error() {
        let e = read_cloud(Path::new("cloud.las"), None).unwrap_err();
        assert!(matches!(e.kind, LoadErrorKind::UnknownFormat { .. }));
        assert!(e.to_string().starts_with("cloud.las: "));
    }

    #[test]
    fn missing_file_is_io_error() {
        let e = read_cloud(Path::new("/definitely/not/here.xyz"), None).unwrap_err();
        assert!(matches!(e.kind, LoadErrorKind::Io(_)));
    }
}
