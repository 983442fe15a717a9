//! A figure like the paper's Fig. 5: per difficulty group, execution time (x) against completion
//! rate (y); each point averages 10 tasks, each method's ellipse is centred on the mean of its
//! points with the points' standard deviation as half-axes.

use std::path::Path;

use plotters::prelude::*;

use crate::{Difficulty, EvalError, Summary};
use planner::methods::MethodKind;

fn colour(m: MethodKind) -> RGBColor {
    match m {
        MethodKind::GropPlus => RGBColor(148, 103, 189),
        MethodKind::Grop => RGBColor(214, 39, 40),
        MethodKind::Satisficing => RGBColor(127, 127, 127),
        MethodKind::Petlon => RGBColor(31, 119, 180),
        MethodKind::Dvh => RGBColor(44, 160, 44),
        MethodKind::FcnPlanning => RGBColor(255, 127, 14),
    }
}

fn mean_std(v: &[f64]) -> (f64, f64) {
    if v.is_empty() {
        return (0.0, 0.0);
    }
    let m = v.iter().sum::<f64>() / v.len() as f64;
    let var = v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / v.len() as f64;
    (m, var.sqrt())
}

/// Draws the three panels into an SVG file.
pub fn fig5_svg(summary: &Summary, methods: &[MethodKind], path: &Path) -> Result<(), EvalError> {
    let err = |e: &dyn std::fmt::Display| EvalError::Plot {
        path: path.to_path_buf(),
        reason: e.to_string(),
    };
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|source| EvalError::Io {
            path: dir.to_path_buf(),
            source,
        })?;
    }
    let root = SVGBackend::new(path, (1500, 520)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let panels = root.split_evenly((1, 3));
    let xs: Vec<f64> = summary.points.iter().map(|p| p.2).collect();
    let x_max = xs.iter().cloned().fold(0.0, f64::max) * 1.1 + 1.0;
    let x_min = (xs.iter().cloned().fold(f64::INFINITY, f64::min) * 0.9).max(0.0);
    let x_min = if x_min.is_finite() { x_min } else { 0.0 };
    for (panel, d) in panels.iter().zip(Difficulty::ALL) {
        let mut chart = ChartBuilder::on(panel)
            .caption(format!("{} tasks", d.name()), ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(50)
            .build_cartesian_2d(x_min..x_max, 0.0..1.05)
            .map_err(|e| err(&e))?;
        chart
            .configure_mesh()
            .x_desc("execution time (s)")
            .y_desc("completion rate")
            .draw()
            .map_err(|e| err(&e))?;
        for &m in methods {
            let pts: Vec<(f64, f64)> = summary
                .points
                .iter()
                .filter(|p| p.0 == m && p.1 == d)
                .map(|p| (p.2, p.3))
                .collect();
            if pts.is_empty() {
                continue;
            }
            let c = colour(m);
            chart
                .draw_series(
                    pts.iter()
                        .map(|&(x, y)| Circle::new((x, y), 3, c.mix(0.6).filled())),
                )
                .map_err(|e| err(&e))?
                .label(m.name())
                .legend(move |(x, y)| Circle::new((x, y), 5, c.filled()));
            let (mx, sx) = mean_std(&pts.iter().map(|p| p.0).collect::<Vec<_>>());
            let (my, sy) = mean_std(&pts.iter().map(|p| p.1).collect::<Vec<_>>());
            let ring: Vec<(f64, f64)> = (0..=72)
                .map(|k| {
                    let t = k as f64 / 72.0 * std::f64::consts::TAU;
                    (mx + sx * t.cos(), my + sy * t.sin())
                })
                .collect();
            chart
                .draw_series(std::iter::once(Polygon::new(
                    ring.clone(),
                    c.mix(0.15).filled(),
                )))
                .map_err(|e| err(&e))?;
            chart
                .draw_series(std::iter::once(PathElement::new(ring, c.stroke_width(2))))
                .map_err(|e| err(&e))?;
            chart
                .draw_series(std::iter::once(Cross::new((mx, my), 6, c.stroke_width(2))))
                .map_err(|e| err(&e))?;
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::LowerRight)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| err(&e))?;
    }
    root.present().map_err(|e| err(&e))?;
    Ok(())
}
