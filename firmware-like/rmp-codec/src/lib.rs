//! Segway RMP host-protocol codec: `#![no_std]`, no heap, every decoder total.
//!
//! Two protocol generations are implemented (facts and sources in `docs/rmp.md` and
//! `shared/reference/rmp-can.md`):
//!
//! * [`v3`]: RMP v3, Segway Inc firmware ("family B1", RMP 210/220/440): 0x500 normalised
//!   motion, 0x501 configuration / general purpose, feedback from 0x502 upward in feedback-bitmap
//!   order ([`feedback`]). The configuration-command numbering differs between firmware
//!   releases, so it sits behind a [`v3::FirmwareProfile`].
//! * [`gen1`]: the older RMP 50/100/200/400 protocol (0x0413 motion + configuration, 0x0412
//!   shutdown, feedback 0x0400..0x0407 and 0x0680).
//!
//! The CAN frame itself is a plain value ([`RawFrame`]); nothing here knows how it travels.
//! [`packet`] holds the USB/UDP framing (CRC-16) of the same messages so that a non-CAN link
//! can be added behind the driver's transport trait later.
//!
//! ```
//! use rmp_codec::v3::{ConfigCommand, FirmwareProfile, ModeRequest, MotionCommand};
//!
//! // Ask for tractor mode, then command half the configured speed limit forward.
//! let mode = ConfigCommand::SetOperationalMode(ModeRequest::Tractor)
//!     .encode(FirmwareProfile::SegwayInc2014)?;
//! assert_eq!(mode.id(), 0x501);
//! let motion = MotionCommand::new(0.5, 0.0)?.encode();
//! assert_eq!(motion.data(), &[0x3F, 0, 0, 0, 0, 0, 0, 0]);
//! // ...and the base side decodes what it receives.
//! let back = MotionCommand::decode(&motion)?;
//! assert_eq!(back.velocity(), 0.5);
//! # Ok::<(), Box<dyn core::error::Error>>(())
//! ```
#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

#[cfg(test)]
extern crate std;

pub mod faults;
pub mod feedback;
mod frame;
pub mod gen1;
pub mod packet;
pub mod v3;

pub use frame::{FrameError, RawFrame};
