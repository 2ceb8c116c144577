//! Fuzz target: the OBJ reader.

fn main() {
    afl::fuzz!(|data: &[u8]| {
        bevy_point_springs_fuzz::cloud(data, bevy_point_springs::core::cloud::io::CloudFormat::Obj);
    });
}
