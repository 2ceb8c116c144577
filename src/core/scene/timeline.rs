//! A scene's pulls on their schedule: which points each pull holds, and where its anchors
//! are at each step.

use glam::Vec3;

use super::*;

/// Where a [`Timeline`] stands: its step and the anchors each pull holds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TimelineState {
    /// Steps taken.
    pub step: usize,
    /// Per pull, its anchors (none before it starts and after it lets go).
    pub anchors: Vec<Vec<AnchorId>>,
}

/// A pull's state during a run.
#[derive(Debug, Clone)]
struct ActivePull {
    pull: Pull,
    end: usize,
    grabbed: Vec<u32>,
    anchors: Vec<AnchorId>,
}

/// A scene's pulls and pokes on their schedule: before each of the scene's steps,
/// [`Timeline::advance`] adds, moves and removes their anchor springs. After the scene's
/// last step the timeline holds still: a pull that lasts to the end keeps holding.
#[derive(Debug, Clone)]
pub struct Timeline {
    pulls: Vec<ActivePull>,
    steps: usize,
    step: usize,
}

impl Timeline {
    /// The timeline of `scene`'s pulls on simulation points at rest at `rest`: each grabs
    /// the points within its radius of where it acts, at least the nearest one.
    pub fn new(scene: &Scene, rest: &[Vec3]) -> Self {
        let index = KnnIndex::build(rest);
        let pulls = scene
            .pulls
            .iter()
            .map(|pull| {
                let mut grabbed: Vec<u32> = match pull.radius {
                    Some(r) => (0..rest.len() as u32)
                        .filter(|&j| rest[j as usize].distance(pull.at) <= r)
                        .collect(),
                    None => Vec::new(),
                };
                // The nearest point at least, however small the radius.
                if grabbed.is_empty() {
                    grabbed = index
                        .nearest(pull.at, 1)
                        .iter()
                        .map(|nb| nb.index)
                        .collect();
                }
                ActivePull {
                    pull: *pull,
                    end: pull.end.unwrap_or(scene.steps),
                    grabbed,
                    anchors: Vec::new(),
                }
            })
            .collect();
        Self {
            pulls,
            steps: scene.steps,
            step: 0,
        }
    }

    /// Steps counted so far.
    pub fn step(&self) -> usize {
        self.step
    }

    /// Steps the timeline lasts.
    pub fn steps(&self) -> usize {
        self.steps
    }

    /// Whether every step of the timeline has been taken.
    pub fn finished(&self) -> bool {
        self.step >= self.steps
    }

    /// Simulation points grabbed by each pull.
    pub fn pulled_points(&self) -> Vec<usize> {
        self.pulls.iter().map(|p| p.grabbed.len()).collect()
    }

    /// What happens before the current step — pulls start, move and let go — applied to
    /// `anchors` (on simulation points at rest at `rest`); then counts the step.
    pub fn advance(&mut self, anchors: &mut Anchors, rest: &[Vec3]) -> Result<(), SolverError> {
        let step = self.step;
        if step >= self.steps {
            return Ok(());
        }
        let points = rest.len();
        for active in &mut self.pulls {
            let p = active.pull;
            if step == p.start {
                active.anchors = active
                    .grabbed
                    .iter()
                    .map(|&j| {
                        let offset = rest[j as usize] - p.at;
                        let anchor = Anchor {
                            point: j,
                            target: p.to + offset,
                            stiffness: p.stiffness,
                            damping: p.damping,
                        };
                        anchors.add(anchor, points)
                    })
                    .collect::<Result<_, _>>()?;
            }
            if step == active.end {
                for id in active.anchors.drain(..) {
                    anchors.remove(id);
                }
            }
            if let (Some(to_end), true) = (p.to_end, (p.start..active.end).contains(&step)) {
                let t = (step - p.start) as f32 / (active.end - p.start) as f32;
                let target = p.to.lerp(to_end, t);
                for (&j, &id) in active.grabbed.iter().zip(&active.anchors) {
                    let offset = rest[j as usize] - p.at;
                    anchors.set_target(id, target + offset)?;
                }
            }
        }
        self.step += 1;
        Ok(())
    }

    /// The step reached and the anchors each pull holds (for a snapshot).
    pub fn state(&self) -> TimelineState {
        TimelineState {
            step: self.step,
            anchors: self.pulls.iter().map(|p| p.anchors.clone()).collect(),
        }
    }

    /// Puts back what [`Self::state`] gave, on the timeline of the same scene: refused
    /// (nothing changed) when the pull count differs, when a pull holds anchors other than
    /// one per grabbed point, or when the step is past the end.
    pub fn restore(&mut self, state: &TimelineState) -> Result<(), SceneError> {
        if state.anchors.len() != self.pulls.len() || state.step > self.steps {
            return Err(invalid(format!(
                "the snapshot's timeline ({} pulls, step {}) is not this scene's ({} pulls, {} steps)",
                state.anchors.len(),
                state.step,
                self.pulls.len(),
                self.steps
            )));
        }
        for (p, held) in self.pulls.iter().zip(&state.anchors) {
            if !held.is_empty() && held.len() != p.grabbed.len() {
                return Err(invalid(
                    "the snapshot's pull holds another number of points than the scene's",
                ));
            }
        }
        for (p, held) in self.pulls.iter_mut().zip(&state.anchors) {
            p.anchors.clone_from(held);
        }
        self.step = state.step;
        Ok(())
    }

    /// Starts the timeline again from its first step: the anchors its pulls hold are
    /// removed from `anchors` (other anchors, a game's grabs, stay).
    pub fn restart(&mut self, anchors: &mut Anchors) {
        for active in &mut self.pulls {
            for id in active.anchors.drain(..) {
                anchors.remove(id);
            }
        }
        self.step = 0;
    }
}
