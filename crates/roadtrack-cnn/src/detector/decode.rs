//! Detector outputs → boxes: the output layouts (YOLO, transposed YOLO, YOLOX, DETR), the
//! score threshold, class-wise non-maximum suppression, the letterbox geometry and its
//! undoing, and COCO classes → roadtrack classes.

use roadtrack::class::ObjectClass;
use roadtrack::geometry::BBox;
use serde::{Deserialize, Serialize};

/// How the model's outputs are laid out (`--layout`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Layout {
    /// Tell from the outputs: two outputs `[1, Q, 4]` + `[1, Q, K]` are DETR; one
    /// `[1, A, B]` is transposed YOLO when `A` is 4 + the number of class names `C`, YOLOX
    /// when `B` is `5 + C`, YOLO when `B` is `4 + C`, else transposed YOLO when `A < B`
    /// and YOLO otherwise.
    #[default]
    Auto,
    /// One output `[1, N, 4+C]`: `cx, cy, w, h` in input px, then C class scores.
    Yolo,
    /// One output `[1, 4+C, N]` (ultralytics' default export): YOLO transposed.
    YoloT,
    /// One output `[1, N, 5+C]`: `cx, cy, w, h` in input px, objectness, C class scores;
    /// score = objectness × class score.
    Yolox,
    /// Two outputs: boxes `[1, Q, 4]` (`cx, cy, w, h` normalised to the input) and class
    /// logits `[1, Q, K]` (see `DetrScores`).
    Detr,
}

impl Layout {
    /// The layout's name as the flag spells it.
    pub fn name(self) -> &'static str {
        match self {
            Layout::Auto => "auto",
            Layout::Yolo => "yolo",
            Layout::YoloT => "yolo-t",
            Layout::Yolox => "yolox",
            Layout::Detr => "detr",
        }
    }
}

/// How DETR class logits become scores.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum DetrScores {
    /// Independent sigmoid per class (RT-DETR, D-FINE, Deformable DETR).
    #[default]
    Sigmoid,
    /// Softmax over the K logits, whose last column is "no object" (the original DETR).
    Softmax,
}

/// One model output: its shape and values (row-major).
#[derive(Debug, Clone, PartialEq)]
pub struct RawOutput {
    /// Dims.
    pub shape: Vec<usize>,
    /// Values, row-major.
    pub values: Vec<f32>,
}

/// A decoded box in model-input px, before NMS and the letterbox undo.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate {
    /// Centre x, input px.
    pub cx: f64,
    /// Centre y, input px.
    pub cy: f64,
    /// Width, input px.
    pub w: f64,
    /// Height, input px.
    pub h: f64,
    /// Model class index.
    pub class: usize,
    /// Confidence in `[0, 1]`.
    pub score: f64,
    /// The learned detector's box gain reads this box at its size times this: 2 on the
    /// zoomed level, whose boxes the network saw twice as large; 1 elsewhere, the shrunk
    /// pyramid level included, whose boxes the gain's fit saw at frame size (docs/
    /// DETECTION.md "Box gain", "Zoom").
    pub gain_scale: f64,
}

impl Candidate {
    fn corners(&self) -> [f64; 4] {
        [
            self.cx - self.w / 2.0,
            self.cy - self.h / 2.0,
            self.cx + self.w / 2.0,
            self.cy + self.h / 2.0,
        ]
    }

    /// Area of the overlap of two boxes.
    fn intersection(&self, other: &Candidate) -> f64 {
        let [a0, a1, a2, a3] = self.corners();
        let [b0, b1, b2, b3] = other.corners();
        let iw = (a2.min(b2) - a0.max(b0)).max(0.0);
        let ih = (a3.min(b3) - a1.max(b1)).max(0.0);
        iw * ih
    }

    /// The fraction of this box's area inside `other` (0 for an empty box).
    pub fn inside_fraction(&self, other: &Candidate) -> f64 {
        let area = self.w * self.h;
        if area > 0.0 {
            self.intersection(other) / area
        } else {
            0.0
        }
    }

    /// Intersection over union of two boxes.
    pub fn iou(&self, other: &Candidate) -> f64 {
        let inter = self.intersection(other);
        let union = self.w * self.h + other.w * other.h - inter;
        if union > 0.0 { inter / union } else { 0.0 }
    }
}

fn shapes_text(outputs: &[Vec<usize>]) -> String {
    outputs
        .iter()
        .map(|s| format!("{s:?}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// `[1, a, b]` of a rank-3, batch-1 shape.
fn rank3(shape: &[usize]) -> Option<(usize, usize)> {
    match shape {
        [1, a, b] => Some((*a, *b)),
        _ => None,
    }
}

/// The DETR boxes and logits outputs' indices when `shapes` are `[1, Q, 4]` + `[1, Q, K]`.
fn detr_outputs(shapes: &[Vec<usize>]) -> Option<(usize, usize)> {
    let [s0, s1] = shapes else { return None };
    let (q0, k0) = rank3(s0)?;
    let (q1, k1) = rank3(s1)?;
    if q0 != q1 || q0 == 0 {
        return None;
    }
    // Choice: when both outputs end in 4, the first is the boxes (4 classes with DETR is
    // rare; the exporters name boxes first or second, so a later `logits`-only 4-class
    // model can set the layout explicitly and still hit this order).
    match (k0, k1) {
        (4, k) if k >= 1 => Some((0, 1)),
        (k, 4) if k >= 1 => Some((1, 0)),
        _ => None,
    }
}

/// The layout of outputs of `shapes`: `layout` checked against them, or (for
/// [`Layout::Auto`]) the one they fit. `names` is the number of class names, which tells
/// YOLOX (`5 + names` columns) from YOLO.
///
/// # Errors
/// A message listing the shapes found when they fit no (or not the given) layout.
pub fn resolve_layout(
    layout: Layout,
    shapes: &[Vec<usize>],
    names: usize,
) -> std::result::Result<Layout, String> {
    let found = shapes_text(shapes);
    let first = shapes.first().and_then(|s| rank3(s));
    let fits = |l: Layout| match l {
        Layout::Auto => false,
        Layout::Detr => detr_outputs(shapes).is_some(),
        Layout::Yolo => first.is_some_and(|(n, w)| n >= 1 && w >= 5),
        Layout::YoloT => first.is_some_and(|(w, n)| n >= 1 && w >= 5),
        Layout::Yolox => first.is_some_and(|(n, w)| n >= 1 && w >= 6),
    };
    let chosen = match layout {
        Layout::Auto => {
            if detr_outputs(shapes).is_some() {
                Some(Layout::Detr)
            } else if let Some((a, b)) = first {
                // By the class count first (4 + C or 5 + C columns), then by which side is
                // longer (anchors outnumber columns in every real export).
                let by_count = if a == 4 + names && b != 4 + names && b != 5 + names {
                    Some(Layout::YoloT)
                } else if b == 5 + names {
                    Some(Layout::Yolox)
                } else if b == 4 + names {
                    Some(Layout::Yolo)
                } else if a < b {
                    Some(Layout::YoloT)
                } else {
                    Some(Layout::Yolo)
                };
                by_count.filter(|l| fits(*l))
            } else {
                None
            }
        }
        l => fits(l).then_some(l),
    };
    chosen.ok_or_else(|| {
        let what = if layout == Layout::Auto {
            "not a detector output layout roadtrack knows".to_owned()
        } else {
            format!("the outputs do not fit --layout {}", layout.name())
        };
        format!(
            "{what}: outputs {found} (expected YOLO [1, N, 4+C] or [1, 4+C, N], YOLOX \
             [1, N, 5+C], or DETR boxes [1, Q, 4] + logits [1, Q, C]; see docs/DETECTION.md)"
        )
    })
}

fn sigmoid(x: f64) -> f64 {
    1.0 / (1.0 + (-x).exp())
}

/// The best class and its score among `scores` (first index on ties).
fn best(scores: impl Iterator<Item = f64>) -> Option<(usize, f64)> {
    scores.enumerate().filter(|(_, s)| s.is_finite()).fold(
        None,
        |acc: Option<(usize, f64)>, (i, s)| match acc {
            Some((_, b)) if b >= s => acc,
            _ => Some((i, s)),
        },
    )
}

/// Decodes the outputs of `layout` (already resolved) into candidates with score ≥
/// `min_score`; `input_wh` is the model input size (DETR boxes are fractions of it).
/// Boxes with a non-finite value or no area are dropped.
pub fn decode(
    layout: Layout,
    outputs: &[RawOutput],
    input_wh: (usize, usize),
    detr_scores: DetrScores,
    min_score: f64,
) -> Vec<Candidate> {
    let mut out = Vec::new();
    let mut push = |b: [f64; 4], best: Option<(usize, f64)>| {
        let Some((class, score)) = best else { return };
        let c = Candidate {
            cx: b[0],
            cy: b[1],
            w: b[2],
            h: b[3],
            class,
            score: score.clamp(0.0, 1.0),
            gain_scale: 1.0,
        };
        if score >= min_score && b.iter().all(|v| v.is_finite()) && c.w > 0.0 && c.h > 0.0 {
            out.push(c);
        }
    };
    let value = |o: &RawOutput, i: usize| f64::from(o.values.get(i).copied().unwrap_or(f32::NAN));
    match layout {
        Layout::Yolo | Layout::Yolox => {
            let Some(o) = outputs.first() else { return out };
            let Some((n, w)) = rank3(&o.shape) else {
                return out;
            };
            let obj_cols = usize::from(layout == Layout::Yolox);
            for r in 0..n {
                let at = |k: usize| value(o, r * w + k);
                let obj = if obj_cols == 1 { at(4) } else { 1.0 };
                let scores = (4 + obj_cols..w).map(|k| obj * at(k));
                push([at(0), at(1), at(2), at(3)], best(scores));
            }
        }
        Layout::YoloT => {
            let Some(o) = outputs.first() else { return out };
            let Some((w, n)) = rank3(&o.shape) else {
                return out;
            };
            for r in 0..n {
                let at = |k: usize| value(o, k * n + r);
                push([at(0), at(1), at(2), at(3)], best((4..w).map(at)));
            }
        }
        Layout::Detr => {
            let shapes: Vec<Vec<usize>> = outputs.iter().map(|o| o.shape.clone()).collect();
            let Some((bi, li)) = detr_outputs(&shapes) else {
                return out;
            };
            let (boxes, logits) = (&outputs[bi], &outputs[li]);
            let q = boxes.shape[1];
            let k = logits.shape[2];
            let (iw, ih) = (input_wh.0 as f64, input_wh.1 as f64);
            for r in 0..q {
                let l = |c: usize| value(logits, r * k + c);
                let scored = match detr_scores {
                    DetrScores::Sigmoid => best((0..k).map(|c| sigmoid(l(c)))),
                    DetrScores::Softmax => {
                        let max = (0..k).map(l).fold(f64::NEG_INFINITY, f64::max);
                        let sum: f64 = (0..k).map(|c| (l(c) - max).exp()).sum();
                        // The last column is "no object".
                        best((0..k.saturating_sub(1)).map(|c| (l(c) - max).exp() / sum))
                    }
                };
                let b = |c: usize| value(boxes, r * 4 + c);
                push([b(0) * iw, b(1) * ih, b(2) * iw, b(3) * ih], scored);
            }
        }
        Layout::Auto => {}
    }
    out
}

/// Class-wise greedy non-maximum suppression: by descending score (earlier first on ties),
/// a box is dropped when its IoU with a kept box of the same class exceeds `iou_threshold`.
/// At most `max` boxes are kept.
pub fn nms(mut candidates: Vec<Candidate>, iou_threshold: f64, max: usize) -> Vec<Candidate> {
    // A stable sort keeps the output order of equal scores: deterministic.
    candidates.sort_by(|a, b| b.score.total_cmp(&a.score));
    let mut kept: Vec<Candidate> = Vec::new();
    for c in candidates {
        if kept.len() >= max {
            break;
        }
        if kept
            .iter()
            .all(|k| k.class != c.class || k.iou(&c) <= iou_threshold)
        {
            kept.push(c);
        }
    }
    kept
}

/// Where the frame sits in the model input: input px = image px · scale + offset.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placement {
    /// Input px per image px along x and y.
    pub scale: (f64, f64),
    /// Input px of the frame's left/top edge.
    pub offset: (f64, f64),
    /// The resized frame's size in the input, px.
    pub size: (usize, usize),
}

impl Placement {
    /// Letterbox: the frame `image_wh` scaled by `min(W/w, H/h)` keeping its aspect,
    /// rounded to whole input px, placed centred (or top-left) in `input_wh`. `stretch`
    /// scales each axis to fill the input instead.
    pub fn new(
        image_wh: (u32, u32),
        input_wh: (usize, usize),
        stretch: bool,
        top_left: bool,
    ) -> Self {
        let (w, h) = (f64::from(image_wh.0.max(1)), f64::from(image_wh.1.max(1)));
        let (iw, ih) = input_wh;
        let (nw, nh) = if stretch {
            (iw, ih)
        } else {
            let r = (iw as f64 / w).min(ih as f64 / h);
            (
                ((w * r).round() as usize).clamp(1, iw),
                ((h * r).round() as usize).clamp(1, ih),
            )
        };
        let offset = if top_left {
            (0, 0)
        } else {
            ((iw - nw) / 2, (ih - nh) / 2)
        };
        Self {
            scale: (nw as f64 / w, nh as f64 / h),
            offset: (offset.0 as f64, offset.1 as f64),
            size: (nw, nh),
        }
    }

    /// The candidate's box in image px, clipped to the `image_wh` frame; `None` when
    /// nothing of it is inside.
    pub fn to_image(&self, c: &Candidate, image_wh: (u32, u32)) -> Option<BBox> {
        let [x0, y0, x1, y1] = c.corners();
        let (sx, sy) = self.scale;
        let (ox, oy) = self.offset;
        let (w, h) = (f64::from(image_wh.0), f64::from(image_wh.1));
        let left = ((x0 - ox) / sx).clamp(0.0, w);
        let right = ((x1 - ox) / sx).clamp(0.0, w);
        let top = ((y0 - oy) / sy).clamp(0.0, h);
        let bottom = ((y1 - oy) / sy).clamp(0.0, h);
        (right > left && bottom > top).then(|| BBox::new(left, top, right - left, bottom - top))
    }
}

/// The 80 COCO class names in the order YOLO/YOLOX/RT-DETR/D-FINE exports number them.
pub const COCO80: [&str; 80] = [
    "person",
    "bicycle",
    "car",
    "motorcycle",
    "airplane",
    "bus",
    "train",
    "truck",
    "boat",
    "traffic light",
    "fire hydrant",
    "stop sign",
    "parking meter",
    "bench",
    "bird",
    "cat",
    "dog",
    "horse",
    "sheep",
    "cow",
    "elephant",
    "bear",
    "zebra",
    "giraffe",
    "backpack",
    "umbrella",
    "handbag",
    "tie",
    "suitcase",
    "frisbee",
    "skis",
    "snowboard",
    "sports ball",
    "kite",
    "baseball bat",
    "baseball glove",
    "skateboard",
    "surfboard",
    "tennis racket",
    "bottle",
    "wine glass",
    "cup",
    "fork",
    "knife",
    "spoon",
    "bowl",
    "banana",
    "apple",
    "sandwich",
    "orange",
    "broccoli",
    "carrot",
    "hot dog",
    "pizza",
    "donut",
    "cake",
    "chair",
    "couch",
    "potted plant",
    "bed",
    "dining table",
    "toilet",
    "tv",
    "laptop",
    "mouse",
    "remote",
    "keyboard",
    "cell phone",
    "microwave",
    "oven",
    "toaster",
    "sink",
    "refrigerator",
    "book",
    "clock",
    "vase",
    "scissors",
    "teddy bear",
    "hair drier",
    "toothbrush",
];

/// The roadtrack class of a COCO class name: person → pedestrian, bicycle, car,
/// motorcycle, bus, truck; `None` for the others.
pub fn road_class(name: &str) -> Option<ObjectClass> {
    match name.trim().to_ascii_lowercase().as_str() {
        "person" | "pedestrian" => Some(ObjectClass::Pedestrian),
        "bicycle" => Some(ObjectClass::Bicycle),
        "car" => Some(ObjectClass::Car),
        "motorcycle" | "motorbike" => Some(ObjectClass::Motorcycle),
        "bus" => Some(ObjectClass::Bus),
        "truck" => Some(ObjectClass::Truck),
        _ => None,
    }
}

/// Parses a `--classes` mapping `INDEX=CLASS,…` (e.g. `0=pedestrian,2=car,7=truck`):
/// model class index → roadtrack class (any word; the known ones as `ObjectClass` spells
/// them).
///
/// # Errors
/// A message naming the bad item.
pub fn parse_class_map(text: &str) -> std::result::Result<Vec<(usize, ObjectClass)>, String> {
    let mut map = Vec::new();
    for item in text.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        let (index, class) = item
            .split_once('=')
            .ok_or_else(|| format!("`{item}`: expected INDEX=CLASS, e.g. 0=pedestrian"))?;
        let index: usize = index
            .trim()
            .parse()
            .map_err(|_| format!("`{item}`: `{}` is not a class index", index.trim()))?;
        let class: ObjectClass = class.trim().parse().unwrap_or_default();
        if class == ObjectClass::Unknown {
            return Err(format!("`{item}`: no class name after `=`"));
        }
        if map.iter().any(|(i, _)| *i == index) {
            return Err(format!("`{item}`: class index {index} given twice"));
        }
        map.push((index, class));
    }
    if map.is_empty() {
        return Err("no INDEX=CLASS item".into());
    }
    Ok(map)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cand(cx: f64, class: usize, score: f64) -> Candidate {
        Candidate {
            cx,
            cy: 10.0,
            w: 10.0,
            h: 10.0,
            class,
            score,
            gain_scale: 1.0,
        }
    }

    #[test]
    fn nms_is_class_wise_and_keeps_the_best() {
        let kept = nms(
            vec![
                cand(10.0, 0, 0.5),
                cand(11.0, 0, 0.9),
                cand(10.0, 1, 0.4),
                cand(40.0, 0, 0.3),
            ],
            0.45,
            10,
        );
        let got: Vec<(f64, usize)> = kept.iter().map(|c| (c.cx, c.class)).collect();
        assert_eq!(got, vec![(11.0, 0), (10.0, 1), (40.0, 0)]);
        assert_eq!(
            nms(vec![cand(10.0, 0, 0.5), cand(40.0, 0, 0.3)], 0.45, 1).len(),
            1
        );
    }

    #[test]
    fn letterbox_places_and_undoes_exactly() {
        // 128×64 frame into 64×64: scale ½, 32 rows high, 16 rows of padding above.
        let p = Placement::new((128, 64), (64, 64), false, false);
        assert_eq!(
            (p.scale, p.offset, p.size),
            ((0.5, 0.5), (0.0, 16.0), (64, 32))
        );
        let b = p
            .to_image(
                &Candidate {
                    cx: 32.0,
                    cy: 32.0,
                    w: 16.0,
                    h: 8.0,
                    class: 0,
                    score: 1.0,
                    gain_scale: 1.0,
                },
                (128, 64),
            )
            .expect("inside");
        assert_eq!((b.left, b.top, b.width, b.height), (48.0, 24.0, 32.0, 16.0));
        // A box reaching into the padding is clipped to the frame.
        let edge = Candidate {
            cx: 4.0,
            cy: 16.0,
            w: 16.0,
            h: 16.0,
            class: 0,
            score: 1.0,
            gain_scale: 1.0,
        };
        let b = p.to_image(&edge, (128, 64)).expect("partly inside");
        assert_eq!((b.left, b.top, b.width, b.height), (0.0, 0.0, 24.0, 16.0));
        let top_left = Placement::new((128, 64), (64, 64), false, true);
        assert_eq!(top_left.offset, (0.0, 0.0));
        let stretch = Placement::new((128, 64), (64, 64), true, false);
        assert_eq!((stretch.scale, stretch.size), ((0.5, 1.0), (64, 64)));
    }

    #[test]
    fn auto_layout_by_shapes_and_unknown_ones_named() {
        let s = |v: &[&[usize]]| v.iter().map(|s| s.to_vec()).collect::<Vec<_>>();
        let r = |l, v: &[&[usize]]| resolve_layout(l, &s(v), 80);
        assert_eq!(r(Layout::Auto, &[&[1, 8400, 84]]), Ok(Layout::Yolo));
        assert_eq!(r(Layout::Auto, &[&[1, 84, 8400]]), Ok(Layout::YoloT));
        assert_eq!(r(Layout::Auto, &[&[1, 8400, 85]]), Ok(Layout::Yolox));
        // Few anchors: the class count decides.
        assert_eq!(r(Layout::Auto, &[&[1, 84, 6]]), Ok(Layout::YoloT));
        assert_eq!(r(Layout::Auto, &[&[1, 6, 84]]), Ok(Layout::Yolo));
        assert_eq!(r(Layout::Auto, &[&[1, 9, 300]]), Ok(Layout::YoloT));
        assert_eq!(
            r(Layout::Auto, &[&[1, 300, 80], &[1, 300, 4]]),
            Ok(Layout::Detr)
        );
        assert_eq!(r(Layout::Yolo, &[&[1, 8400, 85]]), Ok(Layout::Yolo));
        let err = r(Layout::Auto, &[&[1, 2]]).expect_err("classifier");
        assert!(
            err.contains("[1, 2]") && err.contains("not a detector"),
            "{err}"
        );
        let err = r(Layout::Detr, &[&[1, 8400, 84]]).expect_err("one output");
        assert!(err.contains("--layout detr"), "{err}");
    }

    #[test]
    fn class_maps_parse_and_reject_nonsense() {
        let m = parse_class_map("0=person, 2=car,5=tram").expect("ok");
        assert_eq!(
            m,
            vec![
                (0, ObjectClass::Pedestrian),
                (2, ObjectClass::Car),
                (5, ObjectClass::Other("tram".into()))
            ]
        );
        for bad in ["", "x=car", "0car", "0=", "1=car,1=bus"] {
            assert!(parse_class_map(bad).is_err(), "{bad}");
        }
        assert_eq!(road_class(COCO80[7]), Some(ObjectClass::Truck));
        assert_eq!(road_class("dog"), None);
    }

    #[test]
    fn detr_softmax_ignores_the_no_object_column() {
        let boxes = RawOutput {
            shape: vec![1, 2, 4],
            values: vec![0.5, 0.5, 0.25, 0.5, 0.1, 0.1, 0.1, 0.1],
        };
        // Query 0: class 1 wins; query 1: "no object" (last) wins, class 0 weak.
        let logits = RawOutput {
            shape: vec![1, 2, 3],
            values: vec![0.0, 3.0, 0.0, 0.0, 0.0, 5.0],
        };
        let c = decode(
            Layout::Detr,
            &[boxes, logits],
            (100, 50),
            DetrScores::Softmax,
            0.5,
        );
        assert_eq!(c.len(), 1);
        assert_eq!(
            (c[0].cx, c[0].cy, c[0].w, c[0].h, c[0].class),
            (50.0, 25.0, 25.0, 25.0, 1)
        );
        let e3 = 3f64.exp();
        assert!((c[0].score - e3 / (e3 + 2.0)).abs() < 1e-9);
    }
}
