//! Timestamp association of two trajectories, as evo's `associate_trajectories`.
//!
//! The shorter trajectory drives the search (the second one on a tie); each of its
//! stamps is matched to the nearest stamp of the other within `max_diff` seconds, the
//! later one on an exact tie between neighbours. Input stamps are sorted (the readers
//! reject anything else), so a binary search suffices.

use crate::trajectory::Trajectory;

/// evo's default maximum stamp difference, s.
pub const DEFAULT_MAX_DIFF_S: f64 = 0.01;

/// Index pairs `(i_first, i_second)` of matching stamps.
pub fn matching_indices(first: &[f64], second: &[f64], max_diff: f64) -> Vec<(usize, usize)> {
    let second_longer = second.len() > first.len();
    let (short, long) = if second_longer { (first, second) } else { (second, first) };
    let mut pairs = Vec::with_capacity(short.len());
    let (Some(&lo), Some(&hi)) = (long.first(), long.last()) else {
        return pairs;
    };
    for (i_short, &stamp) in short.iter().enumerate() {
        if stamp < lo - max_diff || stamp > hi + max_diff {
            continue;
        }
        let upper = long.partition_point(|&v| v <= stamp).min(long.len() - 1);
        let diff_ub = long[upper] - stamp;
        let diff_lb = if upper > 0 { stamp - long[upper - 1] } else { f64::INFINITY };
        let best = if diff_ub <= max_diff && diff_ub < diff_lb {
            upper
        } else if diff_lb <= max_diff && diff_lb <= diff_ub {
            upper - 1
        } else {
            continue;
        };
        pairs.push(if second_longer { (i_short, best) } else { (best, i_short) });
    }
    pairs
}

/// The two trajectories reduced to their matched poses, in the same order.
pub fn associate(first: &Trajectory, second: &Trajectory, max_diff: f64) -> (Trajectory, Trajectory) {
    let pairs = matching_indices(&first.stamps, &second.stamps, max_diff);
    let (a, b): (Vec<usize>, Vec<usize>) = pairs.into_iter().unzip();
    (first.select(&a), second.select(&b))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_within_tolerance_only() {
        let a = [0.0, 0.1, 0.2, 0.3];
        let b = [0.005, 0.2, 0.35];
        assert_eq!(matching_indices(&a, &b, 0.01), vec![(0, 0), (2, 1)]);
        assert_eq!(matching_indices(&b, &a, 0.01), vec![(0, 0), (1, 2)]);
    }

    #[test]
    fn equal_distance_prefers_the_earlier_stamp() {
        // evo: diff_ub < diff_lb picks the upper one, a tie goes to the lower one.
        assert_eq!(matching_indices(&[0.0, 0.5], &[0.25], 0.25), vec![(0, 0)]);
    }

    #[test]
    fn empty_inputs_match_nothing() {
        assert!(matching_indices(&[], &[1.0], 0.01).is_empty());
        assert!(matching_indices(&[1.0], &[], 0.01).is_empty());
    }
}
