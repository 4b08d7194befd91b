//! Start-up of the background model: the initial per-pixel mean and variance from frames
//! sampled evenly over the sequence.
//!
//! - [`median`]: per-channel median and median absolute deviation (× 1.4826). A pixel's
//!   median is a vehicle's colour as soon as vehicles cover it in more than half of the
//!   samples, which is what happens under a queue at a red light: each of several queued
//!   vehicles covers the pixel for a while, and the median of a mix of their colours and
//!   the road's is some vehicle's colour (or none at all).
//! - [`persistent`]: the most persistent colour. For each sample, count the samples whose
//!   colour lies within a radius `r` of it; the densest sample's cluster (those within `r`)
//!   is the background, its mean the initial mean and its spread the initial variance.
//!
//! Choice: the densest cluster rather than a mode of quantised colours (no bin edges to
//! split the road's cluster in two under illumination drift) or the longest stable run
//! (a vehicle stopped for a long time is also a stable run, and runs break on sensor
//! noise). The road wins as long as it shows longer than any one vehicle covers the pixel,
//! whatever the vehicles' total share; vehicles of different colours form separate
//! clusters. A vehicle that covers a pixel for most of the sequence still enters the
//! background (no start-up from pixels alone can see the road under it).
//!
//! `r` is half the foreground threshold at the noise floor, `k·√3·σ_min / 2` (≈ 21 grey
//! levels of RGB distance with the defaults): samples closer than that would never be
//! foreground against each other, and half leaves a margin for noise and slow drift.

/// What the start-up needs of the background model's config (`BackgroundConfig`'s fields of
/// the same names): the match threshold and the bounds on each pixel's standard deviation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spread {
    /// Match threshold, in standard deviations.
    pub threshold_sigma: f64,
    /// Lower bound on a pixel's standard deviation.
    pub min_sigma: f64,
    /// Upper bound on a pixel's standard deviation.
    pub max_sigma: f64,
}
use image::RgbImage;

/// Per-pixel median and variance from the median absolute deviation: `(mean, var)`, 3 and
/// 1 values per pixel. `samples` is non-empty and of one size.
pub fn median(samples: &[RgbImage], config: &Spread) -> (Vec<f32>, Vec<f32>) {
    let n_px = samples.first().map_or(0, |s| s.as_raw().len() / 3);
    let mut mean = vec![0f32; n_px * 3];
    let mut var = vec![0f32; n_px];
    let mut column = Vec::with_capacity(samples.len());
    let mut dev = Vec::with_capacity(samples.len() * 3);
    let min_var = (config.min_sigma * config.min_sigma) as f32;
    let max_var = (config.max_sigma * config.max_sigma) as f32;
    for p in 0..n_px {
        dev.clear();
        for c in 0..3 {
            column.clear();
            column.extend(samples.iter().map(|s| s.as_raw()[p * 3 + c]));
            column.sort_unstable();
            let med = median_u8(&column);
            mean[p * 3 + c] = med;
            dev.extend(column.iter().map(|&v| (f32::from(v) - med).abs()));
        }
        dev.sort_unstable_by(f32::total_cmp);
        let mad = if dev.is_empty() {
            0.0
        } else {
            dev[dev.len() / 2]
        };
        let sigma = 1.4826 * mad;
        var[p] = (sigma * sigma).clamp(min_var, max_var);
    }
    (mean, var)
}

fn median_u8(sorted: &[u8]) -> f32 {
    let n = sorted.len();
    if n % 2 == 1 {
        f32::from(sorted[n / 2])
    } else {
        (f32::from(sorted[n / 2 - 1]) + f32::from(sorted[n / 2])) / 2.0
    }
}

/// The cluster radius of [`persistent`], RGB distance.
pub fn persistent_radius(config: &Spread) -> f64 {
    config.threshold_sigma * 3f64.sqrt() * config.min_sigma / 2.0
}

/// Per-pixel most persistent colour (the densest cluster of samples, see the module
/// documentation) and its variance: `(mean, var)`, 3 and 1 values per pixel. `samples`
/// is non-empty and of one size. Ties go to the earliest sample (deterministic).
pub fn persistent(samples: &[RgbImage], config: &Spread) -> (Vec<f32>, Vec<f32>) {
    let n_px = samples.first().map_or(0, |s| s.as_raw().len() / 3);
    let n = samples.len();
    let r = persistent_radius(config);
    let r2 = (r * r) as i32;
    let min_var = (config.min_sigma * config.min_sigma) as f32;
    let max_var = (config.max_sigma * config.max_sigma) as f32;
    let mut mean = vec![0f32; n_px * 3];
    let mut var = vec![0f32; n_px];
    let mut col: Vec<[i32; 3]> = vec![[0; 3]; n];
    let mut count = vec![0u32; n];
    for p in 0..n_px {
        for (c, s) in col.iter_mut().zip(samples) {
            let px = &s.as_raw()[p * 3..p * 3 + 3];
            *c = [i32::from(px[0]), i32::from(px[1]), i32::from(px[2])];
        }
        count.fill(1);
        for i in 0..n {
            let a = col[i];
            for j in i + 1..n {
                let b = col[j];
                let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
                if d[0] * d[0] + d[1] * d[1] + d[2] * d[2] <= r2 {
                    count[i] += 1;
                    count[j] += 1;
                }
            }
        }
        let mut best = 0;
        for (i, &c) in count.iter().enumerate() {
            if c > count[best] {
                best = i;
            }
        }
        let centre = col[best];
        let mut sum = [0f64; 3];
        let mut members = 0u32;
        for c in &col {
            let d = [c[0] - centre[0], c[1] - centre[1], c[2] - centre[2]];
            if d[0] * d[0] + d[1] * d[1] + d[2] * d[2] <= r2 {
                for k in 0..3 {
                    sum[k] += f64::from(c[k]);
                }
                members += 1;
            }
        }
        let m = sum.map(|s| s / f64::from(members));
        let mut ss = 0f64;
        for c in &col {
            let d = [c[0] - centre[0], c[1] - centre[1], c[2] - centre[2]];
            if d[0] * d[0] + d[1] * d[1] + d[2] * d[2] <= r2 {
                ss += (0..3)
                    .map(|k| (f64::from(c[k]) - m[k]).powi(2))
                    .sum::<f64>();
            }
        }
        for k in 0..3 {
            mean[p * 3 + k] = m[k] as f32;
        }
        var[p] = ((ss / (3.0 * f64::from(members))) as f32).clamp(min_var, max_var);
    }
    (mean, var)
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::Rgb;

    /// `BackgroundConfig::default()`'s values.
    const DEFAULTS: Spread = Spread {
        threshold_sigma: 3.0,
        min_sigma: 8.0,
        max_sigma: 40.0,
    };

    fn plain(rgb: [u8; 3]) -> RgbImage {
        RgbImage::from_pixel(4, 3, Rgb(rgb))
    }

    #[test]
    fn persistent_finds_the_road_under_a_queue_of_different_vehicles() {
        // A pixel covered by vehicles in 6 of 10 samples (3 colours, 2 samples each) and
        // road in 4: the median is a vehicle's colour, the most persistent the road.
        let road = [100, 100, 100];
        let mut samples = vec![plain(road); 4];
        for c in [[240, 240, 240], [200, 200, 200], [160, 160, 220]] {
            samples.push(plain(c));
            samples.push(plain(c));
        }
        let cfg = DEFAULTS;
        let (m, _) = persistent(&samples, &cfg);
        assert_eq!(&m[..3], &[100.0, 100.0, 100.0]);
        let (med, _) = median(&samples, &cfg);
        assert_ne!(&med[..3], &[100.0, 100.0, 100.0]);
    }

    #[test]
    fn persistent_averages_the_cluster_and_floors_the_variance() {
        let samples = vec![
            plain([100, 100, 100]),
            plain([104, 100, 100]),
            plain([250, 0, 0]),
        ];
        let cfg = DEFAULTS;
        let (m, v) = persistent(&samples, &cfg);
        assert_eq!(&m[..3], &[102.0, 100.0, 100.0]);
        assert_eq!(v[0], 64.0);
    }
}
