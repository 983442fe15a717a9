//! Scene suites for `grop hil --suite NAME` / `--scenes DIR`: folders of hand-written scene
//! files, each one mission. The hand-made suite (`hil-tests/layouts/`, docs/hil.md) holds layouts
//! the generator never makes: chairs pushed against the table with gaps of 0.8-1.0 m, odd chair
//! yaws, tables of 6-10 segments, targets near the table ends, starts off to the side or facing
//! away, small rooms, 4-5 objects.

use std::path::{Path, PathBuf};

use crate::harness_error::{Context, HarnessError, bail};
use world::Scene;

/// The suites that have a name, and their folders below the workspace root.
pub const SUITES: [(&str, &str); 1] = [("handmade", "hil-tests/layouts")];

/// The folder of the named suite (an absolute path inside this checkout).
pub fn suite_dir(name: &str) -> Result<PathBuf, HarnessError> {
    let (_, rel) = SUITES.iter().find(|(n, _)| *n == name).with_context(|| {
        let known: Vec<&str> = SUITES.iter().map(|(n, _)| *n).collect();
        format!("unknown suite {name:?} (known: {})", known.join(", "))
    })?;
    Ok(Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../..")
        .join(rel))
}

/// One scene of a suite.
#[derive(Debug, Clone)]
pub struct SuiteScene {
    /// The file.
    pub path: PathBuf,
    /// The file's stem (`03-near-row-gaps-0.8`): the scene's name in reports.
    pub name: String,
    /// The scene, validated.
    pub scene: Scene,
}

/// Every `.toml` and `.json` scene file of `dir`, in file-name order, loaded and validated; a
/// bad file is an error naming it and its field. An empty folder is an error too.
pub fn load_dir(dir: &Path) -> Result<Vec<SuiteScene>, HarnessError> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .with_context(|| format!("reading the scene folder {}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file() && p.extension().is_some_and(|e| e == "toml" || e == "json"))
        .collect();
    paths.sort();
    if paths.is_empty() {
        bail!("no scene files (.toml, .json) in {}", dir.display());
    }
    paths
        .into_iter()
        .map(|path| {
            let scene = Scene::load(&path).context("loading a scene")?;
            scene
                .validate()
                .with_context(|| format!("scene file {}", path.display()))?;
            let name = path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default();
            Ok(SuiteScene { path, name, scene })
        })
        .collect()
}
