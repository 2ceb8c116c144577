//! Spring storage and the spring-force kernels.
//!
//! Springs are stored as a structure of arrays in an internal order chosen for speed:
//!
//! * **Runs.** Springs are sorted by their index offset `b − a`, then by `a`. A stretch of
//!   springs with the same offset and consecutive `a` (point `a0 + i` to point `b0 + i`)
//!   becomes a *run*: its endpoints are two contiguous windows of the position and velocity
//!   arrays, so the loop over it reads and writes contiguous memory and the compiler turns it
//!   into SIMD code. Forces on the `a` ends go to one accumulator and forces on the `b` ends to
//!   a second one, so a run never writes the array it reads from twice in one iteration (no
//!   aliasing, no gather, no scatter). Grids are almost all runs; a Morton-ordered
//!   point-cloud network has few.
//!   Runs of one offset that are only a point or two apart (the rows of a grid) are joined
//!   into one by *padding* springs of zero stiffness and damping, which exert no force: the
//!   32×32 cloth's 5826 springs form 6 runs with 153 padding springs, instead of 128 short
//!   runs whose loop tails cost more than their bodies.
//! * **Scattered springs**, the rest, sorted by `(a, b)`, take a scalar loop through the same
//!   per-spring function.
//!
//! [`SpringLayout::order`] maps internal positions back to the caller's spring indices.

use super::parts::Soa3;

/// Shortest run kept as a run; shorter ones go to the scattered loop.
pub(crate) const MIN_RUN: usize = 4;

/// Runs of one offset whose ends are at most this many points apart are joined into one
/// by padding springs of zero stiffness and damping (grid rows become one long run).
pub(crate) const MAX_GAP: u32 = 2;

/// [`SpringLayout::order`] entry of a padding spring.
pub(crate) const PADDING: u32 = u32::MAX;

/// Below this distance two endpoints count as coincident: the spring's direction is then
/// taken as +X (a deterministic choice that pushes the points apart along X when the spring
/// has a rest length, and exerts no force when it has none).
pub const COINCIDENT_DISTANCE: f32 = 1.0e-12;

/// Scattered springs handled per chunk.
const GATHER_CHUNK: usize = 256;

/// Per-chunk buffers of the scattered loop.
struct Gather {
    d: [[f32; GATHER_CHUNK]; 3],
    dv: [[f32; GATHER_CHUNK]; 3],
    f: [[f32; GATHER_CHUNK]; 3],
}

impl Default for Gather {
    fn default() -> Self {
        Self {
            d: [[0.0; GATHER_CHUNK]; 3],
            dv: [[0.0; GATHER_CHUNK]; 3],
            f: [[0.0; GATHER_CHUNK]; 3],
        }
    }
}

/// [`SpringLayout::accumulate`]'s work, handed to [`pulp`] so that the loops are compiled
/// once per instruction set and the widest one the processor has is picked at run time.
struct Accumulate<'a, const AXIAL: bool> {
    layout: &'a SpringLayout,
    x: &'a Soa3,
    v: &'a Soa3,
    fa: &'a mut Soa3,
    fb: &'a mut Soa3,
}

impl<const AXIAL: bool> pulp::WithSimd for Accumulate<'_, AXIAL> {
    type Output = ();

    // Everything below is inlined into pulp's `#[target_feature]` entry points, so the
    // compiler vectorises it for AVX2 + FMA where the processor has them (8 springs per
    // instruction instead of SSE's 4). No fused multiply-adds are formed (Rust does not
    // contract `a * b + c`), so every instruction set gives bit-identical results.
    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) {
        self.layout
            .accumulate_here::<AXIAL>(self.x, self.v, self.fa, self.fb);
    }
}

/// A spring as the solver is given it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpringSpec {
    /// First endpoint.
    pub a: u32,
    /// Second endpoint.
    pub b: u32,
    /// Natural length l⁰ (eq 2); zero is allowed.
    pub rest_length: f32,
    /// Stiffness k (eq 2), force per unit length.
    pub stiffness: f32,
    /// Damping k_d (eq 3), force per unit relative speed.
    pub damping: f32,
}

/// Springs with their endpoints consecutive: point `a0 + i` to `b0 + i` for springs
/// `first + i`, `i < len`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Run {
    pub a0: u32,
    pub b0: u32,
    pub first: u32,
    pub len: u32,
}

/// The springs of one solver in kernel order (see the module docs).
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct SpringLayout {
    pub a: Vec<u32>,
    pub b: Vec<u32>,
    pub rest: Vec<f32>,
    pub k: Vec<f32>,
    pub kd: Vec<f32>,
    /// Internal position → the caller's index ([`PADDING`] for padding).
    pub order: Vec<u32>,
    pub runs: Vec<Run>,
    /// Springs `scattered_start..` take the scalar loop.
    pub scattered_start: usize,
    /// Padding springs (no force) that join runs across short gaps.
    pub padding: usize,
}

impl SpringLayout {
    /// Lays out validated springs (endpoints distinct and in range).
    pub fn new(springs: &[SpringSpec]) -> Self {
        // Each spring with a < b; the force is symmetric in its endpoints.
        let norm = |i: u32| {
            let s = &springs[i as usize];
            if s.a < s.b { (s.a, s.b) } else { (s.b, s.a) }
        };
        let mut sorted: Vec<u32> = (0..springs.len() as u32).collect();
        sorted.sort_by_key(|&i| {
            let (a, b) = norm(i);
            (b - a, a, i)
        });
        // Maximal groups of consecutive a with one offset; long ones become runs, and runs
        // of one offset separated by a short gap are joined by padding springs.
        let mut pieces: Vec<(u32, u32, Vec<u32>)> = Vec::new(); // (a0, offset, members)
        let mut scattered = Vec::new();
        let mut start = 0;
        while start < sorted.len() {
            let (a0, b0) = norm(sorted[start]);
            let offset = b0 - a0;
            let mut end = start + 1;
            while end < sorted.len() {
                let (a, b) = norm(sorted[end]);
                if b - a != offset || a != a0 + (end - start) as u32 {
                    break;
                }
                end += 1;
            }
            let group = &sorted[start..end];
            start = end;
            if group.len() < MIN_RUN {
                scattered.extend_from_slice(group);
                continue;
            }
            if let Some((last_a0, last_offset, members)) = pieces.last_mut() {
                let last_end = *last_a0 + members.len() as u32;
                let gap = a0.wrapping_sub(last_end);
                if *last_offset == offset && (1..=MAX_GAP).contains(&gap) {
                    members.extend(std::iter::repeat_n(PADDING, gap as usize));
                    members.extend_from_slice(group);
                    continue;
                }
            }
            pieces.push((a0, offset, group.to_vec()));
        }
        let mut layout = Self::default();
        for (a0, offset, members) in pieces {
            layout.runs.push(Run {
                a0,
                b0: a0 + offset,
                first: layout.order.len() as u32,
                len: members.len() as u32,
            });
            for (i, &member) in members.iter().enumerate() {
                let a = a0 + i as u32;
                layout.push(member, a, a + offset, springs);
            }
        }
        layout.scattered_start = layout.order.len();
        scattered.sort_by_key(|&i| {
            let (a, b) = norm(i);
            (a, b, i)
        });
        for i in scattered {
            let (a, b) = norm(i);
            layout.push(i, a, b, springs);
        }
        layout
    }

    /// Appends spring `user` (or padding) between `a` and `b`.
    fn push(&mut self, user: u32, a: u32, b: u32, springs: &[SpringSpec]) {
        let s = springs.get(user as usize).copied().unwrap_or(SpringSpec {
            a,
            b,
            rest_length: 0.0,
            stiffness: 0.0,
            damping: 0.0,
        });
        if user == PADDING {
            self.padding += 1;
        }
        self.order.push(user);
        self.a.push(a);
        self.b.push(b);
        self.rest.push(s.rest_length);
        self.k.push(s.stiffness);
        self.kd.push(s.damping);
    }

    /// Number of real springs (padding excluded).
    pub fn real(&self) -> usize {
        self.len() - self.padding
    }

    /// Whether internal spring `s` is padding.
    pub fn is_padding(&self, s: usize) -> bool {
        self.order[s] == PADDING
    }

    /// Number of springs.
    pub fn len(&self) -> usize {
        self.a.len()
    }

    /// Real springs that take the SIMD-friendly run loop.
    pub fn in_runs(&self) -> usize {
        self.scattered_start - self.padding
    }

    /// The spring at internal position `s`, as given.
    pub fn spec(&self, s: usize) -> SpringSpec {
        SpringSpec {
            a: self.a[s],
            b: self.b[s],
            rest_length: self.rest[s],
            stiffness: self.k[s],
            damping: self.kd[s],
        }
    }

    /// Adds every spring's force on its endpoints: the `a` ends to `fa`, the `b` ends to `fb`
    /// (scattered springs put both into `fa`). `AXIAL` selects damping along the spring,
    /// k_d((v_b − v_a)·l̂)l̂, instead of the paper's eq 3, k_d(v_b − v_a).
    pub fn accumulate<const AXIAL: bool>(&self, x: &Soa3, v: &Soa3, fa: &mut Soa3, fb: &mut Soa3) {
        pulp::Arch::new().dispatch(Accumulate::<AXIAL> {
            layout: self,
            x,
            v,
            fa,
            fb,
        });
    }

    /// [`Self::accumulate`] compiled for the caller's instruction set.
    #[inline(always)]
    fn accumulate_here<const AXIAL: bool>(&self, x: &Soa3, v: &Soa3, fa: &mut Soa3, fb: &mut Soa3) {
        for run in &self.runs {
            self.accumulate_run::<AXIAL>(run, x, v, fa, fb);
        }
        // Scattered springs in chunks: gather the endpoint differences (independent loads,
        // so cache misses overlap), compute the forces in a vectorised loop, scatter them.
        let mut g = Gather::default();
        let mut start = self.scattered_start;
        while start < self.len() {
            let m = (self.len() - start).min(GATHER_CHUNK);
            let (a, b) = (&self.a[start..start + m], &self.b[start..start + m]);
            for i in 0..m {
                let (a, b) = (a[i] as usize, b[i] as usize);
                g.d[0][i] = x.x[b] - x.x[a];
                g.d[1][i] = x.y[b] - x.y[a];
                g.d[2][i] = x.z[b] - x.z[a];
                g.dv[0][i] = v.x[b] - v.x[a];
                g.dv[1][i] = v.y[b] - v.y[a];
                g.dv[2][i] = v.z[b] - v.z[a];
            }
            let (rest, k, kd) = (
                &self.rest[start..start + m],
                &self.k[start..start + m],
                &self.kd[start..start + m],
            );
            let [dx, dy, dz] = &g.d;
            let [dvx, dvy, dvz] = &g.dv;
            let (dx, dy, dz, dvx, dvy, dvz) = (
                &dx[..m],
                &dy[..m],
                &dz[..m],
                &dvx[..m],
                &dvy[..m],
                &dvz[..m],
            );
            let [fx, fy, fz] = &mut g.f;
            let (fx, fy, fz) = (&mut fx[..m], &mut fy[..m], &mut fz[..m]);
            for i in 0..m {
                let f = spring_force::<AXIAL>(
                    [dx[i], dy[i], dz[i]],
                    [dvx[i], dvy[i], dvz[i]],
                    rest[i],
                    k[i],
                    kd[i],
                );
                fx[i] = f[0];
                fy[i] = f[1];
                fz[i] = f[2];
            }
            for i in 0..m {
                let (a, b) = (a[i] as usize, b[i] as usize);
                fa.x[a] += fx[i];
                fa.y[a] += fy[i];
                fa.z[a] += fz[i];
                fa.x[b] -= fx[i];
                fa.y[b] -= fy[i];
                fa.z[b] -= fz[i];
            }
            start += m;
        }
    }

    /// One run: every slice is cut to the run's length first, so the loop has no bounds
    /// checks and vectorises.
    #[inline(always)]
    fn accumulate_run<'a, const AXIAL: bool>(
        &'a self,
        run: &Run,
        x: &'a Soa3,
        v: &'a Soa3,
        fa: &mut Soa3,
        fb: &mut Soa3,
    ) {
        let n = run.len as usize;
        let (a0, b0, s0) = (run.a0 as usize, run.b0 as usize, run.first as usize);
        let window = |s: &'a [f32], at: usize| -> &'a [f32] { &s[at..at + n] };
        let (ax, ay, az) = (window(&x.x, a0), window(&x.y, a0), window(&x.z, a0));
        let (bx, by, bz) = (window(&x.x, b0), window(&x.y, b0), window(&x.z, b0));
        let (avx, avy, avz) = (window(&v.x, a0), window(&v.y, a0), window(&v.z, a0));
        let (bvx, bvy, bvz) = (window(&v.x, b0), window(&v.y, b0), window(&v.z, b0));
        let (rest, k, kd) = (
            window(&self.rest, s0),
            window(&self.k, s0),
            window(&self.kd, s0),
        );
        let (fax, fay, faz) = (
            &mut fa.x[a0..a0 + n],
            &mut fa.y[a0..a0 + n],
            &mut fa.z[a0..a0 + n],
        );
        let (fbx, fby, fbz) = (
            &mut fb.x[b0..b0 + n],
            &mut fb.y[b0..b0 + n],
            &mut fb.z[b0..b0 + n],
        );
        for i in 0..n {
            let d = [bx[i] - ax[i], by[i] - ay[i], bz[i] - az[i]];
            let dv = [bvx[i] - avx[i], bvy[i] - avy[i], bvz[i] - avz[i]];
            let f = spring_force::<AXIAL>(d, dv, rest[i], k[i], kd[i]);
            fax[i] += f[0];
            fay[i] += f[1];
            faz[i] += f[2];
            fbx[i] -= f[0];
            fby[i] -= f[1];
            fbz[i] -= f[2];
        }
    }

    /// Potential energy ½k(|l| − l⁰)² summed over the springs.
    pub fn energy(&self, x: &Soa3) -> f64 {
        (0..self.len())
            .map(|s| {
                let (a, b) = (self.a[s] as usize, self.b[s] as usize);
                let d = [x.x[b] - x.x[a], x.y[b] - x.y[a], x.z[b] - x.z[a]];
                let len = f64::from(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                let stretch = len - f64::from(self.rest[s]);
                0.5 * f64::from(self.k[s]) * stretch * stretch
            })
            .sum()
    }
}

/// The force of one spring on its `a` end (the `b` end gets the opposite): Hooke's law
/// (eq 2) along the spring plus damping. `d = x_b − x_a`, `dv = v_b − v_a`.
///
/// Branch-free (selects only) so that loops over it vectorise.
#[inline(always)]
pub(crate) fn spring_force<const AXIAL: bool>(
    d: [f32; 3],
    dv: [f32; 3],
    rest: f32,
    k: f32,
    kd: f32,
) -> [f32; 3] {
    let len2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    let len = len2.sqrt();
    let apart = len > COINCIDENT_DISTANCE;
    // len / len² instead of 1 / len: the square root and the division start together
    // instead of one after the other (a shorter dependency chain per spring).
    let inv = len * (1.0 / if apart { len2 } else { 1.0 });
    let u = if apart {
        [d[0] * inv, d[1] * inv, d[2] * inv]
    } else {
        [1.0, 0.0, 0.0]
    };
    let hooke = k * (len - rest);
    if AXIAL {
        let s = hooke + kd * (u[0] * dv[0] + u[1] * dv[1] + u[2] * dv[2]);
        [s * u[0], s * u[1], s * u[2]]
    } else {
        [
            hooke * u[0] + kd * dv[0],
            hooke * u[1] + kd * dv[1],
            hooke * u[2] + kd * dv[2],
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(a: u32, b: u32) -> SpringSpec {
        SpringSpec {
            a,
            b,
            rest_length: 1.0,
            stiffness: 1.0,
            damping: 0.0,
        }
    }

    #[test]
    fn runs_cover_grid_rows_and_order_maps_back() {
        // A row of 10 points: 9 neighbour springs (one run), plus a few odd ones.
        let mut springs: Vec<SpringSpec> = (0..9).map(|i| spec(i + 1, i)).collect();
        springs.push(spec(0, 7));
        springs.push(spec(2, 9));
        let layout = SpringLayout::new(&springs);
        assert_eq!(layout.runs.len(), 1);
        assert_eq!(
            layout.runs[0],
            Run {
                a0: 0,
                b0: 1,
                first: 0,
                len: 9
            }
        );
        assert_eq!(layout.in_runs(), 9);
        assert_eq!(layout.len(), 11);
        let mut seen: Vec<u32> = layout.order.clone();
        seen.sort_unstable();
        assert_eq!(seen, (0..11).collect::<Vec<_>>());
        for (s, &user) in layout.order.iter().enumerate() {
            let given = springs[user as usize];
            assert_eq!(
                (layout.a[s], layout.b[s]),
                (given.a.min(given.b), given.a.max(given.b))
            );
        }
    }

    /// The dispatched kernel (AVX2 where the processor has it) and the portable scalar
    /// build give bit-identical forces: no fused multiply-adds, no reassociation.
    #[test]
    fn every_instruction_set_gives_the_same_bits() {
        use glam::Vec3;
        // A 12×12 grid (runs, with padding) plus long-range springs (scattered).
        let side = 12u32;
        let mut springs = Vec::new();
        for y in 0..side {
            for x in 0..side {
                let i = y * side + x;
                if x > 0 {
                    springs.push(spec(i, i - 1));
                }
                if y > 0 {
                    springs.push(spec(i, i - side));
                }
                if x > 1 && y > 2 {
                    springs.push(spec(i, i - 2 * side - 3));
                }
            }
        }
        for i in (0..side * side - 40).step_by(7) {
            springs.push(SpringSpec {
                rest_length: 0.5,
                stiffness: 3.0,
                damping: 0.25,
                ..spec(i, i + 37)
            });
        }
        let layout = SpringLayout::new(&springs);
        assert!(layout.runs.len() > 1 && layout.scattered_start < layout.len());
        // Deterministic, irregular state.
        let n = (side * side) as usize;
        let mut seed = 0x2545_f491_u32;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed as f32 / u32::MAX as f32 - 0.5
        };
        let x = Soa3::from_vec3(
            &(0..n)
                .map(|i| Vec3::new((i % 12) as f32 + next(), (i / 12) as f32 + next(), next()))
                .collect::<Vec<_>>(),
        );
        let v = Soa3::from_vec3(
            &(0..n)
                .map(|_| Vec3::new(next(), next(), next()))
                .collect::<Vec<_>>(),
        );
        fn forces<const AXIAL: bool>(
            arch: Option<pulp::Arch>,
            layout: &SpringLayout,
            x: &Soa3,
            v: &Soa3,
        ) -> (Soa3, Soa3) {
            let (mut fa, mut fb) = (Soa3::zeros(x.x.len()), Soa3::zeros(x.x.len()));
            match arch {
                None => layout.accumulate::<AXIAL>(x, v, &mut fa, &mut fb),
                Some(arch) => arch.dispatch(Accumulate::<AXIAL> {
                    layout,
                    x,
                    v,
                    fa: &mut fa,
                    fb: &mut fb,
                }),
            }
            (fa, fb)
        }
        let bits = |s: &Soa3| {
            [&s.x, &s.y, &s.z]
                .iter()
                .flat_map(|c| c.iter().map(|f| f.to_bits()))
                .collect::<Vec<_>>()
        };
        for axial in [false, true] {
            let (fast, scalar) = if axial {
                (
                    forces::<true>(None, &layout, &x, &v),
                    forces::<true>(Some(pulp::Arch::Scalar), &layout, &x, &v),
                )
            } else {
                (
                    forces::<false>(None, &layout, &x, &v),
                    forces::<false>(Some(pulp::Arch::Scalar), &layout, &x, &v),
                )
            };
            assert!(bits(&fast.0).iter().any(|&b| b != 0));
            assert_eq!(bits(&fast.0), bits(&scalar.0), "a ends, axial = {axial}");
            assert_eq!(bits(&fast.1), bits(&scalar.1), "b ends, axial = {axial}");
        }
    }

    #[test]
    fn coincident_endpoints_push_apart_along_x_without_nan() {
        let f = spring_force::<true>([0.0; 3], [0.0; 3], 2.0, 3.0, 1.0);
        assert_eq!(f, [-6.0, 0.0, 0.0]);
        let f = spring_force::<false>([0.0; 3], [1.0, 0.0, 0.0], 0.0, 3.0, 1.0);
        assert_eq!(f, [1.0, 0.0, 0.0]);
        assert!(spring_force::<true>([0.0; 3], [0.0; 3], 0.0, 3.0, 1.0) == [0.0; 3]);
    }
}
