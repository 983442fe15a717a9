//! Segway RMP codec (`firmware-like/rmp-codec`): v3 and Gen-1 frames, the feedback assembler,
//! the USB/UDP packet framing.

use rmp_codec::RawFrame;
use rmp_codec::faults::FaultStatus;
use rmp_codec::feedback::{
    FeedbackAssembler, FeedbackBitmaps, FeedbackItem, FeedbackLayout, FeedbackSet, MAX_ITEMS,
};
use rmp_codec::gen1::{Gen1Command, Gen1Feedback, Gen1Scaling, counter_delta};
use rmp_codec::packet::{
    MAX_COMMAND_PACKET, crc16, decode_command, encode_command, gen1_usb_checksum, gen1_usb_command,
};
use rmp_codec::v3::{ConfigCommand, FirmwareProfile, HostCommand, MotionCommand, OperationalState};

use crate::bytes::Bytes;

const PROFILES: [FirmwareProfile; 2] = [FirmwareProfile::SegwayInc2014, FirmwareProfile::Older440];

/// A CAN frame from the input: 11-bit id (2 bytes), DLC (1 byte, mod 9), data.
fn frame(b: &mut Bytes<'_>) -> RawFrame {
    let id = b.u16() & 0x7FF;
    let len = usize::from(b.u8() % 9);
    let data = b.array::<8>();
    match RawFrame::new(id, &data[..len]) {
        Ok(f) => f,
        Err(e) => panic!("id {id:#x} and {len} bytes are in range: {e}"),
    }
}

/// v3 host commands (0x500 motion, 0x501 configuration) on both firmware numberings: whatever
/// decodes re-encodes to a frame that decodes to the same command; motion frames re-encode
/// byte for byte.
pub fn rmp_v3(data: &[u8]) {
    let mut b = Bytes::new(data);
    let f = frame(&mut b);
    for profile in PROFILES {
        match HostCommand::decode(profile, &f) {
            Ok(HostCommand::Motion(m)) => {
                assert!(
                    m.velocity().is_finite() && m.velocity().abs() <= 1.0,
                    "{m:?}"
                );
                assert!(
                    m.yaw_rate().is_finite() && m.yaw_rate().abs() <= 1.0,
                    "{m:?}"
                );
                assert_eq!(m.encode(), f, "motion command re-encodes byte for byte");
                assert_eq!(MotionCommand::new(m.velocity(), m.yaw_rate()), Ok(m));
            }
            Ok(HostCommand::Config(c)) => {
                let again = match c.encode(profile) {
                    Ok(frame) => frame,
                    Err(e) => panic!("decoded {c:?} does not re-encode on {profile:?}: {e}"),
                };
                assert_eq!(ConfigCommand::decode(profile, &again), Ok(c));
                assert_eq!(
                    HostCommand::decode(profile, &again),
                    Ok(HostCommand::Config(c))
                );
            }
            Err(e) => {
                let _ = e.to_string();
            }
        }
        if let Err(e) = ConfigCommand::decode(profile, &f) {
            let _ = e.to_string();
        }
        // The words alone, as a USB/UDP transport would hand them over.
        let (command, parameter) = (b.u32(), b.u32());
        if let Ok(c) = ConfigCommand::from_words(profile, command, parameter) {
            let words = c.to_words(profile);
            assert!(
                words.is_ok(),
                "{c:?} from ({command}, {parameter}) has no words"
            );
            if let Ok((c2, p2)) = words {
                assert_eq!(ConfigCommand::from_words(profile, c2, p2), Ok(c));
            }
        }
    }
    match MotionCommand::decode(&f) {
        Ok(m) => assert_eq!(m.encode(), f),
        Err(e) => {
            let _ = e.to_string();
        }
    }
    let word = b.u32();
    assert_eq!(OperationalState::from_word(word).to_word(), word);
    let faults = FaultStatus::new([b.u32(), b.u32(), b.u32(), b.u32()]);
    let _ = faults.stops_motion();
    assert!(faults.active().count() <= 31);
}

/// Gen-1 command (0x0413) and feedback (0x0400..0x0407, 0x0680) frames, and the Gen-1 USB
/// wrapping of the frame.
pub fn rmp_gen1(data: &[u8]) {
    let mut b = Bytes::new(data);
    let f = frame(&mut b);
    match Gen1Command::decode(&f) {
        Ok(c) => {
            let again = match c.encode() {
                Ok(frame) => frame,
                Err(e) => panic!("decoded {c:?} does not re-encode: {e}"),
            };
            assert_eq!(Gen1Command::decode(&again), Ok(c));
            if c.config.is_some() {
                assert_eq!(
                    again, f,
                    "a command with a configuration re-encodes exactly"
                );
            }
        }
        Err(e) => {
            let _ = e.to_string();
        }
    }
    match Gen1Feedback::decode(&f) {
        Ok(feedback) => {
            assert!(matches!(f.id(), 0x400..=0x407 | 0x680) && f.len() == 8);
            let scaling = [Gen1Scaling::RMP_200_400, Gen1Scaling::RMP_50_100];
            match feedback {
                Gen1Feedback::WheelDisplacement { left, right }
                | Gen1Feedback::Integrated {
                    fore_aft: left,
                    yaw: right,
                } => {
                    assert_eq!(left.wrapping_add(counter_delta(left, right)), right);
                    for s in scaling {
                        assert!(s.displacement_m(left).is_finite());
                    }
                }
                Gen1Feedback::Velocities { left_wheel, .. } => {
                    for s in scaling {
                        assert!(s.speed_mps(left_wheel).is_finite());
                    }
                }
                _ => {}
            }
        }
        Err(e) => {
            let _ = e.to_string();
        }
    }
    let usb = gen1_usb_command(&f);
    assert_eq!(usb[..2], [0xF0, 0x55]);
    assert_eq!(usb[6..8], f.id().to_be_bytes());
    assert_eq!(&usb[9..9 + f.len()], f.data());
    assert_eq!(usb[17], gen1_usb_checksum(&usb[..17]));
    // Velocity conversion stays inside the command limits whatever the speed.
    let speed = f32::from_bits(b.u32());
    for s in [Gen1Scaling::RMP_200_400, Gen1Scaling::RMP_50_100] {
        let counts = s.velocity_counts(speed);
        assert!(
            counts.unsigned_abs() <= 1176,
            "{speed} m/s -> {counts} counts"
        );
    }
}

/// The feedback assembler over an arbitrary frame stream, with the layout chosen by the input.
/// Every completed set has the layout's item count and, sent again frame by frame, assembles to
/// the same set.
pub fn rmp_feedback(data: &[u8]) {
    let mut b = Bytes::new(data);
    let selector = b.u8();
    let layout = if selector & 1 == 1 {
        FeedbackLayout::ForcedConfig
    } else {
        let words = [b.u32(), b.u32(), b.u32(), 0];
        match FeedbackBitmaps::new(words) {
            Ok(bitmaps) => FeedbackLayout::User(bitmaps),
            Err(e) => panic!("bitmap 4 is zero, bitmaps 1..3 are all valid: {e}"),
        }
    };
    // Bitmap 4 never names an item.
    assert!(FeedbackBitmaps::new([0, 0, 0, b.u32() | 1]).is_err());
    let mut asm = FeedbackAssembler::new(layout);
    let mut completed = 0;
    while !b.is_empty() {
        // One byte of id (0x500..=0x5FF: the commands, all feedback ids and beyond), DLC, data.
        let control = b.u8();
        let id = 0x500 + u16::from(b.u8());
        let len = usize::from(control % 9);
        let payload = b.take(len);
        let mut bytes = [0u8; 8];
        bytes[..payload.len()].copy_from_slice(payload);
        let f = match RawFrame::new(id, &bytes[..len]) {
            Ok(f) => f,
            Err(e) => panic!("{id:#x} with {len} bytes is a valid frame: {e}"),
        };
        if control & 0x80 != 0 {
            asm.reset();
        }
        match asm.push(&f) {
            Ok(Some(set)) => {
                completed += 1;
                check_set(&set, layout);
            }
            Ok(None) => {}
            Err(e) => {
                let _ = e.to_string();
            }
        }
    }
    let _ = completed;
}

fn check_set(set: &FeedbackSet, layout: FeedbackLayout) {
    assert_eq!(*set.layout(), layout);
    assert_eq!(set.words().len(), layout.item_count());
    assert!(set.words().len() <= MAX_ITEMS);
    for index in 0..MAX_ITEMS {
        let Some(item) = FeedbackItem::from_index(index) else {
            panic!("item {index} exists");
        };
        assert_eq!(set.get(item).is_some(), layout.position(item).is_some());
    }
    let _ = set.operational_state();
    let _ = set.fault_status().map(|f| f.stops_motion());
    // Sent again, the set assembles to itself, completing on its last frame only.
    let mut again = FeedbackAssembler::new(layout);
    let frames: Vec<RawFrame> = set.frames().collect();
    assert_eq!(frames.len(), layout.frame_count());
    for (k, f) in frames.iter().enumerate() {
        let got = again.push(f);
        if k + 1 < frames.len() {
            assert_eq!(got, Ok(None), "frame {k} of {}", frames.len());
        } else {
            assert_eq!(got, Ok(Some(*set)), "last frame completes the set");
        }
    }
    let rebuilt = FeedbackSet::from_words(layout, set.words());
    assert_eq!(rebuilt, *set);
}

/// The v3 USB/UDP command packet (id, words, CRC-16): what decodes re-encodes byte for byte;
/// encoding words from the input decodes back to them; any single flipped bit is detected.
pub fn rmp_packet(data: &[u8]) {
    match decode_command(data) {
        Ok((id, words, n)) => {
            assert!(n <= 3 && data.len() == 4 + 4 * n);
            let mut out = [0u8; MAX_COMMAND_PACKET];
            let len = encode_command(id, &words[..n], &mut out);
            assert_eq!(len, Ok(data.len()));
            assert_eq!(&out[..data.len()], data, "packet re-encodes byte for byte");
        }
        Err(e) => {
            let _ = e.to_string();
        }
    }
    let _ = gen1_usb_checksum(data);
    let mut b = Bytes::new(data);
    let id = b.u16();
    let n = usize::from(b.u8() % 4);
    let words: Vec<u32> = (0..n).map(|_| b.u32()).collect();
    let mut out = [0u8; MAX_COMMAND_PACKET];
    let len = match encode_command(id, &words, &mut out) {
        Ok(len) => len,
        Err(e) => panic!("{n} words fit a command packet: {e}"),
    };
    let decoded = decode_command(&out[..len]);
    assert_eq!(
        decoded.map(|(i, w, c)| (i, w[..c].to_vec())),
        Ok((id, words))
    );
    assert_eq!(
        crc16(&out[..len - 2]).to_be_bytes(),
        out[len - 2..len],
        "CRC appended most significant byte first"
    );
    let flip = usize::from(b.u16()) % (8 * len);
    out[flip / 8] ^= 1 << (flip % 8);
    assert!(decode_command(&out[..len]).is_err(), "bit {flip} flipped");
}
