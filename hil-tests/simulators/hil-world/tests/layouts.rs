//! The hand-made layout suite (`hil-tests/layouts/`, docs/hil.md): every file loads with the
//! scene validation and says what it tests; three layouts run closed loop.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use hil_world::suite;

#[test]
fn every_handmade_layout_loads_validates_and_says_what_it_tests() {
    let dir = suite::suite_dir("handmade").unwrap();
    let scenes = suite::load_dir(&dir).unwrap();
    assert!(scenes.len() >= 12, "{} layouts", scenes.len());
    for s in &scenes {
        let text = std::fs::read_to_string(&s.path).unwrap();
        assert!(
            text.starts_with("# Hand-made layout"),
            "{}: no comment header",
            s.path.display()
        );
    }
    let most = scenes.iter().map(|s| s.scene.targets.len()).max();
    assert_eq!(most, Some(5), "a layout with 5 objects");
    assert!(suite::suite_dir("nope").is_err());
}

mod closed_loop {
    use std::time::Duration;

    use hil_world::mission::{self, MissionSpec};
    use hil_world::objects::ObjectState;
    use hil_world::report::{MissionEnd, WorldReport};
    use hil_world::suite;

    fn layout(name: &str) -> suite::SuiteScene {
        let dir = suite::suite_dir("handmade").unwrap();
        suite::load_dir(&dir)
            .unwrap()
            .into_iter()
            .find(|s| s.name.starts_with(name))
            .unwrap_or_else(|| panic!("no layout {name}"))
    }

    fn run(name: &str, seed: u64) -> WorldReport {
        run_with(name, seed, false)
    }

    fn run_with(name: &str, seed: u64, lidar: bool) -> WorldReport {
        let s = layout(name);
        let dir = std::env::temp_dir().join(mission::unique_run_name(&format!("grop-{name}")));
        // Blind (the range sensor off), as the other closed-loop tests of loading and planning:
        // docs/lidar.md, "Not done".
        let spec = MissionSpec {
            max_sim_s: 400.0,
            lidar,
            ..MissionSpec::new(
                dir,
                s.scene,
                std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                    .join("../../../models/psi-fcn.onnx"),
                seed,
            )
        };
        let bins = mission::binaries(true).expect("the world and onboard binaries build");
        mission::start(&spec, &bins)
            .expect("mission starts")
            .finish(Duration::from_secs(600), &mut |_| {})
            .expect("the world reports")
    }

    fn details<'a>(r: &'a WorldReport, kind: &str, has: &str) -> Vec<&'a str> {
        r.events
            .iter()
            .filter(|e| e.kind == kind && e.detail.contains(has))
            .map(|e| e.detail.as_str())
            .collect()
    }

    /// Issue 26, item 1: five objects with a tray of three. The world loads exactly what each
    /// load request asks, once; every object the executive reports released lands on its own
    /// target (on main three landed on other objects' targets, 2.1-4.2 m off). With the range
    /// sensor on: blind, the base stalls against a chair of this layout's 0.8 m gaps after the
    /// second unload and the mission ends stuck; with it, the legs to the last three spots end
    /// held by the monitor and those objects are given up (the mission still finishes).
    #[test]
    fn five_objects_with_a_tray_of_three_are_loaded_as_asked() {
        let r = run_with("01-", 7, true);
        assert_eq!(r.end, MissionEnd::Finished, "events: {:#?}", r.events);
        let asked = details(&r, "LoadRequested", "asked for");
        let loaded = details(&r, "Loaded", "put on the tray");
        assert!(asked.len() >= 2, "two station visits: {asked:?}");
        assert_eq!(asked.len(), loaded.len(), "{asked:?} / {loaded:?}");
        for (a, l) in asked.iter().zip(&loaded) {
            let mask = |s: &str| {
                s.split_whitespace()
                    .find(|w| w.starts_with("0x"))
                    .map(str::to_owned)
            };
            assert_eq!(mask(a), mask(l), "asked {a:?}, loaded {l:?}");
            assert!(!l.contains("of 0x"), "loaded less than asked: {l:?}");
        }
        assert!(details(&r, "TrayMismatch", "").is_empty());
        for o in &r.objects {
            assert_ne!(o.state, ObjectState::AtStation, "{o:?}");
            if let ObjectState::Released { error_m, .. } = o.state {
                assert!(
                    error_m < 0.3,
                    "object {} released {error_m:.2} m off",
                    o.index
                );
            }
        }
        let released = details(&r, "UnloadSucceeded", "released");
        assert!(released.len() >= 2, "{released:?}");
    }

    /// Issue 26, item 2: a target whose view reaches past the camera frame (outside the room:
    /// wall) no longer stops the mission: it ends with PlanFinished, none left at the station.
    #[test]
    fn a_view_past_the_frame_in_a_small_room_is_planned() {
        let r = run("02-", 3);
        assert_eq!(r.end, MissionEnd::Finished, "events: {:#?}", r.events);
        assert!(r.timing.sim_time_s < 300.0, "{:.1} s", r.timing.sim_time_s);
        assert!(r.not_attempted.is_empty(), "{:?}", r.not_attempted);
        assert!(r.placed_end_state >= 1, "{:#?}", r.objects);
    }

    /// Chairs pushed in on both sides with gaps of 0.9-1.0 m: the mission finishes and places.
    #[test]
    fn both_rows_pushed_in_finish_and_place() {
        let r = run("04-", 11);
        assert_eq!(r.end, MissionEnd::Finished, "events: {:#?}", r.events);
        assert!(r.placed_end_state >= 2, "{:#?}", r.objects);
    }
}
