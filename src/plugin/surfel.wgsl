// Surfels pulled from a storage buffer: each dense point is a hexagonal disc facing along
// its normal (cut along the surface's edge where it lies on one). The index mesh holds the
// unit hexagon's six corners per surfel; this vertex shader finds its surfel from the vertex
// index, builds a tangent frame from the normal and places the corner. StandardMaterial's
// PBR fragment shades it.

#import bevy_pbr::{
    mesh_bindings::mesh,
    mesh_functions,
    view_transformations::position_world_to_clip,
}
#ifdef PREPASS_PIPELINE
#import bevy_pbr::prepass_io::VertexOutput
#else
#import bevy_pbr::forward_io::VertexOutput
#endif

struct Surfel {
    // xyz: position in the surface's own coordinates; w: disc radius (0: an unused slot).
    pos_radius: vec4<f32>,
    // Unit normal.
    normal: vec3<f32>,
    // 0, or where the surface's edge cuts the disc: the outward direction's angle in the
    // tangent frame below (high 16 bits, -pi to pi) and the cut's distance from the centre
    // in radii, plus one (low 16 bits); see `core::cloud::surfels::edge_word`.
    edge: u32,
};

// As `core::cloud::surfels::EDGE_WORD_STEPS`.
const EDGE_WORD_STEPS: f32 = 65535.0;
const PI: f32 = 3.14159265358979;

@group(#{MATERIAL_BIND_GROUP}) @binding(100) var<storage, read> surfels: array<Surfel>;

struct Vertex {
    @builtin(instance_index) instance_index: u32,
    @builtin(vertex_index) vertex_index: u32,
    // The unit hexagon corner (x, y, 0).
    @location(0) position: vec3<f32>,
};

const CORNERS_PER_SURFEL: u32 = 6u;

// Duff et al. 2017, "Building an orthonormal basis, revisited" (n of unit length).
fn any_tangent(n: vec3<f32>) -> vec3<f32> {
    let s = select(-1.0, 1.0, n.z >= 0.0);
    let a = -1.0 / (s + n.z);
    return vec3<f32>(1.0 + s * n.x * n.x * a, s * n.x * n.y * a, -s * n.x);
}

@vertex
fn vertex(v: Vertex) -> VertexOutput {
    var out: VertexOutput;
    // The mesh allocator packs meshes into shared buffers: count from this mesh's start.
    let local_index = v.vertex_index - mesh[v.instance_index].first_vertex_index;
    let id = min(local_index / CORNERS_PER_SURFEL, arrayLength(&surfels) - 1u);
    let s = surfels[id];
    let n = normalize(s.normal);
    let t = any_tangent(n);
    let b = cross(n, t);
    let radius = s.pos_radius.w;
    var c = v.position.xy * radius;
    if (s.edge != 0u) {
        // Cut by the surface's edge: the corners past the cut line are moved onto it, so
        // the disc ends where the surface does.
        let a = f32(s.edge >> 16u) / EDGE_WORD_STEPS * 2.0 * PI - PI;
        let offset = f32((s.edge & 0xffffu) - 1u) / (EDGE_WORD_STEPS - 1.0) * radius;
        let outward = vec2<f32>(cos(a), sin(a));
        c -= outward * max(dot(c, outward) - offset, 0.0);
    }
    let local_pos = vec4<f32>(s.pos_radius.xyz + c.x * t + c.y * b, 1.0);

    let world_from_local = mesh_functions::get_world_from_local(v.instance_index);
    out.world_position = mesh_functions::mesh_position_local_to_world(world_from_local, local_pos);
    out.position = position_world_to_clip(out.world_position.xyz);

#ifdef PREPASS_PIPELINE
#ifdef UNCLIPPED_DEPTH_ORTHO_EMULATION
    out.unclipped_depth = out.position.z;
    out.position.z = min(out.position.z, 1.0);
#endif
#ifdef NORMAL_PREPASS_OR_DEFERRED_PREPASS
    out.world_normal = mesh_functions::mesh_normal_local_to_world(n, v.instance_index);
#endif
#ifdef MOTION_VECTOR_PREPASS
    out.previous_world_position = mesh_functions::mesh_position_local_to_world(
        mesh_functions::get_previous_world_from_local(v.instance_index), local_pos);
#endif
#else
    out.world_normal = mesh_functions::mesh_normal_local_to_world(n, v.instance_index);
#endif

#ifdef VERTEX_OUTPUT_INSTANCE_INDEX
    // The PBR fragment reads the mesh's flags through it.
    out.instance_index = v.instance_index;
#endif
#ifdef VISIBILITY_RANGE_DITHER
    out.visibility_range_dither = mesh_functions::get_visibility_range_dither_level(
        v.instance_index, world_from_local[3]);
#endif
    return out;
}
