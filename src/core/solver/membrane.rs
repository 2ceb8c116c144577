//! A membrane's in-plane stiffness on one triangle of the network, written over the changes
//! of the triangle's three edge lengths: the constant-strain triangle of linear elasticity in
//! plane stress, as a 3 × 3 matrix that a spring network can be compared with (and coupled
//! by).
//!
//! **Why edge lengths.** A triangle's in-plane strain ε (2 × 2, symmetric: three numbers) is
//! fixed by the strains of its three edges, eₖ = δₖ/L̄ₖ = dₖᵀ·ε·dₖ with dₖ the edge's unit
//! direction. So a membrane's energy A·½·εᵀCε is a quadratic form ½·δᵀKδ in the length
//! changes δ, rotation-invariant by construction. A spring network is the same form with K
//! *diagonal*. On an equilateral triangle with Poisson's ratio 1/3 the membrane's K is
//! diagonal too, each edge's entry E·A/L² (two triangles per edge give a lattice's spring
//! k = √3·E/2: [`SHEET_LATTICE_FACTOR`](super::SHEET_LATTICE_FACTOR)'s relation). On the
//! irregular triangles that §3 leaves, K has off-diagonal entries as large as its diagonal,
//! which no choice of spring stiffness can stand for: measured on the hat at 40–50 % of its
//! points, sheet springs alone were 14–18 % stiffer than the membrane they claimed to be
//! for one smooth deflection, and 8 % softer at full resolution (docs/PERFORMANCE.md,
//! "Why the hat does not converge"). So a sheet's material
//! ([`MaterialUnits::Sheet`](super::MaterialUnits::Sheet)) puts the diagonal into the
//! springs and the rest into couplings between a triangle's edges
//! ([`SpringMaterial::couplings`](super::SpringMaterial::couplings)): together they are
//! this membrane on any triangulation.

use glam::{DMat3, DVec3, Vec3};

/// The Poisson's ratio of a regular triangle lattice of equal springs (plane stress): the
/// only one a spring network can stand for, and the one [`triangle_stiffness`] is compared at.
pub const LATTICE_POISSON_RATIO: f32 = 1.0 / 3.0;

/// The edges of a triangle `[p₀, p₁, p₂]` in the order [`triangle_stiffness`] uses:
/// (p₀, p₁), (p₁, p₂), (p₂, p₀).
pub const TRIANGLE_EDGES: [(usize, usize); 3] = [(0, 1), (1, 2), (2, 0)];

/// A triangle whose area is below this fraction of its longest edge squared is degenerate
/// (its edges' directions do not fix a strain).
const DEGENERATE_AREA: f64 = 1e-6;

/// The stiffness K (N/m) of a constant-strain membrane triangle at rest at `corners`, of
/// Young's modulus `modulus` (N/m, a sheet's: E·thickness) and Poisson's ratio `poisson`,
/// over the length changes of its edges in [`TRIANGLE_EDGES`] order: its energy is
/// ½·δᵀKδ with δₖ = Lₖ − L̄ₖ, to second order in the strain. `None` when the triangle is
/// degenerate (zero area against its size), when `poisson` is not in (−1, ½], or when a
/// number is not finite.
pub fn triangle_stiffness(corners: [Vec3; 3], modulus: f32, poisson: f32) -> Option<[[f32; 3]; 3]> {
    if !(modulus.is_finite() && poisson > -1.0 && poisson <= 0.5) {
        return None;
    }
    let p = corners.map(|c| c.as_dvec3());
    let normal = (p[1] - p[0]).cross(p[2] - p[0]);
    let area = 0.5 * normal.length();
    let longest = TRIANGLE_EDGES
        .iter()
        .map(|&(i, j)| p[j].distance_squared(p[i]))
        .fold(0.0, f64::max);
    if !(area.is_finite() && area > DEGENERATE_AREA * longest) {
        return None;
    }
    // An orthonormal frame of the triangle's plane.
    let u = (p[1] - p[0]).normalize();
    let v = normal.normalize().cross(u);
    // Rows: an edge's strain over (εxx, εyy, γxy) (γ the engineering shear 2εxy).
    let mut rows = [DVec3::ZERO; 3];
    let mut lengths = [0.0; 3];
    for (k, &(i, j)) in TRIANGLE_EDGES.iter().enumerate() {
        let edge = p[j] - p[i];
        lengths[k] = edge.length();
        let (c, s) = (edge.dot(u) / lengths[k], edge.dot(v) / lengths[k]);
        rows[k] = DVec3::new(c * c, s * s, c * s);
    }
    let strain_of_edges = DMat3::from_cols(rows[0], rows[1], rows[2])
        .transpose()
        .inverse();
    let (e, nu) = (f64::from(modulus), f64::from(poisson));
    let c = e / (1.0 - nu * nu);
    let elasticity = DMat3::from_cols(
        DVec3::new(c, c * nu, 0.0),
        DVec3::new(c * nu, c, 0.0),
        DVec3::new(0.0, 0.0, c * (1.0 - nu) / 2.0),
    );
    let over_strains = strain_of_edges.transpose() * elasticity * strain_of_edges * area;
    let mut out = [[0.0; 3]; 3];
    for (a, row) in out.iter_mut().enumerate() {
        for (b, entry) in row.iter_mut().enumerate() {
            *entry = (over_strains.col(b)[a] / (lengths[a] * lengths[b])) as f32;
        }
    }
    out.iter().flatten().all(|x| x.is_finite()).then_some(out)
}

/// The energy ½·δᵀKδ of a triangle of stiffness `stiffness` ([`triangle_stiffness`]) whose
/// edges' length changes are `changes` ([`TRIANGLE_EDGES`] order), J.
pub fn triangle_energy(stiffness: &[[f32; 3]; 3], changes: [f32; 3]) -> f64 {
    let mut energy = 0.0;
    for (a, row) in stiffness.iter().enumerate() {
        for (b, &k) in row.iter().enumerate() {
            energy += 0.5 * f64::from(k) * f64::from(changes[a]) * f64::from(changes[b]);
        }
    }
    energy
}

/// The in-plane energy of a membrane on `triangles` at rest at `rest`, displaced to
/// `positions`, of Young's modulus `modulus` and Poisson's ratio `poisson` (the sum of
/// [`triangle_energy`] over the triangles; degenerate triangles carry none), J. Rigid motion
/// costs nothing.
///
/// # Panics
/// When a triangle names a point past `rest` or `positions`.
pub fn membrane_energy(
    triangles: &[[u32; 3]],
    rest: &[Vec3],
    positions: &[Vec3],
    modulus: f32,
    poisson: f32,
) -> f64 {
    triangles
        .iter()
        .filter_map(|t| {
            let corners = t.map(|i| rest[i as usize]);
            let stiffness = triangle_stiffness(corners, modulus, poisson)?;
            let now = t.map(|i| positions[i as usize]);
            let changes = TRIANGLE_EDGES
                .map(|(i, j)| now[j].distance(now[i]) - corners[j].distance(corners[i]));
            Some(triangle_energy(&stiffness, changes))
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Quat;

    /// Plane stress energy of the strain `(εxx, εyy, εxy)` over `area`, written out.
    fn plane_stress(area: f64, modulus: f64, nu: f64, (xx, yy, xy): (f64, f64, f64)) -> f64 {
        let trace = xx + yy;
        let squares = xx * xx + yy * yy + 2.0 * xy * xy;
        area * modulus / (2.0 * (1.0 - nu * nu)) * ((1.0 - nu) * squares + nu * trace * trace)
    }

    /// The length changes a strain gives a triangle lying in the xy plane (to first order).
    fn changes(p: [Vec3; 3], (xx, yy, xy): (f64, f64, f64)) -> [f32; 3] {
        TRIANGLE_EDGES.map(|(i, j)| {
            let e = (p[j] - p[i]).as_dvec3();
            let l = e.length();
            let (c, s) = (e.x / l, e.y / l);
            (l * (c * c * xx + s * s * yy + 2.0 * c * s * xy)) as f32
        })
    }

    #[test]
    fn equals_plane_stress_on_uneven_triangles() {
        let triangles = [
            [
                Vec3::ZERO,
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(0.2, 0.7, 0.0),
            ],
            [
                Vec3::ZERO,
                Vec3::new(0.3, -0.1, 0.0),
                Vec3::new(2.0, 0.4, 0.0),
            ],
            [
                Vec3::new(1.0, 1.0, 0.0),
                Vec3::new(0.9, 3.0, 0.0),
                Vec3::new(0.0, 1.2, 0.0),
            ],
        ];
        let strains = [(1e-3, 0.0, 0.0), (0.0, -2e-3, 5e-4), (7e-4, 3e-4, -9e-4)];
        for p in triangles {
            let area = 0.5 * f64::from((p[1] - p[0]).cross(p[2] - p[0]).length());
            for nu in [0.0, 1.0 / 3.0, 0.45] {
                let k = triangle_stiffness(p, 70.0, nu).unwrap();
                for strain in strains {
                    let want = plane_stress(area, 70.0, f64::from(nu), strain);
                    let got = triangle_energy(&k, changes(p, strain));
                    assert!((got - want).abs() <= 1e-4 * want, "{got} against {want}");
                }
            }
        }
    }

    #[test]
    fn an_equilateral_triangle_at_one_third_is_three_springs() {
        let (l, e) = (0.3f32, 70.0f32);
        let p = [
            Vec3::ZERO,
            Vec3::new(l, 0.0, 0.0),
            Vec3::new(l / 2.0, l * 3f32.sqrt() / 2.0, 0.0),
        ];
        let k = triangle_stiffness(p, e, LATTICE_POISSON_RATIO).unwrap();
        let area = l * l * 3f32.sqrt() / 4.0;
        for (a, row) in k.iter().enumerate() {
            for (b, &entry) in row.iter().enumerate() {
                let want = if a == b { e * area / (l * l) } else { 0.0 };
                assert!(
                    (entry - want).abs() < 1e-4 * e,
                    "K[{a}][{b}] = {entry}, want {want}"
                );
            }
        }
        // Two such triangles per edge: a lattice spring of 3·E·A/L² with A = 2·area/3.
        let lattice = super::super::SHEET_LATTICE_FACTOR * e * (2.0 * area / 3.0) / (l * l);
        assert!((2.0 * k[0][0] - lattice).abs() < 1e-4 * lattice);
    }

    #[test]
    fn does_not_depend_on_where_the_triangle_lies() {
        let p = [
            Vec3::ZERO,
            Vec3::new(0.3, -0.1, 0.0),
            Vec3::new(2.0, 0.4, 0.0),
        ];
        let turn = Quat::from_axis_angle(Vec3::new(1.0, 2.0, -0.5).normalize(), 1.1);
        let moved = p.map(|c| turn * c + Vec3::new(5.0, -3.0, 2.0));
        let (a, b) = (
            triangle_stiffness(p, 10.0, 0.3).unwrap(),
            triangle_stiffness(moved, 10.0, 0.3).unwrap(),
        );
        for (ra, rb) in a.iter().zip(&b) {
            for (x, y) in ra.iter().zip(rb) {
                assert!((x - y).abs() <= 1e-4 * 10.0, "{x} against {y}");
            }
        }
        // A rigid motion costs nothing.
        let energy = membrane_energy(&[[0, 1, 2]], &p, &moved, 10.0, 0.3);
        assert!(energy.abs() < 1e-9, "{energy}");
    }

    #[test]
    fn refuses_degenerate_triangles_and_ratios() {
        let line = [Vec3::ZERO, Vec3::X, Vec3::X * 2.0];
        assert!(triangle_stiffness(line, 1.0, 0.3).is_none());
        let p = [Vec3::ZERO, Vec3::X, Vec3::Y];
        assert!(triangle_stiffness(p, 1.0, 0.6).is_none());
        assert!(triangle_stiffness(p, 1.0, -1.0).is_none());
        assert!(triangle_stiffness(p, f32::NAN, 0.3).is_none());
        assert!(triangle_stiffness([Vec3::NAN, Vec3::X, Vec3::Y], 1.0, 0.3).is_none());
        // A degenerate triangle carries no energy and no NaN.
        let energy = membrane_energy(
            &[[0, 1, 2]],
            &line,
            &[Vec3::ZERO, Vec3::X, Vec3::Y],
            1.0,
            0.3,
        );
        assert_eq!(energy, 0.0);
    }
}
