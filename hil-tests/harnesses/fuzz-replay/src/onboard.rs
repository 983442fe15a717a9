//! Files the onboard processes read (`runtime/processes/onboard`): the deployment file, as text, and the
//! mission log (MCAP with JSON messages) that `grop replay` reads back.
#![allow(
    unsafe_code,
    reason = "the fuzz replay views plain-old-data messages as bytes"
)]

use std::path::Path;

use grop_ipc::CameraFrameMsg;
use grop_onboard::deployment::{CanSpec, Deployment};
use grop_onboard::mission_log::{Channel, MissionLog, codec};

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

/// The mission log (`runtime/processes/onboard/src/mission_log`), as `grop replay` reads it. First byte
/// even: the rest is an MCAP file for `MissionLog::from_bytes`, and every message of a channel
/// with a decoder goes through it. Odd: the second byte picks a channel and the rest is one
/// logged message's JSON for that channel's decoder. A message that decodes, encoded again,
/// decodes to the same message (the log is lossless for everything a replay feeds back).
pub fn mission_log(data: &[u8]) {
    let mut b = crate::bytes::Bytes::new(data);
    let mode = b.u8();
    if mode % 2 == 0 {
        let bytes = b.rest();
        match MissionLog::from_bytes(bytes, Path::new("fuzz.mcap")) {
            Ok(log) => {
                let per_channel: usize = Channel::ALL.iter().map(|c| log.channel(*c).count()).sum();
                assert_eq!(per_channel, log.messages.len());
                let _ = log.digest();
                for m in log.messages.iter().take(256) {
                    logged_message(m.channel, &m.data);
                }
            }
            Err(e) => {
                let _ = e.to_string();
            }
        }
    } else {
        let channel = Channel::ALL[usize::from(b.u8()) % Channel::ALL.len()];
        logged_message(channel, b.rest());
    }
}

thread_local! {
    /// Two camera messages to decode into (3.5 MiB each: allocated once, as the replay does).
    static FRAMES: std::cell::RefCell<(Box<CameraFrameMsg>, Box<CameraFrameMsg>)> =
        std::cell::RefCell::new((CameraFrameMsg::boxed_zeroed(), CameraFrameMsg::boxed_zeroed()));
}

/// The bytes of a plain-data message (compared as bytes: NaN != NaN).
fn same<T: Copy>(a: &T, b: &T) -> bool {
    // SAFETY: only called with the `#[repr(C)]` IPC messages below, whose fields are integers,
    // floats and byte arrays without padding (the ipc crate's wire-size tests), so all their
    // bytes are initialised.
    let bytes = |v: &T| unsafe {
        std::slice::from_raw_parts((v as *const T).cast::<u8>(), size_of::<T>()).to_vec()
    };
    bytes(a) == bytes(b)
}

fn logged_message(channel: Channel, data: &[u8]) {
    match channel {
        Channel::BasePose => {
            if let Ok(m) = codec::decode_base_pose(data) {
                let again = codec::decode_base_pose(&codec::encode_base_pose(&m));
                assert!(again.is_ok_and(|a| same(&a, &m)), "{m:?}");
            }
        }
        Channel::ArmIo => {
            if let Ok(m) = codec::decode_arm_io(data) {
                assert!(m.call().is_ok() && m.outcome().is_ok());
                let again = codec::decode_arm_io(&codec::encode_arm_io(&m));
                assert!(again.is_ok_and(|a| same(&a, &m)), "{m:?}");
            }
        }
        Channel::Events => {
            if let Ok(m) = codec::decode_event(data) {
                assert!(m.kind().is_ok() && m.detail().is_ok());
                let again = codec::decode_event(&codec::encode_event(&m));
                assert!(again.is_ok_and(|a| same(&a, &m)), "{m:?}");
            }
        }
        Channel::Health => {
            if let Ok(m) = codec::decode_health(data) {
                let again = codec::decode_health(&codec::encode_health(&m));
                assert!(again.is_ok_and(|a| same(&a, &m)), "{m:?}");
            }
        }
        Channel::Can => {
            if let Ok(f) = codec::decode_can(data) {
                assert_eq!(codec::decode_can(&codec::encode_can(&f)).ok(), Some(f));
            }
        }
        Channel::CameraFrame => {
            let id = codec::camera_frame_id(data);
            FRAMES.with_borrow_mut(|(first, second)| {
                if codec::decode_camera_into(data, first).is_ok() {
                    assert_eq!(id.ok(), Some(first.header.frame_id));
                    let image = first.image().map(<[u8]>::to_vec);
                    assert!(image.is_ok(), "a decoded frame's header checks");
                    let encoded = codec::encode_camera(first);
                    assert!(codec::decode_camera_into(&encoded, second).is_ok());
                    assert!(same(&first.header, &second.header));
                    assert_eq!(second.image().map(<[u8]>::to_vec), image);
                }
            });
        }
        _ => {}
    }
}
