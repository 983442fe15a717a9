//! Parser for the URScript subset the simulator executes.
//!
//! Supported: one `def name():` / `sec name():` program of straight-line statements (no
//! control flow, no nested functions) or bare one-line statements, each a call
//! `name(arg, key=arg, ...)` whose arguments are numbers, lists `[..]`, poses `p[..]`,
//! strings and `True`/`False`. The calls the simulator understands are in [`Statement`];
//! anything else rejects the whole program with a clear message, as the controller's compiler
//! would.

use thiserror::Error;

/// A parsed argument value.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    /// A number.
    Number(f64),
    /// A list of numbers `[..]`.
    List(Vec<f64>),
    /// A pose `p[..]`.
    Pose([f64; 6]),
    /// A string.
    Text(String),
    /// `True` / `False`.
    Bool(bool),
}

/// Target of a move: joints or a pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Target {
    /// Joint positions (rad).
    Joints([f64; 6]),
    /// TCP pose `p[x, y, z, rx, ry, rz]`.
    Pose([f64; 6]),
}

/// Action of `rtde_set_watchdog`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WatchdogAction {
    /// Only log.
    Ignore,
    /// Pause the program.
    Pause,
    /// Stop the program.
    Stop,
}

/// One executable statement.
#[derive(Debug, Clone, PartialEq)]
pub enum Statement {
    /// `movej(target, a, v)`.
    MoveJ {
        /// Target.
        target: Target,
        /// Acceleration (rad/s^2).
        accel: f64,
        /// Speed (rad/s).
        speed: f64,
    },
    /// `movel(target, a, v)`.
    MoveL {
        /// Target.
        target: Target,
        /// Acceleration (m/s^2).
        accel: f64,
        /// Speed (m/s).
        speed: f64,
    },
    /// `stopj(a)`.
    StopJ {
        /// Deceleration (rad/s^2).
        decel: f64,
    },
    /// `stopl(a)`: the simulator decelerates in joint space with the equivalent rate.
    StopL {
        /// Deceleration (m/s^2).
        decel: f64,
    },
    /// `speedj(qd, a, t)`.
    SpeedJ {
        /// Joint speeds (rad/s).
        qd: [f64; 6],
        /// Acceleration (rad/s^2).
        accel: f64,
        /// Duration (s); `None` = until the next statement replaces it.
        time_s: Option<f64>,
    },
    /// `sleep(t)`.
    Sleep {
        /// Seconds.
        time_s: f64,
    },
    /// `sync()`: wait one control cycle.
    Sync,
    /// `textmsg(..)`.
    TextMsg(String),
    /// `rtde_set_watchdog(name, f, action)`.
    RtdeWatchdog {
        /// Watched input.
        input: String,
        /// Minimum frequency (Hz); 0 disables.
        min_frequency_hz: f64,
        /// Action.
        action: WatchdogAction,
    },
    /// `set_tcp(p[..])`.
    SetTcp([f64; 6]),
    /// `set_standard_digital_out(n, b)`.
    SetStandardDigitalOut {
        /// Output 0..7.
        index: u8,
        /// Level.
        on: bool,
    },
    /// `set_tool_digital_out(n, b)`.
    SetToolDigitalOut {
        /// Output 0..1.
        index: u8,
        /// Level.
        on: bool,
    },
}

/// A parsed program.
#[derive(Debug, Clone, PartialEq)]
pub struct Program {
    /// Name from `def`, or `"<line>"` for bare statements.
    pub name: String,
    /// `sec` programs (secondary): no motion allowed.
    pub secondary: bool,
    /// Body.
    pub statements: Vec<Statement>,
}

/// Why a script was rejected.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum ScriptParseError {
    /// Empty text.
    #[error("empty script")]
    Empty,
    /// `def` without a matching final `end`, or a malformed header.
    #[error("program framing: {0}")]
    Framing(String),
    /// ur_rtde's control script (`def rtde_control():`): not URScript this parser runs; the
    /// simulator serves its register loop natively ([`parse_rtde_control`]).
    #[error(
        "ur_rtde control script (def rtde_control): served natively by its register loop, not parsed as URScript"
    )]
    UrRtdeControlScript,
    /// A line that is not a supported call.
    #[error("line {line}: {reason}: {text:?}")]
    Statement {
        /// 1-based line number.
        line: usize,
        /// Why.
        reason: String,
        /// The line.
        text: String,
    },
}

/// Parses a program sent to 30001/30002/30003.
pub fn parse_program(text: &str) -> Result<Program, ScriptParseError> {
    let lines: Vec<(usize, &str)> = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, strip_comment(l)))
        .filter(|(_, l)| !l.trim().is_empty())
        .collect();
    let (&(_, first), _) = lines.split_first().ok_or(ScriptParseError::Empty)?;
    let header = first.trim_end();
    let framed = header.starts_with("def ") || header.starts_with("sec ");
    if !framed {
        let statements = lines
            .iter()
            .map(|&(n, l)| parse_statement(n, l.trim()))
            .collect::<Result<Vec<_>, _>>()?;
        return Ok(Program {
            name: "<line>".into(),
            secondary: false,
            statements,
        });
    }
    let secondary = header.starts_with("sec ");
    let name = header[4..]
        .strip_suffix("():")
        .map(str::trim)
        .filter(|n| !n.is_empty() && n.chars().all(|c| c.is_ascii_alphanumeric() || c == '_'))
        .ok_or_else(|| {
            ScriptParseError::Framing(format!("header {header:?} is not `def name():`"))
        })?;
    if name == "rtde_control" {
        return Err(ScriptParseError::UrRtdeControlScript);
    }
    let (&(_, last), body) = lines[1..]
        .split_last()
        .ok_or_else(|| ScriptParseError::Framing("no `end`".into()))?;
    if last.trim_end() != "end" || last.starts_with(char::is_whitespace) {
        return Err(ScriptParseError::Framing(
            "last line must be `end` in column 1".into(),
        ));
    }
    let mut statements = Vec::with_capacity(body.len());
    for &(n, l) in body {
        if !l.starts_with(char::is_whitespace) {
            return Err(ScriptParseError::Statement {
                line: n,
                reason: "body lines must be indented".into(),
                text: l.into(),
            });
        }
        let s = parse_statement(n, l.trim())?;
        if secondary
            && matches!(
                s,
                Statement::MoveJ { .. }
                    | Statement::MoveL { .. }
                    | Statement::SpeedJ { .. }
                    | Statement::Sleep { .. }
            )
        {
            return Err(ScriptParseError::Statement {
                line: n,
                reason: "secondary programs may not move or sleep".into(),
                text: l.into(),
            });
        }
        statements.push(s);
    }
    Ok(Program {
        name: name.to_string(),
        secondary,
        statements,
    })
}

/// One step of the path ur_rtde injects into its control script (`moveJ(path)`, `moveL(path)`,
/// `movePath`).
#[derive(Debug, Clone, PartialEq)]
pub enum PathStep {
    /// `signal_async_progress(n)`: the async progress register reports waypoint `n`.
    Progress(i32),
    /// A `movej` / `movel` waypoint (its blend radius `r` is read and ignored: every waypoint
    /// ends at rest).
    Move(Statement),
}

/// What the simulator takes from ur_rtde's control script (`def rtde_control():`, ur_rtde
/// 1.6's `rtde_control.script`): the register offsets ur_rtde injected (0: registers 0-23,
/// 24: the upper range) and the path injected into `exec_move_path`. The rest of the script
/// (its command loop) is served natively by the simulator, command by command
/// (`docs/ur5e.md`).
#[derive(Debug, Clone, PartialEq)]
pub struct RtdeControlScript {
    /// Offset of the integer registers the script reads and writes.
    pub int_offset: usize,
    /// Offset of the double registers.
    pub float_offset: usize,
    /// The injected move path (empty when none).
    pub path: Vec<PathStep>,
}

/// Whether `text` is ur_rtde's control script: `def rtde_control():` with its command loop.
pub fn is_rtde_control(text: &str) -> bool {
    let header = text
        .lines()
        .map(|l| strip_comment(l).trim_end())
        .find(|l| !l.trim().is_empty());
    header == Some("def rtde_control():")
        && text.contains("def process_cmd(")
        && text.contains("def signal_ready():")
}

/// Reads ur_rtde's control script: its register offsets and its injected path.
///
/// The offsets follow `global reg_offset_int =` (ur_rtde injects the number after the comment
/// that ends that line, so it stands at the start of the next one). Errors name the line.
pub fn parse_rtde_control(text: &str) -> Result<RtdeControlScript, ScriptParseError> {
    if !is_rtde_control(text) {
        return Err(ScriptParseError::Framing(
            "not ur_rtde's control script (def rtde_control() with process_cmd and signal_ready)"
                .into(),
        ));
    }
    let offset = |name: &str| -> Result<usize, ScriptParseError> {
        let key = format!("global {name} =");
        let at = text
            .find(&key)
            .ok_or_else(|| ScriptParseError::Framing(format!("control script without `{key}`")))?;
        let line = text[..at].lines().count().max(1);
        let mut rest = &text[at + key.len()..];
        if let Some(after) = rest.trim_start_matches([' ', '\t']).strip_prefix('#') {
            rest = after.split_once('\n').map_or("", |(_, r)| r);
        }
        let digits: String = rest
            .trim_start()
            .chars()
            .take_while(char::is_ascii_digit)
            .collect();
        match digits.parse::<usize>() {
            Ok(v @ (0 | 24)) => Ok(v),
            _ => Err(ScriptParseError::Statement {
                line,
                reason: format!("{name} must be 0 or 24"),
                text: rest.lines().next().unwrap_or("").into(),
            }),
        }
    };
    let int_offset = offset("reg_offset_int")?;
    let float_offset = offset("reg_offset_float")?;
    let mut path = Vec::new();
    let mut in_path = false;
    for (i, raw) in text.lines().enumerate() {
        let l = strip_comment(raw).trim();
        if !in_path {
            // ur_rtde's injected offset may stand in front of the line.
            in_path = l.ends_with("def exec_move_path():");
            continue;
        }
        if l == "end" {
            break;
        }
        if l.is_empty() || l.starts_with("textmsg(") {
            continue;
        }
        if let Some(n) = l
            .strip_prefix("signal_async_progress(")
            .and_then(|r| r.strip_suffix(')'))
        {
            let n = n
                .trim()
                .parse::<i32>()
                .map_err(|_| ScriptParseError::Statement {
                    line: i + 1,
                    reason: "progress must be an integer".into(),
                    text: l.into(),
                })?;
            path.push(PathStep::Progress(n));
            continue;
        }
        match parse_statement(i + 1, l)? {
            s @ (Statement::MoveJ { .. } | Statement::MoveL { .. }) => path.push(PathStep::Move(s)),
            _ => {
                return Err(ScriptParseError::Statement {
                    line: i + 1,
                    reason: "a move path holds movej and movel only in this simulator".into(),
                    text: l.into(),
                });
            }
        }
    }
    Ok(RtdeControlScript {
        int_offset,
        float_offset,
        path,
    })
}

fn strip_comment(line: &str) -> &str {
    let mut in_str = false;
    for (i, c) in line.char_indices() {
        match c {
            '"' => in_str = !in_str,
            '#' if !in_str => return &line[..i],
            _ => {}
        }
    }
    line
}

/// Splits `a, [b, c], p[d], "e,f"` at top-level commas.
fn split_args(s: &str) -> Vec<&str> {
    let mut out = Vec::new();
    let (mut depth, mut in_str, mut start) = (0i32, false, 0);
    for (i, c) in s.char_indices() {
        match c {
            '"' => in_str = !in_str,
            '[' | '(' if !in_str => depth += 1,
            ']' | ')' if !in_str => depth -= 1,
            ',' if !in_str && depth == 0 => {
                out.push(s[start..i].trim());
                start = i + 1;
            }
            _ => {}
        }
    }
    let tail = s[start..].trim();
    if !tail.is_empty() || !out.is_empty() {
        out.push(tail);
    }
    out
}

fn parse_number(s: &str) -> Option<f64> {
    match s.trim() {
        "pi" => Some(std::f64::consts::PI),
        "-pi" => Some(-std::f64::consts::PI),
        t => t.parse::<f64>().ok().filter(|v| v.is_finite()),
    }
}

fn parse_value(s: &str) -> Option<Value> {
    let s = s.trim();
    if let Some(inner) = s.strip_prefix("p[").and_then(|r| r.strip_suffix(']')) {
        let v: Option<Vec<f64>> = split_args(inner).into_iter().map(parse_number).collect();
        let v = v?;
        return <[f64; 6]>::try_from(v.as_slice()).ok().map(Value::Pose);
    }
    if let Some(inner) = s.strip_prefix('[').and_then(|r| r.strip_suffix(']')) {
        let v: Option<Vec<f64>> = split_args(inner).into_iter().map(parse_number).collect();
        return v.map(Value::List);
    }
    if let Some(inner) = s.strip_prefix('"').and_then(|r| r.strip_suffix('"')) {
        return Some(Value::Text(inner.into()));
    }
    match s {
        "True" | "true" => return Some(Value::Bool(true)),
        "False" | "false" => return Some(Value::Bool(false)),
        _ => {}
    }
    parse_number(s).map(Value::Number)
}

struct Args {
    positional: Vec<Value>,
    named: Vec<(String, Value)>,
}

impl Args {
    /// Argument `name` at position `pos`, by keyword or position.
    fn get(&self, pos: usize, name: &str) -> Option<&Value> {
        self.named
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v)
            .or_else(|| self.positional.get(pos))
    }

    fn number(&self, pos: usize, name: &str, default: Option<f64>) -> Result<f64, String> {
        match self.get(pos, name) {
            Some(Value::Number(v)) => Ok(*v),
            Some(other) => Err(format!("argument {name} must be a number, got {other:?}")),
            None => default.ok_or_else(|| format!("missing argument {name}")),
        }
    }

    fn six(&self, pos: usize, name: &str) -> Result<[f64; 6], String> {
        match self.get(pos, name) {
            Some(Value::List(v)) => <[f64; 6]>::try_from(v.as_slice())
                .map_err(|_| format!("{name} needs 6 numbers, got {}", v.len())),
            Some(other) => Err(format!(
                "argument {name} must be a list of 6, got {other:?}"
            )),
            None => Err(format!("missing argument {name}")),
        }
    }

    fn target(&self, pos: usize, name: &str) -> Result<Target, String> {
        match self.get(pos, name) {
            Some(Value::Pose(p)) => Ok(Target::Pose(*p)),
            Some(Value::List(_)) => self.six(pos, name).map(Target::Joints),
            Some(other) => Err(format!(
                "argument {name} must be joints or a pose, got {other:?}"
            )),
            None => Err(format!("missing argument {name}")),
        }
    }

    fn text(&self, pos: usize, name: &str) -> Result<String, String> {
        match self.get(pos, name) {
            Some(Value::Text(t)) => Ok(t.clone()),
            Some(Value::Number(v)) => Ok(v.to_string()),
            Some(other) => Err(format!("argument {name} must be a string, got {other:?}")),
            None => Err(format!("missing argument {name}")),
        }
    }

    fn flag(&self, pos: usize, name: &str) -> Result<bool, String> {
        match self.get(pos, name) {
            Some(Value::Bool(b)) => Ok(*b),
            Some(Value::Number(v)) => Ok(*v != 0.0),
            Some(other) => Err(format!("argument {name} must be a bool, got {other:?}")),
            None => Err(format!("missing argument {name}")),
        }
    }
}

fn positive(v: f64, name: &str) -> Result<f64, String> {
    if v > 0.0 {
        Ok(v)
    } else {
        Err(format!("{name} must be positive, got {v}"))
    }
}

#[allow(clippy::too_many_lines, reason = "one arm per URScript statement")]
fn parse_statement(line: usize, text: &str) -> Result<Statement, ScriptParseError> {
    let fail = |reason: String| ScriptParseError::Statement {
        line,
        reason,
        text: text.into(),
    };
    let open = text
        .find('(')
        .ok_or_else(|| fail("not a function call".into()))?;
    let name = text[..open].trim();
    let inner = text[open + 1..]
        .trim_end()
        .strip_suffix(')')
        .ok_or_else(|| fail("missing closing parenthesis".into()))?;
    let mut args = Args {
        positional: Vec::new(),
        named: Vec::new(),
    };
    for raw in split_args(inner) {
        let (key, value_text) = match raw.split_once('=') {
            Some((k, v))
                if k.trim()
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '_')
                    && !k.trim().is_empty() =>
            {
                (Some(k.trim()), v)
            }
            _ => (None, raw),
        };
        let value = parse_value(value_text)
            .ok_or_else(|| fail(format!("cannot parse argument {raw:?}")))?;
        match key {
            Some(k) => args.named.push((k.to_string(), value)),
            None => args.positional.push(value),
        }
    }
    let stmt = match name {
        "movej" => Statement::MoveJ {
            target: args.target(0, "q").map_err(fail)?,
            accel: positive(args.number(1, "a", Some(1.4)).map_err(fail)?, "a").map_err(fail)?,
            speed: positive(args.number(2, "v", Some(1.05)).map_err(fail)?, "v").map_err(fail)?,
        },
        "movel" => Statement::MoveL {
            target: args.target(0, "pose").map_err(fail)?,
            accel: positive(args.number(1, "a", Some(1.2)).map_err(fail)?, "a").map_err(fail)?,
            speed: positive(args.number(2, "v", Some(0.25)).map_err(fail)?, "v").map_err(fail)?,
        },
        "stopj" => Statement::StopJ {
            decel: positive(args.number(0, "a", None).map_err(fail)?, "a").map_err(fail)?,
        },
        "stopl" => Statement::StopL {
            decel: positive(args.number(0, "a", None).map_err(fail)?, "a").map_err(fail)?,
        },
        "speedj" => Statement::SpeedJ {
            qd: args.six(0, "qd").map_err(fail)?,
            accel: positive(args.number(1, "a", None).map_err(fail)?, "a").map_err(fail)?,
            time_s: match args.get(2, "t") {
                Some(_) => {
                    Some(positive(args.number(2, "t", None).map_err(fail)?, "t").map_err(fail)?)
                }
                None => None,
            },
        },
        "sleep" => Statement::Sleep {
            time_s: args.number(0, "t", None).map_err(fail)?.max(0.0),
        },
        "sync" => Statement::Sync,
        "textmsg" => {
            let mut s = args.text(0, "s1").map_err(fail)?;
            if args.positional.len() > 1 {
                s.push_str(&args.text(1, "s2").map_err(fail)?);
            }
            Statement::TextMsg(s)
        }
        "rtde_set_watchdog" => Statement::RtdeWatchdog {
            input: args.text(0, "variable_name").map_err(fail)?,
            min_frequency_hz: args.number(1, "min_frequency", None).map_err(fail)?,
            action: match args.get(2, "action") {
                None => WatchdogAction::Pause,
                Some(Value::Text(a)) => match a.as_str() {
                    "ignore" => WatchdogAction::Ignore,
                    "pause" => WatchdogAction::Pause,
                    "stop" => WatchdogAction::Stop,
                    other => return Err(fail(format!("unknown watchdog action {other:?}"))),
                },
                Some(other) => {
                    return Err(fail(format!(
                        "watchdog action must be a string, got {other:?}"
                    )));
                }
            },
        },
        "set_tcp" => match args.get(0, "pose") {
            Some(Value::Pose(p)) => Statement::SetTcp(*p),
            _ => return Err(fail("set_tcp needs a pose p[...]".into())),
        },
        "set_standard_digital_out" | "set_tool_digital_out" => {
            let n = args.number(0, "n", None).map_err(fail)?;
            let limit = if name == "set_tool_digital_out" {
                2.0
            } else {
                8.0
            };
            if !(0.0..limit).contains(&n) || n.fract() != 0.0 {
                return Err(fail(format!("output index {n} out of range")));
            }
            let on = args.flag(1, "b").map_err(fail)?;
            if name == "set_tool_digital_out" {
                Statement::SetToolDigitalOut { index: n as u8, on }
            } else {
                Statement::SetStandardDigitalOut { index: n as u8, on }
            }
        }
        other => {
            return Err(fail(format!(
                "function {other:?} is not supported by the simulator"
            )));
        }
    };
    Ok(stmt)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn driver_program_parses() {
        let text = "def grop_motion():\n  rtde_set_watchdog(\"input_int_register_24\", 10, \"stop\")\n  \
                    movej([0, -1.5, 1.25, -0.5, 0, 0.125], a=1.4, v=1.05)\nend\n";
        let p = parse_program(text).unwrap();
        assert_eq!(p.name, "grop_motion");
        assert_eq!(
            p.statements[1],
            Statement::MoveJ {
                target: Target::Joints([0.0, -1.5, 1.25, -0.5, 0.0, 0.125]),
                accel: 1.4,
                speed: 1.05
            }
        );
        assert!(matches!(
            p.statements[0],
            Statement::RtdeWatchdog {
                action: WatchdogAction::Stop,
                ..
            }
        ));
    }

    #[test]
    fn bare_lines_and_positional_arguments() {
        let p = parse_program("movel(p[0.1, 0.2, 0.3, 0, 3.14, 0], 1.2, 0.25)\nstopj(2) # stop\n")
            .unwrap();
        assert_eq!(p.statements.len(), 2);
        assert_eq!(p.statements[1], Statement::StopJ { decel: 2.0 });
    }

    #[test]
    fn bad_scripts_are_rejected_with_line_numbers() {
        assert!(matches!(
            parse_program("def a():\n  foo(1)\nend\n"),
            Err(ScriptParseError::Statement { line: 2, .. })
        ));
        assert!(matches!(
            parse_program("def a():\n  sleep(1)\n"),
            Err(ScriptParseError::Framing(_))
        ));
        assert!(matches!(
            parse_program("def rtde_control():\n  sleep(1)\nend\n"),
            Err(ScriptParseError::UrRtdeControlScript)
        ));
        assert!(parse_program("movej([1, 2, 3], a=1, v=1)").is_err());
        assert!(parse_program("movej([0,0,0,0,0,0], a=-1, v=1)").is_err());
        assert!(parse_program("sec s():\n  movej([0,0,0,0,0,0])\nend").is_err());
        assert!(parse_program("").is_err());
    }
}

#[cfg(test)]
mod properties {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// Script text from a client never panics the parser.
        #[test]
        fn parser_never_panics(text in "(def a\\(\\):\n)?( *[a-z_]{1,8}\\([-0-9.,\\[\\]p\" =a-z]{0,30}\\)\n){0,4}(end\n)?") {
            let _ = parse_program(&text);
        }

        #[test]
        fn parser_never_panics_on_any_string(text in "\\PC{0,200}") {
            let _ = parse_program(&text);
        }
    }
}
