//! The range sensor on the base (the paper's robot carried a Velodyne VLP-16): its place in the
//! robot file ([`LidarSpec`]) and what its rays hit in a scene ([`RayScene`]).
//!
//! What a ray can hit is not what the base collides with: a table is a top slab on four legs
//! per segment (a ray under the top passes between the legs), a chair is the solid box the
//! world models, the walls are 3 m high, the floor is the plane z = 0. The robot's own body is
//! not in the ray scene (the sensor's rays start outside it, see `docs/lidar.md`). Overhangs
//! that the rings cannot see (a table top above the top ring near the table) stay unseen; the
//! onboard monitor takes them from the prior map.

use serde::{Deserialize, Serialize};

use crate::scene::{Scene, TABLE_CENTER_Y_M};

/// Where the range sensor sits and how the simulator degrades it (robot file, `[lidar]`).
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct LidarSpec {
    /// The sensor's frame in the base frame.
    pub mount: LidarMount,
    /// Rotation rate (rev/min; the VLP-16 takes 300-1200, default 600 = 10 Hz).
    pub rpm: f64,
    /// Returns nearer than this are not reported (m).
    pub min_range_m: f64,
    /// Returns farther than this are not reported (m).
    pub max_range_m: f64,
    /// Simulator: standard deviation of the range noise (m).
    pub range_noise_sigma_m: f64,
    /// Simulator: share of firings that return nothing.
    pub dropout_probability: f64,
}

/// The sensor's frame in the base frame (x forward, y left, z up from the floor).
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct LidarMount {
    /// Forward of the base centre (m).
    pub x_m: f64,
    /// Left of the base centre (m).
    pub y_m: f64,
    /// Height of the optical centre above the floor (m).
    pub z_m: f64,
    /// The sensor's azimuth zero relative to the base heading (rad).
    pub yaw_rad: f64,
}

impl Default for LidarSpec {
    /// A VLP-16 on a short post at the middle of the deck, 0.40 m above the floor, at 10 Hz:
    /// centred so that its 0.25 m minimum range lies inside the footprint (every point outside
    /// the body is in range), low enough that its rings (+-15 deg) see chair seats and table
    /// legs next to the base.
    fn default() -> Self {
        Self {
            mount: LidarMount {
                x_m: 0.0,
                y_m: 0.0,
                z_m: 0.40,
                yaw_rad: 0.0,
            },
            rpm: 600.0,
            min_range_m: 0.25,
            max_range_m: 100.0,
            range_noise_sigma_m: 0.01,
            dropout_probability: 0.01,
        }
    }
}

impl LidarSpec {
    /// Range checks; `(field, reason)` of the first bad field.
    pub fn check(&self) -> Result<(), (&'static str, String)> {
        let m = &self.mount;
        let finite = [
            ("lidar.mount.x_m", m.x_m),
            ("lidar.mount.y_m", m.y_m),
            ("lidar.mount.z_m", m.z_m),
            ("lidar.mount.yaw_rad", m.yaw_rad),
            ("lidar.rpm", self.rpm),
            ("lidar.min_range_m", self.min_range_m),
            ("lidar.max_range_m", self.max_range_m),
            ("lidar.range_noise_sigma_m", self.range_noise_sigma_m),
            ("lidar.dropout_probability", self.dropout_probability),
        ];
        if let Some((field, _)) = finite.iter().find(|(_, v)| !v.is_finite()) {
            return Err((field, "not a finite number".into()));
        }
        if !(300.0..=1200.0).contains(&self.rpm) {
            return Err((
                "lidar.rpm",
                format!("the VLP-16 turns at 300-1200 rpm, found {}", self.rpm),
            ));
        }
        if !(0.0..=3.0).contains(&m.z_m) {
            return Err(("lidar.mount.z_m", format!("must be 0-3 m, found {}", m.z_m)));
        }
        if m.x_m.abs() > 2.0 || m.y_m.abs() > 2.0 {
            return Err(("lidar.mount", "more than 2 m from the base centre".into()));
        }
        if self.min_range_m < 0.0
            || self.max_range_m <= self.min_range_m
            || self.max_range_m > 131.0
        {
            return Err((
                "lidar.max_range_m",
                format!(
                    "need 0 <= min_range_m < max_range_m <= 131 (the 2 mm x 65535 the packet holds), found {} and {}",
                    self.min_range_m, self.max_range_m
                ),
            ));
        }
        if !(0.0..=1.0).contains(&self.range_noise_sigma_m) {
            return Err(("lidar.range_noise_sigma_m", "must be 0-1 m".into()));
        }
        if !(0.0..1.0).contains(&self.dropout_probability) {
            return Err(("lidar.dropout_probability", "must be in [0, 1)".into()));
        }
        Ok(())
    }
}

/// A box a ray can hit: yawed about z, from `z0` to `z1`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct RayBox {
    cx: f64,
    cy: f64,
    /// cos and sin of the yaw.
    c: f64,
    s: f64,
    hx: f64,
    hy: f64,
    z0: f64,
    z1: f64,
    /// Radius of the bounding circle in the plane.
    r: f64,
    /// What it is.
    kind: HitKind,
}

/// What a ray hit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HitKind {
    /// The floor.
    Floor,
    /// A wall.
    Wall,
    /// A chair.
    Chair,
    /// A table's leg.
    TableLeg,
    /// A table's top.
    TableTop,
}

/// Side of a table leg (m).
pub const TABLE_LEG_SIZE_M: f64 = 0.06;
/// Thickness of a table top (m).
pub const TABLE_TOP_THICKNESS_M: f64 = 0.04;
const WALL_HEIGHT_M: f64 = 3.0;
const WALL_THICKNESS_M: f64 = 0.1;

/// The scene as rays see it. Build once per scene (again when furniture moves).
#[derive(Debug, Clone, Default)]
pub struct RayScene {
    boxes: Vec<RayBox>,
}

impl RayScene {
    /// The ray scene of `scene`.
    #[allow(
        clippy::too_many_lines,
        reason = "one block per kind of furniture and wall"
    )]
    pub fn from_scene(scene: &Scene) -> Self {
        let mut boxes = Vec::new();
        let mut add = |cx: f64, cy: f64, yaw: f64, lx: f64, ly: f64, z0: f64, z1: f64, kind| {
            let (s, c) = f64::sin_cos(yaw);
            boxes.push(RayBox {
                cx,
                cy,
                c,
                s,
                hx: 0.5 * lx,
                hy: 0.5 * ly,
                z0,
                z1,
                r: 0.5 * lx.hypot(ly),
                kind,
            });
        };
        let table =
            |x0: f64,
             length: f64,
             cy: f64,
             depth: f64,
             top: f64,
             add: &mut dyn FnMut(f64, f64, f64, f64, f64, f64, f64, HitKind)| {
                let top0 = (top - TABLE_TOP_THICKNESS_M).max(0.0);
                add(
                    x0 + 0.5 * length,
                    cy,
                    0.0,
                    length,
                    depth,
                    top0,
                    top,
                    HitKind::TableTop,
                );
                let inset = 0.5 * TABLE_LEG_SIZE_M + 0.02;
                for lx in [x0 + inset, x0 + length - inset] {
                    for ly in [cy - 0.5 * depth + inset, cy + 0.5 * depth - inset] {
                        add(
                            lx,
                            ly,
                            0.0,
                            TABLE_LEG_SIZE_M,
                            TABLE_LEG_SIZE_M,
                            0.0,
                            top0,
                            HitKind::TableLeg,
                        );
                    }
                }
            };
        let bt = &scene.banquet_table;
        for k in 0..bt.segment_count {
            let x0 = bt.x_min_m() + f64::from(k) * bt.segment_length_m;
            table(
                x0,
                bt.segment_length_m,
                TABLE_CENTER_Y_M,
                bt.depth_m,
                bt.top_height_m,
                &mut add,
            );
        }
        let lt = &scene.loading_table;
        table(
            lt.center_x_m - 0.5 * lt.length_m,
            lt.length_m,
            lt.center_y_m,
            lt.depth_m,
            lt.top_height_m,
            &mut add,
        );
        for ch in &scene.chairs {
            add(
                ch.x_m,
                ch.y_m,
                ch.yaw_rad,
                ch.depth_m,
                ch.width_m,
                0.0,
                ch.height_m,
                HitKind::Chair,
            );
        }
        let room = &scene.room;
        let t = WALL_THICKNESS_M;
        let (w, h) = (room.x_max_m - room.x_min_m, room.y_max_m - room.y_min_m);
        let (mx, my) = (
            0.5 * (room.x_min_m + room.x_max_m),
            0.5 * (room.y_min_m + room.y_max_m),
        );
        add(
            room.x_min_m - 0.5 * t,
            my,
            0.0,
            t,
            h + 2.0 * t,
            0.0,
            WALL_HEIGHT_M,
            HitKind::Wall,
        );
        add(
            room.x_max_m + 0.5 * t,
            my,
            0.0,
            t,
            h + 2.0 * t,
            0.0,
            WALL_HEIGHT_M,
            HitKind::Wall,
        );
        add(
            mx,
            room.y_min_m - 0.5 * t,
            0.0,
            w + 2.0 * t,
            t,
            0.0,
            WALL_HEIGHT_M,
            HitKind::Wall,
        );
        add(
            mx,
            room.y_max_m + 0.5 * t,
            0.0,
            w + 2.0 * t,
            t,
            0.0,
            WALL_HEIGHT_M,
            HitKind::Wall,
        );
        Self { boxes }
    }

    /// Boxes in the scene (tops, legs, chairs, walls).
    pub fn len(&self) -> usize {
        self.boxes.len()
    }

    /// True when there is nothing (never for a scene: it has walls).
    pub fn is_empty(&self) -> bool {
        self.boxes.is_empty()
    }

    /// The nearest hit of the ray from `origin` along the unit vector `dir` (world frame)
    /// within `max_range` m: its distance and what it hit. The floor counts (z = 0).
    pub fn cast(&self, origin: [f64; 3], dir: [f64; 3], max_range: f64) -> Option<(f64, HitKind)> {
        let mut best = max_range;
        let mut kind = None;
        if dir[2] < -1e-9 && origin[2] > 0.0 {
            let t = -origin[2] / dir[2];
            if t < best {
                best = t;
                kind = Some(HitKind::Floor);
            }
        }
        let hxy = (dir[0] * dir[0] + dir[1] * dir[1]).sqrt();
        let inv_hxy = if hxy > 1e-12 { 1.0 / hxy } else { 0.0 };
        for b in &self.boxes {
            // Broad phase in the plane: the bounding circle against the ray's line, and
            // nothing wholly farther than the nearest hit so far (a ray reaches horizontal
            // distance `along` at range `along / hxy`).
            let (ox, oy) = (b.cx - origin[0], b.cy - origin[1]);
            if hxy > 1e-12 {
                let along = (ox * dir[0] + oy * dir[1]) * inv_hxy;
                let across = (ox * dir[1] - oy * dir[0]).abs() * inv_hxy;
                if across > b.r || along < -b.r || along - b.r > best * hxy {
                    continue;
                }
            } else if ox * ox + oy * oy > b.r * b.r {
                continue;
            }
            if let Some(t) = b.hit(origin, dir)
                && t < best
            {
                best = t;
                kind = Some(b.kind);
            }
        }
        kind.map(|k| (best, k))
    }
}

impl RayBox {
    /// Entry distance of the ray into the box (slabs in the box's frame), if it enters ahead.
    fn hit(&self, o: [f64; 3], d: [f64; 3]) -> Option<f64> {
        let (px, py) = (o[0] - self.cx, o[1] - self.cy);
        // Into the box frame (rotate by -yaw).
        let lo = [self.c * px + self.s * py, -self.s * px + self.c * py, o[2]];
        let ld = [
            self.c * d[0] + self.s * d[1],
            -self.s * d[0] + self.c * d[1],
            d[2],
        ];
        let bounds = [(-self.hx, self.hx), (-self.hy, self.hy), (self.z0, self.z1)];
        let (mut t0, mut t1) = (0.0_f64, f64::INFINITY);
        for axis in 0..3 {
            let (lo_b, hi_b) = bounds[axis];
            if ld[axis].abs() < 1e-12 {
                if lo[axis] < lo_b || lo[axis] > hi_b {
                    return None;
                }
                continue;
            }
            let inv = 1.0 / ld[axis];
            let (mut a, mut b) = ((lo_b - lo[axis]) * inv, (hi_b - lo[axis]) * inv);
            if a > b {
                std::mem::swap(&mut a, &mut b);
            }
            t0 = t0.max(a);
            t1 = t1.min(b);
            if t0 > t1 {
                return None;
            }
        }
        Some(t0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Chair;

    fn scene() -> Scene {
        Scene::from_toml_str(
            include_str!("../data/example-scene.toml"),
            "example-scene.toml",
        )
        .expect("example scene")
    }

    #[test]
    fn a_level_ray_hits_a_chair_face_and_a_rising_ray_passes_over_it() {
        let mut s = scene();
        s.chairs = vec![Chair::new(2.0, 2.0, 0.0)];
        let rays = RayScene::from_scene(&s);
        let (t, kind) = rays
            .cast([0.5, 2.0, 0.4], [1.0, 0.0, 0.0], 100.0)
            .expect("hit");
        assert_eq!(kind, HitKind::Chair);
        assert!((t - (2.0 - 0.225 - 0.5)).abs() < 1e-9, "{t}");
        // 45 deg up from 0.4 m: over the 0.9 m backrest by the chair's near face.
        let up = std::f64::consts::FRAC_1_SQRT_2;
        let over = rays.cast([0.5, 2.0, 0.4], [up, 0.0, up], 100.0);
        assert_eq!(over, None, "nothing above the room's 3 m walls");
        // Down: the floor at 0.4 / sin(15 deg).
        let (s15, c15) = 15f64.to_radians().sin_cos();
        let (t, kind) = rays
            .cast([0.5, 3.0, 0.4], [0.0, c15, -s15], 100.0)
            .expect("hit");
        assert_eq!(kind, HitKind::Floor);
        assert!((t - 0.4 / s15).abs() < 1e-9);
    }

    #[test]
    fn under_a_table_top_a_ray_passes_between_the_legs_and_a_high_ray_hits_the_top() {
        let mut s = scene();
        s.chairs.clear();
        let rays = RayScene::from_scene(&s);
        let bt = s.banquet_table;
        // From the near side, level at 0.4 m, through the middle of a segment (no leg there).
        let x = bt.x_min_m() + 0.5 * bt.segment_length_m;
        let (t, kind) = rays
            .cast([x, 4.5, 0.4], [0.0, 1.0, 0.0], 100.0)
            .expect("hit");
        assert_eq!(kind, HitKind::Wall, "{t}");
        // Through a leg's line: a leg.
        let leg_x = bt.x_min_m() + 0.5 * TABLE_LEG_SIZE_M + 0.02;
        let (_, kind) = rays
            .cast([leg_x, 4.5, 0.4], [0.0, 1.0, 0.0], 100.0)
            .expect("hit");
        assert_eq!(kind, HitKind::TableLeg);
        // Level at the top's height: the top's edge.
        let z = bt.top_height_m - 0.01;
        let (t, kind) = rays.cast([x, 4.5, z], [0.0, 1.0, 0.0], 100.0).expect("hit");
        assert_eq!(kind, HitKind::TableTop);
        assert!((t - (TABLE_CENTER_Y_M - 0.5 * bt.depth_m - 4.5)).abs() < 1e-9);
    }

    #[test]
    fn a_yawed_chair_is_hit_at_its_rotated_face() {
        let mut s = scene();
        s.chairs = vec![Chair::new(2.0, 2.0, std::f64::consts::FRAC_PI_4)];
        let rays = RayScene::from_scene(&s);
        let (t, kind) = rays
            .cast([0.5, 2.0, 0.4], [1.0, 0.0, 0.0], 100.0)
            .expect("hit");
        assert_eq!(kind, HitKind::Chair);
        // A square of side 0.45 turned 45 deg reaches 0.45/sqrt(2) along x.
        assert!(
            (t - (1.5 - 0.45 * std::f64::consts::FRAC_1_SQRT_2)).abs() < 1e-9,
            "{t}"
        );
    }

    #[test]
    fn the_default_spec_checks_and_bad_values_are_named() {
        LidarSpec::default().check().expect("default");
        let bad = LidarSpec {
            rpm: 100.0,
            ..LidarSpec::default()
        };
        assert_eq!(bad.check().unwrap_err().0, "lidar.rpm");
        let mut bad = LidarSpec::default();
        bad.mount.z_m = f64::NAN;
        assert_eq!(bad.check().unwrap_err().0, "lidar.mount.z_m");
    }
}
