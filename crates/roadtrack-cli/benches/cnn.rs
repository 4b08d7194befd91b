//! CNN throughput figures for docs/PERFORMANCE.md "CNN".
//!
//! ```text
//! cargo bench -p roadtrack-cli --bench cnn
//! ```
//! Measures, on a 640×480 frame: per-window scoring (patches/s) and dense score maps
//! (frames/s, with 700 particle lookups = 10 targets × 70 particles) for the network
//! `roadtrack train` writes (person preset, 64×32 input, untrained weights: speed does not
//! depend on the values) and the tiny test fixture; and the SSDLite pedestrian network when
//! `scripts/setup.sh --models` has fetched it.

use roadtrack::rng::{Stream, rng};
use roadtrack_cli::bench::cnn::{
    bench_score_map, bench_ssd_score_map, bench_window_scoring, test_frame,
};
use roadtrack_cli::bench::{StageResult, cpu_seconds, machine};
use roadtrack_cnn::export::write_onnx;
use roadtrack_cnn::net::TinyCnn;
use roadtrack_cnn::ssd::{SsdConfig, SsdPersonDetector, default_model_path};
use roadtrack_cnn::train::{TrainConfig, training_preprocessing};
use roadtrack_cnn::{CnnConfig, OnnxClassifier};

fn main() -> roadtrack::Result<()> {
    let m = machine();
    println!(
        "machine: {} ({} cores, {} rayon threads)",
        m.cpu, m.cores, m.rayon_threads
    );
    let dir = tempfile::tempdir().map_err(|e| roadtrack::Error::io("tempdir", e))?;
    let person = dir.path().join("person.onnx");
    let net = TinyCnn::new(
        TrainConfig::default().shape(),
        &mut rng(0, Stream::Synthetic),
    );
    write_onnx(&person, &net, &training_preprocessing(), None)?;
    let fixture = std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../roadtrack-cnn/tests/fixtures/tiny_classifier.onnx"
    ));
    let mut rows = Vec::new();
    let mut cpu = Vec::new();
    let mut timed = |rows: &mut Vec<_>,
                     f: &mut dyn FnMut() -> roadtrack::Result<StageResult>|
     -> roadtrack::Result<()> {
        let c = cpu_seconds();
        let r = f()?;
        cpu.push(cpu_seconds() - c);
        rows.push(r);
        Ok(())
    };
    for (name, path) in [
        ("trained-size CNN 64×32", person.as_path()),
        ("tiny fixture 32×16", fixture),
    ] {
        let model = OnnxClassifier::load(path, &CnnConfig::default())?;
        timed(&mut rows, &mut || bench_window_scoring(&model, name, 700))?;
        for stride in [4, 8, 16] {
            timed(&mut rows, &mut || {
                bench_score_map(&model, name, stride, 700, 10)
            })?;
        }
    }
    if let Some(p) = default_model_path().filter(|p| p.exists()) {
        let det = SsdPersonDetector::load(&p, &SsdConfig::default())?;
        let frame = test_frame(640, 480);
        timed(&mut rows, &mut || {
            bench_ssd_score_map(&det, &frame, 8, 700, 10)
        })?;
    } else {
        println!("(SSD model absent: scripts/setup.sh --models)");
    }
    println!("| stage | input | items | wall s | per wall s | CPU s |");
    println!("| --- | --- | --- | --- | --- | --- |");
    for (r, c) in rows.iter().zip(&cpu) {
        println!(
            "| {} | {} | {} {} | {:.3} | {:.1} | {:.2} |",
            r.stage, r.input, r.items, r.unit, r.seconds, r.per_second, c
        );
    }
    Ok(())
}
