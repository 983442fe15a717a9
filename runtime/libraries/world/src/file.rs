//! Shared reading of the versioned world files (scene and robot): extension -> encoding, read,
//! version probe, TOML or JSON parse, validation ([`InvalidField`], and the search for non-finite
//! numbers). Each file type maps [`FileFailure`] into its own error type, adding the path.

use std::path::Path;

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

/// File encodings of scene and robot files.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum FileEncoding {
    Toml,
    Json,
}

/// The encoding chosen by the file extension (`.toml` or `.json`, any case).
pub(crate) fn encoding_of(path: &Path) -> Option<FileEncoding> {
    match path.extension().and_then(|e| e.to_str()) {
        Some(e) if e.eq_ignore_ascii_case("toml") => Some(FileEncoding::Toml),
        Some(e) if e.eq_ignore_ascii_case("json") => Some(FileEncoding::Json),
        _ => None,
    }
}

/// Why a world file could not be loaded; the caller adds the path and its file kind.
#[derive(Debug)]
pub(crate) enum FileFailure {
    /// The extension is neither `.toml` nor `.json`.
    UnknownExtension,
    /// The file could not be read.
    Read(std::io::Error),
    /// The parser's message (syntax, unknown or missing field, wrong type).
    Parse(String),
    /// The file says another format version than `supported`.
    UnsupportedVersion { found: u32, supported: u32 },
    /// Validation failed.
    Invalid(InvalidField),
}

#[derive(Deserialize)]
struct VersionProbe {
    format_version: u32,
}

/// Reads, parses and validates the file at `path` (encoding by extension).
pub(crate) fn load<T: DeserializeOwned>(
    path: &Path,
    supported: std::ops::RangeInclusive<u32>,
    validate: impl FnOnce(&T) -> Result<(), InvalidField>,
) -> Result<T, FileFailure> {
    let encoding = encoding_of(path).ok_or(FileFailure::UnknownExtension)?;
    let text = read_capped(path)?;
    parse(&text, encoding, supported, validate)
}

/// Most bytes a scene or robot file may have (the largest generated scene is a few kB): a
/// bigger file, or a special file that never ends, is refused before it fills the memory.
pub const MAX_WORLD_FILE_BYTES: u64 = 4 << 20;

/// Reads at most [`MAX_WORLD_FILE_BYTES`] (+1 to tell that there is more) as UTF-8.
fn read_capped(path: &Path) -> Result<String, FileFailure> {
    use std::io::Read;
    let file = std::fs::File::open(path).map_err(FileFailure::Read)?;
    let mut text = String::new();
    file.take(MAX_WORLD_FILE_BYTES + 1)
        .read_to_string(&mut text)
        .map_err(FileFailure::Read)?;
    if text.len() as u64 > MAX_WORLD_FILE_BYTES {
        return Err(FileFailure::Parse(format!(
            "larger than the {MAX_WORLD_FILE_BYTES} bytes a world file may have"
        )));
    }
    Ok(text)
}

/// Parses and validates `text` in `encoding`; `supported` are the format versions this build
/// reads (older ones load with the newer fields' defaults).
pub(crate) fn parse<T: DeserializeOwned>(
    text: &str,
    encoding: FileEncoding,
    supported: std::ops::RangeInclusive<u32>,
    validate: impl FnOnce(&T) -> Result<(), InvalidField>,
) -> Result<T, FileFailure> {
    // Look at the version first so that an old or future file says so instead of failing
    // on the first field it does not know.
    let version = match encoding {
        FileEncoding::Toml => toml::from_str::<VersionProbe>(text)
            .map(|p| p.format_version)
            .ok(),
        FileEncoding::Json => serde_json::from_str::<VersionProbe>(text)
            .map(|p| p.format_version)
            .ok(),
    };
    if let Some(found) = version
        && !supported.contains(&found)
    {
        return Err(FileFailure::UnsupportedVersion {
            found,
            supported: *supported.end(),
        });
    }
    let value: T = match encoding {
        FileEncoding::Toml => toml::from_str(text)
            .map_err(|e| FileFailure::Parse(e.to_string().trim_end().to_owned()))?,
        FileEncoding::Json => {
            serde_json::from_str(text).map_err(|e| FileFailure::Parse(e.to_string()))?
        }
    };
    validate(&value).map_err(FileFailure::Invalid)?;
    Ok(value)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_past_the_cap_is_refused_before_it_is_parsed() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("big.toml");
        let mut body = String::from("format_version = 1\n");
        while (body.len() as u64) <= MAX_WORLD_FILE_BYTES {
            body.push_str("# padding padding padding padding padding padding padding padding\n");
        }
        std::fs::write(&path, body).expect("write");
        let result = load::<VersionProbe>(&path, 1..=1, |_| Ok(()));
        match result {
            Err(FileFailure::Parse(m)) => assert!(m.contains("larger than"), "{m}"),
            other => panic!("expected a refusal for size, got {:?}", other.err()),
        }
        // Within the cap the same reader reads it.
        let small = dir.path().join("small.toml");
        std::fs::write(&small, "format_version = 1\n").expect("write");
        assert!(load::<VersionProbe>(&small, 1..=1, |_| Ok(())).is_ok());
    }
}

/// A field that failed validation: its path in the file (`chairs[3].x_m`) and the reason.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("field `{field}`: {reason}")]
pub struct InvalidField {
    /// Path of the field, e.g. `chairs[3].x_m`.
    pub field: String,
    /// What is wrong with it.
    pub reason: String,
}

impl InvalidField {
    pub(crate) fn new(field: impl Into<String>, reason: impl Into<String>) -> Self {
        Self {
            field: field.into(),
            reason: reason.into(),
        }
    }
}

/// Finds the first non-finite number anywhere in a serialisable value and names its path.
pub(crate) fn first_non_finite<T: Serialize>(value: &T) -> Option<String> {
    fn walk(value: &toml::Value, path: &str) -> Option<String> {
        match value {
            toml::Value::Float(f) if !f.is_finite() => Some(path.to_owned()),
            toml::Value::Array(items) => items
                .iter()
                .enumerate()
                .find_map(|(i, v)| walk(v, &format!("{path}[{i}]"))),
            toml::Value::Table(table) => table.iter().find_map(|(k, v)| {
                let child = if path.is_empty() {
                    k.clone()
                } else {
                    format!("{path}.{k}")
                };
                walk(v, &child)
            }),
            _ => None,
        }
    }
    // A value that toml cannot represent has no floats we could check; serde_json would reject
    // NaN anyway, so treat a failed conversion as "nothing found" and let validation go on.
    toml::Value::try_from(value).ok().and_then(|v| walk(&v, ""))
}
