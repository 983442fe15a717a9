//! Collision primitives: the arm as capsules (one per link), the world as yawed boxes.
//!
//! A capsule is a segment swept by a sphere; it collides with a box when the segment comes
//! closer to the box than the radius. The distance from a point to a box is convex along a
//! segment, so the exact segment-box distance is a 1-D convex minimisation (golden section);
//! a slab test against the box grown by the radius rejects almost every pair before that.

use nalgebra::{Isometry3, Point3, Vector3};
use serde::{Deserialize, Serialize};

use crate::kinematics::{Joints, Ur5e};

/// An obstacle: a box in the world frame, rotated about the vertical by `yaw_rad`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObstacleBox {
    /// Box centre in the world frame [m].
    pub center: Point3<f64>,
    /// Half the box size along its own x, y, z axes [m].
    pub half_extents: Vector3<f64>,
    /// Rotation of the box about the world z axis [rad].
    pub yaw_rad: f64,
}

impl ObstacleBox {
    /// An axis-aligned box from its minimum and maximum corners.
    pub fn from_min_max(min: Point3<f64>, max: Point3<f64>) -> Self {
        Self {
            center: nalgebra::center(&min, &max),
            half_extents: (max - min) * 0.5,
            yaw_rad: 0.0,
        }
    }

    /// The point `p` (world frame) in the box's own frame (origin at the centre, axes along the
    /// box edges).
    #[inline]
    fn point_in_box_frame(&self, p: &Vector3<f64>, sin_yaw: f64, cos_yaw: f64) -> Vector3<f64> {
        let d = p - self.center.coords;
        Vector3::new(
            cos_yaw * d.x + sin_yaw * d.y,
            -sin_yaw * d.x + cos_yaw * d.y,
            d.z,
        )
    }

    /// Radius of the sphere around the centre that holds the box.
    pub fn bounding_radius_m(&self) -> f64 {
        self.half_extents.norm()
    }

    /// Whether the capsule from `a` to `b` (world frame) with radius `radius_m` touches the box.
    pub fn intersects_capsule(&self, a: &Vector3<f64>, b: &Vector3<f64>, radius_m: f64) -> bool {
        let (s, c) = self.yaw_rad.sin_cos();
        let la = self.point_in_box_frame(a, s, c);
        let lb = self.point_in_box_frame(b, s, c);
        segment_aabb_within(&la, &lb, &self.half_extents, radius_m)
    }
}

/// Squared distance from point `p` to the box `[-h, h]` (box frame).
#[inline]
fn point_aabb_sq(p: &Vector3<f64>, h: &Vector3<f64>) -> f64 {
    let mut sq = 0.0;
    for i in 0..3 {
        let excess = p[i].abs() - h[i];
        if excess > 0.0 {
            sq += excess * excess;
        }
    }
    sq
}

/// Whether the segment `a`-`b` comes within `r` of the box `[-h, h]` (all in the box frame).
fn segment_aabb_within(a: &Vector3<f64>, b: &Vector3<f64>, h: &Vector3<f64>, r: f64) -> bool {
    // Slab test of the segment against the box grown by r: a necessary condition (the grown box
    // holds the rounded box), and exact when the closest feature is a face.
    let d = b - a;
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for i in 0..3 {
        let lo = -h[i] - r;
        let hi = h[i] + r;
        if d[i].abs() < 1e-15 {
            if a[i] < lo || a[i] > hi {
                return false;
            }
        } else {
            let inv = 1.0 / d[i];
            let (mut ta, mut tb) = ((lo - a[i]) * inv, (hi - a[i]) * inv);
            if ta > tb {
                core::mem::swap(&mut ta, &mut tb);
            }
            t0 = t0.max(ta);
            t1 = t1.min(tb);
            if t0 > t1 {
                return false;
            }
        }
    }
    // Exact distance on the clipped part of the segment: the squared point-box distance is
    // convex along the segment, so golden-section search finds its minimum.
    let r_sq = r * r;
    let f = |t: f64| point_aabb_sq(&(a + d * t), h);
    let (mut lo, mut hi) = (t0, t1);
    if f(lo) <= r_sq || f(hi) <= r_sq {
        return true;
    }
    const INV_PHI: f64 = 0.618_033_988_749_894_8;
    let mut x1 = hi - INV_PHI * (hi - lo);
    let mut x2 = lo + INV_PHI * (hi - lo);
    let (mut f1, mut f2) = (f(x1), f(x2));
    // 40 steps shrink the interval by 0.618^40 ~ 4e-9 of the link length: sub-micrometre.
    for _ in 0..40 {
        if f1.min(f2) <= r_sq {
            return true;
        }
        if f1 < f2 {
            hi = x2;
            x2 = x1;
            f2 = f1;
            x1 = hi - INV_PHI * (hi - lo);
            f1 = f(x1);
        } else {
            lo = x1;
            x1 = x2;
            f1 = f2;
            x2 = lo + INV_PHI * (hi - lo);
            f2 = f(x2);
        }
    }
    f1.min(f2) <= r_sq
}

/// The arm as capsules: radii of each link and the offsets of the physical tubes from the DH
/// frames. Defaults follow the UR5e's outer dimensions (joint housings about 0.12 m across at
/// the base, 0.09 m at the wrists) and a Robotiq 2F-140 gripper.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArmCollisionModel {
    /// Upper arm tube and shoulder/elbow housings [m].
    pub upper_arm_radius_m: f64,
    /// Offset of the upper arm tube along joint axis 2 from the DH plane [m] (UR5e: 0.138).
    pub upper_arm_offset_m: f64,
    /// Forearm tube [m].
    pub forearm_radius_m: f64,
    /// Offset of the forearm tube along the joint axis from the DH plane [m] (UR5e: 0.007).
    pub forearm_offset_m: f64,
    /// Wrist 1 and wrist 2 housings [m].
    pub wrist_radius_m: f64,
    /// Wrist 3, coupling and gripper body down to the tool centre point [m].
    pub gripper_radius_m: f64,
    /// Base and shoulder housing, arm base to joint 2, for self-collision [m] (UR5e base
    /// about 0.15 m across).
    #[serde(default = "default_base_radius_m")]
    pub base_radius_m: f64,
    /// Added to every radius: clearance demanded from obstacles [m].
    pub margin_m: f64,
}

fn default_base_radius_m() -> f64 {
    0.075
}

impl Default for ArmCollisionModel {
    fn default() -> Self {
        Self {
            upper_arm_radius_m: 0.06,
            upper_arm_offset_m: 0.138,
            forearm_radius_m: 0.05,
            forearm_offset_m: 0.007,
            wrist_radius_m: 0.045,
            gripper_radius_m: 0.05,
            base_radius_m: default_base_radius_m(),
            margin_m: 0.01,
        }
    }
}

/// Number of capsules in [`ArmCollisionModel::capsules`].
pub const ARM_CAPSULES: usize = 5;

/// One capsule in the world frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Capsule {
    /// Segment start [m].
    pub a: Vector3<f64>,
    /// Segment end [m].
    pub b: Vector3<f64>,
    /// Radius including the margin [m].
    pub radius_m: f64,
}

impl ArmCollisionModel {
    /// The arm's capsules in the world frame for joints `q`, the arm base at `world_from_arm`
    /// and the tool centre point `tcp_offset_m` along the flange z axis. The shoulder link
    /// (base to joint 2) is left out: it stands on the mount and may touch it.
    pub fn capsules(
        &self,
        arm: &Ur5e,
        world_from_arm: &Isometry3<f64>,
        q: &Joints,
        tcp_offset_m: f64,
    ) -> [Capsule; ARM_CAPSULES] {
        let (o, z) = arm.origins_and_axes(q);
        let m = self.margin_m;
        // Joints 2..4 are parallel: z1 = z2 = z3 is the axis of the planar chain.
        let up = o[1] + z[1] * self.upper_arm_offset_m;
        let ue = o[2] + z[1] * self.upper_arm_offset_m;
        let fs = o[2] + z[1] * self.forearm_offset_m;
        let fe = o[3] + z[1] * self.forearm_offset_m;
        let tcp = o[6] + z[6] * tcp_offset_m;
        let w = |v: Vector3<f64>| world_from_arm.transform_point(&Point3::from(v)).coords;
        [
            Capsule {
                a: w(up),
                b: w(ue),
                radius_m: self.upper_arm_radius_m + m,
            },
            Capsule {
                a: w(fs),
                b: w(fe),
                radius_m: self.forearm_radius_m + m,
            },
            // Wrist 1 housing along joint axis 4 (o3 -> o4), wrist 2 housing along axis 5.
            Capsule {
                a: w(fe),
                b: w(o[4]),
                radius_m: self.wrist_radius_m + m,
            },
            Capsule {
                a: w(o[4]),
                b: w(o[5]),
                radius_m: self.wrist_radius_m + m,
            },
            // Wrist 3, coupling and gripper: o5 -> flange -> TCP are collinear.
            Capsule {
                a: w(o[5]),
                b: w(tcp),
                radius_m: self.gripper_radius_m + m,
            },
        ]
    }
}

/// Squared distance between segments `p1`-`q1` and `p2`-`q2` (closest points by clamped
/// parameters, the classic construction for two segments).
pub fn segment_segment_sq(
    p1: &Vector3<f64>,
    q1: &Vector3<f64>,
    p2: &Vector3<f64>,
    q2: &Vector3<f64>,
) -> f64 {
    let d1 = q1 - p1;
    let d2 = q2 - p2;
    let r = p1 - p2;
    let a = d1.dot(&d1);
    let e = d2.dot(&d2);
    let f = d2.dot(&r);
    const EPS: f64 = 1e-18;
    let (s, t) = if a <= EPS && e <= EPS {
        (0.0, 0.0)
    } else if a <= EPS {
        (0.0, (f / e).clamp(0.0, 1.0))
    } else {
        let c = d1.dot(&r);
        if e <= EPS {
            ((-c / a).clamp(0.0, 1.0), 0.0)
        } else {
            let b = d1.dot(&d2);
            let denom = a * e - b * b;
            let mut s = if denom > EPS {
                ((b * f - c * e) / denom).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let mut t = (b * s + f) / e;
            if t < 0.0 {
                t = 0.0;
                s = (-c / a).clamp(0.0, 1.0);
            } else if t > 1.0 {
                t = 1.0;
                s = ((b - c) / a).clamp(0.0, 1.0);
            }
            (s, t)
        }
    };
    let c1 = p1 + d1 * s;
    let c2 = p2 + d2 * t;
    (c1 - c2).norm_squared()
}

impl ArmCollisionModel {
    /// Whether non-adjacent links of the arm touch each other: gripper and wrist 2 against the
    /// upper arm, gripper against the forearm, and gripper, wrist 2 and forearm against the
    /// base column (DH origin 0 to joint 2, radius `base_radius_m`). `capsules` are those of
    /// [`ArmCollisionModel::capsules`] and `column` the base column in the same frame. The
    /// obstacle margin is not applied between the arm's own links.
    pub fn self_collides(&self, capsules: &[Capsule; ARM_CAPSULES], column: &Capsule) -> bool {
        const PAIRS: [(usize, usize); 3] = [(4, 0), (4, 1), (3, 0)];
        let m = self.margin_m;
        let touch = |x: &Capsule, y: &Capsule| {
            let reach = (x.radius_m - m) + (y.radius_m - m);
            segment_segment_sq(&x.a, &x.b, &y.a, &y.b) < reach * reach
        };
        PAIRS
            .iter()
            .any(|&(i, j)| touch(&capsules[i], &capsules[j]))
            || [1, 3, 4].iter().any(|&i| touch(&capsules[i], column))
    }

    /// The base column (arm base to joint 2) in the world frame, radius including the margin
    /// (so that [`ArmCollisionModel::self_collides`] treats it like the other capsules).
    pub fn base_column(&self, arm: &Ur5e, world_from_arm: &Isometry3<f64>) -> Capsule {
        let w = |v: Vector3<f64>| world_from_arm.transform_point(&Point3::from(v)).coords;
        Capsule {
            a: w(Vector3::zeros()),
            b: w(Vector3::new(0.0, 0.0, arm.d_m[0])),
            radius_m: self.base_radius_m + self.margin_m,
        }
    }
}

/// Whether any capsule touches the floor (z = 0) or any obstacle.
pub fn capsules_collide(capsules: &[Capsule], obstacles: &[ObstacleBox]) -> bool {
    for c in capsules {
        if c.a.z < c.radius_m || c.b.z < c.radius_m {
            return true;
        }
    }
    for o in obstacles {
        let reach = o.bounding_radius_m();
        for c in capsules {
            // Sphere-sphere broad phase: capsule's bounding sphere against the box's.
            let mid = (c.a + c.b) * 0.5;
            let half_len = (c.b - c.a).norm() * 0.5;
            if (mid - o.center.coords).norm() > reach + half_len + c.radius_m {
                continue;
            }
            if o.intersects_capsule(&c.a, &c.b, c.radius_m) {
                return true;
            }
        }
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(x: f64, y: f64, z: f64) -> Vector3<f64> {
        Vector3::new(x, y, z)
    }

    #[test]
    fn capsule_box_face_edge_and_corner_cases() {
        let b =
            ObstacleBox::from_min_max(Point3::new(-1.0, -1.0, -1.0), Point3::new(1.0, 1.0, 1.0));
        // Through the box.
        assert!(b.intersects_capsule(&v(-3.0, 0.0, 0.0), &v(3.0, 0.0, 0.0), 0.01));
        // Parallel to a face at 0.1 m: touches with r 0.11, not with r 0.09.
        assert!(b.intersects_capsule(&v(-3.0, 1.1, 0.0), &v(3.0, 1.1, 0.0), 0.11));
        assert!(!b.intersects_capsule(&v(-3.0, 1.1, 0.0), &v(3.0, 1.1, 0.0), 0.09));
        // Past a corner diagonally: the slab test alone would say yes, the distance is
        // sqrt(3) * 0.1 - ... the segment passes (1.1, 1.1, z) at distance 0.1 * sqrt(2).
        let (a, bb) = (v(1.1, 1.1, -3.0), v(1.1, 1.1, 3.0));
        assert!(!b.intersects_capsule(&a, &bb, 0.14));
        assert!(b.intersects_capsule(&a, &bb, 0.15));
        // Segment ends short of the box.
        assert!(!b.intersects_capsule(&v(3.0, 0.0, 0.0), &v(1.2, 0.0, 0.0), 0.1));
        assert!(b.intersects_capsule(&v(3.0, 0.0, 0.0), &v(1.05, 0.0, 0.0), 0.1));
    }

    #[test]
    fn yaw_rotates_the_box() {
        // A long thin box along x, rotated 90 degrees, lies along y.
        let b = ObstacleBox {
            center: Point3::new(0.0, 0.0, 0.0),
            half_extents: Vector3::new(1.0, 0.1, 0.1),
            yaw_rad: core::f64::consts::FRAC_PI_2,
        };
        assert!(b.intersects_capsule(&v(-0.2, 0.9, 0.0), &v(0.2, 0.9, 0.0), 0.01));
        assert!(!b.intersects_capsule(&v(0.9, -0.2, 0.0), &v(0.9, 0.2, 0.0), 0.01));
    }

    #[test]
    fn segment_distances() {
        let d = |a: [f64; 3], b: [f64; 3], c: [f64; 3], e: [f64; 3]| {
            segment_segment_sq(&a.into(), &b.into(), &c.into(), &e.into()).sqrt()
        };
        // Crossing at right angles 0.5 apart.
        assert!(
            (d([-1., 0., 0.], [1., 0., 0.], [0., -1., 0.5], [0., 1., 0.5]) - 0.5).abs() < 1e-12
        );
        // Parallel, overlapping.
        assert!((d([0., 0., 0.], [1., 0., 0.], [0.5, 0.3, 0.], [2., 0.3, 0.]) - 0.3).abs() < 1e-12);
        // Collinear, apart end to end.
        assert!((d([0., 0., 0.], [1., 0., 0.], [1.5, 0., 0.], [2., 0., 0.]) - 0.5).abs() < 1e-12);
        // A point against a segment.
        assert!((d([0.5, 1., 0.], [0.5, 1., 0.], [0., 0., 0.], [1., 0., 0.]) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn self_collision_of_folded_and_upright_arms() {
        let model = ArmCollisionModel::default();
        let arm = Ur5e::default();
        let id = Isometry3::identity();
        let column = model.base_column(&arm, &id);
        let half_pi = core::f64::consts::FRAC_PI_2;
        // Upright (the planner's carry pose) and a placing pose: free.
        for q in [
            [0.0, -half_pi, 0.0, -half_pi, 0.0, 0.0],
            [0.3, -1.8, -1.4, -1.5, 1.57, 0.0],
        ] {
            let caps = model.capsules(&arm, &id, &q, 0.2);
            assert!(!model.self_collides(&caps, &column), "{q:?}");
        }
        // Upper arm up, elbow folded right back, wrist pointing the gripper at the base.
        let folded = [0.0, -half_pi, 3.0, 0.0, 0.0, 0.0];
        let caps = model.capsules(&arm, &id, &folded, 0.2);
        assert!(model.self_collides(&caps, &column));
    }

    #[test]
    fn floor_counts_as_obstacle() {
        let c = [Capsule {
            a: v(0.0, 0.0, 0.03),
            b: v(1.0, 0.0, 0.5),
            radius_m: 0.05,
        }];
        assert!(capsules_collide(&c, &[]));
        let c = [Capsule {
            a: v(0.0, 0.0, 0.3),
            b: v(1.0, 0.0, 0.5),
            radius_m: 0.05,
        }];
        assert!(!capsules_collide(&c, &[]));
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(3000))]

        /// The capsule test agrees with the distance from 2001 points along the segment,
        /// outside a 1 mm band around the radius (where sampling itself is inexact).
        #[test]
        fn capsule_test_matches_dense_sampling(
            ax in -2.0..2.0f64, ay in -2.0..2.0f64, az in -2.0..2.0f64,
            bx in -2.0..2.0f64, by in -2.0..2.0f64, bz in -2.0..2.0f64,
            hx in 0.05..1.0f64, hy in 0.05..1.0f64, hz in 0.05..1.0f64,
            yaw in -3.2..3.2f64, r in 0.01..0.5f64,
        ) {
            let b = ObstacleBox {
                center: Point3::new(0.1, -0.2, 0.3),
                half_extents: v(hx, hy, hz),
                yaw_rad: yaw,
            };
            let (a, e) = (v(ax, ay, az), v(bx, by, bz));
            let (sy, cy) = yaw.sin_cos();
            let min_dist = (0..=2000)
                .map(|k| {
                    let p = a + (e - a) * (k as f64 / 2000.0);
                    point_aabb_sq(&b.point_in_box_frame(&p, sy, cy), &b.half_extents).sqrt()
                })
                .fold(f64::INFINITY, f64::min);
            // Sampling overestimates the distance by at most half a sample spacing.
            let spacing = (e - a).norm() / 2000.0;
            let hit = b.intersects_capsule(&a, &e, r);
            if min_dist < r - 1e-3 {
                proptest::prop_assert!(hit, "missed: sampled distance {} < r {}", min_dist, r);
            }
            if min_dist > r + spacing + 1e-3 {
                proptest::prop_assert!(!hit, "false hit: sampled distance {} > r {}", min_dist, r);
            }
        }
    }
}
