//! The learned detector's first three layers (`conv1`–`conv3`, each with its ReLU) run by
//! roadtrack's own kernels; tract runs the rest of the network from their output `r3`.
//!
//! Why: these layers have few channels over many pixels, and tract runs them as a direct
//! convolution at a third of the throughput of the later layers — half of a pass's time
//! (docs/PERFORMANCE.md, "Where the learned detector's time goes"). Here the buffers are
//! channels-last (`y, x, c`) with a one-pixel zero border (the layers' padding), and each
//! output pixel's channels sit in vector registers: for every input tap (`ky, kx, c`) one
//! weight vector per 8 output channels is loaded and multiplied into the accumulators of
//! several neighbouring output pixels (6 with 16 channels, 4 with 24: 12 of AVX2's 16
//! registers either way).
//!
//! With AVX2 and FMA (checked at run time) an explicit-intrinsics kernel runs; elsewhere a
//! portable loop with a multiply and an add. Both agree with a naive reference within
//! rounding (tests), and the cut network with tract's whole one within 1e-4 on the outputs.

use super::{CenterNetWeights, LayerWeights};

/// `conv1`'s output channels the kernels are built for (the default shape's).
pub const C1: usize = 16;
/// `conv2`'s and `conv3`'s.
pub const C2: usize = 24;

/// One 3 × 3 convolution (padding 1) packed for the kernel: `taps[(ky·3 + kx)·CIN + c]`
/// holds the weights of input channel `c` at `(ky, kx)` for every output channel.
#[derive(Debug, Clone)]
pub struct Conv3<const CIN: usize, const COUT: usize> {
    taps: Vec<[f32; COUT]>,
    bias: [f32; COUT],
}

impl<const CIN: usize, const COUT: usize> Conv3<CIN, COUT> {
    /// Packs ONNX-order weights `[COUT][CIN][3][3]`; `None` when the sizes differ.
    pub fn pack(layer: &LayerWeights) -> Option<Self> {
        if layer.weight.len() != COUT * CIN * 9 || layer.bias.len() != COUT {
            return None;
        }
        let mut taps = vec![[0.0; COUT]; 9 * CIN];
        for (o, per_out) in layer.weight.chunks_exact(CIN * 9).enumerate() {
            for (c, kernel) in per_out.chunks_exact(9).enumerate() {
                for (tap, &v) in kernel.iter().enumerate() {
                    taps[tap * CIN + c][o] = v;
                }
            }
        }
        Some(Self {
            taps,
            bias: std::array::from_fn(|o| layer.bias[o]),
        })
    }

    /// `relu(conv(input))` with stride `S`. `input`: channels-last `(ih + 2) × (iw + 2) ×
    /// CIN` with a zero border; `out`: channels-last `(oh + 2) × (ow + 2) × COUT`, whose
    /// interior is written and border left as it is. `oh`, `ow` must be the output sides
    /// (`(ih − 1) / S + 1`).
    ///
    /// # Panics
    /// When a buffer is smaller than its sides say.
    pub fn run<const S: usize>(
        &self,
        input: &[f32],
        iw: usize,
        out: &mut [f32],
        oh: usize,
        ow: usize,
    ) {
        self.run_with::<S>(input, iw, out, oh, ow, true);
    }

    /// [`Conv3::run`]; `simd = false` forces the portable path (tests compare both).
    #[allow(unsafe_code)]
    pub fn run_with<const S: usize>(
        &self,
        input: &[f32],
        iw: usize,
        out: &mut [f32],
        oh: usize,
        ow: usize,
        simd: bool,
    ) {
        let in_row = (iw + 2) * CIN;
        let out_row = (ow + 2) * COUT;
        assert!(
            ow == 0 || S * (ow - 1) < iw,
            "conv3x3: output width {ow} too wide for input width {iw} at stride {S}"
        );
        assert!(
            input.len() >= (S * oh.saturating_sub(1) + 3) * in_row,
            "conv3x3: input of {} values, too short for {oh} output rows",
            input.len()
        );
        assert!(
            out.len() >= (oh + 2) * out_row,
            "conv3x3: output of {} values, too short",
            out.len()
        );
        let g = Geometry {
            // Each tap's offset from its window's top-left value, in `taps` order.
            offsets: (0..9 * CIN)
                .map(|t| (t / CIN / 3) * in_row + (t / CIN % 3) * CIN + t % CIN)
                .collect(),
            in_row,
            out_row,
            oh,
            ow,
        };
        #[cfg(target_arch = "x86_64")]
        if simd
            && COUT.is_multiple_of(8)
            && COUT <= 24
            && std::arch::is_x86_feature_detected!("avx2")
            && std::arch::is_x86_feature_detected!("fma")
        {
            // SAFETY: the CPU has AVX2 and FMA (checked just above), `COUT` is 8, 16 or 24,
            // and the buffers' sizes that the kernel's loads and stores rely on are asserted
            // above. As many pixels at a time as keep 12 accumulators.
            unsafe {
                if COUT <= 16 {
                    self.rows_avx2::<S, 6>(&g, input, out);
                } else {
                    self.rows_avx2::<S, 4>(&g, input, out);
                }
            }
            return;
        }
        let _ = simd;
        self.rows_portable::<S>(&g, input, out);
    }

    /// The portable kernel: one output pixel at a time, a multiply and an add per weight.
    fn rows_portable<const S: usize>(&self, g: &Geometry, input: &[f32], out: &mut [f32]) {
        for oy in 0..g.oh {
            let dst = &mut out[(oy + 1) * g.out_row + COUT..][..g.ow * COUT];
            for (ox, d) in dst.chunks_exact_mut(COUT).enumerate() {
                let base = S * (oy * g.in_row + ox * CIN);
                let mut acc = self.bias;
                for (w, &off) in self.taps.iter().zip(&g.offsets) {
                    let x = input[base + off];
                    for (a, &w) in acc.iter_mut().zip(w) {
                        *a += x * w;
                    }
                }
                for (d, a) in d.iter_mut().zip(acc) {
                    *d = a.max(0.0);
                }
            }
        }
    }

    /// The AVX2 + FMA kernel: `P` output pixels of a row at a time, `COUT / 8` vectors each.
    ///
    /// # Safety
    /// The CPU has AVX2 and FMA; `COUT` is 8, 16 or 24; `g` is [`Conv3::run_with`]'s (each
    /// offset below `3 · in_row`); `input` holds `(S · (oh − 1) + 3) · in_row` values with
    /// `S · (ow − 1) + 3 ≤ in_row / CIN`, and `out` `(oh + 2) · out_row` with `out_row =
    /// (ow + 2) · COUT`.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    #[allow(unsafe_code)]
    unsafe fn rows_avx2<const S: usize, const P: usize>(
        &self,
        g: &Geometry,
        input: &[f32],
        out: &mut [f32],
    ) {
        let (in_row, out_row, oh, ow) = (g.in_row, g.out_row, g.oh, g.ow);
        use std::arch::x86_64::{
            _mm256_broadcast_ss, _mm256_fmadd_ps, _mm256_loadu_ps, _mm256_max_ps,
            _mm256_setzero_ps, _mm256_storeu_ps,
        };
        let vectors = COUT / 8;
        let zero = _mm256_setzero_ps();
        let (ip, op) = (input.as_ptr(), out.as_mut_ptr());
        for oy in 0..oh {
            let top = S * oy * in_row;
            let row_out = (oy + 1) * out_row + COUT;
            let mut ox = 0;
            while ox < ow {
                let n = (ow - ox).min(P);
                // The last group of a row repeats its last pixel to fill `P` (not stored).
                let base: [usize; P] = std::array::from_fn(|p| top + S * (ox + p.min(n - 1)) * CIN);
                // SAFETY: loads read `input[base[p] + off]`, below `top + S·(ow − 1)·CIN +
                // 3·in_row ≤ (S·oy + 3)·in_row ≤ input.len()`; `taps[t]` and `bias` hold COUT
                // values, read 8 at a time below COUT; stores write `out[row_out + (ox + p)·COUT
                // + 8v ..][..8]` for p < n, inside the output's row oy + 1.
                unsafe {
                    let mut acc = [[zero; 3]; P];
                    for a in acc.iter_mut() {
                        for (v, a) in a.iter_mut().enumerate().take(vectors) {
                            *a = _mm256_loadu_ps(self.bias.as_ptr().add(8 * v));
                        }
                    }
                    for (w, &off) in self.taps.iter().zip(&g.offsets) {
                        let wp = w.as_ptr();
                        let w0 = _mm256_loadu_ps(wp);
                        let w1 = if vectors > 1 {
                            _mm256_loadu_ps(wp.add(8))
                        } else {
                            zero
                        };
                        let w2 = if vectors > 2 {
                            _mm256_loadu_ps(wp.add(16))
                        } else {
                            zero
                        };
                        for (a, &b) in acc.iter_mut().zip(&base) {
                            let x = _mm256_broadcast_ss(&*ip.add(b + off));
                            a[0] = _mm256_fmadd_ps(x, w0, a[0]);
                            if vectors > 1 {
                                a[1] = _mm256_fmadd_ps(x, w1, a[1]);
                            }
                            if vectors > 2 {
                                a[2] = _mm256_fmadd_ps(x, w2, a[2]);
                            }
                        }
                    }
                    for (p, a) in acc.iter().enumerate().take(n) {
                        for (v, &a) in a.iter().enumerate().take(vectors) {
                            _mm256_storeu_ps(
                                op.add(row_out + (ox + p) * COUT + 8 * v),
                                _mm256_max_ps(a, zero),
                            );
                        }
                    }
                }
                ox += n;
            }
        }
    }
}

/// One layer call's sizes, checked by [`Conv3::run_with`], that the kernels index by.
struct Geometry {
    /// Each tap's offset from its window's top-left value, in `taps` order.
    offsets: Vec<usize>,
    /// Values per input row (border included).
    in_row: usize,
    /// Values per output row (border included).
    out_row: usize,
    /// Output rows (interior).
    oh: usize,
    /// Output columns (interior).
    ow: usize,
}

/// `conv1`–`conv3` of a network of the default widths ([`C1`], [`C2`]).
#[derive(Debug, Clone)]
pub struct Stem {
    conv1: Conv3<3, C1>,
    conv2: Conv3<C1, C2>,
    conv3: Conv3<C2, C2>,
}

impl Stem {
    /// The stem of `net`; `None` when its widths are not [`C1`], [`C2`] (such a network runs
    /// whole in tract).
    pub fn new(net: &CenterNetWeights) -> Option<Self> {
        let layers = net.shape.layers();
        let k3 = layers.iter().take(3).all(|l| l.k == 3 && l.pad == 1);
        if !k3 || net.layers.len() < 3 {
            return None;
        }
        Some(Self {
            conv1: Conv3::pack(&net.layers[0])?,
            conv2: Conv3::pack(&net.layers[1])?,
            conv3: Conv3::pack(&net.layers[2])?,
        })
    }

    /// The three layers (for per-layer timing: the `prof_detector` example).
    pub fn layers(&self) -> (&Conv3<3, C1>, &Conv3<C1, C2>, &Conv3<C2, C2>) {
        (&self.conv1, &self.conv2, &self.conv3)
    }

    /// `r3` of a preprocessed planar `3 × h × w` input (`h`, `w` multiples of 4): planar
    /// `C2 × h/4 × w/4`, as tract's `r3`. `simd = false` forces the portable kernel.
    ///
    /// # Panics
    /// When `input` is shorter than `3 · h · w`.
    pub fn run(&self, input: &[f32], h: usize, w: usize, simd: bool) -> Vec<f32> {
        let mut out = vec![0.0; C2 * h.div_ceil(4) * w.div_ceil(4)];
        self.run_into(input, h, w, simd, &mut out);
        out
    }

    /// [`Stem::run`] into `out` (`C2 · h/4 · w/4` values; the detector passes tract's input
    /// tensor, so `r3` is written once).
    ///
    /// # Panics
    /// When `input` or `out` is shorter than that.
    pub fn run_into(&self, input: &[f32], h: usize, w: usize, simd: bool, out: &mut [f32]) {
        let (h1, w1) = (h.div_ceil(2), w.div_ceil(2));
        let (h2, w2) = (h1.div_ceil(2), w1.div_ceil(2));
        BUFFERS.with_borrow_mut(|cache| {
            let i = match cache.iter().position(|(size, _)| *size == (h, w)) {
                Some(i) => i,
                None => {
                    if cache.len() == CACHED_SIZES {
                        cache.remove(0);
                    }
                    let zeros = |h: usize, w: usize, c: usize| vec![0.0; (h + 2) * (w + 2) * c];
                    let b = Buffers {
                        x: zeros(h, w, 3),
                        r1: zeros(h1, w1, C1),
                        r2: zeros(h2, w2, C2),
                        r3: zeros(h2, w2, C2),
                    };
                    cache.push(((h, w), b));
                    cache.len() - 1
                }
            };
            let b = &mut cache[i].1;
            channels_last(input, h, w, &mut b.x);
            self.conv1.run_with::<2>(&b.x, w, &mut b.r1, h1, w1, simd);
            self.conv2.run_with::<2>(&b.r1, w1, &mut b.r2, h2, w2, simd);
            self.conv3.run_with::<1>(&b.r2, w2, &mut b.r3, h2, w2, simd);
            planar(&b.r3, h2, w2, out);
        });
    }
}

/// One thread's bordered buffers for one input size. Their borders stay zero: the stem
/// writes only interiors, and every interior value on every run.
struct Buffers {
    x: Vec<f32>,
    r1: Vec<f32>,
    r2: Vec<f32>,
    r3: Vec<f32>,
}

/// Input sizes whose buffers a thread keeps.
const CACHED_SIZES: usize = 4;

thread_local! {
    // Choice: the buffers of the last few input sizes, per thread (the pyramid alternates
    // two sizes, the zoom adds one), so that a 640 × 480 pass neither allocates nor zeroes
    // its 12 MB of buffers (2 of the stem's 9 ms before).
    static BUFFERS: std::cell::RefCell<Vec<((usize, usize), Buffers)>> =
        const { std::cell::RefCell::new(Vec::new()) };
}

/// A planar `3 × h × w` input into the interior of the channels-last `(h + 2) × (w + 2) × 3`
/// buffer `out`.
fn channels_last(input: &[f32], h: usize, w: usize, out: &mut [f32]) {
    let plane = h * w;
    for y in 0..h {
        let dst = &mut out[((y + 1) * (w + 2) + 1) * 3..][..w * 3];
        for (x, px) in dst.chunks_exact_mut(3).enumerate() {
            for (c, v) in px.iter_mut().enumerate() {
                *v = input[c * plane + y * w + x];
            }
        }
    }
}

/// The interior of a channels-last `(h + 2) × (w + 2) × C2` buffer into planar `C2 × h × w`
/// `out`.
fn planar(buf: &[f32], h: usize, w: usize, out: &mut [f32]) {
    for y in 0..h {
        let src = &buf[((y + 1) * (w + 2) + 1) * C2..][..w * C2];
        for (x, px) in src.chunks_exact(C2).enumerate() {
            for (c, &v) in px.iter().enumerate() {
                out[c * h * w + y * w + x] = v;
            }
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Values in [-0.5, 0.5) from a 64-bit LCG (reproducible, no dependency).
    pub fn values(n: usize, seed: u64) -> Vec<f32> {
        let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
        (0..n)
            .map(|_| {
                s = s
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1_442_695_040_888_963_407);
                (s >> 40) as f32 / (1u64 << 24) as f32 - 0.5
            })
            .collect()
    }

    /// The naive reference: planar `cin × h × w` in, planar `cout × oh × ow` out, ONNX
    /// weights `[cout][cin][3][3]`, padding 1, sums in f64, then ReLU.
    fn naive(
        input: &[f32],
        (cin, h, w): (usize, usize, usize),
        layer: &LayerWeights,
        cout: usize,
        stride: usize,
    ) -> (Vec<f32>, usize, usize) {
        let (oh, ow) = ((h - 1) / stride + 1, (w - 1) / stride + 1);
        let mut out = vec![0.0; cout * oh * ow];
        for o in 0..cout {
            for oy in 0..oh {
                for ox in 0..ow {
                    let mut sum = f64::from(layer.bias[o]);
                    for c in 0..cin {
                        for ky in 0..3 {
                            for kx in 0..3 {
                                let (y, x) = (
                                    (stride * oy + ky) as isize - 1,
                                    (stride * ox + kx) as isize - 1,
                                );
                                if y < 0 || x < 0 || y >= h as isize || x >= w as isize {
                                    continue;
                                }
                                let v = input[(c * h + y as usize) * w + x as usize];
                                let k = layer.weight[((o * cin + c) * 3 + ky) * 3 + kx];
                                sum += f64::from(v) * f64::from(k);
                            }
                        }
                    }
                    out[(o * oh + oy) * ow + ox] = (sum as f32).max(0.0);
                }
            }
        }
        (out, oh, ow)
    }

    /// Planar `c × h × w` as channels-last with a zero border (any `c`).
    fn bordered(input: &[f32], c: usize, h: usize, w: usize) -> Vec<f32> {
        let mut out = vec![0.0; (h + 2) * (w + 2) * c];
        for ch in 0..c {
            for y in 0..h {
                for x in 0..w {
                    out[((y + 1) * (w + 2) + x + 1) * c + ch] = input[(ch * h + y) * w + x];
                }
            }
        }
        out
    }

    /// One layer's kernel, portable and (where the CPU has them) AVX2 + FMA, against
    /// [`naive`]; the border of the output is left zero.
    fn check_layer<const CIN: usize, const COUT: usize, const S: usize>(
        h: usize,
        w: usize,
        seed: u64,
    ) {
        let layer = LayerWeights {
            weight: values(COUT * CIN * 9, seed),
            bias: values(COUT, seed + 1),
        };
        let input = values(CIN * h * w, seed + 2);
        let (want, oh, ow) = naive(&input, (CIN, h, w), &layer, COUT, S);
        assert!(want.iter().filter(|&&v| v > 0.0).count() > want.len() / 4);
        let conv = Conv3::<CIN, COUT>::pack(&layer).expect("sizes");
        let x = bordered(&input, CIN, h, w);
        for simd in [false, true] {
            let mut out = vec![0.0; (oh + 2) * (ow + 2) * COUT];
            conv.run_with::<S>(&x, w, &mut out, oh, ow, simd);
            for o in 0..COUT {
                for y in 0..oh + 2 {
                    for xx in 0..ow + 2 {
                        let got = out[(y * (ow + 2) + xx) * COUT + o];
                        let inside = (1..=oh).contains(&y) && (1..=ow).contains(&xx);
                        let expect = if inside {
                            want[(o * oh + y - 1) * ow + xx - 1]
                        } else {
                            0.0
                        };
                        assert!(
                            (got - expect).abs() <= 1e-5,
                            "{CIN}->{COUT} stride {S}, {h} x {w}, simd {simd}: ({o}, {y}, {xx}) {got} vs {expect}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn each_stem_kernel_equals_a_naive_convolution() {
        // Widths whose output rows end in a partial group of four pixels too.
        for (h, w) in [(16, 16), (9, 22), (12, 30)] {
            check_layer::<3, C1, 2>(h, w, 1);
            check_layer::<C1, C2, 2>(h, w, 2);
            check_layer::<C2, C2, 1>(h, w, 3);
        }
    }

    #[test]
    fn a_thread_reusing_its_buffers_gets_what_a_fresh_thread_gets() {
        let layer = |cin: usize, cout: usize, seed: u64| LayerWeights {
            weight: values(cout * cin * 9, seed),
            bias: values(cout, seed + 1),
        };
        let stem = Stem {
            conv1: Conv3::pack(&layer(3, C1, 1)).expect("sizes"),
            conv2: Conv3::pack(&layer(C1, C2, 3)).expect("sizes"),
            conv3: Conv3::pack(&layer(C2, C2, 5)).expect("sizes"),
        };
        let sizes = [
            (16, 16),
            (32, 48),
            (16, 32),
            (48, 16),
            (32, 32),
            (16, 16),
            (32, 48),
        ];
        let input = |k: usize, (h, w): (usize, usize)| values(3 * h * w, 10 + k as u64);
        // Each run on a new thread: new buffers.
        let fresh: Vec<Vec<f32>> = sizes
            .iter()
            .enumerate()
            .map(|(k, &(h, w))| {
                let (stem, x) = (stem.clone(), input(k, (h, w)));
                std::thread::spawn(move || stem.run(&x, h, w, true))
                    .join()
                    .expect("thread")
            })
            .collect();
        // One thread, sizes alternating and more of them than it keeps.
        assert!(sizes.len() > CACHED_SIZES);
        for (k, &(h, w)) in sizes.iter().enumerate() {
            let out = stem.run(&input(k, (h, w)), h, w, true);
            assert!(out.iter().any(|&v| v > 0.0));
            assert_eq!(out, fresh[k], "run {k}, {h} x {w}");
        }
    }

    #[test]
    fn weights_of_the_wrong_size_are_not_packed() {
        let layer = LayerWeights {
            weight: vec![0.0; C2 * C1 * 9],
            bias: vec![0.0; C2],
        };
        assert!(Conv3::<C1, C2>::pack(&layer).is_some());
        assert!(Conv3::<C2, C2>::pack(&layer).is_none());
        assert!(Conv3::<C1, C1>::pack(&layer).is_none());
    }
}
