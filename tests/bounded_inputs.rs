//! The bounded suite over the readers and the scene format that CI runs (the long,
//! coverage-guided fuzzing is in `fuzz/`): random bytes, mutated valid files, absurd
//! headers, counts of 10^12 and deep nesting, and random snapshots. Each input gives an
//! error or a valid result, never a panic, and never allocates more than a small multiple
//! of its own size: a counting allocator adds up what every read asks for.

use std::alloc::System;
use std::path::Path;

use bevy_point_springs::core::cloud::io::{CloudFormat, read_cloud_from_bytes};
use bevy_point_springs::core::scene::{SNAPSHOT_MAGIC, Scene, Snapshot};
use proptest::prelude::*;
use proptest::test_runner::{Config, TestRunner};
use stats_alloc::{INSTRUMENTED_SYSTEM, Region, StatsAlloc};

/// Counts every allocation of this test binary. It holds a single test, so nothing else
/// allocates while a read is measured.
#[global_allocator]
static ALLOCATOR: &StatsAlloc<System> = &INSTRUMENTED_SYSTEM;

/// The most a read may allocate in all: this many times the input's size, plus a fixed
/// allowance (an error message, a small cloud).
const PER_INPUT_BYTE: usize = 16;
/// The fixed allowance, bytes.
const ALLOWANCE: usize = 1 << 20;

/// Runs `read` on `input` and checks what it allocated: every byte it asked for over the
/// read, freed or not (so a bound on the peak too).
fn bounded<T>(what: &str, input: &[u8], read: impl FnOnce(&[u8]) -> T) -> T {
    let region = Region::new(ALLOCATOR);
    let out = read(input);
    let stats = region.change();
    let asked = stats.bytes_allocated + stats.bytes_reallocated.max(0) as usize;
    let limit = PER_INPUT_BYTE * input.len() + ALLOWANCE;
    assert!(
        asked <= limit,
        "{what}: {} input bytes made {asked} bytes of allocations (limit {limit})",
        input.len()
    );
    out
}

/// Reads `bytes` as `format`: an error, or a cloud whose every coordinate is finite.
fn read_cloud_checked(what: &str, bytes: &[u8], format: CloudFormat) {
    if let Ok(cloud) = bounded(what, bytes, |b| read_cloud_from_bytes(b, format, what)) {
        assert!(cloud.positions().iter().all(|p| p.is_finite()), "{what}");
        if let Some(n) = cloud.normals() {
            assert!(n.iter().all(|v| v.is_finite()), "{what}");
        }
    }
}

/// Reads `bytes` as a scene.
fn read_scene_checked(what: &str, bytes: &[u8]) {
    let text = String::from_utf8_lossy(bytes);
    let _ = bounded(what, text.as_bytes(), |b| {
        Scene::from_ron(std::str::from_utf8(b).unwrap_or_default())
    });
}

fn asset(name: &str) -> Vec<u8> {
    std::fs::read(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("assets")
            .join(name),
    )
    .unwrap()
}

/// Valid inputs to mutate: every shipped cloud format and scene.
fn seeds() -> Vec<(CloudFormat, Vec<u8>)> {
    vec![
        (CloudFormat::Ply, asset("hat3000.ply")),
        (CloudFormat::Ply, asset("example.ply")),
        (CloudFormat::Ply, asset("letter_b.ply")),
        (CloudFormat::Pwn, asset("sphere926.pwn")),
        (CloudFormat::Xyz, asset("half.xyz")),
        (CloudFormat::Off, asset("kitten.off")),
        (CloudFormat::Off, asset("elephant.off")),
        (
            CloudFormat::Obj,
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nvn 0 0 1\nf 1//1 2//1 3//1\nf 1 2 4\n".to_vec(),
        ),
    ]
}

fn scene_seeds() -> Vec<Vec<u8>> {
    [
        "hat.ron",
        "letter_b.ron",
        "sculpt_letter.ron",
        "sphere_poke.ron",
        "sphere_poke_local_global.ron",
    ]
    .iter()
    .map(|name| asset(&format!("scenes/{name}")))
    .collect()
}

/// Tokens a mutation may splice in: numbers at the edges of every type, words the formats
/// use, and structure.
const TOKENS: &[&str] = &[
    "1000000000000",
    "-1",
    "0",
    "nan",
    "inf",
    "1e39",
    "-1e300",
    "4294967296",
    "18446744073709551616",
    "element vertex ",
    "element face ",
    "property list uchar int vertex_indices\n",
    "property double x\n",
    "format binary_big_endian 1.0\n",
    "end_header\n",
    "OFF\n",
    "f ",
    "v ",
    "vn ",
    "//",
    "\n",
    " ",
    "(",
    ")",
    "[",
    "]",
    "Some(",
    ":",
    ",",
    "\"",
    "\u{0}",
    "\u{feff}",
];

/// One mutation of a byte string.
#[derive(Debug, Clone)]
enum Mutation {
    /// Set the byte at (a fraction of the length) to a value.
    Set(f64, u8),
    /// Remove a run of bytes.
    Remove(f64, usize),
    /// Insert a token.
    Insert(f64, usize),
    /// Repeat a run of bytes.
    Repeat(f64, usize, usize),
    /// Cut the input there.
    Truncate(f64),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        (0.0..1.0f64, any::<u8>()).prop_map(|(at, b)| Mutation::Set(at, b)),
        (0.0..1.0f64, 1usize..64).prop_map(|(at, n)| Mutation::Remove(at, n)),
        (0.0..1.0f64, 0..TOKENS.len()).prop_map(|(at, t)| Mutation::Insert(at, t)),
        (0.0..1.0f64, 1usize..64, 2usize..8).prop_map(|(at, n, k)| Mutation::Repeat(at, n, k)),
        (0.0..1.0f64).prop_map(Mutation::Truncate),
    ]
}

fn mutate(mut bytes: Vec<u8>, mutations: &[Mutation]) -> Vec<u8> {
    for m in mutations {
        let at = |f: f64, len: usize| ((f * len as f64) as usize).min(len);
        match *m {
            Mutation::Set(f, b) => {
                if !bytes.is_empty() {
                    let i = at(f, bytes.len() - 1);
                    bytes[i] = b;
                }
            }
            Mutation::Remove(f, n) => {
                let i = at(f, bytes.len());
                let end = (i + n).min(bytes.len());
                bytes.drain(i..end);
            }
            Mutation::Insert(f, t) => {
                let i = at(f, bytes.len());
                bytes.splice(i..i, TOKENS[t].bytes());
            }
            Mutation::Repeat(f, n, k) => {
                let i = at(f, bytes.len());
                let run: Vec<u8> = bytes[i..(i + n).min(bytes.len())].to_vec();
                for _ in 1..k {
                    bytes.splice(i..i, run.iter().copied());
                }
            }
            Mutation::Truncate(f) => {
                let i = at(f, bytes.len());
                bytes.truncate(i);
            }
        }
    }
    bytes
}

/// Runs `test` on `cases` inputs drawn from `strategy` (proptest's runner, its failures
/// shrunk and reported as usual).
fn check<S: Strategy>(cases: u32, strategy: S, test: impl Fn(S::Value)) {
    let mut runner = TestRunner::new(Config {
        cases,
        failure_persistence: None,
        ..Config::default()
    });
    runner
        .run(&strategy, |value| {
            test(value);
            Ok(())
        })
        .unwrap();
}

/// Cases per strategy.
const CASES: u32 = 2000;

/// The one test of this binary (see [`ALLOCATOR`]).
#[test]
fn every_input_is_an_error_or_a_valid_result_within_its_memory() {
    check(
        CASES,
        (
            prop::collection::vec(any::<u8>(), 0..2000),
            prop::sample::select(CloudFormat::ALL.to_vec()),
        ),
        |(bytes, format)| read_cloud_checked("random bytes", &bytes, format),
    );
    check(
        CASES,
        (0usize..8, prop::collection::vec(mutation(), 1..6)),
        |(which, mutations)| {
            let (format, bytes) = seeds().swap_remove(which);
            read_cloud_checked("mutated file", &mutate(bytes, &mutations), format);
        },
    );
    check(
        CASES,
        (0usize..5, prop::collection::vec(mutation(), 1..6)),
        |(which, mutations)| {
            let bytes = mutate(scene_seeds().swap_remove(which), &mutations);
            read_scene_checked("mutated scene", &bytes);
        },
    );
    check(
        CASES,
        prop::collection::vec(any::<u8>(), 0..2000),
        |bytes| {
            let mut with_magic = SNAPSHOT_MAGIC.to_vec();
            with_magic.extend(&bytes);
            for input in [&bytes, &with_magic] {
                let _ = bounded("random snapshot", input, Snapshot::from_bytes);
            }
        },
    );
    absurd_headers_in_every_format();
    deep_nesting_and_huge_numbers_in_scenes();
}

fn absurd_headers_in_every_format() {
    let huge = "1000000000000";
    let cases: Vec<(CloudFormat, String)> = vec![
        (CloudFormat::Ply, format!("ply\nformat ascii 1.0\nelement vertex {huge}\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n")),
        (CloudFormat::Ply, format!("ply\nformat binary_little_endian 1.0\nelement vertex {huge}\nproperty double x\nproperty double y\nproperty double z\nend_header\n")),
        (CloudFormat::Ply, "ply\nformat ascii 1.0\nelement vertex 1\nproperty list uint uint x\nend_header\n4000000000 1\n".to_owned()),
        (CloudFormat::Ply, format!("ply\nformat ascii 1.0\n{}end_header\n", "element e 1\nproperty float p\n".repeat(5000))),
        (CloudFormat::Ply, format!("ply\nformat ascii 1.0\ncomment {}\nend_header\n", "x".repeat(100_000))),
        (CloudFormat::Off, format!("OFF\n{huge} {huge} 0\n0 0 0\n")),
        (CloudFormat::Off, "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n4000000000 0 1 2\n".to_owned()),
        (CloudFormat::Obj, format!("v 0 0 0\nf {huge} -{huge} 1\n")),
        (CloudFormat::Xyz, "1 2 3 4 5 6 7 8 9 10 11 12 13 14 15\n".repeat(1000)),
        (CloudFormat::Xyz, format!("{} 0 0\n", "9".repeat(100_000))),
    ];
    for (i, (format, text)) in cases.iter().enumerate() {
        read_cloud_checked(&format!("absurd header {i}"), text.as_bytes(), *format);
    }
}

fn deep_nesting_and_huge_numbers_in_scenes() {
    for text in [
        "(".repeat(100_000),
        "[".repeat(100_000),
        format!(
            "(cloud: \"a.ply\", dt: 0.01, steps: 1, pins: {}",
            "[".repeat(50_000)
        ),
        format!(
            "(cloud: \"a.ply\", dt: 0.01, steps: {})",
            "9".repeat(10_000)
        ),
        "(cloud: \"a.ply\", dt: 1e39, steps: 18446744073709551616)".to_owned(),
        format!("(cloud: \"{}\", dt: 0.01, steps: 1)", "a".repeat(1 << 20)),
        "(cloud: \"a.ply\", dt: 0.01, steps: 1, simplify: (target: Some(1000000000000)))"
            .to_owned(),
    ] {
        read_scene_checked("deep scene", text.as_bytes());
    }
}
