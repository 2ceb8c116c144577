//! The broad phase between bodies given by their bounds: sort and sweep along x, so that
//! many bodies cost a sort and the pairs whose x ranges overlap, not every pair.

use glam::Vec3;

/// The pairs `(i, j)`, `i < j`, of `bounds` (each a lowest and a highest corner) that
/// overlap on every axis (touching counts), in increasing `(i, j)` order. Bounds with a
/// NaN corner overlap nothing.
pub fn overlapping_pairs(bounds: &[(Vec3, Vec3)]) -> Vec<(usize, usize)> {
    let valid = |(lo, hi): &(Vec3, Vec3)| !lo.is_nan() && !hi.is_nan();
    let mut order: Vec<usize> = (0..bounds.len()).filter(|&i| valid(&bounds[i])).collect();
    order.sort_by(|&i, &j| bounds[i].0.x.total_cmp(&bounds[j].0.x));
    let mut pairs = Vec::new();
    for (k, &i) in order.iter().enumerate() {
        let (lo, hi) = bounds[i];
        for &j in &order[k + 1..] {
            let (other_lo, other_hi) = bounds[j];
            if other_lo.x > hi.x {
                break;
            }
            if lo.cmple(other_hi).all() && other_lo.cmple(hi).all() {
                pairs.push((i.min(j), i.max(j)));
            }
        }
    }
    pairs.sort_unstable();
    pairs
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn brute_force(bounds: &[(Vec3, Vec3)]) -> Vec<(usize, usize)> {
        let mut pairs = Vec::new();
        for i in 0..bounds.len() {
            for j in i + 1..bounds.len() {
                let ((a, b), (c, d)) = (bounds[i], bounds[j]);
                if a.cmple(d).all() && c.cmple(b).all() {
                    pairs.push((i, j));
                }
            }
        }
        pairs
    }

    proptest! {
        #[test]
        fn the_sweep_finds_the_pairs_every_pair_test_finds(
            boxes in prop::collection::vec(
                (prop::array::uniform3(-10.0f32..10.0), prop::array::uniform3(0.0f32..4.0)),
                0..40,
            )
        ) {
            let bounds: Vec<(Vec3, Vec3)> = boxes
                .iter()
                .map(|(at, size)| (Vec3::from(*at), Vec3::from(*at) + Vec3::from(*size)))
                .collect();
            prop_assert_eq!(overlapping_pairs(&bounds), brute_force(&bounds));
        }
    }

    #[test]
    fn far_apart_bounds_and_nan_bounds_make_no_pair() {
        let unit = |x: f32| (Vec3::new(x, 0.0, 0.0), Vec3::new(x + 1.0, 1.0, 1.0));
        let nan = (Vec3::NAN, Vec3::ONE);
        assert!(overlapping_pairs(&[unit(0.0), unit(100.0), nan]).is_empty());
        // Touching counts; a NaN box is left out, not panicked on.
        assert_eq!(
            overlapping_pairs(&[unit(0.0), nan, unit(1.0)]),
            vec![(0, 2)]
        );
    }
}
