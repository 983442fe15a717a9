//! Overhead views: the ceiling camera's 64 x 64 px, 4 m x 4 m view centred on a target, its
//! near and far 64 x 32 crops (the network's input Psi sees, paper eq. 2), heatmaps in the same
//! layout, and a whole-room picture.
//!
//! Geometry (docs/architecture.md, binding for all crates): the view is centred on
//! (x_t, [`TABLE_CENTER_Y_M`]), 0.0625 m per pixel, rows top-to-bottom = decreasing y. The near
//! crop is full-view rows 32..63; the far crop is rows 0..31 rotated 180 degrees, so its cell
//! (r, c) is the point mirror of near cell (r, c) through the target.
//!
//! Rendering is deterministic and cheap (about 0.15 ms per crop, `cargo bench -p world`): each cell averages 4 x 4
//! sub-samples of the gray level of what lies there (floor, table top, chair, wall).

pub use image::{Rgb, RgbImage};

use crate::geometry::OrientedRect;
use crate::scene::{Scene, TABLE_CENTER_Y_M};

/// Rows of a crop (and of a heatmap).
pub const CROP_ROWS: usize = 32;
/// Columns of a crop (and of a heatmap).
pub const CROP_COLS: usize = 64;
/// Cells of a crop: `CROP_ROWS * CROP_COLS`.
pub const CROP_CELLS: usize = CROP_ROWS * CROP_COLS;
/// Side of the full square view in pixels.
pub const VIEW_PX: usize = 64;
/// Side of the full square view (m).
pub const VIEW_SIZE_M: f64 = 4.0;
/// Size of one pixel / cell (m).
pub const CELL_SIZE_M: f64 = VIEW_SIZE_M / VIEW_PX as f64;
/// Crop rows of the paper's 24 x 8 candidate area: 0.5625 .. 1.0625 m off the centre line.
pub const CANDIDATE_ROWS: std::ops::RangeInclusive<usize> = 9..=16;
/// Crop columns of the candidate area: 1.5 m along the table centred on the target.
pub const CANDIDATE_COLS: std::ops::RangeInclusive<usize> = 20..=43;
/// Number of candidate cells (24 x 8 = 192).
pub const CANDIDATE_CELLS: usize = 24 * 8;

/// Gray level of bare floor in a crop.
pub const FLOOR_GRAY: u8 = 96;
/// Gray level of a table top.
pub const TABLE_GRAY: u8 = 176;
/// Gray level of a chair.
pub const CHAIR_GRAY: u8 = 255;
/// Gray level beyond the walls.
pub const WALL_GRAY: u8 = 0;

/// Sub-samples per cell side (4 x 4 = 16 per cell).
const SUBSAMPLES: usize = 4;

/// Which side of the banquet table the robot works from.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum Side {
    /// y < 6: the side of the loading station and the robot start.
    Near,
    /// y > 6.
    Far,
}

impl Side {
    /// Both sides, near first.
    pub const BOTH: [Side; 2] = [Side::Near, Side::Far];

    /// +1 for near, -1 for far (the dataset's `side` column).
    pub fn sign(self) -> i8 {
        match self {
            Side::Near => 1,
            Side::Far => -1,
        }
    }

    /// Base yaw that faces the table from this side: +pi/2 near, -pi/2 far.
    pub fn facing_yaw_rad(self) -> f64 {
        match self {
            Side::Near => std::f64::consts::FRAC_PI_2,
            Side::Far => -std::f64::consts::FRAC_PI_2,
        }
    }

    /// The side a world y lies on (the centre line itself counts as near).
    pub fn of_y(y_m: f64) -> Side {
        if y_m <= TABLE_CENTER_Y_M {
            Side::Near
        } else {
            Side::Far
        }
    }

    /// Lower-case name (`near`, `far`).
    pub fn name(self) -> &'static str {
        match self {
            Side::Near => "near",
            Side::Far => "far",
        }
    }
}

impl std::fmt::Display for Side {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Side {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "near" => Ok(Side::Near),
            "far" => Ok(Side::Far),
            other => Err(format!("unknown side `{other}` (near or far)")),
        }
    }
}

/// Whether crop cell (row, col) is one of the paper's 24 x 8 candidate cells.
pub fn in_candidate_area(row: usize, col: usize) -> bool {
    CANDIDATE_ROWS.contains(&row) && CANDIDATE_COLS.contains(&col)
}

/// All candidate cells, row-major.
pub fn candidate_cells() -> impl Iterator<Item = (usize, usize)> {
    CANDIDATE_ROWS.flat_map(|r| CANDIDATE_COLS.map(move |c| (r, c)))
}

/// World (x, y) of the centre of crop cell (row, col) for a target at `target_x_m`.
///
/// Near: x = x_t - 2 + (c + 0.5) * 0.0625, y = 6 - (r + 0.5) * 0.0625. Far: the point mirror
/// of that through (x_t, 6).
pub fn cell_center_world(target_x_m: f64, side: Side, row: usize, col: usize) -> (f64, f64) {
    crop_point_world(target_x_m, side, row as f64 + 0.5, col as f64 + 0.5)
}

/// World (x, y) of the fractional crop position (row_f, col_f), in cell units from the crop's
/// top-left corner.
pub fn crop_point_world(target_x_m: f64, side: Side, row_f: f64, col_f: f64) -> (f64, f64) {
    let along = -0.5 * VIEW_SIZE_M + col_f * CELL_SIZE_M;
    let across = row_f * CELL_SIZE_M;
    match side {
        Side::Near => (target_x_m + along, TABLE_CENTER_Y_M - across),
        Side::Far => (target_x_m - along, TABLE_CENTER_Y_M + across),
    }
}

/// The crop cell (row, col) of `side` containing world (x, y), or `None` outside that crop.
pub fn world_to_cell(target_x_m: f64, side: Side, x_m: f64, y_m: f64) -> Option<(usize, usize)> {
    let (along, across) = match side {
        Side::Near => (x_m - target_x_m, TABLE_CENTER_Y_M - y_m),
        Side::Far => (target_x_m - x_m, y_m - TABLE_CENTER_Y_M),
    };
    let col_f = (along + 0.5 * VIEW_SIZE_M) / CELL_SIZE_M;
    let row_f = across / CELL_SIZE_M;
    if !(0.0..CROP_COLS as f64).contains(&col_f) || !(0.0..CROP_ROWS as f64).contains(&row_f) {
        return None;
    }
    Some((row_f as usize, col_f as usize))
}

/// A feasibility heatmap: 32 x 64 f32 values in [0, 1], row-major, the same layout as a crop.
/// Value = probability that a base commanded to the cell centre, facing the table, ends up
/// collision-free and can place the object (Fea^m of paper eq. 1).
#[derive(Clone, PartialEq)]
pub struct Heatmap {
    values: [f32; CROP_CELLS],
}

impl Default for Heatmap {
    fn default() -> Self {
        Self::zeros()
    }
}

impl std::fmt::Debug for Heatmap {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let max = self.values.iter().copied().fold(0.0f32, f32::max);
        let nonzero = self.values.iter().filter(|v| **v > 0.0).count();
        f.debug_struct("Heatmap")
            .field("max", &max)
            .field("nonzero_cells", &nonzero)
            .finish()
    }
}

impl Heatmap {
    /// All zeros.
    pub fn zeros() -> Self {
        Self {
            values: [0.0; CROP_CELLS],
        }
    }

    /// From row-major values.
    pub fn from_values(values: [f32; CROP_CELLS]) -> Self {
        Self { values }
    }

    /// Row-major values.
    pub fn values(&self) -> &[f32; CROP_CELLS] {
        &self.values
    }

    /// Row-major values, mutable.
    pub fn values_mut(&mut self) -> &mut [f32; CROP_CELLS] {
        &mut self.values
    }

    /// Value at (row, col). Panics on an index outside 32 x 64 (a programming error).
    pub fn get(&self, row: usize, col: usize) -> f32 {
        self.values[row * CROP_COLS + col]
    }

    /// Sets the value at (row, col). Panics on an index outside 32 x 64.
    pub fn set(&mut self, row: usize, col: usize, value: f32) {
        self.values[row * CROP_COLS + col] = value;
    }

    /// The cell with the highest value and that value (first in row-major order on ties).
    pub fn argmax(&self) -> ((usize, usize), f32) {
        let mut best = (0, self.values[0]);
        for (i, &v) in self.values.iter().enumerate() {
            if v > best.1 {
                best = (i, v);
            }
        }
        ((best.0 / CROP_COLS, best.0 % CROP_COLS), best.1)
    }
}

/// Everything a crop can see, as gray shapes (with their bounding boxes), clipped to the crop.
struct ViewShapes {
    room: crate::scene::Room,
    tables: Vec<OrientedRect>,
    table_bounds: Vec<(f64, f64, f64, f64)>,
    chairs: Vec<OrientedRect>,
    chair_bounds: Vec<(f64, f64, f64, f64)>,
}

impl ViewShapes {
    /// The shapes whose bounding boxes meet `[x0, x1] x [y0, y1]`.
    fn within(scene: &Scene, x0: f64, x1: f64, y0: f64, y1: f64) -> Self {
        let meets = |b: &(f64, f64, f64, f64)| b.1 >= x0 && b.0 <= x1 && b.3 >= y0 && b.2 <= y1;
        let keep = |shapes: Vec<OrientedRect>| {
            let (mut kept, mut bounds) = (Vec::new(), Vec::new());
            for r in shapes {
                let b = r.bounds();
                if meets(&b) {
                    kept.push(r);
                    bounds.push(b);
                }
            }
            (kept, bounds)
        };
        let (tables, table_bounds) = keep(vec![
            scene.banquet_table.footprint(),
            scene.loading_table.footprint(),
        ]);
        let (chairs, chair_bounds) = keep(scene.chairs.iter().map(|c| c.footprint()).collect());
        Self {
            room: scene.room,
            tables,
            table_bounds,
            chairs,
            chair_bounds,
        }
    }

    fn gray_at(&self, x_m: f64, y_m: f64) -> u8 {
        if !self.room.contains(x_m, y_m) {
            WALL_GRAY
        } else if self.chairs.iter().any(|c| c.contains_point(x_m, y_m)) {
            CHAIR_GRAY
        } else if self.tables.iter().any(|t| t.contains_point(x_m, y_m)) {
            TABLE_GRAY
        } else {
            FLOOR_GRAY
        }
    }

    /// Mean gray over SUBSAMPLES^2 points of the cell whose top-left corner is (row, col).
    fn cell_gray(&self, target_x_m: f64, side: Side, row: usize, col: usize) -> u8 {
        // Most cells touch no shape and no wall: their bounds decide without sub-sampling.
        let (xa, ya) = crop_point_world(target_x_m, side, row as f64, col as f64);
        let (xb, yb) = crop_point_world(target_x_m, side, row as f64 + 1.0, col as f64 + 1.0);
        let (x0, x1, y0, y1) = (xa.min(xb), xa.max(xb), ya.min(yb), ya.max(yb));
        let touches = |&(rx0, rx1, ry0, ry1): &(f64, f64, f64, f64)| {
            rx1 >= x0 && rx0 <= x1 && ry1 >= y0 && ry0 <= y1
        };
        let inside_room = self.room.contains(x0, y0) && self.room.contains(x1, y1);
        // Chairs: a cell strictly apart from every chair (separating axis) sees none in any
        // sub-sample; a cell with all four corners in one chair (convex) sees it in all of them,
        // and a chair hides the table under it. Only cells on a chair's outline are sub-sampled.
        let mut chair_edge = false;
        for (chair, _) in self
            .chairs
            .iter()
            .zip(&self.chair_bounds)
            .filter(|(_, b)| touches(b))
        {
            match cell_relation(chair, x0, x1, y0, y1) {
                Relation::Apart => {}
                Relation::Inside if inside_room => return CHAIR_GRAY,
                _ => chair_edge = true,
            }
        }
        if inside_room && !chair_edge {
            if !self.table_bounds.iter().any(touches) {
                return FLOOR_GRAY;
            }
            // Table shapes are convex: all four corners inside means the whole cell is.
            let covered = |t: &&OrientedRect| {
                t.contains_point(x0, y0)
                    && t.contains_point(x1, y0)
                    && t.contains_point(x0, y1)
                    && t.contains_point(x1, y1)
            };
            if self.tables.iter().any(|t| covered(&t)) {
                return TABLE_GRAY;
            }
        }
        let mut sum = 0u32;
        for i in 0..SUBSAMPLES {
            for j in 0..SUBSAMPLES {
                let row_f = row as f64 + (i as f64 + 0.5) / SUBSAMPLES as f64;
                let col_f = col as f64 + (j as f64 + 0.5) / SUBSAMPLES as f64;
                let (x, y) = crop_point_world(target_x_m, side, row_f, col_f);
                sum += u32::from(self.gray_at(x, y));
            }
        }
        let n = (SUBSAMPLES * SUBSAMPLES) as u32;
        // Rounded integer mean: exact and platform-independent.
        ((sum + n / 2) / n) as u8
    }
}

/// Where an axis-aligned cell lies relative to a rectangle.
enum Relation {
    /// No point of the cell is in the rectangle (separated by more than rounding).
    Apart,
    /// Every point of the cell is in the rectangle.
    Inside,
    /// Anything else.
    Partial,
}

/// The cell `[x0, x1] x [y0, y1]` against `rect`, conservatively: `Apart` and `Inside` only when
/// certain. The caller has checked that the bounding boxes touch, so the cell's axes do not
/// separate them; the rectangle's own axes are tested here.
fn cell_relation(rect: &OrientedRect, x0: f64, x1: f64, y0: f64, y1: f64) -> Relation {
    // Margin well above rounding, far below the sub-sample spacing (1/8 of a 6.25 cm cell).
    const EPS: f64 = 1e-9;
    let corners = [(x0, y0), (x1, y0), (x0, y1), (x1, y1)];
    let local = corners.map(|(x, y)| rect.local_coordinates(x, y));
    let (hl, hw) = (rect.half_length_m, rect.half_width_m);
    let apart = local.iter().all(|l| l.0 > hl + EPS)
        || local.iter().all(|l| l.0 < -hl - EPS)
        || local.iter().all(|l| l.1 > hw + EPS)
        || local.iter().all(|l| l.1 < -hw - EPS);
    if apart {
        Relation::Apart
    } else if corners.iter().all(|&(x, y)| rect.contains_point(x, y)) {
        Relation::Inside
    } else {
        Relation::Partial
    }
}

/// The grayscale crop of `side` for a target at `target_x_m`: 32 x 64, row-major, exactly the
/// FCN's input (the far crop already rotated 180 degrees).
pub fn render_crop(scene: &Scene, target_x_m: f64, side: Side) -> [u8; CROP_CELLS] {
    // The crop's extent in the world, one cell wider all round.
    let (xa, ya) = crop_point_world(target_x_m, side, -1.0, -1.0);
    let (xb, yb) = crop_point_world(
        target_x_m,
        side,
        CROP_ROWS as f64 + 1.0,
        CROP_COLS as f64 + 1.0,
    );
    let shapes = ViewShapes::within(scene, xa.min(xb), xa.max(xb), ya.min(yb), ya.max(yb));
    let mut crop = [0u8; CROP_CELLS];
    for row in 0..CROP_ROWS {
        for col in 0..CROP_COLS {
            crop[row * CROP_COLS + col] = shapes.cell_gray(target_x_m, side, row, col);
        }
    }
    crop
}

/// The full 64 x 64 overhead view centred on (x_t, 6), row-major, north up: what the ceiling
/// camera above the target sees. Rows 32..63 equal the near crop; rows 0..31 are the far crop
/// rotated back.
pub fn render_view(scene: &Scene, target_x_m: f64) -> Vec<u8> {
    let near = render_crop(scene, target_x_m, Side::Near);
    let far = render_crop(scene, target_x_m, Side::Far);
    let mut view = vec![0u8; VIEW_PX * VIEW_PX];
    for row in 0..CROP_ROWS {
        for col in 0..CROP_COLS {
            view[(CROP_ROWS + row) * VIEW_PX + col] = near[row * CROP_COLS + col];
            // Far crop cell (r, c) sits at full-view row 31 - r, column 63 - c.
            view[(CROP_ROWS - 1 - row) * VIEW_PX + (CROP_COLS - 1 - col)] =
                far[row * CROP_COLS + col];
        }
    }
    view
}

/// Mapping between the world and a whole-room picture (north up).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RoomView {
    /// World x at the picture's left edge (m).
    pub x_min_m: f64,
    /// World y at the picture's top edge (m).
    pub y_max_m: f64,
    /// Picture resolution (pixels per metre).
    pub pixels_per_m: f64,
    /// Picture width (px).
    pub width_px: u32,
    /// Picture height (px).
    pub height_px: u32,
}

impl RoomView {
    /// The whole room at `pixels_per_m` (clamped to 1..=200).
    pub fn whole_room(scene: &Scene, pixels_per_m: f64) -> Self {
        Self::window(
            scene.room.x_min_m,
            scene.room.x_max_m,
            scene.room.y_min_m,
            scene.room.y_max_m,
            pixels_per_m,
        )
    }

    /// A window of the world [x_min, x_max] x [y_min, y_max] at `pixels_per_m` (clamped to 1..=200).
    pub fn window(
        x_min_m: f64,
        x_max_m: f64,
        y_min_m: f64,
        y_max_m: f64,
        pixels_per_m: f64,
    ) -> Self {
        let ppm = if pixels_per_m.is_finite() {
            pixels_per_m.clamp(1.0, 200.0)
        } else {
            40.0
        };
        let width_px = (((x_max_m - x_min_m) * ppm).ceil().max(1.0)) as u32;
        let height_px = (((y_max_m - y_min_m) * ppm).ceil().max(1.0)) as u32;
        Self {
            x_min_m,
            y_max_m,
            pixels_per_m: ppm,
            width_px,
            height_px,
        }
    }

    /// Picture coordinates (px, fractional) of a world point.
    pub fn to_pixel(&self, x_m: f64, y_m: f64) -> (f64, f64) {
        (
            (x_m - self.x_min_m) * self.pixels_per_m,
            (self.y_max_m - y_m) * self.pixels_per_m,
        )
    }

    /// World point at the centre of pixel (px, py).
    pub fn to_world(&self, px: u32, py: u32) -> (f64, f64) {
        (
            self.x_min_m + (f64::from(px) + 0.5) / self.pixels_per_m,
            self.y_max_m - (f64::from(py) + 0.5) / self.pixels_per_m,
        )
    }
}

// Colours of the room picture (the public ones are for legends).
const ROOM_FLOOR: Rgb<u8> = Rgb([222, 216, 204]);
const ROOM_WALL: Rgb<u8> = Rgb([60, 60, 60]);
/// Tables in [`render_room`].
pub const ROOM_TABLE: Rgb<u8> = Rgb([150, 110, 70]);
const ROOM_TABLE_SEAM: Rgb<u8> = Rgb([110, 80, 50]);
/// Chairs in [`render_room`].
pub const ROOM_CHAIR: Rgb<u8> = Rgb([70, 90, 140]);
/// Target crosses in [`render_room`].
pub const ROOM_TARGET: Rgb<u8> = Rgb([30, 60, 230]);
/// The robot's start in [`render_room`].
pub const ROOM_START: Rgb<u8> = Rgb([200, 40, 40]);

/// A colour picture of the room seen from above (floor, walls, tables, chairs, targets as blue
/// crosses, the robot start as a red dot). Deterministic.
pub fn render_room(scene: &Scene, view: &RoomView) -> RgbImage {
    let tables = [
        scene.banquet_table.footprint(),
        scene.loading_table.footprint(),
    ];
    let chairs: Vec<OrientedRect> = scene.chairs.iter().map(|c| c.footprint()).collect();
    let seam_half_width_m = 0.5 / view.pixels_per_m;
    let seams: Vec<f64> = (1..scene.banquet_table.segment_count)
        .map(|i| {
            scene.banquet_table.x_min_m() + f64::from(i) * scene.banquet_table.segment_length_m
        })
        .collect();
    let mut img = RgbImage::new(view.width_px, view.height_px);
    for (px, py, pixel) in img.enumerate_pixels_mut() {
        let (x, y) = view.to_world(px, py);
        *pixel = if !scene.room.contains(x, y) {
            ROOM_WALL
        } else if chairs.iter().any(|c| c.contains_point(x, y)) {
            ROOM_CHAIR
        } else if tables.iter().any(|t| t.contains_point(x, y)) {
            if tables[0].contains_point(x, y)
                && seams.iter().any(|s| (x - s).abs() <= seam_half_width_m)
            {
                ROOM_TABLE_SEAM
            } else {
                ROOM_TABLE
            }
        } else {
            ROOM_FLOOR
        };
    }
    for target in &scene.targets {
        draw_cross(&mut img, view, target.x_m, target.y_m, 0.12, ROOM_TARGET);
    }
    draw_disc(
        &mut img,
        view,
        scene.robot_start.x_m,
        scene.robot_start.y_m,
        0.1,
        ROOM_START,
    );
    img
}

/// Blends a heatmap of `side` for a target at `target_x_m` into a room picture: each cell is
/// painted from red (0) over yellow to green (1) with opacity growing with its value, cells
/// outside `only_candidates` (when set) are left alone. This is the paper's "combined heatmap".
pub fn overlay_heatmap(
    img: &mut RgbImage,
    view: &RoomView,
    target_x_m: f64,
    side: Side,
    heatmap: &Heatmap,
    only_candidates: bool,
) {
    for row in 0..CROP_ROWS {
        for col in 0..CROP_COLS {
            if only_candidates && !in_candidate_area(row, col) {
                continue;
            }
            let value = heatmap.get(row, col).clamp(0.0, 1.0);
            let (cx, cy) = cell_center_world(target_x_m, side, row, col);
            let (x0, y0) = view.to_pixel(cx - 0.5 * CELL_SIZE_M, cy + 0.5 * CELL_SIZE_M);
            let (x1, y1) = view.to_pixel(cx + 0.5 * CELL_SIZE_M, cy - 0.5 * CELL_SIZE_M);
            let colour = heat_colour(value);
            // Zero cells stay visible as a faint red so the labelled area shows.
            let alpha = 0.35 + 0.5 * f64::from(value);
            for py in pixel_span(y0, y1, view.height_px) {
                for px in pixel_span(x0, x1, view.width_px) {
                    let p = img.get_pixel_mut(px, py);
                    for (channel, target) in p.0.iter_mut().zip(colour.0) {
                        *channel = (f64::from(*channel) * (1.0 - alpha) + f64::from(target) * alpha)
                            .round() as u8;
                    }
                }
            }
        }
    }
}

/// Red (0) -> yellow (0.5) -> green (1).
pub fn heat_colour(value: f32) -> Rgb<u8> {
    let v = value.clamp(0.0, 1.0);
    if v < 0.5 {
        Rgb([230, (460.0 * v) as u8, 20])
    } else {
        Rgb([(230.0 * (2.0 - 2.0 * v)) as u8, 230, 20])
    }
}

/// A crop and its heatmap as one picture, scaled up `scale` times: gray crop, heatmap cells
/// (all of them, or the candidate area only) blended on top. Like the paper's Fig. 1 "combined
/// heatmaps".
pub fn combined_crop_image(
    crop: &[u8; CROP_CELLS],
    heatmap: &Heatmap,
    scale: u32,
    only_candidates: bool,
) -> RgbImage {
    let scale = scale.clamp(1, 64);
    let mut img = RgbImage::new(CROP_COLS as u32 * scale, CROP_ROWS as u32 * scale);
    for (px, py, pixel) in img.enumerate_pixels_mut() {
        let (row, col) = ((py / scale) as usize, (px / scale) as usize);
        let g = crop[row * CROP_COLS + col];
        let mut rgb = [g, g, g];
        if !only_candidates || in_candidate_area(row, col) {
            let value = heatmap.get(row, col);
            let colour = heat_colour(value);
            let alpha = 0.35 + 0.5 * f64::from(value.clamp(0.0, 1.0));
            for (channel, target) in rgb.iter_mut().zip(colour.0) {
                *channel =
                    (f64::from(*channel) * (1.0 - alpha) + f64::from(target) * alpha).round() as u8;
            }
        }
        *pixel = Rgb(rgb);
    }
    img
}

fn pixel_span(a: f64, b: f64, limit: u32) -> std::ops::Range<u32> {
    let lo = a.min(b).round().max(0.0) as u32;
    let hi = (a.max(b).round().max(0.0) as u32).min(limit);
    lo.min(hi)..hi
}

fn draw_disc(
    img: &mut RgbImage,
    view: &RoomView,
    x_m: f64,
    y_m: f64,
    radius_m: f64,
    colour: Rgb<u8>,
) {
    let (cx, cy) = view.to_pixel(x_m, y_m);
    let r = (radius_m * view.pixels_per_m).max(1.5);
    for py in pixel_span(cy - r, cy + r, img.height()) {
        for px in pixel_span(cx - r, cx + r, img.width()) {
            let dx = f64::from(px) + 0.5 - cx;
            let dy = f64::from(py) + 0.5 - cy;
            if dx * dx + dy * dy <= r * r {
                img.put_pixel(px, py, colour);
            }
        }
    }
}

fn draw_cross(
    img: &mut RgbImage,
    view: &RoomView,
    x_m: f64,
    y_m: f64,
    half_m: f64,
    colour: Rgb<u8>,
) {
    let (cx, cy) = view.to_pixel(x_m, y_m);
    let r = (half_m * view.pixels_per_m).max(2.0);
    let thick = (0.02 * view.pixels_per_m).max(1.0);
    for py in pixel_span(cy - r, cy + r, img.height()) {
        for px in pixel_span(cx - r, cx + r, img.width()) {
            let dx = f64::from(px) + 0.5 - cx;
            let dy = f64::from(py) + 0.5 - cy;
            if (dx - dy).abs() <= thick || (dx + dy).abs() <= thick {
                img.put_pixel(px, py, colour);
            }
        }
    }
}

/// Draws a filled marker (disc) at a world point: for goals and realised base positions.
pub fn draw_marker(
    img: &mut RgbImage,
    view: &RoomView,
    x_m: f64,
    y_m: f64,
    radius_m: f64,
    colour: Rgb<u8>,
) {
    draw_disc(img, view, x_m, y_m, radius_m, colour);
}

/// Draws the outline of a footprint (e.g. the robot base) into a room picture.
pub fn draw_rect_outline(
    img: &mut RgbImage,
    view: &RoomView,
    rect: &OrientedRect,
    colour: Rgb<u8>,
) {
    let corners = rect.corners();
    for k in 0..4 {
        let (ax, ay) = view.to_pixel(corners[k].0, corners[k].1);
        let (bx, by) = view.to_pixel(corners[(k + 1) % 4].0, corners[(k + 1) % 4].1);
        let steps = ((bx - ax).abs().max((by - ay).abs()).ceil() as u32).max(1);
        for s in 0..=steps {
            let t = f64::from(s) / f64::from(steps);
            let (px, py) = (ax + t * (bx - ax), ay + t * (by - ay));
            if px >= 0.0 && py >= 0.0 && (px as u32) < img.width() && (py as u32) < img.height() {
                img.put_pixel(px as u32, py as u32, colour);
            }
        }
    }
}
