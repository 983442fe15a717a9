//! Our own tract operator for the network's convolutions: a direct NCHW convolution with the
//! bias, a constant added map (the position biases) and the ReLU fused into its store.
//!
//! tract lowers each convolution to `Pad` + lazy im2col + a small packed matrix product, and
//! its direct spatial kernel only engages for output rows of at least 128 (`MIN_DIRECT_SPATIAL_W`
//! in tract-core's `ops/cnn/conv/conv.rs`); our rows are 8 to 32 wide. Here each convolution
//! runs as: one copy of the input into a zero-padded buffer whose columns are split by stride
//! phase (so every tap of a strided convolution reads 8 consecutive floats; the buffer is the
//! node's state, its padding written once), then a register-blocked loop over 4 output channels x
//! 2 vectors of 8 output pixels (8 accumulators: with 3 vectors, 12 accumulators + loads +
//! broadcast overflow AVX2's 16 registers and spill, measured 1.7x slower), AVX2 + FMA when the
//! CPU has them, checked once at run time, the same loop in scalar code otherwise. Bias, the
//! added map, the ReLU and a following depth-to-space are applied in the store.
//!
//! [`rewrite_convolutions`] swaps tract's `Conv` nodes for [`DirectConv`] in a typed model before
//! tract declutters and optimises it, fusing a following `Add` of a constant, a ReLU (`Max` with
//! 0) and a depth-to-space (PixelShuffle(2), which tract runs as two axis moves) when each is the
//! only consumer of what precedes it. The model's file is not changed: the
//! weights are the same, and `tests/direct_conv.rs` checks the rewritten plan against tract's own.
#![allow(
    unsafe_code,
    reason = "AVX2/FMA intrinsics of the direct convolution, behind runtime feature detection"
)]

use tract_onnx::prelude::*;
use tract_onnx::tract_core::internal::*;
use tract_onnx::tract_core::ops::binary::{BinMiniOp, TypedBinOp};
use tract_onnx::tract_core::ops::cnn::conv::{Conv, KernelFormat};
use tract_onnx::tract_core::ops::math::{Add, Max};
use tract_onnx::tract_core::ops::nn::DataFormat;

/// Output channels per register block.
const OB: usize = 4;
/// Output pixels per vector.
const LANES: usize = 8;
/// Vectors per register block (see the module documentation for why 2).
const NV: usize = 2;

/// A 2-D convolution (group 1, dilation 1, NCHW, f32) with constant weights, run directly.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct DirectConv {
    in_c: usize,
    out_c: usize,
    kh: usize,
    kw: usize,
    sh: usize,
    sw: usize,
    /// Zero padding: top, left, bottom, right.
    pad: [usize; 4],
    /// Weights packed per block of [`OB`] output channels: `[ocb][ic][ky][kx][OB]`, zero past
    /// `out_c`.
    packed: Arc<Tensor>,
    /// `[out_c]`.
    bias: Arc<Tensor>,
    /// Added after the bias: `[out_c, out_h, out_w]`, when a constant `Add` was fused.
    add_map: Option<Arc<Tensor>>,
    /// ReLU fused after the add.
    relu: bool,
    /// A following depth-to-space (PyTorch's PixelShuffle(2), ONNX DepthToSpace CRD, block 2)
    /// fused into the store: output `[n, out_c / 4, 2 out_h, 2 out_w]`, channel `4k + 2i + j`
    /// of pixel `(y, x)` written at `(k, 2y + i, 2x + j)`.
    shuffle: bool,
}

impl DirectConv {
    /// A convolution from OIHW weights `[out_c, in_c, kh, kw]` and a bias `[out_c]`.
    pub fn new(
        weights: &Tensor,
        bias: &[f32],
        strides: [usize; 2],
        pad: [usize; 4],
    ) -> TractResult<DirectConv> {
        let shape = weights.shape();
        ensure!(shape.len() == 4, "weights must be OIHW, got {shape:?}");
        let (out_c, in_c, kh, kw) = (shape[0], shape[1], shape[2], shape[3]);
        ensure!(
            bias.len() == out_c,
            "bias of {} for {out_c} outputs",
            bias.len()
        );
        ensure!(strides[0] >= 1 && strides[1] >= 1, "zero stride");
        ensure!(
            out_c > 0 && in_c > 0 && kh > 0 && kw > 0,
            "empty kernel {shape:?}"
        );
        let w = weights.cast_to::<f32>()?;
        let w = w.try_as_plain_ram()?;
        let w = w.as_slice::<f32>()?;
        let blocks = out_c.div_ceil(OB);
        let mut packed = vec![0.0f32; blocks * in_c * kh * kw * OB];
        for oc in 0..out_c {
            let (ocb, o) = (oc / OB, oc % OB);
            for ic in 0..in_c {
                for ky in 0..kh {
                    for kx in 0..kw {
                        let src = ((oc * in_c + ic) * kh + ky) * kw + kx;
                        let dst = ((((ocb * in_c + ic) * kh + ky) * kw + kx) * OB) + o;
                        packed[dst] = w[src];
                    }
                }
            }
        }
        Ok(DirectConv {
            in_c,
            out_c,
            kh,
            kw,
            sh: strides[0],
            sw: strides[1],
            pad,
            packed: Arc::new(tensor1(&packed)),
            bias: Arc::new(tensor1(bias)),
            add_map: None,
            relu: false,
            shuffle: false,
        })
    }

    /// Output height and width for an input of `h` x `w`.
    pub fn output_hw(&self, h: usize, w: usize) -> TractResult<(usize, usize)> {
        let ph = h + self.pad[0] + self.pad[2];
        let pw = w + self.pad[1] + self.pad[3];
        ensure!(
            ph >= self.kh && pw >= self.kw,
            "input {h}x{w} smaller than kernel"
        );
        Ok(((ph - self.kh) / self.sh + 1, (pw - self.kw) / self.sw + 1))
    }

    /// Fuses `+ map` (any constant broadcastable to `[out_c, out_h, out_w]`) after the bias.
    fn with_add(mut self, map: &Tensor, out_h: usize, out_w: usize) -> TractResult<DirectConv> {
        ensure!(self.add_map.is_none() && !self.relu);
        let full = [self.out_c, out_h, out_w];
        let mut shape: TVec<usize> = map.shape().into();
        while shape.len() > 3 {
            ensure!(shape[0] == 1, "added map {:?} not per image", map.shape());
            shape.remove(0);
        }
        while shape.len() < 3 {
            shape.insert(0, 1);
        }
        let map = map.cast_to::<f32>()?.into_owned().into_shape(&shape)?;
        let map = map.broadcast_to_shape(&full)?;
        self.add_map = Some(Arc::new(map));
        Ok(self)
    }

    /// The output shape `[c, h, w]` per image for an input of `h` x `w`.
    fn output_chw(&self, h: usize, w: usize) -> TractResult<[usize; 3]> {
        let (oh, ow) = self.output_hw(h, w)?;
        Ok(if self.shuffle {
            [self.out_c / 4, 2 * oh, 2 * ow]
        } else {
            [self.out_c, oh, ow]
        })
    }

    fn with_relu(mut self) -> DirectConv {
        self.relu = true;
        self
    }

    /// Runs the convolution on `input` `[n, in_c, h, w]`, writing `[n, out_c, out_h, out_w]`.
    pub fn run(
        &self,
        input: &[f32],
        n: usize,
        h: usize,
        w: usize,
        out: &mut [f32],
    ) -> TractResult<()> {
        self.run_with(&mut Scratch::default(), input, n, h, w, out)
    }

    /// [`DirectConv::run`] reusing `scratch` (the padded input buffer: its padding stays zero
    /// from one call to the next, only the interior is rewritten).
    fn run_with(
        &self,
        scratch: &mut Scratch,
        input: &[f32],
        n: usize,
        h: usize,
        w: usize,
        out: &mut [f32],
    ) -> TractResult<()> {
        let (oh, ow) = self.output_hw(h, w)?;
        ensure!(input.len() == n * self.in_c * h * w, "input size");
        ensure!(out.len() == n * self.out_c * oh * ow, "output size");
        if scratch.geo.as_ref().is_none_or(|g| (g.h, g.w) != (h, w)) {
            let geo = Geometry::new(self, h, w, oh, ow);
            scratch.buf = vec![0.0f32; geo.buf_len];
            scratch.geo = Some(geo);
        }
        let Scratch {
            geo: Some(geo),
            buf,
        } = scratch
        else {
            bail!("DirectConv scratch without geometry");
        };
        let packed = self.packed.try_as_plain_ram()?;
        let packed = packed.as_slice::<f32>()?;
        let bias = self.bias.try_as_plain_ram()?;
        let bias = bias.as_slice::<f32>()?;
        let add_map = match &self.add_map {
            Some(m) => Some(m.try_as_plain_ram()?),
            None => None,
        };
        let add_map = match &add_map {
            Some(m) => Some(m.as_slice::<f32>()?),
            None => None,
        };
        let image_in = self.in_c * h * w;
        let image_out = self.out_c * oh * ow;
        for img in 0..n {
            let image = &input[img * image_in..][..image_in];
            // Without padding, stride phases or extra columns the buffer would be a copy of
            // the image: read the image itself (the 1x1 convolutions).
            let buf: &[f32] = if geo.reads_input_in_place() {
                image
            } else {
                geo.fill(buf, image);
                buf
            };
            let out = &mut out[img * image_out..][..image_out];
            let job = Job {
                conv: self,
                geo,
                buf,
                packed,
                bias,
                add_map,
            };
            job.run(out);
        }
        Ok(())
    }
}

/// The padded input buffer and its geometry, kept by the plan's state between calls.
#[derive(Debug, Clone, Default)]
struct Scratch {
    geo: Option<Geometry>,
    buf: Vec<f32>,
}

/// The per-session state of a [`DirectConv`] node: its scratch.
#[derive(Debug, Clone, Default)]
struct DirectConvState {
    scratch: Scratch,
}

impl OpState for DirectConvState {
    fn eval(
        &mut self,
        _ctx: &EvalContext,
        op: &dyn Op,
        inputs: TVec<TValue>,
    ) -> TractResult<TVec<TValue>> {
        let op = op
            .downcast_ref::<DirectConv>()
            .context("DirectConvState on another op")?;
        op.eval_into(&mut self.scratch, inputs)
    }

    fn reset_lanes(&mut self, _lanes: &[LaneId]) -> TractResult<()> {
        // The scratch holds no values from one call to the next, only zero padding.
        Ok(())
    }
}

/// Shapes and offsets of one call: the padded, phase-split input buffer and the taps.
#[derive(Debug, Clone)]
struct Geometry {
    in_c: usize,
    h: usize,
    w: usize,
    oh: usize,
    ow: usize,
    sw: usize,
    pad_top: usize,
    pad_left: usize,
    /// Rows of the padded input.
    hp: usize,
    /// Columns of one stride phase of the padded input, with room for the last vector.
    wq: usize,
    buf_len: usize,
    /// Offset of each tap `(ky, kx)` from a vector's base, within one input channel.
    taps: Vec<usize>,
    /// Per output vector: its base offset in the buffer (a table, so the hot loops divide
    /// nothing; apart from [`Geometry::dests`] so that a block borrows its `N` entries of each
    /// as arrays instead of copying them).
    bases: Vec<usize>,
    /// Per output vector: its offset `y * ow + x0` in an output plane, its lanes inside the
    /// row, its row `y`.
    dests: Vec<(usize, usize, usize)>,
    /// The register blocks of one output-channel block: first vector and vector count.
    blocks: Vec<(usize, usize)>,
    /// Per stride phase: the first input column of the phase and its offset in the buffer row.
    phases: Vec<(usize, usize)>,
}

impl Geometry {
    fn new(c: &DirectConv, h: usize, w: usize, oh: usize, ow: usize) -> Geometry {
        let vecs_per_row = ow.div_ceil(LANES);
        let hp = h + c.pad[0] + c.pad[2];
        let wp = w + c.pad[1] + c.pad[3];
        // Phase p holds the padded columns p, p + sw, ...; the last vector of a row reads up to
        // column vecs_per_row * LANES - 1 + (kw - 1) / sw of a phase.
        let wq = wp
            .div_ceil(c.sw)
            .max(vecs_per_row * LANES + (c.kw - 1) / c.sw);
        let taps = (0..c.kh)
            .flat_map(|ky| (0..c.kw).map(move |kx| ((kx % c.sw) * hp + ky) * wq + kx / c.sw))
            .collect();
        Geometry {
            in_c: c.in_c,
            h,
            w,
            oh,
            ow,
            sw: c.sw,
            pad_top: c.pad[0],
            pad_left: c.pad[1],
            bases: (0..oh * vecs_per_row)
                .map(|v| (v / vecs_per_row) * c.sh * wq + (v % vecs_per_row) * LANES)
                .collect(),
            dests: (0..oh * vecs_per_row)
                .map(|v| {
                    let (y, x0) = (v / vecs_per_row, (v % vecs_per_row) * LANES);
                    (y * ow + x0, (ow - x0).min(LANES), y)
                })
                .collect(),
            blocks: register_blocks(oh * vecs_per_row),
            phases: (0..c.sw)
                .map(|phase| {
                    // The smallest x >= 0 with (x + pad_left) % sw == phase.
                    let first = (phase + c.sw - c.pad[1] % c.sw) % c.sw;
                    (first, phase * hp * wq + (first + c.pad[1]) / c.sw)
                })
                .collect(),
            hp,
            wq,
            buf_len: c.in_c * c.sw * hp * wq,
            taps,
        }
    }

    /// Whether the padded, phase-split buffer has the image's own layout (no padding, stride 1
    /// across, rows of whole vectors), so that the convolution can read the image in place.
    fn reads_input_in_place(&self) -> bool {
        self.sw == 1 && self.hp == self.h && self.wq == self.w
    }

    /// Floats of one input channel in the buffer.
    fn channel_len(&self) -> usize {
        self.sw * self.hp * self.wq
    }

    /// Copies one image into the padded, phase-split buffer (the padding stays zero).
    fn fill(&self, buf: &mut [f32], image: &[f32]) {
        let sw = self.sw;
        for ic in 0..self.in_c {
            for y in 0..self.h {
                let row = &image[(ic * self.h + y) * self.w..][..self.w];
                let base = ic * self.channel_len() + (y + self.pad_top) * self.wq;
                if sw == 1 {
                    buf[base + self.pad_left..][..self.w].copy_from_slice(row);
                    continue;
                }
                // Padded column c = x + pad_left lands in phase c % sw at c / sw: per phase,
                // a strided read of the row and a contiguous write. As chunks of `sw` (not
                // `step_by`), so that the compiler turns it into vector shuffles.
                for &(first, offset) in &self.phases {
                    let dst = &mut buf[base + offset..];
                    let src = &row[first.min(self.w)..];
                    match sw {
                        2 => copy_phase2(dst, src),
                        _ => {
                            for (d, &v) in dst.iter_mut().zip(src.iter().step_by(sw)) {
                                *d = v;
                            }
                        }
                    }
                }
            }
        }
    }
}

/// `dst[k] = src[k * S]` for every `k` both have: one stride phase of an input row. With the
/// stride a constant the loop has no division and becomes vector shuffles.
fn copy_phase<const S: usize>(dst: &mut [f32], src: &[f32]) {
    let chunks = src.chunks_exact(S);
    let tail = chunks.remainder().first();
    let mut written = 0;
    for (d, chunk) in dst.iter_mut().zip(chunks) {
        *d = chunk[0];
        written += 1;
    }
    if let (Some(&v), Some(d)) = (tail, dst.get_mut(written)) {
        *d = v;
    }
}

/// [`copy_phase`] for stride 2, the stride of every strided convolution of ours: with AVX2, 16
/// floats at a time split into their even lanes by two shuffles (the scalar copy, one float at a
/// time, held the hottest lines of `run_with`'s own time in `perf annotate`). The same floats,
/// moved.
fn copy_phase2(dst: &mut [f32], src: &[f32]) {
    #[cfg(target_arch = "x86_64")]
    if simd_available() {
        // SAFETY: AVX2 is present (checked at run time); the function checks its own bounds.
        unsafe { copy_phase2_avx2(dst, src) };
        return;
    }
    copy_phase::<2>(dst, src);
}

/// [`copy_phase2`] with AVX2.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn copy_phase2_avx2(dst: &mut [f32], src: &[f32]) {
    use std::arch::x86_64::*;
    // As many outputs as `copy_phase` writes.
    let n = dst.len().min(src.len().div_ceil(2));
    let mut k = 0;
    while k + LANES <= n && 2 * k + 2 * LANES <= src.len() {
        // SAFETY: the 16 floats read and the 8 written are in bounds by the loop condition.
        unsafe {
            let a = _mm256_loadu_ps(src.as_ptr().add(2 * k));
            let b = _mm256_loadu_ps(src.as_ptr().add(2 * k + LANES));
            // Per 128-bit lane: a0 a2 b0 b2 | a4 a6 b4 b6; then the 64-bit pairs reordered
            // 0, 2, 1, 3: s0 s2 s4 s6 s8 s10 s12 s14.
            let even = _mm256_shuffle_ps::<0b10_00_10_00>(a, b);
            let even = _mm256_castpd_ps(_mm256_permute4x64_pd::<0b11_01_10_00>(_mm256_castps_pd(
                even,
            )));
            _mm256_storeu_ps(dst.as_mut_ptr().add(k), even);
        }
        k += LANES;
    }
    copy_phase::<2>(&mut dst[k..n], &src[2 * k..]);
}

/// `vectors` output vectors in register blocks of [`NV`], balanced (4 vectors as 2 + 2, not
/// 3 + 1: a block of one vector has too few accumulators to keep the FMA units busy): each
/// block's first vector and count.
fn register_blocks(vectors: usize) -> Vec<(usize, usize)> {
    let blocks = vectors.div_ceil(NV);
    (0..blocks)
        .map(|b| {
            let v = vectors * b / blocks;
            (v, vectors * (b + 1) / blocks - v)
        })
        .collect()
}

/// One image's convolution: inputs prepared, output to write.
struct Job<'a> {
    conv: &'a DirectConv,
    geo: &'a Geometry,
    buf: &'a [f32],
    packed: &'a [f32],
    bias: &'a [f32],
    add_map: Option<&'a [f32]>,
}

impl Job<'_> {
    fn run(&self, out: &mut [f32]) {
        let g = self.geo;
        let per_block = g.in_c * g.taps.len() * OB;
        for ocb in 0..self.conv.out_c.div_ceil(OB) {
            let weights = &self.packed[ocb * per_block..][..per_block];
            let epilogue = Epilogue {
                plane: g.oh * g.ow,
                first_oc: ocb * OB,
                out_c: self.conv.out_c,
                bias: self.bias,
                map: self.add_map,
                relu: self.conv.relu,
                shuffle: self.conv.shuffle,
                ow: g.ow,
            };
            for &(v, nv) in &g.blocks {
                match nv {
                    3 => self.block::<3>(weights, &epilogue, v, out),
                    2 => self.block::<2>(weights, &epilogue, v, out),
                    _ => self.block::<1>(weights, &epilogue, v, out),
                }
            }
        }
    }

    /// `OB` output channels (`weights`: their block) x `N` vectors from vector `v0`:
    /// accumulate, then bias, added map, ReLU and store of the lanes inside the output row.
    fn block<const N: usize>(
        &self,
        weights: &[f32],
        epilogue: &Epilogue,
        v0: usize,
        out: &mut [f32],
    ) {
        let g = self.geo;
        // Borrowed in place: copying these small arrays onto the stack cost a store-forwarding
        // stall per block (the profile's hottest instruction outside the sums).
        let (Some(bases), Some(dest)) = (
            g.bases[v0..].first_chunk::<N>(),
            g.dests[v0..].first_chunk::<N>(),
        ) else {
            unreachable!("register blocks lie inside the vector tables")
        };
        let ocb = epilogue.first_oc / OB;
        let plane = epilogue.plane;
        let mut acc = [[[0.0f32; LANES]; N]; OB];
        #[cfg(target_arch = "x86_64")]
        if simd_available() {
            let (buf, acc) = (self.buf, &mut acc);
            // SAFETY: AVX2 and FMA are present (checked at run time); the function checks its
            // own bounds. It stores the vectors whose 8 lanes are all inside the row itself.
            // The 3x3 and 1x1 tap loops get a constant trip count, so they unroll.
            unsafe {
                match g.taps.len() {
                    9 => accumulate_avx2::<N, 9>(buf, weights, g, bases, acc, epilogue, dest, out),
                    1 => accumulate_avx2::<N, 1>(buf, weights, g, bases, acc, epilogue, dest, out),
                    _ => accumulate_avx2::<N, 0>(buf, weights, g, bases, acc, epilogue, dest, out),
                }
            };
            if dest.iter().all(|&(_, lanes, _)| lanes == LANES) {
                return;
            }
        } else {
            accumulate_scalar::<N>(self.buf, weights, g, bases, &mut acc);
        }
        #[cfg(not(target_arch = "x86_64"))]
        accumulate_scalar::<N>(self.buf, weights, g, bases, &mut acc);
        let simd_stored = cfg!(target_arch = "x86_64") && simd_available_any();
        for (o, rows) in acc.iter().enumerate() {
            let oc = ocb * OB + o;
            if oc >= self.conv.out_c {
                break;
            }
            for (row, &(at, lanes, y)) in rows.iter().zip(dest) {
                if simd_stored && lanes == LANES {
                    continue;
                }
                let x0 = at - y * g.ow;
                for (l, &a) in row[..lanes].iter().enumerate() {
                    out[epilogue.dst(oc, y, x0 + l)] = epilogue.apply(a, oc, oc * plane + at + l);
                }
            }
        }
    }
}

/// What follows the sums: bias, added map, ReLU.
struct Epilogue<'a> {
    plane: usize,
    first_oc: usize,
    out_c: usize,
    bias: &'a [f32],
    map: Option<&'a [f32]>,
    relu: bool,
    shuffle: bool,
    ow: usize,
}

impl Epilogue<'_> {
    /// Output index of channel `oc` at row `y`, column `x` of the convolution's plane.
    fn dst(&self, oc: usize, y: usize, x: usize) -> usize {
        if !self.shuffle {
            return oc * self.plane + y * self.ow + x;
        }
        let (k, i, j) = (oc / 4, (oc / 2) % 2, oc % 2);
        k * 4 * self.plane + (2 * y + i) * 2 * self.ow + 2 * x + j
    }

    fn apply(&self, sum: f32, oc: usize, at: usize) -> f32 {
        let mut value = sum + self.bias[oc];
        if let Some(map) = self.map {
            value += map[at];
        }
        if self.relu { value.max(0.0) } else { value }
    }
}

fn simd_available_any() -> bool {
    #[cfg(target_arch = "x86_64")]
    return simd_available();
    #[cfg(not(target_arch = "x86_64"))]
    false
}

#[cfg(target_arch = "x86_64")]
fn simd_available() -> bool {
    #[cfg(test)]
    if tests::FORCE_PLAIN.with(|f| f.get()) {
        return false;
    }
    static AVAILABLE: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *AVAILABLE.get_or_init(|| {
        std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
    })
}

/// The register block in plain Rust: the path without AVX2 + FMA.
fn accumulate_scalar<const N: usize>(
    buf: &[f32],
    weights: &[f32],
    g: &Geometry,
    bases: &[usize; N],
    acc: &mut [[[f32; LANES]; N]; OB],
) {
    let taps = g.taps.len();
    for ic in 0..g.in_c {
        let channel = ic * g.channel_len();
        for (t, &tap) in g.taps.iter().enumerate() {
            let w = &weights[(ic * taps + t) * OB..][..OB];
            for (j, &base) in bases.iter().enumerate() {
                let x = &buf[channel + tap + base..][..LANES];
                for (o, &wo) in w.iter().enumerate() {
                    for (a, &xl) in acc[o][j].iter_mut().zip(x) {
                        *a += wo * xl;
                    }
                }
            }
        }
    }
}

/// [`accumulate_scalar`] with AVX2 + FMA: `OB * N` accumulators in registers, one unaligned
/// load per vector and one broadcast per output channel for each input channel and tap; `T`
/// taps (0: as many as the geometry has).
///
/// # Safety
/// The CPU must support AVX2 and FMA.
// Index loops over the register arrays on purpose: they unroll into straight register code.
#[allow(clippy::too_many_arguments, clippy::needless_range_loop)]
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn accumulate_avx2<const N: usize, const T: usize>(
    buf: &[f32],
    weights: &[f32],
    g: &Geometry,
    bases: &[usize; N],
    acc: &mut [[[f32; LANES]; N]; OB],
    epilogue: &Epilogue,
    dest: &[(usize, usize, usize); N],
    out: &mut [f32],
) {
    use std::arch::x86_64::*;
    // T taps when T > 0 (a constant trip count), all of them otherwise.
    let taps = if T == 0 { g.taps.len() } else { T };
    assert_eq!(taps, g.taps.len());
    // Every read below stays inside `buf` and `weights`: the furthest vector read starts at
    // the last channel's furthest tap plus the furthest base, and ends LANES floats later.
    let max_tap = g.taps.iter().copied().max().unwrap_or(0);
    let max_base = bases.iter().copied().max().unwrap_or(0);
    assert!((g.in_c - 1) * g.channel_len() + max_tap + max_base + LANES <= buf.len());
    assert!(weights.len() >= g.in_c * taps * OB);
    let mut a = [[_mm256_setzero_ps(); N]; OB];
    let bp = buf.as_ptr();
    let mut wp = weights.as_ptr();
    for ic in 0..g.in_c {
        let channel = ic * g.channel_len();
        for t in 0..taps {
            // SAFETY: in bounds by the asserts above.
            unsafe {
                let tap = *g.taps.get_unchecked(t);
                // No closures here: they would not inherit this function's target features.
                let mut x = [_mm256_setzero_ps(); N];
                for j in 0..N {
                    x[j] = _mm256_loadu_ps(bp.add(channel + tap + bases[j]));
                }
                for o in 0..OB {
                    let w = _mm256_broadcast_ss(&*wp.add(o));
                    for j in 0..N {
                        a[o][j] = _mm256_fmadd_ps(w, x[j], a[o][j]);
                    }
                }
                wp = wp.add(OB);
            }
        }
    }
    // Epilogue: full vectors go straight to the output, partial ones to `acc` for the caller.
    let zero = _mm256_setzero_ps();
    if epilogue.shuffle {
        // SAFETY: AVX2 is present (this function's own requirement).
        unsafe { store_shuffled::<N>(&a, acc, epilogue, dest, out) };
        return;
    }
    for o in 0..OB {
        let oc = epilogue.first_oc + o;
        if oc >= epilogue.out_c {
            break;
        }
        let bias = _mm256_set1_ps(epilogue.bias[oc]);
        for j in 0..N {
            let (at, lanes, _) = dest[j];
            if lanes < LANES {
                // SAFETY: `acc[o][j]` is LANES floats.
                unsafe { _mm256_storeu_ps(acc[o][j].as_mut_ptr(), a[o][j]) };
                continue;
            }
            let at = oc * epilogue.plane + at;
            assert!(at + LANES <= out.len());
            let mut v = _mm256_add_ps(a[o][j], bias);
            if let Some(map) = epilogue.map {
                assert!(at + LANES <= map.len());
                // SAFETY: in bounds by the assert.
                v = _mm256_add_ps(v, unsafe { _mm256_loadu_ps(map.as_ptr().add(at)) });
            }
            if epilogue.relu {
                v = _mm256_max_ps(v, zero);
            }
            // SAFETY: in bounds by the assert.
            unsafe { _mm256_storeu_ps(out.as_mut_ptr().add(at), v) };
        }
    }
}

/// The epilogue of a block fused with depth-to-space: the block's 4 channels are `4k + 2i + j`
/// for one `k` (blocks of [`OB`] = 4, `out_c` a multiple of 4), so channels `j = 0, 1` of a row
/// `i` interleave into 16 consecutive outputs of row `2y + i`.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[allow(clippy::needless_range_loop)]
unsafe fn store_shuffled<const N: usize>(
    a: &[[std::arch::x86_64::__m256; N]; OB],
    acc: &mut [[[f32; LANES]; N]; OB],
    epilogue: &Epilogue,
    dest: &[(usize, usize, usize); N],
    out: &mut [f32],
) {
    use std::arch::x86_64::*;
    let zero = _mm256_setzero_ps();
    let k = epilogue.first_oc / 4;
    for j in 0..N {
        let (at, lanes, y) = dest[j];
        if lanes < LANES {
            for o in 0..OB {
                // SAFETY: `acc[o][j]` is LANES floats.
                unsafe { _mm256_storeu_ps(acc[o][j].as_mut_ptr(), a[o][j]) };
            }
            continue;
        }
        let mut v = [zero; OB];
        for o in 0..OB {
            let oc = epilogue.first_oc + o;
            v[o] = _mm256_add_ps(a[o][j], _mm256_set1_ps(epilogue.bias[oc]));
            if let Some(map) = epilogue.map {
                let m = oc * epilogue.plane + at;
                assert!(m + LANES <= map.len());
                // SAFETY: in bounds by the assert.
                v[o] = _mm256_add_ps(v[o], unsafe { _mm256_loadu_ps(map.as_ptr().add(m)) });
            }
            if epilogue.relu {
                v[o] = _mm256_max_ps(v[o], zero);
            }
        }
        let x = at - y * epilogue.ow;
        for i in 0..2 {
            let row = k * 4 * epilogue.plane + (2 * y + i) * 2 * epilogue.ow + 2 * x;
            assert!(row + 2 * LANES <= out.len());
            let lo = _mm256_unpacklo_ps(v[2 * i], v[2 * i + 1]);
            let hi = _mm256_unpackhi_ps(v[2 * i], v[2 * i + 1]);
            // SAFETY: in bounds by the assert.
            unsafe {
                _mm256_storeu_ps(
                    out.as_mut_ptr().add(row),
                    _mm256_permute2f128_ps(lo, hi, 0x20),
                );
                _mm256_storeu_ps(
                    out.as_mut_ptr().add(row + LANES),
                    _mm256_permute2f128_ps(lo, hi, 0x31),
                );
            }
        }
    }
}

impl Op for DirectConv {
    fn name(&self) -> StaticName {
        "DirectConv".into()
    }

    fn info(&self) -> TractResult<Vec<String>> {
        Ok(vec![format!(
            "{}->{} {}x{} stride {}x{} pad {:?}{}{}{}",
            self.in_c,
            self.out_c,
            self.kh,
            self.kw,
            self.sh,
            self.sw,
            self.pad,
            if self.add_map.is_some() { " +map" } else { "" },
            if self.relu { " relu" } else { "" },
            if self.shuffle {
                " depth-to-space 2"
            } else {
                ""
            }
        )])
    }

    op_as_typed_op!();
}

impl DirectConv {
    fn eval_into(&self, scratch: &mut Scratch, inputs: TVec<TValue>) -> TractResult<TVec<TValue>> {
        ensure!(inputs.len() == 1, "DirectConv takes one input");
        let shape = inputs[0].shape().to_vec();
        ensure!(
            shape.len() == 4 && shape[1] == self.in_c,
            "DirectConv input {shape:?}, expected [N, {}, H, W]",
            self.in_c
        );
        let (n, h, w) = (shape[0], shape[2], shape[3]);
        let input = inputs[0].try_as_plain_ram()?;
        let [c, oh, ow] = self.output_chw(h, w)?;
        // SAFETY: f32 has no invalid bit patterns, and `run_with` writes every output element
        // (every channel, row and column) before anything reads it.
        let mut out = unsafe { Tensor::uninitialized::<f32>(&[n, c, oh, ow])? };
        {
            let mut view = out.try_as_plain_ram_mut()?;
            self.run_with(
                scratch,
                input.as_slice::<f32>()?,
                n,
                h,
                w,
                view.as_slice_mut::<f32>()?,
            )?;
        }
        Ok(tvec!(out.into_tvalue()))
    }
}

impl EvalOp for DirectConv {
    op_out_of_plan!();

    fn eval(&self, _ctx: &EvalContext, inputs: TVec<TValue>) -> TractResult<TVec<TValue>> {
        self.eval_into(&mut Scratch::default(), inputs)
    }

    fn state(&self, _ctx: &EvalContext) -> TractResult<Option<Box<dyn OpState>>> {
        Ok(Some(Box::new(DirectConvState::default())))
    }
}

impl TypedOp for DirectConv {
    as_op!();

    fn output_facts(&self, inputs: &[&TypedFact]) -> TractResult<TVec<TypedFact>> {
        let shape = &inputs[0].shape;
        ensure!(
            inputs[0].datum_type == f32::datum_type(),
            "DirectConv runs on f32"
        );
        ensure!(shape.rank() == 4, "DirectConv input rank {}", shape.rank());
        let h = shape[2].to_usize()?;
        let w = shape[3].to_usize()?;
        let [c, oh, ow] = self.output_chw(h, w)?;
        Ok(tvec!(f32::fact([
            shape[0].clone(),
            c.to_dim(),
            oh.to_dim(),
            ow.to_dim()
        ])))
    }
}

/// What the rewrite did, for logs and tests.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RewriteSummary {
    /// Convolutions replaced by [`DirectConv`].
    pub convolutions: usize,
    /// Constant `Add`s fused into them.
    pub fused_adds: usize,
    /// ReLUs fused into them.
    pub fused_relus: usize,
    /// Depth-to-space (pixel shuffle) chains fused into them.
    pub fused_shuffles: usize,
}

/// Replaces every f32 `Conv` of a typed (not yet decluttered) model that [`DirectConv`] can run
/// (group 1, dilation 1, NCHW, OIHW, constant weights and bias, known spatial input size) by a
/// [`DirectConv`], fusing a following constant `Add` and ReLU where the convolution's output
/// feeds nothing else. Other convolutions are left to tract.
pub fn rewrite_convolutions(model: &mut TypedModel) -> TractResult<RewriteSummary> {
    let mut summary = RewriteSummary::default();
    for id in model.eval_order()? {
        let Some((op, last, fused)) = plan_replacement(model, id)? else {
            continue;
        };
        let mut patch = TypedModelPatch::default();
        let tap = patch.tap_model(model, model.node(id).inputs[0])?;
        let name = model.node(id).name.clone();
        let out = patch.wire_node(format!("{name}.direct"), op, &[tap])?[0];
        patch.shunt_outside(model, OutletId::new(last, 0), out)?;
        patch.apply(model)?;
        summary.convolutions += 1;
        summary.fused_adds += usize::from(fused.add);
        summary.fused_relus += usize::from(fused.relu);
        summary.fused_shuffles += usize::from(fused.shuffle);
    }
    Ok(summary)
}

/// What was fused into one replacement.
#[derive(Debug, Clone, Copy, Default)]
struct Fused {
    add: bool,
    relu: bool,
    shuffle: bool,
}

/// The replacement for node `id` if it is a convolution we run: the op, the last node it
/// covers, and what was fused.
fn plan_replacement(
    model: &TypedModel,
    id: usize,
) -> TractResult<Option<(DirectConv, usize, Fused)>> {
    let node = model.node(id);
    let Some(conv) = node.op_as::<Conv>() else {
        return Ok(None);
    };
    let spec = &conv.pool_spec;
    let input = model.outlet_fact(node.inputs[0])?;
    if conv.q_params.is_some()
        || conv.group != 1
        || conv.kernel_fmt != KernelFormat::OIHW
        || spec.data_format != DataFormat::NCHW
        || spec.rank() != 2
        || spec.dilations().iter().any(|&d| d != 1)
        || input.datum_type != f32::datum_type()
        || input.rank() != 4
        || node.inputs.len() != 3
    {
        return Ok(None);
    }
    let (Ok(h), Ok(w)) = (input.shape[2].to_usize(), input.shape[3].to_usize()) else {
        return Ok(None);
    };
    let Some((kernel, bias)) = kernel_and_bias(model, node)? else {
        return Ok(None);
    };
    if kernel.shape()
        != [
            spec.output_channels,
            spec.input_channels,
            spec.kernel_shape[0],
            spec.kernel_shape[1],
        ]
    {
        return Ok(None);
    }
    let padding = spec.computed_padding(&[h, w]);
    let pad = [
        padding[0].pad_before,
        padding[1].pad_before,
        padding[0].pad_after,
        padding[1].pad_after,
    ];
    let bias = bias.cast_to::<f32>()?;
    let bias_plain = bias.try_as_plain_ram()?;
    let bias_values = bias_plain.as_slice::<f32>()?;
    let bias: Vec<f32> = match bias_values.len() {
        1 => vec![bias_values[0]; spec.output_channels],
        n if n == spec.output_channels => bias_values.to_vec(),
        _ => return Ok(None),
    };
    let strides = spec.strides();
    let mut op = DirectConv::new(&kernel, &bias, [strides[0], strides[1]], pad)?;
    let (oh, ow) = op.output_hw(h, w)?;
    // The declared output must be what we compute.
    let declared = &model.outlet_fact(OutletId::new(id, 0))?.shape;
    if declared.rank() != 4
        || declared[1].to_usize().ok() != Some(op.out_c)
        || declared[2].to_usize().ok() != Some(oh)
        || declared[3].to_usize().ok() != Some(ow)
    {
        return Ok(None);
    }
    let mut last = id;
    let mut fused = Fused::default();
    if let Some((next, konst)) = sole_binary_consumer::<Add>(model, last)? {
        if let Ok(fused_op) = op.clone().with_add(&konst, oh, ow) {
            op = fused_op;
            last = next;
            fused.add = true;
        }
    }
    if let Some((next, konst)) = sole_binary_consumer::<Max>(model, last)? {
        let zero = konst.len() == 1
            && konst
                .cast_to::<f32>()?
                .try_as_plain_ram()?
                .as_slice::<f32>()?[0]
                == 0.0;
        if zero {
            op = op.with_relu();
            last = next;
            fused.relu = true;
        }
    }
    if op.out_c % 4 == 0
        && let Some(end) = depth_to_space_chain(model, last, op.out_c, oh, ow)?
    {
        op.shuffle = true;
        last = end;
        fused.shuffle = true;
    }
    Ok(Some((op, last, fused)))
}

/// The last node of the chain of axis ops after node `id` (output `[n, c, h, w]`) when the
/// whole chain, each link the only consumer of the one before, is depth-to-space with block 2
/// in CRD order (PyTorch's PixelShuffle(2)). tract's ONNX import writes DepthToSpace as such a
/// chain of reshapes and axis moves; which order it encodes is checked here by running the
/// chain on a tensor of indices, not by reading its ops.
pub(crate) fn depth_to_space_chain(
    model: &TypedModel,
    id: usize,
    c: usize,
    h: usize,
    w: usize,
) -> TractResult<Option<usize>> {
    let mut chain = vec![];
    let mut cur = id;
    loop {
        let node = model.node(cur);
        let outlet = OutletId::new(cur, 0);
        if node.outputs.len() != 1
            || node.outputs[0].successors.len() != 1
            || model.output_outlets()?.contains(&outlet)
        {
            break;
        }
        let next = model.node(node.outputs[0].successors[0].node);
        if next.op_as::<AxisOp>().is_none() || next.inputs.len() != 1 {
            break;
        }
        chain.push(next.id);
        cur = next.id;
    }
    let Some(&end) = chain.last() else {
        return Ok(None);
    };
    let Ok(n) = model.outlet_fact(OutletId::new(id, 0))?.shape[0].to_usize() else {
        return Ok(None);
    };
    let end_shape = &model.outlet_fact(OutletId::new(end, 0))?.shape;
    let want = [n, c / 4, 2 * h, 2 * w];
    if end_shape.as_concrete() != Some(&want[..]) {
        return Ok(None);
    }
    let len = n * c * h * w;
    let iota: Vec<f32> = (0..len).map(|i| i as f32).collect();
    let mut value = Tensor::from_shape(&[n, c, h, w], &iota)?.into_tvalue();
    for &link in &chain {
        let Some(out) = model.node(link).op().eval_out_of_plan(tvec!(value))? else {
            return Ok(None);
        };
        value = out[0].clone();
    }
    let got = value.try_as_plain_ram()?;
    let got = got.as_slice::<f32>()?;
    let plane = h * w;
    for (dst, &v) in got.iter().enumerate() {
        let (img, rest) = (dst / (c * plane), dst % (c * plane));
        let (k, rest) = (rest / (4 * plane), rest % (4 * plane));
        let (yy, xx) = (rest / (2 * w), rest % (2 * w));
        let src = ((img * c + 4 * k + 2 * (yy % 2) + xx % 2) * h + yy / 2) * w + xx / 2;
        if v != src as f32 {
            return Ok(None);
        }
    }
    Ok(Some(end))
}

/// A convolution node's weights and bias (its inputs 1 and 2), when both are constants.
pub(crate) fn kernel_and_bias(
    model: &TypedModel,
    node: &TypedNode,
) -> TractResult<Option<(Arc<Tensor>, Arc<Tensor>)>> {
    Ok(
        match (
            constant(model, node.inputs[1])?,
            constant(model, node.inputs[2])?,
        ) {
            (Some(kernel), Some(bias)) => Some((kernel, bias)),
            _ => None,
        },
    )
}

/// The value of a wire that is a constant, or a cast of one (ONNX import casts biases; tract
/// folds those casts only while decluttering, after our rewrite).
pub(crate) fn constant(model: &TypedModel, outlet: OutletId) -> TractResult<Option<Arc<Tensor>>> {
    if let Some(konst) = &model.outlet_fact(outlet)?.konst {
        return Ok(Some(konst.clone()));
    }
    let node = model.node(outlet.node);
    if let Some(cast) = node.op_as::<tract_onnx::tract_core::ops::cast::Cast>()
        && node.inputs.len() == 1
        && let Some(source) = constant(model, node.inputs[0])?
    {
        return Ok(Some(Arc::new(source.cast_to_dt(cast.to)?.into_owned())));
    }
    Ok(None)
}

/// The node consuming node `id`'s only output, when it is its only consumer, `id` is not a
/// model output, and it is the binary op `B` with a constant on its other side that does not
/// change the output's shape.
fn sole_binary_consumer<B: BinMiniOp>(
    model: &TypedModel,
    id: usize,
) -> TractResult<Option<(usize, Arc<Tensor>)>> {
    let node = model.node(id);
    let outlet = OutletId::new(id, 0);
    if node.outputs.len() != 1
        || node.outputs[0].successors.len() != 1
        || model.output_outlets()?.contains(&outlet)
    {
        return Ok(None);
    }
    let next = model.node(node.outputs[0].successors[0].node);
    let Some(bin) = next.op_as::<TypedBinOp>() else {
        return Ok(None);
    };
    if !bin.0.is::<B>() || bin.1.is_some() || next.inputs.len() != 2 {
        return Ok(None);
    }
    let other = if next.inputs[0] == outlet {
        next.inputs[1]
    } else {
        next.inputs[0]
    };
    let Some(konst) = constant(model, other)? else {
        return Ok(None);
    };
    if model.outlet_fact(OutletId::new(next.id, 0))?.shape != model.outlet_fact(outlet)?.shape
        || konst.datum_type() != f32::datum_type()
    {
        return Ok(None);
    }
    Ok(Some((next.id, konst)))
}

#[cfg(test)]
mod tests {
    use super::*;

    thread_local! {
        /// Makes this thread's convolutions take the plain-Rust path.
        pub(super) static FORCE_PLAIN: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
    }

    /// Deterministic values in [-1, 1).
    fn values(n: usize, seed: u64) -> Vec<f32> {
        let mut x = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (0..n)
            .map(|_| {
                x = x
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((x >> 40) as f32 / (1u64 << 23) as f32) - 1.0
            })
            .collect()
    }

    #[test]
    fn stride_two_phase_split_equals_the_scalar_copy() {
        // Source lengths around the 16-float step, odd and even; destinations shorter, equal
        // and longer than what the source fills.
        for src_len in [0usize, 1, 2, 7, 15, 16, 17, 31, 32, 33, 63, 64, 65] {
            let src = values(src_len, src_len as u64);
            for dst_len in [0usize, 3, 8, src_len / 2, src_len.div_ceil(2), src_len + 9] {
                let mut fast = vec![f32::NAN; dst_len];
                let mut plain = vec![f32::NAN; dst_len];
                copy_phase2(&mut fast, &src);
                copy_phase::<2>(&mut plain, &src);
                let same = fast
                    .iter()
                    .zip(&plain)
                    .all(|(a, b)| a.to_bits() == b.to_bits());
                assert!(same, "src {src_len}, dst {dst_len}: {fast:?} vs {plain:?}");
                for (k, &v) in fast.iter().enumerate().take(src_len.div_ceil(2)) {
                    assert_eq!(v.to_bits(), src[2 * k].to_bits(), "src {src_len}, lane {k}");
                }
            }
        }
    }

    /// The plain-Rust path (what a robot computer without AVX2 + FMA runs, an ARM board among
    /// them) gives what the AVX2 path gives on every kind of convolution the network has: 3x3
    /// at strides 1 and 2 with padding, 1x1, with the bias, an added map, ReLU and
    /// depth-to-space fused, rows that end inside a vector, odd and even vector counts, a batch.
    /// (They differ only by fused versus separate multiply-add rounding.)
    #[test]
    fn plain_path_equals_the_simd_path() {
        // (in_c, out_c, kernel, stride, pad, h, w, add, relu, shuffle)
        let cases = [
            (1, 8, 3, 2, 1, 32, 64, true, true, false),
            (8, 16, 3, 2, 1, 16, 32, false, true, false),
            (16, 16, 3, 1, 1, 8, 16, false, true, false),
            (16, 32, 3, 2, 1, 8, 16, false, true, false),
            (32, 8, 1, 1, 0, 4, 8, false, false, false),
            (8, 16, 1, 1, 0, 8, 16, false, false, true),
            (3, 5, 3, 1, 1, 7, 13, true, true, false),
            (4, 6, 3, 2, 1, 9, 21, false, false, false),
        ];
        for (k, &(in_c, out_c, ks, stride, pad, h, w, add, relu, shuffle)) in
            cases.iter().enumerate()
        {
            let weights = Tensor::from_shape(
                &[out_c, in_c, ks, ks],
                &values(out_c * in_c * ks * ks, 10 + k as u64),
            )
            .unwrap();
            let mut conv = DirectConv::new(
                &weights,
                &values(out_c, 20 + k as u64),
                [stride, stride],
                [pad; 4],
            )
            .unwrap();
            let (oh, ow) = conv.output_hw(h, w).unwrap();
            if add {
                let map =
                    Tensor::from_shape(&[out_c, oh, ow], &values(out_c * oh * ow, 30)).unwrap();
                conv = conv.with_add(&map, oh, ow).unwrap();
            }
            if relu {
                conv = conv.with_relu();
            }
            conv.shuffle = shuffle;
            let n = 2;
            let input = values(n * in_c * h * w, 40 + k as u64);
            let mut simd = vec![f32::NAN; n * out_c * oh * ow];
            let mut plain = vec![f32::NAN; n * out_c * oh * ow];
            conv.run(&input, n, h, w, &mut simd).unwrap();
            FORCE_PLAIN.with(|f| f.set(true));
            let ran = conv.run(&input, n, h, w, &mut plain);
            FORCE_PLAIN.with(|f| f.set(false));
            ran.unwrap();
            for (i, (a, b)) in simd.iter().zip(&plain).enumerate() {
                assert!(
                    (a - b).abs() <= 1e-4 * (1.0 + a.abs()),
                    "case {k}, output {i}: simd {a}, plain {b}"
                );
            }
        }
    }
}
