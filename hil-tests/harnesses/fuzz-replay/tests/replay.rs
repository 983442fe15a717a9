//! Replays every committed fuzz corpus file (`fuzz/corpus/<target>/`) and every seed through the
//! target bodies, on stable, so that CI catches a regression on an input the fuzzer once found
//! interesting without running the fuzzer (docs/fuzzing.md).

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};

use fuzz_replay::{seeds::seeds, targets};

fn corpus_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../fuzz/corpus")
}

/// The files of one target's corpus, sorted.
fn corpus_files(target: &str) -> Vec<PathBuf> {
    let dir = corpus_root().join(target);
    let Ok(entries) = std::fs::read_dir(&dir) else {
        return Vec::new();
    };
    let mut files: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file())
        .collect();
    files.sort();
    files
}

/// Runs `body` on each input; returns the names of those that panicked.
fn replay(body: fn(&[u8]), inputs: Vec<(String, Vec<u8>)>) -> Vec<String> {
    inputs
        .into_iter()
        .filter(|(_, bytes)| catch_unwind(AssertUnwindSafe(|| body(bytes))).is_err())
        .map(|(name, _)| name)
        .collect()
}

#[test]
fn every_corpus_folder_belongs_to_a_target() {
    let Ok(entries) = std::fs::read_dir(corpus_root()) else {
        panic!("no corpus folder at {}", corpus_root().display());
    };
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        assert!(
            targets().iter().any(|(t, _)| *t == name),
            "fuzz/corpus/{name} has no target in fuzz_replay::targets()"
        );
    }
}

#[test]
fn committed_corpora_and_seeds_replay_without_a_failure() {
    let seeds = seeds();
    let failures: Vec<String> = std::thread::scope(|scope| {
        let handles: Vec<_> = targets()
            .into_iter()
            .map(|(name, body)| {
                let mut inputs: Vec<(String, Vec<u8>)> = corpus_files(name)
                    .into_iter()
                    .map(|p| {
                        let bytes =
                            std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
                        (p.display().to_string(), bytes)
                    })
                    .collect();
                assert!(
                    !inputs.is_empty(),
                    "target {name} has no committed corpus in fuzz/corpus/{name}"
                );
                let target_seeds = seeds
                    .iter()
                    .find(|(t, _)| *t == name)
                    .map(|(_, s)| s.clone())
                    .unwrap_or_default();
                assert!(!target_seeds.is_empty(), "target {name} has no seeds");
                inputs.extend(
                    target_seeds
                        .into_iter()
                        .enumerate()
                        .map(|(k, bytes)| (format!("seed {k} of {name}"), bytes)),
                );
                scope.spawn(move || replay(body, inputs))
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().unwrap_or_else(|_| vec!["a replay thread".into()]))
            .collect()
    });
    assert!(failures.is_empty(), "failing inputs: {failures:#?}");
}

/// The seeds are what they claim to be: valid inputs that reach each decoder's success path (a
/// format change that silently turned them into rejected inputs would leave the fuzzer to start
/// from nothing).
#[test]
fn seeds_are_valid_inputs() {
    let seeds = seeds();
    let of = |target: &str| -> Vec<Vec<u8>> {
        seeds
            .iter()
            .find(|(t, _)| *t == target)
            .map(|(_, s)| s.clone())
            .unwrap_or_default()
    };
    for seed in of("scene_file").iter().filter(|s| s[0] == 0) {
        let text = String::from_utf8_lossy(&seed[1..]);
        let loaded = world::Scene::from_toml_str(&text, "seed.toml");
        assert!(loaded.is_ok(), "{loaded:?}");
    }
    for seed in of("robot_file").iter().filter(|s| s[0] == 0) {
        let text = String::from_utf8_lossy(&seed[1..]);
        let loaded = world::RobotConfig::from_toml_str(&text, "seed.toml");
        assert!(loaded.is_ok(), "{loaded:?}");
    }
    for seed in of("deployment_file") {
        let text = String::from_utf8_lossy(&seed);
        let loaded = grop_onboard::deployment::Deployment::from_toml_str(
            &text,
            Path::new("/etc/grop/deployment.toml"),
        );
        assert!(loaded.is_ok(), "{loaded:?}");
    }
    for seed in of("urscript").iter().filter(|s| s[0] == 0) {
        let text = String::from_utf8_lossy(&seed[1..]);
        let parsed = sim_ur5e::urscript::parse_program(&text);
        assert!(parsed.is_ok(), "{parsed:?}");
    }
    for seed in &of("candump_text")[..6] {
        let text = String::from_utf8_lossy(seed);
        assert!(text.parse::<can_bus::CanFrame>().is_ok(), "{text}");
    }
    for seed in of("can_wire_frame").iter().take(4) {
        assert!(can_bus::fuzz_decode_wire_frame(seed).is_ok());
    }
    for seed in of("rmp_packet") {
        assert!(rmp_codec::packet::decode_command(&seed).is_ok());
    }
    for seed in of("mission_log") {
        if seed[0] == 0 {
            let log = grop_onboard::mission_log::MissionLog::from_bytes(
                &seed[1..],
                Path::new("seed.mcap"),
            );
            assert!(log.is_ok_and(|l| l.messages.len() == 6 && l.truncated.is_none()));
        }
    }
    for seed in of("vlp16_packet") {
        let packets = seed[fuzz_replay::VLP16_HEADER_LEN..].chunks(1206);
        let good = packets
            .filter(|p| vlp16::DataPacket::decode(p).is_ok())
            .count();
        assert!(
            good >= 2,
            "a VLP-16 seed has at least two packets that decode"
        );
    }
    let models = of("model_loader");
    for model in [&models[0], &models[5]] {
        let loaded = fcn_infer::FcnModel::from_bytes(model, Path::new("seed.onnx"));
        assert!(loaded.is_ok(), "{loaded:?}");
    }
}
