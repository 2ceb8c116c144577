//! The transfer on the GPU (feature `render`): for surfaces drawn with
//! [`TransferDevice::Gpu`](super::render::TransferDevice) a compute pass writes their surfel
//! records straight into their batch's storage buffer, the one `surfel.wgsl` draws from.
//!
//! **What moves.** The coefficients, the rest points and the surfel shape
//! ([`GpuTransferLayout`]) go to the GPU once, and again only when they change (pins held
//! anew, resampling, a bake: [`DenseCloud::transfer_id`](crate::core::pipeline::DenseCloud::transfer_id)).
//! Each frame the simulation points to draw go up ([`GpuTransferInput`], 16 bytes a point,
//! blended between ticks as for the CPU), and the pass runs, only when they changed.
//! Nothing dense crosses the bus and the CPU neither transfers nor packs.
//!
//! **How.** The main world keeps [`GpuSurfels`] on each such surface (its layout, its
//! batch's buffer and its slot); `ExtractSchedule` copies what changed into the render
//! world's jobs; `RenderSystems::PrepareBindGroups` uploads and binds; a system in the
//! `RenderGraph` schedule, before the cameras draw, dispatches the three entry points of
//! `surfel_transfer.wgsl` over the dense points. The batch's buffer is never written from
//! the main world (a CPU upload would overwrite the pass's output), so GPU surfaces have
//! batches of their own.

use std::collections::HashMap;
use std::sync::Arc;

use bevy::asset::{embedded_asset, load_embedded_asset};
use bevy::core_pipeline::schedule::camera_driver;
use bevy::prelude::*;
use bevy::render::render_asset::RenderAssets;
use bevy::render::render_resource::binding_types::{
    storage_buffer_read_only_sized, storage_buffer_sized, uniform_buffer_sized,
};
use bevy::render::render_resource::{
    BindGroup, BindGroupEntries, BindGroupLayoutDescriptor, BindGroupLayoutEntries, Buffer,
    BufferDescriptor, BufferId, BufferInitDescriptor, BufferUsages, CachedComputePipelineId,
    ComputePassDescriptor, ComputePipelineDescriptor, PipelineCache, ShaderStages,
};
use bevy::render::renderer::{RenderContext, RenderDevice, RenderGraph, RenderQueue};
use bevy::render::storage::{GpuShaderBuffer, ShaderBuffer};
use bevy::render::{Extract, ExtractSchedule, Render, RenderApp, RenderStartup, RenderSystems};

use super::components::GpuTransferInput;
use crate::core::transfer::gpu::GpuTransferLayout;

/// Invocations per workgroup (`surfel_transfer.wgsl`'s `@workgroup_size`).
const WORKGROUP: u32 = 64;

/// Most workgroups along one dimension of a dispatch (WebGPU's limit); larger surfaces
/// dispatch a second dimension.
const MAX_GROUPS_PER_DIMENSION: u32 = 65_535;

/// The entry points, in the order they run.
const ENTRY_POINTS: [&str; 3] = ["transfer_rows", "stretch_radii", "cut_edges"];

/// Bytes of `surfel_transfer.wgsl`'s `Params`.
const PARAMS_BYTES: u64 = 32;

/// A surface whose transfer runs on the GPU, as the renderer keeps it (main world).
#[derive(Component, Debug, Clone)]
pub struct GpuSurfels {
    /// What the pass reads; rebuilt when the transfer or the surfel shape changes.
    pub(crate) layout: Arc<GpuTransferLayout>,
    /// Names `layout` (a new one each rebuild).
    pub(crate) layout_id: u64,
    /// The transfer id (see `DenseCloud::transfer_id`) and slot the layout was built for.
    pub(crate) built_for: (u64, u64),
    /// The batch's buffer and the surface's first record in it.
    pub(crate) buffer: Handle<ShaderBuffer>,
    pub(crate) first: u32,
}

impl GpuSurfels {
    /// Bytes uploaded once per layout (coefficients, rest points, surfel shape).
    pub fn layout_bytes(&self) -> usize {
        self.layout.bytes()
    }
}

/// Adds the render world's part; called by `SurfelRenderPlugin`.
pub(crate) fn build(app: &mut App) {
    embedded_asset!(app, "surfel_transfer.wgsl");
    let Some(render_app) = app.get_sub_app_mut(RenderApp) else {
        return;
    };
    render_app
        .init_resource::<GpuTransferJobs>()
        .add_systems(RenderStartup, init_pipeline)
        .add_systems(ExtractSchedule, extract_jobs)
        .add_systems(
            Render,
            prepare_jobs.in_set(RenderSystems::PrepareBindGroups),
        )
        .add_systems(RenderGraph, dispatch_jobs.before(camera_driver));
}

/// The pass's bind group layout and its three pipelines.
#[derive(Resource)]
struct GpuTransferPipeline {
    layout: BindGroupLayoutDescriptor,
    pipelines: [CachedComputePipelineId; 3],
}

fn init_pipeline(mut commands: Commands, assets: Res<AssetServer>, cache: Res<PipelineCache>) {
    let read = || storage_buffer_read_only_sized(false, None);
    let layout = BindGroupLayoutDescriptor::new(
        "surfel_transfer",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::COMPUTE,
            (
                uniform_buffer_sized(false, None),
                read(),
                read(),
                read(),
                read(),
                read(),
                read(),
                storage_buffer_sized(false, None),
            ),
        ),
    );
    let shader = load_embedded_asset!(assets.as_ref(), "surfel_transfer.wgsl");
    let pipelines = ENTRY_POINTS.map(|entry| {
        cache.queue_compute_pipeline(ComputePipelineDescriptor {
            label: Some(format!("surfel_transfer::{entry}").into()),
            layout: vec![layout.clone()],
            shader: shader.clone(),
            entry_point: Some(entry.into()),
            ..default()
        })
    });
    commands.insert_resource(GpuTransferPipeline { layout, pipelines });
}

/// The GPU's copy of a layout.
struct LayoutBuffers {
    params: Buffer,
    sim: Buffer,
    arrays: [Buffer; 5],
}

/// A surface's transfer in the render world.
#[derive(Default)]
struct Job {
    layout: Option<Arc<GpuTransferLayout>>,
    layout_id: u64,
    buffers: Option<LayoutBuffers>,
    /// The positions to upload, when new ones came.
    positions: Option<Vec<[f32; 4]>>,
    input_revision: u64,
    target: Option<Handle<ShaderBuffer>>,
    first: u32,
    /// The first record the params buffer holds.
    params_first: Option<u32>,
    /// The bind group and the surfel buffer it binds.
    bind_group: Option<(BindGroup, BufferId)>,
    /// Whether the pass must run this frame.
    due: bool,
    /// Whether the simulation points were uploaded at least once.
    uploaded: bool,
    /// Seen in this frame's extraction.
    seen: bool,
}

/// Each GPU-transferred surface's job, by main-world entity.
#[derive(Resource, Default)]
struct GpuTransferJobs(HashMap<Entity, Job>);

fn extract_jobs(
    mut jobs: ResMut<GpuTransferJobs>,
    surfaces: Extract<Query<(Entity, &GpuSurfels, &GpuTransferInput)>>,
) {
    for job in jobs.0.values_mut() {
        job.seen = false;
    }
    for (entity, gpu, input) in &surfaces {
        let job = jobs.0.entry(entity).or_default();
        job.seen = true;
        if job.layout_id != gpu.layout_id {
            job.layout = Some(gpu.layout.clone());
            job.layout_id = gpu.layout_id;
            job.buffers = None;
            job.bind_group = None;
            job.uploaded = false;
        }
        if job.input_revision != input.revision || !job.uploaded {
            job.positions = Some(input.positions.clone());
            job.input_revision = input.revision;
        }
        if job.target.as_ref() != Some(&gpu.buffer) {
            job.target = Some(gpu.buffer.clone());
        }
        job.first = gpu.first;
    }
    jobs.0.retain(|_, job| job.seen);
}

/// `u32`s and `f32`s as the GPU's bytes (little-endian).
fn words<T: Copy>(values: &[T], bits: impl Fn(T) -> u32) -> Vec<u8> {
    values.iter().flat_map(|&v| bits(v).to_le_bytes()).collect()
}

fn vec4_bytes(values: &[[f32; 4]]) -> Vec<u8> {
    values
        .iter()
        .flat_map(|v| v.iter().flat_map(|c| c.to_le_bytes()))
        .collect()
}

fn params_bytes(layout: &GpuTransferLayout, first: u32) -> Vec<u8> {
    [
        layout.dense,
        layout.simulation,
        layout.k,
        layout.stride,
        layout.edge_k,
        layout.cutters,
        first,
        0,
    ]
    .iter()
    .flat_map(|w| w.to_le_bytes())
    .collect()
}

/// A storage buffer of `contents` (at least 4 bytes: WebGPU has no empty bindings).
fn storage(device: &RenderDevice, label: &'static str, mut contents: Vec<u8>) -> Buffer {
    if contents.is_empty() {
        contents.resize(4, 0);
    }
    device.create_buffer_with_data(&BufferInitDescriptor {
        label: Some(label),
        contents: &contents,
        usage: BufferUsages::STORAGE,
    })
}

fn upload_layout(device: &RenderDevice, layout: &GpuTransferLayout) -> LayoutBuffers {
    LayoutBuffers {
        params: device.create_buffer(&BufferDescriptor {
            label: Some("surfel_transfer params"),
            size: PARAMS_BYTES,
            usage: BufferUsages::UNIFORM | BufferUsages::COPY_DST,
            mapped_at_creation: false,
        }),
        sim: device.create_buffer(&BufferDescriptor {
            label: Some("surfel_transfer simulation points"),
            size: (u64::from(layout.simulation) * 16).max(16),
            usage: BufferUsages::STORAGE | BufferUsages::COPY_DST,
            mapped_at_creation: false,
        }),
        arrays: [
            storage(device, "surfel_transfer rest", vec4_bytes(&layout.sim_rest)),
            storage(
                device,
                "surfel_transfer indices",
                words(&layout.indices, |w| w),
            ),
            storage(
                device,
                "surfel_transfer coefficients",
                words(&layout.coefficients, f32::to_bits),
            ),
            storage(
                device,
                "surfel_transfer points",
                words(&layout.points, |w| w),
            ),
            storage(device, "surfel_transfer edges", words(&layout.edges, |w| w)),
        ],
    }
}

/// Uploads what changed and (re)binds; marks the jobs whose pass must run.
fn prepare_jobs(
    mut jobs: ResMut<GpuTransferJobs>,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    cache: Res<PipelineCache>,
    pipeline: Option<Res<GpuTransferPipeline>>,
    surfel_buffers: Res<RenderAssets<GpuShaderBuffer>>,
) {
    let Some(pipeline) = pipeline else {
        return;
    };
    for job in jobs.0.values_mut() {
        let Some(layout) = job.layout.clone() else {
            continue;
        };
        if job.buffers.is_none() {
            job.buffers = Some(upload_layout(&device, &layout));
            job.params_first = None;
            job.bind_group = None;
        }
        let Some(buffers) = job.buffers.as_ref() else {
            continue;
        };
        if job.params_first != Some(job.first) {
            queue.write_buffer(&buffers.params, 0, &params_bytes(&layout, job.first));
            job.params_first = Some(job.first);
            job.due = true;
        }
        if let Some(positions) = job.positions.take()
            && positions.len() == layout.simulation as usize
            && !positions.is_empty()
        {
            queue.write_buffer(&buffers.sim, 0, &vec4_bytes(&positions));
            job.uploaded = true;
            job.due = true;
        }
        let Some(target) = job.target.as_ref().and_then(|h| surfel_buffers.get(h)) else {
            continue;
        };
        // The slot must lie inside the buffer (a batch's buffer grows under a new handle,
        // which the job sees a frame later).
        let end = (u64::from(job.first) + u64::from(layout.dense)) * 32;
        if target.buffer.size() < end {
            job.bind_group = None;
            continue;
        }
        if job.bind_group.as_ref().map(|(_, id)| *id) != Some(target.buffer.id()) {
            let [rest, indices, coefficients, points, edges] = &buffers.arrays;
            let group = device.create_bind_group(
                "surfel_transfer",
                &cache.get_bind_group_layout(&pipeline.layout),
                &BindGroupEntries::sequential((
                    buffers.params.as_entire_binding(),
                    buffers.sim.as_entire_binding(),
                    rest.as_entire_binding(),
                    indices.as_entire_binding(),
                    coefficients.as_entire_binding(),
                    points.as_entire_binding(),
                    edges.as_entire_binding(),
                    target.buffer.as_entire_binding(),
                )),
            );
            job.bind_group = Some((group, target.buffer.id()));
            job.due = true;
        }
    }
}

/// The workgroups of a dispatch over `points` points: (x, y).
fn groups(points: u32) -> (u32, u32) {
    let groups = points.div_ceil(WORKGROUP).max(1);
    let x = groups.min(MAX_GROUPS_PER_DIMENSION);
    (x, groups.div_ceil(x))
}

/// Runs the pass of each job that is due, before the cameras draw.
fn dispatch_jobs(
    mut context: RenderContext,
    cache: Res<PipelineCache>,
    pipeline: Option<Res<GpuTransferPipeline>>,
    mut jobs: ResMut<GpuTransferJobs>,
) {
    let Some(pipeline) = pipeline else {
        return;
    };
    let [Some(rows), Some(radii), Some(edges)] =
        pipeline.pipelines.map(|id| cache.get_compute_pipeline(id))
    else {
        // Still compiling: the jobs stay due.
        return;
    };
    let due: Vec<(&BindGroup, u32)> = jobs
        .0
        .values_mut()
        .filter(|job| job.due && job.uploaded)
        .filter_map(|job| {
            let dense = job.layout.as_ref()?.dense;
            let (group, _) = job.bind_group.as_ref()?;
            job.due = false;
            Some((group, dense))
        })
        .collect();
    if due.is_empty() {
        return;
    }
    let mut pass = context
        .command_encoder()
        .begin_compute_pass(&ComputePassDescriptor {
            label: Some("surfel_transfer"),
            ..default()
        });
    for (group, dense) in due {
        let (x, y) = groups(dense);
        pass.set_bind_group(0, group, &[]);
        for stage in [rows, radii, edges] {
            pass.set_pipeline(stage);
            pass.dispatch_workgroups(x, y, 1);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dispatches_cover_every_point_within_the_limits() {
        for points in [1, 63, 64, 65, 100_000, 1_000_000, 10_000_000] {
            let (x, y) = groups(points);
            assert!(x <= MAX_GROUPS_PER_DIMENSION && y <= MAX_GROUPS_PER_DIMENSION);
            assert!(u64::from(x) * u64::from(y) * u64::from(WORKGROUP) >= u64::from(points));
        }
    }
}
