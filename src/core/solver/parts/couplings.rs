//! Couplings between the three edge springs of a triangle: the part of a membrane's in-plane
//! energy that springs alone cannot carry.
//!
//! A constant-strain membrane triangle's energy is ½·δᵀKδ over its three edges' length
//! changes δ (see [`membrane`](crate::core::solver::membrane)). Its diagonal goes into the
//! edges' springs (½·kᵢ·δᵢ², summed over the triangles an edge has); a coupling adds the
//! rest, Σᵢ<ⱼ Cᵢⱼ·δᵢ·δⱼ with Cᵢⱼ = Kᵢⱼ. The springs keep their rest lengths, so plastic flow,
//! bakes and snapshots of the rest lengths reach the couplings with no state of their own:
//! δᵢ is measured against spring i's rest length. The forces are central (along each edge),
//! so they keep momentum and angular momentum. Implicit Euler takes their Gauss–Newton
//! block h²·JᵀCJ (J: each edge's direction on its two ends), whose sum with the springs'
//! diagonal is the membrane's positive semi-definite JᵀKJ; the preconditioner takes its
//! blocks too (block Jacobi's at the corner each pair of edges shares, Gauss–Seidel's on the
//! triangle's edges), without which conjugate gradient needs 15–36 % more iterations.

use glam::{DVec3, Vec3};

use super::super::spring_layout::{COINCIDENT_DISTANCE, SpringLayout};
use super::{PointState, Soa3};
use crate::core::solver::SolverError;

/// One triangle's coupling: its three edge springs (by the index they were given at, see
/// [`Springs::iter`](super::Springs::iter)) and the couplings C₀₁, C₁₂, C₂₀ between them
/// (N/m: the energy gains Cᵢⱼ·δᵢ·δⱼ).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CouplingSpec {
    /// The springs of the triangle's edges.
    pub springs: [u32; 3],
    /// The couplings of the pairs (0, 1), (1, 2) and (2, 0).
    pub coupling: [f32; 3],
}

/// The pairs of a triangle's edges that [`CouplingSpec::coupling`] couples, in its order.
pub(crate) const COUPLED_PAIRS: [(usize, usize); 3] = [(0, 1), (1, 2), (2, 0)];

/// C·x for the symmetric coupling matrix C with zero diagonal and the off-diagonal entries
/// `coupling` ([`COUPLED_PAIRS`] order): each edge's share from the other two.
#[inline]
fn coupled<T>(coupling: [T; 3], x: [T; 3]) -> [T; 3]
where
    T: Copy + std::ops::Mul<Output = T> + std::ops::Add<Output = T>,
{
    let [c01, c12, c20] = coupling;
    [
        c01 * x[1] + c20 * x[2],
        c01 * x[0] + c12 * x[2],
        c12 * x[1] + c20 * x[0],
    ]
}

/// The couplings of a surface (see the module docs), part of
/// [`Springs`](super::Springs), over the springs' internal order.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Couplings {
    /// Each triangle's three springs, at their internal positions.
    pub(crate) springs: Vec<[u32; 3]>,
    pub(crate) coupling: Vec<[f32; 3]>,
}

/// One triangle's coupling in an implicit step: each edge's unit direction (`b` end minus
/// `a` end) and h²·Cᵢⱼ.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct CouplingBlock {
    pub u: [DVec3; 3],
    pub scaled: [f64; 3],
}

impl CouplingBlock {
    /// For each pair of edges (i, j) with its scaled coupling c: the corner the two edges
    /// share, and the signs it has in each (+1 at an edge's `a` end, −1 at its `b` end), from
    /// each edge's `[a, b]` ends.
    pub fn corners(
        &self,
        ends: [[usize; 2]; 3],
    ) -> impl Iterator<Item = (usize, usize, f64, [f64; 2], usize)> + '_ {
        COUPLED_PAIRS
            .iter()
            .zip(self.scaled)
            .flat_map(move |(&(i, j), c)| {
                let mut shared = None;
                for (p, si) in ends[i].into_iter().zip([1.0, -1.0]) {
                    for (q, sj) in ends[j].into_iter().zip([1.0, -1.0]) {
                        if p == q {
                            shared = Some((i, j, c, [si, sj], p));
                        }
                    }
                }
                shared
            })
    }

    /// The block's w = h²·C·(J·p) over its three edges, J·p = uᵢ·(p_a − p_b) for each edge.
    #[inline]
    pub fn weights(&self, rates: [f64; 3]) -> [f64; 3] {
        coupled(self.scaled, rates)
    }
}

impl Couplings {
    /// The couplings of `specs` over `layout`'s springs: each triangle's three springs
    /// distinct and in range, its couplings finite.
    pub(crate) fn new(specs: &[CouplingSpec], layout: &SpringLayout) -> Result<Self, SolverError> {
        let mut internal = vec![u32::MAX; layout.real()];
        for s in 0..layout.len() {
            if !layout.is_padding(s) {
                internal[layout.order[s] as usize] = s as u32;
            }
        }
        let mut out = Self::default();
        for (triangle, spec) in specs.iter().enumerate() {
            let [a, b, c] = spec.springs;
            let in_range = spec.springs.iter().all(|&s| (s as usize) < internal.len());
            if !in_range || a == b || b == c || c == a {
                return Err(SolverError::InvalidCoupling {
                    triangle,
                    what: "its three springs must be distinct and in range",
                });
            }
            if !spec.coupling.iter().all(|c| c.is_finite()) {
                return Err(SolverError::InvalidCoupling {
                    triangle,
                    what: "its couplings must be finite",
                });
            }
            out.springs.push(spec.springs.map(|s| internal[s as usize]));
            out.coupling.push(spec.coupling);
        }
        Ok(out)
    }

    /// Each edge's unit direction (b end minus a end; +X for coincident ends) and length
    /// change against its spring's rest length, at `x`.
    #[inline]
    fn edges(layout: &SpringLayout, springs: [u32; 3], x: &Soa3) -> [(Vec3, f32); 3] {
        springs.map(|s| {
            let s = s as usize;
            let d = x.get(layout.b[s] as usize) - x.get(layout.a[s] as usize);
            let len = d.length();
            let u = if len > COINCIDENT_DISTANCE {
                d / len
            } else {
                Vec3::X
            };
            (u, len - layout.rest[s])
        })
    }

    /// Adds the couplings' forces at `points` to `f`: each edge pulled together by its extra
    /// tension (pushed apart where negative).
    pub(crate) fn accumulate(&self, layout: &SpringLayout, points: &PointState, f: &mut Soa3) {
        for (&springs, &coupling) in self.springs.iter().zip(&self.coupling) {
            let edges = Self::edges(layout, springs, &points.x);
            // Each edge's extra tension Σⱼ Cᵢⱼ·δⱼ from the other two.
            let t = coupled(coupling, edges.map(|(_, d)| d));
            for ((&s, (u, _)), t) in springs.iter().zip(edges).zip(t) {
                let (a, b) = (layout.a[s as usize] as usize, layout.b[s as usize] as usize);
                f.set(a, f.get(a) + t * u);
                f.set(b, f.get(b) - t * u);
            }
        }
    }

    /// The couplings' energy Σᵢ<ⱼ Cᵢⱼ·δᵢ·δⱼ at `points` (it may be negative; with the
    /// springs' it is the membrane's, which is not).
    pub(crate) fn energy(&self, layout: &SpringLayout, points: &PointState) -> f64 {
        self.springs
            .iter()
            .zip(&self.coupling)
            .map(|(&springs, coupling)| {
                let d = Self::edges(layout, springs, &points.x).map(|(_, d)| f64::from(d));
                COUPLED_PAIRS
                    .iter()
                    .zip(coupling)
                    .map(|(&(i, j), &c)| f64::from(c) * d[i] * d[j])
                    .sum::<f64>()
            })
            .sum()
    }

    /// The couplings for an implicit step of length `step` at `points`, into `out`.
    pub(crate) fn linearised(
        &self,
        layout: &SpringLayout,
        points: &PointState,
        step: f64,
        out: &mut Vec<CouplingBlock>,
    ) {
        out.clear();
        // The directions in f64, as the springs' blocks have theirs.
        let direction = |s: u32| {
            let s = s as usize;
            let d = (points.x.get(layout.b[s] as usize) - points.x.get(layout.a[s] as usize))
                .as_dvec3();
            let len = d.length();
            if len > f64::from(COINCIDENT_DISTANCE) {
                d / len
            } else {
                DVec3::X
            }
        };
        out.extend(
            self.springs
                .iter()
                .zip(&self.coupling)
                .map(|(&springs, c)| CouplingBlock {
                    u: springs.map(direction),
                    scaled: c.map(|c| step * step * f64::from(c)),
                }),
        );
    }

    /// Each coupled triangle's springs' ends, `[a, b]` per edge (internal order's).
    pub(crate) fn ends<'a>(
        &'a self,
        layout: &'a SpringLayout,
    ) -> impl Iterator<Item = [[usize; 2]; 3]> + 'a {
        self.springs.iter().map(move |springs| {
            springs.map(|s| [layout.a[s as usize] as usize, layout.b[s as usize] as usize])
        })
    }

    /// Adds each coupling's Gershgorin row bound to `stiff`: 2·|Cᵢⱼ| at the four ends of the
    /// pair of edges it couples.
    pub(crate) fn stability_rows(&self, layout: &SpringLayout, stiff: &mut [f64]) {
        for (ends, coupling) in self.ends(layout).zip(&self.coupling) {
            for (&(i, j), &c) in COUPLED_PAIRS.iter().zip(coupling) {
                let bound = 2.0 * f64::from(c.abs());
                for p in ends[i].into_iter().chain(ends[j]) {
                    stiff[p] += bound;
                }
            }
        }
    }

    /// Every coupling with its springs named by the index they were given at.
    pub(crate) fn iter<'a>(
        &'a self,
        layout: &'a SpringLayout,
    ) -> impl ExactSizeIterator<Item = CouplingSpec> + 'a {
        self.springs
            .iter()
            .zip(&self.coupling)
            .map(|(springs, &coupling)| CouplingSpec {
                springs: springs.map(|s| layout.order[s as usize]),
                coupling,
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::solver::SpringSpec;
    use crate::core::solver::parts::Springs;

    /// Two triangles (0, 1, 2) and (1, 3, 2) sharing the edge 1–2, out of their plane, each
    /// edge a spring off its rest length, and couplings of both signs.
    fn patch() -> (Springs, Vec<Vec3>) {
        let x = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.1, 0.1, 0.0),
            Vec3::new(0.3, 0.9, 0.2),
            Vec3::new(1.2, 1.0, -0.3),
        ];
        let edges = [(0, 1), (1, 2), (2, 0), (1, 3), (3, 2)];
        let specs: Vec<SpringSpec> = edges
            .iter()
            .enumerate()
            .map(|(s, &(a, b))| SpringSpec {
                a,
                b,
                rest_length: x[a as usize].distance(x[b as usize]) * [0.9, 1.15, 1.0][s % 3],
                stiffness: 50.0 + 10.0 * s as f32,
                damping: 0.0,
            })
            .collect();
        let mut springs = Springs::new(&specs, x.len()).unwrap();
        springs
            .set_couplings(&[
                CouplingSpec {
                    springs: [0, 1, 2],
                    coupling: [12.0, -7.0, 4.0],
                },
                CouplingSpec {
                    springs: [3, 4, 1],
                    coupling: [-5.0, 9.0, 3.0],
                },
            ])
            .unwrap();
        (springs, x)
    }

    #[test]
    fn the_force_is_minus_the_energy_gradient() {
        let (springs, x) = patch();
        let points = PointState::new(&x).unwrap();
        let mut f = Soa3::zeros(x.len());
        springs
            .couplings
            .accumulate(&springs.layout, &points, &mut f);
        let h = 1e-3;
        for i in 0..x.len() {
            for axis in [Vec3::X, Vec3::Y, Vec3::Z] {
                let energy = |sign: f32| {
                    let mut moved = x.clone();
                    moved[i] += sign * h * axis;
                    let p = PointState::new(&moved).unwrap();
                    springs.couplings.energy(&springs.layout, &p)
                };
                let numeric = -(energy(1.0) - energy(-1.0)) / (2.0 * f64::from(h));
                let exact = f64::from(f.get(i).dot(axis));
                assert!(
                    (numeric - exact).abs() < 2e-3 * (1.0 + exact.abs()),
                    "{i} {axis}: {numeric} against {exact}"
                );
            }
        }
        // Central forces: no net force, no net torque.
        let total: Vec3 = (0..x.len()).map(|i| f.get(i)).sum();
        let torque: Vec3 = (0..x.len()).map(|i| x[i].cross(f.get(i))).sum();
        assert!(total.length() < 1e-4 && torque.length() < 1e-4);
    }

    #[test]
    fn springs_name_the_couplings_back_and_bad_ones_are_refused() {
        let (mut springs, _) = patch();
        let back = springs.couplings();
        assert_eq!(back[1].springs, [3, 4, 1]);
        assert_eq!(back[0].coupling, [12.0, -7.0, 4.0]);
        let before = springs.clone();
        for bad in [
            CouplingSpec {
                springs: [0, 0, 1],
                coupling: [1.0; 3],
            },
            CouplingSpec {
                springs: [0, 1, 5],
                coupling: [1.0; 3],
            },
            CouplingSpec {
                springs: [0, 1, 2],
                coupling: [1.0, f32::NAN, 0.0],
            },
        ] {
            assert!(matches!(
                springs.set_couplings(&[bad]),
                Err(SolverError::InvalidCoupling { triangle: 0, .. })
            ));
        }
        assert_eq!(springs, before, "a refusal changes nothing");
    }
}
