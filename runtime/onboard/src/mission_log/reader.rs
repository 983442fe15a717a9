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
        let records = Records::new(bytes);
        let mut topics: BTreeMap<u16, Option<Channel>> = BTreeMap::new();
        for record in records {
            let record = match record {
                Ok(r) => r,
                Err(detail) if log.messages.is_empty() && log.metadata.is_empty() => {
                    return Err(LogError::Mcap {
                        path: path.to_owned(),
                        stage: "reading records",
                        detail,
                    });
                }
                Err(detail) => {
                    log.truncated = Some(detail);
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

/// Largest record the reader loads, compressed or not (a logged camera frame is about 5 MB of
/// JSON; the writer's whole queue is 64 MiB). A record claiming more is an error.
pub const MAX_RECORD_BYTES: usize = 256 << 20;

/// MCAP opcodes of the records the log is read for.
const CHANNEL: u8 = 0x04;
const MESSAGE: u8 = 0x05;
const METADATA: u8 = 0x0C;

/// The records of an MCAP file held in memory that a [`MissionLog`] uses (channels, messages,
/// metadata), chunks unpacked. Every length the file claims is checked against the bytes that
/// are there before anything is allocated for it: each record's length against
/// [`MAX_RECORD_BYTES`], and the strings and maps of the channel and metadata records against
/// their record. Other records are skipped unparsed. (The mcap crate's `ChunkFlattener` set no
/// record limit and sized its buffer by the claimed length, and its record parser reserves what a
/// field claims before reading it: a 5 KB file claiming a 1 PiB record aborted the process on the
/// failed allocation, a 2 KB one made it reserve 4 GiB. Found by fuzzing, docs/fuzzing.md.)
struct Records<'a> {
    reader: mcap::sans_io::LinearReader,
    unread: &'a [u8],
}

impl<'a> Records<'a> {
    fn new(bytes: &'a [u8]) -> Self {
        let options = mcap::sans_io::LinearReaderOptions::default()
            .with_skip_end_magic(true)
            .with_record_length_limit(MAX_RECORD_BYTES);
        Self {
            reader: mcap::sans_io::LinearReader::new_with_options(options),
            unread: bytes,
        }
    }
}

impl Iterator for Records<'_> {
    type Item = Result<mcap::records::Record<'static>, String>;

    fn next(&mut self) -> Option<Self::Item> {
        while let Some(event) = self.reader.next_event() {
            match event {
                Ok(mcap::sans_io::LinearReadEvent::ReadRequest(wanted)) => {
                    let n = wanted.min(self.unread.len());
                    self.reader.insert(n).copy_from_slice(&self.unread[..n]);
                    self.reader.notify_read(n);
                    self.unread = &self.unread[n..];
                }
                Ok(mcap::sans_io::LinearReadEvent::Record { data, opcode }) => {
                    if !matches!(opcode, CHANNEL | MESSAGE | METADATA) {
                        continue;
                    }
                    if let Err(detail) = fields_fit(opcode, data) {
                        return Some(Err(detail));
                    }
                    let record = mcap::parse_record(opcode, data);
                    return Some(record.map(|r| r.into_owned()).map_err(|e| e.to_string()));
                }
                Err(e) => return Some(Err(e.to_string())),
            }
        }
        None
    }
}

/// Checks that the length-prefixed fields of a channel or metadata record (strings: u32 length
/// and bytes; maps: u32 byte length and key/value strings) lie within the record's `body`.
fn fields_fit(opcode: u8, body: &[u8]) -> Result<(), String> {
    let too_long = |claimed: usize, at: usize| {
        format!(
            "record {opcode:#04x}: a field at byte {at} claims {claimed} bytes, the record holds {}",
            body.len()
        )
    };
    // The length at `at`, checked against what follows it; `at` moves past the length.
    let length = |at: &mut usize| -> Result<usize, String> {
        let bytes = body.get(*at..*at + 4).ok_or_else(|| too_long(4, *at))?;
        let n = u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]) as usize;
        *at += 4;
        if n > body.len() - *at {
            return Err(too_long(n, *at - 4));
        }
        Ok(n)
    };
    let string = |at: &mut usize| -> Result<(), String> {
        let n = length(at)?;
        *at += n;
        Ok(())
    };
    let map = |at: &mut usize| -> Result<(), String> {
        let n = length(at)?;
        let end = *at + n;
        while *at < end {
            string(at)?;
            string(at)?;
        }
        Ok(())
    };
    let mut at = 0;
    match opcode {
        CHANNEL => {
            at = 4; // channel id, schema id
            string(&mut at)?; // topic
            string(&mut at)?; // message encoding
            map(&mut at)
        }
        METADATA => {
            string(&mut at)?; // name
            map(&mut at)
        }
        _ => Ok(()),
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

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;

    use super::*;
    use crate::mission_log::{LogWriter, WriterConfig};

    /// A small log: metadata and two messages, as the writer makes it.
    fn small_log() -> Vec<u8> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("small.mcap");
        let mut metadata = BTreeMap::new();
        metadata.insert(
            "grop.mission".to_owned(),
            BTreeMap::from([("seed".to_owned(), "1".to_owned())]),
        );
        let writer = LogWriter::create(&path, metadata, WriterConfig::default()).unwrap();
        writer.push(
            Channel::Can,
            1,
            1,
            br#"{"id":1280,"extended":false,"data":[1]}"#.to_vec(),
        );
        writer.push(
            Channel::Can,
            2,
            2,
            br#"{"id":1281,"extended":false,"data":[]}"#.to_vec(),
        );
        writer.finish().unwrap();
        std::fs::read(&path).unwrap()
    }

    #[test]
    fn a_log_reads_back_with_its_metadata_and_messages() {
        let log = MissionLog::from_bytes(&small_log(), Path::new("small.mcap")).unwrap();
        assert_eq!(log.messages.len(), 2);
        assert_eq!(log.messages[1].log_time, 2);
        assert_eq!(log.metadata["grop.mission"]["seed"], "1");
        assert!(log.truncated.is_none());
    }

    fn record(opcode: u8, body: &[u8]) -> Vec<u8> {
        let mut out = vec![opcode];
        out.extend_from_slice(&(body.len() as u64).to_le_bytes());
        out.extend_from_slice(body);
        out
    }

    fn string(out: &mut Vec<u8>, s: &str) {
        out.extend_from_slice(&(s.len() as u32).to_le_bytes());
        out.extend_from_slice(s.as_bytes());
    }

    /// An MCAP file whose one zstd chunk holds a message record that claims `claimed` bytes.
    fn log_with_chunk_record_claiming(claimed: u64) -> Vec<u8> {
        // The chunk's content: a message record header (opcode 0x05, u64 length) and 8 bytes.
        let mut content = vec![0x05];
        content.extend_from_slice(&claimed.to_le_bytes());
        content.extend_from_slice(&[0; 8]);
        // A zstd frame holding it as one raw (stored) block: magic, frame header descriptor
        // 0x20 (single segment, 1-byte content size), content size, block header (last block,
        // raw, size), the bytes.
        let mut frame = vec![0x28, 0xB5, 0x2F, 0xFD, 0x20, content.len() as u8];
        let block_header = 1 | ((content.len() as u32) << 3);
        frame.extend_from_slice(&block_header.to_le_bytes()[..3]);
        frame.extend_from_slice(&content);
        let mut chunk = Vec::new();
        chunk.extend_from_slice(&0u64.to_le_bytes()); // message start time
        chunk.extend_from_slice(&0u64.to_le_bytes()); // message end time
        chunk.extend_from_slice(&(content.len() as u64).to_le_bytes()); // uncompressed size
        chunk.extend_from_slice(&0u32.to_le_bytes()); // uncompressed CRC: none
        string(&mut chunk, "zstd");
        chunk.extend_from_slice(&(frame.len() as u64).to_le_bytes());
        chunk.extend_from_slice(&frame);
        let mut header = Vec::new();
        string(&mut header, "");
        string(&mut header, "test");
        let mut file = b"\x89MCAP0\r\n".to_vec();
        file.extend(record(0x01, &header));
        file.extend(record(0x06, &chunk));
        file
    }

    #[test]
    fn a_record_claiming_a_huge_length_is_an_error_not_an_allocation() {
        // A record inside a compressed chunk claiming 1 PiB: the mcap crate's chunk flattener
        // sized its buffer by the claim and the process aborted on the failed allocation.
        let bytes = log_with_chunk_record_claiming(1 << 50);
        match MissionLog::from_bytes(&bytes, Path::new("huge.mcap")) {
            Err(e) => assert!(e.to_string().contains("exceeds limit"), "{e}"),
            Ok(log) => panic!("read {} messages", log.messages.len()),
        }
        // Within the limit the same record reaches the record parser (and is too short for a
        // message): the chunk itself is read as before.
        match MissionLog::from_bytes(&log_with_chunk_record_claiming(8), Path::new("s.mcap")) {
            Err(e) => assert!(e.to_string().contains("parse"), "{e}"),
            Ok(log) => panic!("read {} messages", log.messages.len()),
        }
    }

    #[test]
    fn a_string_claiming_more_than_its_record_holds_is_an_error() {
        // A metadata record whose name claims 4 GiB: the record parser reserved that much
        // before finding the bytes missing (found by fuzzing as a 2 KB log).
        let mut metadata = Vec::new();
        metadata.extend_from_slice(&0xFF00_0000u32.to_le_bytes());
        metadata.extend_from_slice(b"grop.mission");
        let mut header = Vec::new();
        string(&mut header, "");
        string(&mut header, "test");
        let mut file = b"\x89MCAP0\r\n".to_vec();
        file.extend(record(0x01, &header));
        file.extend(record(0x0C, &metadata));
        match MissionLog::from_bytes(&file, Path::new("long-name.mcap")) {
            Err(e) => assert!(e.to_string().contains("claims 4278190080 bytes"), "{e}"),
            Ok(log) => panic!("read {:?}", log.metadata),
        }
        // The same record with its true length reads.
        let mut good = Vec::new();
        string(&mut good, "grop.mission");
        good.extend_from_slice(&0u32.to_le_bytes()); // an empty map
        let mut file = b"\x89MCAP0\r\n".to_vec();
        file.extend(record(0x01, &header));
        file.extend(record(0x0C, &good));
        let log = MissionLog::from_bytes(&file, Path::new("good.mcap")).unwrap();
        assert!(log.metadata["grop.mission"].is_empty());
    }
}
