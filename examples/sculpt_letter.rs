//! The paper's Fig. 7: sculpting the letter "B". A flat "B" sheet of a plastic material,
//! its stem held; drag it with the mouse and it keeps the shape you pulled.
//!
//! ```sh
//! cargo run --release --features egui --example sculpt_letter
//! cargo run --release --features egui --example sculpt_letter -- --screenshot letter.png --frames 240
//! ```
//!
//! The scene (`assets/scenes/sculpt_letter.ron`) simplifies the 3300-point letter to 300
//! simulation points with a yield strain of 2 % and a creep rate of 4 per second: strain
//! beyond yield becomes rest length, so a drag held for a second stays. The panel tunes the
//! material live, bakes the shape (it becomes the rest shape) and exports the dense surface
//! to PLY; B and E do the same from the keyboard (`sculpted_letter.ply`). Left-drag
//! sculpts, right-drag orbits, the wheel zooms, G shows the simulation points and springs.
//!
//! With `--screenshot` (or `--frames`) a scripted hand pulls the upper bowl's edge, then the
//! lower one's, out of the plane and lets go; the screenshot shows what stayed.

mod utils;

use bevy::prelude::*;
use bevy_point_springs::prelude::*;
use utils::{DemoArgs, DemoPlugin, FramesSinceReady, spawn_camera_and_light};

/// Where the keyboard's E exports the sculpted surface.
const EXPORT_PATH: &str = "sculpted_letter.ply";

/// The grab key of the scripted hand.
const SCRIPT_KEY: u64 = 1_000;

/// One scripted drag: where it takes hold, how far it pulls, and its frames (start, end of
/// the pull, release).
struct Drag {
    at: Vec3,
    pull: Vec3,
    frames: (u32, u32, u32),
}

/// The scripted hand: the upper bowl's edge out of the plane, then the lower one's.
const DRAGS: [Drag; 2] = [
    Drag {
        at: Vec3::new(0.5, 0.52, 0.0),
        pull: Vec3::new(-0.1, 0.05, 0.6),
        frames: (1, 60, 90),
    },
    Drag {
        at: Vec3::new(0.55, -0.47, 0.0),
        pull: Vec3::new(-0.1, -0.05, -0.45),
        frames: (100, 160, 190),
    },
];

fn main() -> AppExit {
    let args = DemoArgs::from_env();
    let scripted = args.scripted();
    let mut app = App::new();
    app.add_plugins(DemoPlugin {
        title: "bevy_point_springs — sculpt_letter",
        args,
        panel: true,
    })
    .add_systems(Startup, setup)
    .add_systems(Update, (bake_and_export_keys, report_outcomes));
    app.insert_resource(SurfacePanel {
        export_path: EXPORT_PATH.to_owned(),
        ..default()
    });
    if scripted {
        app.add_systems(
            FixedUpdate,
            scripted_hand.before(PointSpringsSystems::Forces),
        );
    }
    app.run()
}

fn setup(mut commands: Commands, assets: Res<AssetServer>) {
    commands.spawn((
        Name::new("letter B"),
        DeformableSurface::scene(assets.load("scenes/sculpt_letter.ron")),
        SurfelRender {
            color: Color::srgb(0.86, 0.45, 0.32),
            ..default()
        },
    ));
    spawn_camera_and_light(&mut commands, Vec3::new(-0.55, 0.0, 0.1), 3.6, 0.55, 0.45);
}

/// B bakes the current shape into the rest shape; E exports the dense surface.
fn bake_and_export_keys(
    keyboard: Res<ButtonInput<KeyCode>>,
    surfaces: Query<Entity, With<DeformableSurface>>,
    mut requests: MessageWriter<ModelMessage>,
) {
    for surface in &surfaces {
        if keyboard.just_pressed(KeyCode::KeyB) {
            requests.write(ModelMessage::Bake { surface });
        }
        if keyboard.just_pressed(KeyCode::KeyE) {
            requests.write(ModelMessage::Export {
                surface,
                path: EXPORT_PATH.into(),
            });
        }
    }
}

/// Bakes and exports say in the log how they went.
fn report_outcomes(mut outcomes: MessageReader<ModelOutcome>) {
    for outcome in outcomes.read() {
        match &outcome.result {
            Ok(()) => info!("{:?}: done", outcome.request),
            Err(e) => error!("{:?}: {e}", outcome.request),
        }
    }
}

/// The scripted drags, tick by tick, then a bake.
fn scripted_hand(
    frames: Res<FramesSinceReady>,
    surfaces: Query<Entity, With<DeformableSurface>>,
    mut grabs: MessageWriter<GrabMessage>,
    mut requests: MessageWriter<ModelMessage>,
) {
    let (Some(frame), Ok(surface)) = (frames.0, surfaces.single()) else {
        return;
    };
    for drag in &DRAGS {
        let (start, end, release) = drag.frames;
        if frame == start {
            grabs.write(GrabMessage::Start {
                key: SCRIPT_KEY,
                surface,
                at: drag.at,
            });
        }
        if (start..=end).contains(&frame) {
            let t = (frame - start) as f32 / (end - start) as f32;
            grabs.write(GrabMessage::Move {
                key: SCRIPT_KEY,
                target: drag.at + t * drag.pull,
            });
        }
        if frame == release {
            grabs.write(GrabMessage::End { key: SCRIPT_KEY });
        }
    }
    // Once both bowls have settled: the shape becomes the rest shape.
    if frame == DRAGS[1].frames.2 + 30 {
        requests.write(ModelMessage::Bake { surface });
    }
}
