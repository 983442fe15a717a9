//! Nodes, publishers and subscribers for the [`Topic`] types.
#![allow(
    unsafe_code,
    reason = "ppoll on iceoryx2's listener fds, geteuid, and iceoryx2's uninitialised loans"
)]

use std::marker::PhantomData;
use std::ops::Deref;
use std::time::{Duration, Instant};

use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;
use iceoryx2::sample::Sample;
use iceoryx2::service::port_factory::{event, publish_subscribe};

use crate::{CameraFrameHeader, CameraFrameMsg, MessageError, Topic};

pub(crate) type Ipc = ipc_threadsafe::Service;

/// Longest accepted namespace.
const MAX_NAMESPACE_LEN: usize = 100;

/// Why a node could not be created.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum NodeError {
    /// The namespace is empty, too long, starts/ends with `/`, or holds characters other than
    /// ASCII letters, digits, `-`, `_`, `.` and `/`.
    #[error(
        "IPC namespace {namespace:?} is invalid: use 1..={MAX_NAMESPACE_LEN} ASCII letters, digits, '-', '_', '.' or inner '/'"
    )]
    InvalidNamespace {
        /// The rejected namespace.
        namespace: String,
    },
    /// iceoryx2 refused the node name.
    #[error("IPC node name {name:?} is invalid: {detail}")]
    InvalidNodeName {
        /// The rejected name.
        name: String,
        /// iceoryx2's reason.
        detail: String,
    },
    /// iceoryx2's folder (sockets, service and node files) belongs to another OS user, who
    /// could then read and replace every file of every service (docs/security.md).
    #[error("iceoryx2's folder {path} is not this user's: {detail}")]
    Insecure {
        /// The folder.
        path: String,
        /// Whose it is, or why its mode cannot be set.
        detail: String,
    },
    /// iceoryx2 could not create the node.
    #[error("creating IPC node {name:?} failed: {detail}")]
    Create {
        /// Node name.
        name: String,
        /// iceoryx2's reason.
        detail: String,
    },
}

/// Why a publisher or subscriber could not be created.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PortError {
    /// The service exists with another message layout or other sizes (another build).
    #[error("IPC service {service} exists but is incompatible: {detail}")]
    Incompatible {
        /// Full service name.
        service: String,
        /// iceoryx2's reason.
        detail: String,
    },
    /// The service already has its maximum number of publishers or subscribers.
    #[error("IPC service {service} has no room for another {port}")]
    Full {
        /// Full service name.
        service: String,
        /// `publisher` or `subscriber`.
        port: &'static str,
    },
    /// Another iceoryx2 failure, named by `stage`.
    #[error("IPC service {service}: {stage} failed: {detail}")]
    Ipc {
        /// Full service name.
        service: String,
        /// What was being set up.
        stage: &'static str,
        /// iceoryx2's reason.
        detail: String,
    },
}

/// Why a message could not be published. It was not sent.
#[derive(Debug, thiserror::Error)]
#[error("publishing on IPC service {service} failed: {detail}")]
pub struct PublishError {
    /// Full service name.
    pub service: String,
    /// iceoryx2's reason.
    pub detail: String,
}

/// Why a camera frame was not published ([`TopicPublisher::publish_frame`]). It was not sent.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FrameError {
    /// The header does not describe an image the message holds.
    #[error("camera frame header: {0}")]
    Header(#[from] MessageError),
    /// iceoryx2 could not loan or send the message.
    #[error(transparent)]
    Publish(#[from] PublishError),
}

/// Why receiving failed.
#[derive(Debug, thiserror::Error)]
#[error("receiving on IPC service {service} failed: {detail}")]
pub struct ReceiveError {
    /// Full service name.
    pub service: String,
    /// iceoryx2's reason.
    pub detail: String,
}

/// A process's (or thread's) presence in one namespace; creates the publishers and subscribers.
pub struct IpcNode {
    namespace: String,
    node: Node<Ipc>,
}

impl IpcNode {
    /// A node named `node_name` in `namespace` (e.g. `robot`, `hil-42`, `test-<pid>-<n>`).
    pub fn new(namespace: &str, node_name: &str) -> Result<Self, NodeError> {
        let valid = !namespace.is_empty()
            && namespace.len() <= MAX_NAMESPACE_LEN
            && !namespace.starts_with('/')
            && !namespace.ends_with('/')
            && !namespace.contains("//")
            && namespace
                .bytes()
                .all(|b| b.is_ascii_alphanumeric() || b"-_./".contains(&b));
        if !valid {
            return Err(NodeError::InvalidNamespace {
                namespace: namespace.to_owned(),
            });
        }
        let name = NodeName::new(node_name).map_err(|error| NodeError::InvalidNodeName {
            name: node_name.to_owned(),
            detail: format!("{error:?}"),
        })?;
        let node = NodeBuilder::new()
            .name(&name)
            // The binaries keep their own Ctrl-C / SIGTERM handling.
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<Ipc>()
            .map_err(|error| NodeError::Create {
                name: node_name.to_owned(),
                detail: format!("{error:?}"),
            })?;
        restrict_root(node.config())?;
        // Reclaim ports of crashed processes so they do not hold publisher/subscriber slots.
        let _ = node.try_cleanup_dead_nodes();
        Ok(Self {
            namespace: namespace.to_owned(),
            node,
        })
    }

    /// The namespace every service name of this node starts with.
    pub fn namespace(&self) -> &str {
        &self.namespace
    }

    /// Full service name of topic `T` in this node's namespace.
    pub fn service_name<T: Topic>(&self) -> String {
        format!("{}/{}", self.namespace, T::NAME)
    }

    fn open<T: Topic>(&self) -> Result<Services<T>, PortError> {
        let service = self.service_name::<T>();
        let ipc = |stage: &'static str, error: &dyn std::fmt::Debug| PortError::Ipc {
            service: service.clone(),
            stage,
            detail: format!("{error:?}"),
        };
        let frames_name = ServiceName::new(&service).map_err(|e| ipc("naming the service", &e))?;
        let frames = self
            .node
            .service_builder(&frames_name)
            .publish_subscribe::<T>()
            .history_size(T::HISTORY)
            .subscriber_max_buffer_size(T::BUFFER)
            .subscriber_max_borrowed_samples(4)
            .max_subscribers(T::MAX_SUBSCRIBERS)
            .max_publishers(T::MAX_PUBLISHERS)
            .max_nodes(T::MAX_SUBSCRIBERS + T::MAX_PUBLISHERS)
            .enable_safe_overflow(true)
            .open_or_create()
            .map_err(|error| match incompatible(&error) {
                Some(detail) => PortError::Incompatible {
                    service: service.clone(),
                    detail,
                },
                None => ipc("opening the service", &error),
            })?;
        // A topic with one writer must not have room for a second: a service another build or
        // program created with more publisher slots is refused, not joined (docs/security.md).
        let slots = frames.static_config().max_publishers();
        if T::MAX_PUBLISHERS == 1 && slots != 1 {
            return Err(PortError::Incompatible {
                service: service.clone(),
                detail: format!("it has room for {slots} publishers; this topic has one writer"),
            });
        }
        let wake_name = ServiceName::new(&format!("{service}/wake"))
            .map_err(|e| ipc("naming the wake-up service", &e))?;
        let wake = self
            .node
            .service_builder(&wake_name)
            .event()
            .max_notifiers(T::MAX_PUBLISHERS)
            .max_listeners(T::MAX_SUBSCRIBERS)
            .max_nodes(T::MAX_SUBSCRIBERS + T::MAX_PUBLISHERS)
            .open_or_create()
            .map_err(|e| ipc("opening the wake-up service", &e))?;
        Ok(Services {
            service,
            frames,
            wake,
        })
    }

    /// A publisher for topic `T`.
    pub fn publisher<T: Topic>(&self) -> Result<TopicPublisher<T>, PortError> {
        let services = self.open::<T>()?;
        let service = services.service.clone();
        let publisher = services
            .frames
            .publisher_builder()
            .max_loaned_samples(2)
            .create()
            .map_err(|error| match error {
                iceoryx2::port::publisher::PublisherCreateError::ExceedsMaxSupportedPublishers => {
                    PortError::Full {
                        service: service.clone(),
                        port: "publisher",
                    }
                }
                other => PortError::Ipc {
                    service: service.clone(),
                    stage: "creating the publisher",
                    detail: format!("{other:?}"),
                },
            })?;
        let notifier =
            services
                .wake
                .notifier_builder()
                .create()
                .map_err(|error| PortError::Ipc {
                    service: service.clone(),
                    stage: "creating the wake-up notifier",
                    detail: format!("{error:?}"),
                })?;
        Ok(TopicPublisher {
            service,
            publisher,
            notifier,
            known_subscribers: 0,
            _services: services,
        })
    }

    /// iceoryx2's configuration of this node (where its node and service files are).
    pub(crate) fn config(&self) -> &Config {
        self.node.config()
    }

    /// A subscriber for topic `T`. It first receives the topic's history (the newest message for
    /// states, plans and frames), then everything published after this call.
    pub fn subscriber<T: Topic>(&self) -> Result<TopicSubscriber<T>, PortError> {
        let services = self.open::<T>()?;
        let service = services.service.clone();
        let listener =
            services
                .wake
                .listener_builder()
                .create()
                .map_err(|error| PortError::Ipc {
                    service: service.clone(),
                    stage: "creating the wake-up listener",
                    detail: format!("{error:?}"),
                })?;
        let mut builder = services.frames.subscriber_builder().buffer_size(T::BUFFER);
        if T::HISTORY > 0 {
            builder = builder.history_request(T::HISTORY);
        }
        let subscriber = builder.create().map_err(|error| match error {
            iceoryx2::port::subscriber::SubscriberCreateError::ExceedsMaxSupportedSubscribers => {
                PortError::Full {
                    service: service.clone(),
                    port: "subscriber",
                }
            }
            other => PortError::Ipc {
                service: service.clone(),
                stage: "creating the subscriber",
                detail: format!("{other:?}"),
            },
        })?;
        // SAFETY: the descriptor belongs to `listener`, which the subscriber owns and keeps open
        // for its whole life; it is only polled, never closed or read through this copy.
        let listener_fd = unsafe { listener.file_descriptor().native_handle() };
        Ok(TopicSubscriber {
            service,
            subscriber,
            listener,
            listener_fd,
            _services: services,
        })
    }
}

/// What in an iceoryx2 open-or-create error of a publish-subscribe service says that the
/// service exists with other settings or another payload type (another build or program), named;
/// `None` for anything else (shared memory, permissions, a full or corrupted service), which is
/// reported as the error itself.
fn incompatible(
    error: &iceoryx2::service::builder::publish_subscribe::PublishSubscribeOpenOrCreateError,
) -> Option<String> {
    use iceoryx2::service::builder::publish_subscribe::{
        PublishSubscribeOpenError as Open, PublishSubscribeOpenOrCreateError as OpenOrCreate,
    };
    match error {
        OpenOrCreate::PublishSubscribeOpenError(
            open @ (Open::IncompatibleTypes
            | Open::IncompatibleMessagingPattern
            | Open::IncompatibleAttributes
            | Open::DoesNotSupportRequestedMinBufferSize
            | Open::DoesNotSupportRequestedMinHistorySize
            | Open::DoesNotSupportRequestedMinSubscriberBorrowedSamples
            | Open::DoesNotSupportRequestedAmountOfPublishers
            | Open::DoesNotSupportRequestedAmountOfSubscribers
            | Open::DoesNotSupportRequestedAmountOfNodes
            | Open::IncompatibleOverflowBehavior),
        ) => Some(format!("{open:?}")),
        _ => None,
    }
}

/// iceoryx2's folder (`/tmp/iceoryx2` by default: the nodes' and services' files and the
/// event sockets) must be this user's; its mode is set to 0700 (iceoryx2 makes it 0750), so no
/// other user, not even of the group, can list or open what is in it. Every file iceoryx2 puts
/// in `/dev/shm` is 0600 but one 16-byte node counter (docs/security.md).
fn restrict_root(config: &Config) -> Result<(), NodeError> {
    use std::os::unix::fs::{MetadataExt, PermissionsExt};
    let root = String::from_utf8_lossy(config.global.root_path().as_bytes()).into_owned();
    let insecure = |detail: String| NodeError::Insecure {
        path: root.clone(),
        detail,
    };
    let meta = std::fs::metadata(&root).map_err(|e| insecure(format!("reading it: {e}")))?;
    // SAFETY: geteuid has no preconditions and cannot fail.
    let uid = unsafe { libc::geteuid() };
    if meta.uid() != uid {
        return Err(insecure(format!(
            "it belongs to uid {}, this process runs as uid {uid}",
            meta.uid()
        )));
    }
    if meta.mode() & 0o077 != 0 {
        std::fs::set_permissions(&root, std::fs::Permissions::from_mode(0o700))
            .map_err(|e| insecure(format!("setting its mode to 0700: {e}")))?;
    }
    Ok(())
}

struct Services<T: Topic> {
    service: String,
    frames: publish_subscribe::PortFactory<Ipc, T, ()>,
    wake: event::PortFactory<Ipc>,
}

/// Publishes messages of topic `T` and wakes its subscribers.
pub struct TopicPublisher<T: Topic> {
    service: String,
    publisher: Publisher<Ipc, T, ()>,
    notifier: Notifier<Ipc>,
    known_subscribers: usize,
    _services: Services<T>,
}

impl<T: Topic> TopicPublisher<T> {
    /// Hands the history (newest message) to subscribers that joined since the last publish or
    /// call, and wakes them. iceoryx2 delivers history only when the publisher updates its
    /// connections, so a publisher that publishes rarely (plans) calls this in its cycle.
    pub fn serve_late_subscribers(&mut self) -> Result<(), PublishError> {
        use iceoryx2::port::update_connections::UpdateConnections;
        self.publisher
            .update_connections()
            .map_err(|e| PublishError {
                service: self.service.clone(),
                detail: format!("updating connections: {e:?}"),
            })?;
        let subscribers = self
            ._services
            .frames
            .dynamic_config()
            .number_of_subscribers();
        if subscribers > self.known_subscribers {
            if let Err(wake_error) = self.notifier.notify() {
                log::warn!(
                    "{}: wake-up notification failed: {wake_error:?}",
                    self.service
                );
            }
        }
        self.known_subscribers = subscribers;
        Ok(())
    }

    fn error(&self, detail: String) -> PublishError {
        PublishError {
            service: self.service.clone(),
            detail,
        }
    }

    /// Sends a written sample and wakes the subscribers; returns how many it reached.
    fn send(
        &self,
        sample: iceoryx2::sample_mut::SampleMut<Ipc, T, ()>,
    ) -> Result<usize, PublishError> {
        let reached = sample
            .send()
            .map_err(|e| self.error(format!("send: {e:?}")))?;
        // The message is out; a failed wake-up only delays readers to their timeout.
        if let Err(wake_error) = self.notifier.notify() {
            log::warn!(
                "{}: wake-up notification failed: {wake_error:?}",
                self.service
            );
        }
        Ok(reached)
    }

    /// Loans a message in shared memory, zeroed, lets `fill` write it in place (no copy of a
    /// large frame), then publishes it. Returns the number of subscribers it reached. For camera
    /// frames [`publish_frame`](TopicPublisher::publish_frame) zeroes only the image's bytes.
    pub fn publish_with(&self, fill: impl FnOnce(&mut T)) -> Result<usize, PublishError> {
        let mut sample = self
            .publisher
            .loan_uninit()
            .map_err(|e| self.error(format!("loan: {e:?}")))?;
        let payload = sample.payload_mut().as_mut_ptr();
        // SAFETY: `payload` points to the loaned, properly aligned slot for one `T`. Every `T`
        // (Topic is sealed to this crate's message types) is `#[repr(C)]` plain data made of
        // integers, floats and arrays of them, so all-zero bytes are a valid `T`.
        let mut sample = unsafe {
            payload.write_bytes(0, 1);
            sample.assume_init()
        };
        fill(sample.payload_mut());
        self.send(sample)
    }

    /// Publishes a copy of `message` (for small messages; use
    /// [`publish_with`](Self::publish_with) for camera frames).
    pub fn publish(&self, message: &T) -> Result<usize, PublishError>
    where
        T: Copy,
    {
        self.publish_with(|slot| *slot = *message)
    }

    /// Full service name.
    pub fn service(&self) -> &str {
        &self.service
    }
}

impl TopicPublisher<CameraFrameMsg> {
    /// Publishes one camera frame written in place: checks `header` and stores it, zeroes the
    /// image bytes it describes (`row_stride_bytes * height_px`: 921,600 of the 3.5 MiB buffer
    /// for 640 x 480 RGB8), lets `fill` write them, and sends. The rest of the buffer, which
    /// the header says is unused, is neither zeroed nor written (`publish_with` zeroes all of
    /// it, about four times the work for a 640 x 480 frame; docs/latency.md). A header that
    /// does not check is an error and nothing is sent.
    pub fn publish_frame(
        &self,
        header: CameraFrameHeader,
        fill: impl FnOnce(&mut [u8]),
    ) -> Result<usize, FrameError> {
        let len = header.checked_len()?;
        let mut sample = self
            .publisher
            .loan_uninit()
            .map_err(|e| self.error(format!("loan: {e:?}")))?;
        let frame = sample.payload_mut().as_mut_ptr();
        // SAFETY: `frame` points to the loaned slot for one CameraFrameMsg: aligned, inside the
        // publisher's data segment, and ours alone until it is sent. Only raw pointers to its
        // fields are formed (no reference to the whole, not yet initialised message). `len` is
        // at most CAMERA_MAX_BYTES (`checked_len`), so the zeroed bytes and the slice lie inside
        // `pixels`; the slice is handed to `fill` and not used after it returns.
        let image = unsafe {
            core::ptr::addr_of_mut!((*frame).header).write(header);
            let pixels = core::ptr::addr_of_mut!((*frame).pixels).cast::<u8>();
            pixels.write_bytes(0, len);
            core::slice::from_raw_parts_mut(pixels, len)
        };
        fill(image);
        // SAFETY: the header and the image bytes are written above. The pixel bytes beyond
        // `len` are left as they are: they lie in the publisher's data segment, a shared-memory
        // file the OS zero-filled when it was created (iceoryx2 zeroes it too), into which this
        // crate only ever writes whole messages of padding-free plain data (`Topic` is sealed to
        // them; the `wire_sizes_are_fixed` tests pin their layouts). So they are initialised
        // bytes (zeros, or pixels of an earlier frame of this publisher), valid `u8` values,
        // and a subscriber that reads or copies the whole message reads no uninitialised byte.
        // None of them carries meaning: `CameraFrameMsg::image` ends at the header's length.
        let sample = unsafe { sample.assume_init() };
        Ok(self.send(sample)?)
    }
}

/// Sleeps until one of the topics behind `wake_fds` ([`TopicSubscriber::wake_fd`]) has a new
/// message, or `timeout` has passed (`grop_clock::wait_readable`: ppoll, no rounding to
/// scheduler ticks; at most `grop_clock::MAX_WAIT_FDS` topics).
pub fn wait_any(wake_fds: &[i32], timeout: Duration) -> std::io::Result<()> {
    grop_clock::wait_readable(wake_fds, timeout)
}

/// A received message, read in place in shared memory (dereferences to `T`).
pub struct Received<T: Topic> {
    sample: Sample<Ipc, T, ()>,
    _topic: PhantomData<T>,
}

impl<T: Topic> Deref for Received<T> {
    type Target = T;
    fn deref(&self) -> &T {
        self.sample.payload()
    }
}

impl<T: Topic> std::fmt::Debug for Received<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.sample.payload().fmt(f)
    }
}

impl<T: Topic> Received<T> {
    /// The publisher that sent it (iceoryx2's id, unique on the machine).
    pub(crate) fn origin(&self) -> iceoryx2::identifiers::UniquePublisherId {
        self.sample.header().publisher_id()
    }

    /// How old the message is at `now_ns` on the runtime clock (0 if stamped in the future).
    pub fn age_ns(&self, now_ns: u64) -> u64 {
        now_ns.saturating_sub(self.stamp_ns())
    }

    /// Whether the message is older than `max_age` at `now_ns`: a stale state or plan must not
    /// drive motion.
    pub fn is_stale(&self, now_ns: u64, max_age: Duration) -> bool {
        u128::from(self.age_ns(now_ns)) > max_age.as_nanos()
    }
}

/// Receives messages of topic `T`.
pub struct TopicSubscriber<T: Topic> {
    service: String,
    subscriber: Subscriber<Ipc, T, ()>,
    listener: Listener<Ipc>,
    /// The listener's socket, valid as long as `listener` lives.
    listener_fd: i32,
    _services: Services<T>,
}

impl<T: Topic> TopicSubscriber<T> {
    fn error(&self, detail: String) -> ReceiveError {
        ReceiveError {
            service: self.service.clone(),
            detail,
        }
    }

    /// The oldest unread message, or `None` at once.
    pub fn try_recv(&self) -> Result<Option<Received<T>>, ReceiveError> {
        let sample = self
            .subscriber
            .receive()
            .map_err(|e| self.error(format!("{e:?}")))?;
        Ok(sample.map(|sample| Received {
            sample,
            _topic: PhantomData,
        }))
    }

    /// The newest unread message, dropping older unread ones (for states and plans, where only
    /// the newest counts), or `None` if nothing is unread.
    pub fn latest(&self) -> Result<Option<Received<T>>, ReceiveError> {
        let mut newest = None;
        while let Some(message) = self.try_recv()? {
            newest = Some(message);
        }
        Ok(newest)
    }

    /// Waits up to `timeout` for a message, sleeping on the topic's wake-up event.
    pub fn recv_timeout(&self, timeout: Duration) -> Result<Option<Received<T>>, ReceiveError> {
        let start = Instant::now();
        loop {
            // Clear wake-ups, then look: a message published after the look comes with a
            // notification that ends the wait, so none is missed and nothing spins.
            self.listener
                .try_wait(|_| {})
                .map_err(|e| self.error(format!("{e:?}")))?;
            if let Some(message) = self.try_recv()? {
                return Ok(Some(message));
            }
            let Some(remaining) = timeout.checked_sub(start.elapsed()) else {
                return Ok(None);
            };
            if remaining.is_zero() {
                return Ok(None);
            }
            // poll(2) on the listener's socket: `Listener::timed_wait` uses a socket receive
            // timeout that the kernel rounds up to scheduler ticks (ms), ppoll does not.
            grop_clock::wait_readable(&[self.listener_fd], remaining)
                .map_err(|e| self.error(format!("waiting for a wake-up: {e}")))?;
        }
    }

    /// Clears the topic's pending wake-ups: a message published after this call comes with a
    /// new one, so a caller that clears, reads everything, then waits on [`wait_any`] misses
    /// nothing and never spins.
    pub fn clear_wakeups(&self) -> Result<(), ReceiveError> {
        self.listener
            .try_wait(|_| {})
            .map(|_| ())
            .map_err(|e| self.error(format!("{e:?}")))
    }

    /// The descriptor that becomes readable when a message is published (for [`wait_any`]).
    pub fn wake_fd(&self) -> i32 {
        self.listener_fd
    }

    /// How many publishers are connected to the service now.
    pub(crate) fn publisher_count(&self) -> usize {
        self._services
            .frames
            .dynamic_config()
            .number_of_publishers()
    }

    /// Calls `each` for the publishers connected to the service now.
    pub(crate) fn publishers(
        &self,
        each: impl FnMut(
            &iceoryx2::service::dynamic_config::publish_subscribe::PublisherDetails,
        ) -> CallbackProgression,
    ) {
        self._services.frames.dynamic_config().list_publishers(each);
    }

    /// Full service name.
    pub fn service(&self) -> &str {
        &self.service
    }
}
