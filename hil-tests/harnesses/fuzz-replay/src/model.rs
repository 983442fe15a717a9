//! The model loader (`models/fcn-infer`): an ONNX model from bytes.

use std::path::Path;

use fcn_infer::{CROP_CELLS, FcnModel, InferError, MAX_BATCH, pattern_crops};

/// Loads the bytes as Psi's model. A model that loads runs: every prediction is a heatmap of
/// probabilities or an error, the same crop gives the same answer, and a batch gives what
/// single calls give.
pub fn model_loader(data: &[u8]) {
    let mut model = match FcnModel::from_bytes(data, Path::new("fuzz.onnx")) {
        Ok(m) => m,
        Err(e) => {
            let _ = e.to_string();
            return;
        }
    };
    let crops = pattern_crops(2);
    let mut first = [f32::NAN; CROP_CELLS];
    match model.predict(&crops[0], &mut first) {
        Ok(()) => {
            assert!(first.iter().all(|v| (0.0..=1.0).contains(v)));
            let mut again = [f32::NAN; CROP_CELLS];
            assert_eq!(model.predict(&crops[0], &mut again), Ok(()));
            assert_eq!(first, again, "the same crop gives the same heatmap");
            let mut batch = vec![[f32::NAN; CROP_CELLS]; 2];
            assert_eq!(model.predict_batch(&crops, &mut batch), Ok(()));
            assert_eq!(batch[0], first);
        }
        Err(e) => {
            let _ = e.to_string();
        }
    }
    let too_many = vec![[0u8; CROP_CELLS]; MAX_BATCH + 1];
    let mut out = vec![[0f32; CROP_CELLS]; MAX_BATCH + 1];
    assert_eq!(
        model.predict_batch(&too_many, &mut out),
        Err(InferError::BatchSize(MAX_BATCH + 1))
    );
}
