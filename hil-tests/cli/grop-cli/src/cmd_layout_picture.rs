//! `grop layout-picture [LOG]`: draws what the committed Foxglove layout
//! (docs/foxglove-layout.json) shows of a mission log, panel by panel, into one PNG, without the
//! Foxglove app: the layout's split tree gives each panel its place, and each panel is drawn
//! from the log's messages on the topics its configuration names, as they were at one instant
//! (`--at`, default the end of the log). A 3D panel is drawn from above (the grid, the scene's
//! entities through the frames of `/tf`, the paths, the visible frames' axes), an Image panel
//! shows the newest camera frame, a Plot panel its paths over the whole log, and a Log panel the
//! newest log messages. docs/logs.md shows the picture of the default mission.

use std::collections::BTreeMap;
use std::path::PathBuf;

use anyhow::{Context, bail};
use base64::Engine as _;
use base64::engine::general_purpose::STANDARD as BASE64;
use grop_onboard::mission_log::{Channel, LoggedMessage, MissionLog};
use serde_json::Value;
use world::view::{Rgb, RgbImage};

use crate::picture::font::{draw_text, text_size};

mod raster;
use raster::{disc, fill_polygon, fill_rect, line, put, turbo};

/// Options of `grop layout-picture`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The mission log (MCAP) written by `grop demo` or `grop-recorder`.
    #[arg(value_name = "LOG", default_value = "out/demo.mcap")]
    pub path: PathBuf,
    /// The Foxglove layout whose panels to draw.
    #[arg(long, default_value = "docs/foxglove-layout.json")]
    pub layout: PathBuf,
    /// The instant to show, in seconds of the log's time (default: its last message).
    #[arg(long)]
    pub at: Option<f64>,
    /// The picture to write (PNG).
    #[arg(long, default_value = "out/foxglove-layout.png")]
    pub out: PathBuf,
    /// Width of the picture in pixels.
    #[arg(long, default_value_t = 1800)]
    pub width: u32,
    /// Height of the picture in pixels.
    #[arg(long, default_value_t = 1100)]
    pub height: u32,
}

const BG: Rgb<u8> = Rgb([32, 36, 42]);
const PANEL: Rgb<u8> = Rgb([24, 26, 31]);
const TITLE: Rgb<u8> = Rgb([48, 52, 60]);
const TEXT: Rgb<u8> = Rgb([225, 228, 232]);
const DIM: Rgb<u8> = Rgb([140, 146, 156]);
const SERIES: [Rgb<u8>; 4] = [
    Rgb([74, 125, 255]),
    Rgb([240, 170, 30]),
    Rgb([90, 200, 120]),
    Rgb([220, 80, 200]),
];

/// A rectangle of the picture.
#[derive(Debug, Clone, Copy)]
struct Rect {
    x: i64,
    y: i64,
    w: i64,
    h: i64,
}

/// Draws the layout's panels for the log at one instant and writes the PNG.
pub fn run(args: Args) -> anyhow::Result<()> {
    let log = MissionLog::read(&args.path)?;
    let layout_path = crate::common::committed_file(&args.layout);
    let text = std::fs::read_to_string(&layout_path)
        .with_context(|| format!("reading the layout {}", layout_path.display()))?;
    let layout: Value = serde_json::from_str(&text)
        .with_context(|| format!("the layout {} is not JSON", layout_path.display()))?;
    let end = log.messages.iter().map(|m| m.log_time).max().unwrap_or(0);
    let at_ns = match args.at {
        Some(s) if s.is_finite() && s >= 0.0 => (s * 1e9) as u64,
        Some(s) => bail!("--at {s}: not a time in seconds"),
        None => end,
    };
    anyhow::ensure!(
        (200..=8000).contains(&args.width) && (200..=8000).contains(&args.height),
        "--width and --height must be within 200..=8000 pixels"
    );
    let mut img = RgbImage::from_pixel(args.width, args.height, BG);
    let painter = Painter {
        log: &log,
        configs: &layout["configById"],
        at_ns,
        end_ns: end,
    };
    let whole = Rect {
        x: 0,
        y: 0,
        w: i64::from(args.width),
        h: i64::from(args.height),
    };
    painter.node(&mut img, &layout["layout"], whole)?;
    if let Some(dir) = args.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    img.save(&args.out)
        .with_context(|| format!("writing {}", args.out.display()))?;
    println!(
        "wrote {} ({} x {}): the panels of {} for {} at {:.1} s",
        args.out.display(),
        args.width,
        args.height,
        layout_path.display(),
        args.path.display(),
        at_ns as f64 * 1e-9
    );
    Ok(())
}

struct Painter<'a> {
    log: &'a MissionLog,
    configs: &'a Value,
    at_ns: u64,
    end_ns: u64,
}

impl Painter<'_> {
    /// The newest message of `topic` at the instant.
    fn latest(&self, topic: &str) -> Option<&LoggedMessage> {
        let c = Channel::from_topic(topic)?;
        self.log
            .messages
            .iter()
            .rfind(|m| m.channel == c && m.log_time <= self.at_ns)
    }

    fn node(&self, img: &mut RgbImage, node: &Value, r: Rect) -> anyhow::Result<()> {
        if let Some(id) = node.as_str() {
            return self.panel(img, id, r);
        }
        let share = node["splitPercentage"].as_f64().unwrap_or(50.0) / 100.0;
        let (a, b) = if node["direction"] == "column" {
            let h = (r.h as f64 * share) as i64;
            (
                Rect { h, ..r },
                Rect {
                    y: r.y + h,
                    h: r.h - h,
                    ..r
                },
            )
        } else {
            let w = (r.w as f64 * share) as i64;
            (
                Rect { w, ..r },
                Rect {
                    x: r.x + w,
                    w: r.w - w,
                    ..r
                },
            )
        };
        self.node(img, &node["first"], a)?;
        self.node(img, &node["second"], b)
    }

    fn panel(&self, img: &mut RgbImage, id: &str, r: Rect) -> anyhow::Result<()> {
        let inner = Rect {
            x: r.x + 3,
            y: r.y + 3,
            w: r.w - 6,
            h: r.h - 6,
        };
        fill_rect(img, inner, PANEL);
        let bar = Rect { h: 26, ..inner };
        fill_rect(img, bar, TITLE);
        let config = &self.configs[id];
        let kind = id.split('!').next().unwrap_or(id);
        let body = Rect {
            y: inner.y + 26,
            h: inner.h - 26,
            ..inner
        };
        let title = match kind {
            "3D" => format!(
                "3D  (map, from above, t = {:.1} s)",
                self.at_ns as f64 * 1e-9
            ),
            "Image" => format!(
                "Image  {}",
                config["imageMode"]["imageTopic"].as_str().unwrap_or("")
            ),
            "Plot" => format!("Plot  {}", config["title"].as_str().unwrap_or("")),
            "RosOut" => format!("Log  {}", config["topicToRender"].as_str().unwrap_or("")),
            other => format!("{other} (not drawn)"),
        };
        draw_text(img, bar.x + 8, bar.y + 4, &title, 2, TEXT);
        match kind {
            "3D" => self.three_d(img, config, body),
            "Image" => self.image(img, config, body),
            "Plot" => self.plot(img, config, body),
            "RosOut" => self.logs(img, config, body),
            _ => Ok(()),
        }
    }

    /// The newest message of the panel's image topic: any `foxglove.RawImage` (`rgb8` or
    /// `mono8`; the camera, Psi's views), scaled to fit.
    fn image(&self, img: &mut RgbImage, config: &Value, r: Rect) -> anyhow::Result<()> {
        let topic = config["imageMode"]["imageTopic"].as_str().unwrap_or("");
        let Some(m) = self.latest(topic) else {
            draw_text(img, r.x + 8, r.y + 8, "no image yet", 2, DIM);
            return Ok(());
        };
        let at = || format!("the image on {topic} at {} ns", m.log_time);
        let v: Value = serde_json::from_slice(&m.data).with_context(at)?;
        let pixels = BASE64
            .decode(v["data"].as_str().unwrap_or(""))
            .with_context(at)?;
        let dim = |k: &str| {
            v[k].as_u64()
                .and_then(|x| i64::try_from(x).ok())
                .unwrap_or(0)
        };
        let (w, ht, step) = (dim("width"), dim("height"), dim("step"));
        let channels = match v["encoding"].as_str() {
            Some("rgb8") => 3,
            Some("mono8") => 1,
            other => bail!("{}: encoding {other:?} (rgb8 or mono8 expected)", at()),
        };
        if w == 0 || ht == 0 || step < w * channels || (pixels.len() as i64) < step * ht {
            bail!(
                "{}: {} bytes for {w} x {ht} at a step of {step}",
                at(),
                pixels.len()
            );
        }
        let scale = (r.w as f64 / w as f64).min(r.h as f64 / ht as f64);
        let (dw, dh) = ((w as f64 * scale) as i64, (ht as f64 * scale) as i64);
        let (ox, oy) = (r.x + (r.w - dw) / 2, r.y + (r.h - dh) / 2);
        for py in 0..dh {
            for px in 0..dw {
                let sx = ((px as f64 / scale) as i64).min(w - 1);
                let sy = ((py as f64 / scale) as i64).min(ht - 1);
                let i = (sy * step + sx * channels) as usize;
                let c = if channels == 3 {
                    Rgb([pixels[i], pixels[i + 1], pixels[i + 2]])
                } else {
                    Rgb([pixels[i]; 3])
                };
                put(img, ox + px, oy + py, c);
            }
        }
        let stamp = format!("at {:.1} s", m.log_time as f64 * 1e-9);
        draw_text(img, r.x + 8, r.y + r.h - 24, &stamp, 2, TEXT);
        Ok(())
    }

    fn plot(&self, img: &mut RgbImage, config: &Value, r: Rect) -> anyhow::Result<()> {
        let mut series: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
        for p in config["paths"].as_array().into_iter().flatten() {
            let path = p["value"].as_str().unwrap_or("");
            let label = p["label"].as_str().unwrap_or(path).to_owned();
            let (topic, field) = path
                .split_once('.')
                .with_context(|| format!("plot path {path:?}: no `.field`"))?;
            let channel = Channel::from_topic(topic)
                .with_context(|| format!("plot path {path:?}: no channel {topic}"))?;
            let (name, index) = match field.split_once('[') {
                Some((n, i)) => (n, i.trim_end_matches(']').parse::<usize>().ok()),
                None => (field, None),
            };
            let mut points = Vec::new();
            for m in self.log.channel(channel) {
                let v: Value = serde_json::from_slice(&m.data)?;
                let x = match index {
                    Some(i) => &v[name][i],
                    None => &v[name],
                };
                if let Some(y) = x.as_f64() {
                    points.push((m.log_time as f64 * 1e-9, y));
                }
            }
            series.push((label, points));
        }
        let t1 = (self.end_ns as f64 * 1e-9).max(1.0);
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for (_, pts) in &series {
            for (_, y) in pts {
                lo = lo.min(*y);
                hi = hi.max(*y);
            }
        }
        if !(lo.is_finite() && hi.is_finite()) {
            draw_text(img, r.x + 8, r.y + 8, "no data", 2, DIM);
            return Ok(());
        }
        if hi - lo < 1e-6 {
            hi = lo + 1.0;
        }
        let pad = 0.08 * (hi - lo);
        let (lo, hi) = (lo - pad, hi + pad);
        let area = Rect {
            x: r.x + 70,
            y: r.y + 10,
            w: r.w - 85,
            h: r.h - 45,
        };
        let to_px = |t: f64, y: f64| -> (i64, i64) {
            (
                area.x + (t / t1 * area.w as f64) as i64,
                area.y + area.h - ((y - lo) / (hi - lo) * area.h as f64) as i64,
            )
        };
        // Axes: zero, and five ticks either way.
        for i in 0..=4 {
            let y = lo + (hi - lo) * f64::from(i) / 4.0;
            let (_, py) = to_px(0.0, y);
            line(
                img,
                (area.x, py),
                (area.x + area.w, py),
                Rgb([50, 54, 62]),
                1,
            );
            draw_text(img, r.x + 4, py - 8, &format!("{y:.2}"), 2, DIM);
            let t = t1 * f64::from(i) / 4.0;
            let (px, _) = to_px(t, lo);
            draw_text(
                img,
                px - 20,
                area.y + area.h + 8,
                &format!("{t:.0} s"),
                2,
                DIM,
            );
        }
        for (k, (_, pts)) in series.iter().enumerate() {
            let c = SERIES[k % SERIES.len()];
            // At most one segment per pixel column (the extremes of each column kept).
            let mut last: Option<(i64, i64)> = None;
            for (t, y) in pts {
                let p = to_px(*t, *y);
                if let Some(q) = last {
                    line(img, q, p, c, 2);
                }
                last = Some(p);
            }
        }
        let (cx, _) = to_px(self.at_ns as f64 * 1e-9, lo);
        line(img, (cx, area.y), (cx, area.y + area.h), TEXT, 1);
        let mut ly = area.y + 6;
        for (k, (label, _)) in series.iter().enumerate() {
            let c = SERIES[k % SERIES.len()];
            let (tw, _) = text_size(label, 2);
            let lx = area.x + area.w - tw as i64 - 40;
            line(img, (lx, ly + 8), (lx + 24, ly + 8), c, 3);
            draw_text(img, lx + 30, ly, label, 2, TEXT);
            ly += 24;
        }
        Ok(())
    }

    fn logs(&self, img: &mut RgbImage, config: &Value, r: Rect) -> anyhow::Result<()> {
        let topic = config["topicToRender"].as_str().unwrap_or("");
        let channel =
            Channel::from_topic(topic).with_context(|| format!("log panel: no channel {topic}"))?;
        let lines: Vec<&LoggedMessage> = self
            .log
            .channel(channel)
            .filter(|m| m.log_time <= self.at_ns)
            .collect();
        let rows = ((r.h - 10) / 22).max(1) as usize;
        let max_chars = ((r.w - 16) / 12).max(10) as usize;
        for (i, m) in lines.iter().rev().take(rows).rev().enumerate() {
            let v: Value = serde_json::from_slice(&m.data)?;
            let (level, colour) = match v["level"].as_u64() {
                Some(4 | 5) => ("ERROR", Rgb([240, 90, 90])),
                Some(3) => ("WARN ", Rgb([240, 190, 70])),
                _ => ("INFO ", TEXT),
            };
            let text = format!(
                "{:7.2} s {level} {}: {}",
                m.log_time as f64 * 1e-9,
                v["name"].as_str().unwrap_or(""),
                v["message"].as_str().unwrap_or("")
            );
            let shown: String = text.chars().take(max_chars).collect();
            draw_text(img, r.x + 8, r.y + 6 + i as i64 * 22, &shown, 2, colour);
        }
        Ok(())
    }

    fn three_d(&self, img: &mut RgbImage, config: &Value, r: Rect) -> anyhow::Result<()> {
        let frames = Frames::at(self.latest("/tf"))?;
        let topics = &config["topics"];
        let visible = |t: &str| topics[t]["visible"].as_bool().unwrap_or(false);
        let scene: Option<Value> = match self.latest("/scene") {
            Some(m) if visible("/scene") => Some(serde_json::from_slice(&m.data)?),
            _ => None,
        };
        // The view: the scene's room (or what the entities span), from above, y up.
        let mut bounds = Bounds::default();
        for e in scene_entities(scene.as_ref()) {
            if e["frame_id"] == "map" {
                for l in e["lines"].as_array().into_iter().flatten() {
                    for p in l["points"].as_array().into_iter().flatten() {
                        bounds.add(num(&p["x"]), num(&p["y"]));
                    }
                }
                for c in e["cubes"].as_array().into_iter().flatten() {
                    bounds.add(
                        num(&c["pose"]["position"]["x"]),
                        num(&c["pose"]["position"]["y"]),
                    );
                }
            }
        }
        if !bounds.valid() {
            bounds = Bounds {
                x0: -7.0,
                x1: 7.0,
                y0: 0.0,
                y1: 10.0,
            };
        }
        let view = View::fit(&bounds, r);
        floor_layers(img, &view, config);
        if visible("/heatmaps/grid") {
            if let Some(m) = self.latest("/heatmaps/grid") {
                let g: Value = serde_json::from_slice(&m.data)?;
                let lo = topics["/heatmaps/grid"]["minValue"].as_f64().unwrap_or(0.0);
                let hi = topics["/heatmaps/grid"]["maxValue"].as_f64().unwrap_or(1.0);
                draw_grid(img, &view, &g, lo, hi)?;
            }
        }
        // Scene entities: furniture first, the robot (attached to its frames) last.
        for e in scene_entities(scene.as_ref()) {
            let frame = e["frame_id"].as_str().unwrap_or("map");
            let Some(to_map) = frames.to_map(frame) else {
                continue;
            };
            draw_entity(img, &view, &to_map, e);
        }
        self.paths(img, &view, topics)?;
        if visible("/scan") {
            if let Some(m) = self.latest("/scan") {
                let cloud: Value = serde_json::from_slice(&m.data)?;
                let colour = topics["/scan"]["flatColor"]
                    .as_str()
                    .and_then(hex)
                    .unwrap_or(TEXT);
                let size = topics["/scan"]["pointSize"].as_f64().unwrap_or(3.0);
                // Through the frames as they were when the scan was taken.
                let then = self
                    .log
                    .messages
                    .iter()
                    .rfind(|t| t.channel == Channel::Tf && t.log_time <= m.log_time);
                draw_cloud(img, &view, &Frames::at(then)?, &cloud, colour, size)?;
            }
        }
        // The visible frames' axes (x red, y green).
        let shown = &config["transforms"];
        for name in frames.parents.keys() {
            if shown[format!("frame:{name}")]["visible"].as_bool() != Some(true) {
                continue;
            }
            if let Some(t) = frames.to_map(name) {
                let o = t.apply([0.0, 0.0, 0.0]);
                let x = t.apply([0.5, 0.0, 0.0]);
                let y = t.apply([0.0, 0.5, 0.0]);
                line(
                    img,
                    view.px(o[0], o[1]),
                    view.px(x[0], x[1]),
                    Rgb([230, 60, 60]),
                    3,
                );
                line(
                    img,
                    view.px(o[0], o[1]),
                    view.px(y[0], y[1]),
                    Rgb([60, 210, 90]),
                    3,
                );
            }
        }
        // Labels last, over everything.
        labels(img, &view, &frames, scene.as_ref());
        // A metre scale.
        let (sx, sy) = (r.x + 16, r.y + r.h - 20);
        let len = view.scale.round() as i64;
        line(img, (sx, sy), (sx + len, sy), TEXT, 3);
        draw_text(img, sx + len + 8, sy - 8, "1 m", 2, TEXT);
        Ok(())
    }
    /// The paths the 3D panel shows, in their colours and widths.
    fn paths(&self, img: &mut RgbImage, view: &View, topics: &Value) -> anyhow::Result<()> {
        let visible = |t: &str| topics[t]["visible"].as_bool().unwrap_or(false);
        for topic in ["/plan/path", "/base/path"] {
            if !visible(topic) {
                continue;
            }
            let Some(m) = self.latest(topic) else {
                continue;
            };
            let v: Value = serde_json::from_slice(&m.data)?;
            let colour = topics[topic]["gradient"][0]
                .as_str()
                .and_then(hex)
                .unwrap_or(TEXT);
            let width = topics[topic]["lineWidth"].as_f64().unwrap_or(0.05);
            let px = (width * view.scale).round().max(2.0) as i64;
            let pts: Vec<(i64, i64)> = v["poses"]
                .as_array()
                .into_iter()
                .flatten()
                .map(|p| view.px(num(&p["position"]["x"]), num(&p["position"]["y"])))
                .collect();
            for w in pts.windows(2) {
                line(img, w[0], w[1], colour, px);
            }
        }
        Ok(())
    }
}

/// The 3D panel's floor grid layers: a line per division, in the map frame.
fn floor_layers(img: &mut RgbImage, view: &View, config: &Value) {
    for layer in config["layers"]
        .as_object()
        .into_iter()
        .flatten()
        .map(|(_, l)| l)
    {
        if layer["layerId"] == "foxglove.Grid" && layer["visible"].as_bool().unwrap_or(true) {
            let size = layer["size"].as_f64().unwrap_or(10.0);
            let n = layer["divisions"].as_u64().unwrap_or(10).max(1);
            let (cx, cy) = (num(&layer["position"][0]), num(&layer["position"][1]));
            let step = size / n as f64;
            for i in 0..=n {
                let d = -0.5 * size + step * i as f64;
                let c = Rgb([55, 60, 70]);
                line(
                    img,
                    view.px(cx + d, cy - 0.5 * size),
                    view.px(cx + d, cy + 0.5 * size),
                    c,
                    1,
                );
                line(
                    img,
                    view.px(cx - 0.5 * size, cy + d),
                    view.px(cx + 0.5 * size, cy + d),
                    c,
                    1,
                );
            }
        }
    }
}

/// The scene's texts, above their places.
fn labels(img: &mut RgbImage, view: &View, frames: &Frames, scene: Option<&Value>) {
    for e in scene_entities(scene) {
        let frame = e["frame_id"].as_str().unwrap_or("map");
        let Some(to_map) = frames.to_map(frame) else {
            continue;
        };
        for t in e["texts"].as_array().into_iter().flatten() {
            let p = to_map.apply(position(&t["pose"]));
            let (x, y) = view.px(p[0], p[1]);
            let text = t["text"].as_str().unwrap_or("");
            let (tw, _) = text_size(text, 2);
            draw_text(img, x - tw as i64 / 2, y - 26, text, 2, TEXT);
        }
    }
}

fn scene_entities(scene: Option<&Value>) -> impl Iterator<Item = &Value> {
    scene
        .and_then(|s| s["entities"].as_array())
        .into_iter()
        .flatten()
}

fn num(v: &Value) -> f64 {
    v.as_f64().unwrap_or(0.0)
}

fn position(pose: &Value) -> [f64; 3] {
    let p = &pose["position"];
    [num(&p["x"]), num(&p["y"]), num(&p["z"])]
}

fn quat(q: &Value) -> [f64; 4] {
    let w = q["w"].as_f64().unwrap_or(1.0);
    [num(&q["x"]), num(&q["y"]), num(&q["z"]), w]
}

/// `#rrggbb` or `#rrggbbaa`.
fn hex(s: &str) -> Option<Rgb<u8>> {
    let s = s.strip_prefix('#')?;
    let byte = |i: usize| u8::from_str_radix(s.get(i..i + 2)?, 16).ok();
    Some(Rgb([byte(0)?, byte(2)?, byte(4)?]))
}

/// A rigid transform: rotation (quaternion x, y, z, w) then translation.
#[derive(Debug, Clone, Copy)]
struct Transform {
    t: [f64; 3],
    q: [f64; 4],
}

impl Transform {
    const ID: Transform = Transform {
        t: [0.0; 3],
        q: [0.0, 0.0, 0.0, 1.0],
    };

    fn rotate(&self, v: [f64; 3]) -> [f64; 3] {
        let [x, y, z, w] = self.q;
        // v + 2 w (u x v) + 2 u x (u x v), u = (x, y, z).
        let u = [x, y, z];
        let cross = |a: [f64; 3], b: [f64; 3]| {
            [
                a[1] * b[2] - a[2] * b[1],
                a[2] * b[0] - a[0] * b[2],
                a[0] * b[1] - a[1] * b[0],
            ]
        };
        let uv = cross(u, v);
        let uuv = cross(u, uv);
        [
            v[0] + 2.0 * (w * uv[0] + uuv[0]),
            v[1] + 2.0 * (w * uv[1] + uuv[1]),
            v[2] + 2.0 * (w * uv[2] + uuv[2]),
        ]
    }

    fn apply(&self, v: [f64; 3]) -> [f64; 3] {
        let r = self.rotate(v);
        [r[0] + self.t[0], r[1] + self.t[1], r[2] + self.t[2]]
    }

    /// `self` then `local` (a transform given in `self`'s frame).
    fn then(&self, local: &Transform) -> Transform {
        let [ax, ay, az, aw] = self.q;
        let [bx, by, bz, bw] = local.q;
        Transform {
            t: self.apply(local.t),
            q: [
                aw * bx + ax * bw + ay * bz - az * by,
                aw * by - ax * bz + ay * bw + az * bx,
                aw * bz + ax * by - ay * bx + az * bw,
                aw * bw - ax * bx - ay * by - az * bz,
            ],
        }
    }

    /// The heading of the transform's x axis in the map, rad.
    fn yaw(&self) -> f64 {
        let x = self.rotate([1.0, 0.0, 0.0]);
        x[1].atan2(x[0])
    }
}

/// The frame tree of one `/tf` message.
struct Frames {
    parents: BTreeMap<String, (String, Transform)>,
}

impl Frames {
    fn at(m: Option<&LoggedMessage>) -> anyhow::Result<Frames> {
        let mut parents = BTreeMap::new();
        if let Some(m) = m {
            let v: Value = serde_json::from_slice(&m.data)?;
            for t in v["transforms"].as_array().into_iter().flatten() {
                let tr = &t["translation"];
                parents.insert(
                    t["child_frame_id"].as_str().unwrap_or("").to_owned(),
                    (
                        t["parent_frame_id"].as_str().unwrap_or("").to_owned(),
                        Transform {
                            t: [num(&tr["x"]), num(&tr["y"]), num(&tr["z"])],
                            q: quat(&t["rotation"]),
                        },
                    ),
                );
            }
        }
        Ok(Frames { parents })
    }

    /// The frame's pose in `map` (`None`: not connected to it).
    fn to_map(&self, frame: &str) -> Option<Transform> {
        let mut chain = Vec::new();
        let mut f = frame;
        while f != "map" {
            let (parent, t) = self.parents.get(f)?;
            chain.push(*t);
            f = parent;
            if chain.len() > 32 {
                return None;
            }
        }
        Some(chain.iter().rev().fold(Transform::ID, |acc, t| acc.then(t)))
    }
}

#[derive(Debug, Clone, Copy)]
struct Bounds {
    x0: f64,
    x1: f64,
    y0: f64,
    y1: f64,
}

impl Default for Bounds {
    fn default() -> Self {
        Bounds {
            x0: f64::INFINITY,
            x1: f64::NEG_INFINITY,
            y0: f64::INFINITY,
            y1: f64::NEG_INFINITY,
        }
    }
}

impl Bounds {
    fn add(&mut self, x: f64, y: f64) {
        self.x0 = self.x0.min(x);
        self.x1 = self.x1.max(x);
        self.y0 = self.y0.min(y);
        self.y1 = self.y1.max(y);
    }

    fn valid(&self) -> bool {
        self.x1 > self.x0 && self.y1 > self.y0
    }
}

/// Map metres to the panel's pixels (from above, y up).
struct View {
    scale: f64,
    ox: f64,
    oy: f64,
}

impl View {
    fn fit(b: &Bounds, r: Rect) -> View {
        let margin = 20.0;
        let scale = ((r.w as f64 - 2.0 * margin) / (b.x1 - b.x0))
            .min((r.h as f64 - 2.0 * margin) / (b.y1 - b.y0));
        let cx = r.x as f64 + 0.5 * r.w as f64 - 0.5 * (b.x0 + b.x1) * scale;
        let cy = r.y as f64 + 0.5 * r.h as f64 + 0.5 * (b.y0 + b.y1) * scale;
        View {
            scale,
            ox: cx,
            oy: cy,
        }
    }

    fn px(&self, x: f64, y: f64) -> (i64, i64) {
        (
            (self.ox + x * self.scale).round() as i64,
            (self.oy - y * self.scale).round() as i64,
        )
    }
}

fn colour(c: &Value) -> Rgb<u8> {
    let ch = |k: &str| (num(&c[k]).clamp(0.0, 1.0) * 255.0).round() as u8;
    Rgb([ch("r"), ch("g"), ch("b")])
}

fn draw_entity(img: &mut RgbImage, view: &View, to_map: &Transform, e: &Value) {
    let list = |k: &str| e[k].as_array().into_iter().flatten();
    for c in list("cubes") {
        let local = Transform {
            t: position(&c["pose"]),
            q: quat(&c["pose"]["orientation"]),
        };
        let t = to_map.then(&local);
        let (sx, sy) = (num(&c["size"]["x"]), num(&c["size"]["y"]));
        let (s, co) = t.yaw().sin_cos();
        let corners: Vec<(f64, f64)> = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
            .iter()
            .map(|(a, b)| {
                let (dx, dy) = (0.5 * a * sx, 0.5 * b * sy);
                (t.t[0] + co * dx - s * dy, t.t[1] + s * dx + co * dy)
            })
            .collect();
        let px: Vec<(i64, i64)> = corners.iter().map(|(x, y)| view.px(*x, *y)).collect();
        fill_polygon(img, &px, colour(&c["color"]));
        for i in 0..4 {
            line(img, px[i], px[(i + 1) % 4], Rgb([15, 15, 15]), 1);
        }
    }
    for c in list("cylinders").chain(list("spheres")) {
        let p = to_map.apply(position(&c["pose"]));
        let (x, y) = view.px(p[0], p[1]);
        let radius = (0.5 * num(&c["size"]["x"]) * view.scale).max(3.0);
        disc(img, x, y, radius, colour(&c["color"]));
    }
    for l in list("lines") {
        let base = to_map.then(&Transform {
            t: position(&l["pose"]),
            q: quat(&l["pose"]["orientation"]),
        });
        let pts: Vec<(i64, i64)> = l["points"]
            .as_array()
            .into_iter()
            .flatten()
            .map(|p| {
                let w = base.apply([num(&p["x"]), num(&p["y"]), num(&p["z"])]);
                view.px(w[0], w[1])
            })
            .collect();
        let c = colour(&l["color"]);
        for w in pts.windows(2) {
            line(img, w[0], w[1], c, 2);
        }
        if l["type"] == 1 && pts.len() > 2 {
            line(img, pts[pts.len() - 1], pts[0], c, 2);
        }
    }
    for a in list("arrows") {
        let t = to_map.then(&Transform {
            t: position(&a["pose"]),
            q: quat(&a["pose"]["orientation"]),
        });
        let len = num(&a["shaft_length"]) + num(&a["head_length"]);
        let tip = t.apply([len, 0.0, 0.0]);
        let c = colour(&a["color"]);
        let from = view.px(t.t[0], t.t[1]);
        let to = view.px(tip[0], tip[1]);
        line(img, from, to, c, 3);
        disc(img, to.0, to.1, 4.0, c);
    }
}

/// A Foxglove grid's first float32 field, coloured from `lo` to `hi` (turbo-like: blue, green,
/// yellow, red); NaN cells left out.
fn draw_grid(img: &mut RgbImage, view: &View, g: &Value, lo: f64, hi: f64) -> anyhow::Result<()> {
    let data = BASE64
        .decode(g["data"].as_str().unwrap_or(""))
        .context("the grid's data is not base64")?;
    let columns = g["column_count"].as_u64().unwrap_or(0) as usize;
    let row_stride = g["row_stride"].as_u64().unwrap_or(0) as usize;
    let cell_stride = g["cell_stride"].as_u64().unwrap_or(4) as usize;
    let offset = g["fields"][0]["offset"].as_u64().unwrap_or(0) as usize;
    if columns == 0 || row_stride == 0 {
        return Ok(());
    }
    let origin = Transform {
        t: position(&g["pose"]),
        q: quat(&g["pose"]["orientation"]),
    };
    let (cw, ch) = (num(&g["cell_size"]["x"]), num(&g["cell_size"]["y"]));
    for row in 0..data.len() / row_stride {
        for col in 0..columns {
            let i = row * row_stride + col * cell_stride + offset;
            let Some(bytes) = data.get(i..i + 4) else {
                continue;
            };
            let v = f64::from(f32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]));
            if v.is_nan() {
                continue;
            }
            let s = ((v - lo) / (hi - lo)).clamp(0.0, 1.0);
            let corners: Vec<(i64, i64)> = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]
                .iter()
                .map(|(a, b)| {
                    let p = origin.apply([(col as f64 + a) * cw, (row as f64 + b) * ch, 0.0]);
                    view.px(p[0], p[1])
                })
                .collect();
            fill_polygon(img, &corners, turbo(s));
        }
    }
    Ok(())
}

/// A Foxglove point cloud's x and y (float32 fields `x`, `y`) as dots, through its frame.
fn draw_cloud(
    img: &mut RgbImage,
    view: &View,
    frames: &Frames,
    cloud: &Value,
    colour: Rgb<u8>,
    size: f64,
) -> anyhow::Result<()> {
    let Some(to_map) = frames.to_map(cloud["frame_id"].as_str().unwrap_or("")) else {
        return Ok(());
    };
    let to_map = to_map.then(&Transform {
        t: position(&cloud["pose"]),
        q: quat(&cloud["pose"]["orientation"]),
    });
    let data = BASE64
        .decode(cloud["data"].as_str().unwrap_or(""))
        .context("the point cloud's data is not base64")?;
    let stride = cloud["point_stride"].as_u64().unwrap_or(0) as usize;
    let offset = |name: &str| {
        cloud["fields"]
            .as_array()
            .into_iter()
            .flatten()
            .find(|f| f["name"] == name)
            .and_then(|f| f["offset"].as_u64())
            .map(|o| o as usize)
    };
    let (Some(ox), Some(oy)) = (offset("x"), offset("y")) else {
        return Ok(());
    };
    if stride == 0 {
        return Ok(());
    }
    let f32_at = |i: usize| {
        data.get(i..i + 4)
            .map(|b| f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])))
    };
    for p in 0..data.len() / stride {
        if let (Some(x), Some(y)) = (f32_at(p * stride + ox), f32_at(p * stride + oy)) {
            let w = to_map.apply([x, y, 0.0]);
            let (px, py) = view.px(w[0], w[1]);
            disc(img, px, py, 0.5 * size, colour);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_compose_down_the_tree() {
        let yaw = |a: f64| [0.0, 0.0, (0.5 * a).sin(), (0.5 * a).cos()];
        let mut parents = BTreeMap::new();
        parents.insert(
            "odom".to_owned(),
            (
                "map".to_owned(),
                Transform {
                    t: [1.0, 0.0, 0.0],
                    q: yaw(std::f64::consts::FRAC_PI_2),
                },
            ),
        );
        parents.insert(
            "base_link".to_owned(),
            (
                "odom".to_owned(),
                Transform {
                    t: [2.0, 0.0, 0.0],
                    q: yaw(0.0),
                },
            ),
        );
        let f = Frames { parents };
        let t = f.to_map("base_link").expect("connected");
        // 2 m along odom's x, which points along the map's y.
        assert!(
            (t.t[0] - 1.0).abs() < 1e-9 && (t.t[1] - 2.0).abs() < 1e-9,
            "{t:?}"
        );
        assert!((t.yaw() - std::f64::consts::FRAC_PI_2).abs() < 1e-9);
        assert!(f.to_map("nowhere").is_none());
    }

    #[test]
    fn colours_parse_and_the_colour_map_runs_blue_to_red() {
        assert_eq!(hex("#c050e0ff"), Some(Rgb([0xc0, 0x50, 0xe0])));
        assert_eq!(hex("c050e0"), None);
        assert_eq!(turbo(0.0), Rgb([48, 18, 160]));
        assert_eq!(turbo(1.0), Rgb([200, 30, 20]));
    }
}
