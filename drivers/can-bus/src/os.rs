//! Small Linux helpers shared by the userspace buses: a sub-millisecond wait on a file
//! descriptor, the host-wide monotonic clock, and the reading of iceoryx2's service-open errors.
//! Used by [`VirtualCanBus`](crate::VirtualCanBus) and by the runtime's iceoryx2 services
//! (grop-ipc).
#![allow(
    unsafe_code,
    reason = "ppoll and clock_gettime through libc: the wait on the bus's sockets and eventfd"
)]

use std::time::Duration;

/// Sleeps until `fd` is readable or `timeout` passed (an interrupted sleep returns early; the
/// caller loops on its own deadline).
pub fn wait_readable(fd: i32, timeout: Duration) -> std::io::Result<()> {
    let mut poll_fd = libc::pollfd {
        fd,
        events: libc::POLLIN,
        revents: 0,
    };
    let timeout = libc::timespec {
        tv_sec: libc::time_t::try_from(timeout.as_secs()).unwrap_or(libc::time_t::MAX),
        // Below 1e9, so it fits a c_long on every target.
        tv_nsec: timeout.subsec_nanos() as libc::c_long,
    };
    // SAFETY: one valid pollfd, a valid timespec, no signal mask change.
    let status = unsafe { libc::ppoll(&mut poll_fd, 1, &timeout, std::ptr::null()) };
    if status < 0 {
        let error = std::io::Error::last_os_error();
        if error.kind() != std::io::ErrorKind::Interrupted {
            return Err(error);
        }
    }
    Ok(())
}

/// CLOCK_MONOTONIC in nanoseconds: one clock for every process on the host, unlike `Instant`,
/// whose value cannot be shared.
pub fn monotonic_ns() -> u64 {
    let mut now = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `now` is a valid, writable timespec; CLOCK_MONOTONIC always exists on Linux.
    let status = unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut now) };
    if status != 0 {
        return 0;
    }
    u64::try_from(now.tv_sec)
        .unwrap_or(0)
        .saturating_mul(1_000_000_000)
        .saturating_add(u64::try_from(now.tv_nsec).unwrap_or(0))
}

/// Why an iceoryx2 publish-subscribe service could not be opened, in the terms callers report.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ServiceOpenFailure {
    /// The service exists but already has as many nodes as it was created for.
    NodeLimit,
    /// The service exists with other settings or payload type (the detail names which).
    Incompatible(String),
    /// Anything else (shared memory, permissions, a corrupted service): report the error itself.
    Other,
}

/// Sorts an iceoryx2 open-or-create error of a publish-subscribe service.
pub fn service_open_failure(
    error: &iceoryx2::service::builder::publish_subscribe::PublishSubscribeOpenOrCreateError,
) -> ServiceOpenFailure {
    use iceoryx2::service::builder::publish_subscribe::{
        PublishSubscribeOpenError as Open, PublishSubscribeOpenOrCreateError as OpenOrCreate,
    };
    match error {
        OpenOrCreate::PublishSubscribeOpenError(Open::ExceedsMaxNumberOfNodes) => {
            ServiceOpenFailure::NodeLimit
        }
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
        ) => ServiceOpenFailure::Incompatible(format!("{open:?}")),
        _ => ServiceOpenFailure::Other,
    }
}
