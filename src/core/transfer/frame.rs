//! Each frame of the transfer: the precomputed rows applied to the simulation points'
//! current positions (or displacements), in chunks, SIMD-compiled, in parallel where that pays.

use glam::{Vec3, Vec3A};
use rayon::prelude::*;

use super::*;

/// Per-frame work is split in at least this many pieces (so small clouds still keep every
/// thread busy), of at least [`MIN_FRAME_CHUNK`] points.
const FRAME_PIECES: usize = 16;
const MIN_FRAME_CHUNK: usize = 128;

/// Dense points per parallel task of a per-frame product.
fn frame_chunk(n: usize) -> usize {
    (n / FRAME_PIECES).clamp(MIN_FRAME_CHUNK, CHUNK)
}

/// Called from outside a rayon thread pool, a frame of up to this many dense points runs on
/// the calling thread: handing the work to the pool and sleeping until it is done costs more
/// than the product itself (on the 3203-point sphere, 40 % of the time went to the wake-ups).
const SEQUENTIAL_POINTS: usize = 16_384;

/// Called from a thread of a rayon pool, where splitting costs little, a frame runs in
/// parallel from this many dense points (on the 3203-point sphere: 45 µs on two threads
/// against 66 µs on one).
const SEQUENTIAL_POINTS_IN_POOL: usize = 1024;

/// Whether a frame over `n` dense points should run in parallel.
fn parallel_frame(n: usize) -> bool {
    let limit = if rayon::current_thread_index().is_some() {
        SEQUENTIAL_POINTS_IN_POOL
    } else {
        SEQUENTIAL_POINTS
    };
    n > limit
}

/// Runs `work(chunk index, positions chunk, normals chunk)` over chunks of `size` points
/// (the normals chunk is empty when there are no normals), in parallel where
/// [`parallel_frame`] says so.
fn for_each_chunk(
    size: usize,
    positions: &mut [Vec3],
    normals: Option<&mut [Vec3]>,
    work: impl Fn(usize, &mut [Vec3], &mut [Vec3]) + Sync + Send,
) {
    let sequential = !parallel_frame(positions.len());
    match (normals, sequential) {
        (Some(normals), true) => positions
            .chunks_mut(size)
            .zip(normals.chunks_mut(size))
            .enumerate()
            .for_each(|(c, (p, n))| work(c, p, n)),
        (Some(normals), false) => positions
            .par_chunks_mut(size)
            .zip(normals.par_chunks_mut(size))
            .enumerate()
            .for_each(|(c, (p, n))| work(c, p, n)),
        (None, true) => positions
            .chunks_mut(size)
            .enumerate()
            .for_each(|(c, p)| work(c, p, &mut [])),
        (None, false) => positions
            .par_chunks_mut(size)
            .enumerate()
            .for_each(|(c, p)| work(c, p, &mut [])),
    }
}

impl Transfer {
    /// Checks the displacement count and the output lengths.
    pub(crate) fn check(
        &self,
        displacements: &[Vec3],
        outputs: &[usize],
    ) -> Result<(), TransferError> {
        if displacements.len() != self.sim_rest.len() {
            return Err(TransferError::DisplacementCount {
                expected: self.sim_rest.len(),
                found: displacements.len(),
            });
        }
        if let Some(&found) = outputs.iter().find(|&&l| l != self.len()) {
            return Err(TransferError::OutputLength {
                expected: self.len(),
                found,
            });
        }
        Ok(())
    }

    /// Deformed dense positions and normals for the simulation points' `displacements`
    /// (current minus rest position), written into `positions` and `normals`.
    pub fn apply(
        &self,
        displacements: &[Vec3],
        positions: &mut [Vec3],
        normals: &mut [Vec3],
    ) -> Result<(), TransferError> {
        self.check(displacements, &[positions.len(), normals.len()])?;
        self.frame(displacements, positions, Some(normals));
        Ok(())
    }

    /// Deformed dense positions only (no normals: cheaper when a scene does not need them).
    pub fn apply_positions(
        &self,
        displacements: &[Vec3],
        positions: &mut [Vec3],
    ) -> Result<(), TransferError> {
        self.check(displacements, &[positions.len()])?;
        self.frame(displacements, positions, None);
        Ok(())
    }

    /// A frame (lengths checked) from displacements, split in chunks that run in parallel
    /// where [`parallel_frame`] says so.
    fn frame(&self, displacements: &[Vec3], positions: &mut [Vec3], normals: Option<&mut [Vec3]>) {
        let input = FrameInput::from_displacements(self, displacements);
        let size = frame_chunk(self.len());
        for_each_chunk(size, positions, normals, |chunk, pos, nrm| {
            self.rows(&input, chunk * size, pos, nrm);
        });
    }

    /// The whole frame `input` describes: deformed positions, and unit normals unless
    /// `normals` is empty. Large frames run in parallel on rayon's pool (see
    /// [`Self::frame_rows`] to split the work some other way).
    pub fn apply_frame(
        &self,
        input: &FrameInput,
        positions: &mut [Vec3],
        normals: &mut [Vec3],
    ) -> Result<(), TransferError> {
        if positions.len() != self.len() {
            return Err(TransferError::OutputLength {
                expected: self.len(),
                found: positions.len(),
            });
        }
        if input.current.len() != self.sim_rest.len() {
            return Err(TransferError::DisplacementCount {
                expected: self.sim_rest.len(),
                found: input.current.len(),
            });
        }
        if !(normals.is_empty() || normals.len() == positions.len()) {
            return Err(TransferError::OutputLength {
                expected: self.len(),
                found: normals.len(),
            });
        }
        let size = frame_chunk(self.len());
        let normals = (!normals.is_empty()).then_some(normals);
        for_each_chunk(size, positions, normals, |chunk, pos, nrm| {
            self.rows(input, chunk * size, pos, nrm);
        });
        Ok(())
    }

    /// Rows `first..first + positions.len()` of the frame `input` describes: the deformed
    /// positions, and the unit normals when `normals` is not empty (it must then be as long
    /// as `positions`). Chunks of a frame are independent, so a caller may compute them on
    /// threads of its own (the Bevy layer uses Bevy's task pool); the result does not
    /// depend on how the rows are split.
    pub fn frame_rows(
        &self,
        input: &FrameInput,
        first: usize,
        positions: &mut [Vec3],
        normals: &mut [Vec3],
    ) -> Result<(), TransferError> {
        if input.current.len() != self.sim_rest.len() {
            return Err(TransferError::DisplacementCount {
                expected: self.sim_rest.len(),
                found: input.current.len(),
            });
        }
        let end = first.checked_add(positions.len());
        if end.is_none_or(|end| end > self.len())
            || !(normals.is_empty() || normals.len() == positions.len())
        {
            return Err(TransferError::OutputLength {
                expected: self.len(),
                found: end.unwrap_or(usize::MAX).max(normals.len()),
            });
        }
        self.rows(input, first, positions, normals);
        Ok(())
    }

    /// One chunk of rows (ranges checked): [`Self::chunk_rows`] for the index width,
    /// compiled for the default k (and so fully unrolled) where that is the k.
    fn rows(&self, input: &FrameInput, first: usize, pos: &mut [Vec3], nrm: &mut [Vec3]) {
        const D: usize = DEFAULT_TRANSFER_K;
        match (&self.neighbours, self.k == D) {
            (Neighbours::Narrow(n), true) => self.chunk_rows::<_, D>(n, input, first, pos, nrm),
            (Neighbours::Narrow(n), false) => self.chunk_rows::<_, 0>(n, input, first, pos, nrm),
            (Neighbours::Wide(n), true) => self.chunk_rows::<_, D>(n, input, first, pos, nrm),
            (Neighbours::Wide(n), false) => self.chunk_rows::<_, 0>(n, input, first, pos, nrm),
        }
    }

    /// A chunk of rows over neighbour rows of one index width; `K` is k, or 0 for any.
    fn chunk_rows<I: NeighbourIndex, const K: usize>(
        &self,
        neighbours: &[I],
        input: &FrameInput,
        first: usize,
        pos: &mut [Vec3],
        nrm: &mut [Vec3],
    ) {
        // A constant in the body itself (not captured), so that the loops unroll.
        let k = if K == 0 { self.k } else { K };
        // Where the fit reproduces the rest surface, the fitted position and tangents of the
        // simulation points' current positions are the deformed ones.
        pulp::Arch::new().dispatch(FrameRows::<I, K> {
            transfer: self,
            neighbours,
            current: &input.current,
            first,
            positions: &mut *pos,
            normals: &mut *nrm,
        });
        let residual = self.residual_rows_in(first, pos.len());
        if !residual.is_empty() {
            let disp = &input.displacements;
            for &i in residual {
                let (u, g1, g2) = self.row_sums(neighbours, i, k, disp);
                pos[i - first] = self.rest[i] + Vec3::from(u);
                if let Some(n) = nrm.get_mut(i - first) {
                    let (t1, t2) = tangent_frame(self.normals[i]);
                    let (t1, t2) = (Vec3A::from(t1) + g1, Vec3A::from(t2) + g2);
                    *n = Vec3::from(t1.cross(t2));
                }
            }
        }
        // Normalised in a second, short loop: the square roots and divisions of many points
        // then overlap instead of each waiting for its own.
        for (row, n) in nrm.iter_mut().enumerate() {
            *n = unit_or(*n, || self.normals[first + row]);
        }
    }

    /// Convenience: [`Self::apply`] into new vectors.
    pub fn deform(&self, displacements: &[Vec3]) -> Result<(Vec<Vec3>, Vec<Vec3>), TransferError> {
        let mut positions = vec![Vec3::ZERO; self.len()];
        let mut normals = vec![Vec3::ZERO; self.len()];
        self.apply(displacements, &mut positions, &mut normals)?;
        Ok((positions, normals))
    }

    /// The residual rows among the `len` rows from `first` on.
    fn residual_rows_in(&self, first: usize, len: usize) -> &[usize] {
        let rows = &self.residual_rows;
        let from = rows.partition_point(|&i| i < first);
        let to = rows.partition_point(|&i| i < first + len);
        &rows[from..to]
    }

    /// The fitted displacement at dense point `i` and its derivatives along t₁ and t₂.
    pub(crate) fn fitted(&self, i: usize, displacements: &[Vec3A]) -> (Vec3A, Vec3A, Vec3A) {
        match &self.neighbours {
            Neighbours::Narrow(n) => self.row_sums(n, i, self.k, displacements),
            Neighbours::Wide(n) => self.row_sums(n, i, self.k, displacements),
        }
    }

    /// Row `i`'s fit of `values` (one per simulation point): its value at the dense point
    /// and its slopes along t₁ and t₂. With a the anchor's value and eⱼ = vⱼ − a the other
    /// neighbours' offsets from it, the value is a + Σ c⁰ⱼeⱼ and the slopes Σ c¹ⱼeⱼ and
    /// Σ c²ⱼeⱼ: every fit reproduces constants (its coefficients sum to 1 in the value and
    /// to 0 in the slopes), so the anchor's own coefficient need not be stored, and the
    /// sums run over small offsets rather than large absolute values.
    #[inline(always)]
    fn row_sums<I: NeighbourIndex>(
        &self,
        neighbours: &[I],
        i: usize,
        k: usize,
        values: &[Vec3A],
    ) -> (Vec3A, Vec3A, Vec3A) {
        // Two sets of sums, over even and odd neighbours: two short dependency chains
        // instead of one long one.
        let (anchor, others) = neighbours[i * k..(i + 1) * k].split_at(1);
        let m = k - 1;
        let row = &self.coefficients[i * row_stride(k)..][..3 * m];
        let (c0, rest) = row.split_at(m);
        let (c1, c2) = rest.split_at(m);
        let a = values[anchor[0].get()];
        let mut sums = [[Vec3A::ZERO; 3]; 2];
        let add = |s: &mut [Vec3A; 3], t: usize| {
            let e = values[others[t].get()] - a;
            s[0] += e * c0[t];
            s[1] += e * c1[t];
            s[2] += e * c2[t];
        };
        let mut t = 0;
        while t + 1 < m {
            let [even, odd] = &mut sums;
            add(even, t);
            add(odd, t + 1);
            t += 2;
        }
        if t < m {
            add(&mut sums[0], t);
        }
        let [even, odd] = sums;
        (a + (even[0] + odd[0]), even[1] + odd[1], even[2] + odd[2])
    }

    /// [`Self::row_sums`]' value alone.
    #[inline(always)]
    fn row_value<I: NeighbourIndex>(
        &self,
        neighbours: &[I],
        i: usize,
        k: usize,
        values: &[Vec3A],
    ) -> Vec3A {
        let (anchor, others) = neighbours[i * k..(i + 1) * k].split_at(1);
        let c0 = &self.coefficients[i * row_stride(k)..][..k - 1];
        let a = values[anchor[0].get()];
        a + others
            .iter()
            .zip(c0)
            .fold(Vec3A::ZERO, |s, (j, &c)| s + (values[j.get()] - a) * c)
    }
}

/// A chunk of a frame's rows computed from the simulation points' current positions
/// (positions and unnormalised normals, or positions alone when `normals` is empty), handed
/// to [`pulp`] so that the loop is compiled for, and runs with, the widest instruction set
/// the processor has (AVX2 broadcasts each coefficient straight from memory, and its
/// three-operand forms save the copies SSE2 needs). `K` is k, or 0 for any.
struct FrameRows<'a, I, const K: usize> {
    transfer: &'a Transfer,
    neighbours: &'a [I],
    current: &'a [Vec3A],
    first: usize,
    positions: &'a mut [Vec3],
    normals: &'a mut [Vec3],
}

impl<I: NeighbourIndex, const K: usize> pulp::WithSimd for FrameRows<'_, I, K> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) {
        let t = self.transfer;
        let k = if K == 0 { t.k } else { K };
        let (neighbours, current, first) = (self.neighbours, self.current, self.first);
        if self.normals.is_empty() {
            for (row, p) in self.positions.iter_mut().enumerate() {
                *p = Vec3::from(t.row_value(neighbours, first + row, k, current));
            }
        } else {
            let rows = self.positions.iter_mut().zip(self.normals.iter_mut());
            for (row, (p, n)) in rows.enumerate() {
                let (v, s1, s2) = t.row_sums(neighbours, first + row, k, current);
                *p = Vec3::from(v);
                *n = Vec3::from(s1.cross(s2));
            }
        }
    }
}

/// The simulation points' current positions (rest plus displacement) as 16-byte SIMD
/// vectors (the per-frame loops gather them).
pub(super) fn simd_positions(rest: &[Vec3], displacements: &[Vec3]) -> Vec<Vec3A> {
    rest.iter()
        .zip(displacements)
        .map(|(&x, &d)| Vec3A::from(x + d))
        .collect()
}

/// Displacements as 16-byte SIMD vectors (the per-frame loops gather them).
pub(crate) fn simd_displacements(displacements: &[Vec3]) -> Vec<Vec3A> {
    displacements.iter().map(|&d| Vec3A::from(d)).collect()
}

/// `n` normalised, or `fallback()` where `n` is (nearly) zero or not finite.
#[inline]
fn unit_or(n: Vec3, fallback: impl FnOnce() -> Vec3) -> Vec3 {
    let len = n.length();
    if len > MIN_NORMAL_LENGTH && len.is_finite() {
        n * len.recip()
    } else {
        fallback()
    }
}
