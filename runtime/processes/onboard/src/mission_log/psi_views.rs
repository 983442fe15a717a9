//! `/psi/views`: what Psi saw for a decision. For every location of a heatmaps message (an
//! object and a side of the table), the 64 x 32 crop cut from the camera frame the decision
//! used, beside the heatmap Psi predicted from it; one location a row, in the message's order.
//! The crops are cut here again from the logged frame with the planner's own cut
//! (`world::camera`), so the picture is the network's input, not a rendering of the map.
//!
//! Image layout (`foxglove.RawImage`, `rgb8`): each row block is [`CROP_ROWS`] pixels high, the
//! crop's grey levels on the left ([`CROP_COLS`] wide, table at the top row, the target at the
//! middle column, cells the camera did not see in dark red), a [`GAP_PX`] gap, then the
//! heatmap in `world::view::heat_colour`; blocks are [`GAP_PX`] apart.

use std::collections::VecDeque;

use base64::Engine as _;
use base64::engine::general_purpose::STANDARD as BASE64;
use grop_ipc::{CameraFrameMsg, HeatmapsMsg};
use world::Side;
use world::camera::{FrameLayout, check_view, cut_view_past_frame, cut_views};
use world::scene::Room;
use world::view::{CROP_CELLS, CROP_COLS, CROP_ROWS, Rgb, heat_colour};

use super::foxglove::{RawImage, Time};

/// Pixels between the crop and its heatmap, and between two locations.
pub const GAP_PX: usize = 2;
/// Frames kept for the heatmaps that name them (the recorder logs a named frame before the
/// heatmaps, in the same drain).
const FRAMES_KEPT: usize = 4;
/// The gap's colour.
const GAP: Rgb<u8> = Rgb([30, 30, 60]);
/// A cell the camera did not see.
const UNSEEN: Rgb<u8> = Rgb([90, 0, 0]);

/// One location of a decision.
struct Location {
    target_x_m: f64,
    side: Side,
    values: Box<[f32; CROP_CELLS]>,
}

/// Heatmaps waiting for their frame.
struct Pending {
    stamp_ns: u64,
    frame_id: u64,
    locations: Vec<Location>,
}

/// The frames and the decisions of a mission, turned into `/psi/views` images.
#[derive(Default)]
pub struct PsiViews {
    frames: VecDeque<(u64, FrameLayout, Vec<u8>)>,
    pending: Vec<Pending>,
    /// Decisions whose frame was not kept (no image for them).
    pub missed: u64,
}

impl PsiViews {
    /// A camera frame the recorder logs.
    pub fn frame(&mut self, m: &CameraFrameMsg) {
        let (Ok(layout), Ok(pixels)) = (m.header.layout(), m.image()) else {
            return;
        };
        if self.frames.len() == FRAMES_KEPT {
            self.frames.pop_front();
        }
        self.frames
            .push_back((m.header.frame_id, layout, pixels.to_vec()));
    }

    /// A heatmaps message: its image is made in [`PsiViews::take`], when its frame is in.
    pub fn heatmaps(&mut self, m: &HeatmapsMsg) {
        let Ok(locations) = m.locations() else {
            return;
        };
        if locations.is_empty() {
            return;
        }
        let locations = locations
            .iter()
            .map(|l| {
                let mut values = Box::new([0f32; CROP_CELLS]);
                values.copy_from_slice(&l.values[..CROP_CELLS]);
                Location {
                    target_x_m: l.target_m[0],
                    side: if l.side >= 0 { Side::Near } else { Side::Far },
                    values,
                }
            })
            .collect();
        self.pending.push(Pending {
            stamp_ns: m.stamp_ns,
            frame_id: m.source_frame_id,
            locations,
        });
    }

    /// The images of the decisions whose frame is in, with their stamps; a decision whose
    /// frame never came is counted in [`PsiViews::missed`].
    pub fn take(&mut self, room: &Room) -> Vec<(u64, RawImage)> {
        let mut out = Vec::new();
        for p in std::mem::take(&mut self.pending) {
            let frame = self.frames.iter().find(|(id, _, _)| *id == p.frame_id);
            match frame.and_then(|(_, layout, pixels)| mosaic(pixels, layout, room, &p)) {
                Some(image) => out.push((p.stamp_ns, image)),
                None => self.missed += 1,
            }
        }
        out
    }
}

/// The crop of one location as Psi saw it, and which cells the camera did not see.
fn cut(
    pixels: &[u8],
    layout: &FrameLayout,
    room: &Room,
    l: &Location,
) -> Option<([u8; CROP_CELLS], [bool; CROP_CELLS])> {
    let mut crop = [[0u8; CROP_CELLS]];
    let mut unseen = [false; CROP_CELLS];
    if check_view(layout, l.target_x_m, l.side).is_ok() {
        cut_views(pixels, layout, &[(l.target_x_m, l.side)], &mut crop).ok()?;
    } else {
        cut_view_past_frame(
            pixels,
            layout,
            room,
            l.target_x_m,
            l.side,
            &mut crop[0],
            &mut unseen,
        )
        .ok()?;
    }
    Some((crop[0], unseen))
}

fn mosaic(pixels: &[u8], layout: &FrameLayout, room: &Room, p: &Pending) -> Option<RawImage> {
    let width = 2 * CROP_COLS + GAP_PX;
    let n = p.locations.len();
    let height = n * CROP_ROWS + (n - 1) * GAP_PX;
    let mut rgb = vec![0u8; width * height * 3];
    let mut put = |x: usize, y: usize, c: Rgb<u8>| {
        let i = 3 * (y * width + x);
        rgb[i..i + 3].copy_from_slice(&c.0);
    };
    for (k, l) in p.locations.iter().enumerate() {
        let (crop, unseen) = cut(pixels, layout, room, l)?;
        let top = k * (CROP_ROWS + GAP_PX);
        for r in 0..CROP_ROWS {
            for c in 0..CROP_COLS {
                let i = r * CROP_COLS + c;
                let g = crop[i];
                put(c, top + r, if unseen[i] { UNSEEN } else { Rgb([g, g, g]) });
                put(CROP_COLS + GAP_PX + c, top + r, heat_colour(l.values[i]));
            }
            for g in 0..GAP_PX {
                put(CROP_COLS + g, top + r, GAP);
            }
        }
        if k + 1 < n {
            for g in 0..GAP_PX {
                for x in 0..width {
                    put(x, top + CROP_ROWS + g, GAP);
                }
            }
        }
    }
    Some(RawImage {
        timestamp: Time::from_ns(p.stamp_ns),
        frame_id: String::new(),
        width: width as u32,
        height: height as u32,
        encoding: "rgb8".to_owned(),
        step: (3 * width) as u32,
        data: BASE64.encode(&rgb),
    })
}
