//! Scene and robot files: every bad-file case of issue 2 fails with an error naming the file
//! and the field; good files round-trip.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::path::PathBuf;

use world::scene::{Chair, SCENE_FORMAT_VERSION};
use world::{RobotConfig, RobotError, Scene, SceneError};

fn data_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("data")
}

fn example_text() -> String {
    std::fs::read_to_string(data_dir().join("example-scene.toml"))
        .expect("example scene is part of the crate")
}

/// Parses `text` as if it were the file `bad.toml`, expecting a failure; returns the message.
fn scene_error(text: &str) -> (SceneError, String) {
    let err = Scene::from_toml_str(text, "bad.toml").expect_err("the scene must be rejected");
    let msg = err.to_string();
    assert!(msg.contains("bad.toml"), "error must name the file: {msg}");
    (err, msg)
}

#[test]
fn example_scene_loads_and_is_valid() {
    let scene = Scene::load(data_dir().join("example-scene.toml")).expect("example scene loads");
    assert_eq!(scene.format_version, SCENE_FORMAT_VERSION);
    assert_eq!(scene.banquet_table.segment_count, 9);
    assert!(!scene.chairs.is_empty());
    assert!(!scene.targets.is_empty());
}

#[test]
fn unknown_field_is_named() {
    let text = example_text().replacen("[room]", "[room]\nceiling_m = 3.0", 1);
    let (err, msg) = scene_error(&text);
    assert!(matches!(err, SceneError::Parse { .. }), "{msg}");
    assert!(msg.contains("ceiling_m"), "{msg}");
}

#[test]
fn nan_is_named() {
    let text = example_text().replacen("x_m = 1.5", "x_m = nan", 1);
    assert_ne!(
        text,
        example_text(),
        "fixture must contain a chair at x_m = 1.5"
    );
    let (err, msg) = scene_error(&text);
    assert!(matches!(err, SceneError::Invalid { .. }), "{msg}");
    assert!(msg.contains("chairs[0].x_m"), "{msg}");
}

#[test]
fn overlapping_chairs_are_rejected() {
    let mut scene = Scene::load(data_dir().join("example-scene.toml")).expect("example loads");
    let first = scene.chairs[0];
    scene
        .chairs
        .push(Chair::new(first.x_m + 0.2, first.y_m, 0.3));
    let text = scene.to_toml_string().expect("serialises");
    let (_, msg) = scene_error(&text);
    let last = scene.chairs.len() - 1;
    assert!(
        msg.contains(&format!("chairs[{last}]")) && msg.contains("overlaps chairs[0]"),
        "{msg}"
    );
}

#[test]
fn chair_overlapping_the_table_is_rejected() {
    let mut scene = Scene::empty_paper_room();
    scene.chairs.push(Chair::new(0.0, 5.7, 0.0));
    let text = scene.to_toml_string().expect("serialises");
    let (_, msg) = scene_error(&text);
    assert!(
        msg.contains("chairs[0]") && msg.contains("banquet table"),
        "{msg}"
    );
}

#[test]
fn chair_outside_the_room_is_rejected() {
    let mut scene = Scene::empty_paper_room();
    // Centre inside, but the footprint crosses the east wall.
    scene.chairs.push(Chair::new(9.9, 5.0, 0.0));
    let text = scene.to_toml_string().expect("serialises");
    let (_, msg) = scene_error(&text);
    assert!(
        msg.contains("chairs[0]") && msg.contains("outside the room"),
        "{msg}"
    );
}

#[test]
fn target_off_the_table_is_rejected() {
    let mut scene = Scene::empty_paper_room();
    scene.targets.push(world::UnloadTarget::on_center_line(2.0));
    scene.targets.push(world::UnloadTarget {
        x_m: 7.5,
        y_m: 6.0,
        z_m: 1.3,
    });
    let text = scene.to_toml_string().expect("serialises");
    let (_, msg) = scene_error(&text);
    assert!(
        msg.contains("targets[1]") && msg.contains("off the banquet table"),
        "{msg}"
    );

    let mut low = Scene::empty_paper_room();
    low.targets.push(world::UnloadTarget {
        x_m: 0.0,
        y_m: 6.0,
        z_m: 0.9,
    });
    let (_, msg) = scene_error(&low.to_toml_string().expect("serialises"));
    assert!(msg.contains("targets[0].z_m"), "{msg}");
}

#[test]
fn overlapping_tables_are_rejected() {
    let mut scene = Scene::empty_paper_room();
    scene.loading_table.center_y_m = 5.9;
    let (_, msg) = scene_error(&scene.to_toml_string().expect("serialises"));
    assert!(
        msg.contains("loading_table") && msg.contains("overlaps"),
        "{msg}"
    );
}

#[test]
fn robot_start_on_furniture_is_rejected() {
    let mut scene = Scene::empty_paper_room();
    scene.robot_start.y_m = 6.0;
    let (_, msg) = scene_error(&scene.to_toml_string().expect("serialises"));
    assert!(msg.contains("robot_start"), "{msg}");
}

#[test]
fn future_version_is_reported_as_such() {
    let text = example_text().replacen("format_version = 1", "format_version = 2", 1);
    let (err, msg) = scene_error(&text);
    assert!(
        matches!(
            err,
            SceneError::UnsupportedVersion {
                found: 2,
                supported: 1,
                ..
            }
        ),
        "{msg}"
    );
}

#[test]
fn missing_field_and_wrong_type_are_named() {
    let text = example_text().replacen("segment_count = 9", "", 1);
    let (_, msg) = scene_error(&text);
    assert!(msg.contains("segment_count"), "{msg}");
    let text = example_text().replacen("segment_count = 9", "segment_count = \"nine\"", 1);
    let (_, msg) = scene_error(&text);
    assert!(msg.contains("segment_count"), "{msg}");
}

#[test]
fn missing_file_and_bad_extension() {
    let err = Scene::load("/nonexistent/dir/scene.toml").expect_err("no such file");
    assert!(matches!(err, SceneError::Read { .. }));
    assert!(err.to_string().contains("/nonexistent/dir/scene.toml"));
    let err = Scene::load("scene.yaml").expect_err("unknown extension");
    assert!(matches!(err, SceneError::UnknownExtension { .. }));
}

#[test]
fn toml_and_json_round_trip() {
    let dir = tempfile::tempdir().expect("temp dir");
    let scene = world::generate::evaluation_scene(3, 25, 14);
    for name in ["s.toml", "s.json"] {
        let path = dir.path().join(name);
        scene.save(&path).expect("saves");
        let back = Scene::load(&path).expect("loads");
        assert_eq!(back, scene, "{name}");
    }
}

/// The in-memory JSON path reads what `save` writes to a `.json` file, and its errors name the
/// origin and the field, as the file path's do.
#[test]
fn json_text_round_trips_and_names_its_origin() {
    let scene = world::generate::evaluation_scene(3, 25, 14);
    let json = scene.to_json_string().expect("serialises");
    let back = Scene::from_json_str(&json, "s.json").expect("parses");
    assert_eq!(back, scene);
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("s.json");
    scene.save(&path).expect("saves");
    assert_eq!(std::fs::read_to_string(&path).expect("reads"), json);

    let bad = json.replacen("\"chairs\"", "\"chair\"", 1);
    let msg = Scene::from_json_str(&bad, "bad.json")
        .expect_err("an unknown field is refused")
        .to_string();
    assert!(msg.contains("bad.json") && msg.contains("chair"), "{msg}");

    let robot = RobotConfig::default();
    let json = robot.to_json_string().expect("serialises");
    let back = RobotConfig::from_json_str(&json, "r.json").expect("parses");
    assert_eq!(
        back.to_toml_string().expect("serialises"),
        robot.to_toml_string().expect("serialises")
    );
    let msg = RobotConfig::from_json_str("{\"format_version\": 999}", "old.json")
        .expect_err("a future version is refused")
        .to_string();
    assert!(msg.contains("old.json") && msg.contains("999"), "{msg}");
}

#[test]
fn default_robot_file_equals_default() {
    let loaded = RobotConfig::load(data_dir().join("robot.toml")).expect("robot.toml loads");
    let default = RobotConfig::default();
    assert_eq!(
        loaded.to_toml_string().expect("serialises"),
        default.to_toml_string().expect("serialises"),
        "data/robot.toml must stay equal to RobotConfig::default()"
    );
}

fn robot_error(text: &str) -> String {
    let err = RobotConfig::from_toml_str(text, "robot-bad.toml").expect_err("must be rejected");
    let msg = err.to_string();
    assert!(
        msg.contains("robot-bad.toml"),
        "error must name the file: {msg}"
    );
    msg
}

#[test]
fn bad_robot_files_name_the_field() {
    let good = RobotConfig::default().to_toml_string().expect("serialises");
    assert!(RobotConfig::from_toml_str(&good, "robot.toml").is_ok());

    let msg = robot_error(&good.replacen("speed_mps = 0.4", "speed_mps = -0.4", 1));
    assert!(msg.contains("speed_mps"), "{msg}");
    let msg = robot_error(&good.replacen("nav_noise_sigma_m = 0.1", "nav_noise_sigma_m = nan", 1));
    assert!(
        msg.contains("nav_noise_sigma_m") && msg.contains("finite"),
        "{msg}"
    );
    // Above what the base itself can be set to: refused, naming the limit.
    for (from, to, field) in [
        ("speed_mps = 0.4", "speed_mps = 40.0", "speed_mps"),
        ("accel_mps2 = 0.5", "accel_mps2 = 9.0", "accel_mps2"),
        (
            "yaw_rate_radps = 1.0",
            "yaw_rate_radps = 6.0",
            "yaw_rate_radps",
        ),
        (
            "yaw_accel_radps2 = 1.5",
            "yaw_accel_radps2 = 100.0",
            "yaw_accel_radps2",
        ),
        (
            "emergency_decel_mps2 = 3.923",
            "emergency_decel_mps2 = 8.0",
            "emergency_decel_mps2",
        ),
    ] {
        let bad = good.replacen(from, to, 1);
        assert_ne!(bad, good, "the default file has {from}");
        let msg = robot_error(&bad);
        assert!(msg.contains(field) && msg.contains("at most"), "{msg}");
    }
    // The safety stop's deceleration: positive, never gentler than the comfort deceleration.
    for (to, words) in [
        ("emergency_decel_mps2 = 0.0", "must be positive"),
        ("emergency_decel_mps2 = 0.3", "at least accel_mps2"),
        ("emergency_decel_mps2 = inf", "finite"),
    ] {
        let msg = robot_error(&good.replacen("emergency_decel_mps2 = 3.923", to, 1));
        assert!(
            msg.contains("emergency_decel_mps2") && msg.contains(words),
            "{msg}"
        );
    }
    // A file written before the field loads with the RMP's factory deceleration.
    let without = good.replacen("emergency_decel_mps2 = 3.923\n", "", 1);
    assert_ne!(without, good);
    let old = RobotConfig::from_toml_str(&without, "old.toml").expect("loads without the field");
    assert_eq!(
        old.emergency_decel_mps2,
        world::robot::DEFAULT_EMERGENCY_DECEL_MPS2
    );
    let msg = robot_error(&good.replacen("speed_mps = 0.4", "speed_mps = 0.4\nturbo = true", 1));
    assert!(msg.contains("turbo"), "{msg}");
    let msg = robot_error(&good.replacen("format_version = 2", "format_version = 7", 1));
    assert!(msg.contains("format_version"), "{msg}");

    // A version 1 file (before the range sensor) still loads, with the default sensor; a bad
    // sensor field is named.
    let lidar_at = good
        .find("[lidar]")
        .expect("the default file has a [lidar] section");
    let end = good[lidar_at..]
        .find("\n[")
        .and_then(|a| {
            good[lidar_at + a + 1..]
                .find("\n[")
                .map(|b| lidar_at + a + 1 + b + 1)
        })
        .unwrap_or(good.len());
    let v1 = format!("{}{}", &good[..lidar_at], &good[end..]).replacen(
        "format_version = 2",
        "format_version = 1",
        1,
    );
    assert!(!v1.contains("lidar"), "{v1}");
    let old = RobotConfig::from_toml_str(&v1, "v1.toml").expect("a version 1 file loads");
    assert_eq!(old.lidar, world::LidarSpec::default());
    let msg = robot_error(&good.replacen("rpm = 600.0", "rpm = 5000.0", 1));
    assert!(msg.contains("lidar.rpm"), "{msg}");

    let msg = robot_error(&good.replacen("carry_capacity = 3", "carry_capacity = 0", 1));
    assert!(msg.contains("carry_capacity"), "{msg}");
    let without = good.replacen("carry_capacity = 3\n", "", 1);
    assert_ne!(without, good, "the default file names carry_capacity");
    let robot = RobotConfig::from_toml_str(&without, "old.toml").expect("capacity is optional");
    assert_eq!(robot.carry_capacity, 3);

    let mut far_mount = RobotConfig::default();
    far_mount.place.mount.forward_m = 2.0;
    let msg = robot_error(&far_mount.to_toml_string().expect("serialises"));
    assert!(msg.contains("place.mount"), "{msg}");
    assert!(matches!(
        RobotConfig::from_toml_str(&far_mount.to_toml_string().expect("serialises"), "x.toml"),
        Err(RobotError::Invalid { .. })
    ));
}

#[test]
fn base_collision_model_is_checked() {
    let good = RobotConfig::default().to_toml_string().expect("serialises");
    let authors = good.replacen(
        "model = \"footprint\"",
        "model = \"chair_discs\"\nradius_m = 0.3",
        1,
    );
    let robot =
        RobotConfig::from_toml_str(&authors, "authors.toml").expect("the authors' model loads");
    assert_eq!(
        robot.base_collision,
        world::BaseCollisionModel::ChairDiscs { radius_m: 0.3 }
    );
    let msg = robot_error(&good.replacen(
        "model = \"footprint\"",
        "model = \"chair_discs\"\nradius_m = -1.0",
        1,
    ));
    assert!(msg.contains("base_collision.radius_m"), "{msg}");
    let msg = robot_error(&good.replacen("model = \"footprint\"", "model = \"hovercraft\"", 1));
    assert!(msg.contains("hovercraft"), "{msg}");
}

#[test]
fn oversized_rooms_and_counts_are_refused_before_anything_is_sized_from_them() {
    // A room 10^7 m long used to reach the occupancy grid and abort on a 12 GB allocation.
    let mut scene = Scene::load(data_dir().join("example-scene.toml")).unwrap();
    scene.room.x_max_m = 1.0e7;
    let text = scene.to_toml_string().unwrap();
    let (err, msg) = scene_error(&text);
    assert!(matches!(err, SceneError::Invalid { .. }), "{msg}");
    assert!(msg.contains("room") && msg.contains("at most"), "{msg}");

    let mut scene = Scene::load(data_dir().join("example-scene.toml")).unwrap();
    let t = scene.targets[0];
    scene.targets = vec![t; world::scene::MAX_TARGETS + 1];
    let (_, msg) = scene_error(&scene.to_toml_string().unwrap());
    assert!(msg.contains("targets"), "{msg}");

    let mut scene = Scene::load(data_dir().join("example-scene.toml")).unwrap();
    scene.banquet_table.segment_count = world::scene::MAX_TABLE_SEGMENTS + 1;
    let (_, msg) = scene_error(&scene.to_toml_string().unwrap());
    assert!(msg.contains("segment_count"), "{msg}");
}
