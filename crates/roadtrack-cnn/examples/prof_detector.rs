//! Per-operation time of an ONNX model in tract's optimised plan, single-threaded: where a
//! detector's inference goes (docs/PERFORMANCE.md "Where the learned detector's time goes").
//!
//!     cargo run --release -p roadtrack-cnn --example prof_detector -- models/detector.onnx [H W]
//!
//! With `NATIVE=1`: also the learned detector's network in roadtrack's own kernels (as the
//! detector runs it), whole and layer by layer, with each layer's GMAC/s.
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
    let native = std::env::var_os("NATIVE").is_some();
    let (proto, dims) = (
        pb::ModelProto::decode(std::fs::read(path)?.as_slice())?,
        [1, 3, h, w],
    );
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
    if native {
        use roadtrack_cnn::centernet::native::Isa;
        // `ISA=avx2` or `ISA=portable` caps the kernels' instruction set.
        let isa = match std::env::var("ISA").as_deref() {
            Ok("avx2") => Isa::Avx2,
            Ok("portable") => Isa::Portable,
            _ => Isa::best(),
        };
        println!("instruction set: {isa:?}");
        // The same pass in roadtrack's kernels: the fastest of 30, whole and per step.
        let net = roadtrack_cnn::centernet::read_weights(std::path::Path::new(path))?;
        let Some(nn) = roadtrack_cnn::centernet::native::NativeNet::new(&net) else {
            return Err("not a network the native kernels run".into());
        };
        let x = vec![0.1f32; 3 * h * w];
        use roadtrack_cnn::centernet::native::channels_last;
        let steps = roadtrack_cnn::centernet::native::STEPS;
        let mut step_best = vec![f64::MAX; steps.len()];
        let mut fastest = f64::MAX;
        for _ in 0..30 {
            let t0 = Instant::now();
            let mut last = t0;
            let mut k = 0;
            std::hint::black_box(nn.run_with(
                h,
                w,
                isa,
                &mut |b| channels_last(&x, h, w, b),
                &mut |_| {
                    let now = Instant::now();
                    step_best[k] = step_best[k].min((now - last).as_secs_f64() * 1e3);
                    last = now;
                    k += 1;
                },
            ));
            fastest = fastest.min(t0.elapsed().as_secs_f64() * 1e3);
        }
        // Each step's multiply-accumulates: conv1..conv7, up1, up2, head, heat + box.
        let layers = net.shape.layers();
        let mut macs = vec![0u64; steps.len()];
        let (mut ch, mut cw) = (h, w);
        for (i, l) in layers.iter().enumerate() {
            let step = (i + 1).min(11);
            match l.kind {
                roadtrack_cnn::centernet::LayerKind::Conv => {
                    ch = (ch + 2 * l.pad - l.k) / l.stride + 1;
                    cw = (cw + 2 * l.pad - l.k) / l.stride + 1;
                    macs[step] += (ch * cw * l.weight_len()) as u64;
                }
                roadtrack_cnn::centernet::LayerKind::Deconv => {
                    macs[step] += (ch * cw * l.weight_len()) as u64;
                    ch *= 2;
                    cw *= 2;
                }
            }
        }
        println!("native (roadtrack's kernels): fastest pass {fastest:.2} ms");
        for ((name, t), m) in steps.iter().zip(&step_best).zip(&macs) {
            let rate = if *m > 0 {
                format!(", {:.1} GMAC/s", *m as f64 / t / 1e6)
            } else {
                String::new()
            };
            println!("  {name:16} {t:6.2} ms{rate}");
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
