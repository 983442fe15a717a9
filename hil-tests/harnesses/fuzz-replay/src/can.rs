//! CAN bus (`drivers/can-bus`): virtual-bus wire frames from shared memory, candump text.

use can_bus::{CanFrame, CanId};

/// A frame as another process left it in the virtual bus's shared memory. The entry point checks
/// that a decoded frame re-encodes to itself; here the frame also survives candump text.
pub fn can_wire_frame(data: &[u8]) {
    match can_bus::fuzz_decode_wire_frame(data) {
        Ok(frame) => {
            assert!(frame.dlc() <= 8 && frame.data().len() == usize::from(frame.dlc()));
            assert_eq!(frame.id().validate(), Ok(frame.id()));
            let text = frame.to_string();
            assert_eq!(text.parse::<CanFrame>(), Ok(frame), "{text}");
        }
        Err(reason) => assert!(!reason.is_empty()),
    }
}

/// candump / cansend notation (`123#DEADBEEF`, `1F334455#`), as `vcan send` reads its arguments:
/// the whole text and each whitespace-separated word. Whatever parses prints back as the same
/// text in upper case.
pub fn candump_text(data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    check_frame_text(&text);
    for word in text.split_whitespace().take(64) {
        check_frame_text(word);
    }
}

fn check_frame_text(text: &str) {
    match text.parse::<CanFrame>() {
        Ok(frame) => {
            assert_eq!(frame.to_string(), text.to_ascii_uppercase());
            let id_digits = text.split_once('#').map_or(0, |(id, _)| id.len());
            assert_eq!(id_digits, if frame.id().is_extended() { 8 } else { 3 });
            if let CanId::Standard(raw) = frame.id() {
                // The RMP codec accepts every standard frame the bus does.
                let raw_frame = rmp_codec::RawFrame::new(raw, frame.data());
                assert!(raw_frame.is_ok(), "{frame}");
            }
        }
        Err(e) => {
            let _ = e.to_string();
        }
    }
}
