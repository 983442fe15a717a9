//! Properties: decoding arbitrary bytes never panics and only yields values the encoder could
//! have produced; encode/decode round trips.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

use proptest::prelude::*;
use rmp_codec::RawFrame;
use rmp_codec::feedback::{FeedbackAssembler, FeedbackBitmaps, FeedbackLayout, FeedbackSet};
use rmp_codec::gen1::{Gen1Command, Gen1Feedback};
use rmp_codec::packet::{decode_command, encode_command};
use rmp_codec::v3::{ConfigCommand, FirmwareProfile, HostCommand, MotionCommand};

fn any_frame() -> impl Strategy<Value = RawFrame> {
    (0u16..=0x7FF, proptest::collection::vec(any::<u8>(), 0..=8))
        .prop_map(|(id, data)| RawFrame::new(id, &data).expect("id and length are in range"))
}

/// Frames whose id is one the decoders care about, to exercise more than the id check.
fn protocol_frame() -> impl Strategy<Value = RawFrame> {
    (
        prop_oneof![
            Just(0x500u16),
            Just(0x501),
            0x400u16..=0x407,
            Just(0x413),
            Just(0x680),
            0x502u16..=0x531
        ],
        proptest::collection::vec(any::<u8>(), 0..=8),
    )
        .prop_map(|(id, data)| RawFrame::new(id, &data).expect("valid id and length"))
}

proptest! {
    #[test]
    fn decoders_never_panic(frame in prop_oneof![any_frame(), protocol_frame()]) {
        for profile in [FirmwareProfile::SegwayInc2014, FirmwareProfile::Older440] {
            if let Ok(cmd) = HostCommand::decode(profile, &frame) {
                // Whatever decodes must re-encode to the same payload (canonical form).
                match cmd {
                    HostCommand::Motion(m) => {
                        prop_assert!(m.velocity().abs() <= 1.0 && m.yaw_rate().abs() <= 1.0);
                        prop_assert_eq!(m.encode(), frame);
                    }
                    HostCommand::Config(c) => {
                        let again = c.encode(profile).expect("decoded command re-encodes");
                        prop_assert_eq!(ConfigCommand::decode(profile, &again), Ok(c));
                    }
                }
            }
        }
        let _ = Gen1Command::decode(&frame);
        let _ = Gen1Feedback::decode(&frame);
        let mut asm = FeedbackAssembler::new(FeedbackLayout::default());
        let _ = asm.push(&frame);
    }

    #[test]
    fn arbitrary_frame_streams_never_panic_the_assembler(
        frames in proptest::collection::vec(protocol_frame(), 0..120),
        bitmaps in any::<[u32; 3]>(),
    ) {
        let layout = FeedbackLayout::User(
            FeedbackBitmaps::new([bitmaps[0], bitmaps[1], bitmaps[2], 0]).expect("valid bits"),
        );
        let mut asm = FeedbackAssembler::new(layout);
        for f in &frames {
            if let Ok(Some(set)) = asm.push(f) {
                prop_assert_eq!(set.words().len(), layout.item_count());
            }
        }
    }

    #[test]
    fn motion_round_trips(v in -1.0f32..=1.0, w in -1.0f32..=1.0) {
        let cmd = MotionCommand::new(v, w).expect("in range");
        prop_assert_eq!(MotionCommand::decode(&cmd.encode()), Ok(cmd));
    }

    #[test]
    fn feedback_sets_round_trip(
        bitmaps in any::<[u32; 3]>(),
        seed in any::<u32>(),
    ) {
        let layout = FeedbackLayout::User(
            FeedbackBitmaps::new([bitmaps[0], bitmaps[1], bitmaps[2], 0]).expect("valid bits"),
        );
        let set = FeedbackSet::from_fn(layout, |item| seed.rotate_left(item as u32) ^ item as u32);
        let mut asm = FeedbackAssembler::new(layout);
        let mut done = None;
        for frame in set.frames() {
            prop_assert!(done.is_none(), "set completed before its last frame");
            done = asm.push(&frame).expect("in-order frames of the layout");
        }
        if layout.item_count() > 0 {
            prop_assert_eq!(done, Some(set));
        }
    }

    #[test]
    fn packets_round_trip_and_detect_single_bit_errors(
        id in any::<u16>(),
        words in proptest::collection::vec(any::<u32>(), 0..=3),
        flip in any::<(usize, u8)>(),
    ) {
        let mut buf = [0u8; 16];
        let n = encode_command(id, &words, &mut buf).expect("fits");
        let (got_id, got_words, count) = decode_command(&buf[..n]).expect("valid packet");
        prop_assert_eq!(got_id, id);
        prop_assert_eq!(&got_words[..count], &words[..]);
        let byte = flip.0 % n;
        buf[byte] ^= 1 << (flip.1 % 8);
        prop_assert!(decode_command(&buf[..n]).is_err());
    }
}
