//! The bodies of the fuzz targets over every decoder of outside input, shared by the cargo-fuzz
//! crate (`fuzz/`, nightly) and the replay test of this crate (stable, `cargo test`), which runs
//! every committed corpus file (`fuzz/corpus/<target>/`) through the same function.
//!
//! Each target takes arbitrary bytes, feeds them to one decoder (or one client over a loopback
//! socket) and panics only when an invariant is broken: beyond "no panic" they check round trips
//! (`decode(encode(x)) == x` for the formats that have an encoder) and the promises the decoders
//! document. The list, the commands and the measured runs are in `docs/fuzzing.md`.
//!
//! Panicking is the point here (a fuzz target reports a broken invariant by panicking), so this
//! crate asserts freely; it is test support, not product code.

// A fuzz build with one group of targets leaves helpers of the others unused.
#![cfg_attr(
    not(all(
        feature = "can",
        feature = "ur5e",
        feature = "world",
        feature = "ipc",
        feature = "onboard",
        feature = "model",
        feature = "lidar"
    )),
    allow(dead_code, unused_mut)
)]

mod bytes;
#[cfg(feature = "can")]
mod can;
#[cfg(feature = "ipc")]
mod ipc;
#[cfg(feature = "lidar")]
mod lidar;
#[cfg(feature = "onboard")]
mod mission_core;
#[cfg(feature = "model")]
mod model;
#[cfg(feature = "ur5e")]
mod net;
#[cfg(feature = "onboard")]
mod onboard;
mod rmp;
#[cfg(feature = "ur5e")]
mod rtde;
#[cfg(feature = "ur5e")]
mod scripted;
#[cfg(all(
    feature = "can",
    feature = "ur5e",
    feature = "world",
    feature = "ipc",
    feature = "onboard",
    feature = "model",
    feature = "lidar"
))]
pub mod seeds;
#[cfg(feature = "ur5e")]
mod ur5e_text;
#[cfg(feature = "ur5e")]
mod urscript;
#[cfg(feature = "world")]
mod world_files;

#[cfg(feature = "can")]
pub use can::{can_wire_frame, candump_text};
#[cfg(feature = "ipc")]
pub use ipc::{camera_frame, ipc_messages};
#[cfg(feature = "lidar")]
pub use lidar::{HEADER_LEN as VLP16_HEADER_LEN, vlp16_packet};
#[cfg(feature = "onboard")]
pub use mission_core::mission_core;
#[cfg(feature = "model")]
pub use model::model_loader;
#[cfg(feature = "onboard")]
pub use onboard::{deployment_file, mission_log};
pub use rmp::{rmp_feedback, rmp_gen1, rmp_packet, rmp_v3};
#[cfg(feature = "ur5e")]
pub use rtde::{rtde_client, rtde_stream, rtde_wire};
#[cfg(feature = "ur5e")]
pub use ur5e_text::{dashboard_client, dashboard_replies, gripper_client, gripper_replies};
#[cfg(feature = "ur5e")]
pub use urscript::urscript;
#[cfg(feature = "world")]
pub use world_files::{robot_file, scene_file};

/// One fuzz target: its name (the cargo-fuzz target and the corpus folder) and its body.
pub type Target = (&'static str, fn(&[u8]));

/// Every target this build has (all of them with the default features), in the order of
/// `docs/fuzzing.md`.
pub fn targets() -> Vec<Target> {
    let mut all: Vec<Target> = vec![
        ("rmp_v3", rmp_v3),
        ("rmp_gen1", rmp_gen1),
        ("rmp_feedback", rmp_feedback),
        ("rmp_packet", rmp_packet),
    ];
    #[cfg(feature = "can")]
    all.extend([
        ("can_wire_frame", can_wire_frame as fn(&[u8])),
        ("candump_text", candump_text),
    ]);
    #[cfg(feature = "ur5e")]
    all.extend([
        ("rtde_wire", rtde_wire as fn(&[u8])),
        ("rtde_client", rtde_client),
        ("rtde_stream", rtde_stream),
        ("dashboard_client", dashboard_client),
        ("dashboard_replies", dashboard_replies),
        ("gripper_client", gripper_client),
        ("gripper_replies", gripper_replies),
        ("urscript", urscript),
    ]);
    #[cfg(feature = "world")]
    all.extend([
        ("scene_file", scene_file as fn(&[u8])),
        ("robot_file", robot_file),
    ]);
    #[cfg(feature = "onboard")]
    all.extend([
        ("deployment_file", deployment_file as fn(&[u8])),
        ("mission_log", mission_log),
        ("mission_core", mission_core),
    ]);
    #[cfg(feature = "ipc")]
    all.extend([
        ("ipc_messages", ipc_messages as fn(&[u8])),
        ("camera_frame", camera_frame),
    ]);
    #[cfg(feature = "model")]
    all.push(("model_loader", model_loader));
    #[cfg(feature = "lidar")]
    all.push(("vlp16_packet", vlp16_packet));
    all
}

/// The body of the target called `name`, if this build has it.
pub fn target(name: &str) -> Option<fn(&[u8])> {
    targets()
        .into_iter()
        .find(|(n, _)| *n == name)
        .map(|(_, f)| f)
}
