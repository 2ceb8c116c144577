//! Grabbing a surface: a press holds the simulation points near where it hit with anchor
//! springs (eq 5), a drag moves their targets, a release lets go.
//!
//! Grabs arrive as [`GrabMessage`]s: a picking observer, a game's own input code or a test
//! writes them, and [`apply_grabs`] turns them into anchors at the start of each tick
//! ([`PointSpringsSystems::Forces`](super::PointSpringsSystems::Forces)). Positions in the
//! messages are in world space; the surface's [`GlobalTransform`] (when it has one) maps them
//! to the surface's own space, where its points live. Each grab has a key of the sender's
//! choosing (a pointer id), so several pointers can hold one surface or several.
//!
//! ```
//! use bevy::prelude::*;
//! use bevy_point_springs::prelude::*;
//!
//! /// Presses on the surface's top and pushes it in.
//! fn poke(mut grabs: MessageWriter<GrabMessage>, surface: Single<Entity, With<DeformableSurface>>) {
//!     grabs.write(GrabMessage::Start { key: 0, surface: *surface, at: Vec3::Y });
//!     grabs.write(GrabMessage::Move { key: 0, target: Vec3::Y * 0.7 });
//! }
//! ```

use bevy::platform::collections::HashMap;
use bevy::prelude::*;

use crate::core::solver::{Anchor, AnchorId, Anchors};

use super::components::{SimulationPoints, SurfaceAnchors, SurfaceNetwork, SurfaceStatus};

/// Grab radius when nothing else is said, in the surface's mean stretch-spring lengths.
pub const DEFAULT_GRAB_RADIUS: f32 = 1.5;

/// Stiffness of each grabbed point's anchor spring when nothing else is said (k_r of eq 5,
/// per unit mass of the default material: stiff enough to lead, soft enough to stay stable
/// at the default tick).
pub const DEFAULT_GRAB_STIFFNESS: f32 = 200.0;

/// Damping of each grabbed point's anchor when nothing else is said.
pub const DEFAULT_GRAB_DAMPING: f32 = 2.0;

/// A grab on a surface, keyed by `key` (a pointer id, or any number the sender picks).
#[derive(Message, Debug, Clone, Copy, PartialEq)]
pub enum GrabMessage {
    /// Holds the simulation points of `surface` within the grab radius of `at` (world space;
    /// at least the nearest point), each where it is now. A key already holding something
    /// lets go of it first.
    Start {
        /// The grab's key.
        key: u64,
        /// The surface grabbed.
        surface: Entity,
        /// Where it was hit, in world space.
        at: Vec3,
    },
    /// Moves the grab so that the point that was at `at` is pulled to `target` (world
    /// space); every grabbed point keeps its offset from it.
    Move {
        /// The grab's key.
        key: u64,
        /// Where the hit point is pulled to, in world space.
        target: Vec3,
    },
    /// Lets go.
    End {
        /// The grab's key.
        key: u64,
    },
}

/// How grabs hold surfaces.
#[derive(Resource, Reflect, Debug, Clone, Copy, PartialEq)]
#[reflect(Resource)]
pub struct GrabSettings {
    /// Points within this many mean stretch-spring lengths of the hit are held.
    pub radius: f32,
    /// Anchor stiffness per grabbed point (k_r of eq 5).
    pub stiffness: f32,
    /// Anchor damping per grabbed point.
    pub damping: f32,
}

impl Default for GrabSettings {
    fn default() -> Self {
        Self {
            radius: DEFAULT_GRAB_RADIUS,
            stiffness: DEFAULT_GRAB_STIFFNESS,
            damping: DEFAULT_GRAB_DAMPING,
        }
    }
}

/// One held grab.
#[derive(Debug, Clone)]
struct Grab {
    surface: Entity,
    /// Each held point's anchor and its offset from the hit (in the surface's space) when
    /// the grab started.
    held: Vec<(AnchorId, Vec3)>,
}

/// What a grab holds of its surface (for a saved game): each held point's anchor and its
/// offset from the hit.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub(crate) struct HeldGrab(Vec<(AnchorId, Vec3)>);

impl HeldGrab {
    /// The anchors it holds.
    pub(crate) fn anchors(&self) -> impl Iterator<Item = AnchorId> + '_ {
        self.0.iter().map(|(id, _)| *id)
    }

    /// The same grab without the anchors `anchors` no longer has (a game removed them).
    pub(crate) fn alive(self, anchors: &Anchors) -> Self {
        Self(
            self.0
                .into_iter()
                .filter(|(id, _)| anchors.get(*id).is_some())
                .collect(),
        )
    }
}

/// The grabs being held, by key.
#[derive(Resource, Debug, Default)]
pub struct Grabs {
    active: HashMap<u64, Grab>,
}

impl Grabs {
    /// How many grabs are held.
    pub fn len(&self) -> usize {
        self.active.len()
    }

    /// Whether no grab is held.
    pub fn is_empty(&self) -> bool {
        self.active.is_empty()
    }

    /// Ends every grab of `surface` without touching its anchors (they were replaced: the
    /// surface was prepared again).
    pub(crate) fn forget_surface(&mut self, surface: Entity) {
        self.active.retain(|_, g| g.surface != surface);
    }

    /// The grabs of `surface`, by key (ascending).
    pub(crate) fn of_surface(&self, surface: Entity) -> Vec<(u64, HeldGrab)> {
        let mut grabs: Vec<(u64, HeldGrab)> = self
            .active
            .iter()
            .filter(|(_, g)| g.surface == surface)
            .map(|(&key, g)| (key, HeldGrab(g.held.clone())))
            .collect();
        grabs.sort_by_key(|(key, _)| *key);
        grabs
    }

    /// Holds `held` of `surface` under `key` (a saved grab put back), ending what `key`
    /// held before without touching its anchors.
    pub(crate) fn hold(&mut self, key: u64, surface: Entity, held: HeldGrab) {
        self.active.insert(
            key,
            Grab {
                surface,
                held: held.0,
            },
        );
    }

    /// The surface and the number of points held by the grab with `key`.
    pub fn get(&self, key: u64) -> Option<(Entity, usize)> {
        self.active.get(&key).map(|g| (g.surface, g.held.len()))
    }
}

/// The surface queried by [`apply_grabs`].
type GrabTarget<'a> = (
    &'a SimulationPoints,
    &'a mut SurfaceAnchors,
    &'a SurfaceNetwork,
    &'a SurfaceStatus,
    Option<&'a GlobalTransform>,
);

/// Turns this tick's [`GrabMessage`]s into anchor springs: added on start, moved on move,
/// removed on end. A message for a surface that is gone, not ready yet or failed, or with a
/// position that is not finite, is logged and ignored.
pub fn apply_grabs(
    mut messages: MessageReader<GrabMessage>,
    mut grabs: ResMut<Grabs>,
    settings: Res<GrabSettings>,
    mut surfaces: Query<GrabTarget>,
) {
    // Grabs of surfaces that are gone (or no longer simulated) end by themselves.
    grabs
        .active
        .retain(|_, g| surfaces.get(g.surface).is_ok_and(|s| s.3.is_ready()));
    for message in messages.read() {
        match *message {
            GrabMessage::Start { key, surface, at } => {
                release(&mut grabs, key, &mut surfaces);
                let Ok((points, mut anchors, network, status, place)) = surfaces.get_mut(surface)
                else {
                    warn!("point-springs grab {key}: {surface} is not a deformable surface");
                    continue;
                };
                if !status.is_ready() || !at.is_finite() {
                    warn!(
                        "point-springs grab {key}: {surface} is not ready, or the hit is not finite"
                    );
                    continue;
                }
                let at = to_local(place, at);
                let radius = settings.radius.max(0.0) * mean_spring_length(network);
                let mut chosen: Vec<u32> = (0..points.len() as u32)
                    .filter(|&i| points.position(i as usize).distance(at) <= radius)
                    .collect();
                if chosen.is_empty() {
                    let nearest = (0..points.len() as u32).min_by(|&a, &b| {
                        let d = |i: u32| points.position(i as usize).distance_squared(at);
                        d(a).total_cmp(&d(b))
                    });
                    chosen.extend(nearest);
                }
                let mut held = Vec::with_capacity(chosen.len());
                for i in chosen {
                    let x = points.position(i as usize);
                    let anchor = Anchor {
                        point: i,
                        target: x,
                        stiffness: settings.stiffness,
                        damping: settings.damping,
                    };
                    match anchors.add(anchor, points.len()) {
                        Ok(id) => held.push((id, x - at)),
                        Err(e) => warn!("point-springs grab {key}: point {i} not held: {e}"),
                    }
                }
                grabs.active.insert(key, Grab { surface, held });
            }
            GrabMessage::Move { key, target } => {
                let Some(grab) = grabs.active.get(&key) else {
                    continue; // a drag after its release, or of nothing
                };
                if !target.is_finite() {
                    warn!("point-springs grab {key}: target is not finite");
                    continue;
                }
                let Ok((_, mut anchors, _, _, place)) = surfaces.get_mut(grab.surface) else {
                    continue;
                };
                let target = to_local(place, target);
                for &(id, offset) in &grab.held {
                    // An anchor removed by the game ends that point's part of the grab.
                    let _ = anchors.set_target(id, target + offset);
                }
            }
            GrabMessage::End { key } => release(&mut grabs, key, &mut surfaces),
        }
    }
}

/// Removes the grab with `key`, if any, and its anchors.
fn release(grabs: &mut Grabs, key: u64, surfaces: &mut Query<GrabTarget>) {
    let Some(grab) = grabs.active.remove(&key) else {
        return;
    };
    if let Ok((_, mut anchors, ..)) = surfaces.get_mut(grab.surface) {
        for (id, _) in grab.held {
            anchors.remove(id);
        }
    }
}

/// `p` (world space) in the space of a surface placed by `place`.
fn to_local(place: Option<&GlobalTransform>, p: Vec3) -> Vec3 {
    place.map_or(p, |g| g.affine().inverse().transform_point3(p))
}

/// Mean rest length of a network's stretch springs.
fn mean_spring_length(network: &SurfaceNetwork) -> f32 {
    let springs = &network.stretch;
    if springs.is_empty() {
        return 0.0;
    }
    springs.iter().map(|s| s.rest_length).sum::<f32>() / springs.len() as f32
}
