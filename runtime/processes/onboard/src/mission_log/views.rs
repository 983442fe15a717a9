//! The mission in Foxglove's well-known schemas, derived by the recorder from the messages it
//! already takes, so that Foxglove's 3D, Image, Plot and Log panels show it with no
//! configuration (docs/logs.md, "Foxglove's panels"). Nothing here is new information: every
//! view is a function of the logged messages before it, the map and the robot file; a replay
//! compares the messages they come from, not the views.
//!
//! - `/tf` (`foxglove.FrameTransforms`, 20 Hz of the base's state): `map -> odom -> base_link ->
//!   arm_base -> arm_link1 .. arm_link6`. `map -> base_link` is the executive's estimate; `odom`
//!   is the base's dead reckoning, integrated here from the measured speeds of `/base/state`
//!   (the executive publishes its estimate only), so `map -> odom` is the correction the
//!   localisation applied to it; the arm links are the UR5e's DH frames at the joint angles of
//!   `/arm/state`, on the robot file's mount.
//! - `/scene` (`foxglove.SceneUpdate`, whenever something in it changes): the room, the tables,
//!   the chairs, the loading station, each object's target labelled with its state (pending,
//!   planned, on tray, placed, failed), the plan's standing spots with their F, the objects
//!   on the tray and the robot's body (attached to its frames).
//! - `/plan/path` (`foxglove.PosesInFrame`, per plan): the base's pose when the plan arrived,
//!   then each navigate step's goal.
//! - `/base/path` (`foxglove.PosesInFrame`, at most every 2 s): the route driven so far (the
//!   estimate, a pose every 10 cm or 0.2 rad).
//! - `/heatmaps/grid` (`foxglove.Grid`, per heatmaps message): Psi's success maps of every
//!   location of a decision over the floor, one float32 `success` per 6.25 cm cell (the most of
//!   the locations that cover it; NaN where none does).
//! - `/events/log` (`foxglove.Log`, per event): each event with a level, its source as the name.
//! - `/psi/views` (`foxglove.RawImage`, per heatmaps message): the crops Psi saw, cut again
//!   from the logged frame the decision used, beside its heatmaps (`super::psi_views`).
//! - In a HIL mission, the world's truth (`/world/truth`, logged as it came) adds the frame
//!   `map -> truth_base_link` to `/tf` and a ghost of the body on it to `/scene`, so the 3D
//!   panel shows the estimate against where the base really is.

use base64::Engine as _;
use base64::engine::general_purpose::STANDARD as BASE64;
use grop_ipc::{
    ArmStateMsg, BaseStateMsg, CameraFrameMsg, EventKind, EventMsg, HeatmapsMsg, TaskPlanMsg,
    TaskStepKind, TruthMsg,
};
use nalgebra::Isometry3;
use planar::{Pose2, wrap_angle};
use serde::Serialize;
use world::view::{CELL_SIZE_M, world_to_cell};
use world::{RobotConfig, Scene, Side};

use super::codec::Channel;
use super::foxglove::{
    ArrowPrimitive, Color, CubePrimitive, CylinderPrimitive, FLOAT32, FrameTransform,
    FrameTransforms, Grid, LinePrimitive, Log, PackedElementField, Pose, PosesInFrame, Quaternion,
    SceneEntity, SceneUpdate, SpherePrimitive, TextPrimitive, Time, Vector2, level, rgba, v3,
};
use super::psi_views::PsiViews;

/// The fixed frame.
pub const MAP: &str = "map";
/// The base's dead-reckoning frame.
pub const ODOM: &str = "odom";
/// The base (centre of its footprint, on the floor).
pub const BASE: &str = "base_link";
/// Where the base really is (HIL only: the simulated world's truth).
pub const TRUTH: &str = "truth_base_link";
/// The arm's base (under joint 1).
pub const ARM_BASE: &str = "arm_base";
/// The arm's DH frames 1..=6 (`arm_link6` is the tool flange).
pub const ARM_LINKS: [&str; 6] = [
    "arm_link1",
    "arm_link2",
    "arm_link3",
    "arm_link4",
    "arm_link5",
    "arm_link6",
];

/// Time between two `/tf` messages (ns of the base's stamps).
const TF_PERIOD_NS: u64 = 50_000_000;
/// Time between two `/base/path` messages (ns).
const PATH_PERIOD_NS: u64 = 2_000_000_000;
/// A driven pose is kept when the base moved this far (m) ...
const PATH_STEP_M: f64 = 0.1;
/// ... or turned this much (rad) since the last one.
const PATH_STEP_RAD: f64 = 0.2;

/// What the views know of an object.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum ObjectState {
    Pending,
    Planned,
    OnTray,
    Placed,
    Failed,
}

impl ObjectState {
    fn name(self) -> &'static str {
        match self {
            Self::Pending => "pending",
            Self::Planned => "planned",
            Self::OnTray => "on tray",
            Self::Placed => "placed",
            Self::Failed => "failed",
        }
    }

    fn color(self) -> Color {
        match self {
            Self::Pending => rgba(150, 150, 150, 1.0),
            Self::Planned => rgba(70, 130, 220, 1.0),
            Self::OnTray => rgba(240, 170, 30, 1.0),
            Self::Placed => rgba(40, 170, 60, 1.0),
            Self::Failed => rgba(210, 40, 40, 1.0),
        }
    }
}

/// A step of a plan, as far as the views need it.
#[derive(Debug, Clone, Copy)]
struct Step {
    kind: Option<TaskStepKind>,
    object: u32,
    load_mask: u64,
    pose: Pose2,
    feasibility: f64,
}

/// The recorder's Foxglove views (see the module docs). Fed every message of the topics it
/// reads in the order the recorder logs them; [`Views::take`] gives what to log.
pub struct Views {
    scene: Scene,
    mount: Isometry3<f64>,
    body: [f64; 3],
    arm: ur5e_kin::Ur5e,
    joints: Option<[f64; 6]>,
    last_tf_ns: Option<u64>,
    /// The dead-reckoned pose, its stamp and the speeds measured then.
    odom: Option<(Pose2, u64, f64, f64)>,
    estimate: Option<Pose2>,
    driven: Vec<Pose2>,
    driven_changed: bool,
    last_path_ns: Option<u64>,
    plans: Vec<(u64, Vec<Step>)>,
    objects: Vec<ObjectState>,
    on_tray: u64,
    scene_changed: bool,
    /// The world's newest truth (HIL only).
    truth: Option<Pose2>,
    psi: PsiViews,
    out: Vec<(Channel, u64, Vec<u8>)>,
}

fn to_vec<T: Serialize>(value: &T) -> Vec<u8> {
    // Plain structs of numbers and strings: serialising into a Vec cannot fail.
    serde_json::to_vec(value).unwrap_or_default()
}

/// A length for a view: to 0.1 mm (the views are for eyes; short numbers keep the log small).
fn mm(x: f64) -> f64 {
    (x * 1e4).round() / 1e4
}

/// A quaternion component for a view, to 1e-6.
fn unit(x: f64) -> f64 {
    (x * 1e6).round() / 1e6
}

fn rounded(q: Quaternion) -> Quaternion {
    Quaternion {
        x: unit(q.x),
        y: unit(q.y),
        z: unit(q.z),
        w: unit(q.w),
    }
}

/// A pose on the floor for a view (rounded).
fn floor_pose(p: &Pose2) -> Pose {
    Pose {
        position: v3(mm(p.x_m), mm(p.y_m), 0.0),
        orientation: rounded(Quaternion::yaw(p.yaw_rad)),
    }
}

fn transform(stamp: Time, parent: &str, child: &str, iso: &Isometry3<f64>) -> FrameTransform {
    let t = iso.translation.vector;
    let q = iso.rotation.into_inner().coords;
    FrameTransform {
        timestamp: stamp,
        parent_frame_id: parent.to_owned(),
        child_frame_id: child.to_owned(),
        translation: v3(mm(t.x), mm(t.y), mm(t.z)),
        rotation: rounded(Quaternion {
            x: q.x,
            y: q.y,
            z: q.z,
            w: q.w,
        }),
    }
}

fn planar_transform(stamp: Time, parent: &str, child: &str, p: &Pose2) -> FrameTransform {
    let pose = floor_pose(p);
    FrameTransform {
        timestamp: stamp,
        parent_frame_id: parent.to_owned(),
        child_frame_id: child.to_owned(),
        translation: pose.position,
        rotation: pose.orientation,
    }
}

fn cube(x: f64, y: f64, z: f64, yaw: f64, size: [f64; 3], color: Color) -> CubePrimitive {
    CubePrimitive {
        pose: Pose::planar(x, y, z, yaw),
        size: v3(size[0], size[1], size[2]),
        color,
    }
}

fn label(x: f64, y: f64, z: f64, text: String) -> TextPrimitive {
    TextPrimitive {
        pose: Pose::planar(x, y, z, 0.0),
        billboard: true,
        font_size: 14.0,
        scale_invariant: true,
        color: rgba(255, 255, 255, 1.0),
        text,
    }
}

impl Views {
    /// Views of a mission on `scene` with `robot`.
    pub fn new(scene: Scene, robot: &RobotConfig) -> Self {
        let objects = vec![ObjectState::Pending; scene.targets.len()];
        Self {
            mount: robot.place.mount.base_from_arm(),
            body: [
                robot.footprint.length_m,
                robot.footprint.width_m,
                robot.footprint.body_height_m,
            ],
            arm: ur5e_kin::Ur5e::default(),
            scene,
            joints: None,
            last_tf_ns: None,
            odom: None,
            estimate: None,
            driven: Vec::new(),
            driven_changed: false,
            last_path_ns: None,
            plans: Vec::new(),
            objects,
            on_tray: 0,
            scene_changed: true,
            truth: None,
            psi: PsiViews::default(),
            out: Vec::new(),
        }
    }

    /// A camera frame the recorder logs (kept for the `/psi/views` of the decisions naming it).
    pub fn camera(&mut self, m: &CameraFrameMsg) {
        self.psi.frame(m);
    }

    /// The simulated world's truth: the `truth_base_link` frame from the next `/tf` on.
    pub fn truth(&mut self, m: &TruthMsg) {
        let p = Pose2::new(m.x_m, m.y_m, m.yaw_rad);
        if p.is_finite() {
            if self.truth.is_none() {
                // The ghost body joins the scene.
                self.scene_changed = true;
            }
            self.truth = Some(p);
        }
    }

    /// Decisions whose `/psi/views` image could not be made (their frame was not kept).
    pub fn psi_views_missed(&self) -> u64 {
        self.psi.missed
    }

    /// The arm's state: its joints move the arm's frames.
    pub fn arm_state(&mut self, m: &ArmStateMsg) {
        if m.joints_rad.iter().all(|q| q.is_finite()) {
            self.joints = Some(m.joints_rad);
        }
    }

    /// The base's state: the estimate, the dead reckoning, `/tf` and the driven path.
    pub fn base_state(&mut self, m: &BaseStateMsg) {
        let estimate = Pose2::new(m.x_m, m.y_m, m.yaw_rad);
        if !estimate.is_finite() {
            return;
        }
        self.estimate = Some(estimate);
        let (speed, yaw_rate) = if m.speed_mps.is_finite() && m.yaw_rate_radps.is_finite() {
            (m.speed_mps, m.yaw_rate_radps)
        } else {
            (0.0, 0.0)
        };
        let odom = match self.odom {
            None => Pose2::default(),
            Some((p, stamp, v, w)) => {
                let dt = m.stamp_ns.saturating_sub(stamp) as f64 * 1e-9;
                let mid = p.yaw_rad + 0.5 * w * dt;
                Pose2::new(
                    p.x_m + v * dt * mid.cos(),
                    p.y_m + v * dt * mid.sin(),
                    wrap_angle(p.yaw_rad + w * dt),
                )
            }
        };
        self.odom = Some((odom, m.stamp_ns, speed, yaw_rate));
        if self
            .last_tf_ns
            .is_none_or(|t| m.stamp_ns >= t + TF_PERIOD_NS)
        {
            self.last_tf_ns = Some(m.stamp_ns);
            self.push_tf(m.stamp_ns, &estimate, &odom);
        }
        let moved = self.driven.last().is_none_or(|last| {
            last.distance_m(&estimate) >= PATH_STEP_M
                || wrap_angle(last.yaw_rad - estimate.yaw_rad).abs() >= PATH_STEP_RAD
        });
        if moved {
            self.driven.push(estimate);
            self.driven_changed = true;
        }
        if self.driven_changed
            && self
                .last_path_ns
                .is_none_or(|t| m.stamp_ns >= t + PATH_PERIOD_NS)
        {
            self.last_path_ns = Some(m.stamp_ns);
            self.driven_changed = false;
            let path = PosesInFrame {
                timestamp: Time::from_ns(m.stamp_ns),
                frame_id: MAP.to_owned(),
                poses: self.driven.iter().map(floor_pose).collect(),
            };
            self.out
                .push((Channel::DrivenPath, m.stamp_ns, to_vec(&path)));
        }
    }

    fn push_tf(&mut self, stamp_ns: u64, estimate: &Pose2, odom: &Pose2) {
        let t = Time::from_ns(stamp_ns);
        let map_from_odom = estimate.compose(&odom.inverse());
        let mut transforms = vec![
            planar_transform(t, MAP, ODOM, &map_from_odom),
            planar_transform(t, ODOM, BASE, odom),
            transform(t, BASE, ARM_BASE, &self.mount),
        ];
        if let Some(q) = self.joints {
            let frames = self.arm.frames(&q).frames;
            let mut parent = ARM_BASE;
            for (i, child) in ARM_LINKS.iter().enumerate() {
                let local = frames[i].inverse() * frames[i + 1];
                transforms.push(transform(t, parent, child, &local));
                parent = child;
            }
        }
        if let Some(truth) = &self.truth {
            transforms.push(planar_transform(t, MAP, TRUTH, truth));
        }
        self.out.push((
            Channel::Tf,
            stamp_ns,
            to_vec(&FrameTransforms { transforms }),
        ));
    }

    fn step(&self, plan_id: u64, index: u32) -> Option<&Step> {
        self.plans
            .iter()
            .rev()
            .find(|(id, _)| *id == plan_id)
            .and_then(|(_, steps)| steps.get(index as usize))
    }

    fn set(&mut self, object: u32, state: ObjectState) {
        if let Some(s) = self.objects.get_mut(object as usize) {
            if *s != state {
                *s = state;
                self.scene_changed = true;
            }
        }
    }

    /// A task plan: its path, and the objects it plans.
    pub fn plan(&mut self, m: &TaskPlanMsg) {
        let n = (m.step_count as usize).min(m.steps.len());
        let steps: Vec<Step> = m.steps[..n]
            .iter()
            .map(|s| Step {
                kind: s.kind().ok(),
                object: s.object_index,
                load_mask: s.load_mask,
                pose: Pose2::new(s.x_m, s.y_m, s.yaw_rad),
                feasibility: s.feasibility,
            })
            .collect();
        let mut poses: Vec<Pose> = self.estimate.iter().map(floor_pose).collect();
        for s in &steps {
            if s.kind == Some(TaskStepKind::Navigate) && s.pose.is_finite() {
                poses.push(floor_pose(&s.pose));
            }
            if s.kind == Some(TaskStepKind::Unload) {
                let on_tray = self.on_tray & (1u64 << (s.object % 64)) != 0;
                let state = self.objects.get(s.object as usize).copied();
                if matches!(state, Some(ObjectState::Pending | ObjectState::Failed)) && !on_tray {
                    self.set(s.object, ObjectState::Planned);
                }
            }
        }
        let path = PosesInFrame {
            timestamp: Time::from_ns(m.stamp_ns),
            frame_id: MAP.to_owned(),
            poses,
        };
        self.out
            .push((Channel::PlannedPath, m.stamp_ns, to_vec(&path)));
        // The newest plans only: an event names a recent one.
        if self.plans.len() == 16 {
            self.plans.remove(0);
        }
        self.plans.push((m.plan_id, steps));
        self.scene_changed = true;
    }

    /// An event: a log message, and what it changes in the scene.
    pub fn event(&mut self, m: &EventMsg) {
        let kind = m.kind().ok();
        let step = self.step(m.plan_id, m.step_index).copied();
        match (kind, step) {
            (Some(EventKind::Loaded), Some(s)) => {
                self.on_tray |= s.load_mask;
                for i in 0..self.objects.len().min(64) {
                    if s.load_mask & (1u64 << i) != 0 {
                        self.set(i as u32, ObjectState::OnTray);
                    }
                }
                self.scene_changed = true;
            }
            (Some(EventKind::UnloadSucceeded), Some(s)) => {
                self.on_tray &= !(1u64 << (s.object % 64));
                self.set(s.object, ObjectState::Placed);
                self.scene_changed = true;
            }
            (Some(EventKind::UnloadFailed), Some(s)) => self.set(s.object, ObjectState::Failed),
            _ => {}
        }
        let level = match kind {
            Some(
                EventKind::LinkLost
                | EventKind::BaseFault
                | EventKind::ArmStopped
                | EventKind::PeerLost
                | EventKind::MissionAborted
                | EventKind::Collision,
            )
            | None => level::ERROR,
            Some(
                EventKind::UnloadFailed
                | EventKind::StaleInput
                | EventKind::TrayMismatch
                | EventKind::NotPlanned
                | EventKind::Obstacle
                | EventKind::InputRefused,
            ) => level::WARNING,
            Some(_) => level::INFO,
        };
        let kind_name = kind.map_or_else(|| format!("kind {}", m.kind), |k| format!("{k:?}"));
        let detail = m.detail().unwrap_or("<invalid utf-8>");
        let log = Log {
            timestamp: Time::from_ns(m.stamp_ns),
            level,
            message: if detail.is_empty() {
                format!("{kind_name} (plan {}, step {})", m.plan_id, m.step_index)
            } else {
                format!(
                    "{kind_name}: {detail} (plan {}, step {})",
                    m.plan_id, m.step_index
                )
            },
            name: match m.source {
                1 => "planner",
                2 => "executive",
                3 => "world",
                _ => "grop",
            }
            .to_owned(),
            file: String::new(),
            line: 0,
        };
        self.out.push((Channel::EventLog, m.stamp_ns, to_vec(&log)));
    }

    /// Psi's heatmaps: one grid over the floor, and the views Psi saw (made in
    /// [`Views::take`], once the frame they were cut from is in).
    pub fn heatmaps(&mut self, m: &HeatmapsMsg) {
        self.psi.heatmaps(m);
        let Ok(locations) = m.locations() else {
            return;
        };
        if locations.is_empty() {
            return;
        }
        // A crop is HEATMAP_COLS cells along the table, centred on the target, and
        // HEATMAP_ROWS cells away from its centre line.
        let half = 0.5 * grop_ipc::HEATMAP_COLS as f64 * CELL_SIZE_M;
        let depth = grop_ipc::HEATMAP_ROWS as f64 * CELL_SIZE_M;
        let x0 = locations
            .iter()
            .map(|l| l.target_m[0] - half)
            .fold(f64::INFINITY, f64::min);
        let x1 = locations
            .iter()
            .map(|l| l.target_m[0] + half)
            .fold(f64::NEG_INFINITY, f64::max);
        let near = locations.iter().any(|l| l.side >= 0);
        let far = locations.iter().any(|l| l.side < 0);
        let table_y = world::scene::TABLE_CENTER_Y_M;
        let y0 = if near { table_y - depth } else { table_y };
        let y1 = if far { table_y + depth } else { table_y };
        if !x0.is_finite() || !x1.is_finite() || x1 <= x0 {
            return;
        }
        let columns = ((x1 - x0) / CELL_SIZE_M).ceil() as usize;
        let rows = ((y1 - y0) / CELL_SIZE_M).ceil() as usize;
        let mut data = Vec::with_capacity(rows * columns * 4);
        for r in 0..rows {
            let y = y0 + (r as f64 + 0.5) * CELL_SIZE_M;
            for c in 0..columns {
                let x = x0 + (c as f64 + 0.5) * CELL_SIZE_M;
                let mut best = f32::NAN;
                for l in locations {
                    let side = if l.side >= 0 { Side::Near } else { Side::Far };
                    if let Some((row, col)) = world_to_cell(l.target_m[0], side, x, y) {
                        let v = l.values[row * grop_ipc::HEATMAP_COLS + col];
                        if best.is_nan() || v > best {
                            best = v;
                        }
                    }
                }
                data.extend_from_slice(&best.to_le_bytes());
            }
        }
        let grid = Grid {
            timestamp: Time::from_ns(m.stamp_ns),
            frame_id: MAP.to_owned(),
            pose: Pose::planar(x0, y0, 0.01, 0.0),
            column_count: columns as u32,
            cell_size: Vector2 {
                x: CELL_SIZE_M,
                y: CELL_SIZE_M,
            },
            row_stride: (columns * 4) as u32,
            cell_stride: 4,
            fields: vec![PackedElementField {
                name: "success".to_owned(),
                offset: 0,
                kind: FLOAT32,
            }],
            data: BASE64.encode(&data),
        };
        self.out
            .push((Channel::HeatmapGrid, m.stamp_ns, to_vec(&grid)));
    }

    /// The scene as it is now (every entity, so that the newest message alone is the scene).
    fn scene_update(&self, stamp_ns: u64) -> SceneUpdate {
        let t = Time::from_ns(stamp_ns);
        let mut entities = self.furniture(t);
        entities.extend(self.objects(t));
        entities.extend(self.robot(t));
        SceneUpdate {
            deletions: Vec::new(),
            entities,
        }
    }

    /// The room, the tables, the chairs and the loading station.
    fn furniture(&self, t: Time) -> Vec<SceneEntity> {
        let s = &self.scene;
        let mut entities = Vec::new();
        let mut room = SceneEntity::new(t, MAP, "room".to_owned());
        let r = &s.room;
        room.lines.push(LinePrimitive {
            kind: 1,
            pose: Pose::default(),
            thickness: 0.05,
            scale_invariant: false,
            points: vec![
                v3(r.x_min_m, r.y_min_m, 0.0),
                v3(r.x_max_m, r.y_min_m, 0.0),
                v3(r.x_max_m, r.y_max_m, 0.0),
                v3(r.x_min_m, r.y_max_m, 0.0),
            ],
            color: rgba(200, 200, 200, 1.0),
            colors: Vec::new(),
            indices: Vec::new(),
        });
        entities.push(room);
        let wood = rgba(150, 110, 70, 1.0);
        let mut tables = SceneEntity::new(t, MAP, "tables".to_owned());
        let lt = &s.loading_table;
        let h = lt.top_height_m;
        tables.cubes.push(cube(
            lt.center_x_m,
            lt.center_y_m,
            0.5 * h,
            0.0,
            [lt.length_m, lt.depth_m, h],
            wood,
        ));
        let bt = &s.banquet_table;
        for f in bt.segment_footprints() {
            let h = bt.top_height_m;
            tables.cubes.push(cube(
                f.center_x_m,
                f.center_y_m,
                0.5 * h,
                f.yaw_rad(),
                [2.0 * f.half_length_m, 2.0 * f.half_width_m, h],
                wood,
            ));
        }
        entities.push(tables);
        let mut chairs = SceneEntity::new(t, MAP, "chairs".to_owned());
        for c in &s.chairs {
            chairs.cubes.push(cube(
                c.x_m,
                c.y_m,
                0.5 * c.height_m,
                c.yaw_rad,
                [c.depth_m, c.width_m, c.height_m],
                rgba(70, 90, 140, 1.0),
            ));
        }
        entities.push(chairs);
        let mut station = SceneEntity::new(t, MAP, "loading_station".to_owned());
        let st = &s.loading_station;
        station.cylinders.push(CylinderPrimitive {
            pose: Pose::planar(st.x_m, st.y_m, 0.005, 0.0),
            size: v3(0.3, 0.3, 0.01),
            bottom_scale: 1.0,
            top_scale: 1.0,
            color: rgba(240, 170, 30, 0.6),
        });
        station
            .texts
            .push(label(st.x_m, st.y_m, 0.3, "loading station".to_owned()));
        entities.push(station);
        entities
    }

    /// Each object's target with its state, and the newest plan's standing spots.
    fn objects(&self, t: Time) -> Vec<SceneEntity> {
        let mut entities = Vec::new();
        for (i, target) in self.scene.targets.iter().enumerate() {
            let state = self.objects.get(i).copied().unwrap_or(ObjectState::Pending);
            let mut e = SceneEntity::new(t, MAP, format!("target/{i}"));
            e.cylinders.push(CylinderPrimitive {
                pose: Pose::planar(target.x_m, target.y_m, target.z_m, 0.0),
                size: v3(0.08, 0.08, 0.12),
                bottom_scale: 1.0,
                top_scale: 1.0,
                color: state.color(),
            });
            e.texts.push(label(
                target.x_m,
                target.y_m,
                target.z_m + 0.25,
                format!("{i} {}", state.name()),
            ));
            e.metadata.push(super::foxglove::KeyValuePair {
                key: "state".to_owned(),
                value: state.name().to_owned(),
            });
            entities.push(e);
        }
        // The newest plan's standing spots (where each object is unloaded from), with their F.
        let mut spots = SceneEntity::new(t, MAP, "standing_spots".to_owned());
        if let Some((_, steps)) = self.plans.last() {
            let mut last_goal: Option<Pose2> = None;
            for st in steps {
                match st.kind {
                    Some(TaskStepKind::Navigate) => last_goal = Some(st.pose),
                    Some(TaskStepKind::Unload) => {
                        if let Some(g) = last_goal.filter(Pose2::is_finite) {
                            spots.arrows.push(ArrowPrimitive {
                                pose: Pose::planar(g.x_m, g.y_m, 0.02, g.yaw_rad),
                                shaft_length: 0.25,
                                shaft_diameter: 0.04,
                                head_length: 0.12,
                                head_diameter: 0.1,
                                color: rgba(70, 130, 220, 1.0),
                            });
                            let f = if st.feasibility.is_finite() {
                                st.feasibility
                            } else {
                                0.0
                            };
                            spots
                                .texts
                                .push(label(g.x_m, g.y_m, 0.35, format!("F {f:.2}")));
                        }
                    }
                    _ => {}
                }
            }
        }
        entities.push(spots);
        entities
    }

    /// The robot's body and the objects on its tray, which move with its frames.
    fn robot(&self, t: Time) -> Vec<SceneEntity> {
        let mut entities = Vec::new();
        let mut body = SceneEntity::new(t, BASE, "robot/base".to_owned());
        body.frame_locked = true;
        let [l, w, hb] = self.body;
        body.cubes.push(cube(
            0.0,
            0.0,
            0.5 * hb,
            0.0,
            [l, w, hb],
            rgba(190, 190, 200, 0.9),
        ));
        let mut slot = 0.0;
        for i in 0..self.objects.len().min(64) {
            if self.on_tray & (1u64 << i) != 0 {
                body.cubes.push(cube(
                    -0.25 * l,
                    -0.3 * w + slot,
                    hb + 0.04,
                    0.0,
                    [0.07, 0.07, 0.08],
                    ObjectState::OnTray.color(),
                ));
                slot += 0.1;
            }
        }
        entities.push(body);
        if self.truth.is_some() {
            let mut ghost = SceneEntity::new(t, TRUTH, "robot/truth".to_owned());
            ghost.frame_locked = true;
            ghost.cubes.push(cube(
                0.0,
                0.0,
                0.5 * hb,
                0.0,
                [l, w, hb],
                rgba(60, 220, 120, 0.35),
            ));
            ghost
                .texts
                .push(label(0.0, 0.0, hb + 0.3, "truth".to_owned()));
            entities.push(ghost);
        }
        for link in ARM_LINKS {
            let mut e = SceneEntity::new(t, link, format!("robot/{link}"));
            e.frame_locked = true;
            e.spheres.push(SpherePrimitive {
                pose: Pose::default(),
                size: v3(0.09, 0.09, 0.09),
                color: rgba(90, 160, 200, 1.0),
            });
            entities.push(e);
        }
        entities
    }

    /// What to log now (log time `now_ns`), in the order it was made; the scene last when it
    /// changed.
    pub fn take(&mut self, now_ns: u64) -> Vec<(Channel, u64, Vec<u8>)> {
        for (stamp, image) in self.psi.take(&self.scene.room) {
            self.out.push((Channel::PsiViews, stamp, to_vec(&image)));
        }
        if self.scene_changed {
            self.scene_changed = false;
            let scene = self.scene_update(now_ns);
            self.out.push((Channel::Scene, now_ns, to_vec(&scene)));
        }
        std::mem::take(&mut self.out)
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message
#[path = "views_tests.rs"]
mod tests;
