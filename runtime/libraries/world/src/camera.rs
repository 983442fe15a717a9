//! The real overhead camera and Psi's views cut from its frames.
//!
//! On the robot the FCN Psi (paper eq. 2, `h = Psi(IM)`) does not get [`crate::view::render_crop`]'s
//! synthetic crops: it gets views cut out of a ceiling camera's whole-room frame. This module holds
//! both halves of that path so that they can be tested against each other:
//!
//! * [`OverheadCamera`]: a camera looking straight down, described by its metric header (size in
//!   pixels, metres per pixel, world x of the left edge of column 0, world y of the top edge of
//!   row 0; rows top-to-bottom = decreasing y, columns = increasing x, docs/architecture.md).
//! * [`render_frame`]: what such a camera sees of a scene, in RGB8: every pixel is the area mean
//!   of the colours under it (4 x 4 sub-samples where an outline crosses it), like a real
//!   sensor's box-filtered pixel. Allocation-free, into the caller's buffer (a loaned
//!   shared-memory frame).
//! * [`cut_view`]: the onboard side: Psi's 64 x 32 crop of one (target, side) from any frame by its
//!   metric header, with exactly the geometry of [`crate::view`] (near crop, or the far crop
//!   rotated 180 degrees). Each crop cell is the exact area average of the frame's gray levels
//!   over the cell's 6.25 cm square (pixels weighted by their overlap), so frames finer or
//!   coarser than 6.25 cm/px and at any offset resample correctly.
//!
//! # Colours and the conversion to Psi's gray levels
//!
//! Psi was trained on four gray levels (`view::FLOOR_GRAY` 96, `TABLE_GRAY` 176, `CHAIR_GRAY`
//! 255, `WALL_GRAY` 0). The camera's palette and the conversion are chosen so that flat areas map
//! back exactly:
//!
//! `gray = (77 R + 150 G + 29 B) / 256` (ITU-R BT.601 luma in 8-bit fixed point; the cutter keeps
//! the fraction while averaging and rounds once per crop cell), with floor (109, 93, 77) -> 96,
//! table wood (202, 170, 138) -> 176, chair covers white (255, 255, 255) -> 255, beyond the walls
//! black -> 0, each exactly (`77 R + 150 G + 29 B = 256 * gray`). The conversion is linear, so a
//! mixed pixel at an outline converts to the area mean of the grays under it. Mono8 frames are
//! taken as gray levels directly. Table seams and target marks are not drawn: the training
//! renders have none.
//!
//! ```
//! use world::camera::{FrameLayout, OverheadCamera, cut_view, render_frame};
//! use world::view::{CROP_CELLS, Side};
//! let scene = world::generate::evaluation_scene(3, 20, 3);
//! let camera = OverheadCamera::fitting_room(&scene);
//! let mut frame = vec![0u8; camera.rgb8_len()];
//! render_frame(&scene, &camera, &mut frame)?;
//! let mut crop = [0u8; CROP_CELLS];
//! cut_view(&frame, &FrameLayout::rgb8(camera), scene.targets[0].x_m, Side::Far, &mut crop)?;
//! # Ok::<(), world::camera::CameraError>(())
//! ```
#![allow(
    unsafe_code,
    reason = "AVX2 gathers of the view cuts, behind runtime feature detection"
)]

use crate::geometry::OrientedRect;
use crate::scene::Scene;
use crate::view::{CELL_SIZE_M, CROP_COLS, CROP_ROWS, Side, crop_point_world};

/// Width of the default camera frame (px).
pub const DEFAULT_WIDTH_PX: u32 = 640;
/// Height of the default camera frame (px).
pub const DEFAULT_HEIGHT_PX: u32 = 480;

/// Colour of bare floor (gray 96).
pub const FLOOR_RGB: [u8; 3] = [109, 93, 77];
/// Colour of a table top (gray 176).
pub const TABLE_RGB: [u8; 3] = [202, 170, 138];
/// Colour of a chair (gray 255).
pub const CHAIR_RGB: [u8; 3] = [255, 255, 255];
/// Colour beyond the walls (gray 0).
pub const WALL_RGB: [u8; 3] = [0, 0, 0];

/// Sub-samples per pixel side where an outline crosses a pixel.
const SUBSAMPLES: usize = 4;
/// Slack (pixels) for a view edge that lies on the frame's edge up to rounding.
const EDGE_SLACK_PX: f64 = 1e-6;

/// A camera looking straight down at the room: its image size and metric header.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OverheadCamera {
    /// Image width (px).
    pub width_px: u32,
    /// Image height (px).
    pub height_px: u32,
    /// Edge length of one pixel on the floor (m).
    pub metres_per_px: f64,
    /// World x of the left edge of column 0 (m).
    pub left_x_m: f64,
    /// World y of the top edge of row 0 (m).
    pub top_y_m: f64,
}

impl OverheadCamera {
    /// The default 640 x 480 camera, scaled so that the whole room fits, room centred.
    pub fn fitting_room(scene: &Scene) -> Self {
        Self::fitting_room_with(scene, DEFAULT_WIDTH_PX, DEFAULT_HEIGHT_PX)
    }

    /// A `width_px` x `height_px` camera (each at least 1), scaled so that the whole room fits,
    /// room centred. The paper's 20 m x 12.2 m room at 640 x 480 gets 3.125 cm per pixel.
    pub fn fitting_room_with(scene: &Scene, width_px: u32, height_px: u32) -> Self {
        let (width_px, height_px) = (width_px.max(1), height_px.max(1));
        let room = &scene.room;
        let metres_per_px = ((room.x_max_m - room.x_min_m) / f64::from(width_px))
            .max((room.y_max_m - room.y_min_m) / f64::from(height_px));
        let centre_x = 0.5 * (room.x_min_m + room.x_max_m);
        let centre_y = 0.5 * (room.y_min_m + room.y_max_m);
        Self {
            width_px,
            height_px,
            metres_per_px,
            left_x_m: centre_x - 0.5 * f64::from(width_px) * metres_per_px,
            top_y_m: centre_y + 0.5 * f64::from(height_px) * metres_per_px,
        }
    }

    /// Bytes of an RGB8 frame without row padding.
    pub fn rgb8_len(&self) -> usize {
        self.width_px as usize * self.height_px as usize * 3
    }

    /// World (x, y) of the centre of pixel (row, col).
    pub fn pixel_center_world(&self, row: u32, col: u32) -> (f64, f64) {
        (
            self.left_x_m + (f64::from(col) + 0.5) * self.metres_per_px,
            self.top_y_m - (f64::from(row) + 0.5) * self.metres_per_px,
        )
    }

    fn check(&self) -> Result<(), CameraError> {
        if self.width_px == 0 || self.height_px == 0 {
            return Err(CameraError::BadHeader {
                field: "width_px/height_px",
                reason: "must be at least 1",
            });
        }
        if !(self.metres_per_px.is_finite() && self.metres_per_px > 0.0) {
            return Err(CameraError::BadHeader {
                field: "metres_per_px",
                reason: "must be finite and > 0",
            });
        }
        if !(self.left_x_m.is_finite() && self.top_y_m.is_finite()) {
            return Err(CameraError::BadHeader {
                field: "left_x_m/top_y_m",
                reason: "must be finite",
            });
        }
        Ok(())
    }
}

/// How a frame's pixels are encoded (the one enum: the `camera/frame` message carries it too).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PixelFormat {
    /// Red, green, blue bytes.
    Rgb8,
    /// One gray byte.
    Mono8,
}

impl PixelFormat {
    /// Bytes per pixel.
    pub fn bytes_per_px(self) -> usize {
        match self {
            Self::Rgb8 => 3,
            Self::Mono8 => 1,
        }
    }
}

/// A frame's full description: geometry, encoding and row stride (what a camera message's
/// header says).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameLayout {
    /// Size and metric header.
    pub camera: OverheadCamera,
    /// Encoding.
    pub format: PixelFormat,
    /// Bytes from one row's start to the next's.
    pub row_stride_bytes: usize,
}

impl FrameLayout {
    /// An unpadded RGB8 frame of `camera` (what [`render_frame`] writes).
    pub fn rgb8(camera: OverheadCamera) -> Self {
        Self {
            camera,
            format: PixelFormat::Rgb8,
            row_stride_bytes: camera.width_px as usize * 3,
        }
    }

    /// Checks the header against itself and the pixel buffer's length.
    pub fn check(&self, pixels_len: usize) -> Result<(), CameraError> {
        self.camera.check()?;
        let row_bytes = self.camera.width_px as usize * self.format.bytes_per_px();
        if self.row_stride_bytes < row_bytes {
            return Err(CameraError::BadHeader {
                field: "row_stride_bytes",
                reason: "shorter than width_px times bytes per pixel",
            });
        }
        let needed = self.row_stride_bytes * (self.camera.height_px as usize - 1) + row_bytes;
        if pixels_len < needed {
            return Err(CameraError::BufferTooSmall {
                needed,
                got: pixels_len,
            });
        }
        Ok(())
    }
}

/// Why a frame could not be rendered or a view could not be cut from it.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum CameraError {
    /// Fewer crop buffers than views to cut.
    #[error("{views} views to cut but only {crops} crop buffers")]
    TooFewCrops {
        /// Views asked for.
        views: usize,
        /// Crop buffers given.
        crops: usize,
    },
    /// A header field makes no sense.
    #[error("camera frame header: {field} {reason}")]
    BadHeader {
        /// The field.
        field: &'static str,
        /// What is wrong with it.
        reason: &'static str,
    },
    /// The pixel buffer is shorter than the header says.
    #[error("camera frame buffer holds {got} bytes, the header needs {needed}")]
    BufferTooSmall {
        /// Bytes the header implies.
        needed: usize,
        /// Bytes given.
        got: usize,
    },
    /// The target's x is NaN or infinite.
    #[error("target x {0} is not finite")]
    BadTarget(f64),
    /// The 4 m x 2 m view of (target, side) is not completely inside the frame.
    #[error(
        "the {side} view of the target at x = {target_x_m:.3} m spans x {x_min_m:.3}..{x_max_m:.3} m, y {y_min_m:.3}..{y_max_m:.3} m, outside the frame's x {frame_x_min_m:.3}..{frame_x_max_m:.3} m, y {frame_y_min_m:.3}..{frame_y_max_m:.3} m"
    )]
    ViewOutsideFrame {
        /// Target x (m).
        target_x_m: f64,
        /// Side of the view.
        side: Side,
        /// View extent (m).
        x_min_m: f64,
        /// View extent (m).
        x_max_m: f64,
        /// View extent (m).
        y_min_m: f64,
        /// View extent (m).
        y_max_m: f64,
        /// Frame extent (m).
        frame_x_min_m: f64,
        /// Frame extent (m).
        frame_x_max_m: f64,
        /// Frame extent (m).
        frame_y_min_m: f64,
        /// Frame extent (m).
        frame_y_max_m: f64,
    },
}

/// Psi's gray level of an RGB colour, unrounded: `(77 R + 150 G + 29 B) / 256`.
pub fn luma(rgb: [u8; 3]) -> f64 {
    f64::from(77 * u32::from(rgb[0]) + 150 * u32::from(rgb[1]) + 29 * u32::from(rgb[2])) / 256.0
}

/// Psi's gray level of an RGB colour, rounded: exact for the camera's four palette colours.
pub fn rgb_to_gray(rgb: [u8; 3]) -> u8 {
    // At most 255.0: cannot overflow.
    luma(rgb).round() as u8
}

/// What lies on the floor at a point, by the same precedence as `view::render_crop`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Surface {
    Wall,
    Floor,
    Table,
    Chair,
}

impl Surface {
    fn rgb(self) -> [u8; 3] {
        match self {
            Surface::Wall => WALL_RGB,
            Surface::Floor => FLOOR_RGB,
            Surface::Table => TABLE_RGB,
            Surface::Chair => CHAIR_RGB,
        }
    }
}

/// The scene's furniture for the renderer, without a heap: the two tables and the chairs (whose
/// footprints are built on demand, only for chairs close to a pixel).
struct Furniture<'s> {
    scene: &'s Scene,
    tables: [OrientedRect; 2],
}

impl Furniture<'_> {
    fn surface_at(&self, x_m: f64, y_m: f64) -> Surface {
        if !self.scene.room.contains(x_m, y_m) {
            Surface::Wall
        } else if self.scene.chairs.iter().any(|c| {
            // Cheap rejection first: the footprint needs a sine and a cosine.
            let r = 0.5 * c.depth_m.hypot(c.width_m);
            (x_m - c.x_m).abs() <= r
                && (y_m - c.y_m).abs() <= r
                && c.footprint().contains_point(x_m, y_m)
        }) {
            Surface::Chair
        } else if self.tables.iter().any(|t| t.contains_point(x_m, y_m)) {
            Surface::Table
        } else {
            Surface::Floor
        }
    }

    /// The colour of the pixel covering `[x0, x1] x [y0, y1]`: the flat colour when one surface
    /// covers it all, else the mean of 4 x 4 sub-samples.
    fn pixel_rgb(&self, x0: f64, x1: f64, y0: f64, y1: f64) -> [u8; 3] {
        let room = &self.scene.room;
        let inside_room = room.contains(x0, y0) && room.contains(x1, y1);
        let outside_room =
            x1 < room.x_min_m || x0 > room.x_max_m || y1 < room.y_min_m || y0 > room.y_max_m;
        if outside_room {
            return WALL_RGB;
        }
        // A chair is certainly apart when its circumcircle misses the pixel's box.
        let chair_near = self.scene.chairs.iter().any(|c| {
            let r = 0.5 * c.depth_m.hypot(c.width_m);
            c.x_m + r >= x0 && c.x_m - r <= x1 && c.y_m + r >= y0 && c.y_m - r <= y1
        });
        if inside_room && !chair_near {
            let covered = |t: &OrientedRect| {
                t.contains_point(x0, y0)
                    && t.contains_point(x1, y0)
                    && t.contains_point(x0, y1)
                    && t.contains_point(x1, y1)
            };
            let touches = |t: &OrientedRect| {
                let (bx0, bx1, by0, by1) = t.bounds();
                bx1 >= x0 && bx0 <= x1 && by1 >= y0 && by0 <= y1
            };
            if !self.tables.iter().any(touches) {
                return FLOOR_RGB;
            }
            if self.tables.iter().any(covered) {
                return TABLE_RGB;
            }
        }
        let mut sum = [0u32; 3];
        for i in 0..SUBSAMPLES {
            for j in 0..SUBSAMPLES {
                let fx = (j as f64 + 0.5) / SUBSAMPLES as f64;
                let fy = (i as f64 + 0.5) / SUBSAMPLES as f64;
                let rgb = self
                    .surface_at(x0 + fx * (x1 - x0), y1 - fy * (y1 - y0))
                    .rgb();
                for (s, v) in sum.iter_mut().zip(rgb) {
                    *s += u32::from(v);
                }
            }
        }
        let n = (SUBSAMPLES * SUBSAMPLES) as u32;
        // Rounded integer mean per channel: at most 255.
        sum.map(|s| ((s + n / 2) / n) as u8)
    }
}

/// Renders what `camera` sees of `scene` into `out` as unpadded RGB8 (`camera.rgb8_len()`
/// bytes): walls, floor, tables and chairs in the palette of this module, each pixel the area mean
/// of the colours under it. Allocates nothing.
pub fn render_frame(
    scene: &Scene,
    camera: &OverheadCamera,
    out: &mut [u8],
) -> Result<(), CameraError> {
    let layout = FrameLayout::rgb8(*camera);
    layout.check(out.len())?;
    let furniture = Furniture {
        scene,
        tables: [
            scene.banquet_table.footprint(),
            scene.loading_table.footprint(),
        ],
    };
    let m = camera.metres_per_px;
    for (row, line) in out
        .chunks_exact_mut(layout.row_stride_bytes)
        .take(camera.height_px as usize)
        .enumerate()
    {
        let y1 = camera.top_y_m - row as f64 * m;
        let y0 = y1 - m;
        for (col, px) in line.chunks_exact_mut(3).enumerate() {
            let x0 = camera.left_x_m + col as f64 * m;
            px.copy_from_slice(&furniture.pixel_rgb(x0, x0 + m, y0, y1));
        }
    }
    Ok(())
}

/// Cuts Psi's 64 x 32 crop of (`target_x_m`, `side`) out of a camera frame by its metric header:
/// the near crop, or the far crop rotated 180 degrees, exactly the cells of
/// [`crate::view::cell_center_world`]. Each cell is the area-weighted mean gray level (see the
/// module docs for the conversion) of the frame pixels under its 6.25 cm square, rounded once.
/// Allocates nothing. For several views of one frame, [`cut_views`] is faster.
pub fn cut_view(
    pixels: &[u8],
    layout: &FrameLayout,
    target_x_m: f64,
    side: Side,
    crop: &mut [u8; CROP_ROWS * CROP_COLS],
) -> Result<(), CameraError> {
    cut_views(
        pixels,
        layout,
        &[(target_x_m, side)],
        std::slice::from_mut(crop),
    )
}

/// [`cut_view`] for every `(target_x_m, side)` of `views` into the crop of the same index: the
/// same crops, byte for byte. Views of one side share their frame rows (their crop rows lie at
/// the same y), so where they overlap along x each frame row under them is converted to gray and
/// weighted once for all of them. Checks every view before cutting any; the first bad one is the
/// error (it names its target and side). Allocates nothing.
pub fn cut_views(
    pixels: &[u8],
    layout: &FrameLayout,
    views: &[(f64, Side)],
    crops: &mut [[u8; CROP_ROWS * CROP_COLS]],
) -> Result<(), CameraError> {
    layout.check(pixels.len())?;
    if crops.len() < views.len() {
        return Err(CameraError::TooFewCrops {
            views: views.len(),
            crops: crops.len(),
        });
    }
    for &(target_x_m, side) in views {
        check_view(layout, target_x_m, side)?;
    }
    for side in [Side::Near, Side::Far] {
        // This side's views by their left pixel, merged into groups that overlap.
        let mut order = [(0usize, 0usize, 0usize); MAX_CUT_VIEWS];
        let mut count = 0;
        for (i, &(x, s)) in views.iter().enumerate() {
            if s != side {
                continue;
            }
            let (p0, p1) = view_pixel_columns(layout, x, side);
            if count == MAX_CUT_VIEWS {
                // More views than the sorting buffer: cut this one alone.
                let (rows, cols) = view_spans(layout, x, side);
                cut_group::<SEPARABLE_MAX_PX>(pixels, layout, &rows, &[(i, cols)], crops);
                continue;
            }
            order[count] = (p0, p1, i);
            count += 1;
        }
        let order = &mut order[..count];
        order.sort_unstable();
        let mut k = 0;
        while k < order.len() {
            let (u0, mut u1, first) = order[k];
            let (rows, cols) = view_spans(layout, views[first].0, side);
            let mut members = [(0usize, [Span::EMPTY; CROP_COLS]); MAX_GROUP];
            members[0] = (first, cols);
            let mut n = 1;
            k += 1;
            while k < order.len() && n < MAX_GROUP {
                let (p0, p1, i) = order[k];
                if p0 >= u1 || p1.max(u1) - u0 > SEPARABLE_MAX_PX {
                    break;
                }
                u1 = u1.max(p1);
                members[n] = (i, view_spans(layout, views[i].0, side).1);
                n += 1;
                k += 1;
            }
            cut_group::<SEPARABLE_MAX_PX>(pixels, layout, &rows, &members[..n], crops);
        }
    }
    Ok(())
}

/// Views sorted and grouped per call of [`cut_views`] and side; further views are cut alone.
const MAX_CUT_VIEWS: usize = 64;
/// Most views cut together in one pass over their frame rows.
const MAX_GROUP: usize = 4;

/// Whether the view of (`target_x_m`, `side`) can be cut from frames of `layout`: a finite
/// target whose view lies inside the frame. [`cut_views`] checks this for every view first.
pub fn check_view(layout: &FrameLayout, target_x_m: f64, side: Side) -> Result<(), CameraError> {
    if !target_x_m.is_finite() {
        return Err(CameraError::BadTarget(target_x_m));
    }
    let cam = &layout.camera;
    let m = cam.metres_per_px;
    // The view's extent, and that it lies inside the frame.
    let (xa, ya) = crop_point_world(target_x_m, side, 0.0, 0.0);
    let (xb, yb) = crop_point_world(target_x_m, side, CROP_ROWS as f64, CROP_COLS as f64);
    let (x_min, x_max, y_min, y_max) = (xa.min(xb), xa.max(xb), ya.min(yb), ya.max(yb));
    let width_px = f64::from(cam.width_px);
    let height_px = f64::from(cam.height_px);
    let inside = (x_min - cam.left_x_m) / m >= -EDGE_SLACK_PX
        && (x_max - cam.left_x_m) / m <= width_px + EDGE_SLACK_PX
        && (cam.top_y_m - y_max) / m >= -EDGE_SLACK_PX
        && (cam.top_y_m - y_min) / m <= height_px + EDGE_SLACK_PX;
    if !inside {
        return Err(CameraError::ViewOutsideFrame {
            target_x_m,
            side,
            x_min_m: x_min,
            x_max_m: x_max,
            y_min_m: y_min,
            y_max_m: y_max,
            frame_x_min_m: cam.left_x_m,
            frame_x_max_m: cam.left_x_m + width_px * m,
            frame_y_min_m: cam.top_y_m - height_px * m,
            frame_y_max_m: cam.top_y_m,
        });
    }
    Ok(())
}

/// Sub-samples per cell side of [`cut_view_past_frame`].
const PAST_FRAME_SUBSAMPLES: usize = 4;

/// Cuts the crop of a view that reaches past the frame's edge (where [`check_view`] refuses
/// it). Each cell is the mean gray of 4 x 4 sub-samples of its square: a sub-sample inside the
/// frame reads the pixel under it; one outside the frame *and outside the room* is wall (gray 0,
/// as the renderer draws beyond the walls: the map says so); one outside the frame but inside
/// the room is *unknown*: the cell is marked in `unknown` and reads as wall (gray 0), since
/// unknown is not free. Returns how many cells are unknown (0: the crop is complete, as the
/// rendered view would be up to the sub-sampling). Allocates nothing.
pub fn cut_view_past_frame(
    pixels: &[u8],
    layout: &FrameLayout,
    room: &crate::scene::Room,
    target_x_m: f64,
    side: Side,
    crop: &mut [u8; CROP_ROWS * CROP_COLS],
    unknown: &mut [bool; CROP_ROWS * CROP_COLS],
) -> Result<usize, CameraError> {
    layout.check(pixels.len())?;
    if !target_x_m.is_finite() {
        return Err(CameraError::BadTarget(target_x_m));
    }
    let cam = &layout.camera;
    let m = cam.metres_per_px;
    let bpp = layout.format.bytes_per_px();
    let wall = f64::from(rgb_to_gray(WALL_RGB));
    let sample = |x: f64, y: f64| -> Option<f64> {
        let u = ((x - cam.left_x_m) / m).floor();
        let v = ((cam.top_y_m - y) / m).floor();
        if u >= 0.0 && v >= 0.0 && u < f64::from(cam.width_px) && v < f64::from(cam.height_px) {
            let at = v as usize * layout.row_stride_bytes + u as usize * bpp;
            Some(match layout.format {
                PixelFormat::Mono8 => f64::from(pixels[at]),
                PixelFormat::Rgb8 => luma([pixels[at], pixels[at + 1], pixels[at + 2]]),
            })
        } else if !room.contains(x, y) {
            Some(wall)
        } else {
            None
        }
    };
    let n = PAST_FRAME_SUBSAMPLES;
    let mut unknown_cells = 0;
    for r in 0..CROP_ROWS {
        for c in 0..CROP_COLS {
            let mut sum = 0.0;
            let mut known = true;
            for i in 0..n {
                for j in 0..n {
                    let (x, y) = crop_point_world(
                        target_x_m,
                        side,
                        r as f64 + (i as f64 + 0.5) / n as f64,
                        c as f64 + (j as f64 + 0.5) / n as f64,
                    );
                    match sample(x, y) {
                        Some(g) => sum += g,
                        None => known = false,
                    }
                }
            }
            let k = r * CROP_COLS + c;
            unknown[k] = !known;
            crop[k] = if known {
                // A mean of gray levels in 0..=255: rounds into the range.
                (sum / (n * n) as f64).round() as u8
            } else {
                unknown_cells += 1;
                wall as u8
            };
        }
    }
    Ok(unknown_cells)
}

/// The frame columns `[p0, p1)` a view's cells touch.
fn view_pixel_columns(layout: &FrameLayout, target_x_m: f64, side: Side) -> (usize, usize) {
    // A column's span moves monotonically with the column (clamping keeps the order), so the
    // extremes are at the two end columns.
    let ends = [0, CROP_COLS - 1].map(|c| col_span(layout, target_x_m, side, c));
    let p0 = ends[0].first.min(ends[1].first);
    let p1 = ends[0].last.max(ends[1].last).max(p0);
    (p0, p1)
}

/// The frame pixel span of crop column `c`.
fn col_span(layout: &FrameLayout, target_x_m: f64, side: Side, c: usize) -> Span {
    let cam = &layout.camera;
    let m = cam.metres_per_px;
    let width_px = f64::from(cam.width_px);
    let (xa, _) = crop_point_world(target_x_m, side, 0.0, c as f64);
    let (xb, _) = crop_point_world(target_x_m, side, 1.0, c as f64 + 1.0);
    let u0 = ((xa.min(xb) - cam.left_x_m) / m).clamp(0.0, width_px);
    let u1 = (u0 + CELL_SIZE_M / m).min(width_px);
    Span {
        lo: u0,
        hi: u1,
        first: u0.floor() as usize,
        last: (u1.ceil() as usize).min(cam.width_px as usize),
    }
}

/// The pixel spans of a view's crop rows and columns in the frame. A cell's horizontal pixel
/// span depends on its column only, its vertical span on its row only (the view is
/// axis-aligned): both are computed once per column and per row, with the same operations as
/// per cell ([`cut_view_reference`]).
fn view_spans(
    layout: &FrameLayout,
    target_x_m: f64,
    side: Side,
) -> ([Span; CROP_ROWS], [Span; CROP_COLS]) {
    let cam = &layout.camera;
    let m = cam.metres_per_px;
    let height_px = f64::from(cam.height_px);
    let cell_px = CELL_SIZE_M / m;
    let mut cols = [Span::EMPTY; CROP_COLS];
    for (c, span) in cols.iter_mut().enumerate() {
        *span = col_span(layout, target_x_m, side, c);
    }
    let mut rows = [Span::EMPTY; CROP_ROWS];
    for (r, span) in rows.iter_mut().enumerate() {
        let (_, ya) = crop_point_world(target_x_m, side, r as f64, 0.0);
        let (_, yb) = crop_point_world(target_x_m, side, r as f64 + 1.0, 1.0);
        let v0 = ((cam.top_y_m - ya.max(yb)) / m).clamp(0.0, height_px);
        let v1 = (v0 + cell_px).min(height_px);
        *span = Span {
            lo: v0,
            hi: v1,
            first: v0.floor() as usize,
            last: (v1.ceil() as usize).min(cam.height_px as usize),
        };
    }
    (rows, cols)
}

/// Most frame pixels the views cut together may span along a row ([`cut_group`]'s buffers live
/// on the stack, zeroed per call): a lone view may have 8 per cell, so cameras down to about
/// 8 mm/px. Finer frames take [`cut_per_cell`].
const SEPARABLE_MAX_PX: usize = 512;

/// Rounds a non-negative value half away from zero, like `f64::round`, clamped to a byte,
/// without the libm call (exact: the integer part and the fraction are both exact in f64).
#[inline(always)]
fn round_non_negative(x: f64) -> u8 {
    let x = x.clamp(0.0, 255.0);
    let t = x as i32;
    // At most 255: 255.0 has no fraction.
    (t + i32::from(x - f64::from(t) >= 0.5)) as u8
}

/// The crops of views of one side (`members`: crop index and column spans; `rows` their common
/// row spans) by separating the area weights (each cell's weight is its column weight times its
/// row weight): every frame row under the views is converted to gray once for all of them (`77
/// R + 150 G + 29 B`, exact; the division by 256 comes last and is exact too), each crop row
/// sums its few frame rows with their row weights, and each cell then sums its few columns with
/// their column weights (computed once per view). The same sums as [`cut_per_cell`] in another
/// order (equal up to the last bits, so the same rounded crop; tested against the per-cell
/// reference). Members whose columns do not fit `MAX_PX` together are cut one by one, and one
/// that does not fit alone by [`cut_per_cell`].
fn cut_group<const MAX_PX: usize>(
    pixels: &[u8],
    layout: &FrameLayout,
    rows: &[Span; CROP_ROWS],
    members: &[(usize, [Span; CROP_COLS])],
    crops: &mut [[u8; CROP_ROWS * CROP_COLS]],
) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2 (checked just above); the function has no other
            // requirement.
            unsafe { cut_group_avx2::<MAX_PX>(pixels, layout, rows, members, crops) };
            return;
        }
    }
    cut_group_body::<MAX_PX>(pixels, layout, rows, members, crops);
}

/// [`cut_group`] compiled for AVX2 (wider vectors for the gray conversion, the row sums and the
/// roundings; no fused multiply-add, so the same results bit for bit).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn cut_group_avx2<const MAX_PX: usize>(
    pixels: &[u8],
    layout: &FrameLayout,
    rows: &[Span; CROP_ROWS],
    members: &[(usize, [Span; CROP_COLS])],
    crops: &mut [[u8; CROP_ROWS * CROP_COLS]],
) {
    cut_group_body::<MAX_PX>(pixels, layout, rows, members, crops);
}

#[inline(always)]
#[allow(
    clippy::too_many_lines,
    reason = "the view cut's inner loop in one body, shared by the AVX2 and the scalar entry points"
)]
fn cut_group_body<const MAX_PX: usize>(
    pixels: &[u8],
    layout: &FrameLayout,
    rows: &[Span; CROP_ROWS],
    members: &[(usize, [Span; CROP_COLS])],
    crops: &mut [[u8; CROP_ROWS * CROP_COLS]],
) {
    let bpp = layout.format.bytes_per_px();
    let p0 = members
        .iter()
        .flat_map(|(_, cols)| cols.iter().map(|s| s.first))
        .min()
        .unwrap_or(0);
    let p1 = members
        .iter()
        .flat_map(|(_, cols)| cols.iter().map(|s| s.last))
        .max()
        .unwrap_or(0)
        .max(p0);
    let width = p1 - p0;
    if width > MAX_PX.min(SEPARABLE_MAX_PX) || members.len() > MAX_GROUP {
        if members.len() == 1 {
            let (i, cols) = &members[0];
            cut_per_cell(pixels, layout, rows, cols, &mut crops[*i]);
        } else {
            for member in members {
                cut_group::<MAX_PX>(pixels, layout, rows, std::slice::from_ref(member), crops);
            }
        }
        return;
    }
    // Column weights, once per view: cell c of member g sums `weights[g][at..at + n]` against
    // the pixels from `first`. Each pixel is in at most two cells of a view.
    let mut weights = [[0.0f64; 2 * CROP_COLS + SEPARABLE_MAX_PX]; MAX_GROUP];
    let mut cells = [[(0usize, 0usize, 0usize, 0.0f64); CROP_COLS]; MAX_GROUP];
    for ((_, cols), (w, cells)) in members.iter().zip(weights.iter_mut().zip(cells.iter_mut())) {
        let mut used = 0;
        for (cs, cell) in cols.iter().zip(cells.iter_mut()) {
            let (mut n, mut first, mut area_x) = (0, p0, 0.0);
            for col in cs.first..cs.last {
                let wx = cs.hi.min(col as f64 + 1.0) - cs.lo.max(col as f64);
                if wx <= 0.0 {
                    continue;
                }
                if n == 0 {
                    first = col;
                }
                // A span's columns after its first positive weight are contiguous.
                w[used + col - first] = wx;
                n = col - first + 1;
                area_x += wx;
            }
            *cell = (used, first - p0, n, area_x);
            used += n;
        }
    }
    // Where every cell spans at most three pixels (cameras of 2.1 cm/px or coarser), the same
    // weights as three per cell, zero-padded: `0 * a` adds an exact zero, so the sums are the
    // same, bit for bit, without a loop per cell.
    let mut three = [[([0.0f64; 3], 0usize); CROP_COLS]; MAX_GROUP];
    let mut fits_three = [false; MAX_GROUP];
    for (g, (w, cells)) in weights
        .iter()
        .zip(cells.iter())
        .enumerate()
        .take(members.len())
    {
        fits_three[g] = cells.iter().all(|&(_, _, n, _)| n <= 3);
        if fits_three[g] {
            for (t, &(at, first, n, _)) in three[g].iter_mut().zip(cells.iter()) {
                t.0[..n].copy_from_slice(&w[at..at + n]);
                t.1 = first;
            }
        }
    }
    let scale = match layout.format {
        PixelFormat::Mono8 => 1.0,
        PixelFormat::Rgb8 => 1.0 / 256.0,
    };
    let mut gray_row = [0.0f64; MAX_PX];
    let mut gray_of = usize::MAX;
    // Two more than `width` ever needs: the three-wide sums read up to two past a cell's last
    // pixel (with weight zero); they stay zero.
    let mut acc_buf = [0.0f64; SEPARABLE_MAX_PX + 2];
    // Crop rows in frame-row order, so a frame row two crop rows share is converted once.
    let ascending = rows[0].first <= rows[CROP_ROWS - 1].first;
    for k in 0..CROP_ROWS {
        let r = if ascending { k } else { CROP_ROWS - 1 - k };
        let rs = &rows[r];
        let acc = &mut acc_buf[..width];
        acc.fill(0.0);
        let mut area_y = 0.0;
        for row in rs.first..rs.last {
            let wy = rs.hi.min(row as f64 + 1.0) - rs.lo.max(row as f64);
            if wy <= 0.0 {
                continue;
            }
            area_y += wy;
            if gray_of != row {
                let at = row * layout.row_stride_bytes + p0 * bpp;
                gray_line(
                    &pixels[at..at + width * bpp],
                    layout.format,
                    &mut gray_row[..width],
                );
                gray_of = row;
            }
            for (a, &g) in acc.iter_mut().zip(&gray_row[..width]) {
                *a += wy * g;
            }
        }
        let acc = &acc_buf;
        for (g, ((i, _), (w, cells))) in members
            .iter()
            .zip(weights.iter().zip(cells.iter()))
            .enumerate()
        {
            // Sums first, then the divisions and roundings in a loop of their own (it
            // vectorises).
            let mut sums = [0.0f64; CROP_COLS];
            if fits_three[g] {
                for (sum, &(wx, first)) in sums.iter_mut().zip(three[g].iter()) {
                    let a = &acc[first..first + 3];
                    *sum = wx[0] * a[0] + wx[1] * a[1] + wx[2] * a[2];
                }
            } else {
                for (sum, &(at, first, n, _)) in sums.iter_mut().zip(cells.iter()) {
                    *sum = w[at..at + n]
                        .iter()
                        .zip(&acc[first..first + n])
                        .map(|(wx, a)| wx * a)
                        .sum();
                }
            }
            let out = &mut crops[*i][r * CROP_COLS..(r + 1) * CROP_COLS];
            for ((o, &sum), &(_, _, _, area_x)) in out.iter_mut().zip(&sums).zip(cells.iter()) {
                let area = area_x * area_y;
                let value = if area > 0.0 { sum * scale / area } else { 0.0 };
                *o = round_non_negative(value);
            }
        }
    }
}

/// One frame row's gray levels, times 256 for RGB8 (`77 R + 150 G + 29 B`, exact).
#[inline(always)]
fn gray_line(line: &[u8], format: PixelFormat, out: &mut [f64]) {
    match format {
        PixelFormat::Mono8 => {
            for (g, &v) in out.iter_mut().zip(line) {
                *g = f64::from(v);
            }
        }
        PixelFormat::Rgb8 => {
            // Integer luma, then the conversion, each in a loop of its own (blocks on the
            // stack).
            let mut luma = [0i32; 128];
            for (line, out) in line.chunks(3 * 128).zip(out.chunks_mut(128)) {
                let luma = &mut luma[..out.len()];
                for (l, px) in luma.iter_mut().zip(line.chunks_exact(3)) {
                    *l = 77 * i32::from(px[0]) + 150 * i32::from(px[1]) + 29 * i32::from(px[2]);
                }
                for (g, &l) in out.iter_mut().zip(luma.iter()) {
                    *g = f64::from(l);
                }
            }
        }
    }
}

/// The crop cells one by one, each summing the weighted gray of every pixel under it: the
/// fallback of [`cut_group`] for very fine frames.
fn cut_per_cell(
    pixels: &[u8],
    layout: &FrameLayout,
    rows: &[Span; CROP_ROWS],
    cols: &[Span; CROP_COLS],
    crop: &mut [u8; CROP_ROWS * CROP_COLS],
) {
    let bpp = layout.format.bytes_per_px();
    for (r, rs) in rows.iter().enumerate() {
        for (c, cs) in cols.iter().enumerate() {
            let mut sum = 0.0;
            let mut area = 0.0;
            for row in rs.first..rs.last {
                let wy = rs.hi.min(row as f64 + 1.0) - rs.lo.max(row as f64);
                if wy <= 0.0 {
                    continue;
                }
                let line = row * layout.row_stride_bytes;
                for col in cs.first..cs.last {
                    let wx = cs.hi.min(col as f64 + 1.0) - cs.lo.max(col as f64);
                    if wx <= 0.0 {
                        continue;
                    }
                    let at = line + col * bpp;
                    let gray = match layout.format {
                        PixelFormat::Mono8 => f64::from(pixels[at]),
                        PixelFormat::Rgb8 => luma([pixels[at], pixels[at + 1], pixels[at + 2]]),
                    };
                    sum += wx * wy * gray;
                    area += wx * wy;
                }
            }
            let gray = if area > 0.0 { sum / area } else { 0.0 };
            crop[r * CROP_COLS + c] = gray.round().clamp(0.0, 255.0) as u8;
        }
    }
}

/// A cell's extent along one frame axis in fractional pixels, and the pixels it touches.
#[derive(Clone, Copy)]
struct Span {
    lo: f64,
    hi: f64,
    first: usize,
    last: usize,
}

impl Span {
    const EMPTY: Span = Span {
        lo: 0.0,
        hi: 0.0,
        first: 0,
        last: 0,
    };
}

/// [`cut_view`] as first written, every cell's span computed per cell: the reference the tests
/// hold the fast version to (same crop, byte for byte). Checks nothing; the frame and the view
/// must be valid.
#[cfg(test)]
pub(crate) fn cut_view_reference(
    pixels: &[u8],
    layout: &FrameLayout,
    target_x_m: f64,
    side: Side,
    crop: &mut [u8; CROP_ROWS * CROP_COLS],
) {
    let cam = &layout.camera;
    let m = cam.metres_per_px;
    let width_px = f64::from(cam.width_px);
    let height_px = f64::from(cam.height_px);
    let bpp = layout.format.bytes_per_px();
    let gray_of = |row: usize, col: usize| -> f64 {
        let at = row * layout.row_stride_bytes + col * bpp;
        match layout.format {
            PixelFormat::Mono8 => f64::from(pixels[at]),
            PixelFormat::Rgb8 => luma([pixels[at], pixels[at + 1], pixels[at + 2]]),
        }
    };
    let cell_px = CELL_SIZE_M / m;
    for r in 0..CROP_ROWS {
        for c in 0..CROP_COLS {
            let (xa, ya) = crop_point_world(target_x_m, side, r as f64, c as f64);
            let (xb, yb) = crop_point_world(target_x_m, side, r as f64 + 1.0, c as f64 + 1.0);
            let u0 = ((xa.min(xb) - cam.left_x_m) / m).clamp(0.0, width_px);
            let u1 = (u0 + cell_px).min(width_px);
            let v0 = ((cam.top_y_m - ya.max(yb)) / m).clamp(0.0, height_px);
            let v1 = (v0 + cell_px).min(height_px);
            let mut sum = 0.0;
            let mut area = 0.0;
            let row_last = (v1.ceil() as usize).min(cam.height_px as usize);
            let col_last = (u1.ceil() as usize).min(cam.width_px as usize);
            for row in (v0.floor() as usize)..row_last {
                let wy = v1.min(row as f64 + 1.0) - v0.max(row as f64);
                if wy <= 0.0 {
                    continue;
                }
                for col in (u0.floor() as usize)..col_last {
                    let wx = u1.min(col as f64 + 1.0) - u0.max(col as f64);
                    if wx <= 0.0 {
                        continue;
                    }
                    sum += wx * wy * gray_of(row, col);
                    area += wx * wy;
                }
            }
            let gray = if area > 0.0 { sum / area } else { 0.0 };
            crop[r * CROP_COLS + c] = gray.round().clamp(0.0, 255.0) as u8;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::view::{CHAIR_GRAY, FLOOR_GRAY, TABLE_GRAY, WALL_GRAY};

    #[test]
    fn palette_converts_exactly_to_psi_gray_levels() {
        for (rgb, gray) in [
            (FLOOR_RGB, FLOOR_GRAY),
            (TABLE_RGB, TABLE_GRAY),
            (CHAIR_RGB, CHAIR_GRAY),
            (WALL_RGB, WALL_GRAY),
        ] {
            assert_eq!(luma(rgb), f64::from(gray), "{rgb:?}");
            assert_eq!(rgb_to_gray(rgb), gray);
        }
    }

    /// A view past the frame: where the frame ends at the wall, the crop is what the renderer
    /// draws (wall beyond it), no cell unknown; where the frame ends inside the room, the cells
    /// beyond are unknown and read as wall.
    #[test]
    fn a_view_past_the_frame_is_wall_outside_the_room_and_unknown_inside() {
        let mut scene = Scene::empty_paper_room();
        scene.room = crate::scene::Room {
            x_min_m: -5.0,
            x_max_m: 5.0,
            y_min_m: -0.6,
            y_max_m: 8.4,
        };
        scene.banquet_table.segment_count = 6;
        let cam = OverheadCamera::fitting_room(&scene);
        let mut frame = vec![0u8; cam.rgb8_len()];
        render_frame(&scene, &cam, &mut frame).unwrap();
        let layout = FrameLayout::rgb8(cam);
        let x = 4.4;
        assert!(
            check_view(&layout, x, Side::Near).is_err(),
            "past the frame"
        );
        let mut crop = [0u8; CROP_ROWS * CROP_COLS];
        let mut unknown = [false; CROP_ROWS * CROP_COLS];
        for side in [Side::Near, Side::Far] {
            let n = cut_view_past_frame(
                &frame,
                &layout,
                &scene.room,
                x,
                side,
                &mut crop,
                &mut unknown,
            )
            .unwrap();
            assert_eq!(n, 0, "{side}: the frame covers the room");
            let rendered = crate::view::render_crop(&scene, x, side);
            let worst = crop
                .iter()
                .zip(&rendered)
                .map(|(a, b)| a.abs_diff(*b))
                .max()
                .unwrap();
            let mean = crop
                .iter()
                .zip(&rendered)
                .map(|(a, b)| f64::from(a.abs_diff(*b)))
                .sum::<f64>()
                / crop.len() as f64;
            assert!(
                mean < 2.0 && worst <= 100,
                "{side}: mean {mean}, worst {worst}"
            );
        }
        // A camera that sees x < 3 m only: the cells of x > 3 m inside the room are unknown.
        let half = OverheadCamera {
            width_px: ((3.0 - cam.left_x_m) / cam.metres_per_px) as u32,
            ..cam
        };
        let mut small = vec![0u8; half.rgb8_len()];
        render_frame(&scene, &half, &mut small).unwrap();
        let n = cut_view_past_frame(
            &small,
            &FrameLayout::rgb8(half),
            &scene.room,
            x,
            Side::Near,
            &mut crop,
            &mut unknown,
        )
        .unwrap();
        // The view spans x 2.4 .. 6.4; the room ends at 5: about (5 - 3) / 4 of it is unknown.
        let share = n as f64 / crop.len() as f64;
        assert!((0.45..0.55).contains(&share), "{n} unknown cells");
        for (k, u) in unknown.iter().enumerate() {
            let (cx, cy) =
                crate::view::cell_center_world(x, Side::Near, k / CROP_COLS, k % CROP_COLS);
            if *u {
                assert_eq!(crop[k], WALL_GRAY);
                assert!(
                    cx > 2.9 && cx < 5.1 && (-0.7..8.5).contains(&cy),
                    "{cx} {cy}"
                );
            }
            if cx < 2.9 {
                assert!(!u, "cell at x {cx} is in the frame");
            }
        }
        assert!(
            cut_view_past_frame(
                &small,
                &FrameLayout::rgb8(half),
                &scene.room,
                f64::NAN,
                Side::Near,
                &mut crop,
                &mut unknown
            )
            .is_err()
        );
    }

    #[test]
    fn default_camera_fits_the_paper_room() {
        let scene = Scene::empty_paper_room();
        let cam = OverheadCamera::fitting_room(&scene);
        assert_eq!((cam.width_px, cam.height_px), (640, 480));
        assert_eq!(cam.metres_per_px, 0.03125);
        assert!(cam.left_x_m <= scene.room.x_min_m && cam.top_y_m >= scene.room.y_max_m);
        assert!(cam.left_x_m + 640.0 * cam.metres_per_px >= scene.room.x_max_m);
        assert!(cam.top_y_m - 480.0 * cam.metres_per_px <= scene.room.y_min_m);
    }

    /// Views cut together give the crops each gives alone, byte for byte: overlapping and apart,
    /// more than a group, both sides mixed, three cameras, RGB8 and Mono8. A bad view fails the
    /// call before any crop is written, and names itself.
    #[test]
    fn cut_views_equals_cut_view_one_by_one() {
        use rand::{RngExt, SeedableRng};
        let scene = Scene::empty_paper_room();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(21);
        for camera in [
            OverheadCamera::fitting_room(&scene),
            OverheadCamera::fitting_room_with(&scene, 500, 371),
            OverheadCamera::fitting_room_with(&scene, 1283, 977),
        ] {
            for format in [PixelFormat::Rgb8, PixelFormat::Mono8] {
                let layout = FrameLayout {
                    camera,
                    format,
                    row_stride_bytes: camera.width_px as usize * format.bytes_per_px() + 3,
                };
                let pixels: Vec<u8> = (0..layout.row_stride_bytes * camera.height_px as usize)
                    .map(|_| rng.random())
                    .collect();
                for count in [1, 2, 3, 6, 11] {
                    let views: Vec<(f64, Side)> = (0..count)
                        .map(|i| {
                            let side = if rng.random::<bool>() {
                                Side::Near
                            } else {
                                Side::Far
                            };
                            // Some close together (one group), some far apart.
                            let x = if i % 3 == 2 {
                                rng.random_range(-4.7..4.7)
                            } else {
                                rng.random_range(-1.0..1.0)
                            };
                            (x, side)
                        })
                        .collect();
                    let mut together = vec![[0u8; CROP_ROWS * CROP_COLS]; count];
                    cut_views(&pixels, &layout, &views, &mut together).unwrap();
                    for (k, &(x, side)) in views.iter().enumerate() {
                        let mut alone = [0u8; CROP_ROWS * CROP_COLS];
                        cut_view(&pixels, &layout, x, side, &mut alone).unwrap();
                        assert_eq!(
                            together[k], alone,
                            "{camera:?} {format:?} view {k} of {views:?}"
                        );
                    }
                }
                let mut crops = vec![[7u8; CROP_ROWS * CROP_COLS]; 3];
                let bad = [(0.0, Side::Near), (40.0, Side::Far), (0.5, Side::Far)];
                match cut_views(&pixels, &layout, &bad, &mut crops) {
                    Err(CameraError::ViewOutsideFrame {
                        target_x_m, side, ..
                    }) => {
                        assert_eq!((target_x_m, side), (40.0, Side::Far));
                    }
                    other => panic!("{other:?}"),
                }
                assert!(
                    crops.iter().all(|c| c.iter().all(|&v| v == 7)),
                    "nothing written"
                );
                assert_eq!(
                    cut_views(&pixels, &layout, &bad, &mut crops[..2]),
                    Err(CameraError::TooFewCrops { views: 3, crops: 2 })
                );
            }
        }
    }

    /// The libm-free rounding is `f64::round` (half away from zero) clamped to a byte, at the
    /// halves, just below them and at random values.
    #[test]
    fn rounding_matches_f64_round() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let halves = (0..300).flat_map(|k| {
            let h = k as f64 + 0.5;
            [h, h.next_down(), h.next_up(), k as f64]
        });
        let random = (0..10_000).map(|_| rng.random_range(0.0..400.0));
        for x in halves.chain(random).chain([0.0, 0.49999999999999994, 1e12]) {
            assert_eq!(
                round_non_negative(x),
                x.round().clamp(0.0, 255.0) as u8,
                "{x}"
            );
        }
    }

    /// The separable `cut_view` and its per-cell fallback give the same crop, byte for byte, as
    /// the per-cell reference: noise frames (every weight shows), both sides, many targets, three
    /// cameras (integer and non-integer pixels per cell), RGB8 and padded Mono8.
    #[test]
    fn cut_view_equals_the_per_cell_reference() {
        use rand::{RngExt, SeedableRng};
        let scene = Scene::empty_paper_room();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(12);
        let cameras = [
            OverheadCamera::fitting_room(&scene),
            OverheadCamera::fitting_room_with(&scene, 500, 371),
            OverheadCamera::fitting_room_with(&scene, 1283, 977),
        ];
        let mut checked = 0;
        for camera in cameras {
            for format in [PixelFormat::Rgb8, PixelFormat::Mono8] {
                let row_stride_bytes = camera.width_px as usize * format.bytes_per_px()
                    + if format == PixelFormat::Mono8 { 5 } else { 0 };
                let layout = FrameLayout {
                    camera,
                    format,
                    row_stride_bytes,
                };
                let pixels: Vec<u8> = (0..row_stride_bytes * camera.height_px as usize)
                    .map(|_| rng.random())
                    .collect();
                for k in 0..40 {
                    let x = if k == 0 {
                        0.0
                    } else {
                        rng.random_range(-4.7..4.7)
                    };
                    for side in [Side::Near, Side::Far] {
                        let mut fast = [0u8; CROP_ROWS * CROP_COLS];
                        let mut reference = [0u8; CROP_ROWS * CROP_COLS];
                        cut_view(&pixels, &layout, x, side, &mut fast).unwrap();
                        cut_view_reference(&pixels, &layout, x, side, &mut reference);
                        assert_eq!(fast, reference, "{camera:?} {format:?} x {x} {side}");
                        // The fallback for frames too fine for the separable cut, forced.
                        let (rows, cols) = view_spans(&layout, x, side);
                        let mut per_cell = [[0u8; CROP_ROWS * CROP_COLS]];
                        cut_per_cell(&pixels, &layout, &rows, &cols, &mut per_cell[0]);
                        assert_eq!(
                            per_cell[0], reference,
                            "per cell: {camera:?} {format:?} x {x}"
                        );
                        // A group too wide for the buffers goes to the per-cell path.
                        per_cell[0] = [0; CROP_ROWS * CROP_COLS];
                        cut_group::<64>(&pixels, &layout, &rows, &[(0, cols)], &mut per_cell);
                        assert_eq!(
                            per_cell[0], reference,
                            "fallback: {camera:?} {format:?} x {x}"
                        );
                        checked += 1;
                    }
                }
            }
        }
        assert_eq!(checked, 3 * 2 * 40 * 2);
    }
}
