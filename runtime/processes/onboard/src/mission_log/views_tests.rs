//! The views against Foxglove's schemas, field for field, and what they say of a mission.

use super::*;
use crate::mission_log::foxglove::{check, fields, json_schema};
use grop_ipc::{
    HEATMAP_COLS, HEATMAP_ROWS, LocationHeatmap, MAX_HEATMAPS, MAX_TASK_STEPS, TableSide, TaskStep,
};
use serde_json::Value;

fn base(seq: u64, t_ns: u64, x: f64) -> BaseStateMsg {
    BaseStateMsg {
        seq,
        stamp_ns: t_ns,
        x_m: x,
        y_m: 1.0,
        yaw_rad: 0.5,
        speed_mps: 0.5,
        yaw_rate_radps: 0.1,
        commanded_speed_mps: 0.5,
        commanded_yaw_rate_radps: 0.1,
        mode: 1,
        fault_bits: 0,
        link_up: 1,
        watchdog_stopped: 0,
        monitor: 0,
        reserved0: 0,
        monitor_clearance_cm: grop_ipc::NO_CLEARANCE_CM,
        reserved: [0; 2],
    }
}

fn plan(scene: &Scene) -> TaskPlanMsg {
    let t = scene.targets[0];
    let mut m = TaskPlanMsg {
        plan_id: 1,
        stamp_ns: 10,
        source_frame_id: 1,
        answers_request: 1,
        utility: 1.0,
        feasibility: 0.8,
        cost_s: 10.0,
        reward: 10.0,
        object_count: 1,
        step_count: 0,
        decision_us: 0,
        steps: [TaskStep::navigate(0.0, 0.0, 0.0, 0.0); MAX_TASK_STEPS],
    };
    m.set_steps(&[
        TaskStep::navigate(0.0, 1.0, 0.0, 1.0),
        TaskStep::load(1, 0.0, 1.0),
        TaskStep::navigate(t.x_m, 5.3, 1.57, 5.0),
        TaskStep::unload(0, TableSide::Near, t.as_array(), [t.x_m, 5.3, 1.57], 0.8),
    ])
    .unwrap();
    m
}

/// Every view of a short made-up mission: the frames, the scene before and after, both
/// paths, the grid and the events.
fn views_of_a_mission() -> Vec<(Channel, u64, Vec<u8>)> {
    let mut scene = Scene::empty_paper_room();
    scene.targets.push(world::UnloadTarget::on_center_line(2.0));
    scene.chairs.push(world::Chair::new(2.0, 5.2, 1.57));
    let mut v = Views::new(scene.clone(), &RobotConfig::default());
    let mut out = v.take(0);
    v.camera(&frame_of(&scene, 1));
    v.truth(&truth(0, 0.05));
    v.arm_state(&ArmStateMsg {
        joints_rad: [0.1, -1.2, 1.0, -1.4, -1.57, 0.0],
        ..arm_msg()
    });
    for i in 0..200u64 {
        v.base_state(&base(i, i * 20_000_000, 0.01 * i as f64));
    }
    v.plan(&plan(&scene));
    let mut maps = heatmaps(&scene, 1, 2, 0.25);
    maps.locations[1].side = -1;
    v.heatmaps(&maps);
    let mut loaded = EventMsg::new(EventKind::Loaded, 20, "objects 0x1 on the tray");
    loaded.plan_id = 1;
    loaded.step_index = 1;
    loaded.source = 2;
    v.event(&loaded);
    let mut placed = EventMsg::new(EventKind::UnloadSucceeded, 30, "");
    placed.plan_id = 1;
    placed.step_index = 3;
    v.event(&placed);
    out.extend(v.take(4_000_000_000));
    out
}

/// Heatmaps of `count` locations of the scene's first target (near side), every cell `value`,
/// from the frame `source_frame_id`.
fn heatmaps(scene: &Scene, source_frame_id: u64, count: u32, value: f32) -> Box<HeatmapsMsg> {
    Box::new(HeatmapsMsg {
        stamp_ns: 10,
        source_frame_id,
        count,
        reserved: 0,
        locations: [LocationHeatmap {
            object_index: 0,
            side: 1,
            target_m: scene.targets[0].as_array(),
            feasibility: 0.8,
            values: [value; HEATMAP_ROWS * HEATMAP_COLS],
        }; MAX_HEATMAPS],
    })
}

/// The camera frame `frame_id` of `scene`, as the world renders it.
fn frame_of(scene: &Scene, frame_id: u64) -> Box<CameraFrameMsg> {
    let camera = world::camera::OverheadCamera::fitting_room(scene);
    let layout = world::camera::FrameLayout::rgb8(camera);
    let header = grop_ipc::CameraFrameHeader::for_layout(frame_id, 0, &layout);
    let mut pixels = vec![0u8; header.checked_len().unwrap()];
    world::camera::render_frame(scene, &camera, &mut pixels).unwrap();
    let mut m = CameraFrameMsg::boxed_zeroed();
    m.set_image(header, &pixels).unwrap();
    m
}

fn truth(stamp_ns: u64, x: f64) -> TruthMsg {
    TruthMsg {
        seq: 1,
        stamp_ns,
        x_m: x,
        y_m: 1.02,
        yaw_rad: 0.48,
        speed_mps: 0.0,
        yaw_rate_radps: 0.0,
    }
}

fn arm_msg() -> ArmStateMsg {
    ArmStateMsg {
        seq: 1,
        stamp_ns: 0,
        joints_rad: [0.0; 6],
        joint_speeds_radps: [0.0; 6],
        flange_pose: [0.0; 6],
        gripper_opening_m: 0.1,
        safety: 1,
        robot_mode: 7,
        program_running: 1,
        connected: 1,
        object_held: 0,
        reserved: [0; 5],
    }
}

#[test]
fn every_view_is_its_foxglove_schema_field_for_field() {
    let out = views_of_a_mission();
    for c in Channel::VIEWS {
        let n = out.iter().filter(|(ch, _, _)| *ch == c).count();
        assert!(n > 0, "no {} message", c.topic());
    }
    for (c, _, data) in &out {
        let v: Value = serde_json::from_slice(data).unwrap();
        if let Err(e) = check(c.schema_name(), &v) {
            panic!("{}: {e}\n{v}", c.topic());
        }
    }
}

#[test]
fn the_views_say_what_happened() {
    let out = views_of_a_mission();
    let last = |c: Channel| -> Value {
        let (_, _, d) = out.iter().rev().find(|(ch, _, _)| *ch == c).unwrap();
        serde_json::from_slice(d).unwrap()
    };
    // The frame tree, down to the flange.
    let tf = last(Channel::Tf);
    let pairs: Vec<(String, String)> = tf["transforms"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| {
            (
                t["parent_frame_id"].as_str().unwrap().to_owned(),
                t["child_frame_id"].as_str().unwrap().to_owned(),
            )
        })
        .collect();
    assert_eq!(pairs[0], ("map".into(), "odom".into()));
    assert_eq!(pairs[1], ("odom".into(), "base_link".into()));
    assert_eq!(pairs[2], ("base_link".into(), "arm_base".into()));
    assert_eq!(pairs[8], ("arm_link5".into(), "arm_link6".into()));
    // The world's truth, beside the estimate (HIL): its own frame, straight off the map.
    assert_eq!(pairs[9], ("map".into(), "truth_base_link".into()));
    assert_eq!(tf["transforms"][9]["translation"]["x"], 0.05);
    assert_eq!(tf["transforms"][9]["translation"]["y"], 1.02);
    // map -> odom -> base_link is the estimate.
    let t = |i: usize, k: &str| tf["transforms"][i]["translation"][k].as_f64().unwrap();
    let q = |i: usize| {
        tf["transforms"][i]["rotation"]["z"]
            .as_f64()
            .unwrap()
            .asin()
            * 2.0
    };
    let (mx, my, myaw) = (t(0, "x"), t(0, "y"), q(0));
    let (ox, oy) = (t(1, "x"), t(1, "y"));
    let x = mx + myaw.cos() * ox - myaw.sin() * oy;
    let y = my + myaw.sin() * ox + myaw.cos() * oy;
    // The base state of that instant had x = 0.01 * its index.
    let stamp = &tf["transforms"][0]["timestamp"];
    let ns = stamp["sec"].as_u64().unwrap() * 1_000_000_000 + stamp["nsec"].as_u64().unwrap();
    let want = 0.01 * (ns / 20_000_000) as f64;
    assert!(
        (x - want).abs() < 1e-3 && (y - 1.0).abs() < 1e-3,
        "{x} {y} {want}"
    );
    // The object was placed: its target says so, and it left the tray.
    let scene = last(Channel::Scene);
    let entity = |id: &str| -> Value {
        scene["entities"]
            .as_array()
            .unwrap()
            .iter()
            .find(|e| e["id"] == id)
            .cloned()
            .unwrap_or_else(|| panic!("no entity {id}"))
    };
    assert_eq!(entity("target/0")["texts"][0]["text"], "0 placed");
    assert_eq!(entity("target/0")["metadata"][0]["value"], "placed");
    assert_eq!(entity("robot/base")["cubes"].as_array().unwrap().len(), 1);
    assert_eq!(entity("robot/truth")["frame_id"], "truth_base_link");
    assert_eq!(
        entity("standing_spots")["arrows"].as_array().unwrap().len(),
        1
    );
    // The first scene, before anything happened: pending.
    let (_, _, first) = out.iter().find(|(c, _, _)| *c == Channel::Scene).unwrap();
    assert!(String::from_utf8_lossy(first).contains("\"0 pending\""));
    // The plan's path: the pose then, and two goals.
    assert_eq!(
        last(Channel::PlannedPath)["poses"]
            .as_array()
            .unwrap()
            .len(),
        3
    );
    // The grid: both sides of the table, 2 m either way of the target and 2 m deep.
    let grid = last(Channel::HeatmapGrid);
    assert_eq!(grid["column_count"], 64);
    let data = BASE64.decode(grid["data"].as_str().unwrap()).unwrap();
    assert_eq!(data.len(), 64 * 64 * 4);
    assert_eq!(&data[..4], &0.25f32.to_le_bytes());
    // Events, with their level and source.
    let log = last(Channel::EventLog);
    assert_eq!(log["level"], level::INFO);
    let (_, _, loaded) = out
        .iter()
        .find(|(c, _, d)| *c == Channel::EventLog && String::from_utf8_lossy(d).contains("Loaded"))
        .unwrap();
    assert!(String::from_utf8_lossy(loaded).contains("\"name\":\"executive\""));
}

/// Foxglove's field names, written out by hand from its schemas (the `.proto` files of
/// `foxglove-schemas-protobuf` 0.4.0), independently of [`fields`]: a misspelt or missing
/// field in the table fails here, and through the table, in every view.
#[test]
fn the_schema_table_has_foxglove_s_field_names() {
    let expected: &[(&str, &str)] = &[
        ("FrameTransforms", "transforms"),
        (
            "FrameTransform",
            "timestamp parent_frame_id child_frame_id translation rotation",
        ),
        ("SceneUpdate", "deletions entities"),
        (
            "SceneEntity",
            "timestamp frame_id id lifetime frame_locked metadata arrows cubes spheres \
             cylinders lines triangles texts models",
        ),
        ("SceneEntityDeletion", "timestamp type id"),
        ("CubePrimitive", "pose size color"),
        ("SpherePrimitive", "pose size color"),
        (
            "CylinderPrimitive",
            "pose size bottom_scale top_scale color",
        ),
        (
            "LinePrimitive",
            "type pose thickness scale_invariant points color colors indices",
        ),
        (
            "TextPrimitive",
            "pose billboard font_size scale_invariant color text",
        ),
        (
            "ArrowPrimitive",
            "pose shaft_length shaft_diameter head_length head_diameter color",
        ),
        ("PosesInFrame", "timestamp frame_id poses"),
        ("Pose", "position orientation"),
        ("Quaternion", "x y z w"),
        ("Color", "r g b a"),
        (
            "Grid",
            "timestamp frame_id pose column_count cell_size row_stride cell_stride fields data",
        ),
        ("PackedElementField", "name offset type"),
        ("Log", "timestamp level message name file line"),
        (
            "RawImage",
            "timestamp frame_id width height encoding step data",
        ),
    ];
    for (schema, names) in expected {
        let table: Vec<&str> = fields(schema).unwrap().iter().map(|(f, _)| *f).collect();
        let names: Vec<&str> = names.split_whitespace().collect();
        assert_eq!(table, names, "foxglove.{schema}");
        // The JSON Schema advertised lists the same.
        let s = json_schema(&format!("foxglove.{schema}"));
        let props: Vec<&str> = s["properties"]
            .as_object()
            .unwrap()
            .keys()
            .map(String::as_str)
            .collect();
        let mut sorted = names.clone();
        sorted.sort_unstable();
        assert_eq!(props, sorted, "foxglove.{schema}'s JSON Schema");
    }
}

#[test]
fn a_wrong_field_is_named() {
    let ok = serde_json::json!({
        "timestamp": {"sec": 1, "nsec": 2}, "level": 2, "message": "m", "name": "n",
        "file": "", "line": 0
    });
    assert_eq!(check("foxglove.Log", &ok), Ok(()));
    let mut renamed = ok.clone();
    let level = renamed.as_object_mut().unwrap().remove("level").unwrap();
    renamed["lvl"] = level;
    assert_eq!(
        check("foxglove.Log", &renamed),
        Err("Log.lvl: not a field of foxglove.Log".to_owned())
    );
    let mut typed = ok.clone();
    typed["line"] = serde_json::json!("0");
    assert!(
        check("foxglove.Log", &typed)
            .unwrap_err()
            .starts_with("Log.line")
    );
    let mut time = ok;
    time["timestamp"] = serde_json::json!({"sec": 1});
    assert!(
        check("foxglove.Log", &time)
            .unwrap_err()
            .starts_with("Log.timestamp")
    );
    let pose = serde_json::json!({"position": {"x": 0, "y": 0}, "orientation":
        {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}});
    assert_eq!(
        check("foxglove.Pose", &pose),
        Err("Pose.position.z: missing".to_owned())
    );
}

/// `/psi/views`: each location's crop is the planner's own cut of the decision's frame, and
/// beside it the heatmap in the heat colours; a decision whose frame was not logged gets none.
#[test]
fn psi_s_views_are_the_cut_crops_beside_their_heatmaps() {
    let out = views_of_a_mission();
    let (_, stamp, data) = out
        .iter()
        .find(|(c, _, _)| *c == Channel::PsiViews)
        .unwrap();
    assert_eq!(*stamp, 10, "stamped as the heatmaps");
    let image: Value = serde_json::from_slice(data).unwrap();
    let (w, h) = (2 * 64 + 2, 2 * 32 + 2);
    assert_eq!(
        (image["width"].as_u64(), image["height"].as_u64()),
        (Some(w), Some(h))
    );
    assert_eq!(image["encoding"], "rgb8");
    let rgb = BASE64.decode(image["data"].as_str().unwrap()).unwrap();
    let (w, h) = (w as usize, h as usize);
    assert_eq!(rgb.len(), w * h * 3);
    let px = |x: usize, y: usize| {
        [
            rgb[3 * (y * w + x)],
            rgb[3 * (y * w + x) + 1],
            rgb[3 * (y * w + x) + 2],
        ]
    };
    // The same scene and frame as the mission's; the planner's cut of both locations.
    let mut scene = Scene::empty_paper_room();
    scene.targets.push(world::UnloadTarget::on_center_line(2.0));
    scene.chairs.push(world::Chair::new(2.0, 5.2, 1.57));
    let frame = frame_of(&scene, 1);
    let layout = frame.header.layout().unwrap();
    let mut crops = [[0u8; 2048]; 2];
    world::camera::cut_views(
        frame.image().unwrap(),
        &layout,
        &[(2.0, Side::Near), (2.0, Side::Far)],
        &mut crops,
    )
    .unwrap();
    let heat = world::view::heat_colour(0.25).0;
    for (k, crop) in crops.iter().enumerate() {
        let top = k * 34;
        for r in 0..32 {
            for c in 0..64 {
                let g = crop[r * 64 + c];
                assert_eq!(px(c, top + r), [g, g, g], "location {k}, cell ({r}, {c})");
                assert_eq!(px(66 + c, top + r), heat, "location {k}, heat ({r}, {c})");
            }
        }
    }
    // The near crop shows the chair (white) next to the table (its top row is the table edge).
    assert!(crops[0].contains(&world::view::CHAIR_GRAY));
    assert_eq!(crops[0][32], world::view::TABLE_GRAY);

    // Heatmaps naming a frame that never came: no image, counted.
    let mut v = Views::new(scene.clone(), &RobotConfig::default());
    v.camera(&frame_of(&scene, 7));
    let mut maps = heatmaps(&scene, 8, 1, 0.5);
    v.heatmaps(&maps);
    assert!(!v.take(1).iter().any(|(c, _, _)| *c == Channel::PsiViews));
    assert_eq!(v.psi_views_missed(), 1);
    maps.source_frame_id = 7;
    v.heatmaps(&maps);
    assert!(v.take(2).iter().any(|(c, _, _)| *c == Channel::PsiViews));
}
