//! The Foxglove WebSocket protocol (subprotocol `foxglove.websocket.v1`), the part a viewer
//! server needs: what the server sends (`serverInfo`, `advertise`, `status`, binary message data
//! and time) and what a client may send (`subscribe`, `unsubscribe`, and everything a viewer
//! refuses: `advertise`, client message data, service calls, parameters, ...).
//!
//! Spec: <https://github.com/foxglove/ws-protocol/blob/main/docs/spec.md>. Text messages are JSON
//! objects with an `op` field; binary messages start with a one-byte opcode, and integers are
//! little-endian.

use serde::Deserialize;
use serde_json::{Value, json};

use crate::mission_log::codec::Channel;

/// The WebSocket subprotocol.
pub const SUBPROTOCOL: &str = "foxglove.websocket.v1";
/// Server binary opcode: a message on a subscription.
pub const OP_MESSAGE_DATA: u8 = 0x01;
/// Server binary opcode: the server's time.
pub const OP_TIME: u8 = 0x02;
/// Client binary opcode: a message the client publishes on a channel it advertised.
pub const OP_CLIENT_MESSAGE_DATA: u8 = 0x01;
/// Client binary opcode: a service call.
pub const OP_SERVICE_CALL_REQUEST: u8 = 0x02;

/// Status levels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Level {
    /// For information.
    Info = 0,
    /// Something the client should know.
    Warning = 1,
    /// A request that failed.
    Error = 2,
}

/// The channel id a [`Channel`] is advertised with (its place in [`Channel::ALL`], from 1).
pub fn channel_id(c: Channel) -> u32 {
    Channel::ALL.iter().position(|x| *x == c).unwrap_or(0) as u32 + 1
}

/// The channel advertised with `id`.
pub fn channel_of(id: u32) -> Option<Channel> {
    let i = usize::try_from(id).ok()?.checked_sub(1)?;
    Channel::ALL.get(i).copied()
}

/// `serverInfo`: the first message to every client. `time`: whether the server publishes its
/// time (the simulated clock); no other capability is claimed (no client publishing, services,
/// parameters or assets: a viewer).
pub fn server_info(name: &str, time: bool, session_id: &str) -> String {
    let capabilities: Vec<&str> = if time { vec!["time"] } else { vec![] };
    json!({
        "op": "serverInfo",
        "name": name,
        "capabilities": capabilities,
        "supportedEncodings": [],
        "metadata": {},
        "sessionId": session_id,
    })
    .to_string()
}

/// `advertise` of `channels`: the same topic, message encoding (`json`), schema name and JSON
/// Schema (`jsonschema`) as the mission log's channels.
pub fn advertise(channels: &[Channel]) -> String {
    let list: Vec<Value> = channels
        .iter()
        .map(|c| {
            json!({
                "id": channel_id(*c),
                "topic": c.topic(),
                "encoding": "json",
                "schemaName": c.schema_name(),
                "schemaEncoding": "jsonschema",
                "schema": c.schema().to_string(),
            })
        })
        .collect();
    json!({"op": "advertise", "channels": list}).to_string()
}

/// `status`.
pub fn status(level: Level, message: &str) -> String {
    json!({"op": "status", "level": level as u8, "message": message}).to_string()
}

/// Binary message data: opcode, subscription id (u32), log time (u64 ns), payload.
pub fn message_data(subscription: u32, log_time_ns: u64, payload: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(13 + payload.len());
    out.push(OP_MESSAGE_DATA);
    out.extend_from_slice(&subscription.to_le_bytes());
    out.extend_from_slice(&log_time_ns.to_le_bytes());
    out.extend_from_slice(payload);
    out
}

/// Binary time: opcode, time (u64 ns).
pub fn time(ns: u64) -> Vec<u8> {
    let mut out = Vec::with_capacity(9);
    out.push(OP_TIME);
    out.extend_from_slice(&ns.to_le_bytes());
    out
}

/// One subscription of a `subscribe` request.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct Subscription {
    /// The client's id for it (message data carries it).
    pub id: u32,
    /// The channel.
    pub channel_id: u32,
}

/// What a client asked, as a viewer server sees it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ClientRequest {
    /// `subscribe`.
    Subscribe(Vec<Subscription>),
    /// `unsubscribe`.
    Unsubscribe(Vec<u32>),
    /// A request a viewer refuses (the `op`, or the binary opcode's meaning): publishing
    /// (`advertise`, `unadvertise`, client message data), service calls, parameters, the
    /// connection graph, assets.
    Refused(String),
    /// Not a message of the protocol (why).
    Invalid(String),
}

#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
struct SubscribeBody {
    subscriptions: Vec<Subscription>,
}

#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
struct UnsubscribeBody {
    subscription_ids: Vec<u32>,
}

/// A client's text message.
pub fn parse_text(text: &str) -> ClientRequest {
    let value: Value = match serde_json::from_str(text) {
        Ok(v) => v,
        Err(e) => return ClientRequest::Invalid(format!("not JSON: {e}")),
    };
    let Some(op) = value.get("op").and_then(Value::as_str).map(str::to_owned) else {
        return ClientRequest::Invalid("a JSON message without an `op`".into());
    };
    match op.as_str() {
        "subscribe" => match serde_json::from_value::<SubscribeBody>(value) {
            Ok(b) => ClientRequest::Subscribe(b.subscriptions),
            Err(e) => ClientRequest::Invalid(format!("subscribe: {e}")),
        },
        "unsubscribe" => match serde_json::from_value::<UnsubscribeBody>(value) {
            Ok(b) => ClientRequest::Unsubscribe(b.subscription_ids),
            Err(e) => ClientRequest::Invalid(format!("unsubscribe: {e}")),
        },
        "advertise"
        | "unadvertise"
        | "getParameters"
        | "setParameters"
        | "subscribeParameterUpdates"
        | "unsubscribeParameterUpdates"
        | "subscribeConnectionGraph"
        | "unsubscribeConnectionGraph"
        | "fetchAsset" => ClientRequest::Refused(op),
        other => ClientRequest::Invalid(format!("unknown op {other:?}")),
    }
}

/// A client's binary message.
pub fn parse_binary(data: &[u8]) -> ClientRequest {
    match data.first() {
        Some(&OP_CLIENT_MESSAGE_DATA) => ClientRequest::Refused("client message data".into()),
        Some(&OP_SERVICE_CALL_REQUEST) => ClientRequest::Refused("service call request".into()),
        Some(op) => ClientRequest::Invalid(format!("unknown binary opcode {op:#04x}")),
        None => ClientRequest::Invalid("an empty binary message".into()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn server_info_claims_time_only_when_asked_and_nothing_else() {
        let v: Value = serde_json::from_str(&server_info("grop", true, "s1")).expect("json");
        assert_eq!(v["op"], "serverInfo");
        assert_eq!(v["name"], "grop");
        assert_eq!(v["capabilities"], json!(["time"]));
        assert_eq!(v["sessionId"], "s1");
        let v: Value = serde_json::from_str(&server_info("grop", false, "s1")).expect("json");
        assert_eq!(v["capabilities"], json!([]));
    }

    #[test]
    fn every_log_channel_is_advertised_as_the_log_writes_it() {
        let v: Value = serde_json::from_str(&advertise(&Channel::ALL)).expect("json");
        assert_eq!(v["op"], "advertise");
        let list = v["channels"].as_array().expect("channels");
        assert_eq!(list.len(), Channel::ALL.len());
        let mut ids = Vec::new();
        for (c, a) in Channel::ALL.iter().zip(list) {
            assert_eq!(a["topic"], c.topic());
            assert_eq!(a["encoding"], "json");
            assert_eq!(a["schemaName"], c.schema_name());
            assert_eq!(a["schemaEncoding"], "jsonschema");
            let schema: Value =
                serde_json::from_str(a["schema"].as_str().expect("schema is a string"))
                    .expect("schema is JSON");
            assert_eq!(schema, c.schema());
            let id = u32::try_from(a["id"].as_u64().expect("id")).expect("u32");
            assert_eq!(channel_of(id), Some(*c));
            ids.push(id);
        }
        ids.dedup();
        assert_eq!(ids.len(), Channel::ALL.len());
        assert_eq!(channel_of(0), None);
        assert_eq!(channel_of(Channel::ALL.len() as u32 + 1), None);
    }

    #[test]
    fn binary_messages_are_little_endian_with_their_opcode() {
        let m = message_data(0x0403_0201, 0x0c0b_0a09_0807_0605, b"{}");
        assert_eq!(
            m,
            [1, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, b'{', b'}'].to_vec()
        );
        assert_eq!(time(258), [2, 2, 1, 0, 0, 0, 0, 0, 0].to_vec());
    }

    #[test]
    fn status_carries_its_level() {
        let v: Value = serde_json::from_str(&status(Level::Error, "no")).expect("json");
        assert_eq!(v, json!({"op": "status", "level": 2, "message": "no"}));
    }

    #[test]
    fn subscribe_and_unsubscribe_parse() {
        assert_eq!(
            parse_text(r#"{"op":"subscribe","subscriptions":[{"id":7,"channelId":3}]}"#),
            ClientRequest::Subscribe(vec![Subscription {
                id: 7,
                channel_id: 3
            }])
        );
        assert_eq!(
            parse_text(r#"{"op":"unsubscribe","subscriptionIds":[7,8]}"#),
            ClientRequest::Unsubscribe(vec![7, 8])
        );
    }

    #[test]
    fn publishing_services_and_parameters_are_refused() {
        let advertise = r#"{"op":"advertise","channels":[{"id":1,"topic":"/cmd","encoding":"json","schemaName":"x"}]}"#;
        assert_eq!(
            parse_text(advertise),
            ClientRequest::Refused("advertise".into())
        );
        for op in [
            "getParameters",
            "setParameters",
            "unadvertise",
            "fetchAsset",
        ] {
            assert_eq!(
                parse_text(&format!(r#"{{"op":"{op}"}}"#)),
                ClientRequest::Refused(op.into())
            );
        }
        assert!(matches!(
            parse_binary(&[1, 1, 0, 0, 0, b'{', b'}']),
            ClientRequest::Refused(_)
        ));
        assert!(matches!(
            parse_binary(&[2, 0, 0, 0, 0]),
            ClientRequest::Refused(_)
        ));
    }

    #[test]
    fn garbage_is_invalid_not_a_panic() {
        for text in [
            "",
            "[]",
            "{}",
            r#"{"op":1}"#,
            r#"{"op":"subscribe"}"#,
            r#"{"op":"x"}"#,
        ] {
            assert!(
                matches!(parse_text(text), ClientRequest::Invalid(_)),
                "{text}"
            );
        }
        assert!(matches!(parse_binary(&[]), ClientRequest::Invalid(_)));
        assert!(matches!(parse_binary(&[9]), ClientRequest::Invalid(_)));
    }
}
