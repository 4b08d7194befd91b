use super::*;

const FIXTURE: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/tests/fixtures/tiny_classifier.onnx"
);
const REFERENCE: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/tests/fixtures/tiny_classifier_ref.json"
);

fn tiny() -> OnnxClassifier {
    OnnxClassifier::load(Path::new(FIXTURE), &CnnConfig::default()).expect("fixture loads")
}

fn textured(w: u32, h: u32) -> RgbImage {
    RgbImage::from_fn(w, h, |x, y| {
        let v = (x * 37 + y * 91 + (x * y) % 53) % 256;
        image::Rgb([
            v as u8,
            ((v * 3 + y) % 256) as u8,
            ((x * 7 + 11) % 256) as u8,
        ])
    })
}

#[test]
fn tract_matches_onnxruntime_on_the_tiny_model() -> Result<()> {
    let reference: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(REFERENCE).map_err(|e| Error::io(REFERENCE, e))?,
    )
    .map_err(|e| Error::Invalid(e.to_string()))?;
    let expected = reference["output"].as_array().expect("output array");
    let model = tiny();
    assert_eq!(model.input_size(), (32, 16));
    let per = 3 * 32 * 16;
    for (n, row) in expected.iter().enumerate() {
        let input: Vec<f32> = (0..per)
            .map(|k| {
                let i = (n * per + k) as i64;
                (((i * 37 + 11) % 101) as f64 / 50.0 - 1.0) as f32
            })
            .collect();
        let got = model.raw_outputs(&input)?;
        let want: Vec<f64> = row
            .as_array()
            .expect("row")
            .iter()
            .filter_map(|v| v.as_f64())
            .collect();
        assert_eq!(got.len(), want.len());
        for (g, w) in got.iter().zip(&want) {
            assert!(
                (f64::from(*g) - w).abs() < 1e-5,
                "tract {g} vs onnxruntime {w}"
            );
        }
    }
    Ok(())
}

#[test]
fn dense_lookup_equals_window_scores_at_grid_points() -> Result<()> {
    let model = tiny();
    let img = textured(61, 47);
    for stride in [4, 8] {
        let map = model.score_map(&img, stride)?;
        assert_eq!(map.stride_px, f64::from(stride));
        assert!(map.cols as f64 * map.stride_px >= 61.0);
        let mut centres = Vec::new();
        for i in 0..map.rows {
            for j in 0..map.cols {
                centres.push(map.cell_centre_px(i, j));
            }
        }
        let mut direct = vec![0.0; centres.len()];
        model.score_windows(&img, &centres, &mut direct)?;
        for (c, d) in centres.iter().zip(&direct) {
            let dense = map.sample(*c);
            assert!(
                (dense - d).abs() < 1e-5,
                "at {c:?}: dense {dense} vs window {d}"
            );
        }
        // The scores vary over the image, so the comparison is not vacuous.
        let (lo, hi) = direct
            .iter()
            .fold((1.0f64, 0.0f64), |(l, h), &v| (l.min(v), h.max(v)));
        assert!(hi - lo > 1e-3, "scores are flat: {lo}..{hi}");
    }
    Ok(())
}

#[test]
fn dense_bands_give_the_same_map_as_one_pass() -> Result<()> {
    let model = tiny();
    let img = textured(45, 70);
    let one = model.score_map_in_bands(&img, 4, 1000)?;
    for rows in [1, 3, 7] {
        let banded = model.score_map_in_bands(&img, 4, rows)?;
        assert_eq!((banded.cols, banded.rows), (one.cols, one.rows));
        for (a, b) in banded.values.iter().zip(&one.values) {
            assert!((a - b).abs() < 1e-6, "{rows} rows: {a} vs {b}");
        }
    }
    Ok(())
}

#[test]
fn dense_mode_is_exact_with_a_window_scale_too() -> Result<()> {
    let cfg = CnnConfig {
        window_scale: Some(1.5),
        ..Default::default()
    };
    let model = OnnxClassifier::load(Path::new(FIXTURE), &cfg)?;
    let img = textured(50, 40);
    let map = model.score_map(&img, 6)?;
    assert_eq!(map.stride_px, 6.0);
    let centres: Vec<Point> = (0..map.cols).map(|j| map.cell_centre_px(2, j)).collect();
    let mut direct = vec![0.0; centres.len()];
    model.score_windows(&img, &centres, &mut direct)?;
    for (c, d) in centres.iter().zip(&direct) {
        assert!((map.sample(*c) - d).abs() < 1e-5);
    }
    Ok(())
}

#[test]
fn window_scores_do_not_depend_on_the_thread_count() -> Result<()> {
    let model = tiny();
    let img = textured(40, 30);
    let centres: Vec<Point> = (0..40)
        .map(|i| Point::new(i as f64 * 1.3, 29.0 - i as f64 * 0.7))
        .collect();
    let mut a = vec![0.0; 40];
    model.score_windows(&img, &centres, &mut a)?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("pool");
    let mut b = vec![0.0; 40];
    pool.install(|| model.score_windows(&img, &centres, &mut b))?;
    assert_eq!(a, b);
    Ok(())
}

#[test]
fn wrong_files_are_rejected_with_the_file_named() {
    let dir = tempfile::tempdir().expect("tempdir");
    let text = dir.path().join("notes.onnx");
    std::fs::write(&text, "this is not a model\n").expect("write");
    let err = OnnxClassifier::load(&text, &CnnConfig::default()).expect_err("text");
    assert!(err.to_string().contains("notes.onnx"), "{err}");

    // Wrong input rank: the tiny model's graph with a rank-2 input.
    let mut proto = tiny().proto.clone();
    if let Some(pb::type_proto::Value::TensorType(t)) = proto
        .graph
        .as_mut()
        .and_then(|g| g.input[0].r#type.as_mut().and_then(|t| t.value.as_mut()))
        && let Some(s) = t.shape.as_mut()
    {
        s.dim.truncate(2);
    }
    let rank = dir.path().join("rank2.onnx");
    std::fs::write(&rank, prost::Message::encode_to_vec(&proto)).expect("write");
    let err = OnnxClassifier::load(&rank, &CnnConfig::default()).expect_err("rank");
    let msg = err.to_string();
    assert!(
        msg.contains("rank2.onnx") && msg.contains("rank 2"),
        "{msg}"
    );

    // Missing output.
    let mut proto = tiny().proto.clone();
    if let Some(g) = proto.graph.as_mut() {
        g.output.clear();
    }
    let noout = dir.path().join("noout.onnx");
    std::fs::write(&noout, prost::Message::encode_to_vec(&proto)).expect("write");
    let err = OnnxClassifier::load(&noout, &CnnConfig::default()).expect_err("no output");
    let msg = err.to_string();
    assert!(
        msg.contains("noout.onnx") && msg.contains("no output"),
        "{msg}"
    );

    // Target class beyond the outputs.
    let cfg = CnnConfig {
        target_class: Some(5),
        ..Default::default()
    };
    let err = OnnxClassifier::load(Path::new(FIXTURE), &cfg).expect_err("class");
    assert!(err.to_string().contains("tiny_classifier.onnx"));

    let missing = dir.path().join("absent.onnx");
    let err = OnnxClassifier::load(&missing, &CnnConfig::default()).expect_err("absent");
    assert!(err.to_string().contains("absent.onnx"));
}

#[test]
fn output_kinds_turn_outputs_into_probabilities() {
    assert_eq!(
        class_probability(&[0.2, 0.8], 1, OutputKind::Probabilities),
        0.8f32 as f64
    );
    let p = class_probability(&[0.0, 2.0_f32.ln()], 1, OutputKind::Softmax);
    assert!((p - 2.0 / 3.0).abs() < 1e-6);
    let s = class_probability(&[0.0], 0, OutputKind::Sigmoid);
    assert!((s - 0.5).abs() < 1e-12);
    assert_eq!(class_probability(&[0.5], 3, OutputKind::Probabilities), 0.0);
}
