//! A tiny CNN classifier written by hand: forward and backward passes (im2col + sgemm on
//! `matrixmultiply`) and Adam, for `roadtrack train` (METHODS.md §3 "Classifier training").
//!
//! ```text
//! input 3×H×W → Conv3×3(3→c1, valid) → ReLU → MaxPool2 → Conv3×3(c1→c2, valid) → ReLU
//!   → MaxPool2 → GlobalAveragePool → Dense(c2→2) → Softmax      (class 1 = target)
//! ```
//!
//! Choice: the paper fine-tunes Inception v3's fully connected layers; a network that small
//! trains from scratch in seconds on a CPU and, having no padding, has an exact fully
//! convolutional form for dense mode (docs/CNN.md). Convolutions are unpadded ("valid") and
//! pooling floors, matching ONNX `Conv` without `pads` and `MaxPool` with the default
//! `ceil_mode = 0`, so the exported ONNX file computes exactly this network.

use rand_distr::{Distribution, Normal};

use roadtrack::rng::Rng;

/// `C = A·B + beta·C` for row-major-or-strided `f32` matrices, through `matrixmultiply`.
///
/// `a` is `m×k` with strides `(rsa, csa)`, `b` is `k×n` with `(rsb, csb)`, `c` is `m×n`
/// row-major.
///
/// # Panics
/// If a slice is too short for the shapes and strides given (checked before the call).
#[allow(unsafe_code, clippy::too_many_arguments)]
fn gemm(
    m: usize,
    k: usize,
    n: usize,
    a: &[f32],
    (rsa, csa): (usize, usize),
    b: &[f32],
    (rsb, csb): (usize, usize),
    beta: f32,
    c: &mut [f32],
) {
    if m == 0 || n == 0 {
        return;
    }
    let last = |rows: usize, cols: usize, rs: usize, cs: usize| {
        (rows.saturating_sub(1)) * rs + (cols.saturating_sub(1)) * cs
    };
    assert!(
        k == 0 || a.len() > last(m, k, rsa, csa),
        "gemm: A too short"
    );
    assert!(
        k == 0 || b.len() > last(k, n, rsb, csb),
        "gemm: B too short"
    );
    assert!(c.len() >= m * n, "gemm: C too short");
    // SAFETY: the asserts above show every index the kernel reads or writes, `i·rs + j·cs`
    // for i < rows, j < cols, lies inside the corresponding slice; `c` is exclusively
    // borrowed and does not alias `a` or `b`.
    unsafe {
        matrixmultiply::sgemm(
            m,
            k,
            n,
            1.0,
            a.as_ptr(),
            rsa as isize,
            csa as isize,
            b.as_ptr(),
            rsb as isize,
            csb as isize,
            beta,
            c.as_mut_ptr(),
            n as isize,
            1,
        );
    }
}

/// 3×3 im2col of a `c×h×w` tensor for an unpadded convolution: `(c·9) × (ho·wo)`.
fn im2col(x: &[f32], c: usize, h: usize, w: usize, cols: &mut Vec<f32>) {
    let (ho, wo) = (h - 2, w - 2);
    cols.clear();
    cols.resize(c * 9 * ho * wo, 0.0);
    for ch in 0..c {
        for ky in 0..3 {
            for kx in 0..3 {
                let row = (ch * 9 + ky * 3 + kx) * ho * wo;
                for y in 0..ho {
                    let src = ch * h * w + (y + ky) * w + kx;
                    cols[row + y * wo..row + (y + 1) * wo].copy_from_slice(&x[src..src + wo]);
                }
            }
        }
    }
}

/// Adds the im2col-shaped gradient back onto a `c×h×w` input gradient.
fn col2im(dcols: &[f32], c: usize, h: usize, w: usize, dx: &mut [f32]) {
    let (ho, wo) = (h - 2, w - 2);
    for ch in 0..c {
        for ky in 0..3 {
            for kx in 0..3 {
                let row = (ch * 9 + ky * 3 + kx) * ho * wo;
                for y in 0..ho {
                    let dst = ch * h * w + (y + ky) * w + kx;
                    for x in 0..wo {
                        dx[dst + x] += dcols[row + y * wo + x];
                    }
                }
            }
        }
    }
}

/// Shapes of the network for a given input size and widths.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shape {
    /// Input height, px.
    pub height: usize,
    /// Input width, px.
    pub width: usize,
    /// Channels of the first convolution.
    pub c1: usize,
    /// Channels of the second convolution.
    pub c2: usize,
}

impl Shape {
    fn conv1_out(&self) -> (usize, usize) {
        (self.height - 2, self.width - 2)
    }
    fn pool1_out(&self) -> (usize, usize) {
        let (h, w) = self.conv1_out();
        (h / 2, w / 2)
    }
    fn conv2_out(&self) -> (usize, usize) {
        let (h, w) = self.pool1_out();
        (h - 2, w - 2)
    }
    fn pool2_out(&self) -> (usize, usize) {
        let (h, w) = self.conv2_out();
        (h / 2, w / 2)
    }
    /// Whether the input is large enough for both conv/pool stages (at least 10×10).
    pub fn is_valid(&self) -> bool {
        self.height >= 10 && self.width >= 10 && self.c1 > 0 && self.c2 > 0
    }
    /// Number of parameters.
    pub fn n_params(&self) -> usize {
        self.c1 * 27 + self.c1 + self.c2 * self.c1 * 9 + self.c2 + 2 * self.c2 + 2
    }
}

/// The network's parameters, in one flat vector (the order of [`TinyCnn::views`]).
#[derive(Debug, Clone, PartialEq)]
pub struct TinyCnn {
    /// Input and channel sizes.
    pub shape: Shape,
    /// All parameters: conv1 weights `[c1][3][3][3]`, conv1 bias, conv2 weights
    /// `[c2][c1][3][3]`, conv2 bias, dense weights `[2][c2]`, dense bias.
    pub params: Vec<f32>,
}

/// Borrowed views of the parameter blocks.
#[derive(Debug)]
pub struct Views<'a> {
    /// Conv1 weights, `[c1][27]`.
    pub conv1_w: &'a [f32],
    /// Conv1 bias.
    pub conv1_b: &'a [f32],
    /// Conv2 weights, `[c2][c1·9]`.
    pub conv2_w: &'a [f32],
    /// Conv2 bias.
    pub conv2_b: &'a [f32],
    /// Dense weights, `[2][c2]`.
    pub fc_w: &'a [f32],
    /// Dense bias.
    pub fc_b: &'a [f32],
}

/// Intermediate values of one forward pass, kept for the backward pass.
#[derive(Debug, Default, Clone)]
pub struct Cache {
    cols1: Vec<f32>,
    a1: Vec<f32>,
    p1: Vec<f32>,
    arg1: Vec<u32>,
    cols2: Vec<f32>,
    a2: Vec<f32>,
    arg2: Vec<u32>,
    gap: Vec<f32>,
    /// Softmax probabilities of the last forward pass.
    pub probs: [f32; 2],
}

/// ReLU in place, then 2×2/2 max-pool (floor) of a `c×h×w` map; records argmaxes.
fn relu_pool(a: &mut [f32], c: usize, h: usize, w: usize, out: &mut Vec<f32>, arg: &mut Vec<u32>) {
    for v in a.iter_mut() {
        *v = v.max(0.0);
    }
    let (ho, wo) = (h / 2, w / 2);
    out.clear();
    arg.clear();
    for ch in 0..c {
        for y in 0..ho {
            for x in 0..wo {
                let mut best = ch * h * w + 2 * y * w + 2 * x;
                for (dy, dx) in [(0, 1), (1, 0), (1, 1)] {
                    let i = ch * h * w + (2 * y + dy) * w + 2 * x + dx;
                    if a[i] > a[best] {
                        best = i;
                    }
                }
                out.push(a[best]);
                arg.push(best as u32);
            }
        }
    }
}

impl TinyCnn {
    /// A network with He-normal weights and zero biases drawn from `rng`.
    pub fn new(shape: Shape, rng: &mut Rng) -> Self {
        let mut params = Vec::with_capacity(shape.n_params());
        let push = |params: &mut Vec<f32>, n: usize, fan_in: usize, rng: &mut Rng| {
            let sd = (2.0 / fan_in as f64).sqrt();
            let normal = Normal::new(0.0, sd).unwrap_or_else(|_| unreachable_normal());
            for _ in 0..n {
                params.push(normal.sample(rng) as f32);
            }
        };
        push(&mut params, shape.c1 * 27, 27, rng);
        params.extend(std::iter::repeat_n(0.0, shape.c1));
        push(&mut params, shape.c2 * shape.c1 * 9, shape.c1 * 9, rng);
        params.extend(std::iter::repeat_n(0.0, shape.c2));
        push(&mut params, 2 * shape.c2, shape.c2, rng);
        params.extend([0.0, 0.0]);
        Self { shape, params }
    }

    /// The parameter blocks of `params` (a parameter or a gradient vector).
    pub fn split<'a>(&self, params: &'a [f32]) -> Views<'a> {
        let s = self.shape;
        let (conv1_w, r) = params.split_at(s.c1 * 27);
        let (conv1_b, r) = r.split_at(s.c1);
        let (conv2_w, r) = r.split_at(s.c2 * s.c1 * 9);
        let (conv2_b, r) = r.split_at(s.c2);
        let (fc_w, fc_b) = r.split_at(2 * s.c2);
        Views {
            conv1_w,
            conv1_b,
            conv2_w,
            conv2_b,
            fc_w,
            fc_b,
        }
    }

    /// The parameter blocks of this network.
    pub fn views(&self) -> Views<'_> {
        self.split(&self.params)
    }

    /// Forward pass of one `3×H×W` input; returns the two logits and fills `cache`.
    pub fn forward(&self, x: &[f32], cache: &mut Cache) -> [f32; 2] {
        let s = self.shape;
        let v = self.views();
        let (h1, w1) = s.conv1_out();
        im2col(x, 3, s.height, s.width, &mut cache.cols1);
        cache.a1.clear();
        for &b in v.conv1_b {
            cache.a1.extend(std::iter::repeat_n(b, h1 * w1));
        }
        gemm(
            s.c1,
            27,
            h1 * w1,
            v.conv1_w,
            (27, 1),
            &cache.cols1,
            (h1 * w1, 1),
            1.0,
            &mut cache.a1,
        );
        relu_pool(&mut cache.a1, s.c1, h1, w1, &mut cache.p1, &mut cache.arg1);
        let (ph, pw) = s.pool1_out();
        let (h2, w2) = s.conv2_out();
        im2col(&cache.p1, s.c1, ph, pw, &mut cache.cols2);
        cache.a2.clear();
        for &b in v.conv2_b {
            cache.a2.extend(std::iter::repeat_n(b, h2 * w2));
        }
        let k2 = s.c1 * 9;
        gemm(
            s.c2,
            k2,
            h2 * w2,
            v.conv2_w,
            (k2, 1),
            &cache.cols2,
            (h2 * w2, 1),
            1.0,
            &mut cache.a2,
        );
        let mut p2 = Vec::new();
        relu_pool(&mut cache.a2, s.c2, h2, w2, &mut p2, &mut cache.arg2);
        let (qh, qw) = s.pool2_out();
        let area = (qh * qw) as f32;
        cache.gap = p2
            .chunks(qh * qw)
            .map(|c| c.iter().sum::<f32>() / area)
            .collect();
        let mut logits = [v.fc_b[0], v.fc_b[1]];
        for (k, l) in logits.iter_mut().enumerate() {
            *l += v.fc_w[k * s.c2..(k + 1) * s.c2]
                .iter()
                .zip(&cache.gap)
                .map(|(a, b)| a * b)
                .sum::<f32>();
        }
        cache.probs = softmax2(logits);
        logits
    }

    /// Probability of class 1 (the target) for one input.
    pub fn predict(&self, x: &[f32]) -> f32 {
        let mut cache = Cache::default();
        self.forward(x, &mut cache);
        cache.probs[1]
    }

    /// Forward and backward pass of one sample with label `label` (0 or 1): adds the
    /// gradient of the cross-entropy loss `−ln p_label` to `grad` and returns the loss.
    pub fn accumulate_gradient(
        &self,
        x: &[f32],
        label: usize,
        cache: &mut Cache,
        grad: &mut [f32],
    ) -> f64 {
        let s = self.shape;
        self.forward(x, cache);
        let p = cache.probs;
        let loss = -f64::from(p[label.min(1)].max(1e-12)).ln();
        let dlogits = [p[0] - f32::from(label == 0), p[1] - f32::from(label == 1)];
        let v = self.views();
        let (h1, w1) = s.conv1_out();
        let (ph, pw) = s.pool1_out();
        let (h2, w2) = s.conv2_out();
        let (qh, qw) = s.pool2_out();
        let n1w = s.c1 * 27;
        let n2w = s.c2 * s.c1 * 9;
        let (g_c1w, r) = grad.split_at_mut(n1w);
        let (g_c1b, r) = r.split_at_mut(s.c1);
        let (g_c2w, r) = r.split_at_mut(n2w);
        let (g_c2b, r) = r.split_at_mut(s.c2);
        let (g_fcw, g_fcb) = r.split_at_mut(2 * s.c2);
        // Dense.
        let mut dgap = vec![0.0f32; s.c2];
        for k in 0..2 {
            g_fcb[k] += dlogits[k];
            for c in 0..s.c2 {
                g_fcw[k * s.c2 + c] += dlogits[k] * cache.gap[c];
                dgap[c] += dlogits[k] * v.fc_w[k * s.c2 + c];
            }
        }
        // GAP → pool2 → ReLU2.
        let area = (qh * qw) as f32;
        let mut da2 = vec![0.0f32; s.c2 * h2 * w2];
        for (i, &src) in cache.arg2.iter().enumerate() {
            let c = i / (qh * qw);
            if cache.a2[src as usize] > 0.0 {
                da2[src as usize] += dgap[c] / area;
            }
        }
        // Conv2.
        let n2 = h2 * w2;
        for c in 0..s.c2 {
            g_c2b[c] += da2[c * n2..(c + 1) * n2].iter().sum::<f32>();
        }
        let k2 = s.c1 * 9;
        // dW2[c2×k2] += dA2[c2×n2] · cols2ᵀ[n2×k2]
        gemm(
            s.c2,
            n2,
            k2,
            &da2,
            (n2, 1),
            &cache.cols2,
            (1, n2),
            1.0,
            g_c2w,
        );
        // dcols2[k2×n2] = W2ᵀ[k2×c2] · dA2[c2×n2]
        let mut dcols2 = vec![0.0f32; k2 * n2];
        gemm(
            k2,
            s.c2,
            n2,
            v.conv2_w,
            (1, k2),
            &da2,
            (n2, 1),
            0.0,
            &mut dcols2,
        );
        let mut dp1 = vec![0.0f32; s.c1 * ph * pw];
        col2im(&dcols2, s.c1, ph, pw, &mut dp1);
        // Pool1 → ReLU1.
        let n1 = h1 * w1;
        let mut da1 = vec![0.0f32; s.c1 * n1];
        for (i, &src) in cache.arg1.iter().enumerate() {
            if cache.a1[src as usize] > 0.0 {
                da1[src as usize] += dp1[i];
            }
        }
        for c in 0..s.c1 {
            g_c1b[c] += da1[c * n1..(c + 1) * n1].iter().sum::<f32>();
        }
        gemm(
            s.c1,
            n1,
            27,
            &da1,
            (n1, 1),
            &cache.cols1,
            (1, n1),
            1.0,
            g_c1w,
        );
        loss
    }
}

fn unreachable_normal() -> Normal<f64> {
    // Normal::new(0, 1) cannot fail; this keeps the library free of `unwrap`.
    Normal::new(0.0, 1.0).unwrap_or_else(|_| unreachable_normal())
}

/// Softmax of two logits.
pub fn softmax2(l: [f32; 2]) -> [f32; 2] {
    let m = l[0].max(l[1]);
    let e = [(l[0] - m).exp(), (l[1] - m).exp()];
    let s = e[0] + e[1];
    [e[0] / s, e[1] / s]
}

/// Adam (Kingma & Ba 2015) with the usual `β1 = 0.9, β2 = 0.999, ε = 1e-8`.
#[derive(Debug, Clone)]
pub struct Adam {
    /// Learning rate.
    pub learning_rate: f64,
    m: Vec<f64>,
    v: Vec<f64>,
    t: i32,
}

impl Adam {
    /// An optimiser for `n` parameters.
    pub fn new(n: usize, learning_rate: f64) -> Self {
        Self {
            learning_rate,
            m: vec![0.0; n],
            v: vec![0.0; n],
            t: 0,
        }
    }

    /// One step with gradient `grad` (already averaged over the batch).
    pub fn step(&mut self, params: &mut [f32], grad: &[f32]) {
        const B1: f64 = 0.9;
        const B2: f64 = 0.999;
        const EPS: f64 = 1e-8;
        self.t += 1;
        let c1 = 1.0 - B1.powi(self.t);
        let c2 = 1.0 - B2.powi(self.t);
        for i in 0..params.len() {
            let g = f64::from(grad[i]);
            self.m[i] = B1 * self.m[i] + (1.0 - B1) * g;
            self.v[i] = B2 * self.v[i] + (1.0 - B2) * g * g;
            let update = self.learning_rate * (self.m[i] / c1) / ((self.v[i] / c2).sqrt() + EPS);
            params[i] -= update as f32;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::RngExt as _;
    use roadtrack::rng::{Stream, rng};

    fn small() -> (TinyCnn, Vec<f32>) {
        let mut r = rng(3, Stream::Synthetic);
        let shape = Shape {
            height: 12,
            width: 11,
            c1: 3,
            c2: 4,
        };
        let mut net = TinyCnn::new(shape, &mut r);
        // Non-zero biases so their gradients are exercised too.
        for p in net.params.iter_mut() {
            *p += r.random_range(-0.1f32..0.1);
        }
        let x: Vec<f32> = (0..3 * 12 * 11)
            .map(|_| r.random_range(-1.0f32..1.0))
            .collect();
        (net, x)
    }

    /// Naive direct convolution, the reference for im2col + gemm.
    fn conv_ref(x: &[f32], c: usize, h: usize, w: usize, wt: &[f32], b: &[f32]) -> Vec<f32> {
        let co = b.len();
        let (ho, wo) = (h - 2, w - 2);
        let mut out = vec![0.0; co * ho * wo];
        for o in 0..co {
            for y in 0..ho {
                for xx in 0..wo {
                    let mut s = b[o];
                    for ch in 0..c {
                        for ky in 0..3 {
                            for kx in 0..3 {
                                s += wt[o * c * 9 + ch * 9 + ky * 3 + kx]
                                    * x[ch * h * w + (y + ky) * w + xx + kx];
                            }
                        }
                    }
                    out[o * ho * wo + y * wo + xx] = s;
                }
            }
        }
        out
    }

    #[test]
    fn im2col_convolution_equals_direct_convolution() {
        let (net, x) = small();
        let v = net.views();
        let reference: Vec<f32> = conv_ref(&x, 3, 12, 11, v.conv1_w, v.conv1_b)
            .into_iter()
            .map(|a| a.max(0.0))
            .collect();
        let mut cache = Cache::default();
        net.forward(&x, &mut cache);
        assert_eq!(cache.a1.len(), reference.len());
        for (a, b) in cache.a1.iter().zip(&reference) {
            assert!((a - b).abs() < 1e-5);
        }
    }

    #[test]
    fn gradients_match_finite_differences() {
        let (net, x) = small();
        for label in [0, 1] {
            let mut cache = Cache::default();
            let mut grad = vec![0.0f32; net.params.len()];
            net.accumulate_gradient(&x, label, &mut cache, &mut grad);
            let loss = |p: &[f32]| {
                let n = TinyCnn {
                    shape: net.shape,
                    params: p.to_vec(),
                };
                let mut c = Cache::default();
                n.forward(&x, &mut c);
                -f64::from(c.probs[label]).ln()
            };
            let mut worst = 0.0f64;
            for i in 0..net.params.len() {
                let h = 2e-3f32;
                let mut plus = net.params.clone();
                plus[i] += h;
                let mut minus = net.params.clone();
                minus[i] -= h;
                let numeric = (loss(&plus) - loss(&minus)) / (2.0 * f64::from(h));
                let analytic = f64::from(grad[i]);
                let err = (numeric - analytic).abs() / (2e-3 + numeric.abs().max(analytic.abs()));
                worst = worst.max(err);
                assert!(
                    err < 0.05,
                    "param {i}: numeric {numeric} analytic {analytic}"
                );
            }
            assert!(worst < 0.05);
        }
    }

    #[test]
    fn adam_minimises_a_quadratic() {
        let mut p = vec![3.0f32, -2.0];
        let mut opt = Adam::new(2, 0.1);
        for _ in 0..500 {
            let g = vec![2.0 * p[0], 2.0 * p[1]];
            opt.step(&mut p, &g);
        }
        assert!(p[0].abs() < 1e-2 && p[1].abs() < 1e-2, "{p:?}");
    }
}
