//! `grop render`: a scene seen from above with ground-truth feasibility heatmaps overlaid, like
//! the paper's Fig. 2 "combined heatmaps". With no arguments it generates an evaluation scene
//! (20 chairs over both sides, 3 targets), simulates both sides of every target and writes
//! `out/render.png`, the scene file beside it and a montage of the network-input crops.

use std::path::{Path, PathBuf};

use crate::common;
use anyhow::Context;
use trial_sim::{HeatmapArea, ground_truth_heatmaps, task_feasibility};
use world::Scene;
use world::view::{self, RgbImage, Side};

/// Arguments of `grop render`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub world: common::SceneArgs,
    /// Sides to simulate.
    #[arg(long, value_enum, default_value_t = SidesArg::Both)]
    pub sides: SidesArg,
    /// Trials per cell (more = smoother heatmaps).
    #[arg(long, default_value_t = 20)]
    pub trials_per_cell: u16,
    /// Cells to simulate: the paper's 24 x 8 candidate area or the whole 64 x 32 crop.
    #[arg(long, value_enum, default_value_t = AreaArg::Candidate)]
    pub area: AreaArg,
    /// Output PNG.
    #[arg(long, default_value = "out/render.png")]
    pub out: PathBuf,
    /// Picture resolution (pixels per metre; 64 makes a crop cell 4 px).
    #[arg(long, default_value_t = 64.0)]
    pub pixels_per_m: f64,
    /// Draw the whole room instead of the band around the banquet table.
    #[arg(long)]
    pub whole_room: bool,
}

/// `--sides` values.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum SidesArg {
    /// Near side only.
    Near,
    /// Far side only.
    Far,
    /// Both sides.
    Both,
}

/// `--area` values.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum AreaArg {
    /// The 24 x 8 candidate cells.
    Candidate,
    /// All 64 x 32 cells of each crop.
    Whole,
}

#[allow(
    clippy::too_many_lines,
    reason = "a command's steps in order: arguments, the scene, the pictures"
)]
pub fn run(args: Args) -> anyhow::Result<()> {
    let (scene, robot) = args.world.load()?;
    if args.trials_per_cell == 0 {
        anyhow::bail!("--trials-per-cell must be at least 1");
    }
    let sides: &[Side] = match args.sides {
        SidesArg::Near => &[Side::Near],
        SidesArg::Far => &[Side::Far],
        SidesArg::Both => &Side::BOTH,
    };
    let area = match args.area {
        AreaArg::Candidate => HeatmapArea::Candidate,
        AreaArg::Whole => HeatmapArea::WholeCrop,
    };
    let pairs: Vec<([f64; 3], Side)> = scene
        .targets
        .iter()
        .flat_map(|t| sides.iter().map(move |&s| (t.as_array(), s)))
        .collect();
    let heatmaps = ground_truth_heatmaps(
        &scene,
        &robot,
        &pairs,
        area,
        args.trials_per_cell,
        args.world.seed,
    );

    let room_view = common::room_view(&scene, args.pixels_per_m, args.whole_room);
    let mut picture = view::render_room(&scene, &room_view);
    let only_candidates = matches!(area, HeatmapArea::Candidate);
    for ((target, side), heatmap) in pairs.iter().zip(&heatmaps) {
        view::overlay_heatmap(
            &mut picture,
            &room_view,
            target[0],
            *side,
            heatmap,
            only_candidates,
        );
    }
    // Targets drawn again on top of the heatmaps, each labelled with its sides' F.
    let mut labels = crate::picture::Labels::default();
    for (i, target) in scene.targets.iter().enumerate() {
        view::draw_marker(
            &mut picture,
            &room_view,
            target.x_m,
            target.y_m,
            0.06,
            view::ROOM_TARGET,
        );
        labels.keep_clear(&room_view, (target.x_m, target.y_m), 0.1);
        let f: Vec<String> = pairs
            .iter()
            .zip(&heatmaps)
            .filter(|((t, _), _)| t[0] == target.x_m && t[1] == target.y_m)
            .map(|((_, side), h)| format!("{} {:.2}", side.name(), task_feasibility(h, area)))
            .collect();
        labels.add(
            &picture,
            &room_view,
            (target.x_m, target.y_m),
            &format!("obj{i} F {}", f.join(" / ")),
            crate::picture::INK,
            i % 2 == 0,
        );
    }
    labels.draw(&mut picture);
    crate::picture::scale_bar(&mut picture, &room_view);
    let mut legend = crate::picture::Legend {
        title: vec![
            format!("grop render: scene {}", scene.name),
            format!(
                "simulated, {} trials per cell, seed {}",
                args.trials_per_cell, args.world.seed
            ),
        ],
        entries: Vec::new(),
    };
    legend
        .entry(
            crate::picture::Swatch::Heat,
            "simulated F of a standing cell, 0 to 1",
        )
        .furniture();
    let picture = crate::picture::with_legend(&picture, &legend);
    if let Some(dir) = args.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    picture
        .save(&args.out)
        .with_context(|| format!("writing {}", args.out.display()))?;

    let crops_path = sibling(&args.out, "crops.png");
    crop_montage(&scene, &pairs, &heatmaps, only_candidates)
        .save(&crops_path)
        .with_context(|| format!("writing {}", crops_path.display()))?;
    let scene_path = sibling(&args.out, "scene.toml");
    scene.save(&scene_path)?;

    println!("target  x_m     side  F (eq. 4)  best cell");
    for ((target, side), heatmap) in pairs.iter().zip(&heatmaps) {
        let ((row, col), best) = heatmap.argmax();
        println!(
            "        {:>6.2}  {:<4}  {:.3}      {:.2} at ({row}, {col})",
            target[0],
            side.name(),
            task_feasibility(heatmap, area),
            best
        );
    }
    println!(
        "wrote {}, {}, {}",
        args.out.display(),
        crops_path.display(),
        scene_path.display()
    );
    Ok(())
}

/// `out/render.png` -> `out/render.<suffix>`.
fn sibling(path: &Path, suffix: &str) -> PathBuf {
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "render".into());
    path.with_file_name(format!("{stem}.{suffix}"))
}

/// The network's view of every (target, side): gray crop with its heatmap, 4x scaled, one row
/// per target, one column per side.
fn crop_montage(
    scene: &Scene,
    pairs: &[([f64; 3], Side)],
    heatmaps: &[world::Heatmap],
    only_candidates: bool,
) -> RgbImage {
    const SCALE: u32 = 4;
    const GAP: u32 = 6;
    let n_targets = pairs
        .iter()
        .map(|p| p.0[0].to_bits())
        .collect::<std::collections::BTreeSet<_>>()
        .len()
        .max(1);
    let cols = pairs.len().div_ceil(n_targets).max(1) as u32;
    let rows = n_targets as u32;
    let (cw, ch) = (
        view::CROP_COLS as u32 * SCALE,
        view::CROP_ROWS as u32 * SCALE,
    );
    let mut montage = RgbImage::from_pixel(
        cols * (cw + GAP) + GAP,
        rows * (ch + GAP) + GAP,
        view::Rgb([255, 255, 255]),
    );
    for (i, ((target, side), heatmap)) in pairs.iter().zip(heatmaps).enumerate() {
        let crop = view::render_crop(scene, target[0], *side);
        let tile = view::combined_crop_image(&crop, heatmap, SCALE, only_candidates);
        let (r, c) = ((i as u32) / cols, (i as u32) % cols);
        let (x0, y0) = (GAP + c * (cw + GAP), GAP + r * (ch + GAP));
        for (x, y, p) in tile.enumerate_pixels() {
            if x0 + x < montage.width() && y0 + y < montage.height() {
                montage.put_pixel(x0 + x, y0 + y, *p);
            }
        }
    }
    montage
}
