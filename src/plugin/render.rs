//! Drawing (feature `render`): each dense point of a surface is a lit disc facing along its
//! normal (a surfel), and the discs follow the transfer every frame.
//!
//! **How.** Surfaces with the same look (colour) share one material and one storage buffer
//! ([`ShaderBuffer`]) holding every surfel of theirs: position and radius, normal (32 bytes
//! each). Each frame the buffer is rewritten in place from the surfaces' deformed points —
//! one copy, no new mesh and no new material. Each surface draws a static index mesh of
//! hexagons (six corners per surfel) whose vertex shader (`surfel.wgsl`) pulls its surfel
//! from the buffer, starting at the surface's offset (its [`MeshTag`]); the fragment is
//! StandardMaterial's PBR, so the surfels are lit like any mesh. A surface whose point
//! count outgrows its slot (resampling) gets a larger slot, and the batch a larger buffer.
//!
//! Optional gizmos ([`SpringGizmos`]) draw the simulation points, the hinges and the stretch and bend
//! springs in two colours.

use std::collections::HashMap;
use std::sync::Arc;
use std::time::Instant;

use bevy::asset::{AssetEventSystems, AssetPath, RenderAssetUsages, embedded_asset, embedded_path};
use bevy::camera::visibility::NoFrustumCulling;
use bevy::ecs::system::SystemParam;
use bevy::material::OpaqueRendererMethod;
use bevy::mesh::{Indices, MeshTag, MeshVertexBufferLayoutRef, PrimitiveTopology};
use bevy::pbr::{
    ExtendedMaterial, MaterialExtension, MaterialExtensionKey, MaterialExtensionPipeline,
};
use bevy::prelude::*;
use bevy::render::render_resource::{
    AsBindGroup, RenderPipelineDescriptor, SpecializedMeshPipelineError,
};
use bevy::render::renderer::{RenderAdapterInfo, RenderDevice};
use bevy::render::storage::ShaderBuffer;
use bevy::shader::{ShaderDefVal, ShaderRef};
use wgpu_types::DeviceType;

use super::PointSpringsSystems;
use super::components::{
    DenseSurface, GpuTransferInput, SimulationPoints, SurfaceNetwork, SurfaceSprings,
    SurfaceTimings,
};
use super::gpu_transfer::GpuSurfels;
use crate::core::cloud::surfels::{DEFAULT_SURFEL_SCALE, SURFEL_BYTES, SurfelShape, pack_surfels};
use crate::core::solver::angle_difference;
use crate::core::transfer::gpu::{GpuTransferLayout, POINT_WORDS};

/// Corners of a surfel's hexagon.
const CORNERS: usize = 6;

/// The hexagon circumscribes the disc of the surfel's radius (1 / cos 30°).
const HEXAGON_SCALE: f32 = 1.154_700_5;

/// Smallest slot (surfels) a surface gets.
const MIN_SLOT: usize = 64;

/// From this many dense points [`TransferDevice::Auto`] transfers on the GPU (where the
/// adapter is one: a software rasteriser such as lavapipe keeps the CPU path).
pub const GPU_TRANSFER_MIN_POINTS: usize = 100_000;

/// Depth bias of the spring gizmos (−1 draws over everything, 0 is plain depth testing).
const GIZMO_DEPTH_BIAS: f32 = -0.01;

/// Adds surfel drawing and the spring gizmos. Needs Bevy's renderer (`DefaultPlugins`)
/// and [`PointSpringsPlugin`](super::PointSpringsPlugin).
#[derive(Debug, Default, Clone, Copy)]
pub struct SurfelRenderPlugin;

impl Plugin for SurfelRenderPlugin {
    fn build(&self, app: &mut App) {
        if !super::has_renderer(app) {
            debug!("point-springs: no renderer, surfaces are not drawn");
            return;
        }
        embedded_asset!(app, "surfel.wgsl");
        app.add_plugins(MaterialPlugin::<SurfelMaterial>::default())
            .register_type::<SurfelRender>()
            .register_type::<SpringGizmos>()
            .init_resource::<SurfelBatches>()
            .init_resource::<SpringGizmos>()
            // Springs are chords of the curved surface and dip under its discs: drawn with
            // a depth bias so that the front ones show.
            .insert_gizmo_config(
                SpringGizmos::default(),
                GizmoConfig {
                    depth_bias: GIZMO_DEPTH_BIAS,
                    ..default()
                },
            )
            // Before the assets' events are sent: the buffer written this frame is drawn this
            // frame (after them, its `Modified` event would wait a frame, and the surfels be
            // drawn a frame behind the meshes).
            .add_systems(
                PostUpdate,
                (attach_surfels, layout_gpu_surfels, upload_surfels)
                    .chain()
                    .after(PointSpringsSystems::Transfer)
                    .before(AssetEventSystems),
            )
            .add_systems(Update, draw_gizmos);
        super::view::add_systems(app);
        super::gpu_transfer::build(app);
    }

    fn finish(&self, app: &mut App) {
        // Added before the renderer, `build` found none: say so now that the log is up.
        if super::has_renderer(app) && !app.world().contains_resource::<SurfelBatches>() {
            warn!(
                "point-springs: SurfelRenderPlugin was added before DefaultPlugins: surfaces \
                 are not drawn (add PointSpringsPlugins after DefaultPlugins)"
            );
        }
    }
}

/// The material of surfels: StandardMaterial's shading with the surfel vertex shader.
pub type SurfelMaterial = ExtendedMaterial<StandardMaterial, SurfelExtension>;

/// The surfel part of [`SurfelMaterial`]: the storage buffer of a batch.
#[derive(Asset, AsBindGroup, Reflect, Debug, Clone)]
pub struct SurfelExtension {
    /// Position and radius, normal and padding of each surfel of the batch.
    #[storage(100, read_only)]
    pub surfels: Handle<ShaderBuffer>,
}

fn surfel_shader() -> ShaderRef {
    ShaderRef::Path(AssetPath::from_path_buf(embedded_path!("surfel.wgsl")).with_source("embedded"))
}

impl MaterialExtension for SurfelExtension {
    fn vertex_shader() -> ShaderRef {
        surfel_shader()
    }

    // The prepass (and with it the shadow maps) runs the same vertex shader, so surfels
    // cast the shadows of their discs, and receive shadows (`NotShadowCaster` and
    // `NotShadowReceiver` on the surface are honoured as for any mesh).
    fn prepass_vertex_shader() -> ShaderRef {
        surfel_shader()
    }

    fn specialize(
        _pipeline: &MaterialExtensionPipeline,
        descriptor: &mut RenderPipelineDescriptor,
        _layout: &MeshVertexBufferLayoutRef,
        _key: MaterialExtensionKey<Self>,
    ) -> Result<(), SpecializedMeshPipelineError> {
        // The main pass computes its normals; never read the view's prepass normals.
        if let Some(fragment) = descriptor.fragment.as_mut() {
            fragment.shader_defs.retain(
                |d| !matches!(d, ShaderDefVal::Bool(name, _) if name == "LOAD_PREPASS_NORMALS"),
            );
        }
        Ok(())
    }
}

/// Draw this surface as surfels.
#[derive(Component, Debug, Clone, Reflect)]
#[reflect(Component, Debug)]
#[require(Visibility)]
pub struct SurfelRender {
    /// Disc radius as a multiple of the distance to the point's
    /// [`SURFEL_NEIGHBOURS`](crate::core::cloud::surfels::SURFEL_NEIGHBOURS)-th neighbour at rest.
    pub radius_scale: f32,
    /// Surface colour (surfaces of one colour share a material).
    pub color: Color,
    /// Where the dense surface is computed for drawing.
    pub device: TransferDevice,
}

impl Default for SurfelRender {
    fn default() -> Self {
        Self {
            radius_scale: DEFAULT_SURFEL_SCALE,
            color: Color::srgb(0.85, 0.62, 0.38),
            device: TransferDevice::Auto,
        }
    }
}

/// Where a drawn surface's transfer runs each frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Reflect)]
pub enum TransferDevice {
    /// The GPU from [`GPU_TRANSFER_MIN_POINTS`] dense points on, where the adapter is a GPU
    /// (not a software rasteriser); the CPU otherwise.
    #[default]
    Auto,
    /// The CPU: the transfer on Bevy's compute pool, the surfel records packed and uploaded
    /// (32 bytes a dense point a frame). [`DenseSurface`] follows every frame.
    Cpu,
    /// The GPU, whatever the size or the adapter: a compute pass writes the surfel records
    /// (see [`gpu_transfer`](super::gpu_transfer)); only the simulation points are uploaded,
    /// and [`DenseSurface`] is brought up to date only where the plugin reads it. Falls
    /// back to the CPU (logged) where the device cannot bind the surface's arrays.
    Gpu,
}

/// Whether `render`'s surface of `dense` points transfers on the GPU of `adapter` (none:
/// no renderer), whose storage bindings hold at most `limit` bytes.
fn on_gpu(
    render: &SurfelRender,
    dense: &DenseSurface,
    adapter: Option<&RenderAdapterInfo>,
    limit: u64,
) -> bool {
    wants_gpu(render.device, dense.len(), adapter.map(|a| a.device_type))
        && gpu_arrays_fit(dense, limit)
}

/// Whether `device` asks for the GPU for `points` dense points on an adapter of type
/// `adapter` (none: no renderer, so no GPU).
fn wants_gpu(device: TransferDevice, points: usize, adapter: Option<DeviceType>) -> bool {
    let Some(adapter) = adapter else {
        return false;
    };
    match device {
        TransferDevice::Cpu => false,
        TransferDevice::Gpu => true,
        TransferDevice::Auto => points >= GPU_TRANSFER_MIN_POINTS && adapter != DeviceType::Cpu,
    }
}

/// Whether the largest array of a surface's GPU layout fits one storage binding.
fn gpu_arrays_fit(dense: &DenseSurface, limit: u64) -> bool {
    let transfer = dense.transfer();
    let k = transfer.config().k.min(transfer.simulation_points()).max(1);
    let per_point = [k, (3 * (k - 1)).max(1), POINT_WORDS]
        .into_iter()
        .max()
        .unwrap_or(POINT_WORDS);
    let largest = (dense.len() as u64) * (per_point as u64) * 4;
    let fits = largest <= limit;
    if !fits {
        warn!(
            "a surface of {} dense points needs {largest} bytes in one storage binding, the \
             device binds {limit}: it is transferred on the CPU",
            dense.len()
        );
    }
    fits
}

/// What to draw over the surfaces with gizmos (a resource; all off by default).
#[derive(Resource, Debug, Clone, Copy, Default, Reflect, GizmoConfigGroup)]
#[reflect(Resource, Debug)]
pub struct SpringGizmos {
    /// The simulation points, as small crosses.
    pub points: bool,
    /// The stretch springs.
    pub stretch: bool,
    /// The bend springs.
    pub bend: bool,
    /// The hinges (bending on hinges): each hinge's edge, from green at its rest angle to red
    /// bent [`HINGE_GIZMO_FULL_BEND`] or more past it.
    pub hinges: bool,
}

/// The bend (radians past the rest angle) a hinge gizmo shows in full red.
pub const HINGE_GIZMO_FULL_BEND: f32 = 0.5;

/// A look: the colour's bits, and whether the GPU writes the batch's buffer (a batch is
/// written either by the CPU or by the GPU, never both).
type LookKey = ([u32; 4], bool);

fn look(color: Color, gpu: bool) -> LookKey {
    (color.to_linear().to_f32_array().map(f32::to_bits), gpu)
}

/// Surfaces of one look: their shared material and buffer, and each one's slot in it.
#[derive(Debug)]
struct Batch {
    material: Handle<SurfelMaterial>,
    buffer: Handle<ShaderBuffer>,
    /// Surfels the buffer holds.
    capacity: usize,
    /// Each member's first surfel and slot size, in order.
    members: Vec<(Entity, usize, usize)>,
    /// Whether the GPU writes the buffer (the main world never does then).
    gpu: bool,
}

/// A batch's buffer of `capacity` surfels (zeros: radius 0 draws nothing). One the GPU
/// writes has no data in the main world, and the CPU never writes it.
fn surfel_buffer(capacity: usize, gpu: bool) -> ShaderBuffer {
    let bytes = SURFEL_BYTES * capacity;
    if gpu {
        ShaderBuffer::with_size(bytes, RenderAssetUsages::RENDER_WORLD)
    } else {
        ShaderBuffer::new(&vec![0u8; bytes], RenderAssetUsages::RENDER_WORLD)
    }
}

impl Batch {
    fn used(&self) -> usize {
        self.members
            .last()
            .map_or(0, |&(_, first, slot)| first + slot)
    }
}

/// The batches of surfels, one per look.
#[derive(Resource, Debug, Default)]
pub struct SurfelBatches {
    batches: HashMap<LookKey, Batch>,
}

impl SurfelBatches {
    /// Number of materials (and storage buffers) in use.
    pub fn materials(&self) -> usize {
        self.batches.len()
    }
}

/// A drawn surface's place in its batch.
#[derive(Component, Debug)]
pub struct SurfelSlot {
    look: LookKey,
    /// Surfels the slot (and the index mesh) holds.
    slot: usize,
    /// Each dense point's disc at rest and the surface's edge.
    shape: SurfelShape,
    /// The dense surface's revision last uploaded.
    uploaded: u64,
    /// The network the radii were measured for (its address): a bake or a new preparation
    /// replaces it, and with it the dense surface's rest shape.
    network: usize,
    /// Names `shape` (a new one each time it is measured), for the GPU layout.
    shape_id: u64,
    /// The setting the device was chosen for.
    device: TransferDevice,
}

impl SurfelSlot {
    /// Whether the GPU writes this surface's surfels.
    pub fn on_gpu(&self) -> bool {
        self.look.1
    }
}

/// A new [`SurfelSlot::shape_id`].
fn next_shape_id() -> u64 {
    use std::sync::atomic::{AtomicU64, Ordering};
    static NEXT: AtomicU64 = AtomicU64::new(1);
    NEXT.fetch_add(1, Ordering::Relaxed)
}

/// The address of a surface's network, which a bake or a preparation replaces.
fn network_key(network: &SurfaceNetwork) -> usize {
    Arc::as_ptr(&network.0) as usize
}

/// A static index mesh of `slot` hexagons.
fn index_mesh(slot: usize) -> Mesh {
    let corners: [[f32; 3]; CORNERS] = std::array::from_fn(|k| {
        let a = k as f32 * std::f32::consts::TAU / CORNERS as f32;
        [HEXAGON_SCALE * a.cos(), HEXAGON_SCALE * a.sin(), 0.0]
    });
    let mut positions = Vec::with_capacity(slot * CORNERS);
    let mut indices = Vec::with_capacity(slot * (CORNERS - 2) * 3);
    for i in 0..slot as u32 {
        positions.extend_from_slice(&corners);
        let b = CORNERS as u32 * i;
        for k in 1..CORNERS as u32 - 1 {
            indices.extend_from_slice(&[b, b + k, b + k + 1]);
        }
    }
    Mesh::new(
        PrimitiveTopology::TriangleList,
        RenderAssetUsages::RENDER_WORLD,
    )
    .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, positions)
    .with_inserted_indices(Indices::U32(indices))
}

/// The surfels of a dense surface at rest, as `render` sizes them.
fn shape_of(dense: &DenseSurface, render: &SurfelRender) -> SurfelShape {
    let rest = dense.transfer();
    SurfelShape::at_rest(
        rest.rest_positions(),
        rest.rest_normals(),
        render.radius_scale,
    )
}

/// The slot for `points` surfels: a power of two, so that resampling rarely outgrows it.
fn slot_for(points: usize) -> usize {
    points.max(MIN_SLOT).next_power_of_two()
}

/// The assets [`attach_surfels`] adds to: meshes, materials and buffers.
#[derive(SystemParam)]
struct SurfelAssets<'w> {
    meshes: ResMut<'w, Assets<Mesh>>,
    materials: ResMut<'w, Assets<SurfelMaterial>>,
    buffers: ResMut<'w, Assets<ShaderBuffer>>,
}

/// The device the renderer runs on (none in a headless app).
#[derive(SystemParam)]
struct Adapter<'w> {
    info: Option<Res<'w, RenderAdapterInfo>>,
    device: Option<Res<'w, RenderDevice>>,
}

impl Adapter<'_> {
    /// Bytes one storage binding may hold.
    fn binding_limit(&self) -> u64 {
        self.device
            .as_ref()
            .map_or(0, |d| d.limits().max_storage_buffer_binding_size)
    }
}

/// What [`attach_surfels`] reads and changes of a surface.
type AttachParts = (
    Entity,
    (&'static DenseSurface, &'static SimulationPoints),
    &'static SurfaceNetwork,
    &'static SurfelRender,
    Option<&'static mut SurfelSlot>,
);

/// Gives new (or outgrown) drawn surfaces a slot, a mesh and their batch's material.
fn attach_surfels(
    mut commands: Commands,
    mut batches: ResMut<SurfelBatches>,
    mut assets: SurfelAssets,
    adapter: Adapter,
    mut surfaces: Query<AttachParts>,
    mut removed: RemovedComponents<SurfelSlot>,
) {
    // Forget despawned surfaces (their slots are reused when the batch is laid out anew).
    for entity in removed.read() {
        batches.forget(entity);
    }
    let limit = adapter.binding_limit();
    for (entity, (dense, points), network, render, slot) in &mut surfaces {
        // Decided once per slot and setting: a size that crosses the threshold by
        // resampling keeps its device until the slot is outgrown.
        let gpu = match &slot {
            Some(slot) if slot.device == render.device && dense.len() <= slot.slot => slot.look.1,
            _ => on_gpu(render, dense, adapter.info.as_deref(), limit),
        };
        let key = look(render.color, gpu);
        let network = network_key(network);
        let mut slot = slot;
        if let Some(slot) = slot.as_mut().filter(|s| s.device != render.device) {
            slot.device = render.device;
        }
        let fits = slot.as_ref().is_some_and(|s| {
            s.look == key
                && s.network == network
                && s.shape.len() == dense.len()
                && dense.len() <= s.slot
        });
        if fits {
            continue;
        }
        if slot
            .as_ref()
            .is_some_and(|s| s.look == key && dense.len() <= s.slot)
        {
            // Grown within its slot (resampling), or given a new rest shape (a bake, a new
            // preparation): new radii only.
            if let Some(mut slot) = slot {
                slot.shape = shape_of(dense, render);
                slot.uploaded = 0;
                slot.network = network;
                slot.shape_id = next_shape_id();
            }
            continue;
        }
        // A new slot: leave the old batch, join (or found) the batch of this look.
        if let Some(batch) = slot
            .as_ref()
            .and_then(|old| batches.batches.get_mut(&old.look))
        {
            batch.members.retain(|m| m.0 != entity);
        }
        let size = slot_for(dense.len());
        let batch = batches
            .batches
            .entry(key)
            .or_insert_with(|| Batch::new(render.color, gpu, size, &mut assets));
        let first = batch.join(entity, size, &mut assets);
        let shape = shape_of(dense, render);
        let mut surface = commands.entity(entity);
        if gpu {
            // Drawn as the points are now until a transfer system hands over newer ones
            // (a paused or sleeping surface may not for a while).
            let mut input = GpuTransferInput::default();
            input.set(points);
            surface.insert(input);
        } else {
            surface.remove::<(GpuTransferInput, GpuSurfels)>();
        }
        surface.insert((
            SurfelSlot {
                look: key,
                slot: size,
                shape,
                uploaded: 0,
                network,
                shape_id: next_shape_id(),
                device: render.device,
            },
            Mesh3d(assets.meshes.add(index_mesh(size))),
            MeshMaterial3d(batch.material.clone()),
            MeshTag(first as u32),
            NoFrustumCulling,
        ));
    }
}

impl SurfelBatches {
    /// Drops a despawned surface from every batch.
    fn forget(&mut self, entity: Entity) {
        for batch in self.batches.values_mut() {
            batch.members.retain(|m| m.0 != entity);
        }
    }
}

impl Batch {
    /// A batch of surfels of `color` with a buffer of `capacity` surfels and no member,
    /// written by the GPU or the CPU.
    fn new(color: Color, gpu: bool, capacity: usize, assets: &mut SurfelAssets) -> Self {
        let buffer = assets.buffers.add(surfel_buffer(capacity, gpu));
        let material = assets.materials.add(SurfelMaterial {
            base: StandardMaterial {
                base_color: color,
                perceptual_roughness: 0.7,
                cull_mode: None,
                double_sided: true,
                opaque_render_method: OpaqueRendererMethod::Forward,
                ..default()
            },
            extension: SurfelExtension {
                surfels: buffer.clone(),
            },
        });
        Self {
            material,
            buffer,
            capacity,
            members: Vec::new(),
            gpu,
        }
    }

    /// Gives `entity` a slot of `size` surfels after the last member's, growing the buffer
    /// when it does not fit; returns the slot's first surfel.
    fn join(&mut self, entity: Entity, size: usize, assets: &mut SurfelAssets) -> usize {
        let first = self.used();
        self.members.push((entity, first, size));
        let needed = first + size;
        if needed > self.capacity {
            // A larger buffer under a new handle, and the material pointed at it (the old
            // buffer is freed once nothing uses it).
            self.capacity = needed.next_power_of_two();
            self.buffer = assets.buffers.add(surfel_buffer(self.capacity, self.gpu));
            if let Some(mut material) = assets.materials.get_mut(&self.material) {
                material.extension.surfels = self.buffer.clone();
            }
        }
        first
    }
}

/// Builds the GPU layout of each surface the GPU transfers, again when its transfer or
/// its surfel shape changed.
fn layout_gpu_surfels(
    mut commands: Commands,
    batches: Res<SurfelBatches>,
    mut surfaces: Query<(Entity, &DenseSurface, &SurfelSlot, Option<&mut GpuSurfels>)>,
) {
    for (entity, dense, slot, gpu) in &mut surfaces {
        if !slot.on_gpu() {
            continue;
        }
        let built_for = (dense.transfer_id(), slot.shape_id);
        if gpu.as_ref().is_some_and(|g| g.built_for == built_for) {
            continue;
        }
        let layout = match GpuTransferLayout::new(dense.transfer(), &slot.shape) {
            Ok(layout) => Arc::new(layout),
            Err(e) => {
                // The shape is measured again next frame (it lags a resampling by one).
                debug!("surface {entity}: GPU layout not built yet: {e}");
                continue;
            }
        };
        let Some((buffer, first)) = batches.place(entity, slot.look) else {
            continue;
        };
        let layout_id = next_shape_id();
        match gpu {
            Some(mut gpu) => {
                gpu.layout = layout;
                gpu.layout_id = layout_id;
                gpu.built_for = built_for;
            }
            None => {
                commands.entity(entity).insert(GpuSurfels {
                    layout,
                    layout_id,
                    built_for,
                    buffer,
                    first,
                });
            }
        }
    }
}

impl SurfelBatches {
    /// A member's batch buffer and first surfel.
    fn place(&self, entity: Entity, look: LookKey) -> Option<(Handle<ShaderBuffer>, u32)> {
        let batch = self.batches.get(&look)?;
        let &(_, first, _) = batch.members.iter().find(|m| m.0 == entity)?;
        Some((batch.buffer.clone(), first as u32))
    }
}

/// Rewrites each batch's buffer where one of its surfaces changed; each surface's packing
/// is timed in [`SurfaceTimings::upload_ms`].
fn upload_surfels(
    batches: Res<SurfelBatches>,
    mut buffers: ResMut<Assets<ShaderBuffer>>,
    mut surfaces: Query<(&DenseSurface, &mut SurfelSlot, &mut SurfaceTimings)>,
    mut gpu_surfels: Query<&mut GpuSurfels>,
) {
    for batch in batches.batches.values() {
        if batch.gpu {
            for &(entity, first, _) in &batch.members {
                if let Ok(mut gpu) = gpu_surfels.get_mut(entity)
                    && (gpu.buffer != batch.buffer || gpu.first as usize != first)
                {
                    gpu.buffer = batch.buffer.clone();
                    gpu.first = first as u32;
                }
                if let Ok((.., mut timings)) = surfaces.get_mut(entity) {
                    timings.upload_ms = 0.0;
                }
            }
            continue;
        }
        let changed = batch.members.iter().any(|&(e, ..)| {
            surfaces
                .get(e)
                .is_ok_and(|(dense, slot, _)| slot.uploaded != dense.revision())
        });
        if !changed {
            for &(entity, ..) in &batch.members {
                if let Ok((.., mut timings)) = surfaces.get_mut(entity) {
                    timings.upload_ms = 0.0;
                }
            }
            continue;
        }
        // A new buffer each frame: it is moved to the render world (one pass over the
        // bytes; packing into a kept buffer and cloning it would be two).
        let mut packed = Vec::with_capacity(batch.capacity * SURFEL_BYTES);
        for &(entity, first, _) in &batch.members {
            let Ok((dense, mut slot, mut timings)) = surfaces.get_mut(entity) else {
                continue;
            };
            let start = Instant::now();
            // Unused surfels (radius 0) up to the slot's start draw nothing.
            packed.resize(first * SURFEL_BYTES, 0);
            pack_surfels(dense.positions(), dense.normals(), &slot.shape, &mut packed);
            slot.uploaded = dense.revision();
            timings.upload_ms = start.elapsed().as_secs_f32() * 1e3;
        }
        packed.resize(batch.capacity * SURFEL_BYTES, 0);
        if let Some(mut buffer) = buffers.get_mut(&batch.buffer) {
            buffer.data = Some(packed);
        }
    }
}

/// Simulation points and springs, when [`SpringGizmos`] asks for them.
fn draw_gizmos(
    settings: Res<SpringGizmos>,
    mut gizmos: Gizmos<SpringGizmos>,
    surfaces: Query<(
        &SimulationPoints,
        &SurfaceSprings,
        &SurfaceNetwork,
        &GlobalTransform,
    )>,
) {
    if !(settings.points || settings.stretch || settings.bend || settings.hinges) {
        return;
    }
    let stretch_color = Color::srgb(0.25, 0.65, 1.0);
    let bend_color = Color::srgb(1.0, 0.35, 0.55);
    for (points, springs, network, transform) in &surfaces {
        let at = |i: usize| transform.transform_point(points.position(i));
        if settings.points {
            // A fifth of the typical spacing: √(area per point).
            let spacing = (network.report.area / network.len().max(1) as f32).sqrt();
            let size = 0.2 * spacing.max(1e-6);
            for i in 0..points.len() {
                gizmos.cross(at(i), size, Color::srgb(1.0, 0.85, 0.2));
            }
        }
        let stretch_count = network.stretch.len();
        // Where hinges are drawn, the stretch springs on their edges are not (the same lines:
        // one colour would hide the other).
        let hinged: std::collections::HashSet<(u32, u32)> = if settings.hinges {
            springs
                .hinges()
                .iter()
                .map(|h| (h.edge[0].min(h.edge[1]), h.edge[0].max(h.edge[1])))
                .collect()
        } else {
            Default::default()
        };
        for (index, spring) in springs.iter() {
            let is_stretch = index < stretch_count;
            if is_stretch && hinged.contains(&(spring.a.min(spring.b), spring.a.max(spring.b))) {
                continue;
            }
            if (is_stretch && settings.stretch) || (!is_stretch && settings.bend) {
                let color = if is_stretch {
                    stretch_color
                } else {
                    bend_color
                };
                gizmos.line(at(spring.a as usize), at(spring.b as usize), color);
            }
        }
        if settings.hinges {
            let hinges = springs.hinges();
            for (hinge, angle) in hinges.iter().zip(hinges.angles(points)) {
                let bend = angle_difference(angle, hinge.rest_angle).abs();
                let t = (bend / HINGE_GIZMO_FULL_BEND).min(1.0);
                let color = Color::srgb(0.2 + 0.8 * t, 0.9 * (1.0 - t) + 0.1, 0.2);
                let [a, b] = hinge.edge.map(|i| at(i as usize));
                gizmos.line(a, b, color);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn auto_takes_the_gpu_for_large_surfaces_on_a_real_gpu_only() {
        let large = GPU_TRANSFER_MIN_POINTS;
        let auto = TransferDevice::Auto;
        assert!(wants_gpu(auto, large, Some(DeviceType::DiscreteGpu)));
        assert!(wants_gpu(auto, large, Some(DeviceType::IntegratedGpu)));
        assert!(!wants_gpu(auto, large - 1, Some(DeviceType::DiscreteGpu)));
        // lavapipe: the GPU would be the same cores.
        assert!(!wants_gpu(auto, large, Some(DeviceType::Cpu)));
        assert!(wants_gpu(TransferDevice::Gpu, 10, Some(DeviceType::Cpu)));
        assert!(!wants_gpu(
            TransferDevice::Cpu,
            large,
            Some(DeviceType::DiscreteGpu)
        ));
        // No renderer: nothing to run a pass on.
        assert!(!wants_gpu(TransferDevice::Gpu, large, None));
    }
}
