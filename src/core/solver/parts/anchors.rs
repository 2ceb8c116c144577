//! Anchor springs (eq 5): each ties a simulation point to a target; ids stay valid while
//! others come and go.

use glam::Vec3;

use super::*;

#[derive(Debug, Clone, PartialEq)]
struct AnchorSlot {
    generation: u32,
    anchor: Option<Anchor>,
}

/// Anchor springs (eq 5) from points to world positions: pins that give, pokes and drags.
/// Added, moved and removed at any time; each has an [`AnchorId`] valid until it is
/// removed.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Anchors {
    slots: Vec<AnchorSlot>,
    free: Vec<u32>,
    pub(crate) revision: u64,
}

impl Anchors {
    fn check(&self, a: &Anchor, points: usize) -> Result<(), SolverError> {
        check_index(a.point as usize, points)?;
        let bad = |what| SolverError::InvalidAnchor {
            point: a.point,
            what,
        };
        if check_vector(a.point as usize, a.target, "anchor target").is_err() {
            return Err(bad("target"));
        }
        if !non_negative(a.stiffness) {
            return Err(bad("stiffness"));
        }
        if !non_negative(a.damping) {
            return Err(bad("damping"));
        }
        Ok(())
    }

    /// Adds an anchor on one of `points` points.
    pub fn add(&mut self, anchor: Anchor, points: usize) -> Result<AnchorId, SolverError> {
        self.check(&anchor, points)?;
        self.revision = next_revision();
        if let Some(slot) = self.free.pop() {
            let s = &mut self.slots[slot as usize];
            s.anchor = Some(anchor);
            return Ok(AnchorId {
                slot,
                generation: s.generation,
            });
        }
        let slot = u32::try_from(self.slots.len())
            .map_err(|_| SolverError::InvalidConfig("too many anchors"))?;
        self.slots.push(AnchorSlot {
            generation: 0,
            anchor: Some(anchor),
        });
        Ok(AnchorId {
            slot,
            generation: 0,
        })
    }

    /// Every slot as `(generation, anchor)` and the free slots in the order they will be
    /// reused: what a snapshot needs to give the same ids back.
    pub(crate) fn slots(&self) -> (Vec<(u32, Option<Anchor>)>, Vec<u32>) {
        let slots = self
            .slots
            .iter()
            .map(|s| (s.generation, s.anchor))
            .collect();
        (slots, self.free.clone())
    }

    /// Anchors with exactly these slots (see [`Self::slots`]), each anchor checked against
    /// `points` points and the free list against the empty slots.
    pub(crate) fn from_slots(
        slots: &[(u32, Option<Anchor>)],
        free: &[u32],
        points: usize,
    ) -> Result<Self, SolverError> {
        for anchor in slots.iter().filter_map(|(_, a)| a.as_ref()) {
            Self::default().check(anchor, points)?;
        }
        let mut empty: Vec<u32> = (0..slots.len() as u32)
            .filter(|&i| slots[i as usize].1.is_none())
            .collect();
        let mut listed = free.to_vec();
        empty.sort_unstable();
        listed.sort_unstable();
        if empty != listed {
            return Err(SolverError::InvalidConfig(
                "the anchors' free list does not match their empty slots",
            ));
        }
        Ok(Self {
            slots: slots
                .iter()
                .map(|&(generation, anchor)| AnchorSlot { generation, anchor })
                .collect(),
            free: free.to_vec(),
            revision: next_revision(),
        })
    }

    fn slot(&self, id: AnchorId) -> Option<&AnchorSlot> {
        self.slots
            .get(id.slot as usize)
            .filter(|s| s.generation == id.generation && s.anchor.is_some())
    }

    /// The anchor behind `id`, if it still exists.
    pub fn get(&self, id: AnchorId) -> Option<&Anchor> {
        self.slot(id).and_then(|s| s.anchor.as_ref())
    }

    /// Number of live anchors.
    pub fn len(&self) -> usize {
        self.slots.len() - self.free.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Every live anchor.
    pub fn iter(&self) -> impl Iterator<Item = (AnchorId, &Anchor)> + '_ {
        self.slots.iter().enumerate().filter_map(|(slot, s)| {
            s.anchor.as_ref().map(|a| {
                (
                    AnchorId {
                        slot: slot as u32,
                        generation: s.generation,
                    },
                    a,
                )
            })
        })
    }

    /// Every live anchor, without ids.
    pub(crate) fn live(&self) -> impl Iterator<Item = &Anchor> + '_ {
        self.slots.iter().filter_map(|s| s.anchor.as_ref())
    }

    /// Removes an anchor, returning it.
    pub fn remove(&mut self, id: AnchorId) -> Option<Anchor> {
        self.slot(id)?;
        let s = &mut self.slots[id.slot as usize];
        let anchor = s.anchor.take();
        s.generation = s.generation.wrapping_add(1);
        self.free.push(id.slot);
        self.revision = next_revision();
        anchor
    }

    /// Moves an anchor's target (a drag). The stable step does not depend on targets, so
    /// this does not make a stepper re-estimate it.
    pub fn set_target(&mut self, id: AnchorId, target: Vec3) -> Result<(), SolverError> {
        let point = self.get(id).ok_or(SolverError::UnknownAnchor)?.point;
        check_vector(point as usize, target, "anchor target").map_err(|_| {
            SolverError::InvalidAnchor {
                point,
                what: "target",
            }
        })?;
        if let Some(a) = self.slots[id.slot as usize].anchor.as_mut() {
            a.target = target;
        }
        Ok(())
    }

    /// Replaces an anchor's settings (on one of `points` points).
    pub fn set(&mut self, id: AnchorId, anchor: Anchor, points: usize) -> Result<(), SolverError> {
        self.get(id).ok_or(SolverError::UnknownAnchor)?;
        self.check(&anchor, points)?;
        self.slots[id.slot as usize].anchor = Some(anchor);
        self.revision = next_revision();
        Ok(())
    }

    /// Removes every anchor (their ids become invalid).
    pub fn clear(&mut self) {
        let ids: Vec<AnchorId> = self.iter().map(|(id, _)| id).collect();
        for id in ids {
            self.remove(id);
        }
    }
}
