//! A series in time order: finding a time in it.

/// The index of the first element of `series` (sorted by `time`) later than `t`: what
/// `series.partition_point(|x| time(x) <= t)` returns, found from where an evenly spaced
/// series would have it, then by doubling the window around that guess. Finishing asks it
/// of the same long series millions of times (the VO poses for every fix in every
/// iteration, the ego for every latency the clock tries for every fix), and a binary search
/// over an hour's drive each time was a third of finishing it (issue #58).
pub(crate) fn index_after<T>(series: &[T], t: f64, time: impl Fn(&T) -> f64) -> usize {
    let (Some(first), Some(last)) = (series.first(), series.last()) else { return 0 };
    let (t0, span) = (time(first), time(last) - time(first));
    let guess = if span > 0.0 { ((t - t0) / span * (series.len() - 1) as f64).round().max(0.0) as usize } else { 0 };
    let (mut lo, mut hi, mut width) = (guess.min(series.len()), guess.min(series.len()), 1);
    // The answer is in [lo, hi] once time(series[lo − 1]) ≤ t < time(series[hi]).
    while lo > 0 && time(&series[lo - 1]) > t {
        hi = lo;
        lo = lo.saturating_sub(width);
        width *= 2;
    }
    while hi < series.len() && time(&series[hi]) <= t {
        lo = hi;
        hi = (hi + width).min(series.len());
        width *= 2;
    }
    lo + series[lo..hi].partition_point(|x| time(x) <= t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn it_is_the_binary_search_s_answer_on_an_uneven_series() {
        // Samples 50 ms apart, a 30 s gap, a burst 1 ms apart, repeated times.
        let mut times: Vec<f64> = (0..200).map(|k| 0.05 * k as f64).collect();
        times.extend((0..100).map(|k| 40.0 + 0.05 * k as f64));
        times.extend((0..50).map(|k| 45.0 + 0.001 * k as f64));
        times.extend([46.0, 46.0, 46.0]);
        let binary = |t: f64| times.partition_point(|&x| x <= t);
        for k in -100..5000 {
            let t = 0.0123 * k as f64;
            assert_eq!(index_after(&times, t, |&x| x), binary(t), "t = {t}");
        }
        for t in [times[0], times[199], times[200], times[349], 46.0, f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            assert_eq!(index_after(&times, t, |&x| x), binary(t), "t = {t}");
        }
        assert_eq!(index_after(&[] as &[f64], 1.0, |&x| x), 0);
        assert_eq!(index_after(&[2.0], 1.0, |&x| x), 0);
        assert_eq!(index_after(&[2.0], 2.0, |&x| x), 1);
    }
}
