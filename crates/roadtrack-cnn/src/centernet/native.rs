//! The learned detector's whole network run by roadtrack's own kernels, without tract.
//!
//! Why: tract ran this network at 11–16 GMAC/s (a direct convolution for the narrow early
//! layers, and per-node copies, padding and layout changes between the small later ones);
//! these kernels reach 25–40 GMAC/s on every layer (docs/PERFORMANCE.md, "The learned
//! detector in roadtrack's kernels").
//!
//! Every activation is a channels-last `(h + 2) × (w + 2) × c` buffer with a one-pixel zero
//! border (the 3 × 3 layers' padding). Every layer is one kind of call: a list of taps, each
//! an offset into the input and one weight per output channel, summed over a grid of output
//! pixels. A 3 × 3 convolution has `9 · cin` taps; a 1 × 1 convolution `cin`; a 2 × 2
//! stride-2 transposed convolution is four 1 × 1 calls, one per output position `(dy, dx)`,
//! writing every second pixel. The transposed convolutions add their skip input (`r5`,
//! `r3`) before the ReLU, as the ONNX graph's `Add` does.
//!
//! With AVX2 and FMA (checked at run time) an explicit-intrinsics kernel keeps the output
//! channels of `P` neighbouring pixels in registers: per tap one weight vector per 8 output
//! channels, multiplied into each pixel's accumulators (`V` vectors × `P` pixels = 12
//! accumulators). Elsewhere a portable loop runs. Both agree with naive references within
//! rounding, and the whole network with tract's run of the same ONNX within 1e-4 (tests).

use super::{CLASSES, CenterNetWeights, LayerKind, LayerWeights};

/// One layer's weights packed for the kernels: `taps[t · cout + o]` is tap `t`'s weight
/// for output channel `o`.
#[derive(Debug, Clone)]
pub struct Packed {
    cout: usize,
    taps: Vec<f32>,
    bias: Vec<f32>,
}

/// A cache line of stack: the kernels hold one so that LLVM realigns their frames to 64
/// bytes. The tiles of 24 accumulators spill a few vectors in the inner loop; from a
/// frame 16 bytes off a line, every spill load and store straddled two cache lines, and
/// the learned detector ran at 2/3 of its speed whenever the callers' stack depth put it
/// there (docs/PERFORMANCE.md "A regression from stack alignment").
#[repr(align(64))]
struct Align64([u8; 64]);

/// The vector kernel (`P` output pixels of a row at a time, `V` vectors of `LANES` output
/// channels each, blocks of `LANES · V` channels in turn), for one instruction set.
/// [`Packed::rows_avx2`] and [`Packed::rows_avx512`] are the same code over 8 and 16 lanes.
macro_rules! vector_kernel {
    ($(#[$doc:meta])* $name:ident, $feature:literal, $lanes:literal, $vec:ident,
     $load:ident, $store:ident, $set1:ident, $fma:ident, $add:ident, $max:ident, $zero:ident) => {
        $(#[$doc])*
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = $feature)]
        #[allow(unsafe_code)]
        unsafe fn $name<const V: usize, const P: usize>(
            &self,
            call: &Call,
            input: &[f32],
            skip: Option<&[f32]>,
            out: &mut [f32],
        ) {
            use std::arch::x86_64::{$vec, $add, $set1, $fma, $load, $max, $zero, $store};
            const L: usize = $lanes;
            let cout = self.cout;
            let zero = $zero();
            let (ip, op, wp, bp) = (
                input.as_ptr(),
                out.as_mut_ptr(),
                self.taps.as_ptr(),
                self.bias.as_ptr(),
            );
            let sp = skip.map(<[f32]>::as_ptr);
            // A 64-byte-aligned local whose address escapes: LLVM realigns the frame and
            // spills vectors with aligned moves ([`Align64`]).
            let anchor = Align64([0; 64]);
            std::hint::black_box(&anchor.0);
            // The call's fields as locals: the stores through `op` could otherwise be taken
            // to change them, and they would be reloaded in the inner loop.
            let (offsets, in_col, out_col, relu) =
                (&call.offsets[..], call.in_col, call.out_col, call.relu);
            for r in 0..call.rows {
                let in_r = call.in_origin + r * call.in_row;
                let out_r = call.out_origin + r * call.out_row;
                let mut col = 0;
                while col < call.cols {
                    // Choice: the last group of a row is moved left to end at the row's end;
                    // the pixels it shares with the group before are computed the same way
                    // again and stored with the same values (no partial group, no masks).
                    let start = col.min(call.cols - P);
                    let base: [usize; P] = std::array::from_fn(|p| in_r + (start + p) * in_col);
                    let dst: [usize; P] = std::array::from_fn(|p| out_r + (start + p) * out_col);
                    for o0 in (0..cout).step_by(L * V) {
                        // SAFETY: reads `input[base[p] + off]` ≤ `last_in`, `taps[t·cout + o0
                        // + L·v ..][..L]` and `bias[o0 + L·v ..][..L]` below their lengths (o0
                        // + L·V ≤ cout); reads `skip` and writes `out` at `dst[p] + o0 + L·v
                        // ..][..L]`, below `end_out` (start + P ≤ cols).
                        unsafe {
                            let mut acc: [[$vec; V]; P] = [[zero; V]; P];
                            #[allow(clippy::needless_range_loop)]
                            for p in 0..P {
                                for v in 0..V {
                                    let b = $load(bp.add(o0 + L * v));
                                    acc[p][v] = match sp {
                                        Some(sp) => $add(b, $load(sp.add(dst[p] + o0 + L * v))),
                                        None => b,
                                    };
                                }
                            }
                            let mut wt = wp.add(o0);
                            for &off in offsets {
                                let mut w = [zero; V];
                                #[allow(clippy::needless_range_loop)]
                                for v in 0..V {
                                    w[v] = $load(wt.add(L * v));
                                }
                                #[allow(clippy::needless_range_loop)]
                                for p in 0..P {
                                    let x = $set1(*ip.add(base[p] + off));
                                    for v in 0..V {
                                        acc[p][v] = $fma(x, w[v], acc[p][v]);
                                    }
                                }
                                wt = wt.wrapping_add(cout);
                            }
                            #[allow(clippy::needless_range_loop)]
                            for p in 0..P {
                                for v in 0..V {
                                    let a = acc[p][v];
                                    let a = if relu { $max(a, zero) } else { a };
                                    $store(op.add(dst[p] + o0 + L * v), a);
                                }
                            }
                        }
                    }
                    col = start + P;
                }
            }
        }
    };
}

impl Packed {
    /// A `k × k` convolution from ONNX weights `[cout][cin][k][k]`: tap `(ky · k + kx) ·
    /// cin + c`. `None` when the sizes differ.
    fn conv(l: &LayerWeights, cin: usize, cout: usize, k: usize) -> Option<Self> {
        if l.weight.len() != cout * cin * k * k || l.bias.len() != cout {
            return None;
        }
        let mut taps = vec![0.0; k * k * cin * cout];
        for (o, per_out) in l.weight.chunks_exact(cin * k * k).enumerate() {
            for (c, kernel) in per_out.chunks_exact(k * k).enumerate() {
                for (tap, &v) in kernel.iter().enumerate() {
                    taps[(tap * cin + c) * cout + o] = v;
                }
            }
        }
        Some(Self {
            cout,
            taps,
            bias: l.bias.clone(),
        })
    }

    /// Output position `(dy, dx)` of a 2 × 2 transposed convolution from ONNX weights
    /// `[cin][cout][2][2]`: tap `c`. `None` when the sizes differ.
    fn deconv_tap(l: &LayerWeights, cin: usize, cout: usize, dy: usize, dx: usize) -> Option<Self> {
        if l.weight.len() != cin * cout * 4 || l.bias.len() != cout {
            return None;
        }
        let mut taps = vec![0.0; cin * cout];
        for c in 0..cin {
            for o in 0..cout {
                taps[c * cout + o] = l.weight[((c * cout + o) * 2 + dy) * 2 + dx];
            }
        }
        Some(Self {
            cout,
            taps,
            bias: l.bias.clone(),
        })
    }

    /// Layers over the same taps side by side: the outputs of `a`, then of `b`.
    fn beside(a: &Self, b: &Self) -> Option<Self> {
        let taps = a.taps.len() / a.cout;
        if b.taps.len() / b.cout != taps {
            return None;
        }
        let mut packed = Vec::with_capacity(a.taps.len() + b.taps.len());
        for t in 0..taps {
            packed.extend_from_slice(&a.taps[t * a.cout..][..a.cout]);
            packed.extend_from_slice(&b.taps[t * b.cout..][..b.cout]);
        }
        Some(Self {
            cout: a.cout + b.cout,
            taps: packed,
            bias: [a.bias.as_slice(), &b.bias].concat(),
        })
    }

    /// Runs `call`: for each output pixel `(r, col)`, `bias + skip + Σ_t taps[t] ·
    /// input[in + offsets[t]]` (then ReLU when `call.relu`) into `out[at .. at + cout]`,
    /// where `in = in_origin + r · in_row + col · in_col` and `at = out_origin + r · out_row +
    /// col · out_col`; `skip` (when given) is read at `at` too. `isa` caps the instruction
    /// set (tests compare them).
    ///
    /// # Panics
    /// When a buffer is shorter than the call reaches, or the taps are not the call's.
    #[allow(unsafe_code)]
    fn run(&self, call: &Call, input: &[f32], skip: Option<&[f32]>, out: &mut [f32], isa: Isa) {
        let cout = self.cout;
        assert_eq!(
            call.offsets.len() * cout,
            self.taps.len(),
            "layer call with another number of taps"
        );
        if call.rows == 0 || call.cols == 0 {
            return;
        }
        let last_in = call.in_origin
            + (call.rows - 1) * call.in_row
            + (call.cols - 1) * call.in_col
            + call.offsets.iter().copied().max().unwrap_or(0);
        assert!(
            last_in < input.len(),
            "layer input of {} values, reads {last_in}",
            input.len()
        );
        let end_out = call.out_origin
            + (call.rows - 1) * call.out_row
            + (call.cols - 1) * call.out_col
            + cout;
        assert!(end_out <= out.len(), "layer output too short");
        assert!(
            skip.is_none_or(|s| end_out <= s.len()),
            "layer skip input too short"
        );
        #[cfg(target_arch = "x86_64")]
        if isa >= Isa::Avx512
            && cout.is_multiple_of(16)
            && std::arch::is_x86_feature_detected!("avx512f")
        {
            // SAFETY: the CPU has AVX-512F (checked just above); `cout` is a multiple of
            // each branch's 16 · V channels and the row at least P pixels wide; every
            // index the kernels read or write is at most `last_in` or below `end_out`,
            // asserted above.
            unsafe {
                if cout.is_multiple_of(64) && call.cols >= 6 {
                    self.rows_avx512::<4, 6>(call, input, skip, out);
                    return;
                }
                if cout.is_multiple_of(48) && call.cols >= 8 {
                    self.rows_avx512::<3, 8>(call, input, skip, out);
                    return;
                }
                if cout.is_multiple_of(32) && call.cols >= 12 {
                    self.rows_avx512::<2, 12>(call, input, skip, out);
                    return;
                }
            }
        }
        #[cfg(target_arch = "x86_64")]
        if isa >= Isa::Avx2
            && cout.is_multiple_of(8)
            && std::arch::is_x86_feature_detected!("avx2")
            && std::arch::is_x86_feature_detected!("fma")
        {
            // SAFETY: the CPU has AVX2 and FMA (checked just above); `cout` is a multiple
            // of 8 · V (each branch's condition) and the row at least P pixels wide; every
            // index the kernel reads or writes is at most `last_in` or below `end_out`,
            // asserted above.
            unsafe {
                if cout.is_multiple_of(24) && call.cols >= 4 {
                    self.rows_avx2::<3, 4>(call, input, skip, out);
                    return;
                }
                if cout.is_multiple_of(16) && call.cols >= 6 {
                    self.rows_avx2::<2, 6>(call, input, skip, out);
                    return;
                }
                if call.cols >= 12 {
                    self.rows_avx2::<1, 12>(call, input, skip, out);
                    return;
                }
            }
        }
        let _ = isa;
        self.rows_portable(call, input, skip, out);
    }

    /// The portable kernel: one output pixel at a time, a multiply and an add per weight.
    fn rows_portable(&self, call: &Call, input: &[f32], skip: Option<&[f32]>, out: &mut [f32]) {
        let cout = self.cout;
        let mut acc = vec![0.0f32; cout];
        for r in 0..call.rows {
            for col in 0..call.cols {
                let at = call.out_origin + r * call.out_row + col * call.out_col;
                let base = call.in_origin + r * call.in_row + col * call.in_col;
                acc.copy_from_slice(&self.bias);
                if let Some(s) = skip {
                    for (a, &s) in acc.iter_mut().zip(&s[at..at + cout]) {
                        *a += s;
                    }
                }
                for (w, &off) in self.taps.chunks_exact(cout).zip(&call.offsets) {
                    let x = input[base + off];
                    for (a, &w) in acc.iter_mut().zip(w) {
                        *a += x * w;
                    }
                }
                for (d, &a) in out[at..at + cout].iter_mut().zip(&acc) {
                    *d = if call.relu { a.max(0.0) } else { a };
                }
            }
        }
    }

    vector_kernel!(
        /// The AVX2 + FMA kernel, 8 lanes.
        ///
        /// # Safety
        /// The CPU has AVX2 and FMA; `cout` is a multiple of `8 · V`; `call.cols ≥ P`; the
        /// buffers hold every index [`Packed::run`] asserts.
        rows_avx2, "avx2,fma", 8, __m256, _mm256_loadu_ps, _mm256_storeu_ps, _mm256_set1_ps,
        _mm256_fmadd_ps, _mm256_add_ps, _mm256_max_ps, _mm256_setzero_ps
    );

    vector_kernel!(
        /// The AVX-512 kernel, 16 lanes.
        ///
        /// # Safety
        /// The CPU has AVX-512F; `cout` is a multiple of `16 · V`; `call.cols ≥ P`; the
        /// buffers hold every index [`Packed::run`] asserts.
        rows_avx512, "avx512f", 16, __m512, _mm512_loadu_ps, _mm512_storeu_ps, _mm512_set1_ps,
        _mm512_fmadd_ps, _mm512_add_ps, _mm512_max_ps, _mm512_setzero_ps
    );
}

/// The widest instruction set the kernels may use (each layer takes the widest of these
/// that the CPU has and its width suits).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Isa {
    /// The portable loop only.
    Portable,
    /// AVX2 + FMA, 8 lanes.
    Avx2,
    /// AVX-512F for layers of 32, 48 or 64 output channels (or multiples), AVX2 for the
    /// others: for 16 and 24 channels the 16-lane kernel measured slower (docs/PERFORMANCE.md).
    Avx512,
}

impl Isa {
    /// The widest the CPU has.
    pub fn best() -> Self {
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx512f") {
                return Self::Avx512;
            }
            if std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma")
            {
                return Self::Avx2;
            }
        }
        Self::Portable
    }
}

/// Where one layer call reads and writes, in values (module docs; [`Packed::run`]).
#[derive(Debug, Clone)]
struct Call {
    /// Each tap's offset from its pixel's window origin, in tap order.
    offsets: Vec<usize>,
    rows: usize,
    cols: usize,
    in_origin: usize,
    in_row: usize,
    in_col: usize,
    out_origin: usize,
    out_row: usize,
    out_col: usize,
    relu: bool,
}

impl Call {
    /// A 3 × 3 convolution (padding 1, stride `s`) with ReLU from a bordered `ih × iw × cin`
    /// buffer into the interior of a bordered `oh × ow × cout` one.
    fn conv3(cin: usize, (ih, iw): (usize, usize), cout: usize, s: usize) -> Self {
        let (oh, ow) = ((ih - 1) / s + 1, (iw - 1) / s + 1);
        let in_row = (iw + 2) * cin;
        let out_row = (ow + 2) * cout;
        Self {
            offsets: (0..9 * cin)
                .map(|t| (t / cin / 3) * in_row + (t / cin % 3) * cin + t % cin)
                .collect(),
            rows: oh,
            cols: ow,
            in_origin: 0,
            in_row: s * in_row,
            in_col: s * cin,
            out_origin: out_row + cout,
            out_row,
            out_col: cout,
            relu: true,
        }
    }

    /// A 1 × 1 convolution over the interior of a bordered `h × w × cin` buffer into that of
    /// a bordered `h × w × cout` one.
    fn pointwise(cin: usize, (h, w): (usize, usize), cout: usize, relu: bool) -> Self {
        let in_row = (w + 2) * cin;
        let out_row = (w + 2) * cout;
        Self {
            offsets: (0..cin).collect(),
            rows: h,
            cols: w,
            in_origin: in_row + cin,
            in_row,
            in_col: cin,
            out_origin: out_row + cout,
            out_row,
            out_col: cout,
            relu,
        }
    }

    /// Output position `(dy, dx)` of a 2 × 2 stride-2 transposed convolution with ReLU:
    /// from the interior of a bordered `h × w × cin` buffer into every second pixel of the
    /// interior of a bordered `2h × 2w × cout` one.
    fn deconv_tap(cin: usize, (h, w): (usize, usize), cout: usize, dy: usize, dx: usize) -> Self {
        let out_row = (2 * w + 2) * cout;
        Self {
            out_origin: (1 + dy) * out_row + (1 + dx) * cout,
            out_row: 2 * out_row,
            out_col: 2 * cout,
            ..Self::pointwise(cin, (h, w), cout, true)
        }
    }
}

/// A 2 × 2 stride-2 transposed convolution: its four output positions.
#[derive(Debug, Clone)]
struct Deconv {
    taps: [Packed; 4],
    cin: usize,
    cout: usize,
}

impl Deconv {
    fn pack(l: &LayerWeights, cin: usize, cout: usize) -> Option<Self> {
        let tap = |i: usize| Packed::deconv_tap(l, cin, cout, i / 2, i % 2);
        Some(Self {
            taps: [tap(0)?, tap(1)?, tap(2)?, tap(3)?],
            cin,
            cout,
        })
    }

    /// `relu(deconv(input) + skip)` into `out`; `input` bordered `h × w × cin`.
    fn run(&self, input: &[f32], hw: (usize, usize), skip: &[f32], out: &mut [f32], isa: Isa) {
        for (i, p) in self.taps.iter().enumerate() {
            let call = Call::deconv_tap(self.cin, hw, self.cout, i / 2, i % 2);
            p.run(&call, input, Some(skip), out, isa);
        }
    }
}

/// The network of `roadtrack train --detector` ([`super::CenterNetShape::layers`]) packed
/// for the kernels.
#[derive(Debug, Clone)]
pub struct NativeNet {
    /// `conv1`–`conv7`: packed weights, input channels, stride.
    convs: Vec<(Packed, usize, usize)>,
    up1: Deconv,
    up2: Deconv,
    head: Packed,
    head_in: usize,
    /// `heat` and `box` side by side: `CLASSES` logits, then 4 box values.
    out: Packed,
}

/// The names of the steps [`NativeNet::run_with`] reports, in order.
pub const STEPS: [&str; 13] = [
    "input",
    "conv1",
    "conv2",
    "conv3",
    "conv4",
    "conv5",
    "conv6",
    "conv7",
    "up1",
    "up2",
    "head",
    "heat, box",
    "output",
];

impl NativeNet {
    /// `net` packed; `None` when its layers are not the ones [`super::CenterNetShape::layers`]
    /// lists (kinds, kernel sizes, strides) or their weights have other sizes.
    pub fn new(net: &CenterNetWeights) -> Option<Self> {
        let specs = net.shape.layers();
        if specs.len() != 12 || net.layers.len() != 12 {
            return None;
        }
        let conv_ok = |i: usize, k: usize| {
            let s = &specs[i];
            s.kind == LayerKind::Conv && s.k == k && s.pad == k / 2
        };
        let mut convs = Vec::with_capacity(7);
        for (i, (s, l)) in specs.iter().zip(&net.layers).take(7).enumerate() {
            if !conv_ok(i, 3) || !(1..=2).contains(&s.stride) {
                return None;
            }
            convs.push((Packed::conv(l, s.cin, s.cout, 3)?, s.cin, s.stride));
        }
        let deconv = |i: usize| {
            let s = &specs[i];
            if s.kind != LayerKind::Deconv || s.k != 2 || s.stride != 2 {
                return None;
            }
            Deconv::pack(&net.layers[i], s.cin, s.cout)
        };
        let (up1, up2) = (deconv(7)?, deconv(8)?);
        if !(9..12).all(|i| conv_ok(i, 1) && specs[i].stride == 1) {
            return None;
        }
        let (sh, sx, sb) = (&specs[9], &specs[10], &specs[11]);
        let head = Packed::conv(&net.layers[9], sh.cin, sh.cout, 1)?;
        let heat = Packed::conv(&net.layers[10], sx.cin, sx.cout, 1)?;
        let boxes = Packed::conv(&net.layers[11], sb.cin, sb.cout, 1)?;
        // The graph's wiring: each layer's input width is the one before's output width,
        // the skips' widths are the deconvolutions' outputs'.
        let chain = (1..7).all(|i| specs[i].cin == specs[i - 1].cout)
            && up1.cin == specs[6].cout
            && up1.cout == specs[4].cout
            && up2.cin == up1.cout
            && up2.cout == specs[2].cout
            && sh.cin == up2.cout
            && sx.cin == sh.cout
            && sb.cin == sh.cout
            && sx.cout == CLASSES
            && sb.cout == 4
            && specs[0].cin == 3
            && convs.iter().map(|c| c.2).collect::<Vec<_>>() == [2, 2, 1, 2, 1, 2, 1];
        if !chain {
            return None;
        }
        Some(Self {
            convs,
            up1,
            up2,
            head_in: sh.cin,
            head,
            out: Packed::beside(&heat, &boxes)?,
        })
    }

    /// The heat map (after its sigmoid) and the box map of a preprocessed planar `3 × h × w`
    /// input (`h`, `w` multiples of 16), planar `CLASSES × h/4 × w/4` and `4 × h/4 × w/4`,
    /// as tract's run of the ONNX gives them. `isa` caps the instruction set.
    ///
    /// # Panics
    /// When `h` or `w` is not a multiple of 16, or `input` is shorter than `3 · h · w`.
    pub fn run(&self, input: &[f32], h: usize, w: usize, isa: Isa) -> (Vec<f32>, Vec<f32>) {
        assert!(input.len() >= 3 * h * w, "native detector input too short");
        let mut fill = |x: &mut [f32]| channels_last(input, h, w, x);
        self.run_with(h, w, isa, &mut fill, &mut |_| {})
    }

    /// [`NativeNet::run`] with the input written by `fill`: every interior value of the
    /// channels-last `(h + 2) × (w + 2) × 3` buffer it is given (the border is zero, and
    /// must stay so).
    ///
    /// # Panics
    /// When `h` or `w` is not a multiple of 16.
    pub fn run_filled(
        &self,
        h: usize,
        w: usize,
        isa: Isa,
        fill: &mut dyn FnMut(&mut [f32]),
    ) -> (Vec<f32>, Vec<f32>) {
        self.run_with(h, w, isa, fill, &mut |_| {})
    }

    /// [`NativeNet::run_filled`], calling `after(step)` as each of [`STEPS`] ends
    /// (per-layer timing: the `prof_detector` example).
    ///
    /// # Panics
    /// As [`NativeNet::run_filled`].
    pub fn run_with(
        &self,
        h: usize,
        w: usize,
        isa: Isa,
        fill: &mut dyn FnMut(&mut [f32]),
        after: &mut dyn FnMut(&'static str),
    ) -> (Vec<f32>, Vec<f32>) {
        assert!(
            h.is_multiple_of(16) && w.is_multiple_of(16),
            "native detector input {h} × {w}: sides must be multiples of 16"
        );
        // Sides of the input and of each conv's output.
        let mut sides = vec![(h, w)];
        for &(_, _, s) in &self.convs {
            let (ih, iw) = sides[sides.len() - 1];
            sides.push((ih / s, iw / s));
        }
        let widths: Vec<usize> = std::iter::once(3)
            .chain(self.convs.iter().map(|c| c.0.cout))
            .collect();
        let (h4, w4) = sides[3];
        let out_c = self.out.cout;
        let mut heat = vec![0.0; CLASSES * h4 * w4];
        let mut boxes = vec![0.0; 4 * h4 * w4];
        BUFFERS.with_borrow_mut(|cache| {
            let key = (h, w, self.convs.iter().map(|c| c.0.cout).sum::<usize>());
            let i = match cache.iter().position(|(k, _)| *k == key) {
                Some(i) => i,
                None => {
                    if cache.len() == CACHED_SIZES {
                        cache.remove(0);
                    }
                    let zeros = |(h, w): (usize, usize), c: usize| vec![0.0; (h + 2) * (w + 2) * c];
                    let mut acts: Vec<Vec<f32>> = sides
                        .iter()
                        .zip(&widths)
                        .map(|(&s, &c)| zeros(s, c))
                        .collect();
                    acts.push(zeros(sides[4], self.up1.cout));
                    acts.push(zeros(sides[3], self.up2.cout));
                    acts.push(zeros(sides[3], self.head.cout));
                    acts.push(zeros(sides[3], out_c));
                    cache.push((key, acts));
                    cache.len() - 1
                }
            };
            let b = &mut cache[i].1;
            fill(&mut b[0]);
            after(STEPS[0]);
            for (l, (p, cin, s)) in self.convs.iter().enumerate() {
                let (src, dst) = pair(b, l, l + 1);
                p.run(
                    &Call::conv3(*cin, sides[l], p.cout, *s),
                    src,
                    None,
                    dst,
                    isa,
                );
                after(STEPS[l + 1]);
            }
            // up1(r7) + r5 → m1 (b[8]); up2(m1) + r3 → m2 (b[9]).
            let (r5, r7, m1) = three(b, 5, 7, 8);
            self.up1.run(r7, sides[7], r5, m1, isa);
            after(STEPS[8]);
            let (r3, m1, m2) = three(b, 3, 8, 9);
            self.up2.run(m1, sides[5], r3, m2, isa);
            after(STEPS[9]);
            let (src, dst) = pair(b, 9, 10);
            let head = Call::pointwise(self.head_in, sides[3], self.head.cout, true);
            self.head.run(&head, src, None, dst, isa);
            after(STEPS[10]);
            let (src, dst) = pair(b, 10, 11);
            let last = Call::pointwise(self.head.cout, sides[3], out_c, false);
            self.out.run(&last, src, None, dst, isa);
            after(STEPS[11]);
            let plane = h4 * w4;
            for y in 0..h4 {
                let row = &dst[((y + 1) * (w4 + 2) + 1) * out_c..][..w4 * out_c];
                for (x, px) in row.chunks_exact(out_c).enumerate() {
                    let at = y * w4 + x;
                    for (k, &v) in px[..CLASSES].iter().enumerate() {
                        heat[k * plane + at] = 1.0 / (1.0 + (-v).exp());
                    }
                    for (k, &v) in px[CLASSES..].iter().enumerate() {
                        boxes[k * plane + at] = v;
                    }
                }
            }
            after(STEPS[12]);
        });
        (heat, boxes)
    }
}

/// `b[i]` to read and `b[j]` to write (`i < j`).
fn pair(b: &mut [Vec<f32>], i: usize, j: usize) -> (&[f32], &mut [f32]) {
    let (lo, hi) = b.split_at_mut(j);
    (&lo[i], &mut hi[0])
}

/// `b[i]`, `b[j]` to read and `b[k]` to write (`i < j < k`).
fn three(b: &mut [Vec<f32>], i: usize, j: usize, k: usize) -> (&[f32], &[f32], &mut [f32]) {
    let (lo, hi) = b.split_at_mut(k);
    (&lo[i], &lo[j], &mut hi[0])
}

/// Input sizes (and network widths) whose buffers a thread keeps.
const CACHED_SIZES: usize = 4;

type Cache = Vec<((usize, usize, usize), Vec<Vec<f32>>)>;

thread_local! {
    // Choice: the buffers of the last few input sizes, per thread (the pyramid alternates
    // two sizes, the zoom adds one), so that a 640 × 480 pass neither allocates nor zeroes
    // its buffers. Their borders stay zero: every layer writes only interiors, and every
    // interior value on every run.
    static BUFFERS: std::cell::RefCell<Cache> = const { std::cell::RefCell::new(Vec::new()) };
}

/// A planar `3 × h × w` input into the interior of the channels-last `(h + 2) × (w + 2) × 3`
/// buffer `out` (a [`NativeNet::run_filled`] input).
pub fn channels_last(input: &[f32], h: usize, w: usize, out: &mut [f32]) {
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

    /// Every instruction set the tests compare (those the CPU lacks fall back).
    const ISAS: [Isa; 3] = [Isa::Portable, Isa::Avx2, Isa::Avx512];

    fn layer(n: usize, cout: usize, seed: u64) -> LayerWeights {
        LayerWeights {
            weight: values(n, seed),
            bias: values(cout, seed + 1),
        }
    }

    /// Planar `c × h × w` as channels-last with a zero border.
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

    /// Asserts that bordered channels-last `got` (`c × h × w` inside) holds planar `want`
    /// inside and zeros on its border.
    fn assert_bordered(got: &[f32], want: &[f32], (c, h, w): (usize, usize, usize), what: &str) {
        for o in 0..c {
            for y in 0..h + 2 {
                for x in 0..w + 2 {
                    let g = got[(y * (w + 2) + x) * c + o];
                    let inside = (1..=h).contains(&y) && (1..=w).contains(&x);
                    let e = if inside {
                        want[(o * h + y - 1) * w + x - 1]
                    } else {
                        0.0
                    };
                    assert!((g - e).abs() <= 1e-5, "{what}: ({o}, {y}, {x}) {g} vs {e}");
                }
            }
        }
    }

    /// Naive 3 × 3 convolution, padding 1, stride `s`, sums in f64, ReLU; planar.
    fn naive_conv3(
        input: &[f32],
        (cin, h, w): (usize, usize, usize),
        l: &LayerWeights,
        cout: usize,
        s: usize,
    ) -> (Vec<f32>, usize, usize) {
        let (oh, ow) = ((h - 1) / s + 1, (w - 1) / s + 1);
        let mut out = vec![0.0; cout * oh * ow];
        for o in 0..cout {
            for oy in 0..oh {
                for ox in 0..ow {
                    let mut sum = f64::from(l.bias[o]);
                    for c in 0..cin {
                        for ky in 0..3 {
                            for kx in 0..3 {
                                let (y, x) =
                                    ((s * oy + ky) as isize - 1, (s * ox + kx) as isize - 1);
                                if y < 0 || x < 0 || y >= h as isize || x >= w as isize {
                                    continue;
                                }
                                let v = input[(c * h + y as usize) * w + x as usize];
                                let k = l.weight[((o * cin + c) * 3 + ky) * 3 + kx];
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

    /// Naive 2 × 2 stride-2 transposed convolution plus `skip`, then ReLU (`relu = false`:
    /// none, and no skip when it is empty); planar.
    fn naive_deconv(
        input: &[f32],
        (cin, h, w): (usize, usize, usize),
        l: &LayerWeights,
        cout: usize,
        skip: &[f32],
    ) -> Vec<f32> {
        let (oh, ow) = (2 * h, 2 * w);
        let mut out = vec![0.0; cout * oh * ow];
        for o in 0..cout {
            for y in 0..oh {
                for x in 0..ow {
                    let mut sum = f64::from(l.bias[o]);
                    for c in 0..cin {
                        let v = input[(c * h + y / 2) * w + x / 2];
                        let k = l.weight[((c * cout + o) * 2 + y % 2) * 2 + x % 2];
                        sum += f64::from(v) * f64::from(k);
                    }
                    let i = (o * oh + y) * ow + x;
                    out[i] = ((sum + f64::from(skip[i])) as f32).max(0.0);
                }
            }
        }
        out
    }

    /// One 3 × 3 layer, portable and (where the CPU has them) AVX2 + FMA, against the naive
    /// reference. Widths from 4 to 30 output pixels: rows narrower than a group (portable),
    /// rows ending in a shifted group.
    #[test]
    fn each_convolution_equals_a_naive_one() {
        for (cin, cout, s) in [
            (3, 16, 2),
            (16, 24, 2),
            (24, 24, 1),
            (24, 48, 2),
            (48, 64, 2),
            (64, 64, 1),
            (5, 8, 1),
        ] {
            for (k, (h, w)) in [(16, 16), (9, 22), (12, 30), (6, 60)]
                .into_iter()
                .enumerate()
            {
                let seed = (cin * cout + k) as u64;
                let l = layer(cout * cin * 9, cout, seed);
                let input = values(cin * h * w, seed + 2);
                let (want, oh, ow) = naive_conv3(&input, (cin, h, w), &l, cout, s);
                assert!(want.iter().filter(|&&v| v > 0.0).count() > want.len() / 4);
                let p = Packed::conv(&l, cin, cout, 3).expect("sizes");
                let x = bordered(&input, cin, h, w);
                for isa in ISAS {
                    let mut out = vec![0.0; (oh + 2) * (ow + 2) * cout];
                    p.run(&Call::conv3(cin, (h, w), cout, s), &x, None, &mut out, isa);
                    let what = format!("{cin}->{cout} stride {s}, {h} x {w}, {isa:?}");
                    assert_bordered(&out, &want, (cout, oh, ow), &what);
                }
            }
        }
    }

    /// The transposed convolution with its skip, and the 1 × 1 layers, against the naive
    /// references.
    #[test]
    fn each_deconvolution_and_pointwise_layer_equals_a_naive_one() {
        for (cin, cout) in [(64, 48), (48, 24), (16, 8)] {
            for (h, w) in [(3, 5), (8, 13), (4, 30)] {
                let seed = (cin + cout + h * w) as u64;
                let l = layer(cin * cout * 4, cout, seed);
                let input = values(cin * h * w, seed + 2);
                let skip = values(cout * 4 * h * w, seed + 3);
                let want = naive_deconv(&input, (cin, h, w), &l, cout, &skip);
                let d = Deconv::pack(&l, cin, cout).expect("sizes");
                let (x, s) = (
                    bordered(&input, cin, h, w),
                    bordered(&skip, cout, 2 * h, 2 * w),
                );
                for isa in ISAS {
                    let mut out = vec![0.0; (2 * h + 2) * (2 * w + 2) * cout];
                    d.run(&x, (h, w), &s, &mut out, isa);
                    let what = format!("deconv {cin}->{cout}, {h} x {w}, {isa:?}");
                    assert_bordered(&out, &want, (cout, 2 * h, 2 * w), &what);
                }
            }
        }
        // 1 × 1: the naive 3 × 3 convolution with only the centre weight set.
        for (cin, cout) in [(24, 32), (32, 8)] {
            let (h, w) = (7, 27);
            let l = layer(cout * cin, cout, 77);
            let input = values(cin * h * w, 78);
            let mut centred = LayerWeights {
                weight: vec![0.0; cout * cin * 9],
                bias: l.bias.clone(),
            };
            for (i, &v) in l.weight.iter().enumerate() {
                centred.weight[i * 9 + 4] = v;
            }
            let (want, _, _) = naive_conv3(&input, (cin, h, w), &centred, cout, 1);
            let p = Packed::conv(&l, cin, cout, 1).expect("sizes");
            let x = bordered(&input, cin, h, w);
            for isa in ISAS {
                let mut out = vec![0.0; (h + 2) * (w + 2) * cout];
                p.run(
                    &Call::pointwise(cin, (h, w), cout, true),
                    &x,
                    None,
                    &mut out,
                    isa,
                );
                assert_bordered(
                    &out,
                    &want,
                    (cout, h, w),
                    &format!("1x1 {cin}->{cout} {isa:?}"),
                );
                // Without the ReLU the negative sums stay.
                p.run(
                    &Call::pointwise(cin, (h, w), cout, false),
                    &x,
                    None,
                    &mut out,
                    isa,
                );
                assert!(out.iter().any(|&v| v < 0.0));
            }
        }
    }

    #[test]
    fn weights_of_the_wrong_size_are_not_packed() {
        let l = layer(24 * 16 * 9, 24, 1);
        assert!(Packed::conv(&l, 16, 24, 3).is_some());
        assert!(Packed::conv(&l, 24, 24, 3).is_none());
        assert!(Packed::conv(&l, 16, 16, 3).is_none());
        assert!(Deconv::pack(&l, 16, 24).is_none());
    }

    #[test]
    fn side_by_side_layers_give_both_outputs() {
        let (a, b) = (layer(32 * 4, 4, 5), layer(32 * 4, 4, 9));
        let (pa, pb) = (
            Packed::conv(&a, 32, 4, 1).expect("a"),
            Packed::conv(&b, 32, 4, 1).expect("b"),
        );
        let both = Packed::beside(&pa, &pb).expect("same taps");
        let x = bordered(&values(32 * 3 * 16, 3), 32, 3, 16);
        let run = |p: &Packed, isa| {
            let mut out = vec![0.0; 5 * 18 * p.cout];
            p.run(
                &Call::pointwise(32, (3, 16), p.cout, false),
                &x,
                None,
                &mut out,
                isa,
            );
            out
        };
        for isa in ISAS {
            let (oa, ob, o) = (
                run(&pa, Isa::Portable),
                run(&pb, Isa::Portable),
                run(&both, isa),
            );
            for px in 0..5 * 18 {
                for k in 0..4 {
                    assert!((o[px * 8 + k] - oa[px * 4 + k]).abs() < 1e-5);
                    assert!((o[px * 8 + 4 + k] - ob[px * 4 + k]).abs() < 1e-5);
                }
            }
        }
    }
}
