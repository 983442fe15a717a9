//! The onboard processes' deployment file (`runtime/onboard/src/deployment.rs`), as text.

use std::path::Path;

use grop_onboard::deployment::{CanSpec, Deployment};

/// The onboard processes' deployment file: whatever loads is valid, its relative paths are
/// resolved against the file's folder, and its CAN spec prints back as a spec that parses to it.
pub fn deployment_file(data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    let path = Path::new("/etc/grop/deployment.toml");
    let deployment = match Deployment::from_toml_str(&text, path) {
        Ok(d) => d,
        Err(e) => {
            let _ = e.to_string();
            return;
        }
    };
    assert!(deployment.validate().is_ok());
    assert_eq!(deployment.source, path);
    assert!(deployment.map.is_absolute() && deployment.model.is_absolute());
    assert!(deployment.robot.as_ref().is_none_or(|r| r.is_absolute()));
    let spec = deployment.can.to_string();
    assert_eq!(CanSpec::parse(&spec), Ok(deployment.can.clone()));
}
