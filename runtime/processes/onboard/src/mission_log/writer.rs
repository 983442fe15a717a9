//! The log writer: a bounded queue in front of a thread that writes MCAP (zstd-compressed
//! chunks), so that whoever records never waits for the disk. The queue is bounded in bytes;
//! when it is full a message is either dropped and counted ([`Overflow::Drop`], on the robot:
//! the recorder must keep up with live topics, and a drop is better than a stall) or the caller
//! waits ([`Overflow::Block`], on a simulated clock, where waiting stops simulated time and so
//! costs nothing but wall time). Chunks are finished and flushed at least once a second, so a
//! killed recorder leaves everything but its last second readable.

use std::collections::{BTreeMap, VecDeque};
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use super::LogError;
use super::codec::Channel;

/// What a full queue does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Overflow {
    /// Drop the message and count it.
    Drop,
    /// Wait until there is room.
    Block,
}

/// Settings of a [`LogWriter`].
#[derive(Debug, Clone, Copy)]
pub struct WriterConfig {
    /// Most bytes of messages waiting to be written.
    pub queue_bytes: usize,
    /// What a full queue does.
    pub overflow: Overflow,
    /// zstd level of the chunks.
    pub zstd_level: u32,
}

impl Default for WriterConfig {
    fn default() -> Self {
        Self {
            queue_bytes: 64 << 20,
            overflow: Overflow::Drop,
            zstd_level: 3,
        }
    }
}

/// Counts of a finished log.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct WriterSummary {
    /// Messages written, per topic.
    pub written: BTreeMap<&'static str, u64>,
    /// Messages dropped because the queue was full, per topic.
    pub dropped: BTreeMap<&'static str, u64>,
    /// Bytes of the file.
    pub file_bytes: u64,
}

struct Entry {
    channel: Channel,
    log_time: u64,
    publish_time: u64,
    data: Vec<u8>,
}

#[derive(Default)]
struct State {
    items: VecDeque<Entry>,
    bytes: usize,
    closed: bool,
    dropped: BTreeMap<&'static str, u64>,
}

struct Queue {
    state: Mutex<State>,
    /// Signalled when an item arrives or the queue closes (the writer waits on it).
    filled: Condvar,
    /// Signalled when items leave (blocked producers wait on it).
    drained: Condvar,
}

fn lock(m: &Mutex<State>) -> MutexGuard<'_, State> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// Writes a mission log (see the module docs).
pub struct LogWriter {
    queue: Arc<Queue>,
    config: WriterConfig,
    thread: Option<JoinHandle<Result<WriterSummary, LogError>>>,
    path: PathBuf,
}

impl LogWriter {
    /// Creates `path` (replacing a file there) and starts the writer thread. The format record
    /// ([`LOG_METADATA`](super::LOG_METADATA): `log_format` [`LOG_FORMAT`](super::LOG_FORMAT)) is
    /// written first, then `metadata`, as MCAP metadata records (name -> key/value pairs); a
    /// record of `metadata` with the format record's name is replaced by this build's.
    pub fn create(
        path: &Path,
        metadata: BTreeMap<String, BTreeMap<String, String>>,
        config: WriterConfig,
    ) -> Result<Self, LogError> {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir)
                .map_err(|e| LogError::io(dir, "creating the folder", e))?;
        }
        let file = File::create(path).map_err(|e| LogError::io(path, "creating", e))?;
        let options = mcap::WriteOptions::new()
            .compression(Some(mcap::Compression::Zstd))
            .compression_level(config.zstd_level)
            .profile("")
            .library(concat!("grop-recorder ", env!("CARGO_PKG_VERSION")));
        let mut writer = options
            .create(BufWriter::new(file))
            .map_err(|e| LogError::mcap(path, "writing the header", e))?;
        let format = BTreeMap::from([
            ("log_format".to_owned(), super::LOG_FORMAT.to_string()),
            (
                "writer".to_owned(),
                concat!("grop ", env!("CARGO_PKG_VERSION")).to_owned(),
            ),
        ]);
        let records = std::iter::once((super::LOG_METADATA.to_owned(), format)).chain(
            metadata
                .into_iter()
                .filter(|(name, _)| name != super::LOG_METADATA),
        );
        for (name, pairs) in records {
            writer
                .write_metadata(&mcap::records::Metadata {
                    name,
                    metadata: pairs,
                })
                .map_err(|e| LogError::mcap(path, "writing metadata", e))?;
        }
        let queue = Arc::new(Queue {
            state: Mutex::new(State::default()),
            filled: Condvar::new(),
            drained: Condvar::new(),
        });
        let thread = {
            let queue = Arc::clone(&queue);
            let thread_path = path.to_owned();
            std::thread::Builder::new()
                .name("mcap-writer".into())
                .spawn(move || write_loop(&queue, writer, &thread_path))
                .map_err(|e| LogError::io(path, "starting the writer thread for", e))?
        };
        Ok(Self {
            queue,
            config,
            thread: Some(thread),
            path: path.to_owned(),
        })
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Queues one message; `false` when it was dropped (queue full with [`Overflow::Drop`], or
    /// the writer has stopped).
    pub fn push(&self, channel: Channel, log_time: u64, publish_time: u64, data: Vec<u8>) -> bool {
        let len = data.len().max(1);
        let mut state = lock(&self.queue.state);
        loop {
            if state.closed {
                *state.dropped.entry(channel.topic()).or_insert(0) += 1;
                return false;
            }
            // A message larger than the whole budget still goes in when the queue is empty.
            if state.bytes + len <= self.config.queue_bytes || state.items.is_empty() {
                break;
            }
            match self.config.overflow {
                Overflow::Drop => {
                    *state.dropped.entry(channel.topic()).or_insert(0) += 1;
                    return false;
                }
                Overflow::Block => {
                    state = self
                        .queue
                        .drained
                        .wait(state)
                        .unwrap_or_else(|e| e.into_inner());
                }
            }
        }
        state.bytes += len;
        state.items.push_back(Entry {
            channel,
            log_time,
            publish_time,
            data,
        });
        drop(state);
        self.queue.filled.notify_one();
        true
    }

    /// Messages dropped so far.
    pub fn dropped(&self) -> u64 {
        lock(&self.queue.state).dropped.values().sum()
    }

    /// Writes what is queued, then the summary, and closes the file.
    pub fn finish(mut self) -> Result<WriterSummary, LogError> {
        self.close()
    }

    fn close(&mut self) -> Result<WriterSummary, LogError> {
        lock(&self.queue.state).closed = true;
        self.queue.filled.notify_all();
        self.queue.drained.notify_all();
        let Some(thread) = self.thread.take() else {
            return Ok(WriterSummary::default());
        };
        let mut summary = thread.join().map_err(|_| LogError::WriterPanicked {
            path: self.path.clone(),
        })??;
        summary.dropped = lock(&self.queue.state).dropped.clone();
        Ok(summary)
    }
}

impl Drop for LogWriter {
    fn drop(&mut self) {
        if self.thread.is_some() {
            if let Err(e) = self.close() {
                log::error!("mission log: {e}");
            }
        }
    }
}

fn write_loop(
    queue: &Queue,
    mut writer: mcap::Writer<BufWriter<File>>,
    path: &Path,
) -> Result<WriterSummary, LogError> {
    let mut channel_ids: BTreeMap<Channel, u16> = BTreeMap::new();
    let mut sequences: BTreeMap<Channel, u32> = BTreeMap::new();
    let mut summary = WriterSummary::default();
    let mut last_flush = Instant::now();
    let mut batch: Vec<Entry> = Vec::with_capacity(256);
    loop {
        let closed = {
            let mut state = lock(&queue.state);
            while state.items.is_empty() && !state.closed {
                let (s, _) = queue
                    .filled
                    .wait_timeout(state, Duration::from_millis(200))
                    .unwrap_or_else(|e| e.into_inner());
                state = s;
                if last_flush.elapsed() >= Duration::from_secs(1) {
                    break;
                }
            }
            batch.extend(state.items.drain(..));
            state.bytes = 0;
            state.closed
        };
        queue.drained.notify_all();
        for entry in batch.drain(..) {
            let id = match channel_ids.get(&entry.channel) {
                Some(id) => *id,
                None => {
                    let c = entry.channel;
                    let schema = serde_json::to_vec(&c.schema()).unwrap_or_default();
                    let schema_id = writer
                        .add_schema(c.schema_name(), "jsonschema", &schema)
                        .map_err(|e| LogError::mcap(path, "adding a schema", e))?;
                    let id = writer
                        .add_channel(schema_id, c.topic(), "json", &BTreeMap::new())
                        .map_err(|e| LogError::mcap(path, "adding a channel", e))?;
                    channel_ids.insert(c, id);
                    id
                }
            };
            let seq = sequences.entry(entry.channel).or_insert(0);
            *seq = seq.wrapping_add(1);
            writer
                .write_to_known_channel(
                    &mcap::records::MessageHeader {
                        channel_id: id,
                        sequence: *seq,
                        log_time: entry.log_time,
                        publish_time: entry.publish_time,
                    },
                    &entry.data,
                )
                .map_err(|e| LogError::mcap(path, "writing a message", e))?;
            *summary.written.entry(entry.channel.topic()).or_insert(0) += 1;
        }
        if last_flush.elapsed() >= Duration::from_secs(1) {
            writer
                .flush()
                .map_err(|e| LogError::mcap(path, "flushing", e))?;
            last_flush = Instant::now();
        }
        if closed {
            break;
        }
    }
    writer
        .finish()
        .map_err(|e| LogError::mcap(path, "writing the summary", e))?;
    drop(writer);
    summary.file_bytes = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
    Ok(summary)
}
