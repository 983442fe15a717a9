//! Files an operator hands the robot (`runtime/libraries/world`): scene and robot files, as text.

use std::borrow::Cow;

use world::{RobotConfig, Scene};

/// The input's text and whether it is JSON (first byte odd) or TOML (even). JSON that is not
/// UTF-8 is `None`: `load` refuses it on reading. TOML is read lossily.
fn file_text(data: &[u8]) -> Option<(bool, Cow<'_, str>)> {
    let (&mode, text) = data.split_first()?;
    if mode % 2 == 1 {
        std::str::from_utf8(text)
            .ok()
            .map(|t| (true, Cow::Borrowed(t)))
    } else {
        Some((false, String::from_utf8_lossy(text)))
    }
}

/// A scene file, in memory: TOML text through `Scene::from_toml_str` (first byte even) or JSON
/// text through `Scene::from_json_str` (odd; a file that is not UTF-8 is refused on reading, as
/// `Scene::load` does). A scene that loads is valid, and written and parsed again (TOML, and
/// JSON for JSON input) it is the same scene. In memory, so that a run costs the parsers and
/// not a temporary file: `Scene::load` is this plus `read_to_string` by the extension.
pub fn scene_file(data: &[u8]) {
    let Some((json, text)) = file_text(data) else {
        return;
    };
    let loaded = if json {
        Scene::from_json_str(&text, "fuzz.json")
    } else {
        Scene::from_toml_str(&text, "fuzz.toml")
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
    if json {
        let text = match scene.to_json_string() {
            Ok(t) => t,
            Err(e) => panic!("a loaded scene cannot be written as JSON: {e}"),
        };
        match Scene::from_json_str(&text, "again.json") {
            Ok(again) => assert_eq!(again, scene, "{text}"),
            Err(e) => panic!("a written JSON scene does not load: {e}\n{text}"),
        }
    }
}

/// A robot file, as [`scene_file`]: valid once loaded, and writes the same TOML after a write
/// and a parse (JSON input also through JSON).
pub fn robot_file(data: &[u8]) {
    let Some((json, text)) = file_text(data) else {
        return;
    };
    let loaded = if json {
        RobotConfig::from_json_str(&text, "fuzz.json")
    } else {
        RobotConfig::from_toml_str(&text, "fuzz.toml")
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
    if json {
        let text = match robot.to_json_string() {
            Ok(t) => t,
            Err(e) => panic!("a loaded robot cannot be written as JSON: {e}"),
        };
        match RobotConfig::from_json_str(&text, "again.json").map(|r| r.to_toml_string()) {
            Ok(Ok(t)) => assert_eq!(t, toml, "{text}"),
            Ok(Err(e)) => panic!("{e}"),
            Err(e) => panic!("a written JSON robot file does not load: {e}\n{text}"),
        }
    }
}
