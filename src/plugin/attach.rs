//! Attachments (issue 35): simulation points tied to another entity's transform, so that
//! they follow it as it moves and turns — a flag on a pole, a cape on a shoulder, a hat's
//! rim on a moving ring. Put [`SurfaceAttachments`] on the surface's entity and
//! [`attach`](SurfaceAttachments::attach) points to a target entity:
//!
//! ```
//! use bevy::prelude::*;
//! use bevy_point_springs::prelude::*;
//!
//! fn hang_the_flag(
//!     mut commands: Commands,
//!     flag: Single<Entity, With<DeformableSurface>>,
//!     pole: Single<Entity, With<Name>>,
//! ) {
//!     let mut attachments = SurfaceAttachments::default();
//!     // The simulation points within 5 cm of the flag's edge at x = 0.
//!     attachments.attach(*pole, AttachPoints::filter(|p| p.x < 0.05));
//!     commands.entity(*flag).insert(attachments);
//! }
//! ```
//!
//! How it works, each tick in [`PointSpringsSystems::Forces`](super::PointSpringsSystems)
//! ([`hold_attachments`]):
//!
//! * an attachment new to the surface (or to a surface prepared again: its points are
//!   picked again on the new network) picks its points on the network's rest positions and
//!   remembers where each is in its target's frame; its points are pinned
//!   ([`Masses::set_pinned`](crate::core::solver::Masses::set_pinned));
//! * each attached point is given the velocity that lands it, at the end of the step, where
//!   its target will be then: the target's transform now, moved on by its rigid body's
//!   velocity over the tick where rapier moves the body by velocity (dynamic and
//!   velocity-based kinematic bodies). The points follow exactly; the surface's springs
//!   carry the motion to the rest of it;
//! * the step measures what held each pinned point
//!   ([`Stepper::pin_impulses`](crate::core::solver::Stepper::pin_impulses)); together with
//!   the change of velocity the attachment gave it, that is the attachment's impulse on the
//!   surface, and its opposite, the surface's pull, is reported ([`SurfaceAttachments::pull`])
//!   and, with the `rapier` feature and [`SurfaceContactPlugin`], applied to the target's
//!   dynamic rigid body at the points before rapier steps: a heavy cape drags its body down,
//!   with momentum exchanged exactly (to the step's solve).
//!
//! A detached attachment, or one whose target is despawned, frees the points it pinned
//! (those the game pinned itself stay pinned) and says so in the log and its
//! [`AttachmentState`]; nothing panics.
//!
//! [`SurfaceContactPlugin`]: super::SurfaceContactPlugin

use std::fmt;
use std::sync::Arc;

use bevy::math::Affine3A;
use bevy::prelude::*;
use bevy::transform::helper::TransformHelper;

use crate::core::network::SpringNetwork;
use crate::core::solver::contact::{CarriedPoint, StepBody};

use super::components::{
    SimulationPoints, SurfaceForces, SurfaceMasses, SurfaceNetwork, SurfaceSleep, SurfaceStatus,
    SurfaceStepper,
};
use super::simulate::{Gate, running};

/// A target that moved less than this (in the surface's units, over a tick) does not wake a
/// sleeping surface.
const STILL_TARGET: f32 = 1e-6;

/// Which simulation points an attachment holds, picked on the network's rest positions (the
/// surface's own coordinates) each time the surface is prepared.
#[derive(Clone)]
pub enum AttachPoints {
    /// These simulation points, by index.
    Indices(Vec<u32>),
    /// The simulation points within `radius` of `centre`.
    Near {
        /// The region's centre, in the surface's coordinates.
        centre: Vec3,
        /// The region's radius (> 0).
        radius: f32,
    },
    /// The simulation points whose rest position the predicate accepts.
    Where(Arc<dyn Fn(Vec3) -> bool + Send + Sync>),
}

impl AttachPoints {
    /// The simulation points whose rest position `accept` accepts.
    pub fn filter(accept: impl Fn(Vec3) -> bool + Send + Sync + 'static) -> Self {
        Self::Where(Arc::new(accept))
    }

    /// The indices of the points picked on a network with these rest `positions`.
    fn pick(&self, positions: &[Vec3]) -> Result<Vec<u32>, AttachmentError> {
        let picked: Vec<u32> = match self {
            Self::Indices(indices) => {
                if let Some(&index) = indices.iter().find(|&&i| i as usize >= positions.len()) {
                    return Err(AttachmentError::PointOutOfRange {
                        index,
                        points: positions.len(),
                    });
                }
                let mut picked = indices.clone();
                picked.sort_unstable();
                picked.dedup();
                picked
            }
            Self::Near { centre, radius } => {
                if !(centre.is_finite() && radius.is_finite() && *radius > 0.0) {
                    return Err(AttachmentError::BadRegion);
                }
                (0..positions.len() as u32)
                    .filter(|&i| positions[i as usize].distance(*centre) <= *radius)
                    .collect()
            }
            Self::Where(accept) => (0..positions.len() as u32)
                .filter(|&i| accept(positions[i as usize]))
                .collect(),
        };
        if picked.is_empty() {
            Err(AttachmentError::NoPoints)
        } else {
            Ok(picked)
        }
    }
}

impl fmt::Debug for AttachPoints {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Indices(indices) => f.debug_tuple("Indices").field(indices).finish(),
            Self::Near { centre, radius } => f
                .debug_struct("Near")
                .field("centre", centre)
                .field("radius", radius)
                .finish(),
            Self::Where(_) => f.write_str("Where(..)"),
        }
    }
}

/// Why an attachment holds nothing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum AttachmentError {
    /// No simulation point matched.
    #[error("no simulation point matches the attachment")]
    NoPoints,
    /// An index past the surface's simulation points.
    #[error("point {index} is out of range ({points} simulation points)")]
    PointOutOfRange {
        /// The index given.
        index: u32,
        /// How many simulation points the surface has.
        points: usize,
    },
    /// A region with a centre or radius that is not finite, or a radius not above zero.
    #[error("the region's centre and radius must be finite and the radius above zero")]
    BadRegion,
    /// The target has no transform, or is gone.
    #[error("the target {0} is gone or has no transform")]
    TargetGone(Entity),
    /// The target's or the surface's transform cannot be inverted or is not finite.
    #[error("the target's or the surface's transform is degenerate")]
    DegenerateTransform,
}

/// Where an attachment stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AttachmentState {
    /// Waiting for the surface to be ready (its points are picked then).
    Pending,
    /// Holding its points to the target.
    Holding,
    /// Holding nothing, and why; its pins were freed.
    Released(AttachmentError),
}

/// Names one attachment of a surface; valid until it is detached.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct AttachmentId {
    slot: u32,
    generation: u32,
}

/// How a target moves over the tick, where its rigid body moves it by velocity (world
/// coordinates): linear velocity, angular velocity, centre of mass.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct TargetMotion {
    pub(crate) linear: Vec3,
    pub(crate) angular: Vec3,
    pub(crate) centre: Vec3,
}

impl TargetMotion {
    /// Where the world point `p`, carried by the body, is after `dt`: the centre moved on
    /// by the linear velocity, the turn about it by the angular one (as rapier integrates).
    fn carry(&self, p: Vec3, dt: f32) -> Vec3 {
        let turn = Quat::from_scaled_axis(self.angular * dt);
        self.centre + self.linear * dt + turn * (p - self.centre)
    }
}

/// One attachment and what it holds.
#[derive(Debug, Clone)]
pub(crate) struct Attachment {
    pub(crate) target: Entity,
    points: AttachPoints,
    state: AttachmentState,
    /// The points held, ascending.
    held: Vec<u32>,
    /// Each held point's place in the target's frame.
    offsets: Vec<Vec3>,
    /// The held points this attachment pinned (the others were pinned already).
    pinned: Vec<u32>,
    /// The impulse the attachment gave each held point this tick before the step, by setting
    /// its velocity (surface coordinates).
    kicks: Vec<Vec3>,
    /// The target's motion over this tick, where a rigid body moves it.
    pub(crate) motion: Option<TargetMotion>,
    /// The target's dynamic body, in the surface's coordinates, for the step to solve with
    /// the surface (its points then carried by it, [`CarriedPoint`]).
    pub(crate) carrier: Option<StepBody>,
    /// The surface's pull on the target in the last step, point by point: where (world)
    /// and how much (world, N·s).
    pulls: Vec<(Vec3, Vec3)>,
    pull: Vec3,
    total_pull: Vec3,
}

impl Attachment {
    fn new(target: Entity, points: AttachPoints) -> Self {
        Self {
            target,
            points,
            state: AttachmentState::Pending,
            held: Vec::new(),
            offsets: Vec::new(),
            pinned: Vec::new(),
            kicks: Vec::new(),
            motion: None,
            carrier: None,
            pulls: Vec::new(),
            pull: Vec3::ZERO,
            total_pull: Vec3::ZERO,
        }
    }

    /// Holds nothing, and hands back the points it pinned.
    fn let_go(&mut self, state: AttachmentState) -> Vec<u32> {
        self.state = state;
        self.held.clear();
        self.offsets.clear();
        self.kicks.clear();
        self.pulls.clear();
        self.pull = Vec3::ZERO;
        std::mem::take(&mut self.pinned)
    }
}

#[derive(Debug, Clone)]
struct Slot {
    generation: u32,
    attachment: Option<Attachment>,
}

/// A surface's attachments: sets of its simulation points tied to other entities'
/// transforms (see the [module documentation](self)). Add, change and remove them at any
/// time; they are picked again on a surface prepared again ([`PrepareAgain`]).
///
/// [`PrepareAgain`]: super::PrepareAgain
#[derive(Component, Debug, Clone, Default)]
pub struct SurfaceAttachments {
    slots: Vec<Slot>,
    free: Vec<u32>,
    /// Points whose attachment went away and that wait to be freed by the next tick.
    to_free: Vec<u32>,
    /// The network the attachments' points were picked on.
    picked_on: Option<Arc<SpringNetwork>>,
    /// The stepper's step count when the pulls were last read.
    steps_read: u64,
}

impl SurfaceAttachments {
    /// Ties the simulation points `points` picks to `target`'s transform, where they are
    /// when the attachment starts holding (on the next tick of a ready surface).
    pub fn attach(&mut self, target: Entity, points: AttachPoints) -> AttachmentId {
        let attachment = Some(Attachment::new(target, points));
        if let Some(slot) = self.free.pop() {
            let s = &mut self.slots[slot as usize];
            s.attachment = attachment;
            return AttachmentId {
                slot,
                generation: s.generation,
            };
        }
        self.slots.push(Slot {
            generation: 0,
            attachment,
        });
        AttachmentId {
            slot: self.slots.len() as u32 - 1,
            generation: 0,
        }
    }

    /// Removes an attachment; its points are freed on the next tick. Returns whether it
    /// existed.
    pub fn detach(&mut self, id: AttachmentId) -> bool {
        let Some(slot) = self
            .slots
            .get_mut(id.slot as usize)
            .filter(|s| s.generation == id.generation && s.attachment.is_some())
        else {
            return false;
        };
        let mut attachment = slot.attachment.take().expect("checked");
        slot.generation = slot.generation.wrapping_add(1);
        self.free.push(id.slot);
        self.to_free
            .extend(attachment.let_go(AttachmentState::Pending));
        true
    }

    /// Ties an attachment's points to another target (or the same one again), where they
    /// are when the next tick picks them. Returns whether the attachment exists.
    pub fn set_target(&mut self, id: AttachmentId, target: Entity) -> bool {
        let Some(attachment) = self.get_mut(id) else {
            return false;
        };
        attachment.target = target;
        let pinned = attachment.let_go(AttachmentState::Pending);
        self.to_free.extend(pinned);
        true
    }

    fn get(&self, id: AttachmentId) -> Option<&Attachment> {
        self.slots
            .get(id.slot as usize)
            .filter(|s| s.generation == id.generation)
            .and_then(|s| s.attachment.as_ref())
    }

    fn get_mut(&mut self, id: AttachmentId) -> Option<&mut Attachment> {
        self.slots
            .get_mut(id.slot as usize)
            .filter(|s| s.generation == id.generation)
            .and_then(|s| s.attachment.as_mut())
    }

    /// The ids of the attachments.
    pub fn ids(&self) -> impl Iterator<Item = AttachmentId> + '_ {
        self.slots.iter().enumerate().filter_map(|(slot, s)| {
            s.attachment.as_ref().map(|_| AttachmentId {
                slot: slot as u32,
                generation: s.generation,
            })
        })
    }

    /// Number of attachments.
    pub fn len(&self) -> usize {
        self.slots.iter().filter(|s| s.attachment.is_some()).count()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// An attachment's target.
    pub fn target(&self, id: AttachmentId) -> Option<Entity> {
        self.get(id).map(|a| a.target)
    }

    /// Where an attachment stands.
    pub fn state(&self, id: AttachmentId) -> Option<AttachmentState> {
        self.get(id).map(|a| a.state)
    }

    /// The simulation points an attachment holds, ascending (empty until it holds).
    pub fn held_points(&self, id: AttachmentId) -> Option<&[u32]> {
        self.get(id).map(|a| &a.held[..])
    }

    /// Where each held point belongs in the target's frame (in the order of
    /// [`Self::held_points`]): the target's transform maps it to the point's place.
    pub fn offsets(&self, id: AttachmentId) -> Option<&[Vec3]> {
        self.get(id).map(|a| &a.offsets[..])
    }

    /// The surface's pull on an attachment's target over the last step (world, N·s): the
    /// opposite of what the attachment gave the surface.
    pub fn pull(&self, id: AttachmentId) -> Option<Vec3> {
        self.get(id).map(|a| a.pull)
    }

    /// The surface's pull on an attachment's target since the attachment started holding
    /// (world, N·s).
    pub fn total_pull(&self, id: AttachmentId) -> Option<Vec3> {
        self.get(id).map(|a| a.total_pull)
    }

    /// Each attachment, mutably.
    pub(crate) fn live_mut(&mut self) -> impl Iterator<Item = &mut Attachment> {
        self.slots.iter_mut().filter_map(|s| s.attachment.as_mut())
    }

    /// The last step's pulls on each attachment's target, point by point: where (world)
    /// and how much (world, N·s).
    #[cfg_attr(not(feature = "rapier"), allow(dead_code))]
    pub(crate) fn pulls_on(&self) -> impl Iterator<Item = (Entity, &[(Vec3, Vec3)])> {
        self.slots
            .iter()
            .filter_map(|s| s.attachment.as_ref())
            .map(|a| (a.target, &a.pulls[..]))
    }

    /// Whether some attachment other than `except` holds point `i`.
    fn held_elsewhere(&self, i: u32, except: Option<usize>) -> bool {
        self.slots.iter().enumerate().any(|(slot, s)| {
            Some(slot) != except
                && s.attachment
                    .as_ref()
                    .is_some_and(|a| a.held.binary_search(&i).is_ok())
        })
    }

    /// Frees `points` where no other attachment holds them.
    fn free_pins(&self, points: &[u32], masses: &mut SurfaceMasses) {
        for &i in points {
            if (i as usize) < masses.len() && !self.held_elsewhere(i, None) {
                masses.0.set_pinned(i as usize, false).expect("in range");
            }
        }
    }
}

/// Where a surface and an attachment's target are in the world this tick.
struct Frames {
    surface: Affine3A,
    target: Affine3A,
}

impl SurfaceAttachments {
    /// Picks the points of the attachment in `slot` on a network with these rest
    /// `positions` (leaving out those another attachment holds), remembers where each is
    /// in the target's frame and pins them; on failure the attachment is released.
    fn start_holding(
        &mut self,
        slot: usize,
        positions: &[Vec3],
        points: &SimulationPoints,
        masses: &mut SurfaceMasses,
        frames: &Frames,
    ) -> Result<(), AttachmentError> {
        let a = self.slots[slot].attachment.as_ref().expect("live");
        let picked = a.points.pick(positions).and_then(|picked| {
            let free: Vec<u32> = picked
                .into_iter()
                .filter(|&i| !self.held_elsewhere(i, Some(slot)))
                .collect();
            if free.is_empty() {
                Err(AttachmentError::NoPoints)
            } else {
                Ok(free)
            }
        });
        let a = self.slots[slot].attachment.as_mut().expect("live");
        let held = match picked {
            Ok(held) => held,
            Err(why) => {
                a.let_go(AttachmentState::Released(why));
                return Err(why);
            }
        };
        let from_target = frames.target.inverse();
        a.offsets = held
            .iter()
            .map(|&i| {
                let world = frames.surface.transform_point3(points.position(i as usize));
                from_target.transform_point3(world)
            })
            .collect();
        a.pinned = held
            .iter()
            .copied()
            .filter(|&i| !masses.is_pinned(i as usize))
            .collect();
        for &i in &a.pinned {
            masses
                .0
                .set_pinned(i as usize, true)
                .expect("picked in range");
        }
        a.held = held;
        a.total_pull = Vec3::ZERO;
        a.state = AttachmentState::Holding;
        Ok(())
    }
}

impl Attachment {
    /// Hands the step the target's dynamic body and the held points it carries, so that
    /// the step solves the body's velocity with the surface's ([`CarriedPoint`]); the kicks
    /// the points took before the step count against the body's velocity.
    fn carry(
        &self,
        frames: &Frames,
        mut body: StepBody,
        motion: TargetMotion,
        forces: &mut SurfaceForces,
        entity: Entity,
    ) {
        let to_surface = Mat3::from(frames.surface.inverse().matrix3);
        let arms: Vec<Vec3> = self
            .offsets
            .iter()
            .map(|&offset| to_surface * (frames.target.transform_point3(offset) - motion.centre))
            .collect();
        let (mut linear, mut angular) = (Vec3::ZERO, Vec3::ZERO);
        for (kick, arm) in self.kicks.iter().zip(&arms) {
            linear += *kick;
            angular += arm.cross(*kick);
        }
        body.linear -= body.inv_mass * linear;
        body.angular -= body.inv_inertia * angular;
        let added = forces.add_body(body).and_then(|index| {
            self.held.iter().zip(&arms).try_for_each(|(&point, &arm)| {
                forces.add_carried(CarriedPoint {
                    point,
                    body: index,
                    arm,
                })
            })
        });
        if let Err(e) = added {
            warn!("point-springs surface {entity}: an attachment's body left out of the step: {e}");
        }
    }

    /// Gives each held point the velocity that lands it on its target at the end of a step
    /// of `dt` (the target carried by `motion` meanwhile), remembering the impulse that
    /// took; returns whether any point had to move.
    fn follow(
        &mut self,
        frames: &Frames,
        motion: Option<TargetMotion>,
        points: &mut SimulationPoints,
        masses: &mut SurfaceMasses,
        dt: f32,
    ) -> bool {
        let to_surface = frames.surface.inverse();
        let mut moved = false;
        for (&i, &offset) in self.held.iter().zip(&self.offsets) {
            let i = i as usize;
            if !masses.is_pinned(i) {
                // The game freed it: the attachment holds it again.
                masses.0.set_pinned(i, true).expect("in range");
            }
            let mut world = frames.target.transform_point3(offset);
            if let Some(motion) = motion {
                world = motion.carry(world, dt);
            }
            let goal = to_surface.transform_point3(world);
            let (x, v) = (points.position(i), points.velocity(i));
            let velocity = (goal - x) / dt;
            if !velocity.is_finite() {
                self.kicks.push(Vec3::ZERO);
                continue;
            }
            moved |= (goal - x).length() > STILL_TARGET;
            self.kicks.push((velocity - v) * masses.mass(i));
            points.set_velocity(i, velocity).expect("in range");
        }
        moved
    }
}

/// What [`hold_attachments`] reads and changes of a surface.
type HoldParts = (
    Entity,
    &'static mut SurfaceAttachments,
    &'static mut SimulationPoints,
    &'static mut SurfaceMasses,
    &'static SurfaceNetwork,
    (&'static mut SurfaceStepper, &'static mut SurfaceForces),
    &'static mut SurfaceSleep,
    Option<&'static GlobalTransform>,
    &'static SurfaceStatus,
    Gate,
);

/// Each tick, before the forces: attachments pick their points where new, and each held
/// point is given the velocity that lands it on its target at the end of the step (see
/// the [module documentation](self)).
pub fn hold_attachments(
    time: Res<Time>,
    transforms: TransformHelper,
    mut surfaces: Query<HoldParts>,
) {
    let dt = time.delta_secs();
    for (
        entity,
        mut attachments,
        mut points,
        mut masses,
        network,
        (mut stepper, mut forces),
        mut sleep,
        place,
        status,
        (settings, once),
    ) in &mut surfaces
    {
        if !status.is_ready() {
            continue;
        }
        let attachments = attachments.bypass_change_detection();
        let network = &network.0;
        if !attachments
            .picked_on
            .as_ref()
            .is_some_and(|n| Arc::ptr_eq(n, network))
        {
            // Prepared (again): new masses, so nothing is pinned; pick every point again.
            for a in attachments.live_mut() {
                a.let_go(AttachmentState::Pending);
            }
            attachments.to_free.clear();
            attachments.picked_on = Some(Arc::clone(network));
        }
        let to_free = std::mem::take(&mut attachments.to_free);
        if !to_free.is_empty() {
            attachments.free_pins(&to_free, &mut masses);
        }
        let surface = place.map_or(Affine3A::IDENTITY, GlobalTransform::affine);
        let moves = running(status, settings, once) && dt > 0.0;
        let mut holding = false;
        for slot in 0..attachments.slots.len() {
            let Some(target) = attachments.slots[slot]
                .attachment
                .as_ref()
                .map(|a| a.target)
            else {
                continue;
            };
            let pose = transforms
                .compute_global_transform(target)
                .map_err(|_| AttachmentError::TargetGone(target))
                .map(|t| t.affine())
                .and_then(|t| {
                    let finite = t.is_finite() && surface.is_finite();
                    let invertible =
                        t.matrix3.determinant() != 0.0 && surface.matrix3.determinant() != 0.0;
                    if finite && invertible {
                        Ok(t)
                    } else {
                        Err(AttachmentError::DegenerateTransform)
                    }
                });
            let frames = Frames {
                surface,
                target: match pose {
                    Ok(pose) => pose,
                    Err(why) => {
                        let a = attachments.slots[slot].attachment.as_mut().expect("live");
                        if !matches!(a.state, AttachmentState::Released(_)) {
                            warn!("point-springs surface {entity}: an attachment let go: {why}");
                            let pinned = a.let_go(AttachmentState::Released(why));
                            attachments.free_pins(&pinned, &mut masses);
                        }
                        continue;
                    }
                },
            };
            let pending = attachments.slots[slot]
                .attachment
                .as_ref()
                .is_some_and(|a| a.state == AttachmentState::Pending);
            if pending
                && let Err(why) = attachments.start_holding(
                    slot,
                    &network.positions,
                    &points,
                    &mut masses,
                    &frames,
                )
            {
                error!("point-springs surface {entity}: an attachment holds nothing: {why}");
                continue;
            }
            let a = attachments.slots[slot].attachment.as_mut().expect("live");
            if a.state != AttachmentState::Holding {
                continue;
            }
            holding = true;
            let motion = a.motion.take();
            let carrier = a.carrier.take();
            a.kicks.clear();
            let moved = moves && a.follow(&frames, motion, &mut points, &mut masses, dt);
            if moves && let (Some(body), Some(motion)) = (carrier, motion) {
                a.carry(&frames, body, motion, &mut forces, entity);
            }
            // A target that moved wakes the surface; one that a rigid body carries keeps it
            // awake (a sleeping surface would stop pulling its body).
            if moved || motion.is_some() {
                if sleep.asleep {
                    sleep.wake();
                } else {
                    sleep.acted = true;
                }
            }
        }
        if stepper.measures_pins() != holding {
            stepper.0.set_measure_pins(holding);
        }
    }
}

/// After the step: each attachment's impulse on the surface (its kicks and what held its
/// points in the step), and the opposite, the surface's pull on the target, point by point
/// in world coordinates. A surface that did not step this tick pulls nothing.
pub fn record_pulls(
    mut surfaces: Query<(
        &mut SurfaceAttachments,
        &SurfaceStepper,
        &SimulationPoints,
        Option<&GlobalTransform>,
    )>,
) {
    for (mut attachments, stepper, points, place) in &mut surfaces {
        let attachments = attachments.bypass_change_detection();
        let steps = stepper.diagnostics().steps;
        let stepped = std::mem::replace(&mut attachments.steps_read, steps) != steps;
        let surface = place.map_or(Affine3A::IDENTITY, GlobalTransform::affine);
        let linear = Mat3::from(surface.matrix3);
        let held = stepper.pin_impulses();
        for a in attachments.live_mut() {
            a.pulls.clear();
            a.pull = Vec3::ZERO;
            if !stepped || a.state != AttachmentState::Holding || a.kicks.len() != a.held.len() {
                continue;
            }
            for (&i, kick) in a.held.iter().zip(&a.kicks) {
                let i = i as usize;
                let given = *kick + held.get(i).copied().unwrap_or(Vec3::ZERO);
                let pull = -(linear * given);
                if pull.is_finite() {
                    a.pulls
                        .push((surface.transform_point3(points.position(i)), pull));
                    a.pull += pull;
                }
            }
            a.total_pull += a.pull;
        }
    }
}
