//! The checks a plan passes before the core follows it: every number against what the robot
//! and the map allow, and the loads against the tray; taking a plan in, or refusing it.

use std::time::Duration;

use grop_ipc::{EventKind, TaskPlanMsg, TaskStep, TaskStepKind};

use super::AbortReason;
use super::cycle::CycleOutputs;
use super::mission::MissionCore;

/// The longest leg a plan may ask for, s (an hour: no table-setting leg comes near it).
pub const MAX_TRAVEL_COST_S: f64 = 3600.0;

/// The highest object target a plan may name, m (the arm on the base reaches about 1.6 m).
pub const MAX_TARGET_HEIGHT_M: f64 = 2.5;

/// The longest docking approach or back-out a plan may ask for, m (the planner's longest is
/// `crate::docking::DOCKING_DISTANCES_M[0]`, 1 m).
pub const MAX_DOCKING_M: f64 = 2.0;

/// What is wrong with a plan's steps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PlanDefect {
    /// A goal off the map.
    OffMap {
        /// Step index.
        step: usize,
    },
    /// A travel cost outside 0 ..= [`MAX_TRAVEL_COST_S`].
    TravelCost {
        /// Step index.
        step: usize,
        /// The cost, s.
        value: f64,
    },
    /// An object the task does not have.
    UnknownObject {
        /// Step index.
        step: usize,
        /// The object.
        index: u32,
        /// Objects of the task.
        objects: u32,
    },
    /// An object target off the map or out of reach in height.
    Target {
        /// Step index.
        step: usize,
    },
    /// A docking approach or back-out that is no distance the base drives straight (not 0 ..=
    /// [`MAX_DOCKING_M`], or for the approach `crate::docking::NO_WAY_IN`).
    Docking {
        /// Step index.
        step: usize,
        /// The approach, m.
        approach_m: f64,
        /// The back-out, m.
        back_out_m: f64,
    },
}

impl std::fmt::Display for PlanDefect {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::OffMap { step } => write!(f, "step {step}: goal off the map"),
            Self::TravelCost { step, value } => {
                write!(f, "step {step}: travel cost {value:.3e} s out of range")
            }
            Self::UnknownObject {
                step,
                index,
                objects,
            } => write!(f, "step {step}: object {index} of a task of {objects}"),
            Self::Target { step } => write!(f, "step {step}: target off the map or out of reach"),
            Self::Docking {
                step,
                approach_m,
                back_out_m,
            } => write!(
                f,
                "step {step}: docking approach {approach_m:.3e} m / back-out {back_out_m:.3e} m out of range"
            ),
        }
    }
}

impl MissionCore {
    /// Every number of every step against what the robot and the map allow: goals and targets
    /// on the map, target heights the arm can reach, travel costs a leg can take, objects of
    /// this task.
    pub(super) fn check_steps(&self, steps: &[TaskStep]) -> Result<(), PlanDefect> {
        let on_map = |x: f64, y: f64| self.grid.cell_of(x, y).is_some();
        let objects = 64 - self.task_objects.leading_zeros();
        for (i, step) in steps.iter().enumerate() {
            if !on_map(step.x_m, step.y_m) {
                return Err(PlanDefect::OffMap { step: i });
            }
            if !(0.0..=MAX_TRAVEL_COST_S).contains(&step.travel_cost_s) {
                return Err(PlanDefect::TravelCost {
                    step: i,
                    value: step.travel_cost_s,
                });
            }
            let approach_ok = (0.0..=MAX_DOCKING_M).contains(&step.approach_m)
                || step.approach_m == crate::docking::NO_WAY_IN;
            if !approach_ok || !(0.0..=MAX_DOCKING_M).contains(&step.back_out_m) {
                return Err(PlanDefect::Docking {
                    step: i,
                    approach_m: step.approach_m,
                    back_out_m: step.back_out_m,
                });
            }
            match step.kind() {
                Ok(TaskStepKind::Load) if step.load_mask & !self.task_objects != 0 => {
                    return Err(PlanDefect::UnknownObject {
                        step: i,
                        index: 63 - (step.load_mask & !self.task_objects).leading_zeros(),
                        objects,
                    });
                }
                Ok(TaskStepKind::Unload) => {
                    if step.object_index >= objects {
                        return Err(PlanDefect::UnknownObject {
                            step: i,
                            index: step.object_index,
                            objects,
                        });
                    }
                    let [x, y, z] = step.target_m;
                    if !on_map(x, y) || !(0.0..=MAX_TARGET_HEIGHT_M).contains(&z) {
                        return Err(PlanDefect::Target { step: i });
                    }
                }
                _ => {}
            }
        }
        Ok(())
    }

    /// Whether the plan's tray adds up from what is on board now: every load fills free usable
    /// slots with its objects, every unload's object is in the slot the step names
    /// ([`crate::tray_plan::check_slots`]: the planner accounts, the executive checks).
    pub(super) fn check_tray(
        &self,
        steps: &[TaskStep],
    ) -> Result<(), crate::tray_plan::TrayPlanError> {
        let usable = self.slots.len().min(self.tray.pick.len());
        crate::tray_plan::check_slots(steps, &self.slots, usable)
    }

    /// A plan refused: the planner keeps answering what the executive cannot take, so after
    /// [`super::PLANS_REFUSED_LIMIT`] in a row the mission is given up (stopped, not spun).
    fn plan_refused(&mut self, now: Duration, outputs: &mut CycleOutputs) {
        self.plans_refused += 1;
        if self.plans_refused >= super::PLANS_REFUSED_LIMIT {
            self.abort(AbortReason::PlansRefused, now, outputs);
        }
    }

    pub(super) fn take_plan(
        &mut self,
        plan: &TaskPlanMsg,
        now: Duration,
        outputs: &mut CycleOutputs,
    ) {
        let Ok(steps) = plan.steps() else {
            self.event(
                EventKind::StaleInput,
                now,
                format_args!("plan {} rejected: malformed", plan.plan_id),
                outputs,
            );
            self.plan_refused(now, outputs);
            return;
        };
        if let Err(defect) = self.check_steps(steps) {
            self.event(
                EventKind::StaleInput,
                now,
                format_args!("plan {} rejected: {defect}", plan.plan_id),
                outputs,
            );
            self.plan_refused(now, outputs);
            return;
        }
        if let Err(defect) = self.check_tray(steps) {
            self.event(
                EventKind::StaleInput,
                now,
                format_args!("plan {} rejected: the tray: {defect}", plan.plan_id),
                outputs,
            );
            self.plan_refused(now, outputs);
            return;
        }
        self.plans_refused = 0;
        self.stats.plans += 1;
        self.steps.clear();
        self.steps.extend_from_slice(steps);
        self.plan_id = plan.plan_id;
        self.step_index = 0;
        self.phase = None;
        self.request_sent = None;
        self.event(
            EventKind::PlanStarted,
            now,
            // Not the wall-clock decision time: events are behaviour, and the same mission
            // must log the same events (the time is in the plan and the log's /timing/).
            format_args!(
                "plan {}: {} steps, U={:.1} F={:.2} C={:.1}s",
                plan.plan_id,
                steps.len(),
                plan.utility,
                plan.feasibility,
                plan.cost_s
            ),
            outputs,
        );
    }
}
