//! The simulated controller's URScript parser (`hil-tests/simulators/sim-ur5e/src/urscript.rs`): arbitrary
//! text, and the programs the driver's script writer (`drivers/ur5e/src/script.rs`) produces.

use sim_ur5e::urscript::{self, Program, Statement, Target};
use ur5e::TcpPose;
use ur5e::script::{ScriptCommand, UrScriptProgram, WatchdogAction};

use crate::bytes::Bytes;

/// First byte even: the rest is script text for the parser, and whatever parses keeps the
/// promises of the statement types (finite numbers, positive rates, no motion in a `sec`
/// program, outputs in range). Odd: the rest builds a program with the driver's typed commands;
/// whatever the driver writes, the simulator parses back to the same commands and numbers.
pub fn urscript(data: &[u8]) {
    let mut b = Bytes::new(data);
    if b.u8() % 2 == 0 {
        let text = String::from_utf8_lossy(b.rest());
        match urscript::parse_program(&text) {
            Ok(program) => check_program(&program, &text),
            Err(e) => {
                let _ = e.to_string();
            }
        }
    } else {
        writer_round_trip(&mut b);
    }
}

fn check_program(p: &Program, text: &str) {
    let lines = text.lines().filter(|l| !l.trim().is_empty()).count();
    assert!(p.statements.len() <= lines);
    if p.name != "<line>" {
        assert!(!p.name.is_empty());
        assert!(
            p.name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_')
        );
    }
    let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
    for s in &p.statements {
        match s {
            Statement::MoveJ {
                target,
                accel,
                speed,
            }
            | Statement::MoveL {
                target,
                accel,
                speed,
            } => {
                let (Target::Joints(v) | Target::Pose(v)) = target;
                assert!(finite(v) && *accel > 0.0 && *speed > 0.0, "{s:?}");
                assert!(accel.is_finite() && speed.is_finite(), "{s:?}");
            }
            Statement::StopJ { decel } | Statement::StopL { decel } => {
                assert!(decel.is_finite() && *decel > 0.0, "{s:?}");
            }
            Statement::SpeedJ { qd, accel, time_s } => {
                assert!(finite(qd) && accel.is_finite() && *accel > 0.0, "{s:?}");
                assert!(time_s.is_none_or(|t| t.is_finite() && t > 0.0), "{s:?}");
            }
            Statement::Sleep { time_s } => assert!(time_s.is_finite() && *time_s >= 0.0),
            Statement::RtdeWatchdog {
                min_frequency_hz, ..
            } => assert!(min_frequency_hz.is_finite()),
            Statement::SetTcp(pose) => assert!(finite(pose)),
            Statement::SetStandardDigitalOut { index, .. } => assert!(*index < 8),
            Statement::SetToolDigitalOut { index, .. } => assert!(*index < 2),
            Statement::Sync | Statement::TextMsg(_) => {}
        }
        if p.secondary {
            assert!(
                !matches!(
                    s,
                    Statement::MoveJ { .. }
                        | Statement::MoveL { .. }
                        | Statement::SpeedJ { .. }
                        | Statement::Sleep { .. }
                ),
                "secondary program moves: {s:?}"
            );
        }
    }
}

/// A number: mostly small values with few digits, sometimes any bit pattern (NaN, infinities,
/// subnormals, huge values).
fn number(b: &mut Bytes<'_>) -> f64 {
    let tag = b.u8();
    if tag & 0x80 != 0 {
        b.f64()
    } else {
        f64::from(i16::from_be_bytes([tag, b.u8()])) / 64.0
    }
}

fn six(b: &mut Bytes<'_>) -> [f64; 6] {
    std::array::from_fn(|_| number(b))
}

fn text(b: &mut Bytes<'_>) -> String {
    let n = usize::from(b.u8() % 24);
    String::from_utf8_lossy(b.take(n)).into_owned()
}

fn command(b: &mut Bytes<'_>) -> ScriptCommand {
    match b.u8() % 9 {
        0 => ScriptCommand::MoveJ {
            q_rad: six(b),
            accel_radps2: number(b),
            speed_radps: number(b),
        },
        1 => ScriptCommand::MoveL {
            pose: TcpPose::from_array(six(b)),
            accel_mps2: number(b),
            speed_mps: number(b),
        },
        2 => ScriptCommand::StopJ {
            decel_radps2: number(b),
        },
        3 => ScriptCommand::StopL {
            decel_mps2: number(b),
        },
        4 => ScriptCommand::SpeedJ {
            qd_radps: six(b),
            accel_radps2: number(b),
            time_s: number(b),
        },
        5 => ScriptCommand::SetTcp(TcpPose::from_array(six(b))),
        6 => ScriptCommand::Sleep { time_s: number(b) },
        7 => ScriptCommand::TextMsg(text(b)),
        _ => ScriptCommand::RtdeWatchdog {
            input: text(b),
            min_frequency_hz: number(b),
            action: match b.u8() % 3 {
                0 => WatchdogAction::Ignore,
                1 => WatchdogAction::Pause,
                _ => WatchdogAction::Stop,
            },
        },
    }
}

/// What the simulator must read for `c`.
fn expected(c: &ScriptCommand) -> Statement {
    match c {
        ScriptCommand::MoveJ {
            q_rad,
            accel_radps2,
            speed_radps,
        } => Statement::MoveJ {
            target: Target::Joints(*q_rad),
            accel: *accel_radps2,
            speed: *speed_radps,
        },
        ScriptCommand::MoveL {
            pose,
            accel_mps2,
            speed_mps,
        } => Statement::MoveL {
            target: Target::Pose(pose.as_array()),
            accel: *accel_mps2,
            speed: *speed_mps,
        },
        ScriptCommand::StopJ { decel_radps2 } => Statement::StopJ {
            decel: *decel_radps2,
        },
        ScriptCommand::StopL { decel_mps2 } => Statement::StopL { decel: *decel_mps2 },
        ScriptCommand::SpeedJ {
            qd_radps,
            accel_radps2,
            time_s,
        } => Statement::SpeedJ {
            qd: *qd_radps,
            accel: *accel_radps2,
            time_s: Some(*time_s),
        },
        ScriptCommand::SetTcp(pose) => Statement::SetTcp(pose.as_array()),
        ScriptCommand::Sleep { time_s } => Statement::Sleep { time_s: *time_s },
        ScriptCommand::TextMsg(t) => Statement::TextMsg(t.clone()),
        ScriptCommand::RtdeWatchdog {
            input,
            min_frequency_hz,
            action,
        } => Statement::RtdeWatchdog {
            input: input.clone(),
            min_frequency_hz: *min_frequency_hz,
            action: match action {
                WatchdogAction::Ignore => urscript::WatchdogAction::Ignore,
                WatchdogAction::Pause => urscript::WatchdogAction::Pause,
                WatchdogAction::Stop => urscript::WatchdogAction::Stop,
            },
        },
    }
}

fn writer_round_trip(b: &mut Bytes<'_>) {
    let name = if b.u8() % 4 == 0 {
        text(b)
    } else {
        "grop_motion".to_owned()
    };
    let count = usize::from(b.u8() % 8);
    let commands: Vec<ScriptCommand> = (0..count).map(|_| command(b)).collect();
    let program = UrScriptProgram::new(name, commands);
    let Ok(script) = program.to_script() else {
        return;
    };
    // The simulator does not emulate ur_rtde's control script (a documented limit).
    if program.name == "rtde_control" {
        return;
    }
    let parsed = match urscript::parse_program(&script) {
        Ok(p) => p,
        Err(e) => panic!("the driver's program does not parse: {e}\n{script}"),
    };
    assert_eq!(parsed.name, program.name);
    assert!(!parsed.secondary);
    let expected: Vec<Statement> = program.commands.iter().map(expected).collect();
    assert_eq!(parsed.statements, expected, "{script}");
    check_program(&parsed, &script);
}
