//! Prepared files: a surface's preparation (its network, springs and masses, the transfer's
//! coefficients and rest normals, the settings) saved once and read back instead of
//! preparing again, which takes seconds for 10⁵ dense points and more for 10⁶.
//!
//! A prepared file names what it was prepared from by a [`SourceFingerprint`]: a BLAKE3
//! hash of the dense cloud (positions, normals and faces, bit for bit), of the settings, and
//! of anything else the caller adds (a scene's pins). Reading it back with another
//! fingerprint, from another version of this crate, or from a damaged file is refused with
//! a [`PreparedFileError`], so the caller can prepare from the source instead. What is read
//! is checked before it is used ([`SpringNetwork::check`], [`Transfer::check_parts`]): a file
//! that passes its hash but was made by hand still gives an error, never a panic.
//!
//! The file: the 8 bytes [`PREPARED_MAGIC`] (whose last byte is the format's version), the
//! 32-byte BLAKE3 hash of everything after it, then in postcard's binary encoding the
//! header (the crate version that wrote it, the source's fingerprint) and the parts
//! (settings, where the normals came from, network, transfer), floats as their exact bits.
//! A surface read back is the one prepared, to the bit (`tests/prepared.rs`).
//!
//! ```
//! use std::ops::ControlFlow;
//! use bevy_point_springs::core::cloud::shapes::fibonacci_sphere;
//! use bevy_point_springs::core::pipeline::prepared::{
//!     PreparedFileError, SourceFingerprint, decode_prepared, encode_prepared,
//! };
//! use bevy_point_springs::core::pipeline::{SurfaceConfig, prepare_surface};
//! use bevy_point_springs::core::simplify::SimplifyConfig;
//!
//! let cloud = fibonacci_sphere(1000, 1.0);
//! let config = SurfaceConfig { simplify: SimplifyConfig::target(100), ..Default::default() };
//! let source = SourceFingerprint::of(&cloud, &config);
//! let surface = prepare_surface(cloud, &config, &mut |_| ControlFlow::Continue(())).unwrap();
//! let bytes = encode_prepared(&surface, source).unwrap();
//! let again = decode_prepared(&bytes, source).unwrap();
//! assert_eq!(again.network, surface.network);
//! // Another cloud's preparation is refused.
//! let other = SourceFingerprint::of(&fibonacci_sphere(1001, 1.0), &config);
//! assert!(matches!(decode_prepared(&bytes, other), Err(PreparedFileError::OtherSource { .. })));
//! ```

use std::fmt;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::{PrepareError, PreparedSurface, SurfaceConfig};
use crate::core::PointCloud;
use crate::core::cloud::io::write_atomically;
use crate::core::network::SpringNetwork;
use crate::core::normals::NormalSource;
use crate::core::transfer::Transfer;

/// The first bytes of a prepared file: a name and the format's version (raise it whenever
/// what the parts hold changes).
pub const PREPARED_MAGIC: &[u8; 8] = b"PSPREP\x00\x01";

/// The extension prepared files are given.
pub const PREPARED_EXTENSION: &str = "psprep";

/// The crate version that writes prepared files; a file from another is refused.
pub const PREPARED_BY: &str = env!("CARGO_PKG_VERSION");

/// Bytes of the hash after the magic.
const HASH_BYTES: usize = 32;

/// Bytes hashed at a time while fingerprinting a cloud.
const FINGERPRINT_CHUNK: usize = 1 << 16;

/// What a preparation starts from, as a BLAKE3 hash: the dense cloud (positions, normals,
/// faces, bit for bit), the settings, and anything the caller adds.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct SourceFingerprint(pub [u8; HASH_BYTES]);

impl fmt::Debug for SourceFingerprint {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "SourceFingerprint({self})")
    }
}

/// The first 8 bytes in hexadecimal (enough to tell two apart in a log).
impl fmt::Display for SourceFingerprint {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.0[..8].iter().try_for_each(|b| write!(f, "{b:02x}"))
    }
}

impl SourceFingerprint {
    /// The fingerprint of preparing `cloud` with `config`.
    pub fn of(cloud: &PointCloud, config: &SurfaceConfig) -> Self {
        Self::with_extra(cloud, config, &[])
    }

    /// The fingerprint of preparing `cloud` with `config` and `extra` (the bytes of
    /// whatever else decides the result, such as a scene's pins).
    pub fn with_extra(cloud: &PointCloud, config: &SurfaceConfig, extra: &[u8]) -> Self {
        let mut hasher = blake3::Hasher::new();
        hasher.update(b"bevy_point_springs source\0");
        let mut chunk = Vec::with_capacity(FINGERPRINT_CHUNK + 16);
        let mut feed = |hasher: &mut blake3::Hasher, bytes: &[u8]| {
            chunk.extend_from_slice(bytes);
            if chunk.len() >= FINGERPRINT_CHUNK {
                hasher.update(&chunk);
                chunk.clear();
            }
        };
        feed(&mut hasher, &(cloud.len() as u64).to_le_bytes());
        for p in cloud.positions() {
            feed(&mut hasher, &vec3_bytes(*p));
        }
        match cloud.normals() {
            Some(normals) => {
                feed(&mut hasher, &[1]);
                for n in normals {
                    feed(&mut hasher, &vec3_bytes(*n));
                }
            }
            None => feed(&mut hasher, &[0]),
        }
        feed(&mut hasher, &(cloud.faces().len() as u64).to_le_bytes());
        for face in cloud.faces() {
            for i in face {
                feed(&mut hasher, &i.to_le_bytes());
            }
        }
        // Settings encode always (plain data); an empty encoding could not collide anyway,
        // as the length goes first.
        let settings = postcard::to_stdvec(config).unwrap_or_default();
        feed(&mut hasher, &(settings.len() as u64).to_le_bytes());
        feed(&mut hasher, &settings);
        feed(&mut hasher, &(extra.len() as u64).to_le_bytes());
        feed(&mut hasher, extra);
        hasher.update(&chunk);
        Self(*hasher.finalize().as_bytes())
    }
}

fn vec3_bytes(v: glam::Vec3) -> [u8; 12] {
    let mut out = [0; 12];
    for (o, c) in out.chunks_exact_mut(4).zip(v.to_array()) {
        o.copy_from_slice(&c.to_bits().to_le_bytes());
    }
    out
}

/// Why a prepared file could not be written or was refused.
#[derive(Debug, thiserror::Error)]
pub enum PreparedFileError {
    /// The file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What the system said.
        source: std::io::Error,
    },
    /// Not a prepared file at all.
    #[error("not a prepared surface file")]
    Foreign,
    /// Written by another version of this crate (or in another format).
    #[error("prepared by bevy_point_springs {found}, and this is {ours}")]
    Version {
        /// The version (or format) that wrote it.
        found: String,
        /// This crate's.
        ours: String,
    },
    /// Prepared from another cloud, or with other settings.
    #[error("prepared from another source (cloud or settings: {found}, expected {expected})")]
    OtherSource {
        /// The file's source.
        found: SourceFingerprint,
        /// The source it was read for.
        expected: SourceFingerprint,
    },
    /// Cut short, changed after it was written, or inconsistent.
    #[error("damaged prepared file: {0}")]
    Damaged(String),
    /// The surface cannot be saved (resampled since its preparation), or its parts cannot
    /// make a surface.
    #[error(transparent)]
    Prepare(#[from] PrepareError),
}

impl PreparedFileError {
    /// Whether the file was simply not there (the first run, before one was written).
    pub fn is_missing(&self) -> bool {
        matches!(self, Self::Io { source, .. } if source.kind() == std::io::ErrorKind::NotFound)
    }
}

/// The header: who wrote the file, and from what.
#[derive(Serialize, Deserialize)]
struct Header {
    version: String,
    source: SourceFingerprint,
}

/// The parts, borrowed for writing.
#[derive(Serialize)]
struct PartsRef<'a> {
    config: &'a SurfaceConfig,
    normal_source: &'a NormalSource,
    network: &'a SpringNetwork,
    transfer: &'a Transfer,
}

/// The parts, owned for reading (the same fields in the same order).
#[derive(Deserialize)]
struct Parts {
    config: SurfaceConfig,
    normal_source: NormalSource,
    network: SpringNetwork,
    transfer: Transfer,
}

/// The bytes of a prepared file for `surface` as the pipeline returned it (before it ran:
/// a surface whose dense cloud has been resampled is refused), prepared from `source`.
pub fn encode_prepared(
    surface: &PreparedSurface,
    source: SourceFingerprint,
) -> Result<Vec<u8>, PreparedFileError> {
    if surface.dense.inserted() > 0 {
        return Err(PrepareError::Invalid(
            "a resampled surface is no longer the one prepared".into(),
        )
        .into());
    }
    let header = Header {
        version: PREPARED_BY.to_owned(),
        source,
    };
    let parts = PartsRef {
        config: &surface.config,
        normal_source: &surface.normal_source,
        network: &surface.network,
        transfer: surface.dense.transfer(),
    };
    let encode = |e: postcard::Error| PreparedFileError::Damaged(format!("encoding: {e}"));
    let mut body = postcard::to_stdvec(&header).map_err(encode)?;
    body.extend(postcard::to_stdvec(&parts).map_err(encode)?);
    let mut bytes = Vec::with_capacity(PREPARED_MAGIC.len() + HASH_BYTES + body.len());
    bytes.extend_from_slice(PREPARED_MAGIC);
    bytes.extend_from_slice(blake3::hash(&body).as_bytes());
    bytes.extend(body);
    Ok(bytes)
}

/// The surface a prepared file's bytes hold, if they were prepared from `expected` by this
/// version, undamaged.
pub fn decode_prepared(
    bytes: &[u8],
    expected: SourceFingerprint,
) -> Result<PreparedSurface, PreparedFileError> {
    let name = &PREPARED_MAGIC[..PREPARED_MAGIC.len() - 1];
    let Some(rest) = bytes.strip_prefix(PREPARED_MAGIC.as_slice()) else {
        return Err(match (bytes.strip_prefix(name), PREPARED_MAGIC.last()) {
            (Some([format, ..]), Some(ours)) => PreparedFileError::Version {
                found: format!("(file format {format})"),
                ours: format!("{PREPARED_BY} (file format {ours})"),
            },
            _ => PreparedFileError::Foreign,
        });
    };
    let damaged = |what: String| PreparedFileError::Damaged(what);
    let (hash, body) = rest
        .split_first_chunk::<HASH_BYTES>()
        .ok_or_else(|| damaged("cut short".into()))?;
    if blake3::hash(body).as_bytes() != hash {
        return Err(damaged("its contents do not match their hash".into()));
    }
    let (header, body) =
        postcard::take_from_bytes::<Header>(body).map_err(|e| damaged(format!("header: {e}")))?;
    if header.version != PREPARED_BY {
        return Err(PreparedFileError::Version {
            found: header.version,
            ours: PREPARED_BY.to_owned(),
        });
    }
    if header.source != expected {
        return Err(PreparedFileError::OtherSource {
            found: header.source,
            expected,
        });
    }
    let (parts, after) =
        postcard::take_from_bytes::<Parts>(body).map_err(|e| damaged(format!("parts: {e}")))?;
    if !after.is_empty() {
        return Err(damaged(format!("{} bytes after the end", after.len())));
    }
    parts
        .config
        .validate()
        .map_err(|e| damaged(format!("settings: {e}")))?;
    parts
        .network
        .check()
        .map_err(|e| damaged(format!("network: {e}")))?;
    parts
        .transfer
        .check_parts()
        .map_err(|e| damaged(format!("transfer: {e}")))?;
    Ok(PreparedSurface::from_parts(
        parts.config,
        parts.normal_source,
        parts.network,
        parts.transfer,
    )?)
}

/// Writes `surface`'s prepared file to `path` (see [`encode_prepared`]), atomically: a
/// failure leaves any file there as it was.
pub fn write_prepared(
    path: &Path,
    surface: &PreparedSurface,
    source: SourceFingerprint,
) -> Result<(), PreparedFileError> {
    let bytes = encode_prepared(surface, source)?;
    write_atomically(path, |w| w.write_all(&bytes)).map_err(|e| PreparedFileError::Io {
        path: path.to_owned(),
        source: e.source,
    })
}

/// Reads the prepared file at `path` for the source `expected` (see [`decode_prepared`]).
pub fn read_prepared(
    path: &Path,
    expected: SourceFingerprint,
) -> Result<PreparedSurface, PreparedFileError> {
    let bytes = std::fs::read(path).map_err(|source| PreparedFileError::Io {
        path: path.to_owned(),
        source,
    })?;
    decode_prepared(&bytes, expected)
}
