//! The crate must stay free of std so that it builds for a microcontroller target
//! (`cargo build -p rmp-codec --target thumbv7em-none-eabihf` once that target is installed,
//! see docs/rmp.md). Without the target on this machine, check the source instead: the crate
//! root declares `#![no_std]` and nothing outside `#[cfg(test)]` names std.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::path::Path;

fn check_no_std(src: &Path) {
    let lib = std::fs::read_to_string(src.join("lib.rs")).expect("lib.rs readable");
    assert!(lib.contains("#![no_std]"), "lib.rs lacks #![no_std]");
    for entry in std::fs::read_dir(src).expect("src readable") {
        let path = entry.expect("dir entry").path();
        let text = std::fs::read_to_string(&path).expect("source readable");
        // Everything after the test module marker is test-only code.
        let shipped = text.split("#[cfg(test)]").next().unwrap_or("");
        for (n, line) in shipped.lines().enumerate() {
            let code = line.split("//").next().unwrap_or("");
            assert!(
                !code.contains("std::") && !code.contains("extern crate std"),
                "{}:{}: std used outside tests: {line}",
                path.display(),
                n + 1
            );
        }
    }
}

#[test]
fn codec_sources_do_not_use_std() {
    check_no_std(&Path::new(env!("CARGO_MANIFEST_DIR")).join("src"));
}
