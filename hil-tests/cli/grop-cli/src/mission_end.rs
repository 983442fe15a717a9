//! Why a closed-loop mission ended, in words, from the world's report: the fault that was
//! injected and when, who noticed it and when (the executive's events), the reaction (the
//! executive's zero commands, when the base and the arm stood still, as the world measured
//! them) and what a person must do next. `grop demo` prints it after a mission that did not
//! simply finish.

use std::path::Path;

use hil_world::report::{MissionEnd, WorldReport};

/// Event kinds that say something went wrong (the executive's and the planner's).
const TROUBLE: [&str; 9] = [
    "StaleInput",
    "LinkLost",
    "BaseFault",
    "ArmStopped",
    "PeerLost",
    "MissionAborted",
    "UnloadFailed",
    "TrayMismatch",
    "NotPlanned",
];

/// The executive's abort reasons, as its `MissionAborted` detail starts
/// (`grop_onboard::executive::AbortReason`'s names).
const REASONS: [&str; 9] = [
    "BaseLinkLost",
    "BaseFault",
    "SecondCommander",
    "ArmLinkLost",
    "ArmStopped",
    "PlannerLost",
    "ClockLost",
    "Shutdown",
    "Stuck",
];

/// Most trouble events listed (the rest are counted).
const MAX_EVENTS: usize = 6;

/// The lines explaining how the mission ended; empty for a mission that finished with no fault
/// and no process death (nothing to explain). `run_dir` is where the logs are.
#[allow(
    clippy::too_many_lines,
    reason = "one explanation per way a mission ends, in the order printed"
)]
pub fn explain(report: &WorldReport, run_dir: &Path) -> Vec<String> {
    let fault = report.fault.as_ref();
    if report.end == MissionEnd::Finished && fault.is_none() && report.deaths.is_empty() {
        return Vec::new();
    }
    let mut out = vec![format!("why the mission ended ({}):", end_name(report.end))];
    // Times after the fault are given relative to it as well.
    let origin = fault.and_then(|f| f.injected_at_s);
    let at = |t: f64| match origin {
        Some(t0) => format!("{t:.2} s (+{:.3} s)", t - t0),
        None => format!("{t:.2} s"),
    };

    // What was injected.
    match fault {
        Some(f) => match f.injected_at_s {
            Some(t) => {
                let mut line = format!(
                    "  fault injected: {} at {t:.2} s (base at {:.2} m/s, fastest joint {:.2} rad/s then)",
                    f.spec, f.base_speed_then_mps, f.arm_speed_then_radps
                );
                let c = &f.can;
                let counts: Vec<String> = [
                    ("dropped", c.dropped),
                    ("duplicated", c.duplicated),
                    ("delayed", c.delayed),
                    ("reordered", c.reordered),
                    ("corrupted", c.corrupted),
                    ("sent by the second commander", c.intruder),
                ]
                .iter()
                .filter(|(_, n)| *n > 0)
                .map(|(what, n)| format!("{n} {what}"))
                .collect();
                if !counts.is_empty() {
                    line.push_str(&format!("; CAN frames: {}", counts.join(", ")));
                }
                out.push(line);
            }
            None => out.push(format!(
                "  fault {}: its trigger never came, so it was never injected",
                f.spec
            )),
        },
        None => out.push("  no fault was injected".into()),
    }

    // Who noticed, and when.
    let from = origin.unwrap_or(f64::NEG_INFINITY) - 1e-6;
    let trouble: Vec<_> = report
        .events
        .iter()
        .filter(|e| e.t_s >= from && TROUBLE.contains(&e.kind.as_str()))
        .collect();
    let reason = abort_reason(report);
    if let Some(who) = reason.map(noticer) {
        out.push(format!("  noticed by {who}:"));
    } else if !trouble.is_empty() {
        out.push("  the onboard processes reported:".into());
    }
    // The last ones matter most (the abort comes last).
    let skip = trouble.len().saturating_sub(MAX_EVENTS);
    if skip > 0 {
        out.push(format!("    ({skip} earlier events left out)"));
    }
    for e in &trouble[skip..] {
        out.push(format!("    {} {}: {}", at(e.t_s), e.kind, e.detail));
    }
    if trouble.is_empty() && origin.is_some() {
        out.push("  no onboard process reported anything after the fault".into());
    }
    for d in &report.deaths {
        let stopped = |s: Option<f64>| s.map_or("never".to_owned(), at);
        out.push(format!(
            "  process {} (pid {}) died, noticed at {}: base then {:.2} m/s, stood still at {}; fastest joint then {:.2} rad/s, stood still at {}",
            d.name,
            d.pid,
            at(d.t_s),
            d.base_speed_then_mps,
            stopped(d.base_stopped_at_s),
            d.arm_speed_then_radps,
            stopped(d.arm_stopped_at_s)
        ));
    }

    // The reaction, as the world measured it.
    if let Some(f) = fault.filter(|f| f.injected_at_s.is_some()) {
        let first = f
            .first_zero_command_at_s
            .map_or("no zero base command after it".to_owned(), |t| {
                format!("first zero base command at {}", at(t))
            });
        let all = f
            .commanded_zero_at_s
            .map_or("the executive kept commanding motion".to_owned(), |t| {
                format!("every command zero from {}", at(t))
            });
        out.push(format!("  reaction: {first}, {all}"));
        let stood = |part: &str, s: Option<f64>| {
            s.map_or(format!("{part} never came to rest"), |t| {
                format!("{part} stood still at {}", at(t))
            })
        };
        out.push(format!(
            "  stopped (the world's truth, below 0.01 m/s and 0.01 rad/s): {}, {}",
            stood("base", f.base_stopped_at_s),
            stood("arm", f.arm_stopped_at_s)
        ));
    } else if report.end != MissionEnd::Finished {
        if let Some(z) = report.commands.zero_since_s {
            out.push(format!(
                "  reaction: every base command zero from {}",
                at(z)
            ));
        }
    }

    out.push(format!(
        "  next: {} (logs in {})",
        next_step(report, reason),
        run_dir.display()
    ));
    out
}

fn end_name(end: MissionEnd) -> &'static str {
    match end {
        MissionEnd::Finished => "finished",
        MissionEnd::Aborted => "aborted",
        MissionEnd::ExecutiveDied => "the executive died",
        MissionEnd::TimedOut => "simulated time ran out",
        MissionEnd::NeverStarted => "never started",
    }
}

/// The executive's abort reason, from its `MissionAborted` event.
fn abort_reason(report: &WorldReport) -> Option<&'static str> {
    let e = report.events.iter().find(|e| e.kind == "MissionAborted")?;
    let first = e.detail.split([';', ':', ' ']).next().unwrap_or("");
    REASONS
        .iter()
        .copied()
        .find(|r| *r == first)
        .or_else(|| e.detail.contains("stuck").then_some("Stuck"))
}

/// Who notices what the abort reason names (docs/reliability.md).
fn noticer(reason: &str) -> &'static str {
    match reason {
        "BaseLinkLost" => {
            "the RMP driver (no readable feedback from the base for 250 ms), and the executive aborted"
        }
        "BaseFault" => {
            "the RMP driver (the base's fault word, or faster than commanded), and the executive aborted"
        }
        "SecondCommander" => {
            "the RMP driver (a motion command on the bus it did not send), and the executive aborted"
        }
        "ArmLinkLost" => "the UR5e driver (no RTDE state for 100 ms), and the executive aborted",
        "ArmStopped" => {
            "the UR5e driver (the controller's protective or emergency stop), and the executive aborted"
        }
        "PlannerLost" => "the executive (the planner's heartbeats stopped)",
        "ClockLost" => "the executive (the simulated clock went away)",
        "Shutdown" => "the executive (asked to stop by a signal)",
        "Stuck" => "the executive (legs kept failing: no way on from where the base stands)",
        _ => "the executive",
    }
}

/// What a person must do next: one line per case.
fn next_step(report: &WorldReport, reason: Option<&str>) -> &'static str {
    let kind = report
        .fault
        .as_ref()
        .filter(|f| f.injected_at_s.is_some())
        .map(|f| f.spec.split('@').next().unwrap_or("").to_owned());
    match (kind.as_deref(), reason) {
        (Some("kill-switch"), _) => {
            "release the base's kill switch, clear its fault (power-cycle the base), then restart the executive (an abort leaves it disarmed) and run the mission again"
        }
        (Some("emergency-stop"), _) => {
            "make the cell safe, release the emergency stop, power the arm on and release its brakes on the pendant, then restart the executive and run the mission again"
        }
        (Some("protective-stop" | "dashboard-late"), _) => {
            "find what the arm hit, unlock the protective stop on the pendant (re-enable the arm), then restart the executive and run the mission again"
        }
        (_, Some("BaseLinkLost")) => {
            "check the base's CAN link (cable, termination, the base powered on), then restart the executive (an abort leaves it disarmed) and run the mission again"
        }
        (_, Some("BaseFault")) => {
            "read the base's fault in the executive log, clear it (kill switch, power-cycle the base), then restart the executive and run the mission again"
        }
        (_, Some("SecondCommander")) => {
            "find the other host sending motion commands on the base's CAN bus and stop it, then restart the executive and run the mission again"
        }
        (_, Some("ArmLinkLost")) => {
            "check the arm's network link and that the controller is on and sending RTDE data, then restart the executive and run the mission again"
        }
        (_, Some("ArmStopped")) => {
            "clear the arm's stop on the pendant (protective: unlock; emergency: release it and power on), then restart the executive and run the mission again"
        }
        (_, Some("PlannerLost")) => {
            "see why the planner stopped (planner.log), then restart the onboard processes and run the mission again"
        }
        (_, Some("ClockLost")) => {
            "the world stopped first: see world.log, then run the mission again"
        }
        (_, Some("Shutdown")) => "it was asked to stop: run the mission again when ready",
        (_, Some("Stuck")) => {
            "clear the way for the base (see the contacts and the route in the picture), then run the mission again for the objects not placed"
        }
        _ => match report.end {
            MissionEnd::ExecutiveDied => {
                "see why the executive died (executive.log; the devices' own timeouts stopped the robot), then restart the onboard processes"
            }
            MissionEnd::TimedOut => {
                "the mission ran out of simulated time: look for where it waited in executive.log, or raise --max-sim-s"
            }
            MissionEnd::NeverStarted => "the onboard processes never joined: read their logs",
            MissionEnd::Finished if report.placed_end_state < report.objects.len() => {
                "the mission rode the fault out; put the objects left on the tray by hand or run the mission again for them"
            }
            MissionEnd::Finished => "nothing: the mission rode the fault out",
            MissionEnd::Aborted => {
                "read the executive log for the abort's cause, then run the mission again"
            }
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A report as the world writes it, with the given end, events and fault.
    fn report(end: &str, events: &[(f64, &str, &str)], fault: serde_json::Value) -> WorldReport {
        let events: Vec<_> = events
            .iter()
            .map(|(t, k, d)| serde_json::json!({"t_s": t, "kind": k, "plan_id": 1, "step": 3, "detail": d}))
            .collect();
        serde_json::from_value(serde_json::json!({
            "scene": "s", "seed": 1, "end": end, "placed": 0, "placed_end_state": 0,
            "objects": [], "collisions": [], "legs": [], "trajectory": [], "events": events,
            "plans": [], "deaths": [], "timing": {
                "sim_time_s": 50.0, "wall_time_s": 5.0, "steps": 1, "frames": 1,
                "world_step_us": 1.0, "request_to_plan_s": null, "plan_to_motion_s": null
            },
            "fault": fault
        }))
        .unwrap()
    }

    #[test]
    fn a_finished_mission_without_a_fault_needs_no_explanation() {
        let r = report("finished", &[], serde_json::Value::Null);
        assert!(explain(&r, Path::new("run")).is_empty());
    }

    #[test]
    fn an_arm_link_lost_names_the_fault_the_noticer_the_stop_times_and_the_next_step() {
        let r = report(
            "aborted",
            &[
                (10.0, "UnloadFailed", "before the fault: not listed"),
                (41.45, "LinkLost", "ArmLinkLost: base to zero, arm stopped"),
                (
                    41.45,
                    "MissionAborted",
                    "ArmLinkLost; restart the executive to re-arm",
                ),
            ],
            serde_json::json!({
                "spec": "rtde-silent@arm", "injected_at_s": 41.3, "base_speed_then_mps": 0.0,
                "arm_speed_then_radps": 0.3, "commanded_zero_at_s": 41.45,
                "first_zero_command_at_s": 41.45, "base_stopped_at_s": 41.3,
                "arm_stopped_at_s": 41.55,
                "can": {"dropped": 0, "duplicated": 0, "delayed": 0, "reordered": 0,
                        "corrupted": 0, "intruder": 0}
            }),
        );
        let text = explain(&r, Path::new("out/demo-run")).join("\n");
        for expected in [
            "why the mission ended (aborted):",
            "fault injected: rtde-silent@arm at 41.30 s",
            "fastest joint 0.30 rad/s then",
            "noticed by the UR5e driver (no RTDE state for 100 ms)",
            "41.45 s (+0.150 s) LinkLost: ArmLinkLost",
            "41.45 s (+0.150 s) MissionAborted",
            "every command zero from 41.45 s (+0.150 s)",
            "arm stood still at 41.55 s (+0.250 s)",
            "next: check the arm's network link",
            "(logs in out/demo-run)",
        ] {
            assert!(text.contains(expected), "no {expected:?} in:\n{text}");
        }
        assert!(!text.contains("before the fault"), "{text}");
        assert!(!text.contains("CAN frames"), "{text}");
    }

    #[test]
    fn a_stuck_base_without_a_fault_says_so_and_what_to_clear() {
        let r = report(
            "aborted",
            &[
                (158.74, "LegFinished", "leg failed"),
                (
                    166.8,
                    "MissionAborted",
                    "3 legs in a row failed: the base is stuck",
                ),
            ],
            serde_json::Value::Null,
        );
        let text = explain(&r, Path::new("run")).join("\n");
        assert!(text.contains("no fault was injected"), "{text}");
        assert!(
            text.contains("noticed by the executive (legs kept failing"),
            "{text}"
        );
        assert!(text.contains("166.80 s MissionAborted"), "{text}");
        assert!(text.contains("next: clear the way for the base"), "{text}");
    }

    #[test]
    fn the_kill_switch_and_can_counts_are_named() {
        let r = report(
            "aborted",
            &[
                (5.04, "BaseFault", "BaseFault: base to zero, arm stopped"),
                (
                    5.04,
                    "MissionAborted",
                    "BaseFault; restart the executive to re-arm",
                ),
            ],
            serde_json::json!({
                "spec": "kill-switch@driving", "injected_at_s": 5.0, "base_speed_then_mps": 0.31,
                "arm_speed_then_radps": 0.0, "commanded_zero_at_s": 5.04,
                "base_stopped_at_s": 5.07, "arm_stopped_at_s": null,
                "can": {"dropped": 3, "duplicated": 0, "delayed": 0, "reordered": 0,
                        "corrupted": 0, "intruder": 0}
            }),
        );
        let text = explain(&r, Path::new("run")).join("\n");
        assert!(text.contains("CAN frames: 3 dropped"), "{text}");
        assert!(
            text.contains("noticed by the RMP driver (the base's fault word"),
            "{text}"
        );
        assert!(text.contains("arm never came to rest"), "{text}");
        assert!(text.contains("no zero base command after it"), "{text}");
        assert!(
            text.contains("every command zero from 5.04 s (+0.040 s)"),
            "{text}"
        );
        assert!(
            text.contains("next: release the base's kill switch"),
            "{text}"
        );
    }
}
