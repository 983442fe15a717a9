//! `rmp.dbc` against the codec: a small parser for the BO_ / SG_ / SIG_VALTYPE_ lines, then
//! (1) the default feedback layout of the codec is exactly what the DBC describes and (2)
//! payloads decoded through the DBC signal definitions equal what the codec decodes, for
//! pseudo-random payloads of every frame.
#![allow(
    clippy::too_many_lines,
    reason = "a test scenario (or the fuzz harness's) reads top to bottom as one story"
)]

use std::collections::HashMap;

use rmp_base::{DRIVER_FEEDBACK_ITEMS, RmpBaseConfig};
use rmp_codec::RawFrame;
use rmp_codec::feedback::{self, FeedbackBitmaps, FeedbackLayout, FeedbackSet, ITEMS, ItemKind};
use rmp_codec::gen1::{Gen1Command, Gen1Feedback};
use rmp_codec::v3::MotionCommand;

#[derive(Debug, Clone)]
struct Signal {
    name: String,
    start_bit: u32,
    length: u32,
    big_endian: bool,
    signed: bool,
    float: bool,
}

#[derive(Debug, Default)]
struct Dbc {
    /// Message id -> (name, signals).
    messages: HashMap<u32, (String, Vec<Signal>)>,
    comment: String,
}

fn parse(text: &str) -> Result<Dbc, String> {
    let mut dbc = Dbc::default();
    let mut current: Option<u32> = None;
    for (n, line) in text.lines().enumerate() {
        let where_ = |what: &str| format!("rmp.dbc line {}: {what}: {line}", n + 1);
        let t = line.trim();
        if let Some(rest) = t.strip_prefix("BO_ ") {
            let mut parts = rest.split_whitespace();
            let id: u32 = parts
                .next()
                .and_then(|s| s.parse().ok())
                .ok_or_else(|| where_("bad message id"))?;
            let name = parts
                .next()
                .map(|s| s.trim_end_matches(':').to_string())
                .ok_or_else(|| where_("no message name"))?;
            if dbc.messages.insert(id, (name, Vec::new())).is_some() {
                return Err(where_("duplicate message id"));
            }
            current = Some(id);
        } else if let Some(rest) = t.strip_prefix("SG_ ") {
            let id = current.ok_or_else(|| where_("signal outside a message"))?;
            // name : start|len@order sign (factor,offset) [min|max] "unit" receivers
            let (name, spec) = rest.split_once(" : ").ok_or_else(|| where_("no ' : '"))?;
            let layout = spec
                .split_whitespace()
                .next()
                .ok_or_else(|| where_("no layout"))?;
            let (start, rest) = layout.split_once('|').ok_or_else(|| where_("no '|'"))?;
            let (len, rest) = rest.split_once('@').ok_or_else(|| where_("no '@'"))?;
            let order = rest.chars().next().ok_or_else(|| where_("no byte order"))?;
            let sign = rest.chars().nth(1).ok_or_else(|| where_("no sign"))?;
            let signal = Signal {
                name: name.trim().to_string(),
                start_bit: start.parse().map_err(|_| where_("bad start bit"))?,
                length: len.parse().map_err(|_| where_("bad length"))?,
                big_endian: order == '0',
                signed: sign == '-',
                float: false,
            };
            dbc.messages
                .get_mut(&id)
                .ok_or_else(|| where_("unknown message"))?
                .1
                .push(signal);
        } else if let Some(rest) = t.strip_prefix("SIG_VALTYPE_ ") {
            let mut parts = rest.split_whitespace();
            let id: u32 = parts
                .next()
                .and_then(|s| s.parse().ok())
                .ok_or_else(|| where_("bad id"))?;
            let name = parts.next().ok_or_else(|| where_("no signal"))?;
            let kind = rest.trim_end_matches(';').rsplit(' ').next().unwrap_or("");
            let sig = dbc
                .messages
                .get_mut(&id)
                .and_then(|(_, sigs)| sigs.iter_mut().find(|s| s.name == name))
                .ok_or_else(|| where_("value type for an unknown signal"))?;
            sig.float = kind == "1";
        } else if t.starts_with("CM_ \"") {
            dbc.comment = t.to_string();
        } else if t.is_empty() {
            current = None;
        }
    }
    Ok(dbc)
}

fn load_file(file: &str) -> Dbc {
    let path = format!("{}/{file}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    parse(&text).unwrap_or_else(|e| panic!("{file}: {e}"))
}

fn load() -> Dbc {
    load_file("rmp.dbc")
}

fn driver_layout() -> FeedbackLayout {
    FeedbackLayout::User(FeedbackBitmaps::from_items(&DRIVER_FEEDBACK_ITEMS))
}

/// Raw bits of a signal. Motorola: start bit is the MSB in DBC sawtooth numbering.
fn raw_bits(sig: &Signal, data: &[u8; 8]) -> u64 {
    let mask = if sig.length == 64 {
        u64::MAX
    } else {
        (1u64 << sig.length) - 1
    };
    if sig.big_endian {
        let msb = (sig.start_bit / 8) * 8 + (7 - sig.start_bit % 8); // linear, MSB-first
        let word = u64::from_be_bytes(*data);
        (word >> (64 - msb - sig.length)) & mask
    } else {
        (u64::from_le_bytes(*data) >> sig.start_bit) & mask
    }
}

/// Value as a physical tools would show it (factor 1, offset 0 everywhere in this file).
fn value(sig: &Signal, data: &[u8; 8]) -> f64 {
    let raw = raw_bits(sig, data);
    if sig.float {
        assert_eq!(sig.length, 32, "{} float must be 32 bits", sig.name);
        return f32::from_bits(raw as u32) as f64;
    }
    if sig.signed {
        let shift = 64 - sig.length;
        ((raw << shift) as i64 >> shift) as f64
    } else {
        raw as f64
    }
}

fn payload(frame: &RawFrame) -> [u8; 8] {
    let mut d = [0u8; 8];
    d[..frame.len()].copy_from_slice(frame.data());
    d
}

fn signal<'a>(dbc: &'a Dbc, id: u32, name: &str) -> &'a Signal {
    dbc.messages[&id]
        .1
        .iter()
        .find(|s| s.name == name)
        .unwrap_or_else(|| panic!("{id:#x} has no signal {name}"))
}

/// xorshift: deterministic pseudo-random payloads without a dependency.
fn next(state: &mut u64) -> u64 {
    *state ^= *state << 13;
    *state ^= *state >> 7;
    *state ^= *state << 17;
    *state
}

#[test]
fn names_the_default_feedback_configuration() {
    let dbc = load();
    assert!(dbc.comment.contains("DEFAULT FEEDBACK CONFIGURATION"));
    assert!(
        dbc.comment
            .contains("bitmaps 1..3 = 0xFFFFFFFF, bitmap 4 = 0")
    );
    for (id, (name, sigs)) in dbc
        .messages
        .iter()
        .chain(load_file("rmp-driver.dbc").messages.iter())
    {
        let ident = |s: &str| {
            s.chars()
                .next()
                .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
                && s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
        };
        assert!(ident(name), "message {id:#x} name {name}");
        for s in sigs {
            assert!(ident(&s.name), "signal {} of {id:#x}", s.name);
            assert!(s.start_bit < 64 && s.length <= 64);
        }
    }
}

#[test]
fn feedback_frames_match_the_codec_layout_item_by_item() {
    let dbc = load();
    assert_eq!(FeedbackLayout::default().frame_count(), 48);
    check_layout(&dbc, FeedbackLayout::default());
    assert_eq!(ITEMS.len(), 96);
}

#[test]
fn the_driver_dbc_matches_the_driver_default_selection() {
    let dbc = load_file("rmp-driver.dbc");
    let layout = driver_layout();
    assert_eq!(
        RmpBaseConfig::default().feedback,
        FeedbackBitmaps::from_items(&DRIVER_FEEDBACK_ITEMS)
    );
    check_layout(&dbc, layout);
    let w = FeedbackBitmaps::from_items(&DRIVER_FEEDBACK_ITEMS).words();
    let named = format!(
        "bitmaps = 0x{:08X} 0x{:08X} 0x{:08X} 0x{:08X}",
        w[0], w[1], w[2], w[3]
    );
    assert!(dbc.comment.contains("DRIVER FEEDBACK CONFIGURATION"));
    assert!(dbc.comment.contains(&named), "{named}");
    let mut rng = 7u64;
    let set = FeedbackSet::from_fn(layout, |_| next(&mut rng) as u32);
    for frame in set.frames() {
        let data = payload(&frame);
        for (k, sig) in dbc.messages[&(frame.id() as u32)].1.iter().enumerate() {
            let word = set.words()[(frame.id() - feedback::FIRST_ID) as usize * 2 + k];
            assert_eq!(raw_bits(sig, &data), word as u64, "{}", sig.name);
        }
    }
}

fn check_layout(dbc: &Dbc, layout: FeedbackLayout) {
    for (pos, item) in layout.items().enumerate() {
        let id = feedback::FIRST_ID as u32 + (pos / 2) as u32;
        let info = item.info();
        let (_, sigs) = dbc
            .messages
            .get(&id)
            .unwrap_or_else(|| panic!("DBC lacks feedback frame {id:#x}"));
        let in_frame = if 2 * (pos / 2) + 1 < layout.item_count() {
            2
        } else {
            1
        };
        assert_eq!(sigs.len(), in_frame, "{id:#x}");
        let sig = &sigs[pos % 2];
        assert_eq!(sig.name, info.name, "item {pos} in {id:#x}");
        assert_eq!(sig.start_bit, if pos % 2 == 0 { 7 } else { 39 });
        assert_eq!(sig.length, 32);
        assert!(sig.big_endian, "{}", sig.name);
        assert_eq!(sig.float, info.kind == ItemKind::F32, "{}", sig.name);
    }
    let feedback_messages = dbc
        .messages
        .keys()
        .filter(|id| feedback::is_feedback_id(**id as u16))
        .count();
    assert_eq!(feedback_messages, layout.frame_count());
}

#[test]
fn dbc_decoding_equals_codec_decoding_for_random_payloads() {
    let dbc = load();
    let mut rng = 0x9E37_79B9_7F4A_7C15u64;
    for _ in 0..200 {
        // v3 feedback: random words, including NaN patterns, compared bit for bit.
        let set = FeedbackSet::from_fn(FeedbackLayout::default(), |_| next(&mut rng) as u32);
        for frame in set.frames() {
            let data = payload(&frame);
            for (k, sig) in dbc.messages[&(frame.id() as u32)].1.iter().enumerate() {
                let pos = (frame.id() - feedback::FIRST_ID) as usize * 2 + k;
                let word = set.words()[pos];
                let got = value(sig, &data);
                if sig.float {
                    let want = f32::from_bits(word) as f64;
                    assert!(
                        got == want || (got.is_nan() && want.is_nan()),
                        "{}",
                        sig.name
                    );
                } else {
                    assert_eq!(got, word as f64, "{}", sig.name);
                }
            }
        }
        // v3 motion.
        let v = (next(&mut rng) % 2001) as f32 / 1000.0 - 1.0;
        let w = (next(&mut rng) % 2001) as f32 / 1000.0 - 1.0;
        let frame = MotionCommand::new(v, w).unwrap().encode();
        let data = payload(&frame);
        assert_eq!(value(signal(&dbc, 0x500, "velocity_norm"), &data), v as f64);
        assert_eq!(value(signal(&dbc, 0x500, "yaw_rate_norm"), &data), w as f64);
        // Gen-1 feedback: random payloads on every id.
        for id in [
            0x400u16, 0x401, 0x402, 0x403, 0x404, 0x405, 0x406, 0x407, 0x680,
        ] {
            let bytes = next(&mut rng).to_be_bytes();
            let frame = RawFrame::new(id, &bytes).unwrap();
            let d = payload(&frame);
            let s = |name: &str| value(signal(&dbc, id as u32, name), &d);
            let pair = |lo: &str, hi: &str| ((s(hi) as u32) << 16 | s(lo) as u32) as i32 as f64;
            match Gen1Feedback::decode(&frame).unwrap() {
                Gen1Feedback::BuildId(b) => assert_eq!(s("gen1_build_id"), b as f64),
                Gen1Feedback::Attitude {
                    pitch,
                    pitch_rate,
                    roll,
                    roll_rate,
                } => {
                    assert_eq!(s("gen1_pitch_counts"), pitch as f64);
                    assert_eq!(s("gen1_pitch_rate_counts"), pitch_rate as f64);
                    assert_eq!(s("gen1_roll_counts"), roll as f64);
                    assert_eq!(s("gen1_roll_rate_counts"), roll_rate as f64);
                }
                Gen1Feedback::Velocities {
                    left_wheel,
                    right_wheel,
                    yaw_rate,
                    frame_counter,
                } => {
                    assert_eq!(s("gen1_left_wheel_vel_counts"), left_wheel as f64);
                    assert_eq!(s("gen1_right_wheel_vel_counts"), right_wheel as f64);
                    assert_eq!(s("gen1_yaw_rate_counts"), yaw_rate as f64);
                    assert_eq!(s("gen1_servo_frame_counter"), frame_counter as f64);
                }
                Gen1Feedback::WheelDisplacement { left, right } => {
                    assert_eq!(
                        pair("gen1_left_wheel_disp_lo", "gen1_left_wheel_disp_hi"),
                        left as f64
                    );
                    assert_eq!(
                        pair("gen1_right_wheel_disp_lo", "gen1_right_wheel_disp_hi"),
                        right as f64
                    );
                }
                Gen1Feedback::Integrated { fore_aft, yaw } => {
                    assert_eq!(
                        pair("gen1_fore_aft_disp_lo", "gen1_fore_aft_disp_hi"),
                        fore_aft as f64
                    );
                    assert_eq!(pair("gen1_yaw_disp_lo", "gen1_yaw_disp_hi"), yaw as f64);
                }
                Gen1Feedback::MotorTorque { left, right } => {
                    assert_eq!(s("gen1_left_motor_torque_counts"), left as f64);
                    assert_eq!(s("gen1_right_motor_torque_counts"), right as f64);
                }
                Gen1Feedback::ModeAndBattery {
                    mode,
                    gain_schedule,
                    ui_battery,
                    base_battery,
                } => {
                    if let Some(m) = mode {
                        assert_eq!(s("gen1_operational_mode"), m as u16 as f64);
                    }
                    assert_eq!(s("gen1_gain_schedule"), gain_schedule as f64);
                    assert_eq!(s("gen1_ui_battery_counts"), ui_battery as f64);
                    assert_eq!(s("gen1_base_battery_counts"), base_battery as f64);
                }
                Gen1Feedback::CommandEcho { velocity, turn } => {
                    assert_eq!(s("gen1_velocity_echo_counts"), velocity as f64);
                    assert_eq!(s("gen1_turn_echo_counts"), turn as f64);
                }
                Gen1Feedback::Status { word1, word2 } => {
                    assert_eq!(s("gen1_status_word_1"), word1 as f64);
                    assert_eq!(s("gen1_status_word_2"), word2 as f64);
                }
                other => panic!("undescribed {other:?}"),
            }
        }
        // Gen-1 command.
        let cmd = Gen1Command {
            velocity_counts: (next(&mut rng) % 2353) as i16 - 1176,
            turn_counts: (next(&mut rng) % 2049) as i16 - 1024,
            config: None,
        };
        let d = payload(&cmd.encode().unwrap());
        assert_eq!(
            value(signal(&dbc, 0x413, "gen1_velocity_counts"), &d),
            cmd.velocity_counts as f64
        );
        assert_eq!(
            value(signal(&dbc, 0x413, "gen1_turn_counts"), &d),
            cmd.turn_counts as f64
        );
    }
}

#[test]
fn the_parser_rejects_broken_lines() {
    assert!(parse("BO_ x NAME: 8 RMP").is_err());
    assert!(parse(" SG_ orphan : 7|32@0+ (1,0) [0|0] \"\" HOST").is_err());
    assert!(parse("BO_ 1 A: 8 RMP\n SG_ s : 7|32 (1,0)").is_err());
}
