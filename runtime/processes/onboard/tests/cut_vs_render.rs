//! What the camera path costs Psi: for many generated scenes, the FCN's F (eq. 4) of every
//! (target, side) from views cut out of a rendered 640 x 480 camera frame
//! (`world::camera::cut_view`) against F from the crops `world::view::render_crop` draws directly
//! (what `TaskProblem::from_world` feeds Psi). Prints the measured differences (run with
//! `--nocapture`).
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use grop_select::task_feasibility;
use planner::feasibility::FcnEvaluator;
use planner::methods::{MethodKind, PlannerConfig, location_heat};
use planner::problem::{TaskProblem, evaluate_crops, side_of_location};
use world::camera::{FrameLayout, OverheadCamera, cut_view, render_frame};
use world::view::CROP_CELLS;
use world::{Heatmap, RobotConfig, Scene};

fn model_path() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../models/psi-fcn.onnx")
}

fn psi_heatmaps(
    psi: &mut FcnEvaluator,
    scene: &Scene,
    robot: &RobotConfig,
    targets: &[[f64; 3]],
    crops: &[[u8; CROP_CELLS]],
) -> Vec<Heatmap> {
    let mut out = vec![Heatmap::zeros(); crops.len()];
    evaluate_crops(scene, robot, targets, crops, psi, &mut out).unwrap();
    out
}

/// F per location, both as the paper reads it (the whole candidate area) and as GROP reads it
/// by default (obstacle-free cells only).
fn location_f(
    scene: &Scene,
    robot: &RobotConfig,
    targets: &[[f64; 3]],
    heatmaps: &[Heatmap],
) -> Vec<(f64, f64)> {
    let problem = TaskProblem::from_heatmaps(scene, robot, targets, heatmaps);
    let config = PlannerConfig::for_robot(robot);
    problem
        .locations
        .iter()
        .map(|l| {
            (
                task_feasibility(&l.heat),
                task_feasibility(&location_heat(MethodKind::Grop, &config, l)),
            )
        })
        .collect()
}

#[test]
fn psi_f_from_cut_views_matches_f_from_rendered_crops() {
    let robot = RobotConfig::default();
    let mut psi = FcnEvaluator::load(&model_path()).unwrap();
    let mut scenes = world::generate::evaluation_suite(21, 3);
    scenes.extend(world::generate::training_scenes(22, 10, 3));
    let (mut sum_paper, mut sum_free, mut worst, mut count, mut pixels) =
        (0.0, 0.0, 0.0f64, 0, 0.0);
    for scene in &scenes {
        let targets: Vec<[f64; 3]> = scene.targets.iter().map(|t| t.as_array()).collect();
        let rendered = TaskProblem::render_crops(scene, &targets).unwrap();
        let camera = OverheadCamera::fitting_room(scene);
        let mut frame = vec![0u8; camera.rgb8_len()];
        render_frame(scene, &camera, &mut frame).unwrap();
        let layout = FrameLayout::rgb8(camera);
        let cut: Vec<[u8; CROP_CELLS]> = (0..rendered.len())
            .map(|i| {
                let mut crop = [0u8; CROP_CELLS];
                cut_view(
                    &frame,
                    &layout,
                    targets[i / 2][0],
                    side_of_location(i),
                    &mut crop,
                )
                .unwrap();
                crop
            })
            .collect();
        for (a, b) in cut.iter().zip(&rendered) {
            pixels += a
                .iter()
                .zip(b)
                .map(|(x, y)| f64::from(x.abs_diff(*y)))
                .sum::<f64>()
                / CROP_CELLS as f64;
        }
        let f_cut = location_f(
            scene,
            &robot,
            &targets,
            &psi_heatmaps(&mut psi, scene, &robot, &targets, &cut),
        );
        let f_rendered = location_f(
            scene,
            &robot,
            &targets,
            &psi_heatmaps(&mut psi, scene, &robot, &targets, &rendered),
        );
        for (c, r) in f_cut.iter().zip(&f_rendered) {
            sum_paper += (c.0 - r.0).abs();
            sum_free += (c.1 - r.1).abs();
            worst = worst.max((c.0 - r.0).abs()).max((c.1 - r.1).abs());
            count += 1;
        }
    }
    let n = f64::from(count);
    let (mean_paper, mean_free) = (sum_paper / n, sum_free / n);
    println!(
        "{} scenes, {count} (target, side) views: mean |cut - rendered| = {:.3} gray levels/px; \
         mean |dF| = {mean_paper:.5} (whole candidate area), {mean_free:.5} (free cells, GROP); \
         worst |dF| = {worst:.5}",
        scenes.len(),
        pixels / n,
    );
    assert!(mean_paper < 0.01 && mean_free < 0.01, "mean |dF| too large");
    assert!(worst < 0.05, "worst |dF| {worst}");
}
