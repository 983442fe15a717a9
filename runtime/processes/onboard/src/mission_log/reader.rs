//! Reading a mission log back: every message of a known channel in file order, the metadata,
//! and the digest that says whether two runs logged the same thing.

use std::collections::BTreeMap;
use std::path::Path;

use sha2::{Digest, Sha256};

use super::codec::Channel;
use super::{LOG_FORMAT, LOG_METADATA, LogError, OLDEST_LOG_FORMAT};

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
#[derive(Debug, Clone)]
pub struct MissionLog {
    /// The format version it is written in (`log_format` of the [`LOG_METADATA`] record; 1 for
    /// a log without it), between [`OLDEST_LOG_FORMAT`] and [`LOG_FORMAT`]. Decoders of a
    /// message whose shape changed between versions choose by it.
    pub log_format: u32,
    /// Metadata records: name -> key/value pairs.
    pub metadata: BTreeMap<String, BTreeMap<String, String>>,
    /// Messages of known channels, in file order.
    pub messages: Vec<LoggedMessage>,
    /// Messages on topics this build does not know (skipped).
    pub unknown: u64,
    /// The file ended early (a recorder that was killed): what came before is here.
    pub truncated: Option<String>,
}

impl Default for MissionLog {
    fn default() -> Self {
        Self {
            log_format: OLDEST_LOG_FORMAT,
            metadata: BTreeMap::new(),
            messages: Vec::new(),
            unknown: 0,
            truncated: None,
        }
    }
}

/// The format version a [`LOG_METADATA`] record names, checked against the versions this build
/// reads.
fn format_of(pairs: &BTreeMap<String, String>, path: &Path) -> Result<u32, LogError> {
    let Some(value) = pairs.get("log_format") else {
        return Ok(OLDEST_LOG_FORMAT);
    };
    let found: u32 = value.trim().parse().map_err(|_| LogError::BadFormat {
        path: path.to_owned(),
        value: value.clone(),
    })?;
    if (OLDEST_LOG_FORMAT..=LOG_FORMAT).contains(&found) {
        Ok(found)
    } else {
        Err(LogError::UnknownFormat {
            path: path.to_owned(),
            found,
        })
    }
}

impl MissionLog {
    /// Reads `path`. A file cut short (the recorder was killed) reads up to the cut, with
    /// [`MissionLog::truncated`] set; a file that is not MCAP at all is an error.
    pub fn read(path: &Path) -> Result<Self, LogError> {
        let bytes = std::fs::read(path).map_err(|e| LogError::io(path, "reading", e))?;
        Self::from_bytes(&bytes, path)
    }

    /// Reads a log held in memory (`path` names it in errors). A log in a format this build
    /// does not read is an error naming the version, before any of its messages is taken.
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
                    if m.name == LOG_METADATA {
                        log.log_format = format_of(&m.metadata, path)?;
                    }
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
///
/// Uncompressed chunks are checked before the reader sees them ([`first_overrunning_chunk`]):
/// the file is read up to the first chunk whose records overrun it, and that chunk is reported
/// as the error (after what came before it, which is kept).
struct Records<'a> {
    reader: mcap::sans_io::LinearReader,
    unread: &'a [u8],
    /// Why the file is read only up to `unread`'s end, reported once the reader is done.
    cut: Option<String>,
}

impl<'a> Records<'a> {
    fn new(bytes: &'a [u8]) -> Self {
        let options = mcap::sans_io::LinearReaderOptions::default()
            .with_skip_end_magic(true)
            .with_record_length_limit(MAX_RECORD_BYTES);
        let (unread, cut) = match first_overrunning_chunk(bytes) {
            Some((at, detail)) => (&bytes[..at], Some(detail)),
            None => (bytes, None),
        };
        Self {
            reader: mcap::sans_io::LinearReader::new_with_options(options),
            unread,
            cut,
        }
    }
}

/// MCAP's magic, at the start (and end) of a file.
const MAGIC_LEN: usize = 8;
/// A record's opcode (1 byte) and length (u64).
const RECORD_HEADER: usize = 9;
const CHUNK: u8 = 0x06;

/// The byte offset of the first top-level chunk record whose records overrun it, uncompressed:
/// its records claim more than the chunk holds, or a record claims more than the chunk's
/// records have left. With why. (The mcap crate subtracts each inner record's length from what
/// the chunk has left without checking: an overflow panic in a debug build, and in a release
/// build a wrapped count after which the records of the rest of the file are read as the
/// chunk's. Found by fuzzing, docs/fuzzing.md.) A chunk cut short by the file's end is checked
/// as far as its bytes go (the crate reads its records from what is there). Compressed chunks
/// are checked by the crate against their decompressed size.
fn first_overrunning_chunk(bytes: &[u8]) -> Option<(usize, String)> {
    let mut at = MAGIC_LEN;
    loop {
        let header = bytes.get(at..at.checked_add(RECORD_HEADER)?)?;
        let len = usize::try_from(u64::from_le_bytes(header[1..].try_into().ok()?)).ok()?;
        let start = at + RECORD_HEADER;
        let end = start.checked_add(len)?;
        let whole = end <= bytes.len();
        if header[0] == CHUNK {
            let body = &bytes[start..end.min(bytes.len())];
            if let Some(why) = chunk_overrun(body, whole) {
                return Some((at, format!("chunk record at byte {at}: {why}")));
            }
        }
        if !whole {
            return None;
        }
        at = end;
    }
}

/// Why the records of an uncompressed chunk `body` overrun it, if they do; `whole`: the body is
/// all of the chunk (not cut short by the file's end).
fn chunk_overrun(body: &[u8], whole: bool) -> Option<String> {
    // Message start and end times, uncompressed size (u64 each), uncompressed CRC (u32), then
    // the compression name (u32 length and bytes) and the records' size (u64).
    let u32_at = |at: usize| -> Option<usize> {
        let b = body.get(at..at.checked_add(4)?)?;
        Some(u32::from_le_bytes(b.try_into().ok()?) as usize)
    };
    let u64_at = |at: usize| -> Option<u64> {
        let b = body.get(at..at.checked_add(8)?)?;
        Some(u64::from_le_bytes(b.try_into().ok()?))
    };
    let name_len = u32_at(28)?;
    if name_len != 0 {
        return None;
    }
    let records_size = u64_at(32)?;
    let records_start = 40;
    let held = body.len().checked_sub(records_start)? as u64;
    if whole && records_size > held {
        return Some(format!(
            "its records claim {records_size} bytes, it holds {held}"
        ));
    }
    let mut left = records_size;
    let mut at = records_start;
    while left > 0 {
        if left < RECORD_HEADER as u64 {
            return Some(format!(
                "{left} bytes left of its records, less than a record header"
            ));
        }
        let len = u64_at(at + 1)?;
        if len > left - RECORD_HEADER as u64 {
            return Some(format!(
                "a record at byte {at} of it claims {len} bytes, {} are left",
                left - RECORD_HEADER as u64
            ));
        }
        left -= RECORD_HEADER as u64 + len;
        at += RECORD_HEADER + len as usize;
    }
    None
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
                Err(e) => {
                    // Past the cut the reader only sees the file end: the cut is the reason.
                    let detail = match self.cut.take() {
                        Some(cut) if self.unread.is_empty() => cut,
                        _ => e.to_string(),
                    };
                    return Some(Err(detail));
                }
            }
        }
        self.cut.take().map(Err)
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

    /// An uncompressed chunk record whose one inner record claims `claimed` bytes while the
    /// chunk's records hold 20.
    fn overrunning_chunk(claimed: u64) -> Vec<u8> {
        let mut body = vec![0u8; 28]; // times, uncompressed size, CRC
        body.extend(0u32.to_le_bytes()); // no compression
        body.extend(20u64.to_le_bytes()); // records' size
        body.push(MESSAGE);
        body.extend(claimed.to_le_bytes());
        body.extend([0u8; 11]);
        let mut record = vec![CHUNK];
        record.extend((body.len() as u64).to_le_bytes());
        record.extend(body);
        record
    }

    /// A chunk whose record claims more than the chunk holds is an error that names it, not an
    /// overflow panic inside the mcap crate (a debug build) or the rest of the file read as
    /// the chunk's records (a release build); what the file held before it is kept, and a
    /// record that fits its chunk exactly is fine. (Found by the `mission_log` fuzz target.)
    #[test]
    fn a_chunk_overrun_by_its_records_is_reported_and_what_came_before_kept() {
        // Alone after the magic and a header record: nothing read, an error.
        let mut bytes = b"\x89MCAP0\r\n".to_vec();
        bytes.extend([0x01, 8, 0, 0, 0, 0, 0, 0, 0]);
        bytes.extend([0u8; 8]);
        let chunk_at = bytes.len();
        bytes.extend(overrunning_chunk(1000));
        // Enough bytes after it for the crate to read the claimed record from.
        bytes.extend([0u8; 1100]);
        // The file is refused, naming the chunk and the record's claim.
        let refused_naming = |file: &[u8], claim: &str| {
            let text = MissionLog::from_bytes(file, Path::new("overrun.mcap"))
                .unwrap_err()
                .to_string();
            assert!(
                text.contains(&format!("chunk record at byte {chunk_at}")) && text.contains(claim),
                "{text}"
            );
        };
        refused_naming(&bytes, "claims 1000 bytes, 11 are left");
        // Exactly filling its chunk, the same record is no error.
        assert_eq!(chunk_overrun(&overrunning_chunk(11)[9..], true), None);

        // A chunk cut short by the file's end (it claims 24,864 bytes) whose record still
        // overruns its records' size with the bytes that are there: the same error.
        let mut short = bytes[..chunk_at].to_vec();
        let mut chunk = overrunning_chunk(30);
        chunk[1..9].copy_from_slice(&24_864u64.to_le_bytes());
        short.extend(chunk);
        short.extend([0u8; 40]);
        refused_naming(&short, "claims 30 bytes, 11 are left");

        // After a log's messages (before its data-end record): they are kept, the log is
        // marked truncated with the chunk as the reason.
        let good = small_log();
        let mut at = MAGIC_LEN;
        while good[at] != 0x0F {
            let len = u64::from_le_bytes(good[at + 1..at + 9].try_into().unwrap()) as usize;
            at += RECORD_HEADER + len;
        }
        let mut spliced = good[..at].to_vec();
        spliced.extend(overrunning_chunk(30));
        spliced.extend(&good[at..]);
        let log = MissionLog::from_bytes(&spliced, Path::new("spliced.mcap")).unwrap();
        let whole = MissionLog::from_bytes(&good, Path::new("small.mcap")).unwrap();
        assert_eq!(log.messages, whole.messages);
        assert!(!log.messages.is_empty());
        let why = log.truncated.as_deref().unwrap_or_default();
        assert!(why.contains(&format!("chunk record at byte {at}")), "{why}");
    }

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
        assert_eq!(log.log_format, LOG_FORMAT);
        assert_eq!(
            log.metadata[LOG_METADATA]["log_format"],
            LOG_FORMAT.to_string()
        );
    }

    /// A log of a header and one metadata record `name` holding `pairs`.
    fn log_with_metadata(name: &str, pairs: &[(&str, &str)]) -> Vec<u8> {
        let mut map = Vec::new();
        for (k, v) in pairs {
            string(&mut map, k);
            string(&mut map, v);
        }
        let mut body = Vec::new();
        string(&mut body, name);
        body.extend_from_slice(&(map.len() as u32).to_le_bytes());
        body.extend(map);
        let mut header = Vec::new();
        string(&mut header, "");
        string(&mut header, "test");
        let mut file = b"\x89MCAP0\r\n".to_vec();
        file.extend(record(0x01, &header));
        file.extend(record(0x0C, &body));
        file
    }

    #[test]
    fn the_format_version_is_read_and_an_unknown_one_is_refused_by_number() {
        // No format record: version 1 (every log before issue 23).
        let v1 = log_with_metadata("grop.mission", &[("seed", "1")]);
        let log = MissionLog::from_bytes(&v1, Path::new("v1.mcap")).unwrap();
        assert_eq!(log.log_format, 1);
        for known in ["1", "2", "3", "4", "5", "6", "7"] {
            let bytes = log_with_metadata(LOG_METADATA, &[("log_format", known)]);
            let log = MissionLog::from_bytes(&bytes, Path::new("k.mcap")).unwrap();
            assert_eq!(log.log_format.to_string(), known);
        }
        // A version from the future, and zero: refused, naming the version and the file.
        for (found, shown) in [("8", "log_format 8"), ("0", "log_format 0")] {
            let bytes = log_with_metadata(LOG_METADATA, &[("log_format", found)]);
            match MissionLog::from_bytes(&bytes, Path::new("future.mcap")) {
                Err(e @ LogError::UnknownFormat { .. }) => {
                    let text = e.to_string();
                    assert!(
                        text.contains(shown) && text.contains("future.mcap"),
                        "{text}"
                    );
                    assert!(text.contains("(1 to 7)"), "{text}");
                }
                other => panic!("log_format {found}: {other:?}"),
            }
        }
        let bytes = log_with_metadata(LOG_METADATA, &[("log_format", "two")]);
        match MissionLog::from_bytes(&bytes, Path::new("bad.mcap")) {
            Err(e @ LogError::BadFormat { .. }) => assert!(e.to_string().contains("\"two\"")),
            other => panic!("{other:?}"),
        }
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
