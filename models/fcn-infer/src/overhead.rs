//! From a 64 x 64 overhead view of a target to the two crops the network sees, and back.
//!
//! The overhead view (docs/architecture.md) is 4 m x 4 m, 0.0625 m per pixel, centred on the
//! target (x_t, 6.0); rows top-to-bottom are decreasing y, columns increasing x. Its bottom half
//! (rows 32..63) is the near crop as is. Its top half (rows 0..31), rotated 180 degrees, is the far
//! crop: the far side then looks like a near side, table at row 0, so one network serves both.
//! The far heatmap is rotated back the same way, which maps far-crop cell (r, c) to the world
//! point mirrored through the target, x = x_t + 2 - (c + 0.5) * 0.0625, y = 6 + (r + 0.5) * 0.0625.

use crate::{CROP_CELLS, CROP_COLS, CROP_ROWS, Crop, HeatmapCells};

/// Rows and columns of the full overhead view.
pub const VIEW_SIZE: usize = 64;
/// Cells of the full overhead view.
pub const VIEW_CELLS: usize = VIEW_SIZE * VIEW_SIZE;
/// Metres per pixel of the overhead view and of a crop.
pub const CELL_SIZE_M: f64 = 0.0625;

/// Which half of the overhead view a crop comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CropSide {
    /// y < 6: the loading-station side, rows 32..63 of the view as they are.
    Near,
    /// y > 6: rows 0..31 of the view rotated 180 degrees.
    Far,
}

/// Full-view (row, col) of crop cell (row, col) on `side`.
pub fn crop_to_view(side: CropSide, row: usize, col: usize) -> (usize, usize) {
    match side {
        CropSide::Near => (CROP_ROWS + row, col),
        CropSide::Far => (CROP_ROWS - 1 - row, CROP_COLS - 1 - col),
    }
}

/// World (x, y) in metres of the centre of crop cell (row, col) for a target at `target_x_m`.
pub fn crop_cell_world(target_x_m: f64, side: CropSide, row: usize, col: usize) -> (f64, f64) {
    let along = (col as f64 + 0.5) * CELL_SIZE_M;
    let across = (row as f64 + 0.5) * CELL_SIZE_M;
    match side {
        CropSide::Near => (target_x_m - 2.0 + along, 6.0 - across),
        CropSide::Far => (target_x_m + 2.0 - along, 6.0 + across),
    }
}

/// Cuts the crop of `side` out of a full overhead view (rotating the far half).
pub fn crop_from_view(view: &[u8; VIEW_CELLS], side: CropSide) -> Crop {
    let mut crop = [0u8; CROP_CELLS];
    for row in 0..CROP_ROWS {
        for col in 0..CROP_COLS {
            let (vr, vc) = crop_to_view(side, row, col);
            crop[row * CROP_COLS + col] = view[vr * VIEW_SIZE + vc];
        }
    }
    crop
}

/// Writes a crop-layout heatmap of `side` back into its half of a full-view heatmap.
pub fn heatmap_to_view(heat: &HeatmapCells, side: CropSide, view: &mut [f32; VIEW_CELLS]) {
    for row in 0..CROP_ROWS {
        for col in 0..CROP_COLS {
            let (vr, vc) = crop_to_view(side, row, col);
            view[vr * VIEW_SIZE + vc] = heat[row * CROP_COLS + col];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn far_crop_is_the_top_half_rotated() {
        let mut view = [0u8; VIEW_CELLS];
        for (i, v) in view.iter_mut().enumerate() {
            *v = (i % 251) as u8;
        }
        let far = crop_from_view(&view, CropSide::Far);
        // Crop row 0 (next to the table) is view row 31, and crop col 0 is view col 63.
        assert_eq!(far[0], view[31 * 64 + 63]);
        assert_eq!(far[CROP_CELLS - 1], view[0]);
        let near = crop_from_view(&view, CropSide::Near);
        assert_eq!(near[0], view[32 * 64]);
        assert_eq!(near[CROP_CELLS - 1], view[VIEW_CELLS - 1]);
    }

    #[test]
    fn round_trip_covers_the_view_once() {
        let mut near = [0f32; CROP_CELLS];
        let mut far = [0f32; CROP_CELLS];
        for i in 0..CROP_CELLS {
            near[i] = i as f32;
            far[i] = -(i as f32) - 1.0;
        }
        let mut view = [f32::NAN; VIEW_CELLS];
        heatmap_to_view(&near, CropSide::Near, &mut view);
        heatmap_to_view(&far, CropSide::Far, &mut view);
        assert!(view.iter().all(|v| v.is_finite()));
        assert_eq!(view[31 * 64 + 63], far[0]);
        assert_eq!(view[32 * 64], near[0]);
    }

    #[test]
    fn far_cell_is_the_mirror_of_the_near_cell_through_the_target() {
        let target_x = 1.7;
        for (row, col) in [(0, 0), (9, 20), (16, 43), (31, 63)] {
            let (nx, ny) = crop_cell_world(target_x, CropSide::Near, row, col);
            let (fx, fy) = crop_cell_world(target_x, CropSide::Far, row, col);
            assert!((nx + fx - 2.0 * target_x).abs() < 1e-12);
            assert!((ny + fy - 12.0).abs() < 1e-12);
        }
        // Candidate area: 0.56 .. 1.06 m off the centre line.
        let (_, y9) = crop_cell_world(0.0, CropSide::Near, 9, 20);
        assert!((6.0 - y9 - 0.59375).abs() < 1e-12);
    }

    #[test]
    fn view_pixel_and_world_agree() {
        // The view's pixel (vr, vc) is centred at x = x_t - 2 + (vc + 0.5) d, y = 6 + 2 - (vr + 0.5) d.
        let target_x = -3.25;
        for side in [CropSide::Near, CropSide::Far] {
            for (row, col) in [(0, 0), (5, 40), (31, 63)] {
                let (vr, vc) = crop_to_view(side, row, col);
                let x = target_x - 2.0 + (vc as f64 + 0.5) * CELL_SIZE_M;
                let y = 8.0 - (vr as f64 + 0.5) * CELL_SIZE_M;
                let (wx, wy) = crop_cell_world(target_x, side, row, col);
                assert!(
                    (x - wx).abs() < 1e-12 && (y - wy).abs() < 1e-12,
                    "{side:?} {row} {col}"
                );
            }
        }
    }
}
