//! A simulation point against a triangle of simulation points: the closest point, and the
//! impulse that keeps the two from closing faster than the gap allows, shared out to the
//! corners by their weights ([`Stencil`]s, so that other pairings, an edge against an edge,
//! could share it). Self-contact keeps a surface's points off their own nearby triangles
//! with it, so that a crease does not fold one triangle through its neighbour (point
//! spheres leave out the pairs close on the network, which a fold-over is made of).

use glam::Vec3;

use super::{ContactParams, friction_impulse};

/// The point of the triangle `a b c` closest to `p`, and its barycentric weights (each in
/// [0, 1], summing to 1). A degenerate triangle gives its closest corner or edge.
pub fn closest_on_triangle(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> (Vec3, [f32; 3]) {
    // Ericson, Real-Time Collision Detection, §5.1.5.
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return (a, [1.0, 0.0, 0.0]);
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return (b, [0.0, 1.0, 0.0]);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (a + ab * v, [1.0 - v, v, 0.0]);
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return (c, [0.0, 0.0, 1.0]);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (a + ac * w, [1.0 - w, 0.0, w]);
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (b + (c - b) * w, [0.0, 1.0 - w, w]);
    }
    let denom = va + vb + vc;
    if denom.abs() <= f32::MIN_POSITIVE {
        return (a, [1.0, 0.0, 0.0]);
    }
    let (v, w) = (vb / denom, vc / denom);
    (a + ab * v + ac * w, [1.0 - v - w, v, w])
}

/// Up to three simulation points taken together at weights (a point: one of weight 1; an
/// edge: two; a triangle: three; unused entries of weight 0): their velocities and inverse
/// masses.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Stencil {
    /// The weights (summing to 1).
    pub weights: [f32; 3],
    /// The points' velocities.
    pub velocities: [Vec3; 3],
    /// The points' inverse masses.
    pub inv_masses: [f32; 3],
}

impl Stencil {
    /// The velocity at the weights.
    pub fn velocity(&self) -> Vec3 {
        (0..3).map(|j| self.velocities[j] * self.weights[j]).sum()
    }

    /// How far an impulse of 1 along a direction moves it: Σ w²/m.
    pub fn compliance(&self) -> f32 {
        (0..3)
            .map(|j| self.weights[j] * self.weights[j] * self.inv_masses[j])
            .sum()
    }
}

/// Two parts of a surface near each other at the start of a tick (a point and a triangle,
/// or two edges), and both sides' velocities at its end without the contact.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StencilProximity {
    /// Unit normal, from the far side towards the near side.
    pub normal: Vec3,
    /// Their distance less the surface's thickness there (negative where closer).
    pub gap: f32,
    /// The near side (the point, or the first edge).
    pub near: Stencil,
    /// The far side (the triangle, or the second edge).
    pub far: Stencil,
}

/// The impulse on the near side (each of its points `j` takes `weights[j]` times it; each
/// of the far side's, `−weights[j]` times it) that keeps the sides from closing faster than
/// the gap allows over `dt` (overlapping, from closing at all: the overlap is for the
/// caller to move out by position, [`recovery`](super::recovery)), with Coulomb friction;
/// `None` when they do not touch this tick or nothing can move.
pub fn stencil_impulse(p: &StencilProximity, dt: f32, params: &ContactParams) -> Option<Vec3> {
    let relative = p.near.velocity() - p.far.velocity();
    let normal_speed = relative.dot(p.normal);
    let allowed = super::allowed_closing(p.gap, dt);
    if normal_speed >= allowed {
        return None;
    }
    let compliance = p.near.compliance() + p.far.compliance();
    if compliance <= 0.0 {
        return None;
    }
    let normal_impulse = (allowed - normal_speed) / compliance;
    let impulse = p.normal * normal_impulse
        + friction_impulse(relative, p.normal, normal_impulse, params.friction, |_| {
            compliance
        });
    impulse.is_finite().then_some(impulse)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_closest_point_is_inside_on_an_edge_or_at_a_corner() {
        let (a, b, c) = (Vec3::ZERO, Vec3::X, Vec3::Y);
        let (q, w) = closest_on_triangle(Vec3::new(0.25, 0.25, 1.0), a, b, c);
        assert!(q.distance(Vec3::new(0.25, 0.25, 0.0)) < 1e-6);
        assert!((w[0] - 0.5).abs() < 1e-6 && (w[1] - 0.25).abs() < 1e-6);
        let (q, w) = closest_on_triangle(Vec3::new(0.5, -1.0, 0.0), a, b, c);
        assert!(q.distance(Vec3::new(0.5, 0.0, 0.0)) < 1e-6 && w[2] == 0.0);
        let (q, w) = closest_on_triangle(Vec3::new(2.0, -1.0, 0.0), a, b, c);
        assert_eq!((q, w), (b, [0.0, 1.0, 0.0]));
        // On the hypotenuse.
        let (q, w) = closest_on_triangle(Vec3::new(1.0, 1.0, 0.0), a, b, c);
        assert!(q.distance(Vec3::new(0.5, 0.5, 0.0)) < 1e-6 && w[0] == 0.0);
        // Degenerate: no NaN.
        let (q, w) = closest_on_triangle(Vec3::ONE, a, a, a);
        assert!(q.is_finite() && w.iter().all(|w| w.is_finite()));
    }

    #[test]
    fn a_point_falling_on_a_triangle_stops_at_the_gap_and_momentum_is_kept() {
        let params = ContactParams {
            friction: 0.0,
            depth_recovery: 0.2,
        };
        let dt = 0.01;
        let triangle = Stencil {
            weights: [0.2, 0.3, 0.5],
            velocities: [Vec3::ZERO; 3],
            inv_masses: [2.0, 2.0, 2.0],
        };
        let point = Stencil {
            weights: [1.0, 0.0, 0.0],
            velocities: [Vec3::new(0.0, 0.0, -5.0), Vec3::ZERO, Vec3::ZERO],
            inv_masses: [1.0, 0.0, 0.0],
        };
        let p = StencilProximity {
            normal: Vec3::Z,
            gap: 0.02,
            near: point,
            far: triangle,
        };
        let j = stencil_impulse(&p, dt, &params).expect("it touches");
        // After the impulses, the point closes on the triangle at exactly gap/dt.
        let moved = |s: &Stencil, sign: f32| Stencil {
            velocities: [0, 1, 2]
                .map(|k| s.velocities[k] + sign * j * s.weights[k] * s.inv_masses[k]),
            ..*s
        };
        let (near, far) = (moved(&p.near, 1.0), moved(&p.far, -1.0));
        assert!(((near.velocity() - far.velocity()).z + p.gap / dt).abs() < 1e-4);
        // Momentum: the corners took −Σw·J = −J.
        let given: Vec3 = (0..3).map(|k| -j * triangle.weights[k]).sum();
        assert!((given + j).length() < 1e-6);
        // Moving apart: nothing.
        let apart = StencilProximity {
            near: Stencil {
                velocities: [Vec3::Z; 3],
                ..point
            },
            ..p
        };
        assert!(stencil_impulse(&apart, dt, &params).is_none());
    }
}
