//! A scene run headless: the prepared surface stepped with its timeline, resampled, and
//! transferred back to every dense point.

use super::*;

/// A prepared scene, run headless: the surface, its timeline, and what the run did.
#[derive(Debug, Clone)]
pub struct SceneRun {
    /// The scene.
    pub scene: Scene,
    /// The dense cloud as loaded (with normals when it had them).
    pub rest: PointCloud,
    /// The network, the solver and the dense surface.
    pub surface: PreparedSurface,
    /// The pulls on their schedule.
    pub timeline: Timeline,
    /// Simulation points held by pins.
    pub pinned: usize,
    /// What resampling did over the run.
    pub(super) resampled: ResampleReport,
}

/// The deformed dense surface.
#[derive(Debug, Clone)]
pub struct Deformed {
    /// Positions and normals (resampled points after the original ones).
    pub cloud: PointCloud,
    /// Largest displacement of a dense point.
    pub max_displacement: f32,
}

impl SceneRun {
    pub(super) fn new(
        scene: Scene,
        rest: PointCloud,
        surface: PreparedSurface,
        timeline: Timeline,
    ) -> Self {
        Self {
            pinned: surface.solver.masses.pinned(),
            scene,
            rest,
            surface,
            timeline,
            resampled: ResampleReport::default(),
        }
    }

    /// The solver.
    pub fn solver(&self) -> &Solver {
        &self.surface.solver
    }

    /// Steps taken.
    pub fn step_count(&self) -> usize {
        self.timeline.step()
    }

    /// Whether all steps are done.
    pub fn finished(&self) -> bool {
        self.timeline.finished()
    }

    /// What resampling did so far (summed over every check).
    pub fn resampled(&self) -> ResampleReport {
        self.resampled
    }

    /// The simulation part of a step: the timeline acts, then the solver steps.
    pub fn simulate(&mut self) -> Result<StepReport, SceneError> {
        let s = &mut self.surface;
        self.timeline
            .advance(&mut s.solver.anchors, &s.network.positions)?;
        Ok(s.solver.step(self.scene.dt)?)
    }

    /// The dense part of a step: resampling, when it is due.
    pub fn maintain(&mut self) -> Result<ResampleReport, SceneError> {
        let s = &mut self.surface;
        let steps = s.solver.diagnostics().steps;
        let report = s.dense.maintain(&s.solver.points, steps)?;
        let r = &mut self.resampled;
        r.inserted += report.inserted;
        r.passes += report.passes;
        r.capped |= report.capped;
        Ok(report)
    }

    /// Takes one step: [`Self::simulate`], then [`Self::maintain`].
    pub fn step(&mut self) -> Result<StepReport, SceneError> {
        let report = self.simulate()?;
        self.maintain()?;
        Ok(report)
    }

    /// Runs the remaining steps, calling `progress` with the step count after each.
    pub fn run(&mut self, progress: &mut dyn FnMut(usize)) -> Result<(), SceneError> {
        while !self.finished() {
            self.step()?;
            progress(self.step_count());
        }
        Ok(())
    }

    /// The deformed dense surface: the transfer of the current state (inserted points
    /// included; they follow the simulation from the step they were inserted at).
    pub fn deformed(&mut self) -> Result<Deformed, SceneError> {
        let s = &mut self.surface;
        s.dense.follow(&s.solver.points)?;
        let cloud = s
            .dense
            .to_cloud()
            .map_err(|e| invalid(format!("the deformed surface is not valid: {e}")))?;
        Ok(Deformed {
            cloud,
            max_displacement: s.dense.max_displacement(),
        })
    }
}
