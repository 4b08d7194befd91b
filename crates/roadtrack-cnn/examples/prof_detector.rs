//! Per-operation time of an ONNX model in tract's optimised plan, single-threaded: where a
//! detector's inference goes (docs/PERFORMANCE.md "Where the learned detector's time goes").
//!
//!     cargo run --release -p roadtrack-cnn --example prof_detector -- models/detector.onnx [H W]
//!
//! With `TAIL=1`: the learned detector's network after its stem, as the detector runs it
//! (input `r3`, `1 × c2 × H/4 × W/4`), and the stem in roadtrack's kernels.
//!
//! Runs 30 passes on a constant `1 × 3 × H × W` input (default 480 × 640) and prints, per
//! node, the fastest of its 30 times, and the fastest whole pass.

use prost::Message as _;
use std::collections::BTreeMap;
use std::time::Instant;
use tract_onnx::pb;
use tract_onnx::prelude::*;
use tract_onnx::tract_core::plan::{SimpleState, eval};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let path = args.get(1).ok_or("usage: prof_detector MODEL.onnx [H W]")?;
    let h: usize = args.get(2).map_or(Ok(480), |s| s.parse())?;
    let w: usize = args.get(3).map_or(Ok(640), |s| s.parse())?;
    // `TAIL=1`: the learned detector's network after its stem (input `r3`, stride 4).
    let tail = std::env::var_os("TAIL").is_some();
    let (proto, dims) = if tail {
        let net = roadtrack_cnn::centernet::read_weights(std::path::Path::new(path))?;
        let c2 = net.shape.c2;
        (
            roadtrack_cnn::centernet::onnx_tail_model(&net)?,
            [1, c2, h / 4, w / 4],
        )
    } else {
        (
            pb::ModelProto::decode(std::fs::read(path)?.as_slice())?,
            [1, 3, h, w],
        )
    };
    let plan = tract_onnx::onnx()
        .model_for_proto_model(&proto)?
        .with_input_fact(0, f32::fact(dims).into())?
        .into_optimized()?
        .into_runnable()?;
    let input = Tensor::from_shape(&dims, &vec![0.1f32; dims.iter().product()])?;
    let mut best: BTreeMap<usize, (String, f64)> = BTreeMap::new();
    let mut total = f64::MAX;
    for _ in 0..30 {
        let mut state = SimpleState::new(&plan)?;
        let mut times = Vec::new();
        let t0 = Instant::now();
        state.run_plan_with_eval(tvec![input.clone().into()], |ctx, st, node, inp| {
            let t = Instant::now();
            let r = eval(ctx, st, node, inp);
            times.push((
                node.id,
                format!("{} {}", node.name, node.op().name()),
                t.elapsed().as_secs_f64() * 1e3,
            ));
            r
        })?;
        total = total.min(t0.elapsed().as_secs_f64() * 1e3);
        for (id, name, t) in times {
            let e = best.entry(id).or_insert((name, f64::MAX));
            e.1 = e.1.min(t);
        }
    }
    if tail {
        // The stem in roadtrack's kernels, on the same size of input.
        let net = roadtrack_cnn::centernet::read_weights(std::path::Path::new(path))?;
        if let Some(stem) = roadtrack_cnn::centernet::stem::Stem::new(&net) {
            let x = vec![0.1f32; 3 * h * w];
            let mut fastest = f64::MAX;
            for _ in 0..30 {
                let t0 = Instant::now();
                std::hint::black_box(stem.run(&x, h, w, true));
                fastest = fastest.min(t0.elapsed().as_secs_f64() * 1e3);
            }
            println!("stem (conv1-conv3, roadtrack's kernels): fastest {fastest:.2} ms");
            // Each kernel alone on bordered channels-last buffers (values 0.1).
            let fastest_of = |f: &mut dyn FnMut()| {
                (0..30)
                    .map(|_| {
                        let t0 = Instant::now();
                        f();
                        t0.elapsed().as_secs_f64() * 1e3
                    })
                    .fold(f64::MAX, f64::min)
            };
            use roadtrack_cnn::centernet::stem::{C1, C2};
            let (c1, c2, c3) = stem.layers();
            let (h1, w1, h2, w2) = (h / 2, w / 2, h / 4, w / 4);
            let x = vec![0.1f32; (h + 2) * (w + 2) * 3];
            let mut r1 = vec![0.0f32; (h1 + 2) * (w1 + 2) * C1];
            let mut r2 = vec![0.0f32; (h2 + 2) * (w2 + 2) * C2];
            let mut r3 = r2.clone();
            let t1 = fastest_of(&mut || c1.run::<2>(&x, w, &mut r1, h1, w1));
            let t2 = fastest_of(&mut || c2.run::<2>(&r1, w1, &mut r2, h2, w2));
            let t3 = fastest_of(&mut || c3.run::<1>(&r2, w2, &mut r3, h2, w2));
            for (name, t, macs) in [
                ("conv1", t1, h1 * w1 * C1 * 27),
                ("conv2", t2, h2 * w2 * C2 * C1 * 9),
                ("conv3", t3, h2 * w2 * C2 * C2 * 9),
            ] {
                println!("  {name}: {t:.2} ms, {:.1} GMAC/s", macs as f64 / t / 1e6);
            }
        }
    }
    let sum: f64 = best.values().map(|v| v.1).sum();
    println!("fastest pass {total:.2} ms; sum of the nodes' fastest {sum:.2} ms");
    for (id, (name, t)) in best {
        if t > 0.05 {
            println!("{id:3} {name:50} {t:7.2} ms");
        }
    }
    Ok(())
}
