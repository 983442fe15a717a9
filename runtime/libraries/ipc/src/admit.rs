//! Who may publish a command topic (docs/security.md): a subscriber that takes a message only
//! from the publisher the deployment names.
//!
//! iceoryx2 stamps every sample with the id of the publisher that sent it; the service lists each
//! publisher with the node it belongs to, and the node registry gives the node's name and the
//! process that created it. An [`AdmittingSubscriber`] resolves the sender of each message that
//! way (once per publisher, then cached) and accepts it only when
//!
//! 1. the sender's node has the name the deployment gives for this input;
//! 2. it is the first publisher of that name this subscriber accepted (or a new port of the same
//!    process after the old one closed): a second copy is refused,
//!    and so is a process that replaces the first after it died (it could be an impostor that
//!    hides the death; a planner that dies ends the mission). Where a new process per message is
//!    normal (a command-line tool), [`AdmittingSubscriber::accept_successors`] accepts the next
//!    process once the previous one has left the service; its sequence starts again;
//! 3. a process id the message carries ([`Sequenced::claimed_pid`], heartbeats) is the
//!    sender's;
//! 4. its sequence ([`Sequenced::sequence`]) advances past the last accepted one.
//!
//! Anything else is refused with a [`Refusal`] that says who sent it and why; the reader counts
//! and reports it and never acts on the message. This guards against another program on the
//! same machine publishing into the namespace by mistake; it is no defence against a hostile
//! process of the same OS user, which can write the shared memory itself (docs/security.md).
//!
//! A new command topic needs one line: `impl Sequenced for MyMsg` (and, where the topic has
//! one writer, `MAX_PUBLISHERS = 1` in its [`Topic`], so that no second publisher connects).

use std::fmt;

use iceoryx2::identifiers::{UniqueNodeId, UniquePublisherId};
use iceoryx2::prelude::*;

use crate::port::Ipc;
use crate::{
    BasePoseMsg, HeartbeatMsg, IpcNode, PortError, ReceiveError, Received, TaskPlanMsg, Topic,
    TopicSubscriber,
};

impl IpcNode {
    /// A subscriber for command topic `T` that accepts messages only from node `allowed`, in
    /// sequence ([`AdmittingSubscriber`]); messages for which `relevant` is false are skipped.
    pub fn admitting_subscriber<T: Sequenced>(
        &self,
        allowed: &str,
        relevant: fn(&T) -> bool,
    ) -> Result<AdmittingSubscriber<T>, PortError> {
        Ok(AdmittingSubscriber::new(
            self.subscriber()?,
            self.config().clone(),
            allowed,
            relevant,
        ))
    }
}

/// Most publishers whose identity one subscriber remembers (the cache is cleared when full).
const KNOWN_PUBLISHERS: usize = 16;

/// A command message that says where it is in its publisher's sequence.
pub trait Sequenced: Topic {
    /// The publisher's counter: it must advance from one accepted message to the next.
    fn sequence(&self) -> u64;
    /// The process id the message says it comes from, if it carries one; it must be the id of
    /// the process whose node published it.
    fn claimed_pid(&self) -> Option<u32> {
        None
    }
}

impl Sequenced for TaskPlanMsg {
    fn sequence(&self) -> u64 {
        self.plan_id
    }
}

impl Sequenced for BasePoseMsg {
    fn sequence(&self) -> u64 {
        self.seq
    }
}

impl Sequenced for crate::OperatorEnableMsg {
    fn sequence(&self) -> u64 {
        self.seq
    }
    fn claimed_pid(&self) -> Option<u32> {
        Some(self.pid)
    }
}

impl Sequenced for HeartbeatMsg {
    fn sequence(&self) -> u64 {
        self.seq
    }
    fn claimed_pid(&self) -> Option<u32> {
        Some(self.pid)
    }
}

/// Who published a message, as iceoryx2's registry says.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Sender {
    /// The node's name.
    pub node: String,
    /// The process that created the node.
    pub pid: u32,
}

impl fmt::Display for Sender {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "node `{}` pid {}", self.node, self.pid)
    }
}

/// Why a message was refused.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Refusal {
    /// The publisher could not be identified: it left the service before its message was read,
    /// or its node's files cannot be read (another OS user).
    UnknownSender,
    /// A node other than the one the deployment names.
    NotAllowed {
        /// Who sent it.
        sender: Sender,
    },
    /// A node of the right name, but not the publisher accepted so far, which is still
    /// connected (a second copy of the process).
    Second {
        /// Who sent it.
        sender: Sender,
        /// The process accepted so far.
        accepted_pid: u32,
    },
    /// A node of the right name that took the place of the publisher accepted before, which
    /// has left (died or restarted); accepted only with
    /// [`AdmittingSubscriber::accept_successors`].
    Successor {
        /// Who sent it.
        sender: Sender,
        /// The process accepted before.
        accepted_pid: u32,
    },
    /// The message names another process than the one that sent it.
    PidMismatch {
        /// Who sent it.
        sender: Sender,
        /// The process id in the message.
        claimed: u32,
    },
    /// The sequence did not advance (a repeated or replayed message).
    NotAdvancing {
        /// Who sent it.
        sender: Sender,
        /// The message's sequence.
        seq: u64,
        /// The last accepted one.
        last: u64,
    },
}

impl fmt::Display for Refusal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::UnknownSender => write!(f, "unidentified publisher"),
            Self::NotAllowed { sender } => write!(f, "{sender} is not the deployment's"),
            Self::Second {
                sender,
                accepted_pid,
            } => write!(
                f,
                "{sender} is a second publisher (pid {accepted_pid} accepted)"
            ),
            Self::Successor {
                sender,
                accepted_pid,
            } => write!(
                f,
                "{sender} is a second publisher (pid {accepted_pid} accepted, gone: no successor)"
            ),
            Self::PidMismatch { sender, claimed } => {
                write!(f, "{sender} claims pid {claimed}")
            }
            Self::NotAdvancing { sender, seq, last } => {
                write!(f, "{sender} seq {seq} not after {last}")
            }
        }
    }
}

/// One message read by an [`AdmittingSubscriber`].
#[derive(Debug)]
pub enum Admission<T: Topic> {
    /// From the deployment's publisher, in sequence: act on it.
    Accepted(Received<T>),
    /// Refused: count and report it, never act on it.
    Refused(Refusal),
}

/// A subscriber that takes messages of `T` only from the node the deployment names (module
/// docs). Messages for which `relevant` is false (a heartbeat of another role) are skipped
/// unchecked.
pub struct AdmittingSubscriber<T: Sequenced> {
    inner: TopicSubscriber<T>,
    config: Config,
    allowed: String,
    relevant: fn(&T) -> bool,
    /// The publisher accepted so far and its process.
    accepted: Option<(UniquePublisherId, u32)>,
    last_seq: Option<u64>,
    known: Vec<(UniquePublisherId, Option<Sender>)>,
    refused: u64,
    /// Whether a new process may take over once the accepted one left.
    successors: bool,
    /// Publishers connected when last looked, and room to list them without allocating.
    connected: usize,
    listed: Vec<UniquePublisherId>,
}

impl<T: Sequenced> AdmittingSubscriber<T> {
    pub(crate) fn new(
        inner: TopicSubscriber<T>,
        config: Config,
        allowed: &str,
        relevant: fn(&T) -> bool,
    ) -> Self {
        Self {
            inner,
            config,
            allowed: allowed.to_owned(),
            relevant,
            accepted: None,
            last_seq: None,
            known: Vec::with_capacity(KNOWN_PUBLISHERS),
            refused: 0,
            successors: false,
            connected: 0,
            listed: Vec::with_capacity(KNOWN_PUBLISHERS),
        }
    }

    /// Accepts a new process of the allowed node once the one accepted before has left the
    /// service (its sequence starts again): for inputs that a new process sends each time (an
    /// operator's command-line tool). Without it the first process is the only one.
    pub fn accept_successors(mut self) -> Self {
        self.successors = true;
        self
    }

    /// The node name whose messages are accepted.
    pub fn allowed(&self) -> &str {
        &self.allowed
    }

    /// Messages refused so far.
    pub fn refused(&self) -> u64 {
        self.refused
    }

    /// The process whose messages are accepted now, once one was.
    pub fn accepted_pid(&self) -> Option<u32> {
        self.accepted.map(|(_, pid)| pid)
    }

    /// The descriptor that becomes readable when a message is published (for
    /// [`crate::wait_any`]); read the message with [`try_recv`](Self::try_recv).
    pub fn wake_fd(&self) -> i32 {
        self.inner.wake_fd()
    }

    /// Full service name.
    pub fn service(&self) -> &str {
        self.inner.service()
    }

    /// Identifies publishers that connected since the last call, before their first message:
    /// the registry's file reads and allocations happen when a publisher connects (the
    /// planner's start), not when its first command arrives. Cheap when nothing changed (one
    /// count in shared memory); called by [`try_recv`](Self::try_recv).
    pub fn identify_new_publishers(&mut self) {
        let connected = self.inner.publisher_count();
        if connected == self.connected {
            return;
        }
        self.connected = connected;
        let mut listed = std::mem::take(&mut self.listed);
        listed.clear();
        self.inner.publishers(|details| {
            if listed.len() < listed.capacity() {
                listed.push(details.publisher_id);
            }
            CallbackProgression::Continue
        });
        for id in &listed {
            self.sender_index(*id);
        }
        self.listed = listed;
    }

    /// The oldest unread relevant message, accepted or refused, or `None` at once.
    pub fn try_recv(&mut self) -> Result<Option<Admission<T>>, ReceiveError> {
        self.identify_new_publishers();
        loop {
            let Some(message) = self.inner.try_recv()? else {
                return Ok(None);
            };
            if !(self.relevant)(&message) {
                continue;
            }
            let verdict = self.admit(&message);
            return Ok(Some(match verdict {
                Ok(()) => Admission::Accepted(message),
                Err(refusal) => {
                    self.refused += 1;
                    Admission::Refused(refusal)
                }
            }));
        }
    }

    /// The checks of the module docs. Allocation-free for a known publisher whose message is
    /// accepted (the executive's cycle); a refusal copies the sender's name into its report.
    fn admit(&mut self, message: &Received<T>) -> Result<(), Refusal> {
        let origin = message.origin();
        let index = self.sender_index(origin);
        let Some(sender) = self.known[index].1.as_ref() else {
            return Err(Refusal::UnknownSender);
        };
        let pid = sender.pid;
        if sender.node != self.allowed {
            return Err(Refusal::NotAllowed {
                sender: sender.clone(),
            });
        }
        if let Some(claimed) = message.claimed_pid().filter(|claimed| *claimed != pid) {
            return Err(Refusal::PidMismatch {
                sender: sender.clone(),
                claimed,
            });
        }
        match self.accepted {
            Some((id, _)) if id == origin => {}
            Some((id, accepted_pid)) if self.is_connected(id) => {
                return Err(Refusal::Second {
                    sender: self.known[index].1.clone().unwrap_or_else(|| Sender {
                        node: String::new(),
                        pid,
                    }),
                    accepted_pid,
                });
            }
            // The same process with a new port after its old one closed: still the one.
            Some((_, accepted_pid)) if accepted_pid == pid => self.accepted = Some((origin, pid)),
            Some((_, accepted_pid)) if !self.successors => {
                return Err(Refusal::Successor {
                    sender: self.known[index].1.clone().unwrap_or_else(|| Sender {
                        node: String::new(),
                        pid,
                    }),
                    accepted_pid,
                });
            }
            previous => {
                if let Some((_, old)) = previous {
                    log::info!(
                        "{}: publisher pid {old} left; accepting node `{}` pid {pid}",
                        self.inner.service(),
                        self.allowed
                    );
                }
                self.accepted = Some((origin, pid));
                self.last_seq = None;
            }
        }
        let seq = message.sequence();
        if let Some(last) = self.last_seq.filter(|last| seq <= *last) {
            return Err(Refusal::NotAdvancing {
                sender: Sender {
                    node: self.allowed.clone(),
                    pid,
                },
                seq,
                last,
            });
        }
        self.last_seq = Some(seq);
        Ok(())
    }

    /// Whether publisher `id` is still connected to the service.
    fn is_connected(&self, id: UniquePublisherId) -> bool {
        let mut found = false;
        self.inner.publishers(|details| {
            found = details.publisher_id == id;
            if found {
                CallbackProgression::Stop
            } else {
                CallbackProgression::Continue
            }
        });
        found
    }

    /// Where publisher `id` is in the cache, after resolving it if it is new: from the
    /// service's publisher list and the node registry (file reads, once per publisher). A
    /// publisher that already left resolves to `None`.
    fn sender_index(&mut self, id: UniquePublisherId) -> usize {
        if let Some(index) = self.known.iter().position(|(k, _)| *k == id) {
            return index;
        }
        let mut node_id: Option<UniqueNodeId> = None;
        self.inner.publishers(|details| {
            if details.publisher_id == id {
                node_id = Some(details.node_id);
                CallbackProgression::Stop
            } else {
                CallbackProgression::Continue
            }
        });
        let sender = node_id.and_then(|node| node_sender(&self.config, node));
        if self.known.len() == KNOWN_PUBLISHERS {
            self.known.clear();
        }
        self.known.push((id, sender));
        self.known.len() - 1
    }
}

/// The name and process of node `id`, if it is alive and its details can be read.
fn node_sender(config: &Config, id: UniqueNodeId) -> Option<Sender> {
    let pid = u32::try_from(id.pid::<Ipc>().ok()?.value()).ok()?;
    match Node::<Ipc>::state_of(config, id) {
        Ok(Some(NodeState::Alive(view))) => {
            use iceoryx2::node::NodeView;
            let details = view.details().as_ref()?;
            // The registry's pid and the one in the id agree for a node that is what it says.
            let registered = u32::try_from(details.process_id().value()).ok()?;
            (registered == pid).then(|| Sender {
                node: details.name().as_str().to_owned(),
                pid,
            })
        }
        _ => None,
    }
}
