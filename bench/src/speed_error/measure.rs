//! One configuration of `point-springs-bench report` run and measured: the scene prepared at a level,
//! stepped frame by frame (one frame: as many steps as fill 1/60 s, then the transfer of
//! positions and normals to every dense point), timed, and compared at the end with the
//! reference's dense surface.

use std::time::Instant;

use bevy_point_springs::core::PointCloud;
use bevy_point_springs::core::pipeline::DenseCloud;
use bevy_point_springs::core::scene::Scene;
use glam::Vec3;

use crate::failure::Failure;

/// A frame's length, s (a game's 60 Hz).
pub const FRAME_S: f32 = 1.0 / 60.0;

/// The deformed dense surface at the end of a run.
#[derive(Debug, Clone)]
pub struct Surface {
    /// Positions.
    pub positions: Vec<Vec3>,
    /// Unit normals.
    pub normals: Vec<Vec3>,
}

/// What one run measured.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// Simulation points.
    pub sim_points: usize,
    /// Springs.
    pub springs: usize,
    /// Steps per frame.
    pub frame_steps: usize,
    /// Milliseconds per step: the timeline's pulls and the solver's step (sub-steps
    /// included), nothing else.
    pub ms_step: f64,
    /// Milliseconds per transfer of positions and normals to every dense point.
    pub ms_transfer: f64,
    /// The most sub-steps a step took.
    pub substeps: u32,
    /// Whether the run finished with a finite state, no guard trip, no solver error and no
    /// point thrown further than the bounding box's diagonal.
    pub stable: bool,
    /// Why it was not stable.
    pub failure: Option<String>,
    /// The largest speed at the end, over the diagonal (per second): small when settled.
    pub residual_speed: f32,
    /// The largest displacement of a dense point at the end, over the diagonal.
    pub max_displacement: f32,
    /// The dense surface at the end (none when unstable).
    pub surface: Option<Surface>,
}

impl Outcome {
    /// Milliseconds per frame: a frame's steps and one transfer.
    pub fn ms_frame(&self) -> f64 {
        self.frame_steps as f64 * self.ms_step + self.ms_transfer
    }
}

/// Prepares `scene` on `cloud` and runs it to its last step, timing steps and transfers.
pub fn run_scene(scene: &Scene, cloud: &PointCloud, diagonal: f32) -> Result<Outcome, Failure> {
    let mut run = scene.prepare_run(cloud.clone()).map_err(Failure::other)?;
    let frame_steps = ((FRAME_S / scene.dt).round() as usize).max(1);
    let (mut simulate, mut transfer) = (0.0f64, 0.0f64);
    let (mut steps, mut transfers, mut substeps) = (0usize, 0usize, 0u32);
    let mut failure = None;
    'frames: while !run.finished() {
        for _ in 0..frame_steps {
            if run.finished() {
                break;
            }
            let start = Instant::now();
            let report = run.simulate();
            simulate += start.elapsed().as_secs_f64();
            steps += 1;
            match report {
                Ok(r) => substeps = substeps.max(r.substeps),
                Err(e) => {
                    failure = Some(e.to_string());
                    break 'frames;
                }
            }
        }
        let start = Instant::now();
        let s = &mut run.surface;
        let moved = s.dense.follow(&s.solver.points);
        transfer += start.elapsed().as_secs_f64();
        transfers += 1;
        if let Err(e) = moved {
            failure = Some(e.to_string());
            break;
        }
        if let Some(why) = thrown(&run.surface.dense, diagonal) {
            failure = Some(why);
            break;
        }
    }
    let solver = &run.surface.solver;
    if failure.is_none() && solver.diagnostics().guard_trips > 0 {
        failure = Some(format!(
            "the guard restored the state {} times",
            solver.diagnostics().guard_trips
        ));
    }
    let stable = failure.is_none();
    let dense = &run.surface.dense;
    Ok(Outcome {
        sim_points: solver.len(),
        springs: solver.spring_count(),
        frame_steps,
        ms_step: simulate * 1e3 / steps.max(1) as f64,
        ms_transfer: transfer * 1e3 / transfers.max(1) as f64,
        substeps,
        stable,
        failure,
        residual_speed: solver.points.max_speed() / diagonal,
        max_displacement: dense.max_displacement() / diagonal,
        surface: stable.then(|| Surface {
            positions: dense.positions().to_vec(),
            normals: dense.normals().to_vec(),
        }),
    })
}

/// Why the dense surface is not sensible: a coordinate not finite, or a point moved
/// further than the bounding box's diagonal (nothing in these scenes moves that far).
fn thrown(dense: &DenseCloud, diagonal: f32) -> Option<String> {
    if !dense.positions().iter().all(|p| p.is_finite()) {
        return Some("a dense point is not finite".to_owned());
    }
    let far = dense.max_displacement();
    (far > diagonal).then(|| format!("a dense point moved {far:.3e}, past the diagonal"))
}

/// The error of a surface against the reference's, over the same dense points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Error {
    /// Root mean square distance, over the bounding box's diagonal.
    pub rms: f64,
    /// Largest distance, over the diagonal.
    pub max: f64,
    /// Mean angle between the normals, degrees.
    pub normal_deg: f64,
}

/// Compares `surface` with `reference` point by point.
pub fn error(surface: &Surface, reference: &Surface, diagonal: f32) -> Error {
    let n = surface
        .positions
        .len()
        .min(reference.positions.len())
        .max(1) as f64;
    let (mut sum, mut max, mut angles) = (0.0f64, 0.0f64, 0.0f64);
    for (p, q) in surface.positions.iter().zip(&reference.positions) {
        let d = f64::from(p.distance(*q));
        sum += d * d;
        max = max.max(d);
    }
    for (a, b) in surface.normals.iter().zip(&reference.normals) {
        angles += f64::from(a.dot(*b).clamp(-1.0, 1.0)).acos().to_degrees();
    }
    let diagonal = f64::from(diagonal);
    Error {
        rms: (sum / n).sqrt() / diagonal,
        max: max / diagonal,
        normal_deg: angles / n,
    }
}
