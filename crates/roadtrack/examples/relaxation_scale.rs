//! Scale benchmark of the relaxation matcher on a generated wide-area road network
//! (0.3 m/px), with correct-match rates of the paper's method and the baselines.
//!
//! ```text
//! cargo run -p roadtrack --example relaxation_scale -- [N ...]
//! ```
//! Default sizes: 50 1000 10000 100000. Set RAYON_NUM_THREADS to pin the thread count.

use roadtrack::track::relaxation::baselines::{nearest_neighbour, optimal_assignment};
use roadtrack::track::relaxation::scale::NetworkConfig;
use roadtrack::track::relaxation::{
    RelaxationConfig, generate_road_network_pair, scale_experiment,
};

fn main() -> roadtrack::Result<()> {
    let sizes: Vec<usize> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let sizes = if sizes.is_empty() {
        vec![50, 1_000, 10_000, 100_000]
    } else {
        sizes
    };
    let cfg = RelaxationConfig::default();
    println!(
        "vehicles,detections1,detections2,labels,support_entries,build_s,solve_s,total_s,build_cpu_s,solve_cpu_s,iterations,converged,heap_mib,peak_rss_mib,correct_rate,nn_rate,assignment_rate,threads"
    );
    for n in sizes {
        let r = scale_experiment(n, &cfg, 1)?;
        // Baselines on the same pair. The assignment is dense per connected component of
        // the gate graph, and on a network the component is the whole network: only up to
        // 1 000 vehicles.
        let (f1, f2, truth) = generate_road_network_pair(n, &NetworkConfig::default(), 1)?;
        let rate = |p: &[Option<usize>]| {
            let ok = truth
                .iter()
                .zip(p)
                .filter(|((_, t), p)| *t == p.map(|k| f2[k].id))
                .count();
            ok as f64 / truth.len().max(1) as f64
        };
        let nn = rate(&nearest_neighbour(&f1, &f2, cfg.gate_half_width_px)?);
        let assign = if n <= 1_000 {
            format!(
                "{:.4}",
                rate(&optimal_assignment(&f1, &f2, cfg.gate_half_width_px)?)
            )
        } else {
            String::new()
        };
        println!(
            "{},{},{},{},{},{:.4},{:.4},{:.4},{},{},{},{},{:.1},{},{:.4},{:.4},{},{}",
            r.n_vehicles,
            r.n_detections.0,
            r.n_detections.1,
            r.n_labels,
            r.n_support_entries,
            r.build_s,
            r.solve_s,
            r.build_s + r.solve_s,
            r.build_cpu_s.map_or(String::new(), |c| format!("{c:.2}")),
            r.solve_cpu_s.map_or(String::new(), |c| format!("{c:.2}")),
            r.iterations,
            r.converged,
            r.heap_bytes as f64 / (1 << 20) as f64,
            r.peak_rss_bytes.map_or(String::new(), |b| format!(
                "{:.1}",
                b as f64 / (1 << 20) as f64
            )),
            r.correct_rate,
            nn,
            assign,
            r.threads
        );
    }
    Ok(())
}
