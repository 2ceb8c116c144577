//! The removal loop of §3: every point's ring judged, the point whose ring is smallest
//! removed first, its neighbours' rings judged again, until the target or the diameter
//! limit is reached.

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::ops::ControlFlow;

use glam::Vec3;
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;

use super::*;
use crate::core::simplify::tangent_delaunay::{ring_voronoi_area, twin_before};

/// Reverse lists per rayon task when sweeping removed points out of them.
const SWEEP_CHUNK: usize = 4096;

/// Marks an unused neighbour slot.
const NONE: u32 = u32::MAX;

/// Per-thread scratch space for evaluations.
#[derive(Default)]
struct Scratch {
    builder: RingBuilder,
    points: Vec<Vec3>,
    ring: Vec<(u32, bool)>,
    found: Vec<(f32, u32)>,
}

/// The removal state.
pub(super) struct State<'a> {
    positions: &'a [Vec3],
    normals: Vec<Vec3>,
    k: usize,
    /// Tree over the points remaining when it was built; its items index `tree_ids`.
    tree: ImmutableKdTree<f32, 3>,
    tree_ids: Vec<u32>,
    /// Points the tree was built with.
    tree_built_with: usize,
    /// Each point's k nearest remaining neighbours at its last evaluation (`NONE`-padded).
    knn: Vec<u32>,
    /// Each point's next [`NEIGHBOUR_SPARES`] nearest remaining neighbours at its last
    /// evaluation, after its `knn` row (`NONE`-padded).
    spares: Vec<u32>,
    /// The farthest (squared) distance the k-d query behind each point's `knn` and `spares`
    /// rows returned: every point it did not return is at least this far (0: no rows;
    /// infinite: the query returned every point).
    reach: Vec<f32>,
    /// Whether re-evaluations may answer from the `knn` and `spares` rows (off only in the
    /// test that checks they change nothing).
    use_spares: bool,
    /// Evaluations that had to query the k-d tree.
    queries: usize,
    /// For each point, the points whose `knn` row holds it, and removed points that did
    /// (swept out whenever the tree is rebuilt).
    rev: Vec<Vec<u32>>,
    pub(super) shapes: Vec<RingShape>,
    /// Each point's share of the area from the first pass ([`Simplification::point_areas`]).
    areas: Vec<f32>,
    /// Which slots of each point's `knn` row are ring vertices (bit r = slot r): the
    /// neighbours whose removal changes its ring. Every slot for a point whose ring is open,
    /// degenerate or has a coincident neighbour (any removal nearby may change those).
    dirty_mask: Vec<u64>,
    alive: Vec<bool>,
    dirty: Vec<bool>,
    /// Points a round may not remove any more (a neighbour of one it removes).
    blocked: Vec<bool>,
    /// Points never removed but as duplicates (empty: none; see
    /// [`simplify_keeping`](super::simplify_keeping)).
    locked: Vec<bool>,
    /// Each point's key at its last evaluation (the bits of its [`priority`]).
    keys: Vec<u32>,
    /// The remaining points in index order while rounds run (then empty).
    remaining: Vec<u32>,
    /// Whether the heap is kept: not while rounds run (they choose by selection).
    queued: bool,
    /// Rounds run while more points than this are left.
    rounds_above: usize,
    generation: Vec<u32>,
    heap: BinaryHeap<Reverse<(u32, u32, u32)>>,
    left: usize,
    removed: usize,
    duplicates_removed: usize,
    evaluations: usize,
    scratch: Scratch,
    /// The neighbour rows of a batch of evaluations, k + [`NEIGHBOUR_SPARES`] each.
    batch_rows: Vec<u32>,
}

/// Priority of a shape: its d; 0 for a point with a coincident neighbour; the smallest
/// positive float for a point without a surface neighbourhood (a thread of points, a tight
/// ring that projects to an arc), so it goes right after duplicates but within the rules.
/// Non-negative floats order like their bit patterns.
fn priority(shape: &RingShape) -> f32 {
    if shape.coincident {
        0.0
    } else if shape.degenerate {
        f32::MIN_POSITIVE
    } else {
        shape.diameter
    }
}

impl<'a> State<'a> {
    /// Point `i`'s [`priority`] with `shape`: infinite (never removed) for a locked point
    /// that has no coincident neighbour.
    fn priority_of(&self, i: usize, shape: &RingShape) -> f32 {
        if !shape.coincident && self.locked.get(i).copied().unwrap_or(false) {
            f32::INFINITY
        } else {
            priority(shape)
        }
    }

    pub(super) fn new(
        positions: &'a [Vec3],
        normals: &[Vec3],
        k: usize,
        rounds_above: usize,
        locked: Vec<bool>,
    ) -> Self {
        let rounds = positions.len() > rounds_above;
        let n = positions.len();
        let ids: Vec<u32> = (0..n as u32).collect();
        let (tree, tree_ids) = build_tree(positions, ids);
        Self {
            positions,
            normals: normals.iter().map(|v| v.normalize_or_zero()).collect(),
            k,
            tree,
            tree_ids,
            tree_built_with: n,
            knn: vec![NONE; n * k],
            spares: vec![NONE; n * NEIGHBOUR_SPARES],
            reach: vec![0.0; n],
            use_spares: true,
            queries: 0,
            rev: vec![Vec::new(); n],
            shapes: vec![RingShape::default(); n],
            areas: Vec::new(),
            dirty_mask: vec![0; n],
            alive: vec![true; n],
            dirty: vec![false; n],
            blocked: vec![false; n],
            locked,
            keys: vec![0; n],
            remaining: if rounds {
                (0..n as u32).collect()
            } else {
                Vec::new()
            },
            queued: !rounds,
            rounds_above,
            generation: vec![0; n],
            heap: BinaryHeap::with_capacity(n),
            left: n,
            removed: 0,
            duplicates_removed: 0,
            evaluations: 0,
            scratch: Scratch::default(),
            batch_rows: Vec::new(),
        }
    }

    /// Evaluates every remaining point in parallel (the initial pass).
    pub(super) fn evaluate_all(&mut self) {
        let all: Vec<u32> = (0..self.positions.len() as u32).collect();
        self.areas = self.evaluate_batch(&all, true);
    }

    /// Re-evaluates `points` in parallel against the current tree and requeues them.
    /// Returns each one's share of the area (see [`Simplification::point_areas`]) when
    /// `with_areas` says so (only the first pass needs them), else nothing.
    fn evaluate_batch(&mut self, points: &[u32], with_areas: bool) -> Vec<f32> {
        let row_len = self.k + NEIGHBOUR_SPARES;
        // The rows are written in place into one buffer kept between batches: an allocation
        // per evaluation, made on a worker and freed on this thread, cost more than the
        // copies (glibc's arenas).
        let mut rows = std::mem::take(&mut self.batch_rows);
        rows.clear();
        rows.resize(points.len() * row_len, NONE);
        type Evaluated = (RingShape, u64, f32, Reach, (u64, u64));
        let results: Vec<Evaluated> = {
            let this = &*self;
            points
                .par_iter()
                .zip(rows.par_chunks_mut(row_len))
                .with_min_len(EVAL_CHUNK)
                .map_init(Scratch::default, |scratch, (&i, row)| {
                    let (shape, mask, reach) = this.evaluate(i, scratch, row);
                    let area = if !with_areas
                        || shape.degenerate
                        || twin_before(i as usize, &row[..scratch.points.len()], this.positions)
                    {
                        0.0
                    } else {
                        ring_voronoi_area(
                            this.positions[i as usize],
                            &scratch.points,
                            &scratch.ring,
                        )
                    };
                    let changes = row_changes(this.row(i), &row[..this.k]);
                    (shape, mask, area, reach, changes)
                })
                .collect()
        };
        let mut areas = Vec::with_capacity(if with_areas { points.len() } else { 0 });
        let evaluated = points.iter().zip(results).zip(rows.chunks_exact(row_len));
        for ((&i, (shape, mask, area, reach, changes)), row) in evaluated {
            self.apply(i, shape, mask, reach, row, changes);
            if with_areas {
                areas.push(area);
            }
        }
        self.batch_rows = rows;
        areas
    }

    /// The ring shape of point `i` among the remaining points, which slots of its neighbour
    /// row are ring vertices, and the reach of the query behind the row (and whether that
    /// query ran now). The row (written to `row`, k + [`NEIGHBOUR_SPARES`] long) holds its k
    /// nearest remaining points, then the spares.
    fn evaluate(&self, i: u32, scratch: &mut Scratch, row: &mut [u32]) -> (RingShape, u64, Reach) {
        let p = self.positions[i as usize];
        let reach = self.neighbours(i, &mut scratch.found);
        row.fill(NONE);
        for (slot, &(_, j)) in row.iter_mut().zip(scratch.found.iter()) {
            *slot = j;
        }
        scratch.points.clear();
        scratch.points.extend(
            scratch
                .found
                .iter()
                .take(self.k)
                .map(|&(_, j)| self.positions[j as usize]),
        );
        scratch.ring.clear();
        let shape = scratch.builder.build(
            p,
            self.normals[i as usize],
            &scratch.points,
            (i, &row[..scratch.points.len()]),
            Some(&mut scratch.ring),
        );
        let mask = scratch
            .ring
            .iter()
            .fold(0u64, |m, &(slot, _)| m | (1u64 << slot));
        (shape, mask, reach)
    }

    /// Point `i`'s nearest remaining points into `found` as (squared distance, point), by
    /// distance then index, at most k + [`NEIGHBOUR_SPARES`] of them; returns the reach of the
    /// k-d query they came from, and whether it ran now. From the rows of its last
    /// evaluation when k of them are left and the k-th is surely nearer than anything that
    /// query passed over (no query then); from the k-d tree otherwise.
    fn neighbours(&self, i: u32, found: &mut Vec<(f32, u32)>) -> Reach {
        let iu = i as usize;
        let (k, spare) = (self.k, NEIGHBOUR_SPARES);
        let p = self.positions[iu];
        let by_distance = |a: &(f32, u32), b: &(f32, u32)| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1));
        let reach = self.reach[iu];
        if self.use_spares && reach > 0.0 {
            found.clear();
            found.extend(
                self.knn[iu * k..(iu + 1) * k]
                    .iter()
                    .chain(&self.spares[iu * spare..(iu + 1) * spare])
                    .filter(|&&j| j != NONE && self.alive[j as usize])
                    .map(|&j| (squared_distance(p, self.positions[j as usize]), j)),
            );
            found.sort_unstable_by(by_distance);
            if found.len() >= k && found[k - 1].0 < reach * SPARES_MARGIN {
                return Reach {
                    farthest: reach,
                    queried: false,
                };
            }
        }
        // The tree still holds removed points, at most a fraction REBUILD_DEAD / REBUILD_OF: ask
        // for enough that the point, its k nearest and the spares are likely among the
        // answers.
        let mut want = (k + 1 + spare) * self.tree_ids.len() / self.left.max(1) + 1;
        loop {
            let asked = want.min(self.tree_ids.len());
            found.clear();
            let mut farthest = 0.0_f32;
            for nb in self
                .tree
                .query(&p.to_array())
                .nearest_n::<SquaredEuclidean<f32>>(
                    NonZeroUsize::new(asked).unwrap_or(NonZeroUsize::MIN),
                )
                .execute()
            {
                let j = self.tree_ids[nb.item as usize];
                let d = squared_distance(p, self.positions[j as usize]);
                farthest = farthest.max(d);
                if j != i && self.alive[j as usize] {
                    found.push((d, j));
                }
            }
            if found.len() >= k || asked == self.tree_ids.len() {
                found.sort_unstable_by(by_distance);
                found.truncate(k + spare);
                let farthest = if asked == self.tree_ids.len() {
                    f32::INFINITY
                } else {
                    farthest
                };
                return Reach {
                    farthest,
                    queried: true,
                };
            }
            want *= 2;
        }
    }

    /// Records a fresh evaluation of `i` and queues it. `changes`: its [`row_changes`]
    /// against its current row.
    fn apply(
        &mut self,
        i: u32,
        shape: RingShape,
        mask: u64,
        reach: Reach,
        row: &[u32],
        changes: (u64, u64),
    ) {
        let k = self.k;
        let iu = i as usize;
        self.queries += usize::from(reach.queried);
        let (row, spares) = row.split_at(k);
        self.spares[iu * NEIGHBOUR_SPARES..(iu + 1) * NEIGHBOUR_SPARES].copy_from_slice(spares);
        self.reach[iu] = reach.farthest;
        // Only neighbours that left or entered the row change reverse lists (usually one or
        // two of k).
        let (left, entered) = changes;
        for slot in Bits(left) {
            let old = self.knn[iu * k + slot] as usize;
            if let Some(pos) = self.rev[old].iter().position(|&x| x == i) {
                self.rev[old].swap_remove(pos);
            }
        }
        for slot in Bits(entered) {
            self.rev[row[slot] as usize].push(i);
        }
        self.knn[iu * k..(iu + 1) * k].copy_from_slice(row);
        self.shapes[iu] = shape;
        self.dirty_mask[iu] = if shape.open || shape.degenerate || shape.coincident {
            u64::MAX
        } else {
            mask
        };
        self.dirty[iu] = false;
        self.generation[iu] = self.generation[iu].wrapping_add(1);
        self.evaluations += 1;
        self.keys[iu] = self.priority_of(iu, &shape).to_bits();
        if self.queued {
            self.heap
                .push(Reverse((self.keys[iu], i, self.generation[iu])));
        }
    }

    /// Point `i`'s current neighbour row (k slots).
    fn row(&self, i: u32) -> &[u32] {
        let iu = i as usize;
        &self.knn[iu * self.k..(iu + 1) * self.k]
    }

    /// Re-evaluates one point (sequential path).
    fn reevaluate(&mut self, i: u32) {
        let mut scratch = std::mem::take(&mut self.scratch);
        let mut row = [NONE; MAX_SIMPLIFY_K + NEIGHBOUR_SPARES];
        let len = self.k + NEIGHBOUR_SPARES;
        let (shape, mask, reach) = self.evaluate(i, &mut scratch, &mut row[..len]);
        self.scratch = scratch;
        let changes = row_changes(self.row(i), &row[..self.k]);
        self.apply(i, shape, mask, reach, &row[..len], changes);
    }

    /// Removes point `i`.
    fn remove(&mut self, i: u32) {
        let iu = i as usize;
        self.alive[iu] = false;
        self.left -= 1;
        self.removed += 1;
        let k = self.k;
        for q in std::mem::take(&mut self.rev[iu]) {
            let qu = q as usize;
            if !self.alive[qu] {
                continue;
            }
            // Only a point whose ring holds `i` changes (or one whose ring is open, degenerate
            // or has a coincident neighbour, which is not in its ring: its mask is full):
            // deleting a vertex from a Delaunay triangulation re-triangulates that vertex's
            // star only.
            let row = &self.knn[qu * k..(qu + 1) * k];
            if row
                .iter()
                .position(|&j| j == i)
                .is_some_and(|slot| self.dirty_mask[qu] & (1u64 << slot) != 0)
            {
                self.dirty[qu] = true;
            }
        }
        // `i` stays in its neighbours' reverse lists until the next rebuild sweeps them: a
        // removed point there is skipped, and finding it in each of k lists at once was a
        // tenth of §3's time on one thread.
        self.knn[iu * k..(iu + 1) * k].fill(NONE);
        self.spares[iu * NEIGHBOUR_SPARES..(iu + 1) * NEIGHBOUR_SPARES].fill(NONE);
        self.reach[iu] = 0.0;
        if (self.tree_built_with - self.left) * REBUILD_OF > self.tree_built_with * REBUILD_DEAD {
            let ids: Vec<u32> = (0..self.positions.len() as u32)
                .filter(|&j| self.alive[j as usize])
                .collect();
            let (tree, ids) = build_tree(self.positions, ids);
            self.tree = tree;
            self.tree_ids = ids;
            self.tree_built_with = self.left;
            let alive = &self.alive;
            self.rev
                .par_iter_mut()
                .with_min_len(SWEEP_CHUNK)
                .for_each(|list| list.retain(|&q| alive[q as usize]));
        }
    }

    /// Removes points until a stopping rule holds.
    pub(super) fn run(
        &mut self,
        floor: usize,
        config: &SimplifyConfig,
        progress: &mut dyn FnMut(SimplifyProgress) -> ControlFlow<()>,
    ) -> StopReason {
        let total = self.left.saturating_sub(floor).max(1);
        let step = (total / PROGRESS_STEPS).max(1);
        loop {
            let stop = self.remove_until_stop(floor, config, progress, step);
            if stop != StopReason::ThresholdReached {
                return stop;
            }
            // Make the threshold rule exact: refresh every stale key, then go on if one of
            // them fell below the threshold.
            let stale: Vec<u32> = (0..self.positions.len() as u32)
                .filter(|&i| self.alive[i as usize] && self.dirty[i as usize])
                .collect();
            if stale.is_empty() {
                return stop;
            }
            self.evaluate_batch(&stale, false);
            let threshold = config.max_diameter.unwrap_or(f32::INFINITY);
            let below = stale
                .iter()
                .any(|&i| self.priority_of(i as usize, &self.shapes[i as usize]) < threshold);
            if !below {
                return stop;
            }
        }
    }

    fn remove_until_stop(
        &mut self,
        floor: usize,
        config: &SimplifyConfig,
        progress: &mut dyn FnMut(SimplifyProgress) -> ControlFlow<()>,
        step: usize,
    ) -> StopReason {
        let threshold = config.max_diameter.unwrap_or(f32::INFINITY);
        let mut round = Round::default();
        loop {
            if !self.queued {
                let before = self.removed;
                if self.left > self.rounds_above && self.round(floor, threshold, &mut round) {
                    let report = SimplifyProgress {
                        points: self.left,
                        removed: self.removed,
                        target: config.target,
                        last_diameter: round.last,
                    };
                    if before / step != self.removed / step && progress(report).is_break() {
                        return StopReason::Cancelled;
                    }
                    continue;
                }
                self.queue_all();
            }
            let Some(Reverse((bits, i, generation))) = self.heap.pop() else {
                break;
            };
            let iu = i as usize;
            if !self.alive[iu] || generation != self.generation[iu] {
                continue;
            }
            if self.dirty[iu] {
                self.reevaluate(i);
                continue;
            }
            let d = f32::from_bits(bits);
            let duplicate = d == 0.0 && self.left > MIN_SIMULATION_POINTS;
            if !duplicate {
                let stop = if self.left <= floor {
                    Some(StopReason::TargetReached)
                } else if d >= threshold {
                    Some(StopReason::ThresholdReached)
                } else if d.is_infinite() {
                    Some(StopReason::NothingRemovable)
                } else {
                    None
                };
                if let Some(stop) = stop {
                    self.heap.push(Reverse((bits, i, generation)));
                    return stop;
                }
            } else {
                self.duplicates_removed += 1;
            }
            self.remove(i);
            if self.removed.is_multiple_of(step)
                && progress(SimplifyProgress {
                    points: self.left,
                    removed: self.removed,
                    target: config.target,
                    last_diameter: d,
                })
                .is_break()
            {
                return StopReason::Cancelled;
            }
        }
        StopReason::NothingRemovable
    }

    /// One round of removals on a large cloud: the smallest keys, none a neighbour of
    /// another, removed together, and the rings they change judged on every thread. Returns
    /// whether it removed anything; when it did not (the front is past a stopping rule, or
    /// the budget is under two), the one-at-a-time path goes on.
    fn round(&mut self, floor: usize, threshold: f32, r: &mut Round) -> bool {
        let budget = (self.left / ROUND_SHARE).min(self.left.saturating_sub(floor));
        if budget < 2 {
            return false;
        }
        let look = ROUND_LOOKAHEAD * budget;
        self.exact_window(look, &mut r.window);
        let k = self.k;
        r.picked.clear();
        let mut taken = 0;
        for &(bits, i, _) in &r.window {
            let d = f32::from_bits(bits);
            // A duplicate goes whatever the rules (one of a coincident pair is the other's
            // neighbour, so a round never takes both); the rounds run far above the floor.
            let duplicate = d == 0.0;
            let stops = d >= threshold || d.is_infinite();
            if !duplicate && (stops || taken >= budget) {
                break;
            }
            let iu = i as usize;
            if self.blocked[iu] {
                continue;
            }
            for &j in self.knn[iu * k..(iu + 1) * k].iter().chain(&self.rev[iu]) {
                if j != NONE {
                    self.blocked[j as usize] = true;
                    r.touched.push(j);
                }
            }
            self.blocked[iu] = true;
            r.touched.push(i);
            r.picked.push(i);
            r.last = d;
            if duplicate {
                self.duplicates_removed += 1;
            } else {
                taken += 1;
            }
        }
        for &j in &r.touched {
            self.blocked[j as usize] = false;
        }
        r.touched.clear();
        for &i in &r.picked {
            self.remove(i);
        }
        !r.picked.is_empty()
    }

    /// Puts the `look` smallest keys of the remaining points into `window`, ascending, each
    /// exact: the stale keys among twice as many are judged again together (on every
    /// thread), until the front `look` are all clean. Stale keys are lower bounds, so no
    /// point outside the window has a smaller key.
    ///
    /// The wide window is chosen from every remaining point once; after a judgement its keys
    /// are refreshed and the front chosen again within it, as long as `look` of them are
    /// still below the largest key it was chosen with (everything outside is above that).
    /// Only when too few are does it go back to every point.
    fn exact_window(&mut self, look: usize, window: &mut Vec<(u32, u32, u32)>) {
        self.remaining.retain(|&i| self.alive[i as usize]);
        let mut bound = None;
        loop {
            match bound {
                None => {
                    window.clear();
                    window.extend(
                        self.remaining
                            .iter()
                            .map(|&i| (self.keys[i as usize], i, self.generation[i as usize])),
                    );
                    let wide = (STALE_WINDOW * look).min(window.len());
                    bound = Some(if wide < window.len() {
                        window.select_nth_unstable(wide.max(1) - 1);
                        window.truncate(wide);
                        window[wide.max(1) - 1]
                    } else {
                        (u32::MAX, u32::MAX, u32::MAX)
                    });
                }
                Some(limit) => {
                    for e in window.iter_mut() {
                        *e = (self.keys[e.1 as usize], e.1, self.generation[e.1 as usize]);
                    }
                    if window.iter().filter(|&&e| e <= limit).count() < look.min(window.len()) {
                        bound = None;
                        continue;
                    }
                }
            }
            let front = look.min(window.len());
            if front > 0 && front < window.len() {
                window.select_nth_unstable(front - 1);
            }
            if window[..front].iter().all(|e| !self.dirty[e.1 as usize]) {
                window.truncate(front);
                window.sort_unstable();
                return;
            }
            let mut stale: Vec<u32> = window
                .iter()
                .map(|e| e.1)
                .filter(|&i| self.dirty[i as usize])
                .collect();
            // In index order, so the rings are judged alike whatever the thread count.
            stale.sort_unstable();
            self.evaluate_batch(&stale, false);
        }
    }

    /// Ends the rounds: from here on the heap orders the removals, one at a time.
    fn queue_all(&mut self) {
        self.queued = true;
        self.heap.clear();
        for i in std::mem::take(&mut self.remaining) {
            let iu = i as usize;
            if self.alive[iu] {
                self.heap
                    .push(Reverse((self.keys[iu], i, self.generation[iu])));
            }
        }
    }

    /// Refreshes stale points and collects the result.
    pub(super) fn finish(mut self, stop: StopReason) -> Simplification {
        let stale: Vec<u32> = (0..self.positions.len() as u32)
            .filter(|&i| self.alive[i as usize] && self.dirty[i as usize])
            .collect();
        self.evaluate_batch(&stale, false);
        let kept: Vec<u32> = (0..self.positions.len() as u32)
            .filter(|&i| self.alive[i as usize])
            .collect();
        let diameters = kept
            .iter()
            .map(|&i| self.shapes[i as usize].diameter)
            .collect();
        let boundary = kept.iter().map(|&i| self.shapes[i as usize].open).collect();
        Simplification {
            kept,
            diameters,
            boundary,
            removed: self.removed,
            duplicates_removed: self.duplicates_removed,
            evaluations: self.evaluations,
            stop,
            noise_level: 0.0,
            projected: None,
            point_areas: std::mem::take(&mut self.areas),
        }
    }
}

/// Which slots of a neighbour row `old` hold a point that `new` does not (bit s = slot s),
/// and which slots of `new` hold one that `old` does not: the reverse lists to update.
fn row_changes(old: &[u32], new: &[u32]) -> (u64, u64) {
    let changed = |from: &[u32], to: &[u32]| {
        from.iter()
            .enumerate()
            .filter(|&(_, &j)| j != NONE && !to.contains(&j))
            .fold(0u64, |m, (slot, _)| m | (1u64 << slot))
    };
    (changed(old, new), changed(new, old))
}

/// The set bits of a mask, lowest first.
struct Bits(u64);

impl Iterator for Bits {
    type Item = usize;

    fn next(&mut self) -> Option<usize> {
        if self.0 == 0 {
            return None;
        }
        let bit = self.0.trailing_zeros() as usize;
        self.0 &= self.0 - 1;
        Some(bit)
    }
}

/// Where a point's neighbour rows came from.
#[derive(Debug, Clone, Copy)]
struct Reach {
    /// The farthest squared distance the k-d query behind them returned (see
    /// `State::reach`).
    farthest: f32,
    /// Whether that query ran in this evaluation (not answered from the rows).
    queried: bool,
}

/// Buffers a round of removals keeps between rounds.
#[derive(Default)]
struct Round {
    /// The round's window: (key, point, generation), ascending.
    window: Vec<(u32, u32, u32)>,
    /// The points it removes.
    picked: Vec<u32>,
    /// The points it marked blocked.
    touched: Vec<u32>,
    /// The key of the last point it removed.
    last: f32,
}

/// The squared distance the neighbour searches order by (the same arithmetic whether the
/// neighbours come from the tree or from a point's rows).
fn squared_distance(a: Vec3, b: Vec3) -> f32 {
    (a - b).length_squared()
}

/// A k-d tree over the points `ids` of `positions`; items index the returned id list.
fn build_tree(positions: &[Vec3], ids: Vec<u32>) -> (ImmutableKdTree<f32, 3>, Vec<u32>) {
    let coords: Vec<[f32; 3]> = ids
        .iter()
        .map(|&i| positions[i as usize].to_array())
        .collect();
    // Construction fails only beyond u32::MAX points, which `validate` rules out.
    let tree = ImmutableKdTree::new_from_slice(&coords).unwrap_or_default();
    (tree, ids)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::cloud::shapes;

    /// §3 on `cloud` down to `target` points (rounds below `rounds_above`), answering
    /// re-evaluations from the spare rows or always from the tree.
    fn run(
        cloud: &PointCloud,
        target: usize,
        rounds_above: usize,
        spares: bool,
    ) -> (Simplification, usize) {
        let config = SimplifyConfig::target(target);
        let normals = cloud.normals().unwrap();
        let mut state = State::new(
            cloud.positions(),
            normals,
            config.k,
            rounds_above,
            Vec::new(),
        );
        state.use_spares = spares;
        state.evaluate_all();
        let stop = state.run(target, &config, &mut |_| ControlFlow::Continue(()));
        let queries = state.queries;
        (state.finish(stop), queries)
    }

    #[test]
    fn the_spare_neighbours_change_no_network_and_save_a_third_of_the_queries() {
        let clouds = [
            shapes::with_noise(&shapes::uneven_sphere(6000, 1.0, 4.0, 7), 0.002, 3),
            shapes::with_noise(&shapes::hat(5000, 1.0, -0.2), 0.001, 5),
        ];
        for (c, cloud) in clouds.iter().enumerate() {
            // One at a time, and in rounds from the first point.
            for rounds_above in [usize::MAX, MIN_ROUND_POINTS] {
                let (with, queries) = run(cloud, 300, rounds_above, true);
                let (without, all) = run(cloud, 300, rounds_above, false);
                assert_eq!(
                    with.kept, without.kept,
                    "cloud {c}, rounds above {rounds_above}"
                );
                assert_eq!(with.diameters, without.diameters);
                assert_eq!(with.boundary, without.boundary);
                assert_eq!(with.point_areas, without.point_areas);
                assert_eq!(with.evaluations, without.evaluations);
                // Without the spares every evaluation queries (counted before the last pass).
                assert!(all > 0 && all <= with.evaluations);
                // The first pass queries for every point; over a third of the later ones
                // need no query (about half, measured).
                let n = cloud.len();
                assert!(
                    (queries - n) * 3 < (all - n) * 2,
                    "cloud {c}: {queries} queries of {all} evaluations"
                );
                println!(
                    "cloud {c}, rounds above {rounds_above}: {queries} of {all} evaluations queried"
                );
            }
        }
    }
}
