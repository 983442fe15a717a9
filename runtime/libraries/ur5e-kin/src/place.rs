//! Arm placement: where the UR5e stands on the mobile base, and whether it can put the held
//! object at its goal from a given base pose (paper section IV-B: a trial succeeds iff "an arm
//! motion to the object's goal exists" from the realised base pose).

use core::f64::consts::{PI, TAU};

use nalgebra::{Isometry3, Matrix3, Point3, Translation3, UnitQuaternion, Vector3};
use planar::Pose2;
use serde::{Deserialize, Serialize};

use crate::collision::{ArmCollisionModel, ObstacleBox, capsules_collide};
use crate::kinematics::{Joints, Ur5e};

/// Where the arm base frame (DH frame 0) sits on the mobile base. The mobile base frame has its
/// origin at the base centre on the floor, x forward, z up.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArmMount {
    /// Arm base axis ahead of the base centre [m].
    pub forward_m: f64,
    /// Arm base axis to the left of the base centre [m].
    pub lateral_m: f64,
    /// Height of the arm base (the mounting flange under joint 1) above the floor [m].
    pub height_m: f64,
    /// Rotation of the arm base frame about the vertical relative to the mobile base [rad].
    pub yaw_rad: f64,
}

impl Default for ArmMount {
    /// 0.10 m ahead of the base centre on the centre line, 1.05 m above the floor, yawed by pi
    /// so that the DH zero pose (arm stretched along the arm base's -x) points forward. With it
    /// the near rows of the candidate band are within reach and the farthest (1.03 m from the
    /// table's centre line, 0.93 m from the arm axis) is not (DESIGN.md).
    fn default() -> Self {
        Self {
            forward_m: 0.10,
            lateral_m: 0.0,
            height_m: 1.05,
            yaw_rad: PI,
        }
    }
}

impl ArmMount {
    /// The arm base frame in the mobile base frame.
    pub fn base_from_arm(&self) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::new(self.forward_m, self.lateral_m, self.height_m),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), self.yaw_rad),
        )
    }
}

/// The mobile base frame (origin at the base centre on the floor, x forward, z up) in the world
/// frame, for a base at `base`.
pub fn world_from_base(base: &Pose2) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(base.x_m, base.y_m, 0.0),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), base.yaw_rad),
    )
}

/// Settings of [`crate::path::plan_joint_path`] (part of [`PlaceConfig`]: the joint paths of a
/// placing).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct JointPathSettings {
    /// Largest joint change of one tree extension (max norm) [rad].
    pub step_rad: f64,
    /// Largest joint change between collision checks along an edge (max norm) [rad]; 0.05 rad
    /// moves the TCP at most about 5 cm at full reach.
    pub edge_resolution_rad: f64,
    /// Samples drawn before giving up.
    pub max_samples: u32,
    /// Shortcut attempts on the found path.
    pub shortcut_attempts: u32,
}

impl Default for JointPathSettings {
    fn default() -> Self {
        Self {
            step_rad: 0.3,
            edge_resolution_rad: 0.05,
            max_samples: 5000,
            shortcut_attempts: 200,
        }
    }
}

/// How the placement is searched: the tool axis may tilt from straight down by up to
/// `down_tolerance_rad`; tilts are tried on `tilt_rings` rings of `tilt_azimuths` directions.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlaceConfig {
    /// The arm base on the mobile base.
    pub mount: ArmMount,
    /// Tool flange to the held object's centre along the flange z axis [m]: Robotiq 2F-140
    /// (coupling plus body, about 0.23 m to the fingertips) holding the object between its pads.
    pub tcp_offset_m: f64,
    /// Largest angle between the tool axis and straight down [rad] (default 10 degrees).
    pub down_tolerance_rad: f64,
    /// Rings of tilt tried after straight down (tilts = tolerance * k / rings, k = 1..rings).
    #[serde(default = "default_tilt_rings")]
    pub tilt_rings: u8,
    /// Directions tried on each tilt ring.
    #[serde(default = "default_tilt_azimuths")]
    pub tilt_azimuths: u8,
    /// The arm: DH parameters and joint limits.
    #[serde(default)]
    pub arm: Ur5e,
    /// The arm's collision capsules.
    #[serde(default)]
    pub collision: ArmCollisionModel,
    /// Joint-space planner settings ([`crate::plan_joint_path`]).
    #[serde(default)]
    pub path: JointPathSettings,
}

fn default_tilt_rings() -> u8 {
    2
}

fn default_tilt_azimuths() -> u8 {
    8
}

impl Default for PlaceConfig {
    fn default() -> Self {
        Self {
            mount: ArmMount::default(),
            tcp_offset_m: 0.20,
            down_tolerance_rad: 10f64.to_radians(),
            tilt_rings: default_tilt_rings(),
            tilt_azimuths: default_tilt_azimuths(),
            arm: Ur5e::default(),
            collision: ArmCollisionModel::default(),
            path: JointPathSettings::default(),
        }
    }
}

/// A [`PlaceConfig`] value that cannot describe a real arm.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("place config field `{field}`: {reason}")]
pub struct PlaceConfigError {
    /// Dotted path of the offending field, e.g. `collision.margin_m`.
    pub field: &'static str,
    /// What is wrong with it.
    pub reason: String,
}

impl PlaceConfig {
    /// Checks every number: finite, lengths and radii non-negative, tolerance within
    /// [0, 90 degrees], lower joint limits below upper ones, at least one tilt direction.
    pub fn validate(&self) -> Result<(), PlaceConfigError> {
        let err = |field: &'static str, reason: String| Err(PlaceConfigError { field, reason });
        let m = &self.mount;
        let c = &self.collision;
        let finite: [(&'static str, f64); 14] = [
            ("mount.forward_m", m.forward_m),
            ("mount.lateral_m", m.lateral_m),
            ("mount.height_m", m.height_m),
            ("mount.yaw_rad", m.yaw_rad),
            ("tcp_offset_m", self.tcp_offset_m),
            ("down_tolerance_rad", self.down_tolerance_rad),
            ("collision.upper_arm_radius_m", c.upper_arm_radius_m),
            ("collision.upper_arm_offset_m", c.upper_arm_offset_m),
            ("collision.forearm_radius_m", c.forearm_radius_m),
            ("collision.forearm_offset_m", c.forearm_offset_m),
            ("collision.wrist_radius_m", c.wrist_radius_m),
            ("collision.gripper_radius_m", c.gripper_radius_m),
            ("collision.margin_m", c.margin_m),
            ("path.step_rad", self.path.step_rad),
        ];
        for (field, v) in finite {
            if !v.is_finite() {
                return err(field, format!("{v} is not a finite number"));
            }
        }
        for (field, v) in &finite[6..] {
            if *v < 0.0 && !field.ends_with("offset_m") {
                return err(field, format!("{v} must not be negative"));
            }
        }
        if m.height_m < 0.0 {
            return err(
                "mount.height_m",
                format!("{} m is below the floor", m.height_m),
            );
        }
        if self.tcp_offset_m < 0.0 {
            return err(
                "tcp_offset_m",
                format!("{} m must not be negative", self.tcp_offset_m),
            );
        }
        if !(0.0..=PI / 2.0).contains(&self.down_tolerance_rad) {
            return err(
                "down_tolerance_rad",
                format!("{} rad is outside [0, pi/2]", self.down_tolerance_rad),
            );
        }
        if self.tilt_azimuths == 0 {
            return err("tilt_azimuths", "at least one direction is needed".into());
        }
        let a = &self.arm;
        if a.a_m
            .iter()
            .chain(&a.d_m)
            .chain(&a.alpha_rad)
            .any(|v| !v.is_finite())
        {
            return err("arm", "DH parameters must be finite".into());
        }
        for j in 0..6 {
            let (lo, hi) = (a.limits.lower_rad[j], a.limits.upper_rad[j]);
            if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
                return err(
                    "arm.limits",
                    format!("joint {}: [{lo}, {hi}] is not a range", j + 1),
                );
            }
        }
        if !(self.path.step_rad > 0.0 && self.path.edge_resolution_rad > 0.0) {
            return err(
                "path",
                "step_rad and edge_resolution_rad must be positive".into(),
            );
        }
        Ok(())
    }
}

/// Why a placement is impossible, from the least to the most progressed stage.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, thiserror::Error)]
pub enum PlaceFailure {
    /// No arm configuration puts the object at the goal with the tool down within tolerance.
    #[error("goal out of the arm's reach with the tool pointing down")]
    OutOfReach,
    /// Configurations exist but every one violates a joint limit.
    #[error("every arm configuration reaching the goal violates a joint limit")]
    JointLimits,
    /// Configurations within the limits exist but every one hits an obstacle or the floor.
    #[error("every arm configuration reaching the goal collides")]
    Collision,
}

/// A feasible placement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlacePlan {
    /// Joint angles that put the object at the goal [rad].
    pub joints: Joints,
    /// Tool flange pose in the world frame.
    pub flange_world: Isometry3<f64>,
    /// Angle between the tool axis and straight down [rad].
    pub tool_tilt_rad: f64,
}

/// Everything about one (config, base pose) that placement and the joint-space planner reuse:
/// the arm base frame in the world and the obstacles the arm can reach.
pub(crate) struct ArmScene<'a> {
    pub world_from_arm: Isometry3<f64>,
    /// Indices into the caller's obstacle slice of boxes within the arm's reach (all of them if
    /// more than the capacity).
    near: heapless::Vec<u16, 64>,
    all_near: bool,
    obstacles: &'a [ObstacleBox],
}

impl<'a> ArmScene<'a> {
    pub fn new(cfg: &PlaceConfig, base: Pose2, obstacles: &'a [ObstacleBox]) -> Self {
        let world_from_arm = world_from_base(&base) * cfg.mount.base_from_arm();
        let shoulder = world_from_arm.transform_point(&Point3::new(0.0, 0.0, cfg.arm.d_m[0]));
        let reach = max_link_reach_m(cfg);
        let mut near = heapless::Vec::new();
        let mut all_near = false;
        for (i, o) in obstacles.iter().enumerate() {
            let within = (o.center - shoulder).norm() <= reach + o.bounding_radius_m();
            if within && (i > u16::MAX as usize || near.push(i as u16).is_err()) {
                all_near = true;
                break;
            }
        }
        Self {
            world_from_arm,
            near,
            all_near,
            obstacles,
        }
    }

    /// Whether the arm at `q` touches an obstacle or the floor.
    pub fn collides(&self, cfg: &PlaceConfig, q: &Joints) -> bool {
        let caps = cfg
            .collision
            .capsules(&cfg.arm, &self.world_from_arm, q, cfg.tcp_offset_m);
        let column = cfg.collision.base_column(&cfg.arm, &self.world_from_arm);
        if cfg.collision.self_collides(&caps, &column) {
            return true;
        }
        if self.all_near {
            return capsules_collide(&caps, self.obstacles);
        }
        // Floor check with no obstacles, then the near boxes one by one.
        if capsules_collide(&caps, &[]) {
            return true;
        }
        self.near
            .iter()
            .any(|&i| capsules_collide(&caps, core::slice::from_ref(&self.obstacles[i as usize])))
    }
}

/// Whether the arm at joints `q`, on the mobile base at `base`, touches any of `obstacles` (world
/// frame) or the floor. The shoulder link is not checked (it stands on the mount).
pub fn arm_collides(cfg: &PlaceConfig, base: Pose2, q: &Joints, obstacles: &[ObstacleBox]) -> bool {
    ArmScene::new(cfg, base, obstacles).collides(cfg, q)
}

/// Whether the arm at joints `q`, on the mobile base at `base`, touches any of `obstacles` or
/// the floor, leaving self-collision aside: what a world simulation counts as contact with its
/// furniture ([`arm_collides`] also refuses self-colliding configurations, as a planner must).
pub fn arm_touches_obstacles(
    cfg: &PlaceConfig,
    base: Pose2,
    q: &Joints,
    obstacles: &[ObstacleBox],
) -> bool {
    let world_from_arm = world_from_base(&base) * cfg.mount.base_from_arm();
    let caps = cfg
        .collision
        .capsules(&cfg.arm, &world_from_arm, q, cfg.tcp_offset_m);
    crate::collision::capsules_collide(&caps, obstacles)
}

/// Distance from joint 2 (the shoulder) beyond which no capsule of the arm can reach [m].
fn max_link_reach_m(cfg: &PlaceConfig) -> f64 {
    let a = &cfg.arm;
    let c = &cfg.collision;
    let planar = a.a_m[1].abs() + a.a_m[2].abs();
    let along_axis = a.d_m[3].abs().max(c.upper_arm_offset_m.abs());
    let wrist = a.d_m[4].abs() + a.d_m[5].abs() + cfg.tcp_offset_m.abs();
    let radius = c
        .upper_arm_radius_m
        .max(c.forearm_radius_m)
        .max(c.wrist_radius_m)
        .max(c.gripper_radius_m)
        + c.margin_m;
    (planar + wrist).hypot(along_axis) + radius
}

fn config_is_finite(cfg: &PlaceConfig) -> bool {
    let m = &cfg.mount;
    let c = &cfg.collision;
    [
        m.forward_m,
        m.lateral_m,
        m.height_m,
        m.yaw_rad,
        cfg.tcp_offset_m,
        cfg.down_tolerance_rad,
    ]
    .iter()
    .chain(cfg.arm.a_m.iter())
    .chain(cfg.arm.d_m.iter())
    .chain(cfg.arm.alpha_rad.iter())
    .chain(
        [
            c.upper_arm_radius_m,
            c.forearm_radius_m,
            c.wrist_radius_m,
            c.gripper_radius_m,
        ]
        .iter(),
    )
    .all(|v| v.is_finite())
}

/// A rotation whose z column is the unit vector `z` (the x column is any perpendicular; the
/// rotation about the tool axis only changes q6, see [`plan_place`]).
fn frame_with_z(z: &Vector3<f64>) -> Matrix3<f64> {
    let helper = if z.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let x = (helper - z * z.dot(&helper)).normalize();
    let y = z.cross(&x);
    Matrix3::from_columns(&[x, y, *z])
}

/// Finds a joint configuration that puts the object held at the tool centre point at `goal`
/// (world frame) with the tool pointing down within `cfg.down_tolerance_rad`, the arm clear of
/// every obstacle and the floor, from the mobile base at `base`.
///
/// Search: straight down first, then tilts on `cfg.tilt_rings` rings of `cfg.tilt_azimuths`
/// directions, the flange leaning towards the arm base first (that shortens the reach). The
/// rotation about the tool axis is free: turning the flange about its own z only changes q6
/// (`T06 * Rz(psi) = T05 * Rz(q6 + psi) * Tz(d6)`), so q1..q5 depend on the flange position and
/// tool axis alone and q6 is set to the in-limit value nearest 0. Of the IK branches, the ones
/// with the elbow highest are tried first (they keep the arm above tables and chairs). The first
/// collision-free configuration wins. A sphere test rejects goals beyond reach before any IK.
///
/// Errors: the most progressed failure over all tried tool axes ([`PlaceFailure`]).
pub fn plan_place(
    cfg: &PlaceConfig,
    base: Pose2,
    goal: Point3<f64>,
    obstacles: &[ObstacleBox],
) -> Result<PlacePlan, PlaceFailure> {
    let finite = base.x_m.is_finite()
        && base.y_m.is_finite()
        && base.yaw_rad.is_finite()
        && goal.coords.iter().all(|v| v.is_finite())
        && config_is_finite(cfg);
    if !finite {
        // Nothing is reachable at a NaN; validated configs never get here
        // (see [`PlaceConfig::validate`]).
        return Err(PlaceFailure::OutOfReach);
    }
    let arm = &cfg.arm;
    let world_from_arm = world_from_base(&base) * cfg.mount.base_from_arm();
    let goal_arm = world_from_arm.inverse_transform_point(&goal).coords;
    // Tool axis directions are expressed in the arm base frame; the mount only yaws, so
    // "down" is -z there too.
    let tcp = cfg.tcp_offset_m;
    let d4 = arm.d_m[3].abs();
    let d6 = arm.d_m[5];
    let tol = cfg.down_tolerance_rad.clamp(0.0, PI / 2.0);

    // Cheap reach test on the wrist centre (origin 5), before IK. Straight down it sits
    // (tcp + d6) above the goal; tilting moves it by at most 2 (tcp + d6) sin(tol / 2).
    // Origin 5 is at most |a2| + |a3| + d5 from the shoulder in the plane of joints 2..4 and d4
    // off that plane.
    let wrist_lever = tcp + d6;
    let slack = 2.0 * wrist_lever * (tol / 2.0).sin();
    let p5_nominal = goal_arm + Vector3::new(0.0, 0.0, wrist_lever);
    let shoulder = Vector3::new(0.0, 0.0, arm.d_m[0]);
    let max_wrist_m = (arm.a_m[1].abs() + arm.a_m[2].abs() + arm.d_m[4].abs()).hypot(d4);
    if (p5_nominal - shoulder).norm() > max_wrist_m + slack || p5_nominal.xy().norm() < d4 - slack {
        return Err(PlaceFailure::OutOfReach);
    }

    let scene = ArmScene::new(cfg, base, obstacles);
    // Azimuth (arm base frame) of the horizontal direction from the goal towards the arm base.
    let towards_base = (-goal_arm.y).atan2(-goal_arm.x);
    let rings = if tol > 0.0 {
        cfg.tilt_rings as usize
    } else {
        0
    };
    let azimuths = (cfg.tilt_azimuths as usize).max(1);
    let mut worst = PlaceFailure::OutOfReach;

    for ring in 0..=rings {
        let tilt = if rings == 0 {
            0.0
        } else {
            tol * ring as f64 / rings as f64
        };
        let directions = if ring == 0 { 1 } else { azimuths };
        for k in 0..directions {
            // Alternate around the preferred direction: 0, +1, -1, +2, -2, ... steps.
            let step = k.div_ceil(2);
            let sign = if k % 2 == 1 { 1.0 } else { -1.0 };
            let az = towards_base + sign * step as f64 * TAU / azimuths as f64;
            // Tool axis z6 points from the flange to the object; the flange leans towards az.
            let (st, ct) = tilt.sin_cos();
            let z6 = Vector3::new(-st * az.cos(), -st * az.sin(), -ct);
            let flange = goal_arm - z6 * tcp;
            let rot = frame_with_z(&z6);
            match place_with_axis(cfg, &scene, &rot, &flange) {
                Ok(joints) => {
                    let flange_world = world_from_arm * arm.forward(&joints);
                    return Ok(PlacePlan {
                        joints,
                        flange_world,
                        tool_tilt_rad: tilt,
                    });
                }
                Err(f) => worst = worst.max_stage(f),
            }
        }
    }
    Err(worst)
}

impl PlaceFailure {
    fn stage(self) -> u8 {
        match self {
            PlaceFailure::OutOfReach => 1,
            PlaceFailure::JointLimits => 2,
            PlaceFailure::Collision => 3,
        }
    }

    fn max_stage(self, other: PlaceFailure) -> PlaceFailure {
        if other.stage() > self.stage() {
            other
        } else {
            self
        }
    }
}

/// IK for one flange position and tool axis; the first collision-free in-limit configuration,
/// elbow-highest first.
fn place_with_axis(
    cfg: &PlaceConfig,
    scene: &ArmScene<'_>,
    rot: &Matrix3<f64>,
    flange: &Vector3<f64>,
) -> Result<Joints, PlaceFailure> {
    let arm = &cfg.arm;
    // q6 is free (rotation about the tool axis): nearest 0 within its limits.
    let q6 = 0.0f64.clamp(arm.limits.lower_rad[5], arm.limits.upper_rad[5]);
    let mut candidates: heapless::Vec<(f64, Joints), 8> = heapless::Vec::new();
    let mut any_solution = false;
    arm.inverse_matrix(rot, flange, q6, |mut q| {
        any_solution = true;
        q[5] = q6;
        if let Some(fitted) = arm.fit_limits(&q) {
            // Elbow height over the arm base: origin 2 = d1 + a2 sin q2.
            let elbow_z = arm.d_m[0] + arm.a_m[1] * fitted[1].sin();
            let _ = candidates.push((elbow_z, fitted));
        }
        true
    });
    if !any_solution {
        return Err(PlaceFailure::OutOfReach);
    }
    if candidates.is_empty() {
        return Err(PlaceFailure::JointLimits);
    }
    candidates.sort_unstable_by(|a, b| b.0.total_cmp(&a.0));
    candidates
        .iter()
        .find(|(_, q)| !scene.collides(cfg, q))
        .map(|(_, q)| *q)
        .ok_or(PlaceFailure::Collision)
}
