//! The pixel primitives of `grop layout-picture`: points, rectangles, discs, thick lines,
//! filled polygons and the colour ramp of the scan and the grid.

use world::view::{Rgb, RgbImage};

use super::Rect;

/// Blue (0) through cyan, green and yellow to red (1).
pub(super) fn turbo(s: f64) -> Rgb<u8> {
    const STOPS: [(f64, [f64; 3]); 5] = [
        (0.0, [48.0, 18.0, 160.0]),
        (0.25, [30.0, 160.0, 230.0]),
        (0.5, [60.0, 220.0, 100.0]),
        (0.75, [245.0, 200.0, 40.0]),
        (1.0, [200.0, 30.0, 20.0]),
    ];
    let i = STOPS.iter().rposition(|(t, _)| *t <= s).unwrap_or(0).min(3);
    let ((t0, a), (t1, b)) = (STOPS[i], STOPS[i + 1]);
    let f = ((s - t0) / (t1 - t0)).clamp(0.0, 1.0);
    let mix = |k: usize| (a[k] + (b[k] - a[k]) * f).round() as u8;
    Rgb([mix(0), mix(1), mix(2)])
}

pub(super) fn put(img: &mut RgbImage, x: i64, y: i64, c: Rgb<u8>) {
    if x >= 0 && y >= 0 && x < i64::from(img.width()) && y < i64::from(img.height()) {
        img.put_pixel(x as u32, y as u32, c);
    }
}

pub(super) fn fill_rect(img: &mut RgbImage, r: Rect, c: Rgb<u8>) {
    for y in r.y..r.y + r.h {
        for x in r.x..r.x + r.w {
            put(img, x, y, c);
        }
    }
}

pub(super) fn disc(img: &mut RgbImage, cx: i64, cy: i64, radius: f64, c: Rgb<u8>) {
    let r = radius.ceil() as i64;
    for dy in -r..=r {
        for dx in -r..=r {
            if ((dx * dx + dy * dy) as f64) <= radius * radius {
                put(img, cx + dx, cy + dy, c);
            }
        }
    }
}

/// A line `width` pixels wide.
pub(super) fn line(img: &mut RgbImage, a: (i64, i64), b: (i64, i64), c: Rgb<u8>, width: i64) {
    let n = (b.0 - a.0).abs().max((b.1 - a.1).abs()).max(1);
    if n > 20_000 {
        return;
    }
    let h = width / 2;
    for i in 0..=n {
        let x = a.0 + (b.0 - a.0) * i / n;
        let y = a.1 + (b.1 - a.1) * i / n;
        for dy in -h..=(width - 1 - h) {
            for dx in -h..=(width - 1 - h) {
                put(img, x + dx, y + dy, c);
            }
        }
    }
}

/// A convex or concave polygon, filled by the even-odd rule at pixel centres.
pub(super) fn fill_polygon(img: &mut RgbImage, pts: &[(i64, i64)], c: Rgb<u8>) {
    if pts.len() < 3 {
        return;
    }
    let y0 = pts.iter().map(|p| p.1).min().unwrap_or(0).max(0);
    let y1 = pts
        .iter()
        .map(|p| p.1)
        .max()
        .unwrap_or(0)
        .min(i64::from(img.height()) - 1);
    for y in y0..=y1 {
        let yc = y as f64 + 0.5;
        let mut xs: Vec<f64> = Vec::new();
        for i in 0..pts.len() {
            let (a, b) = (pts[i], pts[(i + 1) % pts.len()]);
            let (ay, by) = (a.1 as f64, b.1 as f64);
            if (ay <= yc && by > yc) || (by <= yc && ay > yc) {
                xs.push(a.0 as f64 + (yc - ay) / (by - ay) * (b.0 - a.0) as f64);
            }
        }
        xs.sort_by(f64::total_cmp);
        for pair in xs.chunks(2) {
            if let [xa, xb] = pair {
                for x in (xa.round() as i64)..(xb.round() as i64) {
                    put(img, x, y, c);
                }
            }
        }
    }
}
