//! The model file's own checks: a size limit applied before the file is read, and the sha256
//! that the model's record (`<model>.json`, written by `models/training/train.py` beside the
//! `.onnx`) names for it.

use std::io::Read;
use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

use crate::ModelLoadError;

/// Largest model file [`crate::FcnModel::load`] reads (64 MiB; the committed Psi is 100 KB).
pub const MAX_MODEL_BYTES: u64 = 64 * 1024 * 1024;
/// Largest record file read (the committed one is 4 KB).
pub const MAX_RECORD_BYTES: u64 = 1024 * 1024;

/// The record that describes `model`: the same path with the extension `.json`.
pub fn record_path(model: &Path) -> PathBuf {
    model.with_extension("json")
}

/// Lower-case hex sha256 of `bytes`, as the record's `"sha256"` field holds it (what
/// `sha256sum` prints).
pub fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// Reads at most `limit` bytes of `path`: the size is checked before reading, and the read
/// itself stops one byte past the limit (a file that grows meanwhile, or a device that reports
/// size 0 and never ends).
pub(crate) fn read_bounded(path: &Path, limit: u64) -> Result<Vec<u8>, ModelLoadError> {
    let io = |source: std::io::Error| {
        if source.kind() == std::io::ErrorKind::NotFound {
            ModelLoadError::NotFound {
                path: path.to_path_buf(),
            }
        } else {
            ModelLoadError::Io {
                path: path.to_path_buf(),
                source,
            }
        }
    };
    let too_large = |size| ModelLoadError::TooLarge {
        path: path.to_path_buf(),
        size,
        limit,
    };
    let file = std::fs::File::open(path).map_err(io)?;
    let size = file.metadata().map_err(io)?.len();
    if size > limit {
        return Err(too_large(size));
    }
    let mut bytes = Vec::with_capacity(usize::try_from(size).unwrap_or(0));
    file.take(limit.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(io)?;
    let read = u64::try_from(bytes.len()).unwrap_or(u64::MAX);
    if read > limit {
        return Err(too_large(read));
    }
    Ok(bytes)
}

/// Checks `bytes`, read from `model`, against the record beside it. No record: a bare model
/// (a test fixture, a hand export), loaded unverified with a warning. A record must parse and
/// name a `"sha256"` that matches.
pub(crate) fn verify(model: &Path, bytes: &[u8]) -> Result<(), ModelLoadError> {
    let record = record_path(model);
    if !record.is_file() {
        log::warn!(
            "FCN model {}: no record {} beside it, checksum not verified",
            model.display(),
            record.display()
        );
        return Ok(());
    }
    let bad = |reason: String| ModelLoadError::BadRecord {
        record: record.clone(),
        reason,
    };
    let text = read_bounded(&record, MAX_RECORD_BYTES).map_err(|e| bad(e.to_string()))?;
    let value: serde_json::Value =
        serde_json::from_slice(&text).map_err(|e| bad(format!("not JSON: {e}")))?;
    let expected = value
        .get("sha256")
        .and_then(|v| v.as_str())
        .ok_or_else(|| {
            bad(
                "no \"sha256\" string: retrain (train.py writes it) or add the model's `sha256sum`"
                    .into(),
            )
        })?
        .to_ascii_lowercase();
    let actual = sha256_hex(bytes);
    if expected != actual {
        return Err(ModelLoadError::ChecksumMismatch {
            path: model.to_path_buf(),
            record,
            expected,
            actual,
        });
    }
    Ok(())
}
