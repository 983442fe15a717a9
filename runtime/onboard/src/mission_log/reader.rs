//! Reading a mission log back: every message of a known channel in file order, the metadata,
//! and the digest that says whether two runs logged the same thing.

use std::collections::BTreeMap;
use std::path::Path;

use sha2::{Digest, Sha256};

use super::LogError;
use super::codec::Channel;

/// One logged message.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LoggedMessage {
    /// Its channel.
    pub channel: Channel,
    /// When the recorder took it (runtime clock, ns).
    pub log_time: u64,
    /// When it was published (the message's own stamp, ns).
    pub publish_time: u64,
    /// The JSON payload.
    pub data: Vec<u8>,
}

/// A mission log in memory.
#[derive(Debug, Clone, Default)]
pub struct MissionLog {
    /// Metadata records: name -> key/value pairs.
    pub metadata: BTreeMap<String, BTreeMap<String, String>>,
    /// Messages of known channels, in file order.
    pub messages: Vec<LoggedMessage>,
    /// Messages on topics this build does not know (skipped).
    pub unknown: u64,
    /// The file ended early (a recorder that was killed): what came before is here.
    pub truncated: Option<String>,
}

impl MissionLog {
    /// Reads `path`. A file cut short (the recorder was killed) reads up to the cut, with
    /// [`MissionLog::truncated`] set; a file that is not MCAP at all is an error.
    pub fn read(path: &Path) -> Result<Self, LogError> {
        let bytes = std::fs::read(path).map_err(|e| LogError::io(path, "reading", e))?;
        Self::from_bytes(&bytes, path)
    }

    /// Reads a log held in memory (`path` names it in errors).
    pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<Self, LogError> {
        let mut log = MissionLog::default();
        let records = mcap::read::ChunkFlattener::new_with_options(
            bytes,
            mcap::read::Options::IgnoreEndMagic.into(),
        )
        .map_err(|e| LogError::mcap(path, "opening", e))?;
        let mut topics: BTreeMap<u16, Option<Channel>> = BTreeMap::new();
        for record in records {
            let record = match record {
                Ok(r) => r,
                Err(e) if log.messages.is_empty() && log.metadata.is_empty() => {
                    return Err(LogError::mcap(path, "reading records", e));
                }
                Err(e) => {
                    log.truncated = Some(e.to_string());
                    break;
                }
            };
            match record {
                mcap::records::Record::Channel(c) => {
                    topics.insert(c.id, Channel::from_topic(&c.topic));
                }
                mcap::records::Record::Metadata(m) => {
                    log.metadata.insert(m.name, m.metadata);
                }
                mcap::records::Record::Message { header, data } => {
                    match topics.get(&header.channel_id).copied().flatten() {
                        Some(channel) => log.messages.push(LoggedMessage {
                            channel,
                            log_time: header.log_time,
                            publish_time: header.publish_time,
                            data: data.into_owned(),
                        }),
                        None => log.unknown += 1,
                    }
                }
                _ => {}
            }
        }
        Ok(log)
    }

    /// The messages of one channel, in order.
    pub fn channel(&self, channel: Channel) -> impl Iterator<Item = &LoggedMessage> {
        self.messages.iter().filter(move |m| m.channel == channel)
    }

    /// See [`digest`].
    pub fn digest(&self) -> String {
        digest(&self.messages)
    }
}

/// SHA-256 over channel, log time and payload of every message in order, skipping the
/// wall-clock measurements under `/timing/`: two runs of one mission on a simulated clock give
/// the same digest exactly when they logged the same messages at the same simulated times.
pub fn digest(messages: &[LoggedMessage]) -> String {
    let mut h = Sha256::new();
    for m in messages {
        let topic = m.channel.topic();
        if topic.starts_with("/timing/") {
            continue;
        }
        h.update((topic.len() as u32).to_le_bytes());
        h.update(topic.as_bytes());
        h.update(m.log_time.to_le_bytes());
        h.update((m.data.len() as u64).to_le_bytes());
        h.update(&m.data);
    }
    h.finalize()
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect::<String>()
}
