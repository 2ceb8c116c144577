//! Fuzz target: scene files (RON), parsed and validated.

use bevy_point_springs::core::scene::Scene;

fn main() {
    afl::fuzz!(|data: &[u8]| {
        if let Ok(text) = std::str::from_utf8(data)
            && let Ok(scene) = Scene::from_ron(text)
        {
            let _ = scene.validate();
        }
    });
}
