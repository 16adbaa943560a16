//! CAN for the drives: CANopen (CiA 301) and its drive profile (CiA 402) over a CAN bus
//! reached through a serial adapter (slcan) or socketcan, as sans-I/O layers.
//!
//! The transport ([`crate::transport::can`]) streams the planned path to three CiA 402
//! servo drives, X, Z and C as nodes 1, 2 and 3, in cyclic synchronous position mode (or
//! interpolated position mode): a SYNC each cycle, each drive's set-point in its RPDO, its statusword and actual position back in its TPDO. This
//! module is what that transport needs below the port: frames as values, the Lawicel
//! codec, CANopen's framing and SDO client, and the CiA 402 state machine's master side.
//! None of it reads a clock or a port; time is passed in.
//!
//! - [`frame`]: a CAN 2.0 frame, 11- or 29-bit identifier, 0–8 bytes or a remote request.
//! - [`slcan`]: the Lawicel ASCII protocol, host side: commands out, adapter replies and
//!   received frames in.
//! - [`cia301`]: COB-IDs, NMT, heartbeat, EMCY, the expedited SDO client, PDO mapping.
//! - [`cia402`]: statusword states, controlword commands, the walk to Operation enabled,
//!   modes of operation, object indices.
//! - [`session`]: the master: boot-up, configuration by SDO, NMT start, the walk to
//!   Operation enabled, the cyclic set-points, heartbeat and emergency supervision, the
//!   stop.
//!
//! The simulator's drives (`whirl_sim::canopen`) are a separate implementation of the
//! other side, so that the two can check each other end to end.
//!
//! # Example
//!
//! Reading a drive's statusword through an slcan adapter:
//!
//! ```
//! use std::time::Duration;
//! use whirl::protocol::canopen::cia301::{NodeId, SdoClient, SdoDone};
//! use whirl::protocol::canopen::cia402::{object, PowerState};
//! use whirl::protocol::canopen::slcan::{Command, Decoder, Received};
//!
//! let mut sdo = SdoClient::new(NodeId::new(1).unwrap(), Duration::from_millis(100));
//! sdo.upload(object::STATUSWORD, 0, Duration::ZERO).unwrap();
//! let request = Command::Transmit(sdo.transmit().unwrap()).encode();
//! assert_eq!(request, b"t60184041600000000000\r");
//!
//! // The adapter acknowledges, then the drive answers 0x0250: Switch on disabled.
//! let mut decoder = Decoder::new();
//! for item in decoder.feed(b"z\rt58184B41600050020000\r") {
//!     if let Ok(Received::Frame { frame, .. }) = item {
//!         let Some(Ok(SdoDone::Uploaded { data, .. })) = sdo.receive(&frame) else {
//!             panic!("no statusword");
//!         };
//!         let word = u16::from_le_bytes([data[0], data[1]]);
//!         assert_eq!(PowerState::from_statusword(word), Ok(PowerState::SwitchOnDisabled));
//!     }
//! }
//! ```

pub mod cia301;
pub mod cia402;
pub mod frame;
pub mod session;
pub mod slcan;

pub use frame::{CanFrame, CanId, FrameError};
