//! Files an operator hands the robot (`runtime/world`): scene and robot files, as text.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use world::{RobotConfig, Scene};

/// A folder of this process for the JSON files (the loaders pick JSON by the extension).
fn scratch(file: &str) -> PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    let dir = DIR.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("grop-fuzz-replay-{}", std::process::id()));
        if let Err(e) = std::fs::create_dir_all(&dir) {
            panic!("cannot create {}: {e}", dir.display());
        }
        dir
    });
    // One file per thread: the replay test runs targets side by side.
    dir.join(format!("{:?}-{file}", std::thread::current().id()).replace(['(', ')'], ""))
}

fn write(path: &Path, text: &[u8]) {
    if let Err(e) = std::fs::write(path, text) {
        panic!("cannot write {}: {e}", path.display());
    }
}

/// A scene file: TOML text through `Scene::from_toml_str` (first byte even) or a `.json` file
/// through `Scene::load` (odd). A scene that loads is valid, and saved and loaded again (TOML,
/// and JSON for JSON input) it is the same scene.
pub fn scene_file(data: &[u8]) {
    let Some((&mode, text)) = data.split_first() else {
        return;
    };
    let loaded = if mode % 2 == 0 {
        Scene::from_toml_str(&String::from_utf8_lossy(text), "fuzz.toml")
    } else {
        let path = scratch("scene.json");
        write(&path, text);
        Scene::load(&path)
    };
    let scene = match loaded {
        Ok(scene) => scene,
        Err(e) => {
            let _ = e.to_string();
            return;
        }
    };
    assert_eq!(scene.validate(), Ok(()));
    let toml = match scene.to_toml_string() {
        Ok(t) => t,
        Err(e) => panic!("a loaded scene cannot be written: {e}"),
    };
    match Scene::from_toml_str(&toml, "again.toml") {
        Ok(again) => assert_eq!(again, scene, "{toml}"),
        Err(e) => panic!("a written scene does not load: {e}\n{toml}"),
    }
    if mode % 2 == 1 {
        let path = scratch("scene-again.json");
        if let Err(e) = scene.save(&path) {
            panic!("a loaded scene cannot be saved: {e}");
        }
        match Scene::load(&path) {
            Ok(again) => assert_eq!(again, scene),
            Err(e) => panic!("a saved scene does not load: {e}"),
        }
    }
}

/// A robot file, as [`scene_file`]: valid once loaded, the same after a save and a load.
pub fn robot_file(data: &[u8]) {
    let Some((&mode, text)) = data.split_first() else {
        return;
    };
    let loaded = if mode % 2 == 0 {
        RobotConfig::from_toml_str(&String::from_utf8_lossy(text), "fuzz.toml")
    } else {
        let path = scratch("robot.json");
        write(&path, text);
        RobotConfig::load(&path)
    };
    let robot = match loaded {
        Ok(robot) => robot,
        Err(e) => {
            let _ = e.to_string();
            return;
        }
    };
    assert!(robot.validate().is_ok());
    assert!(robot.travel_time_s(1.0).is_finite());
    let toml = match robot.to_toml_string() {
        Ok(t) => t,
        Err(e) => panic!("a loaded robot cannot be written: {e}"),
    };
    let again = match RobotConfig::from_toml_str(&toml, "again.toml") {
        Ok(r) => r,
        Err(e) => panic!("a written robot file does not load: {e}\n{toml}"),
    };
    // RobotConfig has no equality: compare what it writes.
    match again.to_toml_string() {
        Ok(t) => assert_eq!(t, toml),
        Err(e) => panic!("{e}"),
    }
}
