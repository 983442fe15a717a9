//! Scene generators: seeded, valid, in the authors' bands.

use world::generate::{evaluation_scene, evaluation_suite, training_scenes};

#[test]
fn same_seed_same_scenes_other_seed_other_scenes() {
    let a = training_scenes(42, 10, 10);
    let b = training_scenes(42, 10, 10);
    let c = training_scenes(43, 10, 10);
    assert_eq!(a, b);
    assert_ne!(a, c);
    assert_eq!(evaluation_scene(5, 20, 14), evaluation_scene(5, 20, 14));
    assert_ne!(evaluation_scene(5, 20, 14), evaluation_scene(6, 20, 14));
}

#[test]
fn training_scenes_follow_the_authors_bands() {
    let scenes = training_scenes(1, 10, 10);
    assert_eq!(scenes.len(), 10);
    for scene in &scenes {
        scene.validate().expect("generated scenes are valid");
        assert_eq!(scene.chairs.len(), 10);
        assert_eq!(scene.targets.len(), 10);
        for chair in &scene.chairs {
            assert!((-7.0..7.0).contains(&chair.x_m));
            assert!(
                (4.35..5.35).contains(&chair.y_m),
                "near band only: {}",
                chair.y_m
            );
            assert!((0.449..0.451).contains(&chair.width_m));
        }
        for (i, a) in scene.chairs.iter().enumerate() {
            for b in &scene.chairs[..i] {
                assert!((a.x_m - b.x_m).hypot(a.y_m - b.y_m) >= 0.8);
            }
        }
        for t in &scene.targets {
            assert!((-6.0..6.0).contains(&t.x_m));
            assert_eq!((t.y_m, t.z_m), (6.0, 1.3));
        }
    }
}

#[test]
fn evaluation_scenes_split_chairs_over_both_sides() {
    for (n, near) in [(15usize, 7usize), (20, 10), (25, 12)] {
        let scene = evaluation_scene(9, n, 14);
        scene.validate().expect("valid");
        assert_eq!(scene.chairs.len(), n);
        assert_eq!(scene.chairs.iter().filter(|c| c.y_m < 6.0).count(), near);
        assert!(
            scene
                .chairs
                .iter()
                .filter(|c| c.y_m > 6.0)
                .all(|c| (6.65..7.65).contains(&c.y_m))
        );
        assert_eq!(scene.targets.len(), 14);
    }
    let suite = evaluation_suite(2, 14);
    assert_eq!(suite.len(), 30);
    assert_eq!(suite.iter().map(|s| s.targets.len()).sum::<usize>(), 420);
}
