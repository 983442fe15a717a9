//! Pieces shared by several subcommands: loading or generating the scene, the robot file, and the
//! picture window around the banquet table.

use std::path::{Path, PathBuf};

use world::view::RoomView;
use world::{RobotConfig, Scene};

/// Which generator makes the scene when no file is given.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum KindArg {
    /// evaluation_scene(seed, chairs, targets): chairs on both sides.
    Evaluation,
    /// training_scenes(seed, 1, targets)[0]: chairs on the near side only.
    Training,
}

/// The scene and robot options shared by the jobs that work on one scene.
#[derive(clap::Args, Debug)]
pub struct SceneArgs {
    /// Scene file (TOML/JSON); default: generate one (see --kind).
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Generated scene: evaluation (chairs on both sides) or training (near side only).
    #[arg(long, value_enum, default_value_t = KindArg::Evaluation)]
    pub kind: KindArg,
    /// Seed of the generated scene and of every random draw of the job.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Chairs in a generated evaluation scene (15 / 20 / 25 in the paper).
    #[arg(long, default_value_t = 20)]
    pub chairs: usize,
    /// Targets (objects to place) in a generated scene.
    #[arg(long, default_value_t = 3)]
    pub targets: usize,
    /// Robot file (TOML/JSON); default: the built-in paper robot.
    #[arg(long)]
    pub robot: Option<PathBuf>,
}

impl SceneArgs {
    /// The scene and the robot these options name.
    pub fn load(&self) -> anyhow::Result<(Scene, RobotConfig)> {
        // Committed scene and robot files are found from any working directory too.
        let scene_file = self.scene.as_deref().map(committed_file);
        let robot_file = self.robot.as_deref().map(committed_file);
        let scene = scene_from(
            scene_file.as_deref(),
            self.kind,
            self.seed,
            self.chairs,
            self.targets,
        )?;
        Ok((scene, robot_from(robot_file.as_deref())?))
    }
}

/// Loads the scene file, or generates one; validated either way.
fn scene_from(
    file: Option<&Path>,
    kind: KindArg,
    seed: u64,
    chairs: usize,
    targets: usize,
) -> anyhow::Result<Scene> {
    let scene = match file {
        Some(path) => Scene::load(path)?,
        None => match kind {
            KindArg::Evaluation => world::generate::evaluation_scene(seed, chairs, targets),
            KindArg::Training => world::generate::training_scenes(seed, 1, targets)
                .pop()
                .ok_or_else(|| anyhow::anyhow!("the generator returned no scene"))?,
        },
    };
    scene
        .validate()
        .map_err(|e| anyhow::anyhow!("scene: {e}"))?;
    Ok(scene)
}

/// Loads the robot file, or the built-in paper robot.
fn robot_from(file: Option<&Path>) -> anyhow::Result<RobotConfig> {
    Ok(match file {
        Some(path) => RobotConfig::load(path)?,
        None => RobotConfig::default(),
    })
}

/// The whole room, or the band around the banquet table (what pictures usually want).
pub fn room_view(scene: &Scene, pixels_per_m: f64, whole_room: bool) -> RoomView {
    if whole_room {
        return RoomView::whole_room(scene, pixels_per_m);
    }
    let bt = &scene.banquet_table;
    RoomView::window(
        (bt.x_min_m() - 0.75).max(scene.room.x_min_m),
        (bt.x_max_m() + 0.75).min(scene.room.x_max_m),
        (bt.y_min_m() - 2.2).max(scene.room.y_min_m),
        (bt.y_max_m() + 2.2).min(scene.room.y_max_m),
        pixels_per_m,
    )
}

/// The world and the onboard binaries a mission starts, built first (unless `build` is false)
/// in the same cargo build as this program's package, so that they share its features and a
/// workspace build (or `cargo run -p grop-cli`) leaves nothing to compile again.
pub fn mission_binaries(build: bool) -> anyhow::Result<hil_world::mission::Binaries> {
    Ok(hil_world::mission::binaries_built_with(
        build,
        &[env!("CARGO_PKG_NAME")],
    )?)
}

/// The checkout this program was built from.
pub fn checkout() -> PathBuf {
    // hil-tests/cli/grop-cli -> the workspace.
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../..")
}

/// A committed file or folder (the model, a model card, docs/) as the command line names it:
/// `path` itself when it exists from the working directory (or is absolute), else the same
/// relative path in the checkout this program was built from, so that every command works from
/// any working directory. Unchanged when neither exists, so that errors name what was given.
pub fn committed_file(path: &Path) -> PathBuf {
    if path.is_absolute() || path.exists() {
        return path.to_path_buf();
    }
    let in_checkout = checkout().join(path);
    if in_checkout.exists() {
        in_checkout
    } else {
        path.to_path_buf()
    }
}

/// [`committed_file`] as an absolute path (for the processes a mission starts, which run in
/// other folders); `what` names the file in the error when it is not there.
pub fn committed_file_abs(path: &Path, what: &str) -> anyhow::Result<PathBuf> {
    use anyhow::Context;
    std::fs::canonicalize(committed_file(path))
        .with_context(|| format!("{what} {} does not exist", path.display()))
}

/// The folder a run writes to: `out_dir` itself, or with `--shard` the shard's own folder in it
/// (created under a temporary name; the returned [`ShardDir`] renames it into place when the
/// run is done). Either way the folder exists on return.
pub fn output_folder(
    out_dir: &std::path::Path,
    shard: Option<trial_sim::shard::Shard>,
) -> anyhow::Result<(Option<trial_sim::shard::ShardDir>, std::path::PathBuf)> {
    use anyhow::Context;
    let shard_dir = match shard {
        Some(shard) => Some(
            trial_sim::shard::ShardDir::create(out_dir, shard)
                .with_context(|| format!("creating the shard folder in {}", out_dir.display()))?,
        ),
        None => None,
    };
    let dir = match &shard_dir {
        Some(d) => d.path().to_path_buf(),
        None => out_dir.to_path_buf(),
    };
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    Ok((shard_dir, dir))
}
