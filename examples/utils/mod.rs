//! Helpers shared by the examples: command-line options, an orbit camera, keys for the
//! simulation, and the `--screenshot PATH --frames N` mode used to check examples headless
//! (under Xvfb).
//!
//! With `--frames N` time advances by whole fixed ticks (1/60 s) per rendered frame, and
//! ticks are counted from the moment every surface is prepared (and held at rest for a
//! warm-up while the renderer compiles its pipelines), so frame N — the frame after tick
//! N — shows the same moment of the simulation on every machine however slow its renderer
//! or its preparation. Far from tick N a frame takes [`FAST_FORWARD_TICKS`] ticks, so a
//! software renderer draws a tenth of the frames; the last ones take one tick each.
//!
//! `--frame-rate HZ` renders the script at another rate than the ticks': each frame then
//! advances 1/HZ s, and frame N is the frame at N/HZ s (at 144 Hz most frames fall between
//! two ticks, at 30 Hz every frame takes two).

use std::path::PathBuf;
use std::time::Duration;

use bevy::input::mouse::{AccumulatedMouseMotion, AccumulatedMouseScroll, MouseScrollUnit};
use bevy::prelude::*;
use bevy::render::view::screenshot::{Screenshot, ScreenshotCaptured};
use bevy::time::TimeUpdateStrategy;
use bevy::window::{PrimaryWindow, WindowResolution};
use bevy_point_springs::core::cloud::io::write_atomically_to_path;
#[cfg(feature = "egui")]
use bevy_point_springs::plugin::panel::PointSpringsPanelPlugin;
use bevy_point_springs::plugin::render::{SpringGizmos, TransferDevice};
use bevy_point_springs::plugin::{PreparationProgress, SceneTimeline, TransferTiming};
use bevy_point_springs::prelude::*;

/// Window size of every example.
pub const WINDOW_SIZE: (u32, u32) = (1280, 720);

/// Frames rendered (after preparation) before the screenshot when `--screenshot` is given
/// without `--frames`.
pub const DEFAULT_SCREENSHOT_FRAMES: u32 = 60;

/// Scripted runs hold the prepared surfaces still for this many frames before counting,
/// so that the renderer has compiled its pipelines (the first frames draw nothing).
pub const WARMUP_FRAMES: u32 = 30;

/// Ticks a scripted frame takes while the screenshot is still more than this many ticks
/// away (then one tick a frame). At most 15: Bevy's virtual clock takes at most 250 ms a
/// frame.
pub const FAST_FORWARD_TICKS: u32 = 10;

/// The fixed tick of the examples: the shipped scenes' step.
pub const TICK_HZ: f64 = 60.0;

/// The slowest `--frame-rate` (Bevy's virtual clock takes at most 250 ms a frame).
const MIN_FRAME_RATE: f64 = 5.0;

/// Radians of orbit per pixel of mouse motion.
const ORBIT_SPEED: f32 = 0.006;

/// Fraction of the distance zoomed per scroll line.
const ZOOM_STEP: f32 = 0.1;

/// Options every example understands.
#[derive(Resource, Debug, Clone, Default)]
pub struct DemoArgs {
    /// A file to use instead of the example's default.
    pub file: Option<PathBuf>,
    /// Save a screenshot of the window here, then exit.
    pub screenshot: Option<PathBuf>,
    /// Exit after this many frames once every surface is prepared (with `--screenshot`:
    /// take it at that frame); time advances one tick per frame, or 1/`frame_rate` s.
    pub frames: Option<u32>,
    /// Window size, pixels (default [`WINDOW_SIZE`]).
    pub size: Option<(u32, u32)>,
    /// Start with the simulation points and springs shown.
    pub gizmos: bool,
    /// Leave the live panel out (a clean picture of the scene).
    pub no_panel: bool,
    /// Frames a second of a scripted run (default: one a tick, [`TICK_HZ`]).
    pub frame_rate: Option<f64>,
    /// Draw each tick's state as it ends instead of interpolating between ticks.
    pub no_interpolation: bool,
    /// Where the surfaces' transfer runs for drawing (`--transfer-on cpu|gpu|auto`).
    pub transfer_on: Option<TransferDevice>,
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
                "--gizmos" => args.gizmos = true,
                "--no-panel" => args.no_panel = true,
                "--no-interpolation" => args.no_interpolation = true,
                "--transfer-on" => {
                    args.transfer_on = match it.next().as_deref() {
                        Some("cpu") => Some(TransferDevice::Cpu),
                        Some("gpu") => Some(TransferDevice::Gpu),
                        Some("auto") => Some(TransferDevice::Auto),
                        other => panic!("--transfer-on takes cpu, gpu or auto, not {other:?}"),
                    };
                }
                "--frame-rate" => {
                    args.frame_rate = it
                        .next()
                        .and_then(|r| r.parse().ok())
                        .filter(|r: &f64| r.is_finite() && *r >= MIN_FRAME_RATE);
                }
                "--size" => {
                    args.size = it.next().and_then(|s| {
                        let (w, h) = s.split_once('x')?;
                        Some((w.parse().ok()?, h.parse().ok()?))
                    });
                }
                "-h" | "--help" => {
                    println!(
                        "options: [FILE] [--screenshot PATH.png] [--frames N] [--frame-rate HZ] [--size WxH] [--gizmos] [--no-panel] [--no-interpolation] [--transfer-on cpu|gpu|auto]"
                    );
                    println!(
                        "mouse: left-drag pokes and pulls a surface, right-drag orbits, wheel zooms"
                    );
                    println!(
                        "keys: space pauses, G cycles the spring gizmos, I switches interpolation between ticks, R restarts"
                    );
                    std::process::exit(0);
                }
                other => args.file = Some(PathBuf::from(other)),
            }
        }
        args
    }

    /// Whether the run is scripted (fixed time per frame, then exit).
    pub fn scripted(&self) -> bool {
        self.frames.is_some() || self.screenshot.is_some()
    }

    /// A scripted frame's time: [`TICK_HZ`]'s tick, or the `--frame-rate`'s period (a whole
    /// number of ticks where the rate divides the ticks', so that those frames land on
    /// ticks exactly).
    fn frame_period(&self) -> Duration {
        let tick = Duration::from_secs_f64(1.0 / TICK_HZ);
        let Some(rate) = self.frame_rate else {
            return tick;
        };
        let ticks = TICK_HZ / rate;
        if ticks.fract() == 0.0 {
            tick * ticks as u32
        } else {
            Duration::from_secs_f64(1.0 / rate)
        }
    }

    /// Frames a fast-forwarding scripted frame takes: [`FAST_FORWARD_TICKS`] ticks' worth.
    fn fast_forward_frames(&self) -> u32 {
        let rate = self.frame_rate.unwrap_or(TICK_HZ);
        ((f64::from(FAST_FORWARD_TICKS) * rate / TICK_HZ).floor() as u32).max(1)
    }
}

/// Window, lighting, the plugin with drawing and mouse grabs, the orbit camera, keys, and the
/// screenshot-and-exit mode. Add it instead of `DefaultPlugins`.
pub struct DemoPlugin {
    /// Window title.
    pub title: &'static str,
    /// Parsed options.
    pub args: DemoArgs,
    /// Show the live panel (built with the `egui` feature; without it, a note in the log).
    pub panel: bool,
}

impl Plugin for DemoPlugin {
    fn build(&self, app: &mut App) {
        let show_panel = self.panel && !self.args.no_panel;
        let plugins = PointSpringsPlugins::default().build();
        #[cfg(feature = "egui")]
        let plugins = if show_panel {
            plugins
        } else {
            plugins.disable::<PointSpringsPanelPlugin>()
        };
        app.add_plugins((
            DefaultPlugins.set(WindowPlugin {
                primary_window: Some(Window {
                    title: self.title.into(),
                    resolution: WindowResolution::from(self.args.size.unwrap_or(WINDOW_SIZE)),
                    ..default()
                }),
                ..default()
            }),
            plugins,
        ))
        .insert_resource(self.args.clone())
        .insert_resource(Time::<Fixed>::from_hz(TICK_HZ))
        .insert_resource(ClearColor(Color::srgb(0.11, 0.12, 0.14)))
        .insert_resource(GlobalAmbientLight {
            brightness: 300.0,
            ..default()
        })
        .init_resource::<FramesSinceReady>()
        .init_resource::<ScriptStarted>()
        .add_systems(FixedFirst, count_ticks)
        .add_systems(
            Update,
            (orbit_camera, keys, show_status, screenshot_and_exit),
        );
        if self.args.no_interpolation {
            app.add_systems(PostUpdate, draw_ticks_as_they_end);
        }
        if let Some(device) = self.args.transfer_on {
            app.add_systems(
                Update,
                move |mut surfaces: Query<&mut SurfelRender, Added<SurfelRender>>| {
                    for mut render in &mut surfaces {
                        render.device = device;
                    }
                },
            );
        }
        if show_panel {
            add_panel(app);
        }
        if self.args.gizmos {
            app.insert_resource(SpringGizmos {
                points: true,
                stretch: true,
                bend: true,
                hinges: true,
            });
        }
        if self.args.scripted() {
            // Exactly one tick per frame.
            app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f64(
                1.0 / TICK_HZ,
            )));
        }
    }
}

/// The live panel (in the plugin group); input over it (drags, scrolls) is the panel's,
/// not the scene's.
#[cfg(feature = "egui")]
fn add_panel(app: &mut App) {
    app.insert_resource(bevy_egui::EguiGlobalSettings {
        enable_absorb_bevy_input_system: true,
        ..default()
    });
}

#[cfg(not(feature = "egui"))]
fn add_panel(_app: &mut App) {
    info!("the live panel needs the `egui` feature: cargo run --features egui,...");
}

/// The material of the props around a surface (the cup, the ring).
#[allow(
    dead_code,
    reason = "each example compiles its own copy of utils; view_cloud has no props"
)]
pub fn prop_material() -> StandardMaterial {
    StandardMaterial {
        base_color: Color::srgb(0.35, 0.38, 0.45),
        perceptual_roughness: 0.5,
        ..default()
    }
}

/// A camera orbiting `target`: right-drag turns it, the wheel zooms.
#[derive(Component, Debug, Clone, Copy)]
pub struct OrbitCamera {
    /// The point looked at.
    pub target: Vec3,
    /// Distance from it.
    pub distance: f32,
    /// Turn about the vertical, radians.
    pub yaw: f32,
    /// Elevation, radians.
    pub pitch: f32,
}

impl OrbitCamera {
    /// Where the camera is for this orbit.
    pub fn transform(&self) -> Transform {
        let rotation = Quat::from_euler(EulerRot::YXZ, self.yaw, -self.pitch, 0.0);
        let eye = self.target + rotation * Vec3::Z * self.distance;
        Transform::from_translation(eye).looking_at(self.target, Vec3::Y)
    }
}

/// Spawns an orbit camera looking at `target` from `distance` (yaw and pitch in radians),
/// and a light over its shoulder.
pub fn spawn_camera_and_light(
    commands: &mut Commands,
    target: Vec3,
    distance: f32,
    yaw: f32,
    pitch: f32,
) {
    let orbit = OrbitCamera {
        target,
        distance,
        yaw,
        pitch,
    };
    let transform = orbit.transform();
    commands.spawn((Camera3d::default(), transform, orbit));
    let eye = transform.translation;
    commands.spawn((
        DirectionalLight {
            illuminance: 8_000.0,
            shadow_maps_enabled: true,
            ..default()
        },
        Transform::from_translation(eye + Vec3::new(distance, distance, 0.0))
            .looking_at(target, Vec3::Y),
    ));
}

fn orbit_camera(
    buttons: Res<ButtonInput<MouseButton>>,
    motion: Res<AccumulatedMouseMotion>,
    scroll: Res<AccumulatedMouseScroll>,
    mut cameras: Query<(&mut Transform, &mut OrbitCamera)>,
) {
    let turn = if buttons.pressed(MouseButton::Right) {
        motion.delta * ORBIT_SPEED
    } else {
        Vec2::ZERO
    };
    let lines = match scroll.unit {
        MouseScrollUnit::Line => scroll.delta.y,
        MouseScrollUnit::Pixel => scroll.delta.y / 40.0,
    };
    if turn == Vec2::ZERO && lines == 0.0 {
        return;
    }
    for (mut transform, mut orbit) in &mut cameras {
        orbit.yaw -= turn.x;
        orbit.pitch = (orbit.pitch + turn.y).clamp(-1.5, 1.5);
        orbit.distance *= (1.0 - ZOOM_STEP).powf(lines);
        *transform = orbit.transform();
    }
}

/// Space pauses, G cycles the gizmos (none, points, points and springs), R puts every
/// ready surface back in its rest shape (a scene's timeline from its start).
fn keys(
    keyboard: Res<ButtonInput<KeyCode>>,
    mut gizmos: ResMut<SpringGizmos>,
    mut surfaces: Query<(Entity, &mut SurfaceRunSettings, &SurfaceStatus)>,
    mut model: MessageWriter<ModelMessage>,
) {
    if keyboard.just_pressed(KeyCode::KeyG) {
        *gizmos = match (gizmos.points, gizmos.stretch) {
            (false, _) => SpringGizmos {
                points: true,
                ..default()
            },
            (true, false) => SpringGizmos {
                points: true,
                stretch: true,
                bend: true,
                hinges: true,
            },
            (true, true) => SpringGizmos::default(),
        };
    }
    for (surface, mut settings, status) in &mut surfaces {
        if keyboard.just_pressed(KeyCode::Space) {
            settings.paused = !settings.paused;
        }
        if keyboard.just_pressed(KeyCode::KeyR) && status.is_ready() {
            model.write(ModelMessage::Reset { surface });
        }
        if keyboard.just_pressed(KeyCode::KeyI) {
            settings.transfer = match settings.transfer {
                TransferTiming::Interpolated => TransferTiming::EveryTick,
                _ => TransferTiming::Interpolated,
            };
            info!("transfer: {:?}", settings.transfer);
        }
    }
}

/// `--no-interpolation`: new surfaces show each tick's state as it ends.
fn draw_ticks_as_they_end(mut surfaces: Query<&mut SurfaceRunSettings, Added<SurfaceRunSettings>>) {
    for mut settings in &mut surfaces {
        settings.transfer = TransferTiming::EveryTick;
    }
}

/// What the window title shows of a surface.
type SurfaceReport = (
    &'static SurfaceStatus,
    Option<&'static PreparationProgress>,
    Option<&'static SceneTimeline>,
    Option<&'static DenseSurface>,
);

/// The window title says what the surfaces are doing.
fn show_status(
    args: Res<DemoArgs>,
    mut windows: Query<&mut Window, With<PrimaryWindow>>,
    surfaces: Query<SurfaceReport>,
    mut last: Local<String>,
) {
    let mut parts = Vec::new();
    for (status, progress, timeline, dense) in &surfaces {
        parts.push(match (status, progress) {
            (SurfaceStatus::Preparing, Some(p)) => {
                format!("preparing: {} {:.0}%", p.stage, 100.0 * p.fraction)
            }
            (SurfaceStatus::Ready, _) => {
                let step = timeline.map_or(String::new(), |t| {
                    format!("step {} of {}, ", t.step(), t.steps())
                });
                let points = dense.map_or(0, |d| d.len());
                format!("{step}{points} surfels")
            }
            (SurfaceStatus::Failed(message), _) => format!("failed: {message}"),
            (other, _) => format!("{other:?}").to_lowercase(),
        });
    }
    let text = parts.join(" | ");
    if *last != text {
        if let Ok(mut window) = windows.single_mut() {
            let title = window
                .title
                .split(" — ")
                .take(2)
                .collect::<Vec<_>>()
                .join(" — ");
            window.title = format!("{title} — {text}");
        }
        if args.scripted() {
            info!("{text}");
        }
        *last = text;
    }
}

/// A screenshot with less of it differing from the background than this counts as blank.
const MIN_DRAWN_FRACTION: f32 = 0.02;

/// The fraction of an image's pixels that differ from its corner pixel (the background).
fn drawn_fraction(image: &Image) -> f32 {
    let Some(data) = image.data.as_deref() else {
        return 0.0;
    };
    let pixels: Vec<&[u8]> = data.chunks_exact(4).collect();
    let Some(&corner) = pixels.first() else {
        return 0.0;
    };
    let drawn = pixels.iter().filter(|&&p| p != corner).count();
    drawn as f32 / pixels.len() as f32
}

/// Fixed ticks run since every surface was prepared and the warm-up ended (none before:
/// scripts act on the tick this reaches their number, in `FixedUpdate`).
#[derive(Resource, Debug, Default)]
pub struct FramesSinceReady(pub Option<u32>);

/// Counts the ticks of a scripted run once its surfaces run.
fn count_ticks(
    args: Res<DemoArgs>,
    mut ticks: ResMut<FramesSinceReady>,
    started: Res<ScriptStarted>,
) {
    if args.scripted() && started.0 {
        *ticks.0.get_or_insert(0) += 1;
    }
}

/// The warm-up is over and the surfaces run.
#[derive(Resource, Debug, Default)]
struct ScriptStarted(bool);

/// A scripted run's frames (of `--frame-rate`'s period) since its start.
#[derive(Debug, Default)]
struct FrameCount {
    /// Frames whose time has passed.
    done: u32,
    /// Frames the next time update takes.
    pending: u32,
}

#[allow(clippy::too_many_arguments)]
fn screenshot_and_exit(
    mut commands: Commands,
    args: Res<DemoArgs>,
    ticks: Res<FramesSinceReady>,
    fixed: Res<Time<Fixed>>,
    mut virtual_time: ResMut<Time<Virtual>>,
    mut started: ResMut<ScriptStarted>,
    mut clock: ResMut<TimeUpdateStrategy>,
    mut surfaces: Query<(&SurfaceStatus, &mut SurfaceRunSettings)>,
    mut warmup: Local<u32>,
    mut frames: Local<FrameCount>,
    mut shot: Local<bool>,
    mut exit: MessageWriter<AppExit>,
) {
    if !args.scripted() || *shot {
        return;
    }
    let prepared = !surfaces.is_empty()
        && surfaces
            .iter()
            .all(|(s, _)| matches!(s, SurfaceStatus::Ready | SurfaceStatus::Failed(_)));
    if prepared && !started.0 {
        let failed: Vec<String> = surfaces
            .iter()
            .filter_map(|(s, _)| match s {
                SurfaceStatus::Failed(why) => Some(why.to_string()),
                _ => None,
            })
            .collect();
        if !failed.is_empty() {
            // A scripted run checks the example; a surface that did not load fails it.
            error!("a surface failed: {}", failed.join("; "));
            exit.write(AppExit::error());
            return;
        }
    }
    let target = args.frames.unwrap_or(DEFAULT_SCREENSHOT_FRAMES);
    if !started.0 {
        // Held still until prepared, then at rest while the renderer warms up.
        if prepared {
            *warmup += 1;
        }
        let running = prepared && *warmup >= WARMUP_FRAMES;
        for (_, mut settings) in &mut surfaces {
            settings.paused = !running;
        }
        started.0 = running;
        if running {
            // The next frame is the script's first.
            frames.pending = 1;
            *clock = TimeUpdateStrategy::ManualDuration(args.frame_period());
        }
        return;
    }
    // This frame's time update took the frames asked for last frame.
    frames.done += frames.pending;
    let left = target.saturating_sub(frames.done);
    if left > 0 {
        // The next frame's: many while the screenshot is far, then one at a time.
        let fast = args.fast_forward_frames();
        frames.pending = if left > fast { fast } else { 1 };
        *clock = TimeUpdateStrategy::ManualDuration(args.frame_period() * frames.pending);
        return;
    }
    *shot = true;
    info!(
        "frame {}: after tick {}, {:.3} of the way to the next",
        frames.done,
        ticks.0.unwrap_or(0),
        fixed.overstep_fraction()
    );
    match &args.screenshot {
        Some(path) => {
            commands
                .spawn(Screenshot::primary_window())
                .observe(save_atomically(path.clone()))
                .observe(
                    |captured: On<ScreenshotCaptured>, mut exit: MessageWriter<AppExit>| {
                        let drawn = drawn_fraction(&captured);
                        if drawn < MIN_DRAWN_FRACTION {
                            error!("the screenshot is blank: {:.2} % drawn", 100.0 * drawn);
                            exit.write(AppExit::error());
                        } else {
                            info!("{:.1} % of the screenshot drawn", 100.0 * drawn);
                            exit.write(AppExit::Success);
                        }
                    },
                );
            // Time stands still while the capture is under way (it takes a frame or two):
            // no more ticks, and the frame's place between two ticks stays.
            virtual_time.pause();
        }
        None => {
            exit.write(AppExit::Success);
        }
    }
}

/// Saves a screenshot to `path` as Bevy's `save_to_disk` does (RGB, the format from the
/// extension), but like every file the project writes: to a temporary file in the same
/// folder, renamed into place once complete.
fn save_atomically(path: PathBuf) -> impl FnMut(On<ScreenshotCaptured>) {
    move |captured| {
        let saved = captured
            .image
            .clone()
            .try_into_dynamic()
            .map_err(|e| e.to_string())
            .and_then(|image| {
                write_atomically_to_path(&path, |tmp| Ok(image.to_rgb8().save(tmp)?))
                    .map_err(|e| e.to_string())
            });
        match saved {
            Ok(()) => info!("screenshot saved to {}", path.display()),
            Err(e) => error!("cannot save the screenshot to {}: {e}", path.display()),
        }
    }
}
