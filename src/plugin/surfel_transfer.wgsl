// The transfer on the GPU: from the simulation points to the surfel records of a surface's
// slot in its batch's storage buffer, the buffer `surfel.wgsl` draws from. Three entry
// points, dispatched in turn over the dense points (each reads what the one before wrote):
// `transfer_rows` (positions and normals), `stretch_radii` (disc radii) and `cut_edges`
// (edge cuts). Each mirrors the CPU: `core::transfer` (`Transfer::apply_frame`) and
// `core::cloud::surfels::pack_surfels`; the data layout is `core::transfer::gpu`'s.

struct Params {
    dense: u32,
    simulation: u32,
    k: u32,
    stride: u32,
    edge_k: u32,
    cutters: u32,
    // The surface's first record in the buffer (its slot's start).
    first: u32,
    _pad: u32,
};

@group(0) @binding(0) var<uniform> params: Params;
// The simulation points' positions this frame (w unused).
@group(0) @binding(1) var<storage, read> sim: array<vec4<f32>>;
// Their rest positions.
@group(0) @binding(2) var<storage, read> sim_rest: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> indices: array<u32>;
@group(0) @binding(4) var<storage, read> coefficients: array<f32>;
@group(0) @binding(5) var<storage, read> points: array<u32>;
@group(0) @binding(6) var<storage, read> edges: array<u32>;
// The batch's surfel records, 8 words each (see `surfel.wgsl`'s `Surfel`).
@group(0) @binding(7) var<storage, read_write> surfels: array<u32>;

// As `core::transfer::gpu`.
const POINT_WORDS: u32 = 12u;
const FLAG_RESIDUAL: u32 = 1u;
const FLAG_EDGE: u32 = 2u;
const CUTTER_SHIFT: u32 = 8u;
const MAX_EDGE_K: u32 = 16u;
const RECORD_WORDS: u32 = 8u;
// As `core::transfer`'s MIN_NORMAL_LENGTH and `core::cloud::surfels`.
const MIN_NORMAL_LENGTH: f32 = 1.0e-12;
const MAX_SURFEL_STRETCH: f32 = 4.0;
const CORNER_GAP: f32 = 3.9269908; // 5π/4
const EDGE_WORD_STEPS: f32 = 65535.0;
const PI: f32 = 3.1415927;
const TAU: f32 = 6.2831855;
const WORKGROUP: u32 = 64u;

// The dense point of an invocation (dispatches over many points are two-dimensional).
fn point_index(id: vec3<u32>, groups: vec3<u32>) -> u32 {
    return id.x + id.y * groups.x * WORKGROUP;
}

fn finite(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;
}

fn point_vec(i: u32, word: u32) -> vec3<f32> {
    let b = i * POINT_WORDS + word;
    return vec3<f32>(bitcast<f32>(points[b]), bitcast<f32>(points[b + 1u]), bitcast<f32>(points[b + 2u]));
}

fn record(i: u32) -> u32 {
    return (params.first + i) * RECORD_WORDS;
}

fn record_vec(i: u32, word: u32) -> vec3<f32> {
    let b = record(i) + word;
    return vec3<f32>(bitcast<f32>(surfels[b]), bitcast<f32>(surfels[b + 1u]), bitcast<f32>(surfels[b + 2u]));
}

fn store_vec(i: u32, word: u32, v: vec3<f32>) {
    let b = record(i) + word;
    surfels[b] = bitcast<u32>(v.x);
    surfels[b + 1u] = bitcast<u32>(v.y);
    surfels[b + 2u] = bitcast<u32>(v.z);
}

// A simulation point's position, or (residual rows) its displacement from rest.
fn sim_value(j: u32, residual: bool) -> vec3<f32> {
    let p = sim[j].xyz;
    if (residual) {
        return p - sim_rest[j].xyz;
    }
    return p;
}

// glam's `Vec3::any_orthonormal_pair` (Duff et al. 2017), as `core::transfer::tangent_frame`.
fn tangent_frame(n: vec3<f32>) -> array<vec3<f32>, 2> {
    let sign = select(1.0, -1.0, (bitcast<u32>(n.z) >> 31u) == 1u);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    return array<vec3<f32>, 2>(
        vec3<f32>(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        vec3<f32>(b, sign + n.y * n.y * a, -n.y),
    );
}

// The frame `surfel.wgsl` builds, in which edge angles are given (`shader_frame`).
fn shader_frame(n: vec3<f32>) -> array<vec3<f32>, 2> {
    let s = select(-1.0, 1.0, n.z >= 0.0);
    let a = -1.0 / (s + n.z);
    let t = vec3<f32>(1.0 + s * n.x * n.x * a, s * n.x * n.y * a, -s * n.x);
    return array<vec3<f32>, 2>(t, cross(n, t));
}

// Dispatch 1: each row's fit of the simulation points (see `Transfer::row_sums`).
@compute @workgroup_size(64)
fn transfer_rows(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = point_index(id, groups);
    if (i >= params.dense) {
        return;
    }
    let k = params.k;
    let m = k - 1u;
    let row = i * k;
    let c = i * params.stride;
    let residual = (points[i * POINT_WORDS + 9u] & FLAG_RESIDUAL) != 0u;
    let a = sim_value(indices[row], residual);
    var s0 = vec3<f32>(0.0);
    var s1 = vec3<f32>(0.0);
    var s2 = vec3<f32>(0.0);
    for (var t = 0u; t < m; t++) {
        let e = sim_value(indices[row + 1u + t], residual) - a;
        s0 += e * coefficients[c + t];
        s1 += e * coefficients[c + m + t];
        s2 += e * coefficients[c + 2u * m + t];
    }
    let rest_normal = point_vec(i, 4u);
    var position = a + s0;
    var normal = cross(s1, s2);
    if (residual) {
        position = point_vec(i, 0u) + position;
        let f = tangent_frame(rest_normal);
        normal = cross(f[0] + s1, f[1] + s2);
    }
    let len = length(normal);
    if (len > MIN_NORMAL_LENGTH && finite(len)) {
        normal = normal * (1.0 / len);
    } else {
        normal = rest_normal;
    }
    store_vec(i, 0u, position);
    store_vec(i, 4u, normal);
    let b = record(i);
    surfels[b + 3u] = 0u;
    surfels[b + 7u] = 0u;
}

// Dispatch 2: each disc's rest radius, grown with the stretch to its far neighbour.
@compute @workgroup_size(64)
fn stretch_radii(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = point_index(id, groups);
    if (i >= params.dense) {
        return;
    }
    let b = i * POINT_WORDS;
    let radius = bitcast<f32>(points[b + 3u]);
    let rest = bitcast<f32>(points[b + 7u]);
    let far = points[b + 8u];
    var stretch = 1.0;
    if (rest > 0.0) {
        stretch = distance(record_vec(far, 0u), record_vec(i, 0u)) / rest;
    }
    surfels[record(i) + 3u] = bitcast<u32>(radius * clamp(stretch, 1.0, MAX_SURFEL_STRETCH));
}

// `normalize_or_zero`.
fn unit_or_zero(v: vec3<f32>) -> vec3<f32> {
    let r = 1.0 / length(v);
    if (finite(r) && r > 0.0) {
        return v * r;
    }
    return vec3<f32>(0.0);
}

// An edge row's outward direction in its point's plane: x, y, z, and w = 1 for an edge
// point, 2 for a corner, 0 where there is none (as `pack_surfels`: the middle of the widest
// gap between the directions to its neighbours).
fn outward(r: u32) -> vec4<f32> {
    let base = r * (1u + params.edge_k);
    let i = edges[base];
    let normal = unit_or_zero(record_vec(i, 4u));
    if (all(normal == vec3<f32>(0.0))) {
        return vec4<f32>(0.0);
    }
    let f = shader_frame(normal);
    let p = record_vec(i, 0u);
    var angles: array<f32, MAX_EDGE_K>;
    var count = 0u;
    for (var t = 0u; t < params.edge_k; t++) {
        let d = record_vec(edges[base + 1u + t], 0u) - p;
        if (finite(d.x) && finite(d.y) && finite(d.z)) {
            // Sorted as they come (insertion).
            let angle = atan2(dot(d, f[1]), dot(d, f[0]));
            var at = count;
            while (at > 0u && angles[at - 1u] > angle) {
                angles[at] = angles[at - 1u];
                at -= 1u;
            }
            angles[at] = angle;
            count += 1u;
        }
    }
    if (count == 0u) {
        return vec4<f32>(0.0);
    }
    var start = angles[count - 1u];
    var width = angles[0] + TAU - angles[count - 1u];
    for (var t = 1u; t < count; t++) {
        let gap = angles[t] - angles[t - 1u];
        if (gap > width) {
            start = angles[t - 1u];
            width = gap;
        }
    }
    if (!(width > 0.0 && finite(width))) {
        return vec4<f32>(0.0);
    }
    if (width > CORNER_GAP) {
        return vec4<f32>(0.0, 0.0, 0.0, 2.0);
    }
    let angle = start + 0.5 * width;
    return vec4<f32>(cos(angle) * f[0] + sin(angle) * f[1], 1.0);
}

// `edge_word`: the angle in the high 16 bits, the offset plus one in the low 16.
fn edge_word(angle: f32, offset: f32) -> u32 {
    let a = u32(max(floor((angle + PI) / TAU * EDGE_WORD_STEPS + 0.5), 0.0));
    let o = u32(floor(clamp(offset, 0.0, 1.0) * (EDGE_WORD_STEPS - 1.0) + 0.5)) + 1u;
    return (min(a, u32(EDGE_WORD_STEPS)) << 16u) | o;
}

fn edge_offset(word: u32) -> f32 {
    return f32(max(word & 0xffffu, 1u) - 1u) / (EDGE_WORD_STEPS - 1.0);
}

// `cut`: the word of a disc (unit `normal`) cut across `out` at `offset` radii, or 0.
fn cut_word(out: vec3<f32>, normal: vec3<f32>, offset: f32) -> u32 {
    let o = out - normal * dot(out, normal);
    let f = shader_frame(normal);
    let angle = atan2(dot(o, f[1]), dot(o, f[0]));
    if (dot(o, o) > 0.0 && finite(angle)) {
        return edge_word(angle, offset);
    }
    return 0u;
}

// Dispatch 3: an edge point's own cut (a corner draws nothing); any other point's nearest
// cut by the edge points around it, visited in the CPU's order.
@compute @workgroup_size(64)
fn cut_edges(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = point_index(id, groups);
    if (i >= params.dense) {
        return;
    }
    let b = i * POINT_WORDS;
    let flags = points[b + 9u];
    if ((flags & FLAG_EDGE) != 0u) {
        let o = outward(points[b + 10u]);
        if (o.w == 2.0) {
            surfels[record(i) + 3u] = 0u;
        } else if (o.w == 1.0) {
            let normal = unit_or_zero(record_vec(i, 4u));
            surfels[record(i) + 7u] = cut_word(o.xyz, normal, 0.0);
        }
        return;
    }
    let count = flags >> CUTTER_SHIFT;
    if (count == 0u) {
        return;
    }
    let normal = unit_or_zero(record_vec(i, 4u));
    if (all(normal == vec3<f32>(0.0))) {
        return;
    }
    let p = record_vec(i, 0u);
    let radius = bitcast<f32>(surfels[record(i) + 3u]);
    var word = 0u;
    let first = params.cutters + points[b + 11u];
    for (var t = 0u; t < count; t++) {
        let r = edges[first + t];
        let o = outward(r);
        if (o.w != 1.0) {
            continue;
        }
        let inside = dot(record_vec(edges[r * (1u + params.edge_k)], 0u) - p, o.xyz);
        if (inside >= 0.0 && inside < radius) {
            let offset = inside / radius;
            if (word == 0u || edge_offset(word) > offset) {
                let w = cut_word(o.xyz, normal, offset);
                if (w != 0u) {
                    word = w;
                }
            }
        }
    }
    surfels[record(i) + 7u] = word;
}
