//! Dense mode: the classifier's `GlobalAveragePool → Flatten → Gemm` head rewritten as
//! `AveragePool → 1×1 Conv`, one pass over the frame for every window on a grid.

use super::*;

/// The affine head of a classifier that dense mode turns into a 1×1 convolution.
#[derive(Debug, Clone)]
pub(super) struct DenseHead {
    /// Nodes of the backbone (everything before the global average pool).
    backbone: Vec<pb::NodeProto>,
    /// Tensor feeding the global average pool.
    features: String,
    /// Gemm weights as `[classes][features]`.
    weight: Vec<f32>,
    /// Gemm bias, one per class.
    bias: Vec<f32>,
    classes: usize,
    n_features: usize,
    /// The activation the model applied after the Gemm, if any.
    activation: Option<OutputKind>,
    /// Feature-map size of one window, `(height, width)`.
    feature_size: (usize, usize),
    /// Input pixels per feature cell.
    net_stride: usize,
}

impl OnnxClassifier {
    /// Finds (once) and returns the classifier's affine head for dense mode.
    fn dense_head(&self) -> Result<Arc<DenseHead>> {
        let mut guard = self
            .head
            .lock()
            .map_err(|_| Error::Invalid("dense head lock poisoned".into()))?;
        if guard.is_none() {
            *guard = Some(self.find_dense_head().map(Arc::new));
        }
        match guard.as_ref() {
            Some(Ok(h)) => Ok(h.clone()),
            Some(Err(msg)) => Err(model_error(&self.path, msg)),
            None => Err(Error::Invalid("dense head missing".into())),
        }
    }

    fn find_dense_head(&self) -> std::result::Result<DenseHead, String> {
        const NEEDS: &str = "dense mode needs a `GlobalAveragePool → Flatten → Gemm [→ Softmax|Sigmoid]` head; use per-window scoring";
        let graph = self.proto.graph.as_ref().ok_or("no graph")?;
        let nodes = &graph.node;
        let consumers = |name: &str| -> Vec<usize> {
            (0..nodes.len())
                .filter(|&i| nodes[i].input.iter().any(|x| x == name))
                .collect()
        };
        let gap = nodes
            .iter()
            .rposition(|n| n.op_type == "GlobalAveragePool")
            .ok_or(NEEDS)?;
        let single = |name: &str| -> std::result::Result<usize, String> {
            match consumers(name).as_slice() {
                [i] => Ok(*i),
                _ => Err(NEEDS.to_string()),
            }
        };
        let flat = single(&nodes[gap].output[0])?;
        if !matches!(nodes[flat].op_type.as_str(), "Flatten" | "Reshape") {
            return Err(NEEDS.into());
        }
        let gemm = single(&nodes[flat].output[0])?;
        let g = &nodes[gemm];
        if g.op_type != "Gemm" || g.input.len() < 2 || g.input[0] != nodes[flat].output[0] {
            return Err(NEEDS.into());
        }
        let int_attr = |n: &str, d: i64| attr(g, n).map_or(d, |a| a.i);
        let float_attr = |n: &str, d: f32| attr(g, n).map_or(d, |a| a.f);
        if int_attr("transA", 0) != 0 || float_attr("alpha", 1.0) != 1.0 {
            return Err(format!("{NEEDS} (Gemm with transA/alpha not supported)"));
        }
        let init = |name: &str| graph.initializer.iter().find(|t| t.name == name);
        let b = init(&g.input[1]).ok_or(NEEDS)?;
        let bv = float_values(b).ok_or("Gemm weights are not float initializers")?;
        let (classes, n_features, weight) = match (b.dims.as_slice(), int_attr("transB", 0)) {
            ([c, f], 1) => (*c as usize, *f as usize, bv),
            ([f, c], 0) => {
                let (f, c) = (*f as usize, *c as usize);
                let mut t = vec![0.0; f * c];
                for i in 0..f {
                    for j in 0..c {
                        t[j * f + i] = bv[i * c + j];
                    }
                }
                (c, f, t)
            }
            _ => return Err("Gemm weights are not a matrix".into()),
        };
        let beta = float_attr("beta", 1.0);
        let bias = match g.input.get(2).filter(|s| !s.is_empty()) {
            Some(name) => {
                let c = init(name).ok_or(NEEDS)?;
                let v = float_values(c).ok_or("Gemm bias is not a float initializer")?;
                match v.len() {
                    1 => vec![v[0] * beta; classes],
                    n if n == classes => v.iter().map(|x| x * beta).collect(),
                    _ => return Err("Gemm bias does not broadcast per class".into()),
                }
            }
            None => vec![0.0; classes],
        };
        let activation = match consumers(&g.output[0]).as_slice() {
            [] => None,
            [i] if nodes[*i].op_type == "Softmax" => Some(OutputKind::Softmax),
            [i] if nodes[*i].op_type == "Sigmoid" => Some(OutputKind::Sigmoid),
            _ => return Err(NEEDS.into()),
        };
        let features = nodes[gap].input[0].clone();
        let backbone: Vec<pb::NodeProto> = nodes[..gap].to_vec();
        // Feature-map size of one window, and the stride, from tract's shape inference on
        // the backbone at two input sizes.
        let feature_hw = |h: usize, w: usize| -> std::result::Result<(usize, usize), String> {
            let proto = self.backbone_proto(&backbone, &features, &[], [1, 3, h, w]);
            let typed = tract_onnx::onnx()
                .model_for_proto_model(&proto)
                .and_then(|m| m.with_input_fact(0, f32::fact([1, 3, h, w]).into()))
                .and_then(|m| m.into_typed())
                .map_err(|e| format!("shape inference of the backbone failed: {e:#}"))?;
            let shape = typed
                .output_fact(0)
                .ok()
                .and_then(|f| f.shape.as_concrete().map(|s| s.to_vec()))
                .ok_or("backbone output shape is not fixed")?;
            match shape.as_slice() {
                [1, c, fh, fw] if *c == n_features => Ok((*fh, *fw)),
                _ => Err(format!(
                    "backbone output {shape:?} is not 1×{n_features}×h×w"
                )),
            }
        };
        let (fh, fw) = feature_hw(self.input_height, self.input_width)?;
        const GROW: usize = 256;
        let (fh2, fw2) = feature_hw(self.input_height + GROW, self.input_width + GROW)?;
        let (dh, dw) = (fh2.saturating_sub(fh), fw2.saturating_sub(fw));
        if dh == 0 || dh != dw || !GROW.is_multiple_of(dh) || fh == 0 || fw == 0 {
            return Err("cannot determine a whole-pixel network stride".into());
        }
        Ok(DenseHead {
            backbone,
            features,
            weight,
            bias,
            classes,
            n_features,
            activation,
            feature_size: (fh, fw),
            net_stride: GROW / dh,
        })
    }

    /// A model holding `backbone` + `extra` nodes with output `output`, fixed input dims.
    fn backbone_proto(
        &self,
        backbone: &[pb::NodeProto],
        output: &str,
        extra: &[(pb::NodeProto, Vec<pb::TensorProto>)],
        input: [usize; 4],
    ) -> pb::ModelProto {
        use pb::tensor_shape_proto::{Dimension, dimension::Value};
        let mut proto = self.proto.clone();
        if let Some(g) = proto.graph.as_mut() {
            g.node = backbone.to_vec();
            for (n, inits) in extra {
                g.node.push(n.clone());
                g.initializer.extend(inits.iter().cloned());
            }
            let initializers: Vec<String> = g.initializer.iter().map(|t| t.name.clone()).collect();
            for i in g.input.iter_mut() {
                if initializers.contains(&i.name) {
                    continue;
                }
                if let Some(pb::type_proto::Value::TensorType(t)) =
                    i.r#type.as_mut().and_then(|t| t.value.as_mut())
                {
                    t.shape = Some(pb::TensorShapeProto {
                        dim: input
                            .iter()
                            .map(|&d| Dimension {
                                value: Some(Value::DimValue(d as i64)),
                                ..Default::default()
                            })
                            .collect(),
                    });
                }
            }
            g.output = vec![pb::ValueInfoProto {
                name: output.to_string(),
                ..Default::default()
            }];
            g.value_info.clear();
        }
        proto
    }

    /// The dense plan for a `height × width` input and pool stride `k` (cached).
    fn dense_plan(
        &self,
        head: &DenseHead,
        height: usize,
        width: usize,
        k: usize,
    ) -> Result<DensePlan> {
        let key = (height, width, k);
        if let Some(p) = self
            .dense_plans
            .lock()
            .map_err(|_| Error::Invalid("dense plan lock poisoned".into()))?
            .get(&key)
        {
            return Ok(p.clone());
        }
        let pool = pb::NodeProto {
            input: vec![head.features.clone()],
            output: vec!["roadtrack_dense_pool".into()],
            name: "roadtrack_dense_pool".into(),
            op_type: "AveragePool".into(),
            attribute: vec![
                ints_attr("kernel_shape", &[head.feature_size.0, head.feature_size.1]),
                ints_attr("strides", &[k, k]),
            ],
            ..Default::default()
        };
        let w = float_tensor(
            "roadtrack_dense_w",
            &[head.classes, head.n_features, 1, 1],
            &head.weight,
        );
        let b = float_tensor("roadtrack_dense_b", &[head.classes], &head.bias);
        let conv = pb::NodeProto {
            input: vec![
                "roadtrack_dense_pool".into(),
                "roadtrack_dense_w".into(),
                "roadtrack_dense_b".into(),
            ],
            output: vec!["roadtrack_dense_logits".into()],
            name: "roadtrack_dense_head".into(),
            op_type: "Conv".into(),
            attribute: vec![ints_attr("kernel_shape", &[1, 1])],
            ..Default::default()
        };
        let proto = self.backbone_proto(
            &head.backbone,
            "roadtrack_dense_logits",
            &[(pool, vec![]), (conv, vec![w, b])],
            [1, 3, height, width],
        );
        let plan = tract_load(&proto, [1, 3, height, width])
            .map_err(|e| model_error(&self.path, format!("dense rewrite failed: {e:#}")))?;
        self.dense_plans
            .lock()
            .map_err(|_| Error::Invalid("dense plan lock poisoned".into()))?
            .insert(key, plan.clone());
        Ok(plan)
    }

    /// Dense mode: runs the network once over the whole frame and returns the target-class
    /// probability for windows centred on a grid of image positions.
    ///
    /// The grid starts at `(0, 0)` and covers the image (one cell beyond its right and
    /// bottom edges). Its stride is `network stride × pool step × window scale`, with the
    /// pool step `k = max(1, round(stride_px / (network stride × window scale)))`; the map
    /// says the stride actually used. At every grid point the value equals
    /// [`OnnxClassifier::score_windows`] for a classifier without padding (same samples,
    /// same border policy); between grid points [`ScoreMap::sample`] interpolates.
    ///
    /// # Errors
    /// When the model's head is not `GlobalAveragePool → Flatten → Gemm [→ activation]`.
    pub fn score_map(&self, image: &RgbImage, stride_px: u32) -> Result<ScoreMap> {
        let head = self.dense_head()?;
        let t = head.net_stride;
        let k = ((f64::from(stride_px) / (t as f64 * self.window_scale)).round() as usize).max(1);
        // Bands of about DENSE_BAND_PX input rows, so the window-height overlap between
        // bands stays a small fraction of the work.
        let band_rows = DENSE_BAND_PX.div_ceil(t * k).max(4);
        self.score_map_in_bands(image, stride_px, band_rows)
    }

    /// [`OnnxClassifier::score_map`] computed in horizontal bands of `band_rows` grid rows,
    /// one network pass per band, bands in parallel.
    ///
    /// Choice: the band height depends on the stride only (not on the thread count), so the
    /// tensors, and hence the values, do not depend on the thread count; tract runs one pass on one core, so bands
    /// are what uses the second core.
    pub(super) fn score_map_in_bands(
        &self,
        image: &RgbImage,
        stride_px: u32,
        band_rows: usize,
    ) -> Result<ScoreMap> {
        let head = self.dense_head()?;
        let s = self.window_scale;
        let t = head.net_stride;
        let k = ((f64::from(stride_px) / (t as f64 * s)).round() as usize).max(1);
        let step_px = (t * k) as f64 * s;
        let (iw, ih) = image.dimensions();
        let nx = (f64::from(iw) / step_px).ceil() as usize + 1;
        let ny = (f64::from(ih) / step_px).ceil() as usize + 1;
        let dw = (nx - 1) * t * k + self.input_width;
        // Dense pixel q samples image position (q − w/2 + 0.5)·s − 0.5 (see cut_window).
        let x0 = (0.5 - self.input_width as f64 / 2.0) * s - 0.5;
        let y0 = (0.5 - self.input_height as f64 / 2.0) * s - 0.5;
        let kind = head.activation.unwrap_or(self.output);
        let band_rows = band_rows.max(1);
        let bands: Vec<(usize, usize)> = (0..ny)
            .step_by(band_rows)
            .map(|r0| (r0, (r0 + band_rows).min(ny)))
            .collect();
        let band_values: Vec<Vec<f64>> = bands
            .par_iter()
            .map(|&(r0, r1)| -> Result<Vec<f64>> {
                let rows = r1 - r0;
                let dh = (rows - 1) * t * k + self.input_height;
                let plan = self.dense_plan(&head, dh, dw, k)?;
                let mut input = vec![0.0f32; 3 * dw * dh];
                let band_y0 = y0 + (r0 * t * k) as f64 * s;
                sample_grid(image, x0, band_y0, s, dw, dh, &self.prep, &mut input);
                let t_in =
                    Tensor::from_shape(&[1, 3, dh, dw], &input).map_err(|e| self.run_error(e))?;
                let out = plan
                    .run(tvec![t_in.into()])
                    .map_err(|e| self.run_error(e))?;
                let first = out.first().ok_or_else(|| self.run_error("no output"))?;
                let view = first
                    .to_plain_array_view::<f32>()
                    .map_err(|e| self.run_error(e))?;
                let shape = view.shape().to_vec();
                let [1, c, oh, ow] = shape.as_slice() else {
                    return Err(self.run_error(format!("dense output shape {shape:?}")));
                };
                let (c, oh, ow) = (*c, *oh, *ow);
                if oh < rows || ow < nx {
                    return Err(self.run_error(format!(
                        "dense output {oh}×{ow} is smaller than the grid {rows}×{nx}"
                    )));
                }
                let data: Vec<f32> = view.iter().copied().collect();
                let mut values = Vec::with_capacity(rows * nx);
                let mut logits = vec![0.0f32; c];
                for i in 0..rows {
                    for j in 0..nx {
                        for (ch, l) in logits.iter_mut().enumerate() {
                            *l = data[(ch * oh + i) * ow + j];
                        }
                        values.push(class_probability(&logits, self.target_class, kind));
                    }
                }
                Ok(values)
            })
            .collect::<Result<_>>()?;
        Ok(ScoreMap {
            origin_px: Point::new(0.0, 0.0),
            stride_px: step_px,
            cols: nx,
            rows: ny,
            values: band_values.concat(),
        })
    }
}

/// Dense-input rows per band, about (see `score_map_in_bands`). Choice: 256, two bands for
/// a 480-row frame, so both cores of the reference machine work on one frame.
const DENSE_BAND_PX: usize = 256;

fn ints_attr(name: &str, v: &[usize]) -> pb::AttributeProto {
    pb::AttributeProto {
        name: name.into(),
        r#type: pb::attribute_proto::AttributeType::Ints as i32,
        ints: v.iter().map(|&x| x as i64).collect(),
        ..Default::default()
    }
}

/// A float initializer.
pub(crate) fn float_tensor(name: &str, dims: &[usize], values: &[f32]) -> pb::TensorProto {
    pb::TensorProto {
        name: name.into(),
        dims: dims.iter().map(|&d| d as i64).collect(),
        data_type: pb::tensor_proto::DataType::Float as i32,
        raw_data: values.iter().flat_map(|v| v.to_le_bytes()).collect(),
        ..Default::default()
    }
}
