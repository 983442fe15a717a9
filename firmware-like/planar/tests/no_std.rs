//! The crate must stay free of std without its `std` feature, so that motion-control still
//! builds for a microcontroller (docs/rmp.md). Without that target on this machine, check the
//! source: the crate root declares `#![no_std]`, and outside `#[cfg(test)]` the one mention of
//! std is the `extern crate std` that the `std` feature (or the tests) turn on.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use std::path::Path;

#[test]
fn sources_do_not_use_std_unless_the_feature_asks() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let lib = std::fs::read_to_string(src.join("lib.rs")).expect("lib.rs readable");
    assert!(lib.contains("#![no_std]"), "lib.rs lacks #![no_std]");
    for entry in std::fs::read_dir(&src).expect("src readable") {
        let path = entry.expect("dir entry").path();
        let text = std::fs::read_to_string(&path).expect("source readable");
        // Everything after the test module marker is test-only code.
        let shipped = text.split("#[cfg(test)]").next().unwrap_or("");
        let mut previous = "";
        for (n, line) in shipped.lines().enumerate() {
            let code = line.split("//").next().unwrap_or("");
            let gated = code.trim() == "extern crate std;"
                && previous.trim() == "#[cfg(any(feature = \"std\", test))]";
            assert!(
                gated || (!code.contains("std::") && !code.contains("extern crate std")),
                "{}:{}: std used outside tests and the std feature: {line}",
                path.display(),
                n + 1
            );
            previous = code;
        }
    }
}
