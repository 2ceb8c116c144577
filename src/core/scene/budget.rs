//! A simplification level chosen from an error budget instead of a point count (the
//! paper's future work): `error_budget: Some(0.01)` in a scene asks for the coarsest level
//! whose deformed dense surface stays within 1 % of the bounding box's diagonal (RMS) of
//! the surface every dense point would give.
//!
//! The estimate is a successive-level one. The scene runs to its last step at 2 %, 4 %,
//! 8 %, … of the dense points (each level twice the last); `d(f)`, the RMS distance between
//! the dense surfaces of levels `f` and `2f`, is measured. Where the error shrinks by a
//! factor `r` per doubling, the error of level `f` is `e(f) = d(f) · r / (r − 1)`; `r` is
//! `d(f/2) / d(f)`, held within [√2, 2] (first to second order in the spacing, which a
//! doubling of the points shrinks by √2), √2 before two differences exist. The climb stops at the first level whose predicted error is
//! within the budget, so it costs the scene's run at every level up to twice the chosen
//! one; past 64 % every dense point is simulated.

use super::*;

/// The levels the estimate climbs through, as fractions of the dense points.
pub const BUDGET_LADDER: [f32; 6] = [0.02, 0.04, 0.08, 0.16, 0.32, 0.64];

/// The least simulation points a level of the ladder gets.
const MIN_LEVEL_POINTS: usize = 20;

/// Bounds on the error's shrink factor per doubling of the points.
const SHRINK_RANGE: (f32, f32) = (std::f32::consts::SQRT_2, 2.0);

/// One level the estimate ran.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LevelEstimate {
    /// Fraction of the dense points asked for.
    pub fraction: f32,
    /// Simulation points the level has.
    pub sim_points: usize,
    /// RMS distance of its dense surface from the next level's, over the diagonal (none
    /// for the last level run).
    pub difference: Option<f32>,
    /// Its predicted RMS error, over the diagonal.
    pub predicted: f32,
}

/// The level an error budget chose.
#[derive(Debug, Clone, PartialEq)]
pub struct LevelChoice {
    /// The budget, RMS over the diagonal.
    pub budget: f32,
    /// Fraction of the dense points chosen (1 when no level of the ladder was within it).
    pub fraction: f32,
    /// Simulation points asked for.
    pub target: usize,
    /// The predicted RMS error of the chosen level (0 for every dense point).
    pub predicted: f32,
    /// The error's shrink factor per doubling, as last estimated.
    pub shrink: f32,
    /// Every level run, coarsest first.
    pub levels: Vec<LevelEstimate>,
}

impl LevelChoice {
    /// The predicted RMS error at any fraction of the points: the prediction of the nearest
    /// level run at or below it, shrunk by [`Self::shrink`] per doubling beyond (0 at 1).
    pub fn predict(&self, fraction: f32) -> f32 {
        if fraction >= 1.0 {
            return 0.0;
        }
        let base = self
            .levels
            .iter()
            .rev()
            .find(|l| l.fraction <= fraction)
            .or(self.levels.first());
        base.map_or(0.0, |l| {
            l.predicted * self.shrink.powf(-(fraction / l.fraction).log2())
        })
    }
}

/// Checks a budget: finite, in (0, 1).
pub(super) fn valid_budget(budget: f32) -> bool {
    budget > 0.0 && budget < 1.0
}

impl Scene {
    /// Chooses the simplification level for an RMS error `budget` (over the bounding box's
    /// diagonal) on `cloud`. The scene (its own error budget ignored) runs to its last step
    /// at each level of [`BUDGET_LADDER`]; `d(f)`, the RMS distance between the dense
    /// surfaces of levels `f` and `2f`, predicts `e(f) = d(f) · r / (r − 1)`, where `r`, the
    /// error's shrink per doubling, is `d(f/2) / d(f)` held within [√2, 2] (√2 before two
    /// differences exist). The climb stops at the first level predicted within the budget;
    /// past the ladder every dense point is simulated.
    pub fn choose_level(&self, cloud: &PointCloud, budget: f32) -> Result<LevelChoice, SceneError> {
        if !valid_budget(budget) {
            return Err(invalid(format!(
                "the error budget must be in (0, 1), got {budget}"
            )));
        }
        let diagonal = cloud
            .bounds()
            .map(|b| b.diagonal())
            .filter(|d| *d > 0.0)
            .ok_or_else(|| invalid("an error budget needs a cloud with extent"))?;
        // The last level run: its fraction, simulation points and dense surface.
        let mut coarse: Option<(f32, usize, Vec<Vec3>)> = None;
        let mut levels: Vec<LevelEstimate> = Vec::new();
        let mut shrink = SHRINK_RANGE.0;
        for fraction in BUDGET_LADDER {
            let target = level_target(cloud.len(), fraction);
            if coarse.as_ref().is_some_and(|c| c.1 >= target) {
                continue;
            }
            let (sim_points, positions) = self.run_level(cloud, target)?;
            let Some((coarse_fraction, coarse_points, coarse_positions)) = coarse.take() else {
                coarse = Some((fraction, sim_points, positions));
                continue;
            };
            let difference = rms_distance(&coarse_positions, &positions) / diagonal;
            coarse = Some((fraction, sim_points, positions));
            if let Some(previous) = levels.last().and_then(|l| l.difference)
                && difference > 0.0
            {
                shrink = (previous / difference).clamp(SHRINK_RANGE.0, SHRINK_RANGE.1);
            }
            let predicted = difference * shrink / (shrink - 1.0);
            levels.push(LevelEstimate {
                fraction: coarse_fraction,
                sim_points: coarse_points,
                difference: Some(difference),
                predicted,
            });
            let finer = LevelEstimate {
                fraction,
                sim_points,
                difference: None,
                predicted: predicted / shrink,
            };
            let chosen = [&levels[levels.len() - 1], &finer]
                .into_iter()
                .find(|l| l.predicted <= budget)
                .map(|l| (l.fraction, l.predicted));
            if let Some((fraction, predicted)) = chosen {
                levels.push(finer);
                return Ok(LevelChoice {
                    budget,
                    fraction,
                    target: level_target(cloud.len(), fraction),
                    predicted,
                    shrink,
                    levels,
                });
            }
        }
        if let Some((fraction, sim_points, _)) = coarse {
            levels.push(LevelEstimate {
                fraction,
                sim_points,
                difference: None,
                predicted: levels.last().map_or(0.0, |l| l.predicted / shrink),
            });
        }
        Ok(LevelChoice {
            budget,
            fraction: 1.0,
            target: cloud.len(),
            predicted: 0.0,
            shrink,
            levels,
        })
    }

    /// This scene with its error budget resolved into a point count on `cloud` (itself when
    /// it has none), and the choice made.
    pub fn resolve_budget(
        &self,
        cloud: &PointCloud,
    ) -> Result<(Scene, Option<LevelChoice>), SceneError> {
        let Some(budget) = self.error_budget else {
            return Ok((self.clone(), None));
        };
        let choice = self.choose_level(cloud, budget)?;
        let mut scene = self.clone();
        scene.error_budget = None;
        scene.simplify.target = Some(choice.target);
        scene.simplify.max_diameter = None;
        Ok((scene, Some(choice)))
    }

    /// Runs this scene (without its budget) at `target` simulation points to its last step:
    /// the simulation points it got and the positions of the original dense points at the end.
    fn run_level(
        &self,
        cloud: &PointCloud,
        target: usize,
    ) -> Result<(usize, Vec<Vec3>), SceneError> {
        let mut scene = self.clone();
        scene.error_budget = None;
        scene.simplify.target = Some(target);
        scene.simplify.max_diameter = None;
        let mut run = scene.prepare_run(cloud.clone())?;
        run.run(&mut |_| {})?;
        let s = &mut run.surface;
        s.dense.follow(&s.solver.points)?;
        // The original dense points only: points a resampling inserted differ by level.
        let original = &s.dense.positions()[..cloud.len().min(s.dense.len())];
        Ok((s.solver.len(), original.to_vec()))
    }
}

/// The simulation points a level at `fraction` of `n` dense points asks for: the nearest
/// count, at least 20 (or every point of a smaller cloud).
pub fn level_target(n: usize, fraction: f32) -> usize {
    ((n as f32 * fraction).round() as usize).clamp(MIN_LEVEL_POINTS.min(n), n)
}

/// RMS distance between two surfaces over their common points.
fn rms_distance(a: &[Vec3], b: &[Vec3]) -> f32 {
    let n = a.len().min(b.len());
    if n == 0 {
        return 0.0;
    }
    let sum: f64 = a[..n]
        .iter()
        .zip(&b[..n])
        .map(|(p, q)| f64::from(p.distance_squared(*q)))
        .sum();
    (sum / n as f64).sqrt() as f32
}
