//! Surfaces in world space. A surface simulates in its own coordinates (its simulation
//! points, forces, gravity and dense surface are local to its entity's transform), while a
//! game thinks in the world's: [`WorldSurfaces`] pushes on points and reads the deformed
//! surface in world coordinates, through the surface's [`GlobalTransform`], and
//! [`SurfacePins`] pins points (by index, or near a world position) and frees them, and
//! [`SurfaceGravity`] says whether a surface's gravity is the world's (the default) or
//! turns with it.
//!
//! ```
//! use bevy::prelude::*;
//! use bevy_point_springs::prelude::*;
//!
//! /// A gust from the west on every surface, 2 N on each point within a metre of the
//! /// origin, wherever and however each surface is placed.
//! fn gust(mut world: WorldSurfaces, surfaces: Query<Entity, With<DeformableSurface>>) {
//!     for surface in &surfaces {
//!         let _ = world.push_near(surface, Vec3::ZERO, 1.0, Vec3::X * 2.0);
//!     }
//! }
//!
//! App::new()
//!     .add_plugins((MinimalPlugins, PointSpringsPlugins::default()))
//!     .add_systems(FixedUpdate, gust.in_set(PointSpringsSystems::Forces));
//! ```

use bevy::ecs::system::SystemParam;
use bevy::prelude::*;

use super::components::{
    DenseSurface, SimulationPoints, SurfaceForces, SurfaceMasses, SurfaceSleep, SurfaceStepper,
};
use crate::core::solver::hold_still;

/// Why a [`WorldSurfaces`] call did nothing.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum WorldSurfaceError {
    /// The entity is not a prepared surface (still preparing, failed, or no surface at all).
    #[error("{0} is not a prepared surface")]
    NotASurface(Entity),
    /// No such simulation point.
    #[error("point {index} of a surface of {points} simulation points")]
    PointOutOfRange {
        /// The index given.
        index: usize,
        /// How many points the surface has.
        points: usize,
    },
    /// A position, radius or force that is not finite (or a negative radius).
    #[error("{what} is not a finite value ({value})")]
    NotFinite {
        /// What was given.
        what: &'static str,
        /// Its value (a radius in x).
        value: Vec3,
    },
}

/// The surfaces, in world coordinates: forces added where the game means them, and the
/// deformed surface where it is drawn. Use it in
/// [`PointSpringsSystems::Forces`](super::PointSpringsSystems::Forces) to push (the step
/// clears the forces after it), anywhere to read.
#[derive(SystemParam)]
pub struct WorldSurfaces<'w, 's> {
    surfaces: Query<
        'w,
        's,
        (
            &'static GlobalTransform,
            &'static SimulationPoints,
            &'static DenseSurface,
            &'static mut SurfaceForces,
        ),
    >,
}

impl std::fmt::Debug for WorldSurfaces<'_, '_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("WorldSurfaces")
            .field("surfaces", &self.surfaces.iter().len())
            .finish()
    }
}

/// A world force in a surface's own coordinates: a world acceleration F/m needs the local
/// force S⁻¹R⁻¹F where the surface is rotated by R and scaled by S.
fn local_force(transform: &GlobalTransform, force: Vec3) -> Vec3 {
    transform.affine().inverse().transform_vector3(force)
}

fn finite(what: &'static str, value: Vec3) -> Result<(), WorldSurfaceError> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(WorldSurfaceError::NotFinite { what, value })
    }
}

impl WorldSurfaces<'_, '_> {
    /// Adds `force` (world coordinates, newtons) to every simulation point of `surface`.
    pub fn push_all(&mut self, surface: Entity, force: Vec3) -> Result<(), WorldSurfaceError> {
        finite("the force", force)?;
        let (transform, _, _, mut forces) = self
            .surfaces
            .get_mut(surface)
            .map_err(|_| WorldSurfaceError::NotASurface(surface))?;
        let local = local_force(transform, force);
        for i in 0..forces.len() {
            // In range and finite: checked above.
            let _ = forces.add(i, local);
        }
        Ok(())
    }

    /// Adds `force` (world coordinates) to each simulation point of `surface` within
    /// `radius` of `at` (world coordinates, where the points are now). Returns how many.
    pub fn push_near(
        &mut self,
        surface: Entity,
        at: Vec3,
        radius: f32,
        force: Vec3,
    ) -> Result<usize, WorldSurfaceError> {
        finite("the force", force)?;
        finite("the centre", at)?;
        if !(radius.is_finite() && radius >= 0.0) {
            return Err(WorldSurfaceError::NotFinite {
                what: "the radius",
                value: Vec3::new(radius, 0.0, 0.0),
            });
        }
        let (transform, points, _, mut forces) = self
            .surfaces
            .get_mut(surface)
            .map_err(|_| WorldSurfaceError::NotASurface(surface))?;
        let local = local_force(transform, force);
        let mut pushed = 0;
        for (i, p) in points.iter_positions().enumerate() {
            if transform.transform_point(p).distance_squared(at) <= radius * radius {
                let _ = forces.add(i, local);
                pushed += 1;
            }
        }
        Ok(pushed)
    }

    /// The simulation points' positions now, in world coordinates.
    pub fn points(&self, surface: Entity) -> Result<Vec<Vec3>, WorldSurfaceError> {
        let (transform, points, _, _) = self
            .surfaces
            .get(surface)
            .map_err(|_| WorldSurfaceError::NotASurface(surface))?;
        Ok(points
            .iter_positions()
            .map(|p| transform.transform_point(p))
            .collect())
    }

    /// The deformed dense surface as last transferred (what is drawn): positions and unit
    /// normals in world coordinates.
    pub fn dense(&self, surface: Entity) -> Result<(Vec<Vec3>, Vec<Vec3>), WorldSurfaceError> {
        let (transform, _, dense, _) = self
            .surfaces
            .get(surface)
            .map_err(|_| WorldSurfaceError::NotASurface(surface))?;
        // Normals go by the inverse transpose, so that a stretched surface keeps them
        // perpendicular to it.
        let normal_map = transform.affine().matrix3.inverse().transpose();
        let positions = dense
            .positions()
            .iter()
            .map(|&p| transform.transform_point(p))
            .collect();
        let normals = dense
            .normals()
            .iter()
            .map(|&n| Vec3::from(normal_map * Vec3A::from(n)).normalize_or(n))
            .collect();
        Ok((positions, normals))
    }
}

/// Pins and frees a surface's simulation points at run time: a pinned point stays where it
/// is (its velocity zeroed; no force, gravity or spring moves it) until it is freed. This
/// is the one way for a game to pin; the core's
/// [`Masses::set_pinned`](crate::core::solver::Masses::set_pinned) alone leaves a moving
/// point drifting.
#[derive(SystemParam)]
pub struct SurfacePins<'w, 's> {
    surfaces: Query<
        'w,
        's,
        (
            &'static GlobalTransform,
            &'static mut SimulationPoints,
            &'static mut SurfaceMasses,
        ),
    >,
}

impl std::fmt::Debug for SurfacePins<'_, '_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SurfacePins")
            .field("surfaces", &self.surfaces.iter().len())
            .finish()
    }
}

impl SurfacePins<'_, '_> {
    /// Pins simulation point `i` of `surface` where it is, and stops it.
    pub fn pin(&mut self, surface: Entity, i: usize) -> Result<(), WorldSurfaceError> {
        self.set(surface, i, true)
    }

    /// Frees simulation point `i` of `surface` (forces move it again from the next step).
    pub fn free(&mut self, surface: Entity, i: usize) -> Result<(), WorldSurfaceError> {
        self.set(surface, i, false)
    }

    /// Pins (`pinned`) or frees point `i`.
    fn set(&mut self, surface: Entity, i: usize, pinned: bool) -> Result<(), WorldSurfaceError> {
        let (_, mut points, mut masses) = self
            .surfaces
            .get_mut(surface)
            .map_err(|_| WorldSurfaceError::NotASurface(surface))?;
        let count = masses.len().min(points.len());
        if i >= count {
            return Err(WorldSurfaceError::PointOutOfRange {
                index: i,
                points: count,
            });
        }
        if pinned {
            // In range: checked above.
            let _ = hold_still(&mut masses.0, &mut points, |j| j == i);
        } else {
            let _ = masses.0.set_pinned(i, false);
        }
        Ok(())
    }

    /// Pins, and stops, every simulation point of `surface` within `radius` of `at` (world
    /// coordinates, where the points are now). Returns how many.
    pub fn pin_near(
        &mut self,
        surface: Entity,
        at: Vec3,
        radius: f32,
    ) -> Result<usize, WorldSurfaceError> {
        finite("the centre", at)?;
        if !(radius.is_finite() && radius >= 0.0) {
            return Err(WorldSurfaceError::NotFinite {
                what: "the radius",
                value: Vec3::new(radius, 0.0, 0.0),
            });
        }
        let (transform, points, _) = self
            .surfaces
            .get(surface)
            .map_err(|_| WorldSurfaceError::NotASurface(surface))?;
        let near: Vec<bool> = points
            .iter_positions()
            .map(|p| transform.transform_point(p).distance_squared(at) <= radius * radius)
            .collect();
        self.pin_where(surface, |j| near[j])
    }

    /// Pins, and stops, every simulation point of `surface` that `held` picks by index (to
    /// pick by rest position, read them from [`SurfaceNetwork`](super::SurfaceNetwork)).
    /// Returns how many.
    pub fn pin_where(
        &mut self,
        surface: Entity,
        held: impl Fn(usize) -> bool,
    ) -> Result<usize, WorldSurfaceError> {
        let (_, mut points, mut masses) = self
            .surfaces
            .get_mut(surface)
            .map_err(|_| WorldSurfaceError::NotASurface(surface))?;
        let count = masses.len().min(points.len());
        hold_still(&mut masses.0, &mut points, |j| j < count && held(j)).map_err(|_| {
            WorldSurfaceError::PointOutOfRange {
                index: count,
                points: count,
            }
        })
    }

    /// Whether point `i` of `surface` is pinned (`None`: no such surface or point).
    pub fn is_pinned(&self, surface: Entity, i: usize) -> Option<bool> {
        let (_, _, masses) = self.surfaces.get(surface).ok()?;
        (i < masses.len()).then(|| masses.is_pinned(i))
    }
}

/// Which way a surface's gravity points. Gravity
/// ([`SolverConfig::gravity`](crate::core::solver::SolverConfig)) is the world's: each tick
/// the plugin turns it into the surface's own coordinates by the surface's transform, so
/// that a surface however turned falls down, as rapier's and avian's bodies do. Optional: a
/// surface without it has [`SurfaceGravity::World`].
#[derive(Component, Debug, Clone, Copy, PartialEq, Eq, Default, Reflect)]
#[reflect(Component, Debug, Default)]
pub enum SurfaceGravity {
    /// Gravity is the world's, whatever the surface's transform (the default).
    #[default]
    World,
    /// Gravity is in the surface's own coordinates: it turns with the surface (a surface
    /// turned upside down falls up).
    Own,
}

/// Sets each surface's gravity frame ([`Stepper::set_gravity_frame`]) from its transform
/// and [`SurfaceGravity`]; a surface whose gravity changed is woken.
///
/// [`Stepper::set_gravity_frame`]: crate::core::solver::Stepper::set_gravity_frame
pub(crate) fn apply_world_gravity(
    mut surfaces: Query<(
        Entity,
        Option<&SurfaceGravity>,
        &GlobalTransform,
        &mut SurfaceStepper,
        &mut SurfaceSleep,
    )>,
) {
    for (entity, gravity, transform, mut stepper, mut sleep) in &mut surfaces {
        let frame = match gravity.copied().unwrap_or_default() {
            SurfaceGravity::World => {
                let linear = Mat3::from(transform.affine().matrix3);
                (linear != Mat3::IDENTITY).then(|| linear.inverse())
            }
            SurfaceGravity::Own => None,
        };
        if stepper.gravity_frame() == frame {
            continue;
        }
        let before = stepper.gravity();
        match stepper.bypass_change_detection().0.set_gravity_frame(frame) {
            Ok(()) if stepper.gravity() != before => sleep.wake(),
            Ok(()) => {}
            Err(e) => warn!("point-springs surface {entity}: world gravity not applied: {e}"),
        }
    }
}
