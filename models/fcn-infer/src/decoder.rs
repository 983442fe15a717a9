//! Psi's decoder run by us over any window of the heatmap, so that a caller who reads only part
//! of each heatmap (the planner reads the 192 candidate cells of 2,048) pays only for that part.
//!
//! The network's decoder (FCN-8s style, `models/training/psi_model.py`) is pointwise: 1x1
//! "score" convolutions on the three encoder stages, 1x1 up-sampling convolutions each followed
//! by a depth-to-space (PixelShuffle(2)), skip additions, a ReLU, an added output-bias map and a
//! sigmoid. Output cell `(r, c)` therefore depends only on the stride-2 features at
//! `(r / 2, c / 2)`, the stride-4 ones at `(r / 4, c / 4)` and the stride-8 ones at
//! `(r / 8, c / 8)`: a window of output cells needs exactly the matching windows of the three
//! stages, and nothing of the encoder can be skipped (its 3x3 convolutions mix neighbours).
//!
//! [`Decoder::recognise`] finds that structure in the typed model by its operators and shapes,
//! not by node names (every link must be the one expected, the depth-to-space order is checked
//! by running it, as for [`crate::direct_conv`]), and takes the weights out of it. The encoder
//! then runs in tract with the three stages as the plan's outputs, and [`Decoder::decode`]
//! computes the wanted cells. `FcnModel` checks the result against the whole network at load
//! time before using it (`crate::FcnModel::load`).
#![allow(
    unsafe_code,
    reason = "AVX2/FMA intrinsics of the decoder, behind runtime feature detection"
)]

use std::ops::Range;

use tract_onnx::prelude::*;
use tract_onnx::tract_core::internal::*;
use tract_onnx::tract_core::ops::binary::TypedBinOp;
use tract_onnx::tract_core::ops::cnn::conv::{Conv, KernelFormat};
use tract_onnx::tract_core::ops::math::{Add, Max};
use tract_onnx::tract_core::ops::nn::DataFormat;
use tract_onnx::tract_core::tract_linalg::{self, element_wise::ElementWise};

use crate::direct_conv::{constant, depth_to_space_chain, kernel_and_bias};
use crate::{CROP_CELLS, CROP_COLS, CROP_ROWS};

/// Stage sizes: stride 2, 4 and 8 of the 32 x 64 crop.
const H1: usize = CROP_ROWS / 2;
const W1: usize = CROP_COLS / 2;
const H2: usize = CROP_ROWS / 4;
const W2: usize = CROP_COLS / 4;
const H3: usize = CROP_ROWS / 8;
const W3: usize = CROP_COLS / 8;

/// The decoder's weights, rearranged so that the innermost loops run over output channels
/// (`[in][out]`), and its buffers.
pub(crate) struct Decoder {
    /// Score channels (`k`).
    k: usize,
    /// Channels of the stride-2, -4 and -8 stages.
    stage_c: [usize; 3],
    /// Score convolutions of the three stages, `[in][k]`.
    score_w: [Vec<f32>; 3],
    /// `score3`'s bias `[k]`.
    score3_b: Vec<f32>,
    /// `up3` per sub-position `q = 2i + j`: `[q][in k][out k]`.
    up3_w: Vec<f32>,
    /// `up3`'s bias per sub-position plus `score2`'s bias: `[q][k]`.
    bias2: Vec<f32>,
    /// `up2`, laid out like `up3_w`.
    up2_w: Vec<f32>,
    /// `up2`'s bias per sub-position plus `score1`'s bias: `[q][k]`.
    bias1: Vec<f32>,
    /// `up1`: `[q][in k]` (as in the model).
    up1_w: Vec<f32>,
    /// `up1`'s bias `[q]`.
    up1_b: [f32; 4],
    /// The added output bias, `[32 * 64]`.
    out_bias: Vec<f32>,
    /// tract's sigmoid kernel (the one the whole network's plan runs).
    sigmoid: Box<dyn ElementWise<f32>>,
    /// Score-3 per stride-8 cell, `[cell][k]`.
    t3: Vec<f32>,
    /// Fused stride-4 scores per cell, `[cell][k]`.
    s2: Vec<f32>,
}

impl std::fmt::Debug for Decoder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Decoder")
            .field("k", &self.k)
            .field("stage_c", &self.stage_c)
            .finish_non_exhaustive()
    }
}

/// Score-channel counts with a compiled decode loop.
const SUPPORTED_K: [usize; 3] = [4, 8, 16];

/// A 1x1 convolution (stride 1, no padding, group 1, NCHW, OIHW) with constant weights
/// `[out][in]` and bias `[out]`, and its input.
struct Pointwise {
    input: OutletId,
    out_c: usize,
    in_c: usize,
    weights: Vec<f32>,
    bias: Vec<f32>,
}

fn pointwise(model: &TypedModel, outlet: OutletId) -> TractResult<Option<Pointwise>> {
    let node = model.node(outlet.node);
    let Some(conv) = node.op_as::<Conv>() else {
        return Ok(None);
    };
    let spec = &conv.pool_spec;
    if conv.q_params.is_some()
        || conv.group != 1
        || conv.kernel_fmt != KernelFormat::OIHW
        || spec.data_format != DataFormat::NCHW
        || spec.rank() != 2
        || spec.kernel_shape.iter().any(|&k| k != 1)
        || spec.strides().iter().any(|&s| s != 1)
        || spec.dilations().iter().any(|&d| d != 1)
        || node.inputs.len() != 3
        || model.outlet_fact(node.inputs[0])?.datum_type != f32::datum_type()
    {
        return Ok(None);
    }
    let input_shape = model.outlet_fact(node.inputs[0])?.shape.clone();
    let Some(dims) = input_shape.as_concrete() else {
        return Ok(None);
    };
    if dims.len() != 4
        || spec
            .computed_padding(&dims[2..])
            .iter()
            .any(|p| p.pad_before != 0 || p.pad_after != 0)
    {
        return Ok(None);
    }
    let Some((kernel, bias)) = kernel_and_bias(model, node)? else {
        return Ok(None);
    };
    let (out_c, in_c) = (spec.output_channels, spec.input_channels);
    if kernel.shape() != [out_c, in_c, 1, 1] || dims[1] != in_c {
        return Ok(None);
    }
    let weights = kernel.cast_to::<f32>()?;
    let weights = weights.try_as_plain_ram()?.as_slice::<f32>()?.to_vec();
    let bias = bias.cast_to::<f32>()?;
    let bias = bias.try_as_plain_ram()?;
    let bias = bias.as_slice::<f32>()?;
    let bias = match bias.len() {
        1 => vec![bias[0]; out_c],
        n if n == out_c => bias.to_vec(),
        _ => return Ok(None),
    };
    Ok(Some(Pointwise {
        input: node.inputs[0],
        out_c,
        in_c,
        weights,
        bias,
    }))
}

/// The pointwise convolution whose output reaches `outlet` through a depth-to-space chain.
fn shuffled_pointwise(model: &TypedModel, outlet: OutletId) -> TractResult<Option<Pointwise>> {
    let mut cur = outlet.node;
    while model.node(cur).op_as::<AxisOp>().is_some() && model.node(cur).inputs.len() == 1 {
        cur = model.node(cur).inputs[0].node;
    }
    if cur == outlet.node {
        return Ok(None);
    }
    let Some(conv) = pointwise(model, OutletId::new(cur, 0))? else {
        return Ok(None);
    };
    let Some(dims) = model
        .outlet_fact(conv.input)?
        .shape
        .as_concrete()
        .map(|d| d.to_vec())
    else {
        return Ok(None);
    };
    if conv.out_c % 4 != 0
        || depth_to_space_chain(model, cur, conv.out_c, dims[2], dims[3])? != Some(outlet.node)
    {
        return Ok(None);
    }
    Ok(Some(conv))
}

/// The two inputs of a binary op `B` without constants, or `None`.
fn binary_inputs<B: tract_onnx::tract_core::ops::binary::BinMiniOp>(
    model: &TypedModel,
    outlet: OutletId,
) -> Option<[OutletId; 2]> {
    let node = model.node(outlet.node);
    let bin = node.op_as::<TypedBinOp>()?;
    (bin.0.is::<B>() && bin.1.is_none() && node.inputs.len() == 2)
        .then(|| [node.inputs[0], node.inputs[1]])
}

/// `a + b` where one side is a depth-to-space'd pointwise convolution and the other a plain
/// one: (shuffled, plain).
fn skip_add(model: &TypedModel, outlet: OutletId) -> TractResult<Option<(Pointwise, Pointwise)>> {
    let Some([a, b]) = binary_inputs::<Add>(model, outlet) else {
        return Ok(None);
    };
    for (x, y) in [(a, b), (b, a)] {
        if let (Some(up), Some(score)) = (shuffled_pointwise(model, x)?, pointwise(model, y)?) {
            return Ok(Some((up, score)));
        }
    }
    Ok(None)
}

/// `[out][in]` as `[in][out]`.
fn transposed(w: &[f32], out_c: usize, in_c: usize) -> Vec<f32> {
    let mut t = vec![0.0; w.len()];
    for o in 0..out_c {
        for i in 0..in_c {
            t[i * out_c + o] = w[o * in_c + i];
        }
    }
    t
}

/// An up-sampling convolution `[4k][k]` (output channel `4c + q`) as `[q][in][out c]`.
fn per_sub_position(w: &[f32], k: usize) -> Vec<f32> {
    let mut t = vec![0.0; 4 * k * k];
    for c in 0..k {
        for q in 0..4 {
            for m in 0..k {
                t[(q * k + m) * k + c] = w[(4 * c + q) * k + m];
            }
        }
    }
    t
}

/// `bias[4c + q] + extra[c]` as `[q][c]`.
fn sub_position_bias(bias: &[f32], extra: &[f32], k: usize) -> Vec<f32> {
    let mut t = vec![0.0; 4 * k];
    for q in 0..4 {
        for c in 0..k {
            t[q * k + c] = bias[4 * c + q] + extra[c];
        }
    }
    t
}

impl Decoder {
    /// The decoder of a typed model (input fixed to `[n, 1, 32, 64]`, not yet decluttered) and
    /// the outlets of its three encoder stages (stride 2, 4, 8), when the model ends in exactly
    /// the pointwise FCN-8s decoder described in the module documentation; `None` otherwise.
    pub(crate) fn recognise(model: &TypedModel) -> TractResult<Option<(Decoder, [OutletId; 3])>> {
        let outputs = model.output_outlets()?;
        let [out] = outputs else {
            return Ok(None);
        };
        let sig = model.node(out.node);
        if sig.op().name() != "Sigmoid" || sig.inputs.len() != 1 {
            return Ok(None);
        }
        // logits + out_bias
        let Some([a, b]) = binary_inputs::<Add>(model, sig.inputs[0]) else {
            return Ok(None);
        };
        let (Some(out_bias), logits) = (match constant(model, b)? {
            Some(k) => (Some(k), a),
            None => (constant(model, a)?, b),
        }) else {
            return Ok(None);
        };
        if out_bias.len() != CROP_CELLS
            || out_bias
                .shape()
                .iter()
                .rev()
                .take(2)
                .copied()
                .collect::<Vec<_>>()
                != [CROP_COLS, CROP_ROWS]
        {
            return Ok(None);
        }
        let Some(up1) = shuffled_pointwise(model, logits)? else {
            return Ok(None);
        };
        let k = up1.in_c;
        if up1.out_c != 4 || !SUPPORTED_K.contains(&k) {
            return Ok(None);
        }
        // ReLU(shuffle(up2(s2)) + score1(f1))
        let Some([a, b]) = binary_inputs::<Max>(model, up1.input) else {
            return Ok(None);
        };
        let (zero, s1) = match constant(model, b)? {
            Some(z) => (z, a),
            None => match constant(model, a)? {
                Some(z) => (z, b),
                None => return Ok(None),
            },
        };
        let zero = zero.cast_to::<f32>()?;
        if zero.len() != 1 || zero.try_as_plain_ram()?.as_slice::<f32>()?[0] != 0.0 {
            return Ok(None);
        }
        let Some((up2, score1)) = skip_add(model, s1)? else {
            return Ok(None);
        };
        let Some((up3, score2)) = skip_add(model, up2.input)? else {
            return Ok(None);
        };
        let Some(score3) = pointwise(model, up3.input)? else {
            return Ok(None);
        };
        let ks = [up2.in_c, up3.in_c, score1.out_c, score2.out_c, score3.out_c];
        if ks.iter().any(|&x| x != k) || up2.out_c != 4 * k || up3.out_c != 4 * k {
            return Ok(None);
        }
        // The stages must have the strides the window arithmetic assumes.
        let stages = [score1.input, score2.input, score3.input];
        let sizes = [(H1, W1), (H2, W2), (H3, W3)];
        let mut stage_c = [0; 3];
        for ((outlet, (h, w)), c) in stages.iter().zip(sizes).zip(stage_c.iter_mut()) {
            let shape = model.outlet_fact(*outlet)?.shape.clone();
            let Some(dims) = shape.as_concrete() else {
                return Ok(None);
            };
            if dims.len() != 4 || dims[2] != h || dims[3] != w {
                return Ok(None);
            }
            *c = dims[1];
        }
        let out_bias = out_bias.cast_to::<f32>()?;
        let out_bias = out_bias.try_as_plain_ram()?.as_slice::<f32>()?.to_vec();
        let decoder = Decoder {
            k,
            stage_c,
            score_w: [
                transposed(&score1.weights, k, score1.in_c),
                transposed(&score2.weights, k, score2.in_c),
                transposed(&score3.weights, k, score3.in_c),
            ],
            score3_b: score3.bias,
            up3_w: per_sub_position(&up3.weights, k),
            bias2: sub_position_bias(&up3.bias, &score2.bias, k),
            up2_w: per_sub_position(&up2.weights, k),
            bias1: sub_position_bias(&up2.bias, &score1.bias, k),
            up1_w: up1.weights,
            up1_b: [up1.bias[0], up1.bias[1], up1.bias[2], up1.bias[3]],
            out_bias,
            sigmoid: tract_linalg::Func::Sigmoid.ew_f32()?,
            t3: vec![0.0; H3 * W3 * k],
            s2: vec![0.0; H2 * W2 * k],
        };
        Ok(Some((decoder, stages)))
    }

    /// Adds `by` to the output bias of one cell (for the test of the load-time check).
    #[cfg(test)]
    pub(crate) fn nudge_out_bias(&mut self, cell: usize, by: f32) {
        self.out_bias[cell] += by;
    }

    /// Channels of the stride-2, -4 and -8 stages the decoder reads.
    pub(crate) fn stage_channels(&self) -> [usize; 3] {
        self.stage_c
    }

    /// Writes the heatmap cells of `rows` x `cols` of one crop into `out` (`[32 * 64]`, other
    /// cells untouched) from its three stages `f1` `[c1, 16, 32]`, `f2` `[c2, 8, 16]`, `f3`
    /// `[c3, 4, 8]`. The window must be non-empty and inside the crop (checked by the caller).
    pub(crate) fn decode(
        &mut self,
        f: [&[f32]; 3],
        rows: Range<usize>,
        cols: Range<usize>,
        out: &mut [f32],
    ) -> TractResult<()> {
        ensure!(
            !rows.is_empty() && !cols.is_empty() && rows.end <= CROP_ROWS && cols.end <= CROP_COLS,
            "decoder window {rows:?} x {cols:?} outside the crop"
        );
        ensure!(
            out.len() == CROP_CELLS,
            "decoder output of {} cells",
            out.len()
        );
        for ((stage, c), cells) in f.iter().zip(self.stage_c).zip([H1 * W1, H2 * W2, H3 * W3]) {
            ensure!(
                stage.len() == c * cells,
                "decoder stage of {} values",
                stage.len()
            );
        }
        match self.k {
            4 => self.logits::<4>(f, &rows, &cols, out),
            8 => self.logits::<8>(f, &rows, &cols, out),
            16 => self.logits::<16>(f, &rows, &cols, out),
            k => bail!("no decode loop for {k} score channels"),
        }
        for r in rows {
            self.sigmoid
                .run(&mut out[r * CROP_COLS + cols.start..r * CROP_COLS + cols.end])?;
        }
        Ok(())
    }

    fn logits<const K: usize>(
        &mut self,
        f: [&[f32]; 3],
        rows: &Range<usize>,
        cols: &Range<usize>,
        out: &mut [f32],
    ) {
        #[cfg(target_arch = "x86_64")]
        {
            if K == 8
                && std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma")
            {
                // SAFETY: the CPU has AVX2 and FMA (checked just above); `decode` checked the
                // stages' lengths and the window, and the weights have their lengths by
                // construction (`recognise`).
                unsafe { self.logits_k8_fma(f, rows, cols, out) };
                return;
            }
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU has AVX2 (checked just above); nothing else is required.
                unsafe { self.logits_avx2::<K>(f, rows, cols, out) };
                return;
            }
        }
        self.logits_body::<K>(f, rows, cols, out);
    }

    /// [`Decoder::logits_body`] for eight score channels, one AVX2 vector per cell's channels,
    /// with fused multiply-adds (so not the same last bits as the plain loop; both are checked
    /// against the whole network at load time).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn logits_k8_fma(
        &mut self,
        [f1, f2, f3]: [&[f32]; 3],
        rows: &Range<usize>,
        cols: &Range<usize>,
        out: &mut [f32],
    ) {
        use std::arch::x86_64::*;
        const K: usize = 8;
        let [c1, c2, c3] = self.stage_c;
        let span = |r: &Range<usize>, s: usize| r.start / s..(r.end - 1) / s + 1;
        // SAFETY: for every pointer below: stage `f_s` holds `c_s` planes of `H_s x W_s` and the
        // cells visited lie inside the planes (the window is inside the crop); the score
        // weights hold `c_s x K`, the up-sampling weights `4 x K x K`, the biases `4 x K`,
        // `t3` and `s2` one `K` per cell of their stage, `out` and `out_bias` 32 x 64.
        unsafe {
            for i in span(rows, 8) {
                for j in span(cols, 8) {
                    let mut acc = [
                        _mm256_loadu_ps(self.score3_b.as_ptr()),
                        zero8(),
                        zero8(),
                        zero8(),
                    ];
                    let x = f3.as_ptr().add(i * W3 + j);
                    fma_column(&mut acc, x, H3 * W3, self.score_w[2].as_ptr(), c3);
                    _mm256_storeu_ps(self.t3.as_mut_ptr().add((i * W3 + j) * K), sum4(acc));
                }
            }
            for i in span(rows, 4) {
                for j in span(cols, 4) {
                    let q = 2 * (i % 2) + j % 2;
                    let mut acc = [
                        _mm256_loadu_ps(self.bias2.as_ptr().add(q * K)),
                        zero8(),
                        zero8(),
                        zero8(),
                    ];
                    let t = self.t3.as_ptr().add(((i / 2) * W3 + j / 2) * K);
                    fma_column(&mut acc, t, 1, self.up3_w.as_ptr().add(q * K * K), K);
                    let x = f2.as_ptr().add(i * W2 + j);
                    fma_column(&mut acc, x, H2 * W2, self.score_w[1].as_ptr(), c2);
                    _mm256_storeu_ps(self.s2.as_mut_ptr().add((i * W2 + j) * K), sum4(acc));
                }
            }
            let up1 = self.up1_w.as_ptr();
            let [w0, w1, w2, w3] = [0, 1, 2, 3].map(|q| _mm256_loadu_ps(up1.add(q * K)));
            let up1_b = _mm_loadu_ps(self.up1_b.as_ptr());
            let zero = _mm256_setzero_ps();
            for i in span(rows, 2) {
                for j in span(cols, 2) {
                    let q = 2 * (i % 2) + j % 2;
                    let mut acc = [
                        _mm256_loadu_ps(self.bias1.as_ptr().add(q * K)),
                        zero8(),
                        zero8(),
                        zero8(),
                    ];
                    let t = self.s2.as_ptr().add(((i / 2) * W2 + j / 2) * K);
                    fma_column(&mut acc, t, 1, self.up2_w.as_ptr().add(q * K * K), K);
                    let x = f1.as_ptr().add(i * W1 + j);
                    fma_column(&mut acc, x, H1 * W1, self.score_w[0].as_ptr(), c1);
                    let acc = sum4(acc);
                    let r = _mm256_max_ps(acc, zero);
                    // The four sub-cells' dot products, summed pairwise across lanes.
                    let h01 = _mm256_hadd_ps(_mm256_mul_ps(r, w0), _mm256_mul_ps(r, w1));
                    let h23 = _mm256_hadd_ps(_mm256_mul_ps(r, w2), _mm256_mul_ps(r, w3));
                    let h = _mm256_hadd_ps(h01, h23);
                    let sums = _mm_add_ps(_mm256_castps256_ps128(h), _mm256_extractf128_ps(h, 1));
                    let mut logit = [0.0f32; 4];
                    _mm_storeu_ps(logit.as_mut_ptr(), _mm_add_ps(sums, up1_b));
                    for (q, &l) in logit.iter().enumerate() {
                        let (r, c) = (2 * i + q / 2, 2 * j + q % 2);
                        if rows.contains(&r) && cols.contains(&c) {
                            let cell = r * CROP_COLS + c;
                            out[cell] = l + self.out_bias[cell];
                        }
                    }
                }
            }
        }
    }

    /// [`Decoder::logits_body`] compiled for AVX2 (eight lanes for the channel loops; no FMA,
    /// so the same sums as the plain build).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn logits_avx2<const K: usize>(
        &mut self,
        f: [&[f32]; 3],
        rows: &Range<usize>,
        cols: &Range<usize>,
        out: &mut [f32],
    ) {
        self.logits_body::<K>(f, rows, cols, out);
    }

    /// The logits of the window: the stride-8 and stride-4 cells under it first (each once),
    /// then per stride-2 cell its ReLU'd features and the up to four output cells it makes.
    #[inline(always)]
    fn logits_body<const K: usize>(
        &mut self,
        [f1, f2, f3]: [&[f32]; 3],
        rows: &Range<usize>,
        cols: &Range<usize>,
        out: &mut [f32],
    ) {
        let [c1, c2, c3] = self.stage_c;
        let span = |r: &Range<usize>, s: usize| r.start / s..(r.end - 1) / s + 1;
        for i in span(rows, 8) {
            for j in span(cols, 8) {
                let mut acc: [f32; K] = std::array::from_fn(|c| self.score3_b[c]);
                add_column(&mut acc, &f3[i * W3 + j..], H3 * W3, &self.score_w[2], c3);
                self.t3[(i * W3 + j) * K..][..K].copy_from_slice(&acc);
            }
        }
        for i in span(rows, 4) {
            for j in span(cols, 4) {
                let q = 2 * (i % 2) + j % 2;
                let mut acc: [f32; K] = std::array::from_fn(|c| self.bias2[q * K + c]);
                let t = &self.t3[((i / 2) * W3 + j / 2) * K..][..K];
                add_column(&mut acc, t, 1, &self.up3_w[q * K * K..], K);
                add_column(&mut acc, &f2[i * W2 + j..], H2 * W2, &self.score_w[1], c2);
                self.s2[(i * W2 + j) * K..][..K].copy_from_slice(&acc);
            }
        }
        for i in span(rows, 2) {
            for j in span(cols, 2) {
                let q = 2 * (i % 2) + j % 2;
                let mut acc: [f32; K] = std::array::from_fn(|c| self.bias1[q * K + c]);
                let t = &self.s2[((i / 2) * W2 + j / 2) * K..][..K];
                add_column(&mut acc, t, 1, &self.up2_w[q * K * K..], K);
                add_column(&mut acc, &f1[i * W1 + j..], H1 * W1, &self.score_w[0], c1);
                let mut logit = self.up1_b;
                for (q, l) in logit.iter_mut().enumerate() {
                    let w = &self.up1_w[q * K..q * K + K];
                    for (m, &x) in acc.iter().enumerate() {
                        *l += w[m] * x.max(0.0);
                    }
                }
                for (q, &l) in logit.iter().enumerate() {
                    let (r, c) = (2 * i + q / 2, 2 * j + q % 2);
                    if rows.contains(&r) && cols.contains(&c) {
                        let cell = r * CROP_COLS + c;
                        out[cell] = l + self.out_bias[cell];
                    }
                }
            }
        }
    }
}

/// `acc += x[m * stride] * w[m * K..m * K + K]` for `m < n` (the plain loop of
/// [`Decoder::logits_body`]).
#[inline(always)]
fn add_column<const K: usize>(acc: &mut [f32; K], x: &[f32], stride: usize, w: &[f32], n: usize) {
    for m in 0..n {
        let xm = x[m * stride];
        let w = &w[m * K..m * K + K];
        for c in 0..K {
            acc[c] += w[c] * xm;
        }
    }
}

/// `acc[m % 4] += x[m * stride] * w[m * 8..m * 8 + 8]` for `m < n`: four independent chains, so
/// the multiply-adds overlap instead of waiting on one another.
///
/// # Safety
/// AVX2 and FMA; `x` readable at `m * stride` and `w` at `8 m .. 8 m + 8` for every `m < n`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline]
unsafe fn fma_column(
    acc: &mut [std::arch::x86_64::__m256; 4],
    x: *const f32,
    stride: usize,
    w: *const f32,
    n: usize,
) {
    use std::arch::x86_64::*;
    // SAFETY: the caller's contract.
    unsafe {
        let [mut a0, mut a1, mut a2, mut a3] = *acc;
        let mut m = 0;
        while m + 4 <= n {
            let x0 = _mm256_set1_ps(*x.add(m * stride));
            let x1 = _mm256_set1_ps(*x.add((m + 1) * stride));
            let x2 = _mm256_set1_ps(*x.add((m + 2) * stride));
            let x3 = _mm256_set1_ps(*x.add((m + 3) * stride));
            a0 = _mm256_fmadd_ps(x0, _mm256_loadu_ps(w.add(m * 8)), a0);
            a1 = _mm256_fmadd_ps(x1, _mm256_loadu_ps(w.add(m * 8 + 8)), a1);
            a2 = _mm256_fmadd_ps(x2, _mm256_loadu_ps(w.add(m * 8 + 16)), a2);
            a3 = _mm256_fmadd_ps(x3, _mm256_loadu_ps(w.add(m * 8 + 24)), a3);
            m += 4;
        }
        while m < n {
            let xm = _mm256_set1_ps(*x.add(m * stride));
            a0 = _mm256_fmadd_ps(xm, _mm256_loadu_ps(w.add(m * 8)), a0);
            m += 1;
        }
        *acc = [a0, a1, a2, a3];
    }
}

/// `(a0 + a1) + (a2 + a3)`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn sum4(a: [std::arch::x86_64::__m256; 4]) -> std::arch::x86_64::__m256 {
    use std::arch::x86_64::*;
    _mm256_add_ps(_mm256_add_ps(a[0], a[1]), _mm256_add_ps(a[2], a[3]))
}

/// Eight zeros.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn zero8() -> std::arch::x86_64::__m256 {
    std::arch::x86_64::_mm256_setzero_ps()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The plain loop (CPUs without AVX2 and FMA, other score-channel counts) computes what the
    /// AVX2 + FMA loop does, within float rounding, over windows of every kind.
    #[test]
    fn plain_logits_equal_the_fma_logits() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../psi-fcn.onnx");
        let typed = tract_onnx::onnx()
            .model_for_path(&path)
            .and_then(|m| m.with_input_fact(0, u8::fact([1, 1, CROP_ROWS, CROP_COLS]).into()))
            .and_then(|m| m.into_typed())
            .expect("the committed model types");
        let (mut decoder, _) = Decoder::recognise(&typed)
            .expect("recognise")
            .expect("the committed model's decoder is recognised");
        assert_eq!(decoder.k, 8);
        // Deterministic stage values in [-1, 2) (ReLU'd stages are non-negative; negative
        // values exercise the decoder's own ReLU all the same).
        let stages: Vec<Vec<f32>> = decoder
            .stage_c
            .iter()
            .zip([H1 * W1, H2 * W2, H3 * W3])
            .enumerate()
            .map(|(s, (&c, cells))| {
                (0..c * cells)
                    .map(|i| ((i * 2654435761 + s * 97) % 3000) as f32 / 1000.0 - 1.0)
                    .collect()
            })
            .collect();
        let f = [&stages[0][..], &stages[1][..], &stages[2][..]];
        for (rows, cols) in [
            (0..32, 0..64),
            (9..17, 20..44),
            (3..4, 61..64),
            (31..32, 0..1),
        ] {
            let mut plain = vec![f32::NAN; CROP_CELLS];
            decoder.logits_body::<8>(f, &rows, &cols, &mut plain);
            let mut fast = vec![f32::NAN; CROP_CELLS];
            decoder.logits::<8>(f, &rows, &cols, &mut fast);
            for cell in 0..CROP_CELLS {
                let (r, c) = (cell / CROP_COLS, cell % CROP_COLS);
                if rows.contains(&r) && cols.contains(&c) {
                    let (a, b) = (plain[cell], fast[cell]);
                    assert!(
                        (a - b).abs() <= 1e-4 * (1.0 + a.abs()),
                        "cell ({r}, {c}): plain {a}, fast {b}"
                    );
                } else {
                    assert!(
                        plain[cell].is_nan() && fast[cell].is_nan(),
                        "cell ({r}, {c}) written"
                    );
                }
            }
        }
    }
}
