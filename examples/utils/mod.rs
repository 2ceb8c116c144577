//! Helpers shared by the examples: command-line options, a camera framing the scene, and the
//! `--screenshot PATH --frames N` mode used to check examples headless (under Xvfb).

use std::path::PathBuf;

use bevy::prelude::*;
use bevy::render::view::screenshot::{Screenshot, ScreenshotCaptured, save_to_disk};
use bevy::window::WindowResolution;

/// Window size of every example.
pub const WINDOW_SIZE: (u32, u32) = (1280, 720);

/// Frames rendered before the screenshot when `--screenshot` is given without `--frames`.
pub const DEFAULT_SCREENSHOT_FRAMES: u32 = 60;

/// Options every example understands.
#[derive(Resource, Debug, Clone, Default)]
pub struct DemoArgs {
    /// A point-cloud file to use instead of the example's default.
    pub file: Option<PathBuf>,
    /// Save a screenshot of the window here, then exit.
    pub screenshot: Option<PathBuf>,
    /// Exit after this many frames (with `--screenshot`: take it at that frame).
    pub frames: Option<u32>,
}

impl DemoArgs {
    /// Parses `[FILE] [--screenshot PATH] [--frames N]` from the process arguments.
    pub fn from_env() -> Self {
        let mut args = DemoArgs::default();
        let mut it = std::env::args().skip(1);
        while let Some(arg) = it.next() {
            match arg.as_str() {
                "--screenshot" => args.screenshot = it.next().map(PathBuf::from),
                "--frames" => args.frames = it.next().and_then(|n| n.parse().ok()),
                "-h" | "--help" => {
                    println!("options: [FILE] [--screenshot PATH.png] [--frames N]");
                    std::process::exit(0);
                }
                other => args.file = Some(PathBuf::from(other)),
            }
        }
        args
    }
}

/// Window, screenshot-and-exit handling, lighting. Add it instead of `DefaultPlugins`.
pub struct DemoPlugin {
    /// Window title.
    pub title: &'static str,
    /// Parsed options.
    pub args: DemoArgs,
}

impl Plugin for DemoPlugin {
    fn build(&self, app: &mut App) {
        app.add_plugins(DefaultPlugins.set(WindowPlugin {
            primary_window: Some(Window {
                title: self.title.into(),
                resolution: WindowResolution::from(WINDOW_SIZE),
                ..default()
            }),
            ..default()
        }))
        .insert_resource(self.args.clone())
        .insert_resource(ClearColor(Color::srgb(0.11, 0.12, 0.14)))
        .insert_resource(GlobalAmbientLight {
            brightness: 300.0,
            ..default()
        })
        .add_systems(Update, screenshot_and_exit);
    }
}

/// Spawns a camera looking at a box of `center` and `diagonal`, and a light over its shoulder.
pub fn spawn_camera_and_light(commands: &mut Commands, center: Vec3, diagonal: f32) {
    let eye = center + Vec3::new(0.55, 0.45, 1.0).normalize() * diagonal * 1.1;
    commands.spawn((
        Camera3d::default(),
        Transform::from_translation(eye).looking_at(center, Vec3::Y),
    ));
    commands.spawn((
        DirectionalLight {
            illuminance: 8_000.0,
            ..default()
        },
        Transform::from_translation(eye + Vec3::new(diagonal, diagonal, 0.0))
            .looking_at(center, Vec3::Y),
    ));
}

fn screenshot_and_exit(
    mut commands: Commands,
    args: Res<DemoArgs>,
    mut frame: Local<u32>,
    mut exit: MessageWriter<AppExit>,
) {
    *frame += 1;
    match (&args.screenshot, args.frames) {
        (Some(path), frames) if *frame == frames.unwrap_or(DEFAULT_SCREENSHOT_FRAMES) => {
            commands
                .spawn(Screenshot::primary_window())
                .observe(save_to_disk(path.clone()))
                .observe(
                    |_: On<ScreenshotCaptured>, mut exit: MessageWriter<AppExit>| {
                        exit.write(AppExit::Success);
                    },
                );
        }
        (None, Some(frames)) if *frame >= frames => {
            exit.write(AppExit::Success);
        }
        _ => {}
    }
}
