//! A hostile local user (docs/security.md): the files iceoryx2 makes for a namespace (its
//! folder, the node and service files, the event sockets, the shared memory in `/dev/shm`) are
//! no wider than the user that runs the robot's processes.
#![allow(
    unsafe_code,
    reason = "libc::geteuid: the file-mode checks need the test's own uid"
)]

use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};

use grop_ipc::{BasePoseMsg, EventMsg, HeartbeatMsg, IpcNode, TaskPlanMsg};

/// iceoryx2's folder (its default configuration: no config file is read).
const ROOT: &str = "/tmp/iceoryx2";

/// The one file iceoryx2 0.10 shares with every user on purpose: a 16-byte counter of created
/// nodes (`GlobalManagementSegment`, `enable_global_access(true)`), part of how node ids are
/// made unique; it holds no message and no service.
fn is_global_node_counter(path: &Path) -> bool {
    path.file_name()
        .and_then(|n| n.to_str())
        .is_some_and(|n| n.starts_with("iox2_") && n.ends_with(".global_mgmt"))
}

fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        // Entries of other processes come and go while we look.
        let Ok(meta) = std::fs::symlink_metadata(&path) else {
            continue;
        };
        out.push(path.clone());
        if meta.is_dir() {
            walk(&path, out);
        }
    }
}

#[test]
fn iceoryx2_files_are_the_users_alone() {
    let ns = format!("test-{}-modes", std::process::id());
    let a = IpcNode::new(&ns, "grop-planner").unwrap();
    let b = IpcNode::new(&ns, "grop-executive").unwrap();
    let _plans = a.publisher::<TaskPlanMsg>().unwrap();
    let _fixes = a.publisher::<BasePoseMsg>().unwrap();
    let _health = a.publisher::<HeartbeatMsg>().unwrap();
    let _events = b.publisher::<EventMsg>().unwrap();
    let _plan_sub = b.subscriber::<TaskPlanMsg>().unwrap();
    let _health_sub = b.subscriber::<HeartbeatMsg>().unwrap();

    // SAFETY: geteuid has no preconditions.
    let uid = unsafe { libc::geteuid() };
    let root = std::fs::metadata(ROOT).expect("iceoryx2's folder exists once a node does");
    assert_eq!(root.uid(), uid, "{ROOT} belongs to this user");
    assert_eq!(
        root.mode() & 0o777,
        0o700,
        "{ROOT}: nobody else may list or enter it"
    );

    let mut files = Vec::new();
    walk(Path::new(ROOT), &mut files);
    let shm: Vec<PathBuf> = std::fs::read_dir("/dev/shm")
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("iox2_"))
        })
        .collect();
    assert!(
        shm.len() > 2,
        "the services' shared memory is in /dev/shm: {shm:?}"
    );
    let mut checked = 0;
    let mut too_wide = Vec::new();
    for path in files.iter().chain(&shm) {
        let Ok(meta) = std::fs::symlink_metadata(path) else {
            continue;
        };
        if meta.uid() != uid {
            too_wide.push(format!("{} belongs to uid {}", path.display(), meta.uid()));
            continue;
        }
        checked += 1;
        let mode = meta.mode() & 0o777;
        if is_global_node_counter(path) {
            assert!(meta.len() <= 64, "{}: {} bytes", path.display(), meta.len());
            continue;
        }
        // Group read/traverse on folders under the 0700 root reaches nothing; no other
        // bits anywhere, no group write.
        let allowed = if meta.is_dir() { 0o750 } else { 0o600 };
        if mode & !allowed != 0 {
            too_wide.push(format!("{} is {mode:o}", path.display()));
        }
    }
    assert!(checked > 5, "looked at {checked} files only");
    assert!(too_wide.is_empty(), "wider than the user: {too_wide:#?}");
}
