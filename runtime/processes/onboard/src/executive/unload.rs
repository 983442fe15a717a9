//! The unload of one object, as a non-blocking sequence of arm skills: pick the object from its
//! tray slot, carry it over the target, lower, release, retreat to the carry pose.
//!
//! The placing configuration is solved with inverse kinematics (ur5e-kin's `plan_place`, tool
//! pointing down, arm links checked against the map's furniture) at the base pose *measured* at
//! the table (the table-relative fix), not at the pose the planner asked for: the base stops
//! where noise put it and the arm makes up for it. The sequence advances one skill at a time
//! through [`ArmPort`], polled once per arm cycle; it never blocks the executive.

use std::time::Duration;

use nalgebra::Point3;
use planar::Pose2;
use ur5e_kin::{Joints, ObstacleBox, PlaceConfig, PlaceFailure, plan_place};

/// How far above the target (and the tray slot) the gripper approaches and retreats, m.
pub const APPROACH_HEIGHT_M: f64 = 0.08;

/// The arm as the unload sequence drives it: the `ur5e` driver on the robot, a fake in tests.
pub trait ArmPort {
    /// Starts a joint move to `q` (the previous skill must be finished).
    fn start_move_joints(&mut self, q: &Joints, now: Duration) -> Result<(), ArmFault>;
    /// Starts opening (`close == false`) or closing the gripper.
    fn start_gripper(&mut self, close: bool, now: Duration) -> Result<(), ArmFault>;
    /// Progress of the running skill at `now`.
    fn poll(&mut self, now: Duration) -> Result<SkillStatus, ArmFault>;
}

/// Progress of one skill.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SkillStatus {
    /// Still moving.
    Running,
    /// Done; for the gripper, whether it closed on an object.
    Done {
        /// Gripper closed on something (closing) / nothing in the way (opening).
        object_held: bool,
    },
}

/// Why the arm cannot go on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ArmFault {
    /// The controller link is gone (the driver already tried to stop the arm).
    LinkLost,
    /// Protective stop (a collision, a limit).
    ProtectiveStop,
    /// Emergency stop.
    EmergencyStop,
    /// A skill did not finish in time or stopped short.
    SkillFailed,
    /// The gripper did not answer or reported a fault.
    GripperFault,
}

/// Why an unload did not place its object (the executive reports it and asks for a replan).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum UnloadFailure {
    /// No placing configuration at the measured base pose.
    Unreachable(PlaceFailure),
    /// No collision-free arm path between the tray and the target.
    NoArmPath,
    /// The gripper closed on nothing: the slot was empty.
    NothingInSlot,
    /// The object slipped out before release.
    Dropped,
    /// The arm faulted.
    Arm(ArmFault),
}

/// The tray on the base: object slots in the base frame, and the arm's carry pose.
#[derive(Debug, Clone, PartialEq)]
pub struct TrayGeometry {
    /// Slot k: the joints that put the gripper on the object in slot k.
    pub pick: Vec<Joints>,
    /// Slot k: the joints above it.
    pub pick_above: Vec<Joints>,
    /// The pose the arm travels in (folded over the base).
    pub carry: Joints,
}

/// Where a tray slot's object sits, base frame (x forward, z up), m.
pub fn default_tray_slots() -> [[f64; 3]; 3] {
    [
        [-0.20, -0.18, 1.10],
        [-0.20, 0.0, 1.10],
        [-0.20, 0.18, 1.10],
    ]
}

/// Solves the tray's joints from slot positions in the base frame (the base at the origin, no
/// furniture): an error names the slot the arm cannot reach.
pub fn solve_tray(cfg: &PlaceConfig, slots: &[[f64; 3]]) -> Result<TrayGeometry, String> {
    let origin = Pose2::default();
    let mut pick = Vec::with_capacity(slots.len());
    let mut pick_above = Vec::with_capacity(slots.len());
    for (k, s) in slots.iter().enumerate() {
        let at = plan_place(cfg, origin, Point3::new(s[0], s[1], s[2]), &[])
            .map_err(|e| format!("tray slot {k} at {s:?} (base frame): {e:?}"))?;
        let above = plan_place(
            cfg,
            origin,
            Point3::new(s[0], s[1], s[2] + APPROACH_HEIGHT_M),
            &[],
        )
        .map_err(|e| format!("above tray slot {k} at {s:?} (base frame): {e:?}"))?;
        pick.push(at.joints);
        pick_above.push(above.joints);
    }
    // Carry: above the middle slot, raised further, so the arm stays inside the base outline.
    let mid = slots
        .get(slots.len() / 2)
        .copied()
        .unwrap_or([-0.2, 0.0, 1.1]);
    let carry = plan_place(
        cfg,
        origin,
        Point3::new(mid[0] + 0.05, mid[1], mid[2] + 0.25),
        &[],
    )
    .map_err(|e| format!("carry pose above the tray: {e:?}"))?
    .joints;
    Ok(TrayGeometry {
        pick,
        pick_above,
        carry,
    })
}

/// The placing joints at the table, solved before the arm moves.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlaceJoints {
    /// On the target.
    pub place: Joints,
    /// Above it.
    pub above: Joints,
}

/// Most waypoints of one arm transit.
pub const MAX_WAYPOINTS: usize = 24;

/// Joint waypoints of a transit (straight joint-space segments, each collision-checked).
pub type Waypoints = heapless::Vec<Joints, MAX_WAYPOINTS>;

/// Everything the arm needs for one unload, planned before it moves: the placing joints and
/// collision-free joint paths (RRT-Connect, `ur5e_kin::plan_joint_path`) from over the tray slot
/// to over the target, and from over the target back to the carry pose.
#[derive(Debug, Clone, PartialEq)]
pub struct UnloadPlan {
    /// Placing joints.
    pub joints: PlaceJoints,
    /// Carry pose -> over the slot (first waypoint excluded).
    pub to_slot: Waypoints,
    /// Over the slot -> over the target (first waypoint excluded: the arm is there).
    pub to_target: Waypoints,
    /// Over the target -> carry pose (first waypoint excluded).
    pub to_carry: Waypoints,
}

impl UnloadPlan {
    /// A plan with straight joint moves only (no obstacles in the way, e.g. tests).
    pub fn direct(joints: PlaceJoints, carry: Joints) -> Self {
        Self::direct_via(joints, carry, None)
    }

    /// As [`UnloadPlan::direct`], with the move to the slot's approach `over_slot` included.
    pub fn direct_via(joints: PlaceJoints, carry: Joints, over_slot: Option<Joints>) -> Self {
        let mut to_slot = Waypoints::new();
        if let Some(q) = over_slot {
            let _ = to_slot.push(q);
        }
        let mut to_target = Waypoints::new();
        let _ = to_target.push(joints.above);
        let mut to_carry = Waypoints::new();
        let _ = to_carry.push(carry);
        Self {
            joints,
            to_slot,
            to_target,
            to_carry,
        }
    }
}

fn waypoints(path: &[Joints]) -> Waypoints {
    // Skip the start (the arm is there); keep the goal; thin the middle if ever too long.
    let rest = path.get(1..).unwrap_or(&[]);
    let n = rest.len();
    let stride = n.div_ceil(MAX_WAYPOINTS).max(1);
    let mut out = Waypoints::new();
    for (i, q) in rest.iter().enumerate() {
        if i % stride == stride - 1 || i + 1 == n {
            let _ = out.push(*q);
        }
    }
    out
}

/// Plans one unload at the measured base pose: placing joints, then the two transits. Runs in
/// the executive's worker (it allocates).
pub fn plan_unload(
    cfg: &PlaceConfig,
    base: Pose2,
    target: [f64; 3],
    obstacles: &[ObstacleBox],
    from_slot: &Joints,
    carry: &Joints,
    seed: u64,
) -> Result<UnloadPlan, UnloadFailure> {
    let joints = solve_place(cfg, base, target, obstacles).map_err(UnloadFailure::Unreachable)?;
    let transit = |a: &Joints, b: &Joints, salt: u64| -> Result<Waypoints, UnloadFailure> {
        match ur5e_kin::plan_joint_path(cfg, base, a, b, obstacles, seed ^ salt) {
            Ok(path) => Ok(waypoints(&path)),
            // The tray and carry poses sit over the base's own body, which the check counts as
            // an obstacle: from there, go straight (the body is the robot's, not furniture).
            Err(ur5e_kin::JointPathError::InvalidStart) => {
                let mut w = Waypoints::new();
                let _ = w.push(*b);
                Ok(w)
            }
            Err(_) => Err(UnloadFailure::NoArmPath),
        }
    };
    Ok(UnloadPlan {
        to_slot: transit(carry, from_slot, 0x736c)?,
        to_target: transit(from_slot, &joints.above, 0x7461)?,
        to_carry: transit(&joints.above, carry, 0x6361)?,
        joints,
    })
}

/// Solves the placing joints for `target` from the measured base pose against the furniture
/// `obstacles` (world frame). Allocates nothing.
pub fn solve_place(
    cfg: &PlaceConfig,
    base: Pose2,
    target: [f64; 3],
    obstacles: &[ObstacleBox],
) -> Result<PlaceJoints, PlaceFailure> {
    let place = plan_place(
        cfg,
        base,
        Point3::new(target[0], target[1], target[2]),
        obstacles,
    )?;
    // The approach from above needs a little more reach than the placing pose itself: at the
    // edge of the workspace lower it, down to none (the last transit waypoint is then the
    // placing pose), so that whatever the placing check accepts, the arm can do.
    let above = [1.0, 0.5, 0.25]
        .iter()
        .find_map(|share| {
            plan_place(
                cfg,
                base,
                Point3::new(target[0], target[1], target[2] + share * APPROACH_HEIGHT_M),
                obstacles,
            )
            .ok()
        })
        .map_or(place.joints, |p| p.joints);
    Ok(PlaceJoints {
        place: place.joints,
        above,
    })
}

/// The stages, in order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// Open the gripper before reaching in.
    OpenFirst,
    /// Over the slot.
    AboveSlot,
    /// Down onto the object.
    AtSlot,
    /// Close on it.
    Grasp,
    /// Lift it out.
    LiftFromSlot,
    /// Over the target.
    AboveTarget,
    /// Down onto the table.
    AtTarget,
    /// Open: the object is on the table.
    Release,
    /// Up again.
    Retreat,
    /// Back to the carry pose.
    Carry,
}

impl Stage {
    fn next(self) -> Option<Stage> {
        use Stage::*;
        Some(match self {
            OpenFirst => AboveSlot,
            AboveSlot => AtSlot,
            AtSlot => Grasp,
            Grasp => LiftFromSlot,
            LiftFromSlot => AboveTarget,
            AboveTarget => AtTarget,
            AtTarget => Release,
            Release => Retreat,
            Retreat => Carry,
            Carry => return None,
        })
    }
}

/// What one poll of the sequence says.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum UnloadProgress {
    /// Working on a stage.
    Busy(Stage),
    /// The object was released on the target and the arm is back in the carry pose.
    Placed,
    /// Gave up; the arm is (or is being) returned to the carry pose where possible.
    Failed(UnloadFailure),
}

/// One unload in progress.
#[derive(Debug, Clone)]
pub struct UnloadSequence {
    slot: usize,
    plan: UnloadPlan,
    stage: Stage,
    waypoint: usize,
    started: bool,
}

impl UnloadSequence {
    /// An unload of the object in tray slot `slot` along `plan`.
    pub fn new(slot: usize, plan: UnloadPlan) -> Self {
        Self {
            slot,
            plan,
            stage: Stage::OpenFirst,
            waypoint: 0,
            started: false,
        }
    }

    /// The current stage.
    pub fn stage(&self) -> Stage {
        self.stage
    }

    fn start(
        &self,
        arm: &mut dyn ArmPort,
        tray: &TrayGeometry,
        now: Duration,
    ) -> Result<(), ArmFault> {
        let slot = self.slot.min(tray.pick.len().saturating_sub(1));
        match self.stage {
            Stage::OpenFirst | Stage::Release => arm.start_gripper(false, now),
            Stage::Grasp => arm.start_gripper(true, now),
            Stage::AboveSlot | Stage::LiftFromSlot => {
                arm.start_move_joints(&tray.pick_above[slot], now)
            }
            Stage::AtSlot => arm.start_move_joints(&tray.pick[slot], now),
            Stage::AboveTarget => match self.plan.to_target.get(self.waypoint) {
                Some(q) => arm.start_move_joints(q, now),
                None => arm.start_move_joints(&self.plan.joints.above, now),
            },
            Stage::Retreat => arm.start_move_joints(&self.plan.joints.above, now),
            Stage::AtTarget => arm.start_move_joints(&self.plan.joints.place, now),
            Stage::Carry => match self.plan.to_carry.get(self.waypoint) {
                Some(q) => arm.start_move_joints(q, now),
                None => arm.start_move_joints(&tray.carry, now),
            },
        }
    }

    /// Advances: starts the current stage's skill, or polls it and moves to the next stage.
    pub fn poll(
        &mut self,
        arm: &mut dyn ArmPort,
        tray: &TrayGeometry,
        now: Duration,
    ) -> UnloadProgress {
        if !self.started {
            if let Err(fault) = self.start(arm, tray, now) {
                return UnloadProgress::Failed(UnloadFailure::Arm(fault));
            }
            self.started = true;
            return UnloadProgress::Busy(self.stage);
        }
        match arm.poll(now) {
            Err(fault) => UnloadProgress::Failed(UnloadFailure::Arm(fault)),
            Ok(SkillStatus::Running) => UnloadProgress::Busy(self.stage),
            Ok(SkillStatus::Done { object_held }) => {
                if self.stage == Stage::Grasp && !object_held {
                    return UnloadProgress::Failed(UnloadFailure::NothingInSlot);
                }
                // Transits run their waypoints one move each.
                let waypoints = match self.stage {
                    Stage::AboveSlot => self.plan.to_slot.len(),
                    Stage::AboveTarget => self.plan.to_target.len(),
                    Stage::Carry => self.plan.to_carry.len(),
                    _ => 0,
                };
                if self.waypoint + 1 < waypoints {
                    self.waypoint += 1;
                    self.started = false;
                    return self.poll(arm, tray, now);
                }
                self.waypoint = 0;
                match self.stage.next() {
                    None => UnloadProgress::Placed,
                    Some(next) => {
                        self.stage = next;
                        self.started = false;
                        // Start the next skill in the same cycle.
                        self.poll(arm, tray, now)
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fake arm: every skill takes `cycles` polls; records what it was asked.
    struct FakeArm {
        cycles: u32,
        left: u32,
        holding_object: bool,
        slot_has_object: bool,
        log: Vec<String>,
        fault_at: Option<usize>,
    }

    impl ArmPort for FakeArm {
        fn start_move_joints(&mut self, q: &Joints, _now: Duration) -> Result<(), ArmFault> {
            if self.fault_at == Some(self.log.len()) {
                return Err(ArmFault::ProtectiveStop);
            }
            self.log.push(format!("move {:.2}", q[0]));
            self.left = self.cycles;
            Ok(())
        }
        fn start_gripper(&mut self, close: bool, _now: Duration) -> Result<(), ArmFault> {
            self.log.push(if close { "close" } else { "open" }.into());
            self.holding_object = close && self.slot_has_object;
            self.left = self.cycles;
            Ok(())
        }
        fn poll(&mut self, _now: Duration) -> Result<SkillStatus, ArmFault> {
            if self.left > 0 {
                self.left -= 1;
                return Ok(SkillStatus::Running);
            }
            Ok(SkillStatus::Done {
                object_held: self.holding_object,
            })
        }
    }

    fn tray() -> TrayGeometry {
        TrayGeometry {
            pick: vec![[1.0; 6]; 3],
            pick_above: vec![[2.0; 6]; 3],
            carry: [3.0; 6],
        }
    }

    fn joints() -> PlaceJoints {
        PlaceJoints {
            place: [4.0; 6],
            above: [5.0; 6],
        }
    }

    fn run(arm: &mut FakeArm) -> UnloadProgress {
        let mut seq = UnloadSequence::new(1, UnloadPlan::direct(joints(), [3.0; 6]));
        let tray = tray();
        for k in 0..1000u64 {
            match seq.poll(arm, &tray, Duration::from_millis(2 * k)) {
                UnloadProgress::Busy(_) => {}
                done => return done,
            }
        }
        panic!("never finished");
    }

    #[test]
    fn a_successful_unload_runs_every_stage_in_order() {
        let mut arm = FakeArm {
            cycles: 3,
            left: 0,
            holding_object: false,
            slot_has_object: true,
            log: Vec::new(),
            fault_at: None,
        };
        assert_eq!(run(&mut arm), UnloadProgress::Placed);
        assert_eq!(
            arm.log,
            [
                "open",
                "move 2.00",
                "move 1.00",
                "close",
                "move 2.00",
                "move 5.00",
                "move 4.00",
                "open",
                "move 5.00",
                "move 3.00"
            ]
        );
    }

    #[test]
    fn an_empty_slot_and_an_arm_fault_fail_the_unload() {
        let mut empty = FakeArm {
            cycles: 1,
            left: 0,
            holding_object: false,
            slot_has_object: false,
            log: Vec::new(),
            fault_at: None,
        };
        assert_eq!(
            run(&mut empty),
            UnloadProgress::Failed(UnloadFailure::NothingInSlot)
        );
        let mut faulty = FakeArm {
            cycles: 1,
            left: 0,
            holding_object: false,
            slot_has_object: true,
            log: Vec::new(),
            fault_at: Some(5),
        };
        assert_eq!(
            run(&mut faulty),
            UnloadProgress::Failed(UnloadFailure::Arm(ArmFault::ProtectiveStop))
        );
    }

    #[test]
    fn transits_run_every_waypoint() {
        let mut plan = UnloadPlan::direct(joints(), [3.0; 6]);
        plan.to_target.clear();
        for q in [6.0, 7.0, 5.0] {
            plan.to_target.push([q; 6]).unwrap();
        }
        let mut arm = FakeArm {
            cycles: 1,
            left: 0,
            holding_object: false,
            slot_has_object: true,
            log: Vec::new(),
            fault_at: None,
        };
        let mut seq = UnloadSequence::new(0, plan);
        let tray = tray();
        for k in 0..1000u64 {
            if seq.poll(&mut arm, &tray, Duration::from_millis(2 * k)) == UnloadProgress::Placed {
                break;
            }
        }
        assert_eq!(
            arm.log[4..8],
            ["move 2.00", "move 6.00", "move 7.00", "move 5.00"]
        );
    }

    #[test]
    fn the_default_tray_is_reachable_with_the_default_mount() {
        let cfg = PlaceConfig::default();
        let tray = solve_tray(&cfg, &default_tray_slots()).expect("tray reachable");
        assert_eq!(tray.pick.len(), 3);
    }
}
