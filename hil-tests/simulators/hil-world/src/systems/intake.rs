//! What the onboard processes say (task plans and events), and what the clock noticed
//! (participants that died).

use grop_ipc::TaskStepKind;

use super::context::{Ctx, Flow, System};
use crate::report::{DeathRecord, EventRecord, MissionEnd, PlanRecord};
use crate::{max_abs, ns_to_s, secs};

/// The task plans: the report's plan records, and the newest plan's steps (the goals
/// [`super::progress::Legs`] compares with).
pub(crate) struct Plans;

impl System for Plans {
    fn name(&self) -> &'static str {
        "Plans"
    }

    fn step(&mut self, ctx: &mut Ctx<'_>) -> Flow {
        let now = ctx.now;
        let m = &mut ctx.mission;
        while let Ok(Some(plan)) = ctx.world.ports.plans.try_recv() {
            if let Ok(steps) = plan.steps() {
                m.latest_plan.clear();
                m.latest_plan.extend_from_slice(steps);
                if m.first_plan.is_none() {
                    m.first_plan = Some(secs(now));
                }
                ctx.report.plans.push(PlanRecord {
                    t_s: secs(now),
                    plan_id: plan.plan_id,
                    answers_request: plan.answers_request,
                    decision_us: plan.decision_us,
                    utility: plan.utility,
                    feasibility: plan.feasibility,
                    cost_s: plan.cost_s,
                    unloads: steps
                        .iter()
                        .filter(|s| s.kind() == Ok(TaskStepKind::Unload))
                        .map(|s| (s.object_index, s.side, s.x_m, s.y_m, s.feasibility))
                        .collect(),
                });
            }
        }
        Flow::Next
    }
}

/// The onboard events: the report's event records, a goal reached (for the legs), the
/// operator's enable asked for (the operator gives it after its delay), the end of the
/// mission.
pub(crate) struct Events;

impl System for Events {
    fn name(&self) -> &'static str {
        "Events"
    }

    fn step(&mut self, ctx: &mut Ctx<'_>) -> Flow {
        let now = ctx.now;
        let cfg = &ctx.cfg;
        let m = &mut ctx.mission;
        let report = &mut ctx.report;
        while let Ok(Some(ev)) = ctx.world.ports.events.try_recv() {
            let kind = ev.kind();
            let detail = ev.detail().unwrap_or("<not UTF-8>").to_owned();
            let kind_name = match kind {
                Ok(k) => format!("{k:?}"),
                Err(_) => format!("unknown({})", ev.kind),
            };
            if kind == Ok(grop_ipc::EventKind::GoalReached) {
                m.goal_reached_pending = true;
            }
            // The executive asks for the operator's enable: the operator gives it.
            if kind == Ok(grop_ipc::EventKind::Enable)
                && detail.contains("waiting for the operator's enable")
            {
                let resume = detail.contains("normal again");
                m.enable_due = cfg
                    .operator_delay
                    .map(|d| now + if resume { cfg.operator_resume_delay } else { d });
            }
            if kind == Ok(grop_ipc::EventKind::ReplanRequested) && m.first_request.is_none() {
                m.first_request = Some(ns_to_s(ev.stamp_ns));
            }
            let is_end = matches!(
                kind,
                Ok(grop_ipc::EventKind::PlanFinished | grop_ipc::EventKind::MissionAborted)
            );
            if cfg.progress_every.is_some() {
                println!("[{:7.2} s] {kind_name}: {detail}", ns_to_s(ev.stamp_ns));
            }
            report.events.push(EventRecord {
                t_s: ns_to_s(ev.stamp_ns),
                kind: kind_name,
                plan_id: ev.plan_id,
                step: ev.step_index,
                detail,
            });
            if is_end && m.ended_at.is_none() {
                m.ended_at = Some(now);
                report.end = if kind == Ok(grop_ipc::EventKind::PlanFinished) {
                    MissionEnd::Finished
                } else {
                    MissionEnd::Aborted
                };
            }
        }
        Flow::Next
    }
}

/// Participants the clock saw die, and when the base and the arm stopped afterwards; the
/// executive's death ends the mission.
pub(crate) struct Deaths;

impl System for Deaths {
    fn name(&self) -> &'static str {
        "Deaths"
    }

    fn step(&mut self, ctx: &mut Ctx<'_>) -> Flow {
        let now = ctx.now;
        let r = &ctx.reading;
        let (v, w, snap) = (r.v, r.w, &r.snap);
        let report = &mut ctx.report;
        for gone in ctx.world.host.take_departures() {
            println!(
                "[{:7.2} s] world: participant {:?} (pid {}) died",
                secs(gone.at),
                gone.name,
                gone.pid
            );
            report.deaths.push(DeathRecord {
                name: gone.name.clone(),
                pid: gone.pid,
                t_s: secs(gone.at),
                base_speed_then_mps: f64::from(v).abs(),
                base_stopped_at_s: None,
                arm_speed_then_radps: max_abs(&snap.qd),
                arm_stopped_at_s: None,
            });
            if gone.name == "grop-executive" && ctx.mission.ended_at.is_none() {
                ctx.mission.ended_at = Some(now);
                report.end = MissionEnd::ExecutiveDied;
            }
        }
        for d in report.deaths.iter_mut() {
            if d.base_stopped_at_s.is_none()
                && f64::from(v).abs() < 0.01
                && f64::from(w).abs() < 0.01
            {
                d.base_stopped_at_s = Some(secs(now));
            }
            if d.arm_stopped_at_s.is_none() && max_abs(&snap.qd) < 0.01 {
                d.arm_stopped_at_s = Some(secs(now));
            }
        }
        Flow::Next
    }
}
