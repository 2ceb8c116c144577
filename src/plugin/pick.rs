//! Poking and dragging with the mouse (feature `render`): a picking backend that casts each
//! pointer's ray against the surfels, and a thin adapter from pointer events to
//! [`GrabMessage`]s.
//!
//! Bevy's mesh picking cannot see a surface drawn from a storage buffer, so this module's
//! backend casts the rays of [`RayMap`] against every surface's deformed dense points as discs
//! ([`ray_cast_surfels`]) and reports [`PointerHits`]; any surface is pickable, open or closed,
//! at rest or deformed. A press of [`PointerGrabSettings::button`] on
//! a surface starts a grab at the hit; while the button is held, the grab's target follows the
//! pointer's ray on the drag plane (through the hit, facing the camera); a release, or the
//! pointer's cancel, ends it. Games and tests can send the same [`GrabMessage`]s themselves.
//!
//! Add [`SurfacePickingPlugin`] next to `DefaultPlugins` (which bring Bevy's picking).

use bevy::picking::PickingSystems;
use bevy::picking::backend::ray::{RayId, RayMap};
use bevy::picking::backend::{HitData, PointerHits};
use bevy::picking::pointer::{PointerAction, PointerButton, PointerId, PointerInput};
use bevy::picking::prelude::{Pointer, Press};
use bevy::platform::collections::HashMap;
use bevy::prelude::*;

use crate::core::cloud::surfels::{
    DEFAULT_SURFEL_SCALE, MAX_SURFEL_STRETCH, ray_cast_surfels, surfel_radii,
};

use super::components::{DeformableSurface, DenseSurface, GpuTransferInput, SimulationPoints};
use super::grab::GrabMessage;
use super::render::SurfelRender;

/// Picking and grabbing surfaces with pointers.
#[derive(Debug, Default)]
pub struct SurfacePickingPlugin;

impl Plugin for SurfacePickingPlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<PointerGrabSettings>()
            .init_resource::<PointerGrabSettings>()
            .init_resource::<PointerGrabs>()
            .init_resource::<RayMap>()
            .add_message::<PointerHits>()
            .add_message::<Pointer<Press>>()
            .add_message::<PointerInput>()
            .add_systems(PreUpdate, surfel_picking.in_set(PickingSystems::Backend))
            .add_systems(
                PreUpdate,
                (grab_on_press, drag_grabs, release_grabs)
                    .chain()
                    .in_set(PickingSystems::Last),
            );
    }
}

/// Which pointer button grabs a surface.
#[derive(Resource, Reflect, Debug, Clone, Copy, PartialEq)]
#[reflect(Resource)]
pub struct PointerGrabSettings {
    /// The button that grabs (the primary one by default).
    pub button: PointerButton,
}

impl Default for PointerGrabSettings {
    fn default() -> Self {
        Self {
            button: PointerButton::Primary,
        }
    }
}

/// A pointer's grab: the camera it was pressed through and the drag plane.
#[derive(Debug, Clone, Copy)]
struct DragPlane {
    camera: Entity,
    /// A point of the plane (the hit), world space.
    point: Vec3,
    /// The plane's unit normal (towards the camera).
    normal: Vec3,
    /// The last target sent.
    last: Vec3,
}

/// The grabs pointers hold, by pointer.
#[derive(Resource, Debug, Default)]
pub struct PointerGrabs {
    active: HashMap<PointerId, DragPlane>,
}

impl PointerGrabs {
    /// Whether `pointer` holds a grab.
    pub fn holds(&self, pointer: PointerId) -> bool {
        self.active.contains_key(&pointer)
    }
}

/// The [`GrabMessage`] key of a pointer.
pub fn grab_key(pointer: PointerId) -> u64 {
    match pointer {
        PointerId::Mouse => 0,
        PointerId::Touch(id) => id.wrapping_add(1),
        PointerId::Custom(uuid) => uuid.as_u64_pair().0 | 1 << 63,
    }
}

/// What the picking backend keeps of a surface between frames.
#[derive(Debug, Default)]
pub(crate) struct PickCache {
    /// Disc radius of each dense point (from the rest cloud).
    radii: Vec<f32>,
    /// The dense surface's revision the bounds were taken at.
    revision: Option<u64>,
    /// Bounds of the discs, in the surface's space.
    bounds: (Vec3, Vec3),
    /// How far the dense surface reached past its simulation points at rest, plus the
    /// largest disc grown to its most: the margin of the box around a GPU-drawn surface's
    /// simulation points.
    gpu_margin: f32,
}

/// The bounds of `points`, grown by `margin`.
fn bounds_of(points: impl Iterator<Item = Vec3>, margin: f32) -> (Vec3, Vec3) {
    let (lo, hi) = points.fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(p), hi.max(p)),
    );
    (lo - Vec3::splat(margin), hi + Vec3::splat(margin))
}

/// What the picking backend reads of a surface.
type PickParts = (
    Entity,
    &'static mut DenseSurface,
    &'static SimulationPoints,
    Has<GpuTransferInput>,
    &'static GlobalTransform,
    Option<&'static SurfelRender>,
);

/// The picking backend: each pointer's ray against each surface's surfels (after a test
/// against the bounds of its discs, kept until the surface moves). A surface drawn by the
/// GPU ([`GpuTransferInput`]) keeps no current dense surface on the CPU: its box is that
/// of its simulation points, grown by how far the dense surface reached past them at rest,
/// and only when a ray meets it is the dense surface brought up to date on the CPU.
pub(crate) fn surfel_picking(
    ray_map: Res<RayMap>,
    cameras: Query<&Camera>,
    mut surfaces: Query<PickParts>,
    mut caches: Local<HashMap<Entity, PickCache>>,
    mut hits: MessageWriter<PointerHits>,
) {
    caches.retain(|e, _| surfaces.contains(*e));
    if ray_map.map.is_empty() {
        return;
    }
    for (entity, dense, points, gpu, _, render) in &surfaces {
        let cache = caches.entry(entity).or_default();
        let positions = dense.positions();
        if cache.radii.len() != positions.len() {
            let scale = render.map_or(DEFAULT_SURFEL_SCALE, |r| r.radius_scale);
            let rest = dense.transfer();
            cache.radii = surfel_radii(rest.rest_positions(), scale);
            let reach = cache.radii.iter().copied().fold(0.0, f32::max);
            let dense_box = bounds_of(rest.rest_positions().iter().copied(), 0.0);
            let sim_box = bounds_of(rest.simulation_rest().iter().copied(), 0.0);
            let past = (sim_box.0 - dense_box.0)
                .max(dense_box.1 - sim_box.1)
                .max(Vec3::ZERO)
                .max_element();
            cache.gpu_margin = past + MAX_SURFEL_STRETCH * reach;
            cache.revision = None;
        }
        if gpu {
            cache.bounds = bounds_of(points.iter_positions(), cache.gpu_margin);
        } else if cache.revision != Some(dense.revision()) {
            let reach = cache.radii.iter().copied().fold(0.0, f32::max);
            cache.bounds = bounds_of(positions.iter().copied(), reach);
            cache.revision = Some(dense.revision());
        }
    }
    for (&RayId { camera, pointer }, ray) in ray_map.iter() {
        let mut picks = Vec::new();
        for (entity, mut dense, points, gpu, place, _) in &mut surfaces {
            let Some(cache) = caches.get(&entity) else {
                continue;
            };
            // The ray in the surface's space.
            let to_local = place.affine().inverse();
            let origin = to_local.transform_point3(ray.origin);
            let direction = to_local.transform_vector3(*ray.direction);
            if !ray_meets_box(origin, direction, cache.bounds) {
                continue;
            }
            if gpu && let Err(e) = super::simulate::follow(&mut dense.0, points) {
                warn!("point-springs: picking surface {entity}: {e}");
                continue;
            }
            let Some(hit) = ray_cast_surfels(
                dense.positions(),
                dense.normals(),
                &cache.radii,
                origin,
                direction,
                f32::INFINITY,
            ) else {
                continue;
            };
            let position = place.transform_point(hit.position);
            let normal = place
                .affine()
                .transform_vector3(hit.normal)
                .normalize_or_zero();
            let depth = position.distance(ray.origin);
            picks.push((
                entity,
                HitData::new(camera, depth, Some(position), Some(normal)),
            ));
        }
        if !picks.is_empty() {
            let order = cameras.get(camera).map_or(0.0, |c| c.order as f32);
            hits.write(PointerHits::new(pointer, picks, order));
        }
    }
}

/// Whether the ray from `origin` along `direction` meets the box `(min, max)` (slab test).
fn ray_meets_box(origin: Vec3, direction: Vec3, (min, max): (Vec3, Vec3)) -> bool {
    let inverse = direction.recip();
    let (a, b) = ((min - origin) * inverse, (max - origin) * inverse);
    let near = a.min(b).max_element();
    let far = a.max(b).min_element();
    // NaN (a zero direction component with the origin on a slab's plane) counts as a meet.
    !(near > far || far < 0.0)
}

/// A press of the grab button on a surface starts a grab at the hit.
fn grab_on_press(
    mut presses: MessageReader<Pointer<Press>>,
    surfaces: Query<(), With<DeformableSurface>>,
    cameras: Query<&GlobalTransform>,
    settings: Res<PointerGrabSettings>,
    mut pointers: ResMut<PointerGrabs>,
    mut grabs: MessageWriter<GrabMessage>,
) {
    for press in presses.read() {
        if press.button != settings.button || !surfaces.contains(press.entity) {
            continue;
        }
        let (Some(at), Ok(eye)) = (press.hit.position, cameras.get(press.hit.camera)) else {
            continue;
        };
        let normal = (eye.translation() - at).normalize_or(Vec3::Y);
        pointers.active.insert(
            press.pointer_id,
            DragPlane {
                camera: press.hit.camera,
                point: at,
                normal,
                last: at,
            },
        );
        grabs.write(GrabMessage::Start {
            key: grab_key(press.pointer_id),
            surface: press.entity,
            at,
        });
    }
}

/// While a grab is held, its target follows the pointer's ray on the drag plane.
fn drag_grabs(
    ray_map: Res<RayMap>,
    mut pointers: ResMut<PointerGrabs>,
    mut grabs: MessageWriter<GrabMessage>,
) {
    for (&pointer, plane) in &mut pointers.active {
        let Some(ray) = ray_map.map.get(&RayId::new(plane.camera, pointer)) else {
            continue; // off the camera's viewport: the grab stays where it was
        };
        let facing = ray.direction.dot(plane.normal);
        if facing.abs() <= f32::EPSILON {
            continue;
        }
        let t = (plane.point - ray.origin).dot(plane.normal) / facing;
        if t < 0.0 {
            continue;
        }
        let target = ray.origin + *ray.direction * t;
        if target != plane.last {
            plane.last = target;
            grabs.write(GrabMessage::Move {
                key: grab_key(pointer),
                target,
            });
        }
    }
}

/// A release of the grab button (anywhere) or a cancelled pointer ends its grab.
fn release_grabs(
    mut inputs: MessageReader<PointerInput>,
    settings: Res<PointerGrabSettings>,
    mut pointers: ResMut<PointerGrabs>,
    mut grabs: MessageWriter<GrabMessage>,
) {
    for input in inputs.read() {
        let ends = match input.action {
            PointerAction::Release(button) => button == settings.button,
            PointerAction::Cancel => true,
            _ => false,
        };
        if ends && pointers.active.remove(&input.pointer_id).is_some() {
            grabs.write(GrabMessage::End {
                key: grab_key(input.pointer_id),
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use bevy::picking::pointer::PointerId;
    use bevy::prelude::*;

    use super::{grab_key, ray_meets_box};

    #[test]
    fn rays_meet_boxes_they_pass_through_and_only_ahead() {
        let unit = (Vec3::splat(-1.0), Vec3::ONE);
        assert!(ray_meets_box(Vec3::Z * 5.0, -Vec3::Z, unit));
        assert!(
            !ray_meets_box(Vec3::Z * 5.0, Vec3::Z, unit),
            "behind the origin"
        );
        assert!(!ray_meets_box(Vec3::new(1.5, 0.0, 5.0), -Vec3::Z, unit));
        assert!(ray_meets_box(Vec3::ZERO, Vec3::X, unit), "from inside");
        // Along an axis, on a face's plane: counted as meeting (a pick is then tested in full).
        assert!(ray_meets_box(Vec3::new(1.0, 0.0, 5.0), -Vec3::Z, unit));
        assert!(ray_meets_box(
            Vec3::new(3.0, 3.0, 0.0),
            Vec3::new(-1.0, -1.0, 0.0).normalize(),
            unit
        ));
    }

    #[test]
    fn pointers_get_distinct_grab_keys() {
        let keys = [
            grab_key(PointerId::Mouse),
            grab_key(PointerId::Touch(0)),
            grab_key(PointerId::Touch(1)),
            grab_key(PointerId::Custom(bevy::asset::uuid::Uuid::from_u128(7))),
        ];
        for (i, a) in keys.iter().enumerate() {
            assert!(keys[i + 1..].iter().all(|b| a != b), "{keys:?}");
        }
    }
}
