//! The mission log: every message of a mission in one MCAP file (the log format Foxglove and
//! ROS 2 tooling read), written by one recorder process (`grop-recorder`).
//!
//! - [`codec`]: each topic as JSON with a JSON Schema (the camera as `foxglove.RawImage`);
//! - [`views`]: channels in Foxglove's well-known schemas ([`foxglove`]) that the recorder
//!   derives from the others: frames, scene, paths, heatmaps over the floor, events as log,
//!   Psi's views ([`psi_views`]);
//! - [`writer`]: a bounded queue in front of an MCAP writer thread (zstd chunks);
//! - [`recorder`]: what the recorder does each cycle: drain every topic and the CAN bus;
//! - [`reader`]: reading a log back, and the digest that compares two runs;
//! - [`live`]: the live view, a Foxglove WebSocket server fed by the recorder.

pub mod codec;
pub mod foxglove;
pub mod live;
pub mod reader;
pub mod recorder;
pub mod writer;

use std::path::{Path, PathBuf};

pub use codec::Channel;
pub use reader::{LoggedMessage, MissionLog, digest};
pub use recorder::{Recorder, RecorderConfig};

pub mod psi_views;
pub mod replay;
pub mod views;
pub use views::Views;
pub use writer::{LogWriter, Overflow, WriterConfig, WriterSummary};

/// Name of the metadata record that says which format the log is written in (`log_format`), and
/// by which build (`writer`). The writer puts it first in every log.
pub const LOG_METADATA: &str = "grop.log";
/// The format version this build writes (the `log_format` of [`LOG_METADATA`]). Every change to
/// a logged message raises it: a field added, removed, renamed or given another meaning or unit,
/// a channel added, removed or renamed. A log without it is version 1. The reader and
/// `grop replay` read every version from [`OLDEST_LOG_FORMAT`] up to this one (docs/logs.md has
/// the history of the versions).
pub const LOG_FORMAT: u32 = 7;
/// The oldest format version this build reads.
pub const OLDEST_LOG_FORMAT: u32 = 1;

/// Name of the metadata record that describes the mission (what a replay needs).
pub const MISSION_METADATA: &str = "grop.mission";
/// Name of the metadata record with the recorder's settings.
pub const RECORDER_METADATA: &str = "grop.recorder";

/// What went wrong with a log file.
#[derive(Debug, thiserror::Error)]
pub enum LogError {
    /// The file system.
    #[error("mission log {}: {stage}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What we were doing.
        stage: &'static str,
        /// The error.
        source: std::io::Error,
    },
    /// The MCAP layer (a corrupt or foreign file).
    #[error("mission log {}: {stage}: {detail}", path.display())]
    Mcap {
        /// The file.
        path: PathBuf,
        /// What we were doing.
        stage: &'static str,
        /// The library's error.
        detail: String,
    },
    /// The log's `log_format` is not a version this build reads (a newer build wrote it).
    #[error(
        "mission log {}: log_format {found} is not a version this build reads ({oldest} to {newest}): it was written by a newer grop; read it with that build",
        path.display(),
        oldest = OLDEST_LOG_FORMAT,
        newest = LOG_FORMAT
    )]
    UnknownFormat {
        /// The file.
        path: PathBuf,
        /// The version the log names.
        found: u32,
    },
    /// The log's `log_format` is not a version number.
    #[error(
        "mission log {}: the `{record}` metadata's log_format {value:?} is not a version number",
        path.display(),
        record = LOG_METADATA
    )]
    BadFormat {
        /// The file.
        path: PathBuf,
        /// What the field holds.
        value: String,
    },
    /// The writer thread died.
    #[error("mission log {}: the writer thread panicked", path.display())]
    WriterPanicked {
        /// The file.
        path: PathBuf,
    },
    /// A subscription or the bus.
    #[error("recorder: {0}")]
    Source(String),
}

impl LogError {
    pub(crate) fn io(path: &Path, stage: &'static str, source: std::io::Error) -> Self {
        Self::Io {
            path: path.to_owned(),
            stage,
            source,
        }
    }

    pub(crate) fn mcap(path: &Path, stage: &'static str, e: mcap::McapError) -> Self {
        Self::Mcap {
            path: path.to_owned(),
            stage,
            detail: e.to_string(),
        }
    }
}

/// The `grop.mission` metadata of a deployment: the deployment file, the map and robot files'
/// contents (a replay needs exactly what the mission ran with), the model's path and SHA-256,
/// and the settings after command-line overrides.
pub fn mission_metadata(
    deployment: &crate::deployment::Deployment,
) -> std::collections::BTreeMap<String, String> {
    use sha2::Digest;
    let read = |p: &Path| std::fs::read_to_string(p).unwrap_or_default();
    let mut m = std::collections::BTreeMap::new();
    m.insert(
        "deployment_file".into(),
        deployment.source.display().to_string(),
    );
    m.insert("deployment".into(), read(&deployment.source));
    m.insert("map".into(), read(&deployment.map));
    m.insert("map_file".into(), deployment.map.display().to_string());
    if let Some(robot) = &deployment.robot {
        m.insert("robot".into(), read(robot));
        m.insert("robot_file".into(), robot.display().to_string());
    }
    let model = std::fs::canonicalize(&deployment.model).unwrap_or(deployment.model.clone());
    m.insert("model_path".into(), model.display().to_string());
    if let Ok(bytes) = std::fs::read(&model) {
        let hash = sha2::Sha256::digest(&bytes);
        m.insert(
            "model_sha256".into(),
            hash.iter().map(|b| format!("{b:02x}")).collect(),
        );
    }
    m.insert("namespace".into(), deployment.namespace.clone());
    m.insert("clock".into(), deployment.clock.clone());
    m.insert("can".into(), deployment.can.to_string());
    m.insert("seed".into(), deployment.seed.to_string());
    m.insert("planner".into(), format!("{:?}", deployment.planner));
    m.insert("grop_version".into(), env!("CARGO_PKG_VERSION").into());
    m
}
