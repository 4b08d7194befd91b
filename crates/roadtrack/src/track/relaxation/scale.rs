//! Scale: a generated wide-area road network seen from a stratospheric platform, and the
//! benchmark of the matcher on it (issue 5, "Scale").
//!
//! The network is a square grid of roads (default: blocks of 250 m, one-way roads of two
//! 3.5 m lanes whose direction alternates, as the paper's two-lane one-way road; two-way
//! roads as an option) at 0.3 m/px. Vehicles sit on the lanes with a mean headway of
//! 30 m (light urban traffic, ≈ 1 000 vehicles/km²), move along their lane at
//! `N(13.9, 2²)` m/s for `Δt = 1.5 s`, keep a car colour with per-frame noise, and miss
//! either frame with a small probability. The grid grows with the number of vehicles, so
//! density — and thus the work per vehicle — is the same at every size.

use super::{RelaxationConfig, RelaxationProblem};
use crate::detection::Detection;
use crate::error::{Error, Result};
use crate::geometry::Point;
use crate::rng::{Stream, rng};
use rand::RngExt;
use rand_distr::{Distribution, Normal};
use std::time::Instant;

/// Parameters of the generated road network (all lengths on the ground, m).
#[derive(Debug, Clone, PartialEq)]
pub struct NetworkConfig {
    /// Ground sampling distance, m/px. Default 0.3.
    pub ground_sample_m_per_px: f64,
    /// Distance between parallel roads, m. Default 250.
    pub block_spacing_m: f64,
    /// Lanes per direction. Default 2.
    pub lanes_per_direction: u32,
    /// Two-way roads (lanes in both directions side by side) instead of one-way roads
    /// whose direction alternates from road to road. Default false: the paper's scene is
    /// a one-way two-lane road, and on two-way roads the neighbour support of one flow
    /// pulls the other towards its displacement (see docs/RELAXATION.md).
    pub two_way: bool,
    /// Lane width, m. Default 3.5.
    pub lane_width_m: f64,
    /// Mean distance between consecutive vehicles of a lane, m. Default 30.
    pub mean_headway_m: f64,
    /// Mean speed, m/s. Default 13.9 (50 km/h).
    pub mean_speed_mps: f64,
    /// Standard deviation of the speed between vehicles, m/s. Default 2.
    pub speed_sd_mps: f64,
    /// Time between the two frames, s. Default 1.5 (the paper's Δt).
    pub dt_s: f64,
    /// Probability that a vehicle is missing from a given frame. Default 0.05.
    pub miss_prob: f64,
    /// Standard deviation of the extracted centre, px. Default 1.
    pub position_noise_px: f64,
    /// Standard deviation of the extracted mean colour per channel. Default 8.
    pub colour_noise: f64,
}

impl Default for NetworkConfig {
    fn default() -> Self {
        Self {
            ground_sample_m_per_px: 0.3,
            block_spacing_m: 250.0,
            lanes_per_direction: 2,
            two_way: false,
            lane_width_m: 3.5,
            mean_headway_m: 30.0,
            mean_speed_mps: 13.9,
            speed_sd_mps: 2.0,
            dt_s: 1.5,
            miss_prob: 0.05,
            position_noise_px: 1.0,
            colour_noise: 8.0,
        }
    }
}

/// Typical car colours (white, black, silver, grey, red, blue, dark green, beige).
const PALETTE: [[f64; 3]; 8] = [
    [235.0, 235.0, 235.0],
    [25.0, 25.0, 30.0],
    [180.0, 182.0, 185.0],
    [110.0, 110.0, 115.0],
    [170.0, 30.0, 35.0],
    [30.0, 60.0, 150.0],
    [30.0, 80.0, 50.0],
    [200.0, 185.0, 150.0],
];

/// Frame 1, frame 2, and for each frame-1 detection its true frame-2 id.
pub type NetworkPair = (Vec<Detection>, Vec<Detection>, Vec<(u64, Option<u64>)>);

/// A frame pair with `n_vehicles` vehicles on a generated road network (see the module
/// doc), seeded by `seed` (stream [`Stream::Synthetic`]).
///
/// Returns frame 1, frame 2 (in a shuffled order, so input order carries no hint) and the
/// truth: for each frame-1 detection, its frame-2 id or `None`. A vehicle keeps its id in
/// both frames; a vehicle that drives off the end of its road is not in frame 2.
pub fn generate_road_network_pair(
    n_vehicles: usize,
    cfg: &NetworkConfig,
    seed: u64,
) -> Result<NetworkPair> {
    let bad =
        |field: &'static str| Error::config("NetworkConfig", field, "must be finite and positive");
    for (f, v) in [
        ("ground_sample_m_per_px", cfg.ground_sample_m_per_px),
        ("block_spacing_m", cfg.block_spacing_m),
        ("lane_width_m", cfg.lane_width_m),
        ("mean_headway_m", cfg.mean_headway_m),
        ("dt_s", cfg.dt_s),
    ] {
        if !(v.is_finite() && v > 0.0) {
            return Err(bad(f));
        }
    }
    let normal = |mean: f64, sd: f64, field| Normal::new(mean, sd).map_err(|_| bad(field));
    let speed = normal(cfg.mean_speed_mps, cfg.speed_sd_mps, "speed_sd_mps")?;
    let noise = normal(0.0, cfg.position_noise_px, "position_noise_px")?;
    let colour_noise = normal(0.0, cfg.colour_noise, "colour_noise")?;
    let mut r = rng(seed, Stream::Synthetic);
    let px = |m: f64| m / cfg.ground_sample_m_per_px;
    let per_direction = cfg.lanes_per_direction.max(1) as usize;
    let lanes_per_road = if cfg.two_way { 2 } else { 1 } * per_direction;
    let per_block = 2.0 * cfg.block_spacing_m * lanes_per_road as f64 / cfg.mean_headway_m;
    let side = ((n_vehicles as f64 / per_block).sqrt().ceil() as usize).max(1);
    let road_len_m = side as f64 * cfg.block_spacing_m;
    let n_lanes = 2 * side * lanes_per_road;
    let mut f1 = Vec::with_capacity(n_vehicles);
    let mut f2 = Vec::with_capacity(n_vehicles);
    let mut truth = Vec::with_capacity(n_vehicles);
    let mut id = 0u64;
    for lane in 0..n_lanes {
        let count = n_vehicles / n_lanes + usize::from(lane < n_vehicles % n_lanes);
        if count == 0 {
            continue;
        }
        let road = lane / lanes_per_road;
        let within = lane % lanes_per_road;
        let vertical = road >= side;
        let centre_m = ((road % side) as f64 + 0.5) * cfg.block_spacing_m;
        let forward = if cfg.two_way {
            within < per_direction
        } else {
            road.is_multiple_of(2)
        };
        let l = (within % per_direction) as f64;
        let offset_m = if forward { 1.0 } else { -1.0 } * (l + 0.5) * cfg.lane_width_m;
        let spacing = road_len_m / count as f64;
        for s in 0..count {
            id += 1;
            let along = (s as f64 + 0.5 + r.random_range(-0.3..0.3)) * spacing;
            let v = speed.sample(&mut r).max(0.0);
            let along2 = if forward {
                along + v * cfg.dt_s
            } else {
                along - v * cfg.dt_s
            };
            let at = |a: f64| -> Point {
                let (x, y) = if vertical {
                    (centre_m + offset_m, a)
                } else {
                    (a, centre_m + offset_m)
                };
                Point::new(px(x), px(y))
            };
            let base = PALETTE[r.random_range(0..PALETTE.len())];
            let jitter = |p: Point, r: &mut crate::rng::Rng| -> (Point, [f64; 3]) {
                let n = |r: &mut crate::rng::Rng| noise.sample(r);
                let c = |r: &mut crate::rng::Rng| colour_noise.sample(r);
                let p = Point::new(p.x + n(r), p.y + n(r));
                let rgb = base.map(|b| (b + c(r)).clamp(0.0, 255.0));
                (p, rgb)
            };
            let (p1, c1) = jitter(at(along), &mut r);
            let (p2, c2) = jitter(at(along2), &mut r);
            let in1 = r.random::<f64>() >= cfg.miss_prob;
            let in2 = r.random::<f64>() >= cfg.miss_prob && (0.0..road_len_m).contains(&along2);
            let (w, h) = if vertical {
                (px(1.8), px(4.5))
            } else {
                (px(4.5), px(1.8))
            };
            let mk = |frame, p, c| Detection {
                size_px: Some((w, h)),
                colour_rgb: Some(c),
                ..Detection::at(frame, id, p)
            };
            if in1 {
                f1.push(mk(1, p1, c1));
                truth.push((id, in2.then_some(id)));
            }
            if in2 {
                f2.push(mk(2, p2, c2));
            }
        }
    }
    // Shuffle frame 2 (Fisher–Yates) so that input order says nothing.
    for i in (1..f2.len()).rev() {
        let j = r.random_range(0..=i);
        f2.swap(i, j);
    }
    Ok((f1, f2, truth))
}

/// What one scale run measured.
#[derive(Debug, Clone, PartialEq)]
pub struct ScaleReport {
    /// Vehicles asked for (before misses).
    pub n_vehicles: usize,
    /// Frame-1 and frame-2 detections.
    pub n_detections: (usize, usize),
    /// Real labels (pairs in the gate).
    pub n_labels: usize,
    /// Support entries, forward plus backward.
    pub n_support_entries: usize,
    /// Time to build labels, support lists and the start, s.
    pub build_s: f64,
    /// Time to iterate and decide, s.
    pub solve_s: f64,
    /// CPU time of the process (all threads) while building, s, when known (Linux).
    pub build_cpu_s: Option<f64>,
    /// CPU time of the process (all threads) while iterating and deciding, s, when known.
    pub solve_cpu_s: Option<f64>,
    /// Iterations run.
    pub iterations: u32,
    /// Whether the iterations met `epsilon`.
    pub converged: bool,
    /// Heap bytes the matcher held (labels, support lists, probabilities and buffers).
    pub heap_bytes: usize,
    /// Peak resident memory of the process so far, bytes (Linux `VmHWM`), when known.
    pub peak_rss_bytes: Option<u64>,
    /// Fraction of frame-1 vehicles whose decision equals the truth.
    pub correct_rate: f64,
    /// Rayon threads available.
    pub threads: usize,
}

/// Generates a network pair of `n_vehicles` (seed `seed`), matches it with `cfg` and
/// reports time, memory and the correct-match rate. Generation is not timed.
///
/// # Errors
/// From [`RelaxationProblem::new`].
pub fn scale_experiment(
    n_vehicles: usize,
    cfg: &RelaxationConfig,
    seed: u64,
) -> Result<ScaleReport> {
    let (f1, f2, truth) = generate_road_network_pair(n_vehicles, &NetworkConfig::default(), seed)?;
    let cpu0 = process_cpu_s();
    let t0 = Instant::now();
    let problem = RelaxationProblem::new(&f1, &f2, cfg)?;
    let build_s = t0.elapsed().as_secs_f64();
    let cpu1 = process_cpu_s();
    let t1 = Instant::now();
    let sol = problem.solve(&cfg.weights(), cfg.epsilon, cfg.max_iterations);
    let m = problem.decide(&sol, cfg.decision);
    let solve_s = t1.elapsed().as_secs_f64();
    let cpu2 = process_cpu_s();
    let diff = |a: Option<f64>, b: Option<f64>| Some(b? - a?);
    let correct = truth
        .iter()
        .zip(&m.partner)
        .filter(|((_, t), p)| *t == p.map(|k| m.ids2[k]))
        .count();
    Ok(ScaleReport {
        n_vehicles,
        n_detections: (f1.len(), f2.len()),
        n_labels: problem.graph.n_labels(),
        n_support_entries: problem.n_support_entries(),
        build_s,
        solve_s,
        build_cpu_s: diff(cpu0, cpu1),
        solve_cpu_s: diff(cpu1, cpu2),
        iterations: sol.iterations,
        converged: sol.converged,
        heap_bytes: problem.heap_bytes(),
        peak_rss_bytes: peak_rss_bytes(),
        correct_rate: if truth.is_empty() {
            1.0
        } else {
            correct as f64 / truth.len() as f64
        },
        threads: rayon::current_num_threads(),
    })
}

/// CPU time (user + system) of this process so far, all threads, s (Linux
/// `/proc/self/stat`, in clock ticks of 10 ms).
pub fn process_cpu_s() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the command name (which is in parentheses and may hold spaces):
    // state is field 3, utime 14, stime 15.
    let rest = &s[s.rfind(')')? + 1..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = |i: usize| f.get(i - 3)?.parse::<u64>().ok();
    Some((ticks(14)? + ticks(15)?) as f64 / 100.0)
}

/// Peak resident set size of this process (Linux `/proc/self/status` `VmHWM`), bytes.
pub fn peak_rss_bytes() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn generator_is_seeded_and_sized() -> Result<()> {
        let cfg = NetworkConfig::default();
        let a = generate_road_network_pair(1000, &cfg, 3)?;
        let b = generate_road_network_pair(1000, &cfg, 3)?;
        assert_eq!(a, b);
        let c = generate_road_network_pair(1000, &cfg, 4)?;
        assert_ne!(a.0, c.0);
        // About 5 % missing from each frame, plus those leaving the network.
        assert!((900..=1000).contains(&a.0.len()), "{}", a.0.len());
        assert!((850..=1000).contains(&a.1.len()), "{}", a.1.len());
        assert_eq!(a.2.len(), a.0.len());
        Ok(())
    }

    #[test]
    fn paper_defaults_match_most_vehicles_of_the_network() -> Result<()> {
        // Measured 0.865 at seed 1 (docs/RELAXATION.md); the bar leaves room for seeds.
        let r = scale_experiment(1000, &RelaxationConfig::default(), 1)?;
        assert!(r.correct_rate > 0.8, "{r:?}");
        assert!(r.n_labels > r.n_detections.0, "{r:?}");
        Ok(())
    }
}
