//! Our direct convolution against tract's own: the committed model's outputs with and without
//! the rewrite, and single convolutions of many shapes (strides, paddings, kernel sizes, widths
//! that leave partial vectors, channel counts that leave partial register blocks) on random data.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::path::Path;

use fcn_infer::direct_conv::{RewriteSummary, rewrite_convolutions};
use fcn_infer::{CROP_CELLS, ConvBackend, FcnModel, MAX_BATCH, pattern_crops};
use tract_onnx::prelude::*;
use tract_onnx::tract_core::ops::binary::TypedBinOp;
use tract_onnx::tract_core::ops::change_axes::AxisOp;
use tract_onnx::tract_core::ops::cnn::conv::{Conv, KernelFormat};
use tract_onnx::tract_core::ops::cnn::{PaddingSpec, PoolSpec};
use tract_onnx::tract_core::ops::math::{Add, Max};
use tract_onnx::tract_core::ops::nn::DataFormat;

const MODEL: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../psi-fcn.onnx");

/// xorshift64*: deterministic test data without a dependency.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }
    fn float(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0
    }
    fn crop(&mut self) -> [u8; CROP_CELLS] {
        std::array::from_fn(|_| (self.next() >> 56) as u8)
    }
}

fn max_abs_diff(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

#[test]
fn committed_model_matches_tract_for_every_batch_size() {
    let mut direct = FcnModel::load_with(Path::new(MODEL), ConvBackend::Direct).unwrap();
    let mut tract = FcnModel::load_with(Path::new(MODEL), ConvBackend::Tract).unwrap();
    let mut rng = Rng(0x5eed);
    let mut crops = pattern_crops(MAX_BATCH);
    crops.push([0; CROP_CELLS]);
    crops.push([255; CROP_CELLS]);
    crops.extend((0..10).map(|_| rng.crop()));
    let mut worst = 0.0f32;
    for batch in 1..=MAX_BATCH {
        for chunk in crops.chunks(batch).filter(|c| c.len() == batch) {
            let mut a = vec![[0.0f32; CROP_CELLS]; batch];
            let mut b = vec![[0.0f32; CROP_CELLS]; batch];
            direct.predict_batch(chunk, &mut a).unwrap();
            tract.predict_batch(chunk, &mut b).unwrap();
            for (x, y) in a.iter().zip(&b) {
                worst = worst.max(max_abs_diff(x, y));
            }
            // A batch gives each crop what a single run gives it.
            for (crop, x) in chunk.iter().zip(&a) {
                let mut single = [0.0f32; CROP_CELLS];
                direct.predict(crop, &mut single).unwrap();
                assert!(max_abs_diff(&single, x) <= 1e-6);
            }
        }
    }
    assert!(worst <= 1e-5, "direct vs tract: max |diff| {worst}");
}

#[test]
fn committed_model_convolutions_are_all_replaced() {
    let mut typed = tract_onnx::onnx()
        .model_for_path(MODEL)
        .unwrap()
        .with_input_fact(0, u8::fact([1, 1, 32, 64]).into())
        .unwrap()
        .into_typed()
        .unwrap();
    let summary = rewrite_convolutions(&mut typed).unwrap();
    // 5 3x3 and 6 1x1 convolutions; the position bias after enc1; ReLUs after the 5 encoders.
    assert_eq!(
        summary,
        RewriteSummary {
            convolutions: 11,
            fused_adds: 1,
            fused_relus: 5,
            fused_shuffles: 3
        }
    );
    let optimized = typed.into_optimized().unwrap();
    assert!(
        optimized
            .nodes()
            .iter()
            .all(|n| !n.op().name().contains("MatMul")
                && n.op().name() != "Pad"
                && n.op().name() != "MoveAxis"),
        "tract convolution or depth-to-space left in the plan"
    );
}

/// One convolution (+ optional constant add + optional ReLU) as a typed model of tract's ops.
struct Case {
    n: usize,
    in_c: usize,
    out_c: usize,
    h: usize,
    w: usize,
    k: [usize; 2],
    s: [usize; 2],
    pad_before: [usize; 2],
    pad_after: [usize; 2],
    add: bool,
    relu: bool,
    /// Followed by tract's DepthToSpace(2, CRD) chain (as its ONNX import writes it).
    shuffle: bool,
}

fn build(case: &Case, rng: &mut Rng) -> (TypedModel, Tensor) {
    let mut model = TypedModel::default();
    let src = model
        .add_source("x", f32::fact([case.n, case.in_c, case.h, case.w]))
        .unwrap();
    let kernel: Vec<f32> = (0..case.out_c * case.in_c * case.k[0] * case.k[1])
        .map(|_| rng.float())
        .collect();
    let kernel =
        Tensor::from_shape(&[case.out_c, case.in_c, case.k[0], case.k[1]], &kernel).unwrap();
    let bias: Vec<f32> = (0..case.out_c).map(|_| rng.float()).collect();
    let k = model.add_const("k", kernel).unwrap();
    let b = model.add_const("b", tensor1(&bias)).unwrap();
    let spec = PoolSpec {
        data_format: DataFormat::NCHW,
        kernel_shape: case.k.iter().copied().collect(),
        padding: PaddingSpec::Explicit(
            case.pad_before.iter().copied().collect(),
            case.pad_after.iter().copied().collect(),
        ),
        dilations: None,
        strides: Some(case.s.iter().copied().collect()),
        input_channels: case.in_c,
        output_channels: case.out_c,
    };
    let conv = Conv::new(spec, KernelFormat::OIHW, 1, None);
    let mut wire = model.wire_node("conv", conv, &[src, k, b]).unwrap()[0];
    let out_shape: Vec<usize> = model
        .outlet_fact(wire)
        .unwrap()
        .shape
        .as_concrete()
        .unwrap()
        .to_vec();
    if case.add {
        let map: Vec<f32> = (0..out_shape[1] * out_shape[2] * out_shape[3])
            .map(|_| rng.float())
            .collect();
        let map = Tensor::from_shape(&[1, out_shape[1], out_shape[2], out_shape[3]], &map).unwrap();
        let m = model.add_const("map", map).unwrap();
        wire = model
            .wire_node("add", TypedBinOp(Box::new(Add), None), &[wire, m])
            .unwrap()[0];
    }
    if case.relu {
        let zero = model
            .add_const(
                "zero",
                Tensor::from_shape(&[1, 1, 1, 1], &[0.0f32]).unwrap(),
            )
            .unwrap();
        wire = model
            .wire_node("relu", TypedBinOp(Box::new(Max), None), &[wire, zero])
            .unwrap()[0];
    }
    if case.shuffle {
        let (c, h, w) = (out_shape[1], out_shape[2], out_shape[3]);
        for (ix, op) in [
            AxisOp::Reshape(
                1,
                tvec!(c.to_dim()),
                tvec!((c / 4).to_dim(), 2.to_dim(), 2.to_dim()),
            ),
            AxisOp::Move(3, 5),
            AxisOp::Move(2, 3),
            AxisOp::Reshape(
                2,
                tvec!(h.to_dim(), 2.to_dim(), w.to_dim(), 2.to_dim()),
                tvec!((2 * h).to_dim(), (2 * w).to_dim()),
            ),
        ]
        .into_iter()
        .enumerate()
        {
            wire = model.wire_node(format!("d2s.{ix}"), op, &[wire]).unwrap()[0];
        }
    }
    model.select_output_outlets(&[wire]).unwrap();
    let input: Vec<f32> = (0..case.n * case.in_c * case.h * case.w)
        .map(|_| rng.float())
        .collect();
    let input = Tensor::from_shape(&[case.n, case.in_c, case.h, case.w], &input).unwrap();
    (model, input)
}

fn run(model: TypedModel, input: &Tensor) -> Vec<f32> {
    let out = model
        .into_runnable()
        .unwrap()
        .run(tvec!(input.clone().into_tvalue()))
        .unwrap();
    out[0]
        .try_as_plain_ram()
        .unwrap()
        .as_slice::<f32>()
        .unwrap()
        .to_vec()
}

#[test]
fn single_convolutions_match_tract_on_random_data() {
    let mut rng = Rng(42);
    let mut cases = Vec::new();
    for (k, s) in [
        ([3, 3], [1, 1]),
        ([3, 3], [2, 2]),
        ([1, 1], [1, 1]),
        ([5, 3], [1, 3]),
    ] {
        for (h, w) in [(8, 16), (5, 13), (16, 32), (4, 8), (7, 29)] {
            for (pad_before, pad_after) in [([1, 1], [1, 1]), ([0, 0], [0, 0]), ([2, 0], [0, 1])] {
                if h + pad_before[0] + pad_after[0] < k[0]
                    || w + pad_before[1] + pad_after[1] < k[1]
                {
                    continue;
                }
                let shuffle = rng.next() % 3 == 0;
                let out_c = if shuffle {
                    4 * (1 + (rng.next() % 3) as usize)
                } else {
                    1 + (rng.next() % 9) as usize
                };
                let in_c = 1 + (rng.next() % 7) as usize;
                cases.push(Case {
                    n: 1 + (rng.next() % 3) as usize,
                    in_c,
                    out_c,
                    h,
                    w,
                    k,
                    s,
                    pad_before,
                    pad_after,
                    add: rng.next() % 2 == 0,
                    relu: rng.next() % 2 == 0,
                    shuffle,
                });
            }
        }
    }
    assert!(cases.len() > 40);
    assert!(cases.iter().filter(|c| c.shuffle).count() > 5);
    for case in &cases {
        let (model, input) = build(case, &mut rng);
        let reference = run(model.clone(), &input);
        let mut rewritten = model;
        let summary = rewrite_convolutions(&mut rewritten).unwrap();
        assert_eq!(summary.convolutions, 1);
        assert_eq!(summary.fused_adds, usize::from(case.add));
        assert_eq!(summary.fused_relus, usize::from(case.relu));
        assert_eq!(summary.fused_shuffles, usize::from(case.shuffle));
        let direct = run(rewritten, &input);
        let diff = max_abs_diff(&reference, &direct);
        assert!(
            diff <= 1e-5,
            "k {:?} s {:?} pad {:?}/{:?} {}x{} {}->{} shuffle {}: max |diff| {diff}",
            case.k,
            case.s,
            case.pad_before,
            case.pad_after,
            case.h,
            case.w,
            case.in_c,
            case.out_c,
            case.shuffle
        );
    }
}
