//! RTDE (`drivers/ur5e/src/rtde`): the wire format, and the client fed arbitrary byte streams,
//! by a fake controller on loopback (the TCP transport) and in memory (at the decoders' speed).

use std::time::Duration;

use ur5e::arm::ARM_OUTPUTS;
use ur5e::rtde::wire::{
    self, HEADER_LEN, RtdeType, RtdeValue, SetupField, decode_fields, encode_fields, split_package,
};
use ur5e::rtde::{
    ControllerVersion, DataPackage, PackageType, RtdeClient, RtdeReceiveError, RtdeRequestError,
    RtdeState, RtdeTimeouts, TextLevel, TextMessage,
};
use ur5e::transport::Transport;

use crate::bytes::Bytes;
use crate::net::OneShotServer;
use crate::scripted::ScriptedStream;

/// The package framing over the whole input, then each package's payload through the payload
/// decoders (text message, controller version, setup reply words), and field values decoded by
/// a recipe read from the input. Round trips: a framed package rebuilds to its bytes, a text
/// message or version re-encodes to its payload, field values re-encode to their bytes.
pub fn rtde_wire(data: &[u8]) {
    let mut rest = data;
    let mut packages = 0;
    loop {
        match split_package(rest) {
            Ok(Some((pkg, used))) => {
                assert!((HEADER_LEN..=rest.len()).contains(&used));
                assert_eq!(usize::from(u16::from_be_bytes([rest[0], rest[1]])), used);
                assert_eq!(pkg.payload, &rest[HEADER_LEN..used]);
                if let Some(ty) = PackageType::from_byte(pkg.type_byte) {
                    assert_eq!(ty as u8, pkg.type_byte);
                    let mut again = Vec::new();
                    if let Err(e) = wire::push_package(&mut again, ty, pkg.payload) {
                        panic!("a received payload re-frames: {e}");
                    }
                    assert_eq!(again, &rest[..used]);
                }
                check_payload(pkg.payload);
                rest = &rest[used..];
                packages += 1;
            }
            Ok(None) => {
                assert!(
                    rest.len() < HEADER_LEN
                        || usize::from(u16::from_be_bytes([rest[0], rest[1]])) > rest.len()
                );
                break;
            }
            Err(e) => {
                let _ = e.to_string();
                break;
            }
        }
    }
    let _ = packages;
    check_payload(data);
    check_fields(data);
}

fn check_payload(payload: &[u8]) {
    match TextMessage::decode(payload) {
        Ok(m) => {
            let mlen = usize::from(payload[0]);
            let slen = usize::from(payload[1 + mlen]);
            let level = payload[2 + mlen + slen];
            let mut out = Vec::new();
            m.encode(&mut out);
            if m.message.len() <= 255 && m.source.len() <= 255 {
                assert_eq!(TextMessage::decode(&out), Ok(m.clone()));
            }
            let utf8 = std::str::from_utf8(&payload[1..1 + mlen]).is_ok()
                && std::str::from_utf8(&payload[2 + mlen..2 + mlen + slen]).is_ok();
            if utf8 && level <= 3 {
                assert_eq!(out, &payload[..3 + mlen + slen], "text message re-encodes");
            }
            assert_eq!(TextLevel::from_byte(m.level.to_byte()), m.level);
        }
        Err(e) => {
            let _ = e.to_string();
        }
    }
    if let Some(v) = ControllerVersion::decode(payload) {
        assert_eq!(v.encode(), payload);
        let _ = v.to_string();
    }
    // A setup reply: recipe id, then a comma-separated word list.
    if let Some((_, words)) = payload.split_first() {
        let text = String::from_utf8_lossy(words);
        for word in wire::split_names(&text).take(64) {
            assert!(!word.is_empty() && !word.contains(',') && word.trim() == word);
            if let Some(field) = SetupField::from_name(word) {
                assert_eq!(field.name(), word);
            }
            if let Some(ty) = RtdeType::from_name(word) {
                assert_eq!(ty.name(), word);
            }
        }
    }
}

/// A recipe from the input (count, then one type byte per field) and a data package's fields.
fn check_fields(data: &[u8]) {
    let mut b = Bytes::new(data);
    let count = usize::from(b.u8() % 17);
    let types: Vec<RtdeType> = b
        .take(count)
        .iter()
        .map(|t| RtdeType::ALL[usize::from(*t) % RtdeType::ALL.len()])
        .collect();
    let bytes = b.rest();
    let mut out: Vec<RtdeValue> = types.iter().map(|t| RtdeValue::zero(*t)).collect();
    match decode_fields(&types, bytes, &mut out) {
        Ok(()) => {
            let expected: usize = types.iter().map(|t| t.wire_len()).sum();
            assert_eq!(bytes.len(), expected);
            for (value, ty) in out.iter().zip(&types) {
                assert_eq!(value.rtde_type(), *ty);
            }
            let mut again = Vec::new();
            if let Err(e) = encode_fields(&types, &out, &mut again) {
                panic!("decoded values re-encode: {e}");
            }
            if types.contains(&RtdeType::Bool) {
                // Any non-zero byte reads as true and writes as 1.
                assert_eq!(again.len(), bytes.len());
                let mut twice: Vec<RtdeValue> = out.clone();
                if let Err(e) = decode_fields(&types, &again, &mut twice) {
                    panic!("re-encoded values decode: {e}");
                }
                let mut thrice = Vec::new();
                if let Err(e) = encode_fields(&types, &twice, &mut thrice) {
                    panic!("{e}");
                }
                assert_eq!(thrice, again);
            } else {
                assert_eq!(again, bytes, "field values re-encode byte for byte");
            }
        }
        Err(e) => {
            let _ = e.to_string();
        }
    }
}

/// Input recipe of the harness (the arm's watchdog register and one more type).
const INPUTS: [&str; 2] = ["input_int_register_24", "input_double_register_24"];

fn package(ty: u8, payload: &[u8]) -> Vec<u8> {
    let mut out = ((payload.len() + HEADER_LEN) as u16).to_be_bytes().to_vec();
    out.push(ty);
    out.extend_from_slice(payload);
    out
}

/// The controller's replies to a complete, successful handshake of the arm's recipe.
pub(crate) fn canned_rtde_handshake() -> Vec<u8> {
    let mut out = package(b'V', &[1]);
    let mut version = Vec::new();
    for v in [5u32, 21, 0, 42] {
        version.extend_from_slice(&v.to_be_bytes());
    }
    out.extend(package(b'v', &version));
    let types: Vec<&str> = ARM_OUTPUTS.iter().map(|(_, t)| t.name()).collect();
    let mut reply = vec![7u8];
    reply.extend_from_slice(types.join(",").as_bytes());
    out.extend(package(b'O', &reply));
    out.extend(package(b'I', b"\x02INT32,DOUBLE"));
    out.extend(package(b'S', &[1]));
    out
}

/// The RTDE client against a controller that sends the input's bytes (after the replies of a
/// good handshake when bit 0 of the first byte is set), through connect, version, both recipes,
/// start, up to 16 receives (bit 1: `receive_latest`, else `receive_newest`), an input package
/// and pause. A good handshake must succeed whatever follows it; a received package always
/// has the recipe's types, and its sequence number grows by the packages it replaced plus one.
pub fn rtde_client(data: &[u8]) {
    let (mode, stream) = controller_bytes(data);
    let (canned, latest) = (mode & 1 == 1, mode & 2 == 2);
    let server = OneShotServer::serve(stream);
    let timeouts = RtdeTimeouts {
        connect: Duration::from_secs(2),
        reply: Duration::from_secs(2),
        write: Duration::from_secs(1),
    };
    match RtdeClient::connect(server.addr(), timeouts) {
        Ok(client) => rtde_session(client, canned, latest),
        Err(e) => assert!(!canned, "a good handshake was refused: {e}"),
    }
    drop(server);
}

/// As [`rtde_client`], in memory: the controller's bytes arrive at most `mode >> 2` bytes a read
/// (0: all that fit), and every write must be one whole package.
pub fn rtde_stream(data: &[u8]) {
    let (mode, stream) = controller_bytes(data);
    let (canned, latest) = (mode & 1 == 1, mode & 2 == 2);
    let transport = ScriptedStream::new(&stream, usize::from(mode >> 2));
    match RtdeClient::over(transport, RtdeTimeouts::default()) {
        Ok(client) => rtde_session(client, canned, latest),
        Err(e) => assert!(!canned, "a good handshake was refused: {e}"),
    }
}

/// The input's mode byte and what the controller sends: the replies of a good handshake when bit
/// 0 of the mode is set, then the rest of the input.
fn controller_bytes(data: &[u8]) -> (u8, Vec<u8>) {
    let mut b = Bytes::new(data);
    let mode = b.u8();
    let mut stream = if mode & 1 == 1 {
        canned_rtde_handshake()
    } else {
        Vec::new()
    };
    stream.extend_from_slice(b.rest());
    (mode, stream)
}

/// Version, both recipes, start, up to 16 receives, an input package and pause, on a connected
/// client.
fn rtde_session<T: Transport>(mut client: RtdeClient<T>, canned: bool, latest: bool) {
    assert_eq!(client.state(), RtdeState::Paused);
    let version = client.controller_version();
    if canned {
        let expected = ControllerVersion {
            major: 5,
            minor: 21,
            bugfix: 0,
            build: 42,
        };
        assert_eq!(version.ok(), Some(expected));
    }
    let names: Vec<&str> = ARM_OUTPUTS.iter().map(|(n, _)| *n).collect();
    match client.setup_outputs(&names, 500.0) {
        Ok(recipe) => {
            assert_eq!(recipe.names, names);
            assert_eq!(recipe.types.len(), names.len());
            if canned {
                let types: Vec<RtdeType> = ARM_OUTPUTS.iter().map(|(_, t)| *t).collect();
                assert_eq!(recipe.types, types);
            }
        }
        Err(e) => assert!(!canned, "good output setup reply refused: {e}"),
    }
    let inputs = client.setup_inputs(&INPUTS);
    match &inputs {
        Ok(recipe) => assert!(recipe.id != 0 && recipe.types.len() == INPUTS.len()),
        Err(e) => assert!(!canned, "good input setup reply refused: {e}"),
    }
    let start = client.start();
    if client.output_recipe().is_none() {
        assert!(matches!(start, Err(RtdeRequestError::NotAllowed { .. })));
    }
    assert!(!canned || start.is_ok(), "good start reply refused");
    assert_eq!(client.state() == RtdeState::Started, start.is_ok());
    if let Some(recipe) = client.output_recipe().cloned() {
        if client.state() == RtdeState::Started {
            let mut pkg = DataPackage::for_recipe(&recipe);
            let mut last_sequence = 0;
            for _ in 0..16 {
                let got = if latest {
                    client
                        .receive_latest(&mut pkg, Duration::from_secs(2))
                        .map(|()| true)
                } else {
                    client.receive_newest(&mut pkg, Duration::from_secs(2))
                };
                match got {
                    Ok(true) => {
                        for (value, ty) in pkg.values.iter().zip(&recipe.types) {
                            assert_eq!(value.rtde_type(), *ty);
                        }
                        assert_eq!(pkg.values.len(), recipe.types.len());
                        assert_eq!(
                            pkg.sequence - last_sequence,
                            u64::from(pkg.skipped) + 1,
                            "sequence {} after {last_sequence} with {} skipped",
                            pkg.sequence,
                            pkg.skipped
                        );
                        last_sequence = pkg.sequence;
                    }
                    Ok(false) => {}
                    Err(RtdeReceiveError::NotStarted) => panic!("receive refused while started"),
                    Err(e) => {
                        let _ = e.to_string();
                        break;
                    }
                }
            }
        }
    }
    if let Ok(input) = &inputs {
        let values: Vec<RtdeValue> = input.types.iter().map(|t| RtdeValue::zero(*t)).collect();
        let _ = client.send_inputs(input, &values);
    }
    let _ = client.pause();
    let _ = client.text_messages();
    client.disconnect();
}
