//! Stragglers (step 3): a point left without a triangle is inserted by splitting the
//! triangle it projects into, or the edge it lies over.

use super::*;

impl Builder<'_> {
    /// Step 5: a point still without a triangle (the closed surface passes just over or under
    /// it) splits the triangle of its neighbours that it lies over: its projection on that
    /// triangle's plane inside it, nearer to the plane than the triangle is long, and each new
    /// triangle facing within 90° of its corners' mean normal. The new sectors go into the
    /// corners' fans in place of the old one.
    pub(super) fn split_for_isolated(&mut self, graph: &KnnGraph) {
        let mut over_edges = Vec::new();
        let normals = &self.normals;
        // Points added to fill holes always have their fans.
        for v in 0..graph.len() as u32 {
            if !self.mesh.wedges[v as usize].is_empty() {
                continue;
            }
            let p = self.positions[v as usize];
            let at = |i: u32| self.positions[i as usize];
            let inside = self.triangles_near(v, graph).find(|&[a, b, c]| {
                let (pa, pb, pc) = (at(a), at(b), at(c));
                let n = (pb - pa).cross(pc - pa);
                let area2 = n.length_squared();
                if area2 == 0.0 {
                    return false;
                }
                let height = (p - pa).dot(n) / area2.sqrt();
                let longest = pa.distance(pb).max(pb.distance(pc)).max(pc.distance(pa));
                let faces_up = |x: u32, y: u32| {
                    let mean = normals[x as usize] + normals[y as usize] + normals[v as usize];
                    (at(y) - at(x)).cross(p - at(x)).dot(mean) > 0.0
                };
                [(pb, pc), (pc, pa), (pa, pb)]
                    .iter()
                    .all(|&(x, y)| (y - x).cross(p - x).dot(n) > 0.0)
                    && height.abs() < longest
                    && faces_up(a, b)
                    && faces_up(b, c)
                    && faces_up(c, a)
            });
            let Some([a, b, c]) = inside else {
                over_edges.push(v);
                continue;
            };
            for (corner, from, to) in [(a, b, c), (b, c, a), (c, a, b)] {
                let first = self.raw_wedge(corner, from, v);
                let second = self.raw_wedge(corner, v, to);
                let fan = &mut self.mesh.wedges[corner as usize];
                if let Some(at) = fan.iter().position(|w| w.from == from && w.to == to) {
                    fan[at] = first;
                    fan.insert(at + 1, second);
                }
            }
            self.mesh.wedges[v as usize] = vec![
                self.raw_wedge(v, a, b),
                self.raw_wedge(v, b, c),
                self.raw_wedge(v, c, a),
            ];
            self.mesh.stats.inserted += 1;
        }
        for v in over_edges {
            self.split_edge_for(v, graph);
        }
    }

    /// Step 5 where `v` projects into no triangle: it lies over an inner edge a–b of its
    /// neighbours' triangles (a, b, c) and (b, a, d), between a and b and within the edge's
    /// length of it, and splits both into four, each facing within 90° of its corners' mean
    /// normal. The nearest such edge is split.
    pub(super) fn split_edge_for(&mut self, v: u32, graph: &KnnGraph) {
        let p = self.positions[v as usize];
        let at = |i: u32| self.positions[i as usize];
        let faces_up = |t: [u32; 3]| {
            let [x, y, z] = t.map(at);
            let mean: Vec3 = t.iter().map(|&i| self.normals[i as usize]).sum();
            (y - x).cross(z - x).dot(mean) > 0.0
        };
        let mut best: Option<(f32, [u32; 4])> = None;
        for [a, b, c] in self.triangles_near(v, graph) {
            // The twin across a–b, as the wedge at a from d to b.
            let Some(d) = self.mesh.wedges[a as usize]
                .iter()
                .find(|w| w.to == b)
                .map(|w| w.from)
            else {
                continue;
            };
            let (pa, pb) = (at(a), at(b));
            let edge = pb - pa;
            let t = (p - pa).dot(edge) / edge.length_squared();
            let distance = (pa + edge * t).distance(p);
            let fits = (0.05..=0.95).contains(&t)
                && distance < edge.length()
                && d != c
                && [[a, v, c], [v, b, c], [b, v, d], [v, a, d]]
                    .into_iter()
                    .all(faces_up);
            if fits && best.is_none_or(|(nearest, _)| distance < nearest) {
                best = Some((distance, [a, b, c, d]));
            }
        }
        let Some((_, [a, b, c, d])) = best else {
            return;
        };
        let replace = |b: &mut Self, corner: u32, from: u32, to: u32, new: &[(u32, u32)]| {
            let wedges: Vec<Wedge> = new
                .iter()
                .map(|&(f, t)| b.raw_wedge(corner, f, t))
                .collect();
            let fan = &mut b.mesh.wedges[corner as usize];
            if let Some(i) = fan.iter().position(|w| w.from == from && w.to == to) {
                fan.splice(i..=i, wedges);
            }
        };
        replace(self, a, b, c, &[(v, c)]);
        replace(self, a, d, b, &[(d, v)]);
        replace(self, b, c, a, &[(c, v)]);
        replace(self, b, a, d, &[(v, d)]);
        replace(self, c, a, b, &[(a, v), (v, b)]);
        replace(self, d, b, a, &[(b, v), (v, a)]);
        self.mesh.wedges[v as usize] = [(a, d), (d, b), (b, c), (c, a)]
            .map(|(f, t)| self.raw_wedge(v, f, t))
            .to_vec();
        self.mesh.stats.inserted += 1;
    }
}

impl Builder<'_> {
    /// Whether triangle `t` lies over the dense surface (always, when it is not known).
    pub(super) fn over_dense(&self, [a, b, c]: [u32; 3]) -> bool {
        let p = |i: u32| self.positions[i as usize];
        self.dense.is_none_or(|d| d.covers([p(a), p(b), p(c)]))
    }
}

impl Builder<'_> {
    /// Step 3 (run before closing and between its strict and relaxed ears, while every sector
    /// is still sorted by angle): a point with no triangle splits a triangle at one of its
    /// nearest neighbours that it projects into.
    pub(super) fn insert_stragglers(&mut self, graph: &KnnGraph) {
        for v in 0..graph.len() as u32 {
            if !self.mesh.wedges[v as usize].is_empty() {
                continue;
            }
            let near: Vec<[u32; 3]> = self.triangles_near(v, graph).collect();
            for t @ [a, b, c] in near {
                if !self.mesh.has_wedge(a as usize, b, c) {
                    continue; // split already
                }
                self.remove(t);
                let mut added = Vec::new();
                for part in [[a, b, v], [b, c, v], [c, a, v]] {
                    if !self.try_add(part) {
                        break;
                    }
                    added.push(part);
                }
                if added.len() == 3 {
                    self.mesh.stats.inserted += 1;
                    break;
                }
                // Undo: drop what was added, put the triangle back.
                for part in added {
                    self.remove(part);
                }
                let restored = self.try_add(t);
                debug_assert!(restored, "a removed triangle fits again");
            }
        }
    }
}
