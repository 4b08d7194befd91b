//! The most probable number of objects from the labels' weights.
//!
//! Each label is read as a Bernoulli component: it is one object with probability `w`
//! (its weight sum, the label's expected count), none otherwise, independently of the
//! others. The number of objects is then Poisson-binomial, and its mode is the count a
//! labelled multi-Bernoulli filter reports (Reuter et al. 2014, the LMB filter's
//! "MAP cardinality estimate"). Σw is the same distribution's mean.

/// The mode of the number of objects: labels of weight `w` are objects with probability
/// `w`, independently.
///
/// Choice: a label heavier than 1 (the paper's PHD update lets a label carry two objects'
/// mass, METHODS.md §3 eq. 13) counts `⌊w⌋` objects surely and one more with probability
/// `w − ⌊w⌋`; non-finite and non-positive weights count nothing. Ties between two counts go
/// to the smaller.
pub fn map_cardinality(weights: impl IntoIterator<Item = f64>) -> usize {
    let mut sure = 0usize;
    // p[n]: probability that the uncertain labels so far hold n objects.
    let mut p = vec![1.0f64];
    for w in weights {
        if !w.is_finite() || w <= 0.0 {
            continue;
        }
        let whole = w.floor();
        // `whole` is finite and ≥ 0 here; the cast saturates on absurd masses.
        sure += whole as usize;
        let r = w - whole;
        if r <= 0.0 {
            continue;
        }
        p.push(0.0);
        for n in (1..p.len()).rev() {
            p[n] = p[n] * (1.0 - r) + p[n - 1] * r;
        }
        p[0] *= 1.0 - r;
    }
    let mode = p
        .iter()
        .enumerate()
        .fold((0, f64::NEG_INFINITY), |best, (n, &q)| {
            if q > best.1 { (n, q) } else { best }
        })
        .0;
    sure + mode
}

#[cfg(test)]
mod tests {
    use super::map_cardinality;

    /// The mode by enumerating every subset of labels (a naive reference).
    fn brute_force(weights: &[f64]) -> usize {
        let n = weights.len();
        let mut p = vec![0.0; n + 1];
        for mask in 0u32..(1 << n) {
            let mut q = 1.0;
            for (i, w) in weights.iter().enumerate() {
                q *= if mask & (1 << i) != 0 { *w } else { 1.0 - w };
            }
            p[mask.count_ones() as usize] += q;
        }
        let mut best = 0;
        for k in 1..=n {
            if p[k] > p[best] {
                best = k;
            }
        }
        best
    }

    #[test]
    fn the_mode_matches_enumeration_of_every_subset() {
        let mut state = 12345u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        for trial in 0..300 {
            let n = 1 + trial % 10;
            let w: Vec<f64> = (0..n).map(|_| next()).collect();
            let mode = map_cardinality(w.iter().copied());
            assert_eq!(mode, brute_force(&w), "{w:?}");
            // Darroch (1964): the mode lies within one of the mean.
            assert!((mode as f64 - w.iter().sum::<f64>()).abs() < 1.0, "{w:?}");
        }
    }

    #[test]
    fn confident_labels_count_once_and_doubtful_ones_not_at_all() {
        // Two sure labels and four at 0.2 (Σw 2.78): P(2) = 0.410 > P(3) = 0.404.
        assert_eq!(map_cardinality([0.99, 0.99, 0.2, 0.2, 0.2, 0.2]), 2);
        assert_eq!(map_cardinality([0.99, 0.99, 0.3, 0.3, 0.3, 0.3]), 3);
        assert_eq!(map_cardinality([]), 0);
        assert_eq!(map_cardinality([0.0, -1.0, f64::NAN, f64::INFINITY]), 0);
        // A label with two objects' mass.
        assert_eq!(map_cardinality([2.0, 0.9]), 3);
        assert_eq!(map_cardinality([1.6]), 2);
        assert_eq!(map_cardinality([1.4]), 1);
    }
}
