//! RTDE (Real-Time Data Exchange, port 30004), protocol version 2.

mod client;
pub mod wire;

pub use client::{
    DataPackage, InputRecipe, OutputRecipe, RTDE_PORT, RtdeClient, RtdeConnectError, RtdeLinkError,
    RtdeMalformed, RtdeReceiveError, RtdeReconnectCause, RtdeReconnectError, RtdeReconnectPolicy,
    RtdeRequestError, RtdeSendError, RtdeSetupError, RtdeState, RtdeTimeouts,
};
pub use wire::{ControllerVersion, PackageType, RtdeType, RtdeValue, TextLevel, TextMessage};
