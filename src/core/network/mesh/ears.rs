//! Closing (step 4): ears across the gaps at closable points, narrowest gap first, until no
//! ear fits; loops of closable points are holes.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use super::*;

impl Builder<'_> {
    /// Step 3: ears across the gaps of closable points, narrowest first. A loop most of whose
    /// points are closable is a hole: its other points are closed too. First ears that pass
    /// every test of the selection; then, for what is left, ears that only keep the mesh a
    /// manifold and do not fold over (see [`Builder::add_ear`]).
    /// Returns which points are closable in the end.
    pub(super) fn close(&mut self, closable: &[bool], graph: &KnnGraph) -> Vec<bool> {
        self.limit = MAX_CLOSING_ANGLE;
        let mut closable = closable.to_vec();
        self.ear_rounds(&mut closable, true);
        // Points the strict ears surrounded: split in while sectors are still sorted.
        self.insert_stragglers(graph);
        self.ear_rounds(&mut closable, false);
        closable
    }

    /// Rounds of ears across the gaps of `closable` points, narrowest first, `strict`ly
    /// tested ([`Builder::try_add`]) or not ([`Builder::add_ear`]); a loop most of whose points
    /// are closable makes all of them closable.
    pub(super) fn ear_rounds(&mut self, closable: &mut [bool], strict: bool) {
        for _ in 0..MAX_CLOSING_ROUNDS {
            for points in self.mesh.boundary_loops() {
                let inner = points.iter().filter(|&&v| closable[v as usize]).count();
                if 2 * inner >= points.len() {
                    for v in points {
                        closable[v as usize] = true;
                    }
                }
            }
            let mut queue: BinaryHeap<Reverse<(u32, u32, u32, u32)>> = BinaryHeap::new();
            for v in (0..closable.len()).filter(|&v| closable[v]) {
                self.queue_gaps(v as u32, &mut queue);
            }
            let before = self.mesh.stats.ears;
            while let Some(Reverse((_, v, u, x))) = queue.pop() {
                let added = if !self.over_dense([v, u, x]) {
                    false
                } else if strict {
                    self.try_add([v, u, x])
                } else {
                    self.add_ear(v, u, x)
                };
                if added {
                    self.mesh.stats.ears += 1;
                    for w in [v, u, x] {
                        if closable[w as usize] {
                            self.queue_gaps(w, &mut queue);
                        }
                    }
                }
            }
            if self.mesh.stats.ears == before {
                break;
            }
        }
    }

    /// Adds the ear (v, u, x) across the gap at `v` from `u` to `x`, where a hole's loop runs
    /// u → v → x, when it keeps the mesh a manifold (the edge u → x is not in use) and does not
    /// fold over: it turns counter-clockwise at `v` by less than [`MAX_CLOSING_ANGLE`] and its
    /// normal is within 90° of the mean of its corners' normals. Where the surface curves
    /// sharply between coarse points (a finger, an ear, a thin leg), no triangle across a hole
    /// can face within 90° of all three corners' normals; tangent planes then say nothing about
    /// overlaps at `u` and `x`, so the new sectors go into their fans by the loop's order, not
    /// by angle.
    pub(super) fn add_ear(&mut self, v: u32, u: u32, x: u32) -> bool {
        let normals = &self.normals;
        if self.wedge(v, u, x).is_none() || !self.ear_is_manifold(v, u, x) {
            return false;
        }
        let p = |i: u32| self.positions[i as usize];
        let normal = (p(u) - p(v)).cross(p(x) - p(v)).normalize_or_zero();
        let mean = normals[v as usize] + normals[u as usize] + normals[x as usize];
        if normal.dot(mean) <= 0.0 || self.overlaps_apart([v, u, x]) {
            return false;
        }
        // Where the triangle faces within 60° of a side corner's normal, that corner's tangent
        // plane is meaningful: the ear must not overlap its triangles there.
        for (c, from, to) in [(u, x, v), (x, v, u)] {
            if normal.dot(normals[c as usize]) > STEEP_COS {
                let Some(w) = self.wedge(c, from, to) else {
                    return false;
                };
                if self.mesh.wedges[c as usize].iter().any(|o| overlaps(o, &w)) {
                    return false;
                }
            }
        }
        self.insert_ear(v, u, x)
    }

    /// Whether the ear (v, u, x) across the gap at `v` from `u` to `x` keeps the mesh a
    /// manifold: that gap exists, no directed edge of the ear is in use, and where u and x are
    /// joined already the ear closes the gap between them at both ends (anything else would
    /// glue two sheets together at u or x).
    pub(super) fn ear_is_manifold(&self, v: u32, u: u32, x: u32) -> bool {
        let fan = |p: u32| &self.mesh.wedges[p as usize];
        let used = |a: u32, b: u32| fan(a).iter().any(|w| w.from == b);
        if u == x || used(v, u) || used(u, x) || used(x, v) {
            return false;
        }
        let (fv, fu, fx) = (fan(v), fan(u), fan(x));
        let gap_at_v = (0..fv.len()).any(|i| fv[i].to == u && fv[(i + 1) % fv.len()].from == x);
        let (Some(at_u), Some(at_x)) = (
            fu.iter().position(|w| w.from == v),
            fx.iter().position(|w| w.to == v),
        ) else {
            return false;
        };
        gap_at_v
            && (!fu.iter().any(|w| w.to == x) || fu[(at_u + fu.len() - 1) % fu.len()].to == x)
            && (!fx.iter().any(|w| w.from == u) || fx[(at_x + 1) % fx.len()].from == u)
    }

    /// Inserts the ear (v, u, x) (checked by [`Builder::ear_is_manifold`]) into the fans of its
    /// corners by the loop's order.
    pub(super) fn insert_ear(&mut self, v: u32, u: u32, x: u32) -> bool {
        let fan = |p: u32| &self.mesh.wedges[p as usize];
        let (fv, fu, fx) = (fan(v), fan(u), fan(x));
        let at_v = (0..fv.len()).find(|&i| fv[i].to == u && fv[(i + 1) % fv.len()].from == x);
        let at_u = fu.iter().position(|w| w.from == v);
        let at_x = fx.iter().position(|w| w.to == v);
        let (Some(at_v), Some(at_u), Some(at_x)) = (at_v, at_u, at_x) else {
            return false;
        };
        let (wv, wu, wx) = (
            self.raw_wedge(v, u, x),
            self.raw_wedge(u, x, v),
            self.raw_wedge(x, v, u),
        );
        self.mesh.wedges[v as usize].insert(at_v + 1, wv);
        self.mesh.wedges[u as usize].insert(at_u, wu);
        self.mesh.wedges[x as usize].insert(at_x + 1, wx);
        true
    }

    /// The sector of triangle (c, from, to) at `c`, whatever its angle.
    pub(super) fn raw_wedge(&self, c: u32, from: u32, to: u32) -> Wedge {
        let start = self.angle(c, from);
        Wedge {
            from,
            to,
            start,
            sweep: (self.angle(c, to) - start).rem_euclid(TAU),
        }
    }
}

impl Builder<'_> {
    /// Queues the ears across `v`'s gaps that are narrow enough, keyed by their angle.
    pub(super) fn queue_gaps(&self, v: u32, queue: &mut BinaryHeap<Reverse<(u32, u32, u32, u32)>>) {
        let gaps: Vec<(u32, u32)> = self.mesh.gaps(v as usize).collect();
        for (u, x) in gaps {
            if let Some(w) = self.wedge(v, u, x) {
                queue.push(Reverse((w.sweep.to_bits(), v, u, x)));
            }
        }
    }
}
