//! The precomputation: every dense point's weighted least-squares fit to its nearest
//! simulation points, stored as coefficients (eq 7–12 with the normal coordinate).

use glam::{DVec3, Vec3, Vec3A};
use rayon::prelude::*;

use super::pins::{PIN_BLEND, PIN_HOLD};
use super::*;

/// Kinds of fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub(crate) enum Fit {
    Full,
    Plane,
    Regularised,
}

/// What a row's fit came out as.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub(crate) struct RowKind {
    pub(crate) fit: Fit,
    /// The fit does not give back the rest surface (see [`reproduces_rest`]).
    pub(crate) residual: bool,
    /// The row follows pinned simulation points only (see [`Transfer::hold`]).
    pub(crate) held: bool,
}

impl Transfer {
    /// Precomputes the transfer from simulation points at `sim_rest` to dense points at
    /// `rest` with unit `normals` (all in the rest state).
    pub fn new(
        rest: &[Vec3],
        normals: &[Vec3],
        sim_rest: &[Vec3],
        config: TransferConfig,
    ) -> Result<Self, TransferError> {
        Self::build(rest, normals, sim_rest, config, true)
    }

    /// [`Self::new`] with `normals` taken as they are, where they are the unit normals of
    /// another transfer ([`Self::rest_normals`]): normalising a unit vector again may move
    /// its last bit, and a transfer rebuilt from a saved rest shape must be the same, bit for
    /// bit. Normals further than 10⁻⁴ from unit length are refused.
    pub(crate) fn with_unit_normals(
        rest: &[Vec3],
        normals: &[Vec3],
        sim_rest: &[Vec3],
        config: TransferConfig,
    ) -> Result<Self, TransferError> {
        if let Some(index) = normals.iter().position(|n| (n.length() - 1.0).abs() > 1e-4) {
            return Err(TransferError::InvalidPoint {
                which: "dense",
                index,
            });
        }
        Self::build(rest, normals, sim_rest, config, false)
    }

    fn build(
        rest: &[Vec3],
        normals: &[Vec3],
        sim_rest: &[Vec3],
        config: TransferConfig,
        normalise: bool,
    ) -> Result<Self, TransferError> {
        if !(1..=MAX_TRANSFER_K).contains(&config.k) {
            return Err(TransferError::KOutOfRange(config.k));
        }
        if !(config.bandwidth > 0.0 && config.bandwidth.is_finite()) {
            return Err(TransferError::InvalidBandwidth(config.bandwidth));
        }
        if sim_rest.is_empty() {
            return Err(TransferError::NoSimulationPoints);
        }
        if sim_rest.len() > MAX_SIMULATION_POINTS {
            return Err(TransferError::TooManySimulationPoints(sim_rest.len()));
        }
        if rest.len() != normals.len() {
            return Err(TransferError::LengthMismatch {
                positions: rest.len(),
                normals: normals.len(),
            });
        }
        if let Some(index) = sim_rest.iter().position(|p| !p.is_finite()) {
            return Err(TransferError::InvalidPoint {
                which: "simulation",
                index,
            });
        }
        if let Some(index) = first_invalid_point(rest, normals) {
            return Err(TransferError::InvalidPoint {
                which: "dense",
                index,
            });
        }
        let mut transfer = Self {
            config,
            k: config.k.min(sim_rest.len()),
            rest: Vec::new(),
            normals: Vec::new(),
            sim_rest: sim_rest.to_vec(),
            neighbours: if sim_rest.len() <= NARROW_INDEX_LIMIT {
                Neighbours::Narrow(Vec::new())
            } else {
                Neighbours::Wide(Vec::new())
            },
            coefficients: Vec::new(),
            residual_rows: Vec::new(),
            kinds: Vec::new(),
            pins: Pins::default(),
        };
        let normals: Vec<Vec3> = if normalise {
            normals.iter().map(|n| n.normalize()).collect()
        } else {
            normals.to_vec()
        };
        transfer.extend(rest, &normals, &KnnIndex::build(sim_rest));
        Ok(transfer)
    }

    /// Adds dense points (validated, unit normals) with their own coefficients.
    pub(crate) fn extend(&mut self, rest: &[Vec3], normals: &[Vec3], index: &KnnIndex) {
        let (k, start) = (self.k, self.rest.len());
        self.rest.extend_from_slice(rest);
        self.normals.extend_from_slice(normals);
        let stride = row_stride(k);
        self.coefficients.resize((start + rest.len()) * stride, 0.0);
        let coefficients = &mut self.coefficients[start * stride..];
        let job = RowFit {
            rest,
            normals,
            sim: &self.sim_rest,
            pins: &self.pins,
            first: start,
            k,
            bandwidth: self.config.bandwidth,
        };
        let nearest = |p: Vec3, _: &[u32], nbr: &mut Vec<u32>| {
            nbr.extend(index.nearest(p, k).iter().map(|nb| nb.index));
        };
        let kinds = match &mut self.neighbours {
            Neighbours::Narrow(n) => {
                n.resize((start + rest.len()) * k, 0);
                job.fill(&mut n[start * k..], coefficients, |_, _| true, nearest)
            }
            Neighbours::Wide(n) => {
                n.resize((start + rest.len()) * k, 0);
                job.fill(&mut n[start * k..], coefficients, |_, _| true, nearest)
            }
        };
        self.kinds.extend(kinds.into_iter().map(Option::unwrap));
        self.residual_rows
            .extend((start..self.kinds.len()).filter(|&i| self.kinds[i].residual));
    }

    /// Which fit the dense points got.
    pub fn report(&self) -> FitReport {
        let mut report = FitReport::default();
        for kind in &self.kinds {
            match kind.fit {
                Fit::Full => report.full += 1,
                Fit::Plane => report.plane += 1,
                Fit::Regularised => report.regularised += 1,
            }
            report.residual += usize::from(kind.residual);
            report.held += usize::from(kind.held);
        }
        report
    }
}

/// The fits of dense points (validated, unit normals) to the simulation points.
pub(super) struct RowFit<'a> {
    pub(super) rest: &'a [Vec3],
    pub(super) normals: &'a [Vec3],
    pub(super) sim: &'a [Vec3],
    pub(super) pins: &'a Pins,
    /// The row of `rest`'s first point.
    pub(super) first: usize,
    pub(super) k: usize,
    pub(super) bandwidth: f32,
}

impl RowFit<'_> {
    /// Fits the rows `wanted` picks (in parallel; all of them `rest`'s, k neighbours a row
    /// in `neighbours`, [`row_stride`] coefficients in `coefficients`): `candidates` gives a
    /// row's neighbours (from its rest position and what the row stores). Per row: its kind,
    /// or `None` where it was left as it was.
    fn fill<I: NeighbourIndex>(
        &self,
        neighbours: &mut [I],
        coefficients: &mut [f32],
        wanted: impl Fn(usize, &[u32]) -> bool + Sync,
        candidates: impl Fn(Vec3, &[u32], &mut Vec<u32>) + Sync,
    ) -> Vec<Option<RowKind>> {
        let (k, stride) = (self.k, row_stride(self.k));
        neighbours
            .par_chunks_mut(CHUNK * k)
            .zip(coefficients.par_chunks_mut(CHUNK * stride))
            .enumerate()
            .flat_map_iter(|(chunk, (nbrs, coefs))| {
                let mut kinds = Vec::with_capacity(nbrs.len() / k);
                let (mut stored, mut nbr) = (Vec::with_capacity(k), Vec::with_capacity(k));
                let mut coef = vec![Vec3A::ZERO; k];
                for (row, (nbrs, coefs)) in nbrs
                    .chunks_exact_mut(k)
                    .zip(coefs.chunks_exact_mut(stride))
                    .enumerate()
                {
                    let i = chunk * CHUNK + row;
                    stored.clear();
                    stored.extend(nbrs.iter().map(|j| j.get() as u32));
                    if !wanted(self.first + i, &stored) {
                        kinds.push(None);
                        continue;
                    }
                    let (p, n) = (self.rest[i], self.normals[i]);
                    nbr.clear();
                    candidates(p, &stored, &mut nbr);
                    let kind = self.fit_row(self.first + i, p, n, &mut nbr, &mut coef);
                    let m = k - 1;
                    let (c0, rest) = coefs.split_at_mut(m);
                    let (c1, c2) = rest.split_at_mut(m);
                    for (stored, &j) in nbrs.iter_mut().zip(&nbr) {
                        *stored = I::new(j);
                    }
                    for (t, c) in coef[1..].iter().enumerate() {
                        (c0[t], c1[t], c2[t]) = (c.x, c.y, c.z);
                    }
                    kinds.push(Some(kind));
                }
                kinds
            })
            .collect()
    }

    /// Fits again, from their stored neighbours, the rows `wanted` picks.
    pub(super) fn refit<I: NeighbourIndex>(
        &self,
        neighbours: &mut [I],
        coefficients: &mut [f32],
        wanted: impl Fn(usize, &[u32]) -> bool + Sync,
    ) -> Vec<Option<RowKind>> {
        self.fill(neighbours, coefficients, wanted, |_, stored, nbr| {
            nbr.extend_from_slice(stored);
        })
    }

    /// Fits dense point `p` (row `row`, unit normal `n`) to the simulation points `nbr`,
    /// which it puts in their stored order: by distance from `p` at rest (then by index),
    /// and, where the row is held (see [`Transfer::hold`]), the pinned ones first, fitted
    /// alone (the free ones get zero coefficients). Writes a coefficient triple per
    /// neighbour into `coef`.
    fn fit_row(
        &self,
        row: usize,
        p: Vec3,
        n: Vec3,
        nbr: &mut [u32],
        coef: &mut [Vec3A],
    ) -> RowKind {
        let distance = |j: u32| self.sim[j as usize].distance_squared(p);
        nbr.sort_by(|&a, &b| distance(a).total_cmp(&distance(b)).then(a.cmp(&b)));
        let pinned = |j: u32| self.pins.simulation(j as usize);
        // The nearest pinned and the nearest free neighbour, as a ratio of distances.
        let first = |pin: bool| nbr.iter().find(|&&j| pinned(j) == pin).copied();
        let ratio = match (first(true), first(false)) {
            (None, _) => f64::INFINITY,
            (Some(_), None) => 0.0,
            // (A pinned neighbour at the point itself holds it, whatever lies there too.)
            (Some(a), _) if distance(a) == 0.0 => 0.0,
            (Some(a), Some(b)) => f64::from(distance(a).sqrt()) / f64::from(distance(b).sqrt()),
        };
        let held = ratio.is_finite() && (ratio <= PIN_HOLD || self.pins.dense(row));
        coef.fill(Vec3A::ZERO);
        let fit = if held {
            nbr.sort_by_key(|&j| !pinned(j));
            let used = nbr.iter().filter(|&&j| pinned(j)).count();
            let (nbr, coef) = (&nbr[..used], &mut coef[..used]);
            fit_point(p, n, self.sim, nbr, self.bandwidth, |_| 1.0, coef)
        } else {
            // By the pins' edge the free neighbours weigh less, down to nothing where the
            // held rows begin: the drawn surface stays whole across the edge.
            let t = ((ratio - PIN_HOLD) / (PIN_BLEND - PIN_HOLD)).clamp(0.0, 1.0);
            let free = t * t * (3.0 - 2.0 * t);
            let scale = |j: u32| if pinned(j) { 1.0 } else { free };
            fit_point(p, n, self.sim, nbr, self.bandwidth, scale, coef)
        };
        RowKind {
            fit,
            residual: !reproduces_rest(p, n, self.sim, nbr, coef),
            held,
        }
    }
}

/// Whether the stored fit of dense point `p` (unit normal `n`) to its neighbours `nbr`
/// (coefficients `coef`, the anchor's unused) gives back, from the neighbours' rest
/// positions, `p` itself to within [`REST_TOLERANCE`] times the neighbourhood's reach and
/// the tangents t₁, t₂ to within [`REST_TOLERANCE`]. The full fit does, by construction
/// (it reproduces every affine function of position, and the position is one), up to the
/// rounding of its coefficients; so does a plane fit on flat ground.
fn reproduces_rest(p: Vec3, n: Vec3, sim: &[Vec3], nbr: &[u32], coef: &[Vec3A]) -> bool {
    let (t1, t2) = tangent_frame(n);
    let p = p.as_dvec3();
    let anchor = sim[nbr[0] as usize].as_dvec3();
    let (mut value, mut s1, mut s2) = (anchor, DVec3::ZERO, DVec3::ZERO);
    let mut reach = anchor.distance(p);
    for (&j, c) in nbr.iter().zip(coef).skip(1) {
        let x = sim[j as usize].as_dvec3();
        let e = x - anchor;
        value += f64::from(c.x) * e;
        s1 += f64::from(c.y) * e;
        s2 += f64::from(c.z) * e;
        reach = reach.max(x.distance(p));
    }
    value.distance(p) <= REST_TOLERANCE * reach
        && s1.distance(t1.as_dvec3()) <= REST_TOLERANCE
        && s2.distance(t2.as_dvec3()) <= REST_TOLERANCE
}

/// A symmetric positive semi-definite matrix of at most 4 × 4, and its Cholesky factor.
struct Normal4 {
    m: [[f64; 4]; 4],
    size: usize,
}

impl Normal4 {
    /// Cholesky factor L (lower) of the leading `size` block; `None` when a pivot falls below
    /// `rel` times the largest diagonal entry.
    fn cholesky(&self, rel: f64) -> Option<[[f64; 4]; 4]> {
        let n = self.size;
        let scale = (0..n).map(|i| self.m[i][i]).fold(0.0, f64::max);
        if scale <= 0.0 || !scale.is_finite() {
            return None;
        }
        let mut l = [[0.0; 4]; 4];
        for i in 0..n {
            for j in 0..=i {
                let mut s = self.m[i][j];
                for (a, b) in l[i][..j].iter().zip(&l[j][..j]) {
                    s -= a * b;
                }
                if i == j {
                    if s <= rel * scale {
                        return None;
                    }
                    l[i][i] = s.sqrt();
                } else {
                    l[i][j] = s / l[j][j];
                }
            }
        }
        Some(l)
    }
}

/// Solves L Lᵀ x = e_r for the leading `n` block.
fn solve_unit(l: &[[f64; 4]; 4], n: usize, r: usize) -> [f64; 4] {
    let mut y = [0.0; 4];
    for i in 0..n {
        let mut s = if i == r { 1.0 } else { 0.0 };
        for j in 0..i {
            s -= l[i][j] * y[j];
        }
        y[i] = s / l[i][i];
    }
    let mut x = [0.0; 4];
    for i in (0..n).rev() {
        let mut s = y[i];
        for j in i + 1..n {
            s -= l[j][i] * x[j];
        }
        x[i] = s / l[i][i];
    }
    x
}

/// Fits dense point `p` (unit normal `n`) to its neighbours `nbr` among `sim`: writes, per
/// neighbour, the coefficients of the value and the two tangent derivatives.
///
/// `scale` multiplies neighbours' weights (1 but for rows by the pins' edge, see
/// [`PIN_BLEND`]).
fn fit_point(
    p: Vec3,
    n: Vec3,
    sim: &[Vec3],
    nbr: &[u32],
    bandwidth: f32,
    scale: impl Fn(u32) -> f64,
    coef: &mut [Vec3A],
) -> Fit {
    let (t1, t2) = tangent_frame(n);
    let (t1, t2, n) = (t1.as_dvec3(), t2.as_dvec3(), n.as_dvec3());
    let local: Vec<DVec3> = nbr
        .iter()
        .map(|&j| {
            let d = (sim[j as usize] - p).as_dvec3();
            DVec3::new(d.dot(t1), d.dot(t2), d.dot(n))
        })
        .collect();
    // h: the bandwidth times the farthest neighbour's distance (1 when all coincide with p).
    // The distance in space, not in the plane: neighbours that all project close to p (far
    // along the normal) must not make h, and with it the slopes' scale, tiny.
    let reach = local.iter().map(|q| q.length()).fold(0.0, f64::max);
    let h = if reach > 0.0 {
        f64::from(bandwidth) * reach
    } else {
        1.0
    };
    let basis = |q: &DVec3| [1.0, q.x / h, q.y / h, q.z / h];
    let weights: Vec<f64> = local
        .iter()
        .zip(nbr)
        .map(|(q, &j)| (-(q.x * q.x + q.y * q.y) / (h * h)).exp() * scale(j))
        .collect();
    let mut normal = Normal4 {
        m: [[0.0; 4]; 4],
        size: 4,
    };
    for (q, &w) in local.iter().zip(&weights) {
        let phi = basis(q);
        for r in 0..4 {
            for s in 0..4 {
                normal.m[r][s] += w * phi[r] * phi[s];
            }
        }
    }
    // Coefficients of the value and the two slopes (unscaled by h) for a factored fit:
    // rows 0..3 of A⁻¹ (A symmetric), then c_r[j] = w_j φ(j)·row_r.
    let coefficients = |l: &[[f64; 4]; 4], size: usize, coef: &mut [Vec3A]| {
        let rows = [
            solve_unit(l, size, 0),
            solve_unit(l, size, 1),
            solve_unit(l, size, 2),
        ];
        let mut amplification = 0.0f64;
        for ((c, q), &w) in coef.iter_mut().zip(&local).zip(&weights) {
            let phi = basis(q);
            let dot = |row: &[f64; 4]| (0..size).map(|s| row[s] * phi[s]).sum::<f64>() * w;
            let value = dot(&rows[0]);
            amplification += value.abs();
            *c = Vec3A::new(
                value as f32,
                (dot(&rows[1]) / h) as f32,
                (dot(&rows[2]) / h) as f32,
            );
        }
        amplification
    };
    if let Some(l) = normal.cholesky(FULL_FIT_PIVOT)
        && coefficients(&l, 4, coef) <= MAX_AMPLIFICATION
    {
        return Fit::Full;
    }
    normal.size = 3;
    if let Some(l) = normal.cholesky(PLANE_FIT_PIVOT) {
        coefficients(&l, 3, coef);
        return Fit::Plane;
    }
    let ridge = RIDGE * weights.iter().sum::<f64>();
    normal.m[1][1] += ridge;
    normal.m[2][2] += ridge;
    match normal.cholesky(0.0) {
        Some(l) => {
            coefficients(&l, 3, coef);
        }
        None => {
            // No weight at all (cannot happen with finite input): follow the nearest.
            coef.iter_mut().for_each(|c| *c = Vec3A::ZERO);
            coef[0] = Vec3A::X;
        }
    }
    Fit::Regularised
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cholesky_solves_a_small_system() {
        let m = Normal4 {
            m: [
                [4.0, 1.0, 0.5, 0.0],
                [1.0, 3.0, 0.2, 0.1],
                [0.5, 0.2, 2.0, 0.3],
                [0.0, 0.1, 0.3, 1.0],
            ],
            size: 4,
        };
        let l = m.cholesky(1e-12).unwrap();
        for r in 0..4 {
            let x = solve_unit(&l, 4, r);
            for i in 0..4 {
                let row: f64 = (0..4).map(|j| m.m[i][j] * x[j]).sum();
                assert!((row - f64::from(u8::from(i == r))).abs() < 1e-12);
            }
        }
        let singular = Normal4 {
            m: [[1.0; 4]; 4],
            size: 2,
        };
        assert!(singular.cholesky(1e-8).is_none());
    }
}
