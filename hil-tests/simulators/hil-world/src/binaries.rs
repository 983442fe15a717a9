//! The world's and the onboard processes' binaries a mission starts: found beside the running
//! program (or its parent folder), built first when asked.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::harness_error::{Context, HarnessError, bail};

/// Where the three binaries are.
#[derive(Debug, Clone)]
pub struct Binaries {
    /// `grop-world`.
    pub world: PathBuf,
    /// `grop-planner`.
    pub planner: PathBuf,
    /// `grop-executive`.
    pub executive: PathBuf,
    /// `grop-recorder`.
    pub recorder: PathBuf,
}

const NAMES: [&str; 4] = [
    "grop-world",
    "grop-planner",
    "grop-executive",
    "grop-recorder",
];

fn workspace_root() -> PathBuf {
    // hil-tests/simulators/hil-world -> the workspace.
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../..")
}

fn find_in(dir: &Path) -> Option<Binaries> {
    let p = |n: &str| dir.join(n);
    NAMES.iter().all(|n| p(n).is_file()).then(|| Binaries {
        world: p(NAMES[0]),
        planner: p(NAMES[1]),
        executive: p(NAMES[2]),
        recorder: p(NAMES[3]),
    })
}

/// Finds the binaries next to the running program (or one folder up, for test binaries in
/// `target/<profile>/deps`). With `build`, first runs `cargo build --workspace --bins
/// --examples` in the same profile: the feature set `cargo test --workspace` builds with, so
/// after the test build this compiles nothing (a build of just the world and the onboard
/// packages would compile about 40 crates again with other features). For tests.
pub fn binaries(build: bool) -> Result<Binaries, HarnessError> {
    binaries_built_with(build, &[])
}

/// [`binaries`], built in one `cargo build` together with `packages` (the running program's
/// own package). Cargo turns on a shared dependency's features for all the packages of one
/// build together: the world and the onboard binaries built alone get other features of
/// `memchr`, `once_cell`, `digest`, `num-bigint` than `cargo build -p grop-cli` or
/// `--workspace` gave them, and about 40 crates compile again. Built with the program's package
/// they get the same features, so the program's own build already built them.
pub fn binaries_built_with(build: bool, packages: &[&str]) -> Result<Binaries, HarnessError> {
    let exe = std::env::current_exe().context("locating the running program")?;
    let dir = exe
        .parent()
        .context("the running program has no folder")?
        .to_path_buf();
    let up = dir.parent().map(Path::to_path_buf);
    if build {
        let manifest = workspace_root().join("Cargo.toml");
        if manifest.is_file() {
            let release = dir.components().any(|c| c.as_os_str() == "release");
            let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
            let mut cmd = Command::new(cargo);
            cmd.arg("build").arg("--manifest-path").arg(&manifest);
            if packages.is_empty() {
                // Called from a test binary: `cargo test --workspace` already built every bin
                // with the features of the whole workspace and its dev-dependencies; this set
                // (and no smaller one) gives the same features, so nothing compiles again.
                cmd.args(["--workspace", "--bins", "--examples"]);
            } else {
                cmd.args(["-p", "hil-world", "-p", "grop-onboard"]);
                for p in packages {
                    cmd.args(["-p", p]);
                }
                cmd.arg("--bins");
            }
            if release {
                cmd.arg("--release");
            }
            let status = cmd
                .status()
                .context("running cargo build for the world and the onboard binaries")?;
            if !status.success() {
                bail!("cargo build of grop-world and the onboard binaries failed");
            }
        }
    }
    find_in(&dir)
        .or_else(|| up.as_deref().and_then(find_in))
        .with_context(|| {
            format!(
                "grop-world, grop-planner, grop-executive and grop-recorder are not next to {} (build them: \
                 cargo build -p hil-world -p grop-onboard --bins)",
                exe.display()
            )
        })
}
