//! The virtual bus's reading of iceoryx2's service-open errors (a full bus, another build's
//! bus). The runtime's iceoryx2 services read theirs in `grop_ipc` (the one-way dependencies of
//! docs/architecture.md keep the runtime off this driver). The waits and the monotonic clock
//! are `grop_clock`'s.

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
