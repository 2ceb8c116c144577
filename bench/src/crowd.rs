//! `point-springs-bench crowd`: many small surfaces at the plugin's default settings, the
//! case a game meets when it scatters deformable props (issue 32): 40 gas-filled spheres of
//! 1500 dense and 120 simulation points took 27 ms a tick when the default integrator was
//! symplectic Euler (56 sub-steps a step).
//!
//! Each sphere falls under gravity and is poked by an anchor for the first half of the run,
//! so every surface steps every tick (none falls asleep). Ticks run in the plugin's fixed
//! schedule headless, timed between marker systems (see `point-springs-bench plugin`).

use std::fmt;
use std::time::{Duration, Instant};

use bevy::prelude::*;
use bevy_point_springs::core::cloud::shapes::fibonacci_sphere;
use bevy_point_springs::core::solver::Anchor;
use bevy_point_springs::plugin::{SurfaceAnchors, SurfaceHealth, SurfaceStepper};
use bevy_point_springs::prelude::{
    DeformableSurface, SimplifyConfig, SimulationPoints, SurfaceConfig, SurfaceStatus,
};
use serde::Serialize;

use crate::failure::Failure;
use crate::flags::JsonFlag;
use crate::plugin::{Clock, ecs_app};
use crate::report::Report;

/// Arguments of `point-springs-bench crowd`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Surfaces.
    #[arg(long, default_value_t = 40)]
    surfaces: usize,
    /// Dense points of each sphere.
    #[arg(long, default_value_t = 1500)]
    dense: usize,
    /// Simulation points of each sphere.
    #[arg(long, default_value_t = 120)]
    sim: usize,
    /// Radius of each sphere.
    #[arg(long, default_value_t = 0.3)]
    radius: f32,
    /// Gas stiffness κ inside each sphere.
    #[arg(long, default_value_t = 300.0)]
    pressure: f32,
    /// Ticks timed (after a warm-up of the same length).
    #[arg(long, default_value_t = 120)]
    ticks: usize,
    /// Relative residual at which implicit Euler's conjugate gradient stops (default: the
    /// solver's default), to weigh speed against accuracy.
    #[arg(long)]
    cg_tolerance: Option<f32>,
    #[command(flatten)]
    json: JsonFlag,
}

/// The fixed tick, s.
const DT: f32 = 1.0 / 60.0;

/// Upper bound on waiting for the preparations (a hang guard).
const PREPARE_TIMEOUT: Duration = Duration::from_secs(600);

/// Largest crowd the command takes.
const MAX_SURFACES: usize = 10_000;
/// Largest sphere the command takes.
const MAX_DENSE: usize = 1_000_000;

/// What `point-springs-bench crowd` reports (times in ms, means over the timed ticks).
#[derive(Debug, Serialize)]
struct CrowdReport {
    /// Surfaces.
    surfaces: usize,
    /// Dense points of each.
    dense_points: usize,
    /// Simulation points of each.
    sim_points: usize,
    /// The integrator the surfaces step with.
    integrator: String,
    /// Implicit Euler's CG tolerance.
    cg_tolerance: f32,
    /// Ticks timed.
    ticks: usize,
    /// Forces, stepping and transfer of every surface, per tick.
    ms_tick: f64,
    /// Forces, per tick.
    ms_forces: f64,
    /// Stepping, per tick.
    ms_stepping: f64,
    /// Transfer, per tick.
    ms_transfer: f64,
    /// Per surface and tick.
    ms_per_surface: f64,
    /// Sub-steps per step, over every surface and step.
    substeps_per_step: f64,
    /// CG iterations per step.
    cg_per_step: f64,
    /// Guard trips, over every surface.
    guard_trips: u64,
    /// Surfaces whose health reported trouble.
    troubled_surfaces: usize,
}

impl fmt::Display for CrowdReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "crowd        {} spheres of {} dense and {} simulation points ({}, CG tolerance {:e})",
            self.surfaces, self.dense_points, self.sim_points, self.integrator, self.cg_tolerance
        )?;
        writeln!(
            f,
            "tick         {:.3} ms = forces {:.3} + stepping {:.3} + transfer {:.3} (mean of {}); {:.4} ms a surface",
            self.ms_tick,
            self.ms_forces,
            self.ms_stepping,
            self.ms_transfer,
            self.ticks,
            self.ms_per_surface
        )?;
        writeln!(
            f,
            "solver       {:.2} sub-steps and {:.1} CG iterations a step, {} guard trips, {} surfaces in trouble",
            self.substeps_per_step, self.cg_per_step, self.guard_trips, self.troubled_surfaces
        )
    }
}

impl Report for CrowdReport {}

/// Runs `point-springs-bench crowd`.
pub fn run(args: &Args) -> Result<(), Failure> {
    if args.surfaces == 0 || args.surfaces > MAX_SURFACES {
        return Err(Failure::bad_input(format!(
            "--surfaces must be from 1 to {MAX_SURFACES}"
        )));
    }
    if args.dense < 20 || args.dense > MAX_DENSE || args.sim < 10 || args.sim > args.dense {
        return Err(Failure::bad_input(format!(
            "--dense must be from 20 to {MAX_DENSE} and --sim from 10 to --dense"
        )));
    }
    if !(args.radius > 0.0
        && args.radius.is_finite()
        && args.pressure >= 0.0
        && args.pressure.is_finite())
    {
        return Err(Failure::bad_input(
            "--radius must be positive and --pressure not negative",
        ));
    }
    if args.ticks == 0 {
        return Err(Failure::bad_input("--ticks must be at least 1"));
    }
    let mut app = ecs_app(DT, false);
    let cloud = fibonacci_sphere(args.dense, args.radius);
    let mut config = SurfaceConfig {
        simplify: SimplifyConfig::target(args.sim),
        pressure: Some(args.pressure),
        ..SurfaceConfig::default()
    };
    if let Some(tolerance) = args.cg_tolerance {
        config.solver.cg_tolerance = tolerance;
    }
    config
        .validate()
        .map_err(|e| Failure::bad_input(e.to_string()))?;
    let side = (args.surfaces as f32).sqrt().ceil() as usize;
    let entities: Vec<Entity> = (0..args.surfaces)
        .map(|i| {
            let at = Vec3::new((i % side) as f32, 0.0, (i / side) as f32) * 3.0 * args.radius;
            app.world_mut()
                .spawn((
                    DeformableSurface::cloud(cloud.clone(), config),
                    Transform::from_translation(at),
                ))
                .id()
        })
        .collect();
    prepare_all(&mut app, &entities)?;
    poke(&mut app, &entities, args.radius)?;
    let before = totals(&app, &entities);
    for tick in 0..2 * args.ticks {
        if tick == args.ticks {
            app.world_mut().resource_mut::<Clock>().timing = true;
        }
        if tick == args.ticks / 2 {
            for &e in &entities {
                if let Some(mut anchors) = app.world_mut().get_mut::<SurfaceAnchors>(e) {
                    anchors.clear();
                }
            }
        }
        app.update();
    }
    let after = totals(&app, &entities);
    let clock = app.world().resource::<Clock>();
    let ms = |s: f64| s * 1e3 / clock.timed.max(1) as f64;
    let (forces, stepping, transfer) = (ms(clock.sums[0]), ms(clock.sums[1]), ms(clock.sums[2]));
    let tick = forces + stepping + transfer;
    let steps = (after.steps - before.steps).max(1) as f64;
    let integrator = app
        .world()
        .get::<SurfaceStepper>(entities[0])
        .map_or_else(String::new, |s| s.integrator().to_string());
    let troubled_surfaces = entities
        .iter()
        .filter(|&&e| {
            app.world()
                .get::<SurfaceHealth>(e)
                .is_some_and(|h| h.episodes > 0)
        })
        .count();
    let report = CrowdReport {
        surfaces: args.surfaces,
        dense_points: args.dense,
        sim_points: args.sim,
        integrator,
        cg_tolerance: config.solver.cg_tolerance,
        ticks: clock.timed,
        ms_tick: tick,
        ms_forces: forces,
        ms_stepping: stepping,
        ms_transfer: transfer,
        ms_per_surface: tick / args.surfaces as f64,
        substeps_per_step: (after.substeps - before.substeps) as f64 / steps,
        cg_per_step: (after.cg - before.cg) as f64 / steps,
        guard_trips: after.guard_trips,
        troubled_surfaces,
    };
    args.json.emit(&report)
}

/// Updates `app` until every surface is prepared.
fn prepare_all(app: &mut App, entities: &[Entity]) -> Result<(), Failure> {
    let start = Instant::now();
    loop {
        let statuses: Vec<SurfaceStatus> = entities
            .iter()
            .filter_map(|&e| app.world().get::<SurfaceStatus>(e).cloned())
            .collect();
        if let Some(SurfaceStatus::Failed(why)) = statuses
            .iter()
            .find(|s| matches!(s, SurfaceStatus::Failed(_)))
        {
            return Err(Failure::bad_input(why.to_string()));
        }
        if statuses.iter().all(SurfaceStatus::is_ready) {
            return Ok(());
        }
        if start.elapsed() > PREPARE_TIMEOUT {
            return Err(Failure::other("the surfaces were not prepared in time"));
        }
        std::thread::sleep(Duration::from_millis(1));
        app.update();
    }
}

/// An anchor on each sphere's top point, pulling it a fifth of the radius in.
fn poke(app: &mut App, entities: &[Entity], radius: f32) -> Result<(), Failure> {
    for &e in entities {
        let top = app
            .world()
            .get::<SimulationPoints>(e)
            .and_then(|p| {
                (0..p.len())
                    .max_by(|&a, &b| p.position(a).y.total_cmp(&p.position(b).y))
                    .map(|i| (i, p.position(i), p.len()))
            })
            .ok_or_else(|| Failure::other("a surface has no points"))?;
        let mut anchors = app
            .world_mut()
            .get_mut::<SurfaceAnchors>(e)
            .ok_or_else(|| Failure::other("a surface has no anchors"))?;
        anchors
            .add(
                Anchor {
                    point: top.0 as u32,
                    target: top.1 - Vec3::Y * 0.2 * radius,
                    stiffness: 50.0,
                    damping: 0.5,
                },
                top.2,
            )
            .map_err(Failure::other)?;
    }
    Ok(())
}

/// Steps, sub-steps, CG iterations and guard trips summed over the surfaces.
#[derive(Debug, Default, Clone, Copy)]
struct Totals {
    /// Steps.
    steps: u64,
    /// Sub-steps.
    substeps: u64,
    /// CG iterations.
    cg: u64,
    /// Guard trips.
    guard_trips: u64,
}

/// The [`Totals`] of `entities`.
fn totals(app: &App, entities: &[Entity]) -> Totals {
    entities
        .iter()
        .filter_map(|&e| app.world().get::<SurfaceStepper>(e))
        .fold(Totals::default(), |t, s| {
            let d = s.diagnostics();
            Totals {
                steps: t.steps + d.steps,
                substeps: t.substeps + d.substeps,
                cg: t.cg + d.cg_iterations,
                guard_trips: t.guard_trips + d.guard_trips,
            }
        })
}
