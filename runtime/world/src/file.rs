//! Shared reading of the versioned world files (scene and robot): extension -> encoding, read,
//! version probe, TOML or JSON parse, validation. Each file type maps [`FileFailure`] into its
//! own error type, adding the path.

use std::path::Path;

use serde::Deserialize;
use serde::de::DeserializeOwned;

use crate::scene::InvalidField;

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
    supported: u32,
    validate: impl FnOnce(&T) -> Result<(), InvalidField>,
) -> Result<T, FileFailure> {
    let encoding = encoding_of(path).ok_or(FileFailure::UnknownExtension)?;
    let text = std::fs::read_to_string(path).map_err(FileFailure::Read)?;
    parse(&text, encoding, supported, validate)
}

/// Parses and validates `text` in `encoding`; `supported` is the format version this build reads.
pub(crate) fn parse<T: DeserializeOwned>(
    text: &str,
    encoding: FileEncoding,
    supported: u32,
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
        && found != supported
    {
        return Err(FileFailure::UnsupportedVersion { found, supported });
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
