//! The hand-made layout suite (`hil-tests/layouts/`, docs/hil.md): every file loads with the
//! scene validation and says what it tests; three layouts run closed loop.

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
