//! Simulates a dataset in memory (no files) and prints its statistics as JSON: for studying
//! how the robot's settings move the success rate.
//! `cargo run --release -p trial-sim --example dataset_stats -- [robot.toml] [seed]`

fn main() -> std::process::ExitCode {
    let mut args = std::env::args().skip(1);
    let mut cfg = trial_sim::datagen::DatagenConfig::default();
    if let Some(path) = args.next() {
        match world::RobotConfig::load(&path) {
            Ok(robot) => cfg.robot = robot,
            Err(e) => {
                eprintln!("error: {e}");
                return std::process::ExitCode::FAILURE;
            }
        }
    }
    if let Some(seed) = args.next() {
        match seed.parse() {
            Ok(s) => cfg.seed = s,
            Err(e) => {
                eprintln!("error: seed `{seed}`: {e}");
                return std::process::ExitCode::FAILURE;
            }
        }
    }
    match trial_sim::datagen::simulate(&cfg, &trial_sim::datagen::NoProgress, true) {
        Ok(dataset) => match serde_json::to_string_pretty(&dataset.summary) {
            Ok(text) => {
                println!("{text}");
                std::process::ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!("error: {e}");
                std::process::ExitCode::FAILURE
            }
        },
        Err(e) => {
            eprintln!("error: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}
