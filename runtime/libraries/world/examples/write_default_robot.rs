//! Writes `RobotConfig::default()` as TOML to stdout: regenerates `data/robot.toml` after the
//! defaults change (`cargo run -p world --example write_default_robot > runtime/libraries/world/data/robot.toml`).

fn main() -> std::process::ExitCode {
    match world::RobotConfig::default().to_toml_string() {
        Ok(text) => {
            print!(
                "# The paper's robot (RobotConfig::default()); format in docs/world.md.\n{text}"
            );
            std::process::ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}
