//! Pins in the transfer: the dense points by pinned simulation points follow the pins alone
//! ([`Transfer::hold`]).

use super::fit::RowFit;
use super::*;

/// A dense point is held by the pins ([`Transfer::hold`]) where its nearest pinned
/// neighbour is at most this many times as far as its nearest free one...
pub const PIN_HOLD: f64 = 1.25;

/// ...and between that and this many times, its free neighbours' weights rise smoothly from
/// nothing to their full Gaussian weight, so that the drawn surface does not tear where the
/// held part meets the free part.
pub const PIN_BLEND: f64 = 2.5;

/// What [`Transfer::hold`] holds the dense points to.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Pins {
    /// Per simulation point: whether it is pinned (empty: none is).
    pub simulation: Vec<bool>,
    /// Per dense point: whether it is held even where its nearest simulation point is free
    /// (a pinned region, drawn at the dense resolution); none beyond the list's end. Kept
    /// while no simulation point is pinned, for when one is again.
    pub dense: Vec<bool>,
}

impl Pins {
    /// Whether simulation point `j` is pinned.
    pub fn simulation(&self, j: usize) -> bool {
        self.simulation.get(j).copied().unwrap_or(false)
    }

    /// Whether dense point `i` is named held.
    pub fn dense(&self, i: usize) -> bool {
        self.dense.get(i).copied().unwrap_or(false)
    }

    /// Whether nothing is pinned.
    pub fn is_empty(&self) -> bool {
        !self.simulation.contains(&true)
    }

    /// The same pins with empty lists where nothing is pinned or named, and the names as
    /// long as the `rows` dense points (a shorter list names none beyond its end), so that
    /// equal pins compare equal.
    fn normalised(&self, rows: usize) -> Self {
        let simulation = if self.is_empty() {
            Vec::new()
        } else {
            self.simulation.clone()
        };
        let mut dense = Vec::new();
        if self.dense.contains(&true) {
            dense.clone_from(&self.dense);
            dense.resize(rows, false);
        }
        Self { simulation, dense }
    }
}

impl Transfer {
    /// Makes the dense points follow the pins. A dense point with a pinned neighbour is
    /// *held* where its nearest pinned neighbour is at most [`PIN_HOLD`] times as far as its
    /// nearest free one, or where `pins` names it (a pinned region drawn at the dense
    /// resolution): its row is fitted again over its pinned neighbours alone, so that it
    /// moves exactly as they do (not at all while they hold still; rigidly with them when
    /// they are moved together, where they allow a full fit), whatever the free points
    /// nearby do. Rows up to [`PIN_BLEND`] times as far weigh their free neighbours less, so
    /// that the drawn surface does not tear at the pins' edge. Only rows whose neighbours'
    /// pins or own name changed are fitted again; the result is the same, bit for bit, as a
    /// transfer given these pins from the start. Returns how many rows were fitted again.
    pub fn hold(&mut self, pins: &Pins) -> Result<usize, TransferError> {
        let (n, rows) = (self.sim_rest.len(), self.rest.len());
        if !pins.simulation.is_empty() && pins.simulation.len() != n {
            return Err(TransferError::PinCount {
                expected: n,
                found: pins.simulation.len(),
            });
        }
        if pins.dense.len() > rows {
            return Err(TransferError::PinCount {
                expected: rows,
                found: pins.dense.len(),
            });
        }
        let pins = pins.normalised(rows);
        if pins == self.pins {
            return Ok(0);
        }
        let was = std::mem::replace(&mut self.pins, pins);
        let sim_changed: Vec<bool> = (0..n)
            .map(|j| was.simulation(j) != self.pins.simulation(j))
            .collect();
        let k = self.k;
        let job = RowFit {
            rest: &self.rest,
            normals: &self.normals,
            sim: &self.sim_rest,
            pins: &self.pins,
            first: 0,
            k,
            bandwidth: self.config.bandwidth,
        };
        let wanted = |row: usize, nbrs: &[u32]| {
            was.dense(row) != job.pins.dense(row) || nbrs.iter().any(|&j| sim_changed[j as usize])
        };
        let refit = match &mut self.neighbours {
            Neighbours::Narrow(nb) => job.refit(nb, &mut self.coefficients, wanted),
            Neighbours::Wide(nb) => job.refit(nb, &mut self.coefficients, wanted),
        };
        let mut count = 0;
        for (kind, new) in self.kinds.iter_mut().zip(refit) {
            if let Some(new) = new {
                *kind = new;
                count += 1;
            }
        }
        self.residual_rows = (0..self.kinds.len())
            .filter(|&i| self.kinds[i].residual)
            .collect();
        Ok(count)
    }

    /// The pins the dense points are held to ([`Self::hold`]).
    pub fn pins(&self) -> &Pins {
        &self.pins
    }
}
