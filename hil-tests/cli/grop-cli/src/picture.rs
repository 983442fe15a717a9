//! The pictures of the room that explain themselves: routes, standing spots, outcome labels, a
//! metre scale and a legend beside the map, in one style for `grop demo` (closed loop and
//! `--in-process`), `grop render` and `grop hil --pictures`. Text is drawn with the small
//! bitmap font in [`font`].

pub mod font;

use hil_world::objects::{ObjectState, Verdict};
use hil_world::report::WorldReport;
use world::nav::OccupancyGrid;
use world::view::{self, Rgb, RgbImage, RoomView};
use world::{RobotConfig, Scene};

/// Text and outlines.
pub const INK: Rgb<u8> = Rgb([25, 25, 25]);
/// A target whose object was placed with no contact on the way.
pub const PLACED: Rgb<u8> = Rgb([0, 150, 0]);
/// A target whose object was placed, with a contact on the way (the paper's end state counts it).
pub const PLACED_CONTACT: Rgb<u8> = Rgb([235, 140, 0]);
/// A target whose object was not placed.
pub const FAILED: Rgb<u8> = Rgb([210, 0, 0]);
/// The route the base drove.
pub const DRIVEN: Rgb<u8> = Rgb([40, 40, 200]);
/// The route the first plan asked for.
pub const PLANNED: Rgb<u8> = Rgb([140, 0, 170]);
/// Routes of later plans (replans).
pub const REPLANNED: Rgb<u8> = Rgb([200, 130, 225]);
/// Where a plan wants the base to stand.
pub const SPOT: Rgb<u8> = Rgb([20, 20, 20]);
/// Where the base came to rest at a goal.
pub const STOPPED: Rgb<u8> = Rgb([120, 120, 120]);
/// Where an object was let go.
pub const RELEASED: Rgb<u8> = Rgb([250, 200, 0]);
/// A contact with furniture.
pub const CONTACT: Rgb<u8> = Rgb([255, 0, 255]);

/// Where the collision monitor held the base (a hold the executive reported, or a leg it failed).
pub const HELD: Rgb<u8> = Rgb([0, 170, 190]);
const PANEL_BG: Rgb<u8> = Rgb([255, 255, 255]);

/// The text scale for a map of this width (the font is 5 x 9 pixels at scale 1).
pub fn text_scale(map: &RgbImage) -> u32 {
    if map.width() >= 500 { 2 } else { 1 }
}

/// A legend item's symbol.
#[derive(Debug, Clone, Copy)]
pub enum Swatch {
    /// A solid line.
    Line(Rgb<u8>),
    /// A dashed line.
    Dashed(Rgb<u8>),
    /// A filled disc.
    Disc(Rgb<u8>),
    /// A ring.
    Ring(Rgb<u8>),
    /// An X.
    Cross(Rgb<u8>),
    /// A filled square (furniture).
    Fill(Rgb<u8>),
    /// The heatmap colours from 0 (red) to 1 (green).
    Heat,
}

/// The legend beside a map: title lines, then one line per symbol.
#[derive(Debug, Clone, Default)]
pub struct Legend {
    /// Title lines (bold facts: what, which scene, how it ended).
    pub title: Vec<String>,
    /// Symbols and what they mean.
    pub entries: Vec<(Swatch, String)>,
}

impl Legend {
    /// Adds an entry.
    pub fn entry(&mut self, swatch: Swatch, text: impl Into<String>) -> &mut Self {
        self.entries.push((swatch, text.into()));
        self
    }

    /// The furniture and the targets as [`view::render_room`] draws them.
    pub fn furniture(&mut self) -> &mut Self {
        self.entry(Swatch::Fill(view::ROOM_TABLE), "table")
            .entry(Swatch::Fill(view::ROOM_CHAIR), "chair")
            .entry(
                Swatch::Cross(view::ROOM_TARGET),
                "target (where an object goes)",
            )
    }

    /// [`Legend::furniture`] and the robot's start (a whole-room picture).
    pub fn room(&mut self) -> &mut Self {
        self.furniture()
            .entry(Swatch::Disc(view::ROOM_START), "robot start")
    }
}

/// The map with the legend as a panel to its right.
pub fn with_legend(map: &RgbImage, legend: &Legend) -> RgbImage {
    let s = text_scale(map);
    let line_h = (font::GLYPH_H * s + 6 * s) as i64;
    let swatch_w = 26 * s;
    let margin = 10 * s;
    let title_w = legend
        .title
        .iter()
        .map(|t| font::text_size(t, s).0)
        .max()
        .unwrap_or(0);
    let entry_w = legend
        .entries
        .iter()
        .map(|(_, t)| swatch_w + 6 * s + font::text_size(t, s).0)
        .max()
        .unwrap_or(0);
    let panel_w = title_w.max(entry_w) + 2 * margin;
    let lines = legend.title.len() as i64 + legend.entries.len() as i64 + 1;
    let panel_h = (lines * line_h) as u32 + 2 * margin;
    let mut out = RgbImage::from_pixel(map.width() + panel_w, map.height().max(panel_h), PANEL_BG);
    for (x, y, p) in map.enumerate_pixels() {
        out.put_pixel(x, y, *p);
    }
    for y in 0..out.height() {
        out.put_pixel(map.width(), y, INK);
    }
    let x0 = i64::from(map.width() + margin);
    let mut y = i64::from(margin);
    for t in &legend.title {
        font::draw_text(&mut out, x0, y, t, s, INK);
        y += line_h;
    }
    y += line_h / 2;
    for (swatch, t) in &legend.entries {
        let mid = y + i64::from(font::GLYPH_H * s) / 2 - i64::from(s);
        draw_swatch(&mut out, x0, mid, i64::from(swatch_w), s, *swatch);
        font::draw_text(&mut out, x0 + i64::from(swatch_w + 6 * s), y, t, s, INK);
        y += line_h;
    }
    out
}

fn draw_swatch(img: &mut RgbImage, x0: i64, mid: i64, w: i64, s: u32, swatch: Swatch) {
    let s = i64::from(s);
    let cx = x0 + w / 2;
    match swatch {
        Swatch::Line(c) => fill_px(img, x0, mid - s, x0 + w, mid + s + 1, c),
        Swatch::Dashed(c) => {
            let mut x = x0;
            while x < x0 + w {
                fill_px(img, x, mid - s, (x + 5 * s).min(x0 + w), mid + s + 1, c);
                x += 8 * s;
            }
        }
        Swatch::Disc(c) => disc_px(img, cx as f64, mid as f64, 4.5 * s as f64, c),
        Swatch::Ring(c) => ring_px(img, cx as f64, mid as f64, 6.0 * s as f64, s as f64, c),
        Swatch::Cross(c) => cross_px(img, cx as f64, mid as f64, 5.0 * s as f64, s as f64, c),
        Swatch::Fill(c) => fill_px(img, cx - 6 * s, mid - 5 * s, cx + 6 * s, mid + 5 * s, c),
        Swatch::Heat => {
            for x in x0..x0 + w {
                let v = (x - x0) as f32 / (w - 1).max(1) as f32;
                fill_px(
                    img,
                    x,
                    mid - 5 * s,
                    x + 1,
                    mid + 5 * s,
                    view::heat_colour(v),
                );
            }
        }
    }
}

fn fill_px(img: &mut RgbImage, x0: i64, y0: i64, x1: i64, y1: i64, c: Rgb<u8>) {
    let (w, h) = (i64::from(img.width()), i64::from(img.height()));
    for y in y0.max(0)..y1.min(h) {
        for x in x0.max(0)..x1.min(w) {
            img.put_pixel(x as u32, y as u32, c);
        }
    }
}

fn blend_px(img: &mut RgbImage, x0: i64, y0: i64, x1: i64, y1: i64, c: Rgb<u8>, alpha: f64) {
    let (w, h) = (i64::from(img.width()), i64::from(img.height()));
    for y in y0.max(0)..y1.min(h) {
        for x in x0.max(0)..x1.min(w) {
            let p = img.get_pixel_mut(x as u32, y as u32);
            for (ch, t) in p.0.iter_mut().zip(c.0) {
                *ch = (f64::from(*ch) * (1.0 - alpha) + f64::from(t) * alpha).round() as u8;
            }
        }
    }
}

fn disc_px(img: &mut RgbImage, cx: f64, cy: f64, r: f64, c: Rgb<u8>) {
    each_px_near(img, cx, cy, r, |dx, dy| dx * dx + dy * dy <= r * r, c);
}

fn ring_px(img: &mut RgbImage, cx: f64, cy: f64, r: f64, thick: f64, c: Rgb<u8>) {
    each_px_near(
        img,
        cx,
        cy,
        r + thick,
        |dx, dy| ((dx * dx + dy * dy).sqrt() - r).abs() <= thick * 0.5 + 0.25,
        c,
    );
}

fn cross_px(img: &mut RgbImage, cx: f64, cy: f64, r: f64, thick: f64, c: Rgb<u8>) {
    each_px_near(
        img,
        cx,
        cy,
        r,
        |dx, dy| (dx - dy).abs() <= thick * 0.75 || (dx + dy).abs() <= thick * 0.75,
        c,
    );
}

fn each_px_near(
    img: &mut RgbImage,
    cx: f64,
    cy: f64,
    r: f64,
    inside: impl Fn(f64, f64) -> bool,
    c: Rgb<u8>,
) {
    let (w, h) = (img.width() as i64, img.height() as i64);
    let (x0, x1) = ((cx - r).floor() as i64, (cx + r).ceil() as i64);
    let (y0, y1) = ((cy - r).floor() as i64, (cy + r).ceil() as i64);
    for y in y0.max(0)..=y1.min(h - 1) {
        for x in x0.max(0)..=x1.min(w - 1) {
            if inside(x as f64 + 0.5 - cx, y as f64 + 0.5 - cy) {
                img.put_pixel(x as u32, y as u32, c);
            }
        }
    }
}

/// A route through world points, `width_px` wide; dashed when `dashed`.
pub fn route(
    img: &mut RgbImage,
    room: &RoomView,
    points: &[(f64, f64)],
    colour: Rgb<u8>,
    width_px: f64,
    dashed: bool,
) {
    let (dash, gap) = (10.0 * width_px / 2.0, 7.0 * width_px / 2.0);
    let mut along = 0.0;
    for seg in points.windows(2) {
        let (ax, ay) = room.to_pixel(seg[0].0, seg[0].1);
        let (bx, by) = room.to_pixel(seg[1].0, seg[1].1);
        let length = (bx - ax).hypot(by - ay);
        let n = (length / 0.5).ceil().max(1.0) as usize;
        for k in 0..=n {
            let t = k as f64 / n as f64;
            let d = along + t * length;
            if dashed && d % (dash + gap) > dash {
                continue;
            }
            disc_px(
                img,
                ax + t * (bx - ax),
                ay + t * (by - ay),
                width_px / 2.0,
                colour,
            );
        }
        along += length;
    }
}

/// A ring around a world point (`radius_m`), `thick_px` wide.
pub fn ring(
    img: &mut RgbImage,
    room: &RoomView,
    xy: (f64, f64),
    radius_m: f64,
    thick_px: f64,
    c: Rgb<u8>,
) {
    let (cx, cy) = room.to_pixel(xy.0, xy.1);
    ring_px(
        img,
        cx,
        cy,
        (radius_m * room.pixels_per_m).max(3.0),
        thick_px,
        c,
    );
}

/// An X at a world point.
pub fn cross(img: &mut RgbImage, room: &RoomView, xy: (f64, f64), half_m: f64, c: Rgb<u8>) {
    let (cx, cy) = room.to_pixel(xy.0, xy.1);
    let r = (half_m * room.pixels_per_m).max(3.0);
    cross_px(img, cx, cy, r, (r / 3.0).max(1.5), c);
}

/// A metre scale in the map's lower left corner: a bar of 0.5, 1, 2 or 5 m with a tick at
/// every metre (or half metre), labelled.
pub fn scale_bar(img: &mut RgbImage, room: &RoomView) {
    let s = text_scale(img);
    let ppm = room.pixels_per_m;
    let length_m = [0.5, 1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .find(|l| l * ppm >= 70.0)
        .unwrap_or(10.0);
    let step_m = if length_m <= 1.0 { length_m / 2.0 } else { 1.0 };
    let bar = (length_m * ppm).round() as i64;
    let label = if length_m < 1.0 {
        format!("{:.0} cm", length_m * 100.0)
    } else {
        format!("{length_m:.0} m")
    };
    let (tw, th) = font::text_size(&label, s);
    let pad = i64::from(5 * s);
    let box_w = bar + i64::from(tw) + 3 * pad;
    let box_h = i64::from(th) + 2 * pad;
    let x0 = i64::from(8 * s);
    let y0 = i64::from(img.height()) - box_h - i64::from(8 * s);
    blend_px(img, x0, y0, x0 + box_w, y0 + box_h, PANEL_BG, 0.85);
    let bar_y = y0 + box_h / 2;
    let (t, h) = (i64::from(s), i64::from(4 * s));
    fill_px(
        img,
        x0 + pad,
        bar_y - t / 2,
        x0 + pad + bar + t,
        bar_y + t - t / 2,
        INK,
    );
    let ticks = (length_m / step_m).round() as i64;
    for k in 0..=ticks {
        let x = x0 + pad + (k as f64 * step_m * ppm).round() as i64;
        let tall = if k == 0 || k == ticks { h } else { h / 2 };
        fill_px(img, x, bar_y - tall, x + t, bar_y + 1, INK);
    }
    font::draw_text(img, x0 + 2 * pad + bar, y0 + pad, &label, s, INK);
}

/// Places text labels next to points of a map without covering each other, each on a pale box
/// with a short leader to its point.
#[derive(Debug, Default)]
pub struct Labels {
    placed: Vec<Rect>,
    pending: Vec<Pending>,
}

/// A pixel rectangle: left, top, right, bottom (exclusive).
type Rect = (i64, i64, i64, i64);

/// A label to draw: its point, its box, its text and colour.
#[derive(Debug)]
struct Pending {
    point: (i64, i64),
    rect: Rect,
    text: String,
    colour: Rgb<u8>,
}

impl Labels {
    /// Keeps labels off a marker at the world point `xy` (`radius_m` around it).
    pub fn keep_clear(&mut self, room: &RoomView, xy: (f64, f64), radius_m: f64) {
        let (px, py) = room.to_pixel(xy.0, xy.1);
        let r = (radius_m * room.pixels_per_m).max(3.0);
        self.placed.push((
            (px - r).floor() as i64,
            (py - r).floor() as i64,
            (px + r).ceil() as i64,
            (py + r).ceil() as i64,
        ));
    }

    /// Reserves a place for `text` near the world point `xy` (above it when `up`, else below;
    /// further out or to the side when that is taken). Drawn by [`Labels::draw`].
    pub fn add(
        &mut self,
        img: &RgbImage,
        room: &RoomView,
        xy: (f64, f64),
        text: &str,
        colour: Rgb<u8>,
        up: bool,
    ) {
        let s = i64::from(text_scale(img));
        let (tw, th) = font::text_size(text, s as u32);
        let (w, h) = (i64::from(tw) + 4 * s, i64::from(th) + 2 * s);
        let (px, py) = room.to_pixel(xy.0, xy.1);
        let (px, py) = (px.round() as i64, py.round() as i64);
        let gap = 8 * s;
        let above = |k: i64| (px - w / 2, py - gap - h - k * (h + 2 * s));
        let below = |k: i64| (px - w / 2, py + gap + k * (h + 2 * s));
        let mut tries = Vec::new();
        for k in 0..4 {
            if up {
                tries.extend([above(k), below(k)]);
            } else {
                tries.extend([below(k), above(k)]);
            }
        }
        tries.push((px + gap, py - h / 2));
        tries.push((px - gap - w, py - h / 2));
        let (iw, ih) = (i64::from(img.width()), i64::from(img.height()));
        let fits = |(x, y): (i64, i64)| {
            x >= 0
                && y >= 0
                && x + w <= iw
                && y + h <= ih
                && self
                    .placed
                    .iter()
                    .all(|&(ax, ay, bx, by)| x + w <= ax || bx <= x || y + h <= ay || by <= y)
        };
        let (x, y) = tries.iter().copied().find(|&p| fits(p)).unwrap_or_else(|| {
            let (x, y) = tries[0];
            (x.clamp(0, (iw - w).max(0)), y.clamp(0, (ih - h).max(0)))
        });
        let rect = (x, y, x + w, y + h);
        self.placed.push(rect);
        self.pending.push(Pending {
            point: (px, py),
            rect,
            text: text.to_owned(),
            colour,
        });
    }

    /// Draws every label (after everything else, so that they stay readable).
    pub fn draw(self, img: &mut RgbImage) {
        let s = i64::from(text_scale(img));
        for Pending {
            point: (px, py),
            rect: (x0, y0, x1, y1),
            text,
            colour,
        } in &self.pending
        {
            // Leader from the point to the nearest point of the box.
            let (qx, qy) = ((*px).clamp(*x0, x1 - 1), (*py).clamp(*y0, y1 - 1));
            let n = (qx - px).abs().max((qy - py).abs()).max(1);
            for k in 0..=n {
                let x = px + (qx - px) * k / n;
                let y = py + (qy - py) * k / n;
                fill_px(img, x, y, x + s.max(1), y + s.max(1), *colour);
            }
            blend_px(img, *x0, *y0, *x1, *y1, PANEL_BG, 0.85);
            outline_px(img, *x0, *y0, *x1, *y1, *colour);
            font::draw_text(img, x0 + 2 * s, y0 + s + s / 2, text, s as u32, *colour);
        }
    }
}

fn outline_px(img: &mut RgbImage, x0: i64, y0: i64, x1: i64, y1: i64, c: Rgb<u8>) {
    fill_px(img, x0, y0, x1, y0 + 1, c);
    fill_px(img, x0, y1 - 1, x1, y1, c);
    fill_px(img, x0, y0, x0 + 1, y1, c);
    fill_px(img, x1 - 1, y0, x1, y1, c);
}

/// An object's outcome: its colour, the short word on the map and the whole story for the
/// legend.
pub fn outcome(state: &ObjectState) -> (Rgb<u8>, &'static str, String) {
    match *state {
        ObjectState::Released {
            verdict, error_m, ..
        } if verdict.placed_strictly() => (
            PLACED,
            "placed",
            format!("placed, {:.1} cm from its target", error_m * 100.0),
        ),
        ObjectState::Released {
            verdict, error_m, ..
        } if verdict.placed_end_state() => (
            PLACED_CONTACT,
            "contact",
            format!(
                "placed, {:.1} cm off, after a contact on the way",
                error_m * 100.0
            ),
        ),
        ObjectState::Released {
            verdict, error_m, ..
        } => (
            FAILED,
            "failed",
            match verdict {
                Verdict::Misplaced => {
                    format!("failed: released {:.0} cm off its target", error_m * 100.0)
                }
                Verdict::Dropped => "failed: dropped".into(),
                v => format!("failed: {v:?}"),
            },
        ),
        ObjectState::OnTray { .. } => (FAILED, "failed", "failed: left on the tray".into()),
        ObjectState::AtStation => (FAILED, "failed", "failed: never loaded".into()),
        ObjectState::Held => (FAILED, "failed", "failed: still in the gripper".into()),
    }
}

/// The legend's heading for a closed-loop mission: the job and scene, the method and seed,
/// how the mission ended and what it placed.
pub fn mission_title(
    job: &str,
    scene: &str,
    method: &str,
    seed: u64,
    report: &WorldReport,
) -> Vec<String> {
    vec![
        format!("grop {job}: {scene}"),
        format!("method {method}, seed {seed}"),
        format!(
            "mission {:?}: placed {} of {}",
            report.end,
            report.placed_end_state,
            report.objects.len()
        ),
        format!("({} without any contact)", report.placed),
    ]
}

/// A closed-loop mission as the world saw it: the first plan's route (dashed) and the later
/// plans' from where the base was, the route driven, the standing spots with their F, where
/// the base stopped, every target labelled with its outcome, where objects were released,
/// contacts, a metre scale and the legend. `title` heads the legend.
#[allow(clippy::too_many_lines, reason = "one picture drawn layer by layer")]
pub fn mission(
    scene: &Scene,
    robot: &RobotConfig,
    report: &WorldReport,
    pixels_per_m: f64,
    title: Vec<String>,
) -> RgbImage {
    let room = RoomView::whole_room(scene, pixels_per_m);
    let mut img = view::render_room(scene, &room);
    let s = f64::from(text_scale(&img));
    let grid = OccupancyGrid::from_scene(scene, robot);
    let routed = |points: &[(f64, f64)]| -> Vec<(f64, f64)> {
        let mut out = vec![points[0]];
        for leg in points.windows(2) {
            match grid.plan(leg[0], leg[1]) {
                Some(path) => out.extend(path.points.iter().skip(1)),
                None => out.push(leg[1]),
            }
        }
        out
    };
    let base_at = |t: f64| {
        report
            .trajectory
            .iter()
            .take_while(|p| p[0] <= t)
            .last()
            .map_or((scene.robot_start.x_m, scene.robot_start.y_m), |p| {
                (p[1], p[2])
            })
    };
    // Later plans first, so that the first plan's route stays on top of them.
    for p in report.plans.iter().skip(1) {
        let mut points = vec![base_at(p.t_s)];
        points.extend(p.unloads.iter().map(|u| (u.2, u.3)));
        if points.len() > 1 {
            route(&mut img, &room, &routed(&points), REPLANNED, 2.0 * s, true);
        }
    }
    if let Some(p) = report.plans.first() {
        let mut points = vec![
            (scene.robot_start.x_m, scene.robot_start.y_m),
            (scene.loading_station.x_m, scene.loading_station.y_m),
        ];
        points.extend(p.unloads.iter().map(|u| (u.2, u.3)));
        route(&mut img, &room, &routed(&points), PLANNED, 2.0 * s, true);
    }
    let driven: Vec<(f64, f64)> = report.trajectory.iter().map(|p| (p[1], p[2])).collect();
    route(&mut img, &room, &driven, DRIVEN, 1.5 * s, false);
    for leg in &report.legs {
        view::draw_marker(
            &mut img,
            &room,
            leg.realised[0],
            leg.realised[1],
            0.05,
            STOPPED,
        );
    }
    let mut labels = Labels::default();
    // Standing spots: every plan's ringed, each place labelled once (spots of several plans
    // within 30 cm are one; the latest plan's F).
    let mut spots: Vec<((f64, f64), f64)> = Vec::new();
    for p in report.plans.iter().rev() {
        for u in &p.unloads {
            let xy = (u.2, u.3);
            ring(&mut img, &room, xy, 0.16, s, SPOT);
            if !spots
                .iter()
                .any(|(q, _)| (q.0 - xy.0).hypot(q.1 - xy.1) < 0.3)
            {
                spots.push((xy, u.4));
            }
        }
    }
    for c in &report.collisions {
        cross(&mut img, &room, (c.base[0], c.base[1]), 0.12, CONTACT);
    }
    // The collision monitor's interventions: where the base was when the executive reported a
    // hold, or gave up a leg or a standing spot because of what the scan saw.
    let held: Vec<(f64, f64)> = report
        .events
        .iter()
        .filter(|e| is_intervention(&e.detail))
        .map(|e| base_at(e.t_s))
        .collect();
    for xy in &held {
        ring(&mut img, &room, *xy, 0.1, 1.5 * s, HELD);
    }
    let table_y = 0.5 * (scene.banquet_table.y_min_m() + scene.banquet_table.y_max_m());
    for (xy, _) in &spots {
        labels.keep_clear(&room, *xy, 0.2);
    }
    for o in &report.objects {
        labels.keep_clear(&room, (o.target[0], o.target[1]), 0.12);
        if let ObjectState::Released { at, .. } = o.state {
            labels.keep_clear(&room, (at[0], at[1]), 0.06);
        }
    }
    let mut stories = Vec::new();
    for o in &report.objects {
        let (colour, word, story) = outcome(&o.state);
        view::draw_marker(&mut img, &room, o.target[0], o.target[1], 0.1, colour);
        if let ObjectState::Released { at, .. } = o.state {
            view::draw_marker(&mut img, &room, at[0], at[1], 0.045, RELEASED);
        }
        // A target's label over the table, a spot's away from it: they miss each other.
        let over_table = o.target[1] < table_y;
        let xy = (o.target[0], o.target[1]);
        labels.add(
            &img,
            &room,
            xy,
            &format!("obj{} {word}", o.index),
            colour,
            over_table,
        );
        stories.push((Swatch::Disc(colour), format!("obj{}: {story}", o.index)));
    }
    for (xy, f) in &spots {
        labels.add(
            &img,
            &room,
            *xy,
            &format!("F {f:.2}"),
            SPOT,
            xy.1 >= table_y,
        );
    }
    labels.draw(&mut img);
    scale_bar(&mut img, &room);
    let mut legend = Legend {
        title,
        entries: Vec::new(),
    };
    legend.entry(Swatch::Dashed(PLANNED), "planned route (first plan)");
    if report.plans.len() > 1 {
        legend.entry(Swatch::Dashed(REPLANNED), "replanned routes");
    }
    legend
        .entry(Swatch::Line(DRIVEN), "driven route (the world's truth)")
        .entry(Swatch::Ring(SPOT), "standing spot, F = its feasibility")
        .entry(Swatch::Disc(STOPPED), "where the base stopped at a goal")
        .entry(Swatch::Disc(PLACED), "target: placed")
        .entry(
            Swatch::Disc(PLACED_CONTACT),
            "target: placed, contact on the way",
        )
        .entry(Swatch::Disc(FAILED), "target: failed")
        .entry(Swatch::Disc(RELEASED), "where the object was released");
    if !report.collisions.is_empty() {
        legend.entry(
            Swatch::Cross(CONTACT),
            "contact with furniture (base there)",
        );
    }
    if !held.is_empty() {
        legend.entry(
            Swatch::Ring(HELD),
            format!("range sensor: base held / spot taken ({})", held.len()),
        );
    }
    legend.room();
    legend.entries.extend(stories);
    with_legend(&img, &legend)
}

/// Whether an executive event reports an intervention of the range sensor: the collision
/// monitor holding the base, a leg failed because of what the scan sees, a standing spot taken
/// or moved.
fn is_intervention(detail: &str) -> bool {
    detail.starts_with("collision monitor: base held")
        || detail.contains("obstacle the scan sees")
        || detail.contains("the standing spot is taken")
        || detail.starts_with("standing spot moved")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn count(img: &RgbImage, c: Rgb<u8>) -> usize {
        img.pixels().filter(|p| **p == c).count()
    }

    /// A mission report as the world writes it: obj0 placed, obj1 placed after a contact,
    /// obj2 left on the tray; one plan, a short drive, one contact.
    fn report(scene: &Scene) -> WorldReport {
        let t = |i: usize| [scene.targets[i].x_m, scene.targets[i].y_m, 0.0];
        let released = |i: usize, verdict: &str| {
            serde_json::json!({"index": i, "target": t(i), "state": {"state": "released",
                "at": t(i), "error_m": 0.01, "verdict": verdict}})
        };
        let (sx, sy) = (scene.robot_start.x_m, scene.robot_start.y_m);
        serde_json::from_value(serde_json::json!({
            "scene": scene.name, "seed": 1, "end": "finished", "placed": 1,
            "placed_end_state": 2,
            "objects": [released(0, "placed"), released(1, "placed_with_contact"),
                        {"index": 2, "target": t(2), "state": {"state": "on_tray", "slot": 0}}],
            "collisions": [{"t_s": 3.0, "part": "base", "base": [sx, sy + 1.0, 0.0]}],
            "legs": [],
            "trajectory": [[0.0, sx, sy, 0.0], [2.0, sx, sy + 1.0, 0.0], [4.0, sx + 1.0, sy + 1.0, 0.0]],
            "events": [],
            "plans": [{"t_s": 0.5, "plan_id": 1, "answers_request": 1, "decision_us": 2000,
                       "utility": 30.0, "feasibility": 2.0, "cost_s": 50.0,
                       "unloads": [[0, 1, t(0)[0], t(0)[1] - 0.7, 0.8],
                                   [1, 1, t(1)[0], t(1)[1] - 0.7, 0.6]]}],
            "deaths": [],
            "timing": {"sim_time_s": 50.0, "wall_time_s": 5.0, "steps": 1, "frames": 1,
                       "world_step_us": 1.0, "request_to_plan_s": null, "plan_to_motion_s": null}
        }))
        .unwrap()
    }

    #[test]
    fn a_mission_picture_shows_routes_outcomes_spots_scale_and_legend() {
        let scene = world::generate::evaluation_scene(1, 20, 3);
        let robot = RobotConfig::default();
        let img = mission(&scene, &robot, &report(&scene), 48.0, vec!["title".into()]);
        let room = RoomView::whole_room(&scene, 48.0);
        // The legend is a panel beside the map.
        assert!(img.width() > room.width_px + 200, "{}", img.width());
        assert!(img.height() >= room.height_px);
        // Each outcome's colour, both routes, the spots and the contact are drawn.
        for (what, c) in [
            ("placed", PLACED),
            ("placed with contact", PLACED_CONTACT),
            ("failed", FAILED),
            ("planned route", PLANNED),
            ("driven route", DRIVEN),
            ("standing spots", SPOT),
            ("contact", CONTACT),
        ] {
            assert!(count(&img, c) > 20, "no {what}");
        }
        // No replan, so no replanned route; no hold of the collision monitor.
        assert_eq!(count(&img, REPLANNED), 0);
        assert_eq!(count(&img, HELD), 0);
    }

    #[test]
    fn the_collision_monitor_s_holds_are_drawn_where_the_base_was() {
        let scene = world::generate::evaluation_scene(1, 20, 3);
        let robot = RobotConfig::default();
        let mut r = report(&scene);
        r.events = serde_json::from_value(serde_json::json!([
            {"t_s": 2.5, "kind": "Obstacle", "plan_id": 1, "step": 0,
             "detail": "collision monitor: base held (an obstacle ahead)"},
            {"t_s": 3.5, "kind": "LegFinished", "plan_id": 1, "step": 0,
             "detail": "leg to (1.00, 2.00) failed: blocked by an obstacle the scan sees"},
            {"t_s": 3.6, "kind": "Obstacle", "plan_id": 1, "step": 0,
             "detail": "collision monitor: clear again after 1.1 s"}
        ]))
        .unwrap();
        let img = mission(&scene, &robot, &r, 48.0, vec!["title".into()]);
        // Two rings where the base stood at 2.5 s and 3.5 s (the same place), and the legend's
        // swatch: a "clear again" is not an intervention.
        assert!(count(&img, HELD) > 20, "no hold drawn");
        assert!(is_intervention(
            "the standing spot is taken (the scan sees something on the way in)"
        ));
        assert!(!is_intervention(
            "collision monitor: clear again after 1.1 s"
        ));
    }

    #[test]
    fn labels_never_cover_each_other_or_a_kept_clear_marker() {
        let scene = world::generate::evaluation_scene(1, 20, 3);
        let room = RoomView::whole_room(&scene, 48.0);
        let img = RgbImage::new(room.width_px, room.height_px);
        let mut labels = Labels::default();
        labels.keep_clear(&room, (0.0, 0.0), 0.2);
        for k in 0..8 {
            labels.add(
                &img,
                &room,
                (0.0, 0.0),
                &format!("label {k}"),
                INK,
                k % 2 == 0,
            );
        }
        let r = &labels.placed;
        for i in 0..r.len() {
            for j in i + 1..r.len() {
                let (a, b) = (r[i], r[j]);
                let apart = a.2 <= b.0 || b.2 <= a.0 || a.3 <= b.1 || b.3 <= a.1;
                assert!(apart, "{a:?} and {b:?} overlap");
            }
        }
    }

    #[test]
    fn the_scale_bar_is_as_long_as_its_label_says() {
        let scene = world::generate::evaluation_scene(1, 20, 3);
        let room = RoomView::whole_room(&scene, 48.0);
        let mut img = RgbImage::from_pixel(room.width_px, room.height_px, Rgb([200, 0, 0]));
        scale_bar(&mut img, &room);
        // At 48 px/m the bar is 2 m: 96 px of ink (plus its end tick) in one run.
        let mut longest = 0;
        for y in 0..img.height() {
            let mut run = 0;
            for x in 0..img.width() {
                run = if *img.get_pixel(x, y) == INK {
                    run + 1
                } else {
                    0
                };
                longest = longest.max(run);
            }
        }
        assert!((96..=99).contains(&longest), "{longest}");
    }
}
