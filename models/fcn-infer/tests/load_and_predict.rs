//! Loading errors for missing, corrupt and wrongly shaped models; exact batching behaviour on a
//! fixture whose heatmap is crop / 255; the committed model's basic contract.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::path::{Path, PathBuf};

use fcn_infer::{CROP_CELLS, Crop, FcnModel, HeatmapCells, InferError, MAX_BATCH, ModelLoadError};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

fn committed_model() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../psi-fcn.onnx")
}

fn patterned_crop(seed: u8) -> Crop {
    let mut crop = [0u8; CROP_CELLS];
    for (i, v) in crop.iter_mut().enumerate() {
        *v = ((i * 7 + seed as usize * 31) % 256) as u8;
    }
    crop
}

#[test]
fn missing_file_is_not_found() {
    let err = FcnModel::load(&fixture("no_such_model.onnx")).unwrap_err();
    assert!(matches!(err, ModelLoadError::NotFound { .. }), "{err}");
    assert!(err.to_string().contains("no_such_model.onnx"));
}

#[test]
fn a_directory_is_an_io_error() {
    let err = FcnModel::load(&fixture("")).unwrap_err();
    assert!(matches!(err, ModelLoadError::Io { .. }), "{err}");
}

#[test]
fn corrupt_file_is_reported() {
    let err = FcnModel::load(&fixture("corrupt.onnx")).unwrap_err();
    assert!(matches!(err, ModelLoadError::Corrupt { .. }), "{err}");
    assert!(err.to_string().contains("corrupt.onnx"));
}

#[test]
fn random_bytes_are_reported() {
    let bytes: Vec<u8> = (0..4096u32)
        .map(|i| (i.wrapping_mul(2654435761) >> 13) as u8)
        .collect();
    let err = FcnModel::from_bytes(&bytes, Path::new("noise.onnx")).unwrap_err();
    assert!(
        matches!(
            err,
            ModelLoadError::Corrupt { .. } | ModelLoadError::WrongInterface { .. }
        ),
        "{err}"
    );
}

#[test]
fn wrong_input_shape_is_reported() {
    let err = FcnModel::load(&fixture("wrong_shape.onnx")).unwrap_err();
    assert!(
        matches!(err, ModelLoadError::WrongInterface { .. }),
        "{err}"
    );
    assert!(err.to_string().contains("axis 2"), "{err}");
}

#[test]
fn wrong_output_shape_is_reported() {
    let err = FcnModel::load(&fixture("wrong_output.onnx")).unwrap_err();
    assert!(
        matches!(err, ModelLoadError::WrongInterface { .. }),
        "{err}"
    );
}

#[test]
fn float_input_is_reported() {
    let err = FcnModel::load(&fixture("float_input.onnx")).unwrap_err();
    assert!(
        matches!(err, ModelLoadError::WrongInterface { .. }),
        "{err}"
    );
    assert!(err.to_string().contains("F32"), "{err}");
}

#[test]
fn single_and_batched_predictions_are_exact_and_in_order() {
    let mut model = FcnModel::load(&fixture("scale.onnx")).expect("fixture loads");
    let crops: Vec<Crop> = (0..MAX_BATCH as u8).map(patterned_crop).collect();
    let mut single = [0f32; CROP_CELLS];
    for (i, crop) in crops.iter().enumerate() {
        model.predict(crop, &mut single).expect("predict");
        for (cell, (&h, &c)) in single.iter().zip(crop.iter()).enumerate() {
            assert!((h - c as f32 / 255.0).abs() < 1e-6, "crop {i} cell {cell}");
        }
    }
    for n in 1..=MAX_BATCH {
        let mut out = vec![[f32::NAN; CROP_CELLS]; n];
        model.predict_batch(&crops[..n], &mut out).expect("batch");
        for (i, heat) in out.iter().enumerate() {
            for (cell, (&h, &c)) in heat.iter().zip(crops[i].iter()).enumerate() {
                assert!(
                    (h - c as f32 / 255.0).abs() < 1e-6,
                    "batch {n} crop {i} cell {cell}"
                );
            }
        }
    }
}

#[test]
fn repeated_calls_reuse_the_plan_and_give_the_same_answer() {
    let mut model = FcnModel::load(&fixture("scale.onnx")).expect("fixture loads");
    let crop = patterned_crop(3);
    let mut a = [0f32; CROP_CELLS];
    let mut b = [1f32; CROP_CELLS];
    model.predict(&crop, &mut a).expect("first");
    for _ in 0..10 {
        model.predict(&patterned_crop(9), &mut b).expect("other");
    }
    model.predict(&crop, &mut b).expect("again");
    assert_eq!(a, b);
}

#[test]
fn bad_batch_sizes_are_errors() {
    let mut model = FcnModel::load(&fixture("scale.onnx")).expect("fixture loads");
    let crops = vec![[0u8; CROP_CELLS]; MAX_BATCH + 1];
    let mut out = vec![[0f32; CROP_CELLS]; MAX_BATCH + 1];
    assert_eq!(
        model.predict_batch(&crops, &mut out),
        Err(InferError::BatchSize(MAX_BATCH + 1))
    );
    assert_eq!(
        model.predict_batch(&[], &mut []),
        Err(InferError::BatchSize(0))
    );
    assert_eq!(
        model.predict_batch(&crops[..2], &mut out[..3]),
        Err(InferError::OutputCount {
            crops: 2,
            outputs: 3
        })
    );
}

#[test]
fn committed_model_gives_probabilities_for_any_crop() {
    let mut model = FcnModel::load(&committed_model()).expect("models/psi-fcn.onnx loads");
    let crops = [
        [0u8; CROP_CELLS],
        [255u8; CROP_CELLS],
        patterned_crop(1),
        patterned_crop(2),
    ];
    let mut out: Vec<HeatmapCells> = vec![[f32::NAN; CROP_CELLS]; crops.len()];
    model.predict_batch(&crops, &mut out).expect("predict");
    for heat in &out {
        assert!(heat.iter().all(|v| (0.0..=1.0).contains(v)));
    }
    // Batched and single calls agree (the same optimised graph at another batch size).
    let mut single = [0f32; CROP_CELLS];
    model.predict(&crops[2], &mut single).expect("single");
    let max_diff = single
        .iter()
        .zip(out[2].iter())
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f32::max);
    assert!(max_diff < 1e-5, "batch vs single differ by {max_diff}");
}

#[test]
fn committed_model_agrees_with_onnxruntime() {
    // Reference crops and onnxruntime's heatmaps (models/training/make_golden.py).
    let crops_raw = std::fs::read(fixture("golden_crops.bin")).expect("golden crops");
    let heat_raw = std::fs::read(fixture("golden_heatmaps.bin")).expect("golden heatmaps");
    assert_eq!(crops_raw.len() * 4, heat_raw.len());
    let mut model = FcnModel::load(&committed_model()).expect("models/psi-fcn.onnx loads");
    let mut out = [0f32; CROP_CELLS];
    let mut max_diff = 0f32;
    for (crop, heat) in crops_raw
        .chunks_exact(CROP_CELLS)
        .zip(heat_raw.chunks_exact(CROP_CELLS * 4))
    {
        let crop: &Crop = crop.try_into().expect("2048 bytes");
        model.predict(crop, &mut out).expect("predict");
        for (o, b) in out.iter().zip(heat.chunks_exact(4)) {
            let want = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
            max_diff = max_diff.max((o - want).abs());
        }
    }
    assert!(
        max_diff < 1e-4,
        "tract and onnxruntime differ by {max_diff} (rerun make_golden.py after retraining)"
    );
}

/// Windows of every shape: one cell in each corner, a row, a column, the planner's candidate
/// cells, odd borders that split the decoder's 2 x 2 / 4 x 4 / 8 x 8 blocks, the whole crop.
const WINDOWS: [(std::ops::Range<usize>, std::ops::Range<usize>); 9] = [
    (9..17, 20..44),
    (0..32, 0..64),
    (0..1, 0..1),
    (31..32, 63..64),
    (5..6, 0..64),
    (0..32, 37..38),
    (3..30, 7..58),
    (1..2, 62..64),
    (15..18, 29..36),
];

#[test]
fn committed_model_decodes_windows() {
    let model = FcnModel::load(&committed_model()).expect("load");
    assert!(
        model.decodes_windows(),
        "the committed model's decoder was not recognised or failed its load-time check"
    );
}

/// A window's cells are the whole heatmap's cells bit for bit (the same decoder code per
/// cell), every other cell is 0, for every batch size.
fn check_windows(path: &Path) {
    let mut model = FcnModel::load(path).expect("load");
    let crops: Vec<Crop> = (0..MAX_BATCH as u8)
        .map(|k| patterned_crop(k * 3 + 1))
        .collect();
    for n in 1..=MAX_BATCH {
        let mut whole = vec![[0.0f32; CROP_CELLS]; n];
        model.predict_batch(&crops[..n], &mut whole).expect("whole");
        for (rows, cols) in WINDOWS {
            let mut part = vec![[f32::NAN; CROP_CELLS]; n];
            model
                .predict_batch_window(&crops[..n], &mut part, rows.clone(), cols.clone())
                .expect("window");
            for (k, (w, p)) in whole.iter().zip(&part).enumerate() {
                for cell in 0..CROP_CELLS {
                    let (r, c) = (cell / 64, cell % 64);
                    let want = if rows.contains(&r) && cols.contains(&c) {
                        w[cell]
                    } else {
                        0.0
                    };
                    assert_eq!(
                        p[cell].to_bits(),
                        want.to_bits(),
                        "{}: batch {n}, crop {k}, window {rows:?} x {cols:?}, cell ({r}, {c}): {} vs {want}",
                        path.display(),
                        p[cell]
                    );
                }
            }
        }
    }
}

#[test]
fn committed_model_windows_are_the_whole_heatmaps_cells() {
    check_windows(&committed_model());
}

#[test]
fn windows_of_a_model_without_a_recognised_decoder_are_cut_from_the_whole_output() {
    let model = FcnModel::load(&fixture("scale.onnx")).expect("load");
    assert!(!model.decodes_windows());
    check_windows(&fixture("scale.onnx"));
    // And they are the fixture's exact values, crop / 255.
    let mut model = model;
    let crop = patterned_crop(5);
    let mut out = [[1.0f32; CROP_CELLS]];
    model
        .predict_batch_window(std::slice::from_ref(&crop), &mut out, 2..4, 10..13)
        .expect("window");
    for cell in 0..CROP_CELLS {
        let (r, c) = (cell / 64, cell % 64);
        let want = if (2..4).contains(&r) && (10..13).contains(&c) {
            crop[cell] as f32 / 255.0
        } else {
            0.0
        };
        assert!((out[0][cell] - want).abs() < 1e-6, "cell ({r}, {c})");
    }
}

#[test]
fn empty_or_outside_windows_are_errors() {
    let mut model = FcnModel::load(&committed_model()).expect("load");
    let crops = [patterned_crop(1)];
    let mut out = [[0.5f32; CROP_CELLS]];
    for (rows, cols) in [
        (3..3, 0..64),
        (0..32, 10..10),
        (0..33, 0..64),
        (0..32, 60..65),
    ] {
        let err = model
            .predict_batch_window(&crops, &mut out, rows.clone(), cols.clone())
            .unwrap_err();
        assert_eq!(
            err,
            InferError::Window {
                rows: rows.clone(),
                cols: cols.clone()
            }
        );
        assert!(err.to_string().contains(&format!("{rows:?}")), "{err}");
        // Nothing was written.
        assert!(out[0].iter().all(|&v| v == 0.5));
    }
}
