//! What `FcnModel::load` checks before it trusts a model file: its size (before reading it all)
//! and the sha256 that the record beside it (`<model>.json`, written by training) names.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::path::{Path, PathBuf};

use fcn_infer::{FcnModel, MAX_MODEL_BYTES, ModelLoadError, record_path, sha256_hex};

fn committed_model() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../psi-fcn.onnx")
}

/// The committed model and its record, copied into a fresh folder.
fn copy_of_committed(dir: &Path) -> (PathBuf, PathBuf) {
    let model = dir.join("psi-fcn.onnx");
    std::fs::copy(committed_model(), &model).unwrap();
    let record = dir.join("psi-fcn.json");
    std::fs::copy(record_path(&committed_model()), &record).unwrap();
    (model, record)
}

#[test]
fn an_oversized_model_file_is_refused_before_it_is_read() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("huge.onnx");
    // Sparse: a size on paper only, so the test writes nothing.
    let file = std::fs::File::create(&path).unwrap();
    file.set_len(MAX_MODEL_BYTES + 1).unwrap();
    match FcnModel::load(&path) {
        Err(ModelLoadError::TooLarge {
            path: named,
            size,
            limit,
        }) => {
            assert_eq!(named, path);
            assert_eq!((size, limit), (MAX_MODEL_BYTES + 1, MAX_MODEL_BYTES));
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_file_that_never_ends_is_cut_at_the_limit() {
    // Reports size 0 and never ends: only a bounded read stops it.
    let path = Path::new("/dev/zero");
    if !path.exists() {
        eprintln!("skipped: no /dev/zero on this system");
        return;
    }
    match FcnModel::load(path) {
        Err(ModelLoadError::TooLarge { limit, .. }) => assert_eq!(limit, MAX_MODEL_BYTES),
        other => panic!("{other:?}"),
    }
}

#[test]
fn the_committed_record_names_the_committed_models_checksum() {
    let bytes = std::fs::read(committed_model()).unwrap();
    let record: serde_json::Value =
        serde_json::from_slice(&std::fs::read(record_path(&committed_model())).unwrap()).unwrap();
    assert_eq!(record["sha256"].as_str(), Some(sha256_hex(&bytes).as_str()));
    FcnModel::load(&committed_model()).expect("the committed model matches its record");
}

#[test]
fn a_model_that_does_not_match_its_record_is_refused_with_file_expected_and_actual() {
    let dir = tempfile::tempdir().unwrap();
    let (model, _) = copy_of_committed(dir.path());
    // One flipped byte in a weight: still valid ONNX, another model.
    let mut bytes = std::fs::read(&model).unwrap();
    let n = bytes.len();
    bytes[n - 100] ^= 0x01;
    std::fs::write(&model, &bytes).unwrap();
    let expected = sha256_hex(&std::fs::read(committed_model()).unwrap());
    let actual = sha256_hex(&bytes);
    let err = FcnModel::load(&model).unwrap_err();
    match &err {
        ModelLoadError::ChecksumMismatch {
            path,
            expected: e,
            actual: a,
            ..
        } => {
            assert_eq!(path, &model);
            assert_eq!((e, a), (&expected, &actual));
        }
        other => panic!("{other:?}"),
    }
    let message = err.to_string();
    for part in [model.display().to_string(), expected, actual] {
        assert!(message.contains(&part), "{message} lacks {part}");
    }
}

#[test]
fn a_record_without_a_checksum_or_unreadable_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let (model, record) = copy_of_committed(dir.path());
    std::fs::write(&record, "{\"model\": \"psi-fcn.onnx\"}").unwrap();
    let err = FcnModel::load(&model).unwrap_err();
    assert!(matches!(err, ModelLoadError::BadRecord { .. }), "{err}");
    assert!(err.to_string().contains("sha256"), "{err}");
    std::fs::write(&record, "not json").unwrap();
    let err = FcnModel::load(&model).unwrap_err();
    assert!(matches!(err, ModelLoadError::BadRecord { .. }), "{err}");
    assert!(err.to_string().contains("psi-fcn.json"), "{err}");
    // No record at all: a bare model file (a fixture, a hand export) loads unverified.
    std::fs::remove_file(&record).unwrap();
    FcnModel::load(&model).expect("a bare model loads");
}
