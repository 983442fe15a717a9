//! The dashboard server (port 29999): one text command per line.

use super::*;

pub(super) fn dashboard_connection(shared: &Arc<Shared>, stream: TcpStream) -> io::Result<()> {
    let mut writer = stream.try_clone()?;
    writer.write_all(b"Connected: Universal Robots Dashboard Server\n")?;
    let mut reader = BufReader::new(stream);
    let mut line = String::new();
    let mut loaded: Option<String> = None;
    loop {
        line.clear();
        // Bounded: a client cannot make the controller buffer without end.
        if (&mut reader).take(4096).read_line(&mut line)? == 0 {
            return Ok(());
        }
        let command = line.trim_end_matches(['\n', '\r']).trim();
        let reply = dashboard_reply(shared, command, &mut loaded);
        let delay_ms = shared
            .link_faults
            .dashboard_delay_ms
            .load(Ordering::Relaxed);
        if delay_ms > 0 {
            std::thread::sleep(Duration::from_millis(delay_ms));
        }
        writer.write_all(reply.as_bytes())?;
        writer.write_all(b"\n")?;
        if command == "quit" {
            let _ = writer.shutdown(Shutdown::Both);
            return Ok(());
        }
    }
}

#[allow(clippy::too_many_lines, reason = "one arm per dashboard command")]
pub(super) fn dashboard_reply(
    shared: &Arc<Shared>,
    command: &str,
    loaded: &mut Option<String>,
) -> String {
    let cfg = &shared.cfg;
    let mut ctl = lock(&shared.ctl);
    let robot = &mut ctl.robot;
    let program_name = || -> String { loaded.clone().unwrap_or_else(|| "<unnamed>".into()) };
    if let Some(file) = command.strip_prefix("load installation ") {
        return format!("Loading installation: {file}");
    }
    if let Some(file) = command.strip_prefix("load ") {
        return if cfg.programs.iter().any(|p| p == file) {
            *loaded = Some(file.to_string());
            format!("Loading program: {file}")
        } else {
            format!("File not found: {file}")
        };
    }
    if command.starts_with("popup ") {
        return "showing popup".into();
    }
    if let Some(text) = command.strip_prefix("addToLog ") {
        log::info!("sim-ur5e dashboard log: {text}");
        return "Added log message".into();
    }
    if let Some(mode) = command.strip_prefix("set operational mode ") {
        return format!("Operational mode {mode} is set");
    }
    if let Some(role) = command.strip_prefix("setUserRole ") {
        return format!("Setting user role: {role}");
    }
    match command {
        "power on" => {
            robot.power_on();
            "Powering on".into()
        }
        "power off" => {
            robot.power_off();
            "Powering off".into()
        }
        "brake release" => {
            robot.brake_release();
            "Brake releasing".into()
        }
        "play"
            if loaded.is_some()
                && cfg.urcap_script_sender.is_some()
                && robot.runtime_state() == crate::robot::runtime_state::STOPPED =>
        {
            // The loaded program is the External Control URCap's: it asks the script sender.
            if let Some(addr) = cfg.urcap_script_sender {
                request_urcap_program(shared, addr);
            }
            "Starting program".into()
        }
        "play" => {
            if robot.play() {
                "Starting program".into()
            } else {
                "Failed to execute: play".into()
            }
        }
        "stop" => {
            robot.dashboard_stop();
            "Stopped".into()
        }
        "pause" => {
            if robot.pause() {
                "Pausing program".into()
            } else {
                "Failed to execute: pause".into()
            }
        }
        "unlock protective stop" => {
            robot.unlock_protective_stop();
            "Protective stop releasing".into()
        }
        "close popup" => "closing popup".into(),
        "close safety popup" => "closing safety popup".into(),
        "restart safety" => "Restarting safety".into(),
        "robotmode" => format!(
            "Robotmode: {}",
            ur5e::dashboard::RobotMode::from_code(robot.robot_mode())
                .map_or("NO_CONTROLLER", |m| m.name())
        ),
        "safetystatus" | "safetymode" => {
            let name = ur5e::dashboard::SafetyMode::from_code(robot.safety_mode())
                .map_or("UNDEFINED_SAFETY_MODE", |m| m.name());
            if command == "safetystatus" {
                format!("Safetystatus: {name}")
            } else {
                format!("Safetymode: {name}")
            }
        }
        "programState" => {
            let name = robot
                .program_name()
                .map(str::to_string)
                .unwrap_or_else(program_name);
            match robot.runtime_state() {
                2 => format!("PLAYING {name}"),
                4 => format!("PAUSED {name}"),
                _ => format!("STOPPED {name}"),
            }
        }
        "running" => format!("Program running: {}", robot.runtime_state() == 2),
        "get loaded program" => match loaded {
            Some(p) => format!("Loaded program: {p}"),
            None => "No program loaded".into(),
        },
        "isProgramSaved" => format!("true {}", program_name()),
        "PolyscopeVersion" => format!("URSoftware {} (Jan 01 2025)", cfg.version),
        "version" => cfg.version.to_string(),
        "get serial number" => cfg.serial_number.clone(),
        "get robot model" => "UR5".into(),
        "is in remote control" => cfg.remote_control.to_string(),
        "get operational mode" => "NONE".into(),
        "clear operational mode" => {
            "No longer controlling the operational mode. Current operational mode: 'NONE'.".into()
        }
        "getUserRole" => "PROGRAMMER".into(),
        "quit" => "Disconnected".into(),
        "shutdown" => {
            robot.power_off();
            "Shutting down".into()
        }
        other => format!("could not understand: '{other}'"),
    }
}
