//! Point-cloud I/O: PLY round trips, every loader on real files, and a table of malformed input.

use std::path::Path;

use bevy_point_springs::core::cloud::io::{
    CloudFormat, LoadErrorKind, PlyEncoding, read_cloud, read_cloud_from_bytes, write_ply,
    write_ply_to,
};
use bevy_point_springs::core::{PointCloud, cloud::shapes};
use glam::Vec3;
use proptest::prelude::*;

const ENCODINGS: [PlyEncoding; 3] = [
    PlyEncoding::Ascii,
    PlyEncoding::BinaryLittleEndian,
    PlyEncoding::BinaryBigEndian,
];

fn asset(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("assets")
        .join(name)
}

fn ply_bytes(cloud: &PointCloud, encoding: PlyEncoding) -> Vec<u8> {
    let mut out = Vec::new();
    write_ply_to(&mut out, cloud, encoding).unwrap();
    out
}

fn assert_bit_exact(a: &[Vec3], b: &[Vec3]) {
    assert_eq!(a.len(), b.len());
    for (i, (p, q)) in a.iter().zip(b).enumerate() {
        let bits = |v: &Vec3| v.to_array().map(f32::to_bits);
        assert_eq!(bits(p), bits(q), "point {i}: {p:?} vs {q:?}");
    }
}

#[test]
fn ply_round_trip_is_bit_exact_in_every_encoding() {
    // Awkward values: negative zero, subnormals, long mantissas, large and tiny exponents.
    let mut positions = shapes::fibonacci_sphere(500, 3.7).into_parts().0;
    positions.extend([
        Vec3::new(-0.0, f32::MIN_POSITIVE / 3.0, 1.0e15),
        Vec3::new(0.1 + 0.2, -1.0e-30, 123_456.79),
        Vec3::new(std::f32::consts::PI, -std::f32::consts::E, 16_777_217.0),
    ]);
    let normals: Vec<Vec3> = positions.iter().map(|p| p.normalize_or(Vec3::Y)).collect();
    let cloud = PointCloud::new(positions, Some(normals)).unwrap();
    let without = PointCloud::new(cloud.positions().to_vec(), None).unwrap();
    for encoding in ENCODINGS {
        let back =
            read_cloud_from_bytes(&ply_bytes(&cloud, encoding), CloudFormat::Ply, "mem").unwrap();
        assert_bit_exact(cloud.positions(), back.positions());
        assert_bit_exact(cloud.normals().unwrap(), back.normals().unwrap());
        let back =
            read_cloud_from_bytes(&ply_bytes(&without, encoding), CloudFormat::Ply, "mem").unwrap();
        assert_bit_exact(without.positions(), back.positions());
        assert!(back.normals().is_none());
    }
}

#[test]
fn ply_round_trip_through_a_file() {
    let dir = std::env::temp_dir().join(format!("bps-io-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("sphere.ply");
    let cloud = shapes::fibonacci_sphere(321, 1.0);
    write_ply(&path, &cloud, PlyEncoding::default()).unwrap();
    let back = read_cloud(&path, None).unwrap();
    assert_bit_exact(cloud.positions(), back.positions());
    std::fs::remove_dir_all(&dir).unwrap();
    // Writing into a missing directory is a typed error naming the path.
    let e = write_ply(&dir.join("no/such/dir.ply"), &cloud, PlyEncoding::Ascii).unwrap_err();
    assert!(e.to_string().contains("dir.ply"));
}

// Case counts follow proptest's default (256), or `PROPTEST_CASES` for longer fuzzing runs.
proptest! {
    #[test]
    fn ply_round_trip_random_bits(
        raw in prop::collection::vec(prop::array::uniform6(any::<u32>()), 1..40),
        encoding in prop::sample::select(ENCODINGS.to_vec()),
    ) {
        // Any finite in-range f32 bit pattern survives a round trip unchanged.
        let clamp = |b: u32| {
            let v = f32::from_bits(b);
            if v.is_finite() && v.abs() <= 1.0e15 { v } else { f32::from_bits(b & 0x3FFF_FFFF) }
        };
        let positions: Vec<Vec3> = raw.iter().map(|r| Vec3::new(clamp(r[0]), clamp(r[1]), clamp(r[2]))).collect();
        let normals: Vec<Vec3> = raw.iter().map(|r| Vec3::new(clamp(r[3]), clamp(r[4]), clamp(r[5]))).collect();
        let cloud = PointCloud::new(positions, Some(normals)).unwrap();
        let back = read_cloud_from_bytes(&ply_bytes(&cloud, encoding), CloudFormat::Ply, "mem").unwrap();
        assert_bit_exact(cloud.positions(), back.positions());
        assert_bit_exact(cloud.normals().unwrap(), back.normals().unwrap());
    }

    #[test]
    fn no_loader_panics_on_arbitrary_bytes(
        bytes in prop::collection::vec(any::<u8>(), 0..600),
        format in prop::sample::select(CloudFormat::ALL.to_vec()),
    ) {
        let _ = read_cloud_from_bytes(&bytes, format, "fuzz");
    }

    #[test]
    fn no_loader_panics_on_damaged_files(
        cut in 0usize..2000,
        flips in prop::collection::vec((0usize..2000, any::<u8>()), 0..4),
        which in 0usize..4,
    ) {
        let valid: Vec<(CloudFormat, Vec<u8>)> = vec![
            (CloudFormat::Ply, ply_bytes(&shapes::fibonacci_sphere(40, 1.0), PlyEncoding::BinaryLittleEndian)),
            (CloudFormat::Ply, ply_bytes(&shapes::fibonacci_sphere(40, 1.0), PlyEncoding::Ascii)),
            (CloudFormat::Off, b"OFF\n4 1 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n".to_vec()),
            (CloudFormat::Obj, b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1\n".to_vec()),
        ];
        let (format, mut bytes) = valid[which].clone();
        for (at, b) in flips {
            if !bytes.is_empty() {
                let i = at % bytes.len();
                bytes[i] = b;
            }
        }
        bytes.truncate(cut);
        let _ = read_cloud_from_bytes(&bytes, format, "damaged");
    }
}

#[test]
fn real_files_load() {
    let sphere = read_cloud(&asset("sphere926.pwn"), None).unwrap();
    assert_eq!(sphere.len(), 926);
    assert!(sphere.has_usable_normals());
    let half = read_cloud(&asset("half.xyz"), None).unwrap();
    assert_eq!(half.len(), 325);
    assert!(half.normals().is_none());
    let kitten = read_cloud(&asset("kitten.off"), None).unwrap();
    assert_eq!(kitten.len(), 5210);
    let example = read_cloud(&asset("example.ply"), None).unwrap();
    assert_eq!(example.len(), 3);
    assert_eq!(example.positions()[1], Vec3::new(0.0, 0.0, 1.0));
    assert_eq!(example.normals().unwrap()[2], Vec3::Z);
    // The format can be forced: the PWN file read as XYZ gives the same cloud.
    let forced = read_cloud(&asset("sphere926.pwn"), Some(CloudFormat::Xyz)).unwrap();
    assert_eq!(forced, sphere);
}

#[test]
fn mesh_files_keep_their_faces_as_triangles() {
    // A unit square as one quad and a triangle on top: the quad becomes a fan of two.
    let off = "OFF\n5 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n0.5 1.5 0\n4 0 1 2 3\n3 3 2 4 255 0 0\n";
    let obj = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 1.5 0\nf 1/1 2/2 3/3 4/4\nf -2 -3 -1\n";
    let ply = "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\n\
               property float z\nelement face 2\nproperty list uchar int vertex_indices\n\
               end_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n0.5 1.5 0\n4 0 1 2 3\n3 3 2 4\n";
    let expected = [[0, 1, 2], [0, 2, 3], [3, 2, 4]];
    for (text, format) in [
        (off, CloudFormat::Off),
        (obj, CloudFormat::Obj),
        (ply, CloudFormat::Ply),
    ] {
        let cloud = read_cloud_from_bytes(text.as_bytes(), format, "mesh").unwrap();
        assert_eq!(cloud.len(), 5, "{format}");
        assert_eq!(cloud.faces(), &expected, "{format}");
    }
    // The same in binary PLY; a polygon naming a point twice keeps only its proper triangles.
    let mut binary = b"ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\n\
        property float y\nproperty float z\nelement face 1\nproperty list uchar uint vertex_indices\n\
        end_header\n"
        .to_vec();
    for p in [
        [0f32, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ] {
        p.iter().for_each(|c| binary.extend(c.to_le_bytes()));
    }
    binary.push(5);
    [0u32, 1, 1, 2, 3]
        .iter()
        .for_each(|i| binary.extend(i.to_le_bytes()));
    let cloud = read_cloud_from_bytes(&binary, CloudFormat::Ply, "binary").unwrap();
    assert_eq!(cloud.faces(), &[[0, 1, 2], [0, 2, 3]]);
    // The elephant from CGAL: every face, and the normals they give.
    let mut elephant = read_cloud(&asset("elephant.off"), None).unwrap();
    assert_eq!((elephant.len(), elephant.faces().len()), (2775, 5558));
    assert!(elephant.normals().is_none());
    let source = bevy_point_springs::core::normals::ensure_normals(&mut elephant, 10).unwrap();
    assert_eq!(
        source,
        bevy_point_springs::core::normals::NormalSource::Faces
    );
}

#[test]
fn faces_that_are_not_triangles_of_the_cloud_are_typed_errors() {
    use bevy_point_springs::core::cloud::CloudError;
    let cloud = || PointCloud::new(vec![Vec3::ZERO, Vec3::X, Vec3::Y], None).unwrap();
    for (face, index) in [([0, 1, 3], 1), ([0, 2, 2], 1)] {
        let err = cloud().with_faces(vec![[0, 1, 2], face]).unwrap_err();
        assert!(
            matches!(err, CloudError::BadFace { index: i, points: 3, .. } if i == index),
            "{err}"
        );
    }
    assert_eq!(
        cloud().with_faces(vec![[2, 0, 1]]).unwrap().faces(),
        &[[2, 0, 1]]
    );
}

#[test]
fn face_normals_point_out_of_a_closed_mesh_whatever_its_winding() {
    use bevy_point_springs::core::normals::vertex_normals_from_faces;
    let corners = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
    let centre = corners.iter().copied().sum::<Vec3>() / 4.0;
    let outward = [[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]];
    let inward = outward.map(|[a, b, c]| [a, c, b]);
    for faces in [outward, inward] {
        let normals = vertex_normals_from_faces(&corners, &faces).unwrap();
        for (p, n) in corners.iter().zip(&normals) {
            assert!((n.length() - 1.0).abs() < 1e-6);
            assert!(n.dot(*p - centre) > 0.0, "{faces:?}: {n}");
        }
    }
    // An open mesh keeps its winding; a point without a triangle means no normals from faces.
    let open = vertex_normals_from_faces(&corners[..3], &[[0, 1, 2]]).unwrap();
    assert!(open.iter().all(|n| *n == Vec3::Z));
    assert!(vertex_normals_from_faces(&corners, &[[0, 1, 2]]).is_none());
}

#[test]
fn every_format_reads_the_same_cloud() {
    let xyz = "0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 1\n";
    let off = "NOFF\n# comment\n3 0 0\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 1\n";
    let obj = "# points\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nvn 0 0 1\nvn 0 0 1\n";
    let obj_faces = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1\n";
    let cloud = read_cloud_from_bytes(xyz.as_bytes(), CloudFormat::Xyz, "a").unwrap();
    for (text, format) in [
        (off, CloudFormat::Off),
        (obj, CloudFormat::Obj),
        (obj_faces, CloudFormat::Obj),
        (xyz, CloudFormat::Pwn),
    ] {
        // The same points and normals (the OBJ with a face has the face too).
        let other = read_cloud_from_bytes(text.as_bytes(), format, "b").unwrap();
        assert_eq!(other.into_parts(), cloud.clone().into_parts(), "{format}");
    }
    let ply = ply_bytes(&cloud, PlyEncoding::Ascii);
    assert_eq!(
        read_cloud_from_bytes(&ply, CloudFormat::Ply, "c").unwrap(),
        cloud
    );
    // CRLF line endings and a PLY with PCL-style normal names and double/int properties.
    let crlf = xyz.replace('\n', "\r\n");
    assert_eq!(
        read_cloud_from_bytes(crlf.as_bytes(), CloudFormat::Xyz, "d").unwrap(),
        cloud
    );
    let pcl = "ply\nformat ascii 1.0\nelement vertex 3\nproperty double x\nproperty int y\nproperty float z\n\
               property float normal_x\nproperty float normal_y\nproperty float normal_z\nelement face 0\n\
               property list uchar int vertex_indices\nend_header\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 1\n";
    assert_eq!(
        read_cloud_from_bytes(pcl.as_bytes(), CloudFormat::Ply, "e").unwrap(),
        cloud
    );
}

#[test]
fn ply_with_an_element_before_vertex() {
    let text = "ply\nformat ascii 1.0\nelement camera 1\nproperty float f\nelement vertex 2\n\
                property float x\nproperty float y\nproperty float z\nend_header\n35\n1 2 3\n4 5 6\n";
    let c = read_cloud_from_bytes(text.as_bytes(), CloudFormat::Ply, "cam").unwrap();
    assert_eq!(
        c.positions(),
        &[Vec3::new(1.0, 2.0, 3.0), Vec3::new(4.0, 5.0, 6.0)]
    );
}

/// A PLY header for `n` float vertices (x y z) in `encoding`.
fn ply_header(format: &str, n: u64) -> String {
    format!(
        "ply\nformat {format} 1.0\nelement vertex {n}\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
    )
}

fn binary_ply(format: &str, n: u64, values: &[f32], big_endian: bool) -> Vec<u8> {
    let mut bytes = ply_header(format, n).into_bytes();
    for v in values {
        bytes.extend(if big_endian {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        });
    }
    bytes
}

type Check = fn(&LoadErrorKind) -> bool;

fn is_empty(k: &LoadErrorKind) -> bool {
    matches!(k, LoadErrorKind::Empty)
}
fn is_truncated(k: &LoadErrorKind) -> bool {
    matches!(k, LoadErrorKind::Truncated { .. })
}
fn is_columns(k: &LoadErrorKind) -> bool {
    matches!(k, LoadErrorKind::ColumnCount { .. })
}
fn is_non_finite(k: &LoadErrorKind) -> bool {
    matches!(k, LoadErrorKind::NonFinite { .. })
}
fn is_too_large(k: &LoadErrorKind) -> bool {
    matches!(k, LoadErrorKind::CountTooLarge { .. })
}
fn is_not_text(k: &LoadErrorKind) -> bool {
    matches!(k, LoadErrorKind::NotText { .. })
}
fn is_syntax(k: &LoadErrorKind) -> bool {
    matches!(k, LoadErrorKind::Syntax { .. })
}
fn is_ply(k: &LoadErrorKind) -> bool {
    matches!(k, LoadErrorKind::Ply { .. })
}
fn is_missing(k: &LoadErrorKind) -> bool {
    matches!(k, LoadErrorKind::Missing(_))
}
fn is_range(k: &LoadErrorKind) -> bool {
    matches!(k, LoadErrorKind::OutOfRange { .. })
}
fn is_unsupported(k: &LoadErrorKind) -> bool {
    matches!(k, LoadErrorKind::Unsupported(_))
}
fn is_bad_corner(k: &LoadErrorKind) -> bool {
    matches!(k, LoadErrorKind::BadCorner { .. })
}
fn is_bad_index(k: &LoadErrorKind) -> bool {
    matches!(k, LoadErrorKind::BadIndex { .. })
}

#[test]
fn malformed_input_gives_typed_errors() {
    const GARBAGE: &[u8] = &[0xFF, 0xFE, 0x00, 0x9C, 0x80, 0x0A, 0xC3, 0x28, 0x0A];
    let le = "binary_little_endian";
    let be = "binary_big_endian";
    // (name, format, bytes, expected kind, text the message must contain)
    let cases: Vec<(&str, CloudFormat, Vec<u8>, Check, &str)> = vec![
        // XYZ / PWN
        ("xyz-empty", CloudFormat::Xyz, b"".to_vec(), is_empty, "no points"),
        ("xyz-comments-only", CloudFormat::Xyz, b"# nothing\n\n".to_vec(), is_empty, "no points"),
        ("xyz-truncated", CloudFormat::Xyz, b"1 2 3\n4 5".to_vec(), is_columns, "line 2"),
        ("xyz-wrong-count", CloudFormat::Xyz, b"1 2 3 4\n".to_vec(), is_columns, "line 1"),
        ("xyz-mixed-count", CloudFormat::Pwn, b"1 2 3\n1 2 3 0 0 1\n".to_vec(), is_columns, "line 2"),
        ("xyz-nan", CloudFormat::Xyz, b"0 0 0\n1 NaN 3\n".to_vec(), is_non_finite, "line 2"),
        ("xyz-inf", CloudFormat::Xyz, b"1 2 -inf\n".to_vec(), is_non_finite, "line 1"),
        ("pwn-nan-normal", CloudFormat::Pwn, b"1 2 3 0 nan 1\n".to_vec(), is_non_finite, "normal"),
        ("xyz-huge-value", CloudFormat::Xyz, b"1e300 0 0\n".to_vec(), is_range, "line 1"),
        ("xyz-overflow-f32", CloudFormat::Xyz, b"1e39 0 0\n".to_vec(), is_range, "line 1"),
        ("xyz-garbage-bytes", CloudFormat::Xyz, GARBAGE.to_vec(), is_not_text, "line 1"),
        ("xyz-words", CloudFormat::Xyz, b"one two three\n".to_vec(), is_syntax, "\"one\""),
        // OFF
        ("off-empty", CloudFormat::Off, b"".to_vec(), is_empty, "no points"),
        ("off-no-vertices", CloudFormat::Off, b"OFF\n0 0 0\n".to_vec(), is_empty, "no points"),
        ("off-truncated", CloudFormat::Off, b"OFF\n3 0 0\n0 0 0\n1 0 0\n".to_vec(), is_truncated, "found 2"),
        ("off-bad-count", CloudFormat::Off, b"OFF\nx 0 0\n".to_vec(), is_syntax, "line 2"),
        ("off-missing-count", CloudFormat::Off, b"OFF\n".to_vec(), is_missing, "count"),
        ("off-short-line", CloudFormat::Off, b"OFF\n2 0 0\n0 0 0\n1 0\n".to_vec(), is_columns, "line 4"),
        ("off-nan", CloudFormat::Off, b"OFF\n1 0 0\n0 nan 0\n".to_vec(), is_non_finite, "line 3"),
        ("off-inf", CloudFormat::Off, b"OFF 1 0 0\ninf 0 0\n".to_vec(), is_non_finite, "line 2"),
        ("off-claims-1e12", CloudFormat::Off, b"OFF\n1000000000000 0 0\n0 0 0\n".to_vec(), is_too_large, "1000000000000"),
        ("off-garbage-bytes", CloudFormat::Off, GARBAGE.to_vec(), is_not_text, "line 1"),
        ("off-not-off", CloudFormat::Off, b"PLY\n1 0 0\n".to_vec(), is_syntax, "OFF keyword"),
        ("off-binary", CloudFormat::Off, b"OFF BINARY\n".to_vec(), is_unsupported, "binary"),
        ("off-face-corner", CloudFormat::Off, b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n".to_vec(), is_bad_corner, "corner 3"),
        ("off-face-short", CloudFormat::Off, b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n4 0 1 2\n".to_vec(), is_columns, "line 6"),
        ("off-face-missing", CloudFormat::Off, b"OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n".to_vec(), is_truncated, "found 1"),
        ("off-face-word", CloudFormat::Off, b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 x 2\n".to_vec(), is_syntax, "line 6"),
        ("off-faces-claim-1e12", CloudFormat::Off, b"OFF\n3 1000000000000 0\n0 0 0\n1 0 0\n0 1 0\n".to_vec(), is_too_large, "face"),
        ("off-4d", CloudFormat::Off, b"4OFF\n1 0 0\n0 0 0 0\n".to_vec(), is_unsupported, "3-D"),
        // OBJ
        ("obj-empty", CloudFormat::Obj, b"".to_vec(), is_empty, "no points"),
        ("obj-no-vertices", CloudFormat::Obj, b"# just a comment\nvn 0 0 1\n".to_vec(), is_empty, "no points"),
        ("obj-truncated", CloudFormat::Obj, b"v 1 2 3\nv 4 5".to_vec(), is_columns, "line 2"),
        ("obj-nan", CloudFormat::Obj, b"v 1 nan 3\n".to_vec(), is_non_finite, "line 1"),
        ("obj-inf-normal", CloudFormat::Obj, b"v 0 0 0\nvn inf 0 0\n".to_vec(), is_non_finite, "line 2"),
        ("obj-bad-face", CloudFormat::Obj, b"v 0 0 0\nvn 0 0 1\nf 1//5\n".to_vec(), is_bad_index, "line 3"),
        ("obj-face-1e12", CloudFormat::Obj, b"v 0 0 0\nf 1000000000000\n".to_vec(), is_bad_index, "1000000000000"),
        ("obj-garbage-bytes", CloudFormat::Obj, GARBAGE.to_vec(), is_not_text, "line 1"),
        ("obj-words", CloudFormat::Obj, b"v a b c\n".to_vec(), is_syntax, "line 1"),
        // PLY, ASCII
        ("ply-empty", CloudFormat::Ply, b"".to_vec(), is_empty, "no points"),
        ("ply-face-corner", CloudFormat::Ply, b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n".to_vec(), is_syntax, "corner 7"),
        ("ply-faces-claim-1e12", CloudFormat::Ply, b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1000000000000\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n".to_vec(), is_too_large, "face"),
        ("ply-zero-vertices", CloudFormat::Ply, ply_header("ascii", 0).into_bytes(), is_empty, "no points"),
        ("ply-ascii-truncated", CloudFormat::Ply, format!("{}1 2 3\n4 5 6\n", ply_header("ascii", 3)).into_bytes(), is_truncated, "3 declared"),
        ("ply-ascii-wrong-count", CloudFormat::Ply, format!("{}1.5 2.5\n3 4 5\n", ply_header("ascii", 2)).into_bytes(), is_ply, "Line"),
        ("ply-ascii-nan", CloudFormat::Ply, format!("{}1 2 3\nnan 0 0\n", ply_header("ascii", 2)).into_bytes(), is_ply, "\"nan 0 0\""),
        ("ply-ascii-inf", CloudFormat::Ply, format!("{}inf 0 0\n", ply_header("ascii", 1)).into_bytes(), is_ply, "Line 8: Couldn't read element line. (vertex \"inf 0 0\")"),
        ("ply-ascii-claims-1e12", CloudFormat::Ply, format!("{}1 2 3\n", ply_header("ascii", 1_000_000_000_000)).into_bytes(), is_too_large, "1000000000000"),
        ("ply-garbage-bytes", CloudFormat::Ply, GARBAGE.to_vec(), is_ply, "PLY"),
        ("ply-no-end-header", CloudFormat::Ply, b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n".to_vec(), is_ply, "PLY"),
        ("ply-no-vertex", CloudFormat::Ply, b"ply\nformat ascii 1.0\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n".to_vec(), is_missing, "vertex"),
        ("ply-no-z", CloudFormat::Ply, b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n1 2\n".to_vec(), is_missing, "`z`"),
        // PLY, binary little and big endian
        ("ply-le-truncated", CloudFormat::Ply, binary_ply(le, 4, &[0.0; 10], false), is_truncated, "found 3"),
        ("ply-be-truncated", CloudFormat::Ply, binary_ply(be, 4, &[0.0; 10], true), is_truncated, "found 3"),
        ("ply-le-nan", CloudFormat::Ply, binary_ply(le, 2, &[0.0, 0.0, 0.0, 1.0, f32::NAN, 0.0], false), is_non_finite, "vertex 1"),
        ("ply-be-inf", CloudFormat::Ply, binary_ply(be, 1, &[f32::INFINITY, 0.0, 0.0], true), is_non_finite, "vertex 0"),
        ("ply-le-claims-1e12", CloudFormat::Ply, binary_ply(le, 1_000_000_000_000, &[1.0; 3], false), is_too_large, "1000000000000"),
        ("ply-be-claims-1e12", CloudFormat::Ply, binary_ply(be, 1_000_000_000_000, &[1.0; 3], true), is_too_large, "at most 1"),
        ("ply-le-garbage-payload", CloudFormat::Ply, { let mut b = ply_header(le, 2).into_bytes(); b.extend([0xFF; 24]); b }, is_non_finite, "vertex 0"),
        ("ply-le-out-of-range", CloudFormat::Ply, binary_ply(le, 1, &[3.0e38, 0.0, 0.0], false), is_range, "vertex 0"),
    ];
    for (name, format, bytes, check, needle) in cases {
        let source = format!("{name}.{format}");
        let err = match read_cloud_from_bytes(&bytes, format, &source) {
            Ok(c) => panic!("{name}: accepted, {} points", c.len()),
            Err(e) => e,
        };
        let message = err.to_string();
        assert!(check(&err.kind), "{name}: wrong kind: {message}");
        assert!(
            message.starts_with(&format!("{source}: ")),
            "{name}: file not named: {message}"
        );
        assert!(
            message.contains(needle),
            "{name}: {message:?} lacks {needle:?}"
        );
    }
}
