//! `point-springs-bench plugin`: the Bevy plugin run headless (one fixed tick per update)
//! against the same work done by the core alone, measured in the same run.
//!
//! The ECS tick is timed by marker systems ordered between the plugin's chained sets, so
//! its figures include the scheduler's own cost: forces (timeline, springs, gravity,
//! anchors, drag, pressure), stepping, transfer. The surfel upload is timed as the renderer
//! does it on the CPU (packing the dense surface into the storage buffer's bytes and
//! handing over a copy); the copy to the GPU itself needs a GPU and is not measured. The
//! core runs the same scene from the same prepared state; ECS and core alternate in blocks
//! of ticks, and their dense surfaces are compared bit for bit at the end.

use std::fmt;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

use bevy::ecs::schedule::SingleThreadedExecutor;
use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy_point_springs::core::PointCloud;
use bevy_point_springs::core::cloud::io::read_cloud;
use bevy_point_springs::core::cloud::surfels::{
    DEFAULT_SURFEL_SCALE, SURFEL_BYTES, SurfelShape, pack_surfels,
};
use bevy_point_springs::core::pipeline::{DenseCloud, PreparedSurface};
use bevy_point_springs::core::scene::{Scene, Timeline};
use bevy_point_springs::prelude::{
    DeformableSurface, DenseSurface, PointSpringsPlugin, PointSpringsSystems, SurfaceStatus,
};
use serde::Serialize;

use crate::args::BendingArg;
use crate::failure::Failure;
use crate::flags::JsonFlag;
use crate::poke::poked_sphere;
use crate::report::Report;

/// Arguments of `point-springs-bench plugin`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// A scene file (default: a generated sphere with a sustained poke).
    scene: Option<PathBuf>,
    /// Dense points of the generated sphere.
    #[arg(long, default_value_t = 3203)]
    dense: usize,
    /// Simulation points of the generated sphere.
    #[arg(long, default_value_t = 338)]
    sim: usize,
    /// Ticks timed (each of the ECS and of the core).
    #[arg(long, default_value_t = 300)]
    ticks: usize,
    /// Ticks per block (the ECS and the core alternate in blocks).
    #[arg(long, default_value_t = 30)]
    block: usize,
    /// Run the fixed schedule on Bevy's single-threaded executor instead of the
    /// multi-threaded default (less dispatch cost per system when one surface is stepped).
    #[arg(long)]
    single_threaded: bool,
    /// The bending model, in place of the scene's (its bend springs, or hinges).
    #[arg(long, value_enum)]
    bending: Option<BendingArg>,
    #[command(flatten)]
    json: JsonFlag,
}

/// Largest dense cloud the generated scene takes.
const MAX_DENSE: usize = 5_000_000;

/// Upper bound on waiting for the ECS preparation (a hang guard).
const PREPARE_TIMEOUT: Duration = Duration::from_secs(600);

/// What `point-springs-bench plugin` reports (times in ms, means over the timed ticks).
#[derive(Debug, Serialize)]
struct PluginReport {
    /// The scene file, or the generated sphere.
    scene: String,
    /// Bevy's executor of the fixed schedule.
    executor: &'static str,
    /// Dense points.
    dense_points: usize,
    /// Simulation points.
    sim_points: usize,
    /// Springs.
    springs: usize,
    /// Hinges (bending; 0 with bend springs).
    hinges: usize,
    /// Points bending on their fitted curvature (0 with another model).
    curvatures: usize,
    /// The integrator.
    integrator: String,
    /// Ticks timed.
    ticks: usize,
    /// The ECS's preparation (in the background).
    ms_prepare: f64,
    /// The ECS's forces per tick.
    ms_forces: f64,
    /// Its stepping per tick.
    ms_stepping: f64,
    /// Its transfer per tick.
    ms_transfer: f64,
    /// The three together.
    ms_tick: f64,
    /// Packing the surfels for the upload, per frame.
    ms_upload: f64,
    /// Tick and upload.
    ms_frame: f64,
    /// The core's tick.
    ms_core_tick: f64,
    /// ECS tick / core tick.
    ecs_over_core: f64,
    /// The core's solver: CG iterations a step, over every step it took.
    cg_per_step: f64,
    /// Whether the ECS's and the core's dense surfaces are the same, bit for bit.
    identical: bool,
}

impl fmt::Display for PluginReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "scene        {} ({} dense, {} simulation points, {} springs, {} hinges, {} curvatures, {}; {} executor)",
            self.scene,
            self.dense_points,
            self.sim_points,
            self.springs,
            self.hinges,
            self.curvatures,
            self.integrator,
            self.executor
        )?;
        writeln!(
            f,
            "prepare      {:.1} ms (in the background)",
            self.ms_prepare
        )?;
        writeln!(
            f,
            "ECS tick     {:.3} ms = forces {:.3} + stepping {:.3} + transfer {:.3} (mean of {})",
            self.ms_tick, self.ms_forces, self.ms_stepping, self.ms_transfer, self.ticks
        )?;
        writeln!(
            f,
            "upload       {:.3} ms (packing the surfels, CPU side); frame {:.3} ms",
            self.ms_upload, self.ms_frame
        )?;
        writeln!(
            f,
            "core tick    {:.3} ms (the same work without the ECS): ECS / core = {:.3}",
            self.ms_core_tick, self.ecs_over_core
        )?;
        writeln!(
            f,
            "solver       {:.1} CG iterations a step",
            self.cg_per_step
        )?;
        writeln!(f, "identical    {}", self.identical)
    }
}

impl Report for PluginReport {}

/// Marker times of the current tick, and the sums over timed ticks.
#[derive(Resource, Default)]
pub(super) struct Clock {
    /// When each marker system ran this tick.
    marks: [Option<Instant>; 4],
    /// Seconds of forces, stepping and transfer, summed over the timed ticks.
    pub(super) sums: [f64; 3],
    /// Ticks timed.
    pub(super) timed: usize,
    /// Whether ticks are being timed.
    pub(super) timing: bool,
}

/// Marker system `I` (0 to 3): notes the time; the last adds up the tick.
fn mark<const I: usize>(mut clock: ResMut<Clock>) {
    clock.marks[I] = Some(Instant::now());
    if I == 3
        && clock.timing
        && let [Some(a), Some(b), Some(c), Some(d)] = clock.marks
    {
        clock.sums[0] += (b - a).as_secs_f64();
        clock.sums[1] += (c - b).as_secs_f64();
        clock.sums[2] += (d - c).as_secs_f64();
        clock.timed += 1;
    }
}

/// A headless app with the plugin, ticking `dt` per update, and the marker systems.
pub(super) fn ecs_app(dt: f32, single_threaded: bool) -> App {
    let tick = Duration::from_secs_f64(f64::from(dt));
    let mut app = App::new();
    app.add_plugins((MinimalPlugins, PointSpringsPlugin::default()))
        .insert_resource(TimeUpdateStrategy::ManualDuration(tick))
        .insert_resource(Time::<Fixed>::from_duration(tick))
        .init_resource::<Clock>()
        .add_systems(
            FixedUpdate,
            (
                mark::<0>.before(PointSpringsSystems::Forces),
                mark::<1>
                    .after(PointSpringsSystems::Forces)
                    .before(PointSpringsSystems::Integrate),
                mark::<2>
                    .after(PointSpringsSystems::Integrate)
                    .before(PointSpringsSystems::Transfer),
                mark::<3>.after(PointSpringsSystems::Transfer),
            ),
        );
    if single_threaded {
        app.edit_schedule(FixedUpdate, |schedule| {
            schedule.set_executor(SingleThreadedExecutor::new());
        });
    }
    app.finish();
    app.cleanup();
    app.update();
    app
}

/// The core's run of the same scene.
struct CoreRun {
    /// The prepared surface.
    surface: PreparedSurface,
    /// The scene's pins and pulls over time.
    timeline: Timeline,
    /// The step, s.
    dt: f32,
}

impl CoreRun {
    /// One tick: as the plugin's systems do it.
    fn tick(&mut self) -> Result<(), Failure> {
        let s = &mut self.surface;
        self.timeline
            .advance(&mut s.solver.anchors, &s.network.positions)
            .map_err(Failure::other)?;
        s.solver.step(self.dt).map_err(Failure::other)?;
        let steps = s.solver.diagnostics().steps;
        s.dense
            .maintain(&s.solver.points, steps)
            .map_err(Failure::other)?;
        s.dense.follow(&s.solver.points).map_err(Failure::other)?;
        Ok(())
    }
}

/// The dense surface of the ECS's `entity`.
fn dense_of(app: &App, entity: Entity) -> Result<&DenseCloud, Failure> {
    app.world()
        .get::<DenseSurface>(entity)
        .map(|d| &**d)
        .ok_or_else(|| Failure::other("the surface has no dense surface"))
}

/// The scene to run (from `args.scene`, or generated with `steps` steps), its cloud and its
/// name.
fn scene(args: &Args, steps: usize) -> Result<(Scene, PointCloud, String), Failure> {
    let (mut scene, cloud, name) = scene_as_given(args, steps)?;
    if let Some(bending) = args.bending {
        scene.material.bending = bending.into();
    }
    Ok((scene, cloud, name))
}

/// The scene of `args.scene`, or the generated sphere.
fn scene_as_given(args: &Args, steps: usize) -> Result<(Scene, PointCloud, String), Failure> {
    Ok(match &args.scene {
        Some(path) => {
            let (scene, base) = Scene::load(path).map_err(Failure::bad_input)?;
            let cloud = read_cloud(&base.join(&scene.cloud), None).map_err(Failure::bad_input)?;
            (scene, cloud, path.display().to_string())
        }
        None => {
            let (scene, cloud) = poked_sphere(args.dense, args.sim, steps);
            let name = scene.cloud.display().to_string();
            (scene, cloud, name)
        }
    })
}

/// Spawns the surface in `app` and updates it until the surface is prepared (in the
/// background): the surface's entity and the milliseconds it took.
fn prepare_ecs(app: &mut App, scene: &Scene, cloud: &PointCloud) -> Result<(Entity, f64), Failure> {
    let start = Instant::now();
    let entity = app
        .world_mut()
        .spawn(DeformableSurface::scene_data(scene.clone(), cloud.clone()))
        .id();
    while matches!(
        app.world().get::<SurfaceStatus>(entity),
        Some(SurfaceStatus::Pending | SurfaceStatus::Loading | SurfaceStatus::Preparing)
    ) {
        if start.elapsed() > PREPARE_TIMEOUT {
            return Err(Failure::other("the surface was not prepared in time"));
        }
        std::thread::sleep(Duration::from_millis(1));
        app.update();
    }
    let ms_prepare = start.elapsed().as_secs_f64() * 1e3;
    if let Some(SurfaceStatus::Failed(message)) = app.world().get::<SurfaceStatus>(entity) {
        return Err(Failure::bad_input(message.to_string()));
    }
    Ok((entity, ms_prepare))
}

/// Steps the ECS's `entity` has taken.
fn ecs_steps(app: &App, entity: Entity) -> u64 {
    app.world()
        .get::<bevy_point_springs::plugin::SurfaceStepper>(entity)
        .map_or(0, |s| s.diagnostics().steps)
}

/// Seconds and ticks the timed blocks measured.
#[derive(Debug, Default)]
struct Timing {
    /// Packing the surfels, summed over the ECS's timed ticks.
    upload: f64,
    /// The core's ticks, summed.
    core: f64,
    /// The core's ticks timed.
    core_ticks: usize,
}

/// A warm-up block of each, then ECS and core ticked in alternating timed blocks.
fn time_blocks(
    args: &Args,
    app: &mut App,
    entity: Entity,
    core: &mut CoreRun,
) -> Result<Timing, Failure> {
    let rest = dense_of(app, entity)?.transfer();
    let shape = SurfelShape::at_rest(
        rest.rest_positions(),
        rest.rest_normals(),
        DEFAULT_SURFEL_SCALE,
    );
    let mut timing = Timing::default();
    // A warm-up block of each, untimed.
    for _ in 0..args.block {
        app.update();
        core.tick()?;
    }
    app.world_mut().resource_mut::<Clock>().timing = true;
    while timing.core_ticks < args.ticks {
        let n = args.block.min(args.ticks - timing.core_ticks);
        for _ in 0..n {
            app.update();
            let dense = dense_of(app, entity)?;
            let start = Instant::now();
            // As the renderer does: a new buffer each frame, moved to the render world.
            let mut packed = Vec::with_capacity(dense.len() * SURFEL_BYTES);
            pack_surfels(dense.positions(), dense.normals(), &shape, &mut packed);
            let handed_over = Arc::new(packed);
            timing.upload += start.elapsed().as_secs_f64();
            drop(handed_over);
        }
        let start = Instant::now();
        for _ in 0..n {
            core.tick()?;
        }
        timing.core += start.elapsed().as_secs_f64();
        timing.core_ticks += n;
    }
    Ok(timing)
}

/// Runs `point-springs-bench plugin`.
pub fn run(args: &Args) -> Result<(), Failure> {
    if args.ticks == 0 || args.block == 0 {
        return Err(Failure::bad_input("--ticks and --block must be at least 1"));
    }
    if !(4..=MAX_DENSE).contains(&args.dense) {
        return Err(Failure::bad_input(format!(
            "--dense must be between 4 and {MAX_DENSE}"
        )));
    }
    // Enough timeline for warm-up and both runs' ticks.
    let steps = args.ticks + args.block + 1;
    let (scene, cloud, name) = scene(args, steps)?;
    // The ECS: prepared in the background, then ticked.
    let mut app = ecs_app(scene.dt, args.single_threaded);
    let (entity, ms_prepare) = prepare_ecs(&mut app, &scene, &cloud)?;
    // The core, from the same cloud and scene.
    let (surface, timeline) = scene
        .prepare_cloud(cloud, &mut |_| std::ops::ControlFlow::Continue(()))
        .map_err(Failure::other)?;
    let mut core = CoreRun {
        surface,
        timeline,
        dt: scene.dt,
    };
    // The first tick ran with the update that finished the preparation: catch the core up.
    while core.surface.solver.diagnostics().steps < ecs_steps(&app, entity) {
        core.tick()?;
    }
    let timing = time_blocks(args, &mut app, entity, &mut core)?;
    let report = report(args, &scene, name, &app, entity, &core, ms_prepare, &timing)?;
    args.json.emit(&report)
}

/// The report, from the ECS's clock and dense surface, and the core's.
#[allow(clippy::too_many_arguments)]
fn report(
    args: &Args,
    scene: &Scene,
    name: String,
    app: &App,
    entity: Entity,
    core: &CoreRun,
    ms_prepare: f64,
    timing: &Timing,
) -> Result<PluginReport, Failure> {
    let clock = app.world().resource::<Clock>();
    let timed = clock.timed.max(1) as f64;
    let [forces, stepping, transfer] = clock.sums.map(|s| s * 1e3 / timed);
    let ms_tick = forces + stepping + transfer;
    let ms_upload = timing.upload * 1e3 / timing.core_ticks as f64;
    let ms_core_tick = timing.core * 1e3 / timing.core_ticks as f64;
    let dense = dense_of(app, entity)?;
    let same = |a: &[Vec3], b: &[Vec3]| {
        a.len() == b.len()
            && a.iter()
                .zip(b)
                .all(|(p, q)| p.to_array().map(f32::to_bits) == q.to_array().map(f32::to_bits))
    };
    let identical = ecs_steps(app, entity) == core.surface.solver.diagnostics().steps
        && same(dense.positions(), core.surface.dense.positions())
        && same(dense.normals(), core.surface.dense.normals());
    Ok(PluginReport {
        scene: name,
        executor: if args.single_threaded {
            "single-threaded"
        } else {
            "multi-threaded"
        },
        dense_points: dense.len(),
        sim_points: core.surface.solver.len(),
        springs: core.surface.solver.spring_count(),
        hinges: core.surface.solver.hinge_count(),
        curvatures: core.surface.solver.curvature_count(),
        integrator: scene.solver.integrator.to_string(),
        ticks: clock.timed,
        ms_prepare,
        ms_forces: forces,
        ms_stepping: stepping,
        ms_transfer: transfer,
        ms_tick,
        ms_upload,
        ms_frame: ms_tick + ms_upload,
        ms_core_tick,
        ecs_over_core: ms_tick / ms_core_tick,
        cg_per_step: {
            let d = core.surface.solver.diagnostics();
            d.cg_iterations as f64 / d.steps.max(1) as f64
        },
        identical,
    })
}
