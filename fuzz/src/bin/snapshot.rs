//! Fuzz target: snapshot files, decoded.

use bevy_point_springs::core::scene::Snapshot;

fn main() {
    afl::fuzz!(|data: &[u8]| {
        let _ = Snapshot::from_bytes(data);
    });
}
