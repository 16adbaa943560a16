//! CANopen (CiA 301) framing for a master: identifiers, NMT commands, heartbeat and
//! emergency messages, an expedited SDO client, and the SDO writes that map a PDO.
//!
//! Values in, frames out, and frames in, values out; the SDO client is told the time.
//!
//! # Identifiers
//!
//! The predefined connection set (CiA 301, "Pre-defined connection set"): a COB-ID is a
//! 4-bit function code above a 7-bit node id, so a node's objects sit at fixed offsets and
//! a master needs no configuration to talk to a freshly booted drive:
//!
//! | object | COB-ID |
//! | --- | --- |
//! | NMT | 0x000 |
//! | SYNC | 0x080 |
//! | EMCY | 0x080 + node |
//! | TPDO1–4 (drive → master) | 0x180, 0x280, 0x380, 0x480 + node |
//! | RPDO1–4 (master → drive) | 0x200, 0x300, 0x400, 0x500 + node |
//! | SDO response (server → client) | 0x580 + node |
//! | SDO request (client → server) | 0x600 + node |
//! | heartbeat, boot-up | 0x700 + node |
//!
//! # SDO
//!
//! Only expedited transfers: the drive's objects this bridge touches are all 1–4 bytes, and
//! expedited transfers fit a request and its answer in one frame each. The first byte is
//! the command specifier (CiA 301, "SDO protocols"): `ccs` or `scs` in bits 7–5, `n`
//! (bytes *not* holding data) in bits 3–2, `e` (expedited) bit 1, `s` (size indicated)
//! bit 0; then the index (little-endian), the sub-index and four data bytes:
//!
//! | frame | byte 0 |
//! | --- | --- |
//! | download request, 1/2/3/4 bytes | 0x2F, 0x2B, 0x27, 0x23 |
//! | download response | 0x60 |
//! | upload request | 0x40 |
//! | upload response, 1/2/3/4 bytes | 0x4F, 0x4B, 0x47, 0x43 (0x42: size not indicated, 4 bytes) |
//! | abort, either way | 0x80, code in bytes 4–7 |
//!
//! One transfer at a time per server, as CiA 301 allows: [`SdoClient`] refuses a second
//! while one is pending. It aborts (and says why) on a timeout, on a response to another
//! object, and on a segmented upload, which it does not implement.
//!
//! # PDO mapping
//!
//! [`pdo_mapping`] lists the SDO writes of CiA 301's mapping procedure (the description of
//! the PDO mapping parameter objects 1600h/1A00h): make the PDO invalid (COB-ID bit 31),
//! set its transmission type, set the mapping's sub-index 0 to 0, write the entries, set
//! sub-index 0 to their number, make the PDO valid again. Devices refuse mapping changes
//! in any other order, so the order is the point.

use std::collections::VecDeque;
use std::fmt;
use std::time::Duration;

use thiserror::Error;

use super::frame::{CanFrame, CanId};

/// A frame that is not what it was taken for, or a value CANopen does not allow.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum CanopenError {
    /// Node ids are 1–127 (0 addresses every node in NMT commands only).
    #[error("node id {0} is not 1-127")]
    NodeId(u8),
    /// The predefined connection set has PDOs 1–4.
    #[error("PDO number {0} is not 1-4")]
    PdoNumber(u8),
    /// A frame decoded as something it is not (wrong COB-ID, or a remote frame).
    #[error("frame {frame} is not {expected}")]
    NotA {
        /// What it was decoded as.
        expected: &'static str,
        /// The frame.
        frame: CanFrame,
    },
    /// A frame of the wrong length.
    #[error("{what} of {found} bytes, CiA 301 says {expected}")]
    Length {
        /// What it is.
        what: &'static str,
        /// Bytes CiA 301 gives it.
        expected: usize,
        /// Bytes it had.
        found: usize,
    },
    /// A heartbeat byte that is none of CiA 301's NMT states.
    #[error("node {node}: heartbeat state 0x{byte:02X} is not an NMT state")]
    HeartbeatState {
        /// The node.
        node: u8,
        /// The byte.
        byte: u8,
    },
    /// A PDO mapping with no entries (a valid PDO must carry something).
    #[error("a PDO mapping needs at least one entry")]
    EmptyMapping,
    /// A mapping entry of 0 bits.
    #[error("mapping entry {index:04X}h/{sub:02X}h has 0 bits")]
    ZeroWidth {
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
    },
    /// Entries beyond a classic CAN frame's 64 bits.
    #[error("PDO mapping of {0} bits, a CAN frame holds 64")]
    MappingBits(u32),
    /// Transmission types 241–251 are reserved.
    #[error("PDO transmission type {0} is reserved")]
    TransmissionType(u8),
}

/// A CANopen node id, 1–127.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct NodeId(u8);

impl NodeId {
    /// Checks the range.
    pub fn new(id: u8) -> Result<NodeId, CanopenError> {
        if (1..=127).contains(&id) {
            Ok(NodeId(id))
        } else {
            Err(CanopenError::NodeId(id))
        }
    }

    /// The number.
    pub fn get(self) -> u8 {
        self.0
    }
}

impl fmt::Display for NodeId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.0)
    }
}

/// A PDO of the predefined connection set, 1–4.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct PdoNumber(u8);

impl PdoNumber {
    /// Checks the range.
    pub fn new(n: u8) -> Result<PdoNumber, CanopenError> {
        if (1..=4).contains(&n) {
            Ok(PdoNumber(n))
        } else {
            Err(CanopenError::PdoNumber(n))
        }
    }

    /// The number.
    pub fn get(self) -> u8 {
        self.0
    }
}

/// COB-IDs of the predefined connection set.
pub mod cob {
    use super::{NodeId, PdoNumber};

    /// NMT commands, from the master.
    pub const NMT: u16 = 0x000;
    /// SYNC.
    pub const SYNC: u16 = 0x080;
    /// TIME stamp.
    pub const TIME: u16 = 0x100;

    /// A node's emergency messages.
    pub fn emcy(node: NodeId) -> u16 {
        0x080 + u16::from(node.get())
    }

    /// A node's transmit PDO `n` (drive → master): 0x180, 0x280, 0x380, 0x480 + node.
    pub fn tpdo(n: PdoNumber, node: NodeId) -> u16 {
        0x080 + 0x100 * u16::from(n.get()) + u16::from(node.get())
    }

    /// A node's receive PDO `n` (master → drive): 0x200, 0x300, 0x400, 0x500 + node.
    pub fn rpdo(n: PdoNumber, node: NodeId) -> u16 {
        0x100 + 0x100 * u16::from(n.get()) + u16::from(node.get())
    }

    /// SDO server → client (the node's answers).
    pub fn sdo_response(node: NodeId) -> u16 {
        0x580 + u16::from(node.get())
    }

    /// SDO client → server (requests to the node).
    pub fn sdo_request(node: NodeId) -> u16 {
        0x600 + u16::from(node.get())
    }

    /// NMT error control: heartbeat and boot-up.
    pub fn heartbeat(node: NodeId) -> u16 {
        0x700 + u16::from(node.get())
    }
}

/// What a standard identifier is in the predefined connection set.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Cob {
    /// 0x000.
    Nmt,
    /// 0x080.
    Sync,
    /// 0x100.
    Time,
    /// 0x081–0x0FF.
    Emcy(NodeId),
    /// 0x181–0x4FF, odd function codes.
    Tpdo(PdoNumber, NodeId),
    /// 0x201–0x57F, even function codes.
    Rpdo(PdoNumber, NodeId),
    /// 0x581–0x5FF.
    SdoResponse(NodeId),
    /// 0x601–0x67F.
    SdoRequest(NodeId),
    /// 0x701–0x77F.
    Heartbeat(NodeId),
    /// Anything else (LSS, node 0 of a per-node object, unused function codes).
    Other(u16),
}

impl Cob {
    /// Splits an 11-bit identifier into function code (bits 10–7) and node (bits 6–0).
    pub fn classify(id: u16) -> Cob {
        let function = id >> 7;
        let node = match NodeId::new((id & 0x7F) as u8) {
            Ok(node) => node,
            Err(_) => {
                return match id {
                    cob::NMT => Cob::Nmt,
                    cob::SYNC => Cob::Sync,
                    cob::TIME => Cob::Time,
                    _ => Cob::Other(id),
                }
            }
        };
        // Function codes 3, 5, 7, 9 are TPDO1–4, 4, 6, 8, 10 RPDO1–4.
        let pdo = |code: u16| PdoNumber(((code - 1) / 2) as u8);
        match function {
            1 => Cob::Emcy(node),
            3 | 5 | 7 | 9 => Cob::Tpdo(pdo(function), node),
            4 | 6 | 8 | 10 => Cob::Rpdo(pdo(function - 1), node),
            11 => Cob::SdoResponse(node),
            12 => Cob::SdoRequest(node),
            14 => Cob::Heartbeat(node),
            _ => Cob::Other(id),
        }
    }
}

/// The standard identifier of a frame, if it is a data frame on one.
fn standard_data_id(frame: &CanFrame) -> Option<u16> {
    match frame.id() {
        CanId::Standard(id) if !frame.is_remote() => Some(id),
        _ => None,
    }
}

/// An NMT command (CiA 301, "NMT services": command specifier in byte 0, node in byte 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NmtCommand {
    /// 0x01: start remote node (→ Operational).
    Start,
    /// 0x02: stop remote node (→ Stopped).
    Stop,
    /// 0x80: enter Pre-operational.
    EnterPreOperational,
    /// 0x81: reset node (application and communication).
    ResetNode,
    /// 0x82: reset communication.
    ResetCommunication,
}

impl NmtCommand {
    /// The command specifier.
    pub fn specifier(self) -> u8 {
        match self {
            NmtCommand::Start => 0x01,
            NmtCommand::Stop => 0x02,
            NmtCommand::EnterPreOperational => 0x80,
            NmtCommand::ResetNode => 0x81,
            NmtCommand::ResetCommunication => 0x82,
        }
    }

    /// The frame for `node`, or for every node (node id 0) with `None`.
    pub fn frame(self, node: Option<NodeId>) -> CanFrame {
        let target = node.map_or(0, NodeId::get);
        CanFrame::standard(cob::NMT, &[self.specifier(), target]).expect("2 bytes on 0x000")
    }
}

/// SYNC without a counter (CiA 301: 0 bytes unless the counter is configured in 1019h).
pub fn sync_frame() -> CanFrame {
    CanFrame::standard(cob::SYNC, &[]).expect("0 bytes on 0x080")
}

/// An NMT state as heartbeats report it (CiA 301, "Heartbeat protocol").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NmtState {
    /// 0x00: the boot-up message, sent once on entering Pre-operational.
    BootUp,
    /// 0x04.
    Stopped,
    /// 0x05.
    Operational,
    /// 0x7F.
    PreOperational,
}

impl NmtState {
    /// The byte a heartbeat carries.
    pub fn byte(self) -> u8 {
        match self {
            NmtState::BootUp => 0x00,
            NmtState::Stopped => 0x04,
            NmtState::Operational => 0x05,
            NmtState::PreOperational => 0x7F,
        }
    }
}

/// A decoded heartbeat or boot-up message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Heartbeat {
    /// Who sent it.
    pub node: NodeId,
    /// Its NMT state.
    pub state: NmtState,
}

/// Reads a heartbeat: one byte on 0x700 + node. A remote frame there is a node-guarding
/// request, not a heartbeat, and is refused.
pub fn decode_heartbeat(frame: &CanFrame) -> Result<Heartbeat, CanopenError> {
    let not_one = || CanopenError::NotA {
        expected: "a heartbeat",
        frame: *frame,
    };
    let node = match standard_data_id(frame).map(Cob::classify) {
        Some(Cob::Heartbeat(node)) => node,
        _ => return Err(not_one()),
    };
    let [byte] = frame.data() else {
        return Err(CanopenError::Length {
            what: "heartbeat",
            expected: 1,
            found: frame.data().len(),
        });
    };
    let state = [
        NmtState::BootUp,
        NmtState::Stopped,
        NmtState::Operational,
        NmtState::PreOperational,
    ]
    .into_iter()
    .find(|state| state.byte() == *byte)
    .ok_or(CanopenError::HeartbeatState {
        node: node.get(),
        byte: *byte,
    })?;
    Ok(Heartbeat { node, state })
}

/// A decoded emergency message (CiA 301, "Emergency object": error code u16, the error
/// register 1001h, five manufacturer-specific bytes).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Emergency {
    /// Who sent it.
    pub node: NodeId,
    /// The error code; 0x0000 means the error was reset.
    pub code: u16,
    /// The error register (1001h): bit 0 generic, 1 current, 2 voltage, 3 temperature,
    /// 4 communication, 5 device profile, 7 manufacturer.
    pub register: u8,
    /// Manufacturer-specific bytes.
    pub manufacturer: [u8; 5],
}

impl Emergency {
    /// Whether it announces that the node's errors were reset (code 0x0000).
    pub fn is_reset(&self) -> bool {
        self.code == 0
    }

    /// The code's class (CiA 301's table of emergency error codes, by its upper digits).
    pub fn class(&self) -> &'static str {
        match self.code {
            0x0000..=0x00FF => "error reset or no error",
            0x1000..=0x10FF => "generic error",
            0x2000..=0x2FFF => "current",
            0x3000..=0x3FFF => "voltage",
            0x4000..=0x4FFF => "temperature",
            0x5000..=0x5FFF => "device hardware",
            0x6000..=0x6FFF => "device software",
            0x7000..=0x7FFF => "additional modules",
            0x8100..=0x81FF => "communication",
            0x8200..=0x82FF => "protocol error",
            0x8000..=0x8FFF => "monitoring",
            0x9000..=0x90FF => "external error",
            0xF000..=0xF0FF => "additional functions",
            0xFF00..=0xFFFF => "device specific",
            _ => "reserved",
        }
    }
}

/// Reads an emergency message: eight bytes on 0x080 + node.
pub fn decode_emcy(frame: &CanFrame) -> Result<Emergency, CanopenError> {
    let node = match standard_data_id(frame).map(Cob::classify) {
        Some(Cob::Emcy(node)) => node,
        _ => {
            return Err(CanopenError::NotA {
                expected: "an emergency message",
                frame: *frame,
            })
        }
    };
    let data = frame.data();
    if data.len() != 8 {
        return Err(CanopenError::Length {
            what: "emergency message",
            expected: 8,
            found: data.len(),
        });
    }
    Ok(Emergency {
        node,
        code: u16::from_le_bytes([data[0], data[1]]),
        register: data[2],
        manufacturer: [data[3], data[4], data[5], data[6], data[7]],
    })
}

/// An SDO abort code (CiA 301, "SDO abort codes").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct AbortCode(pub u32);

impl AbortCode {
    /// SDO protocol timed out.
    pub const TIMEOUT: AbortCode = AbortCode(0x0504_0000);
    /// Client/server command specifier not valid or unknown.
    pub const COMMAND: AbortCode = AbortCode(0x0504_0001);
    /// Attempt to write a read-only object.
    pub const READ_ONLY: AbortCode = AbortCode(0x0601_0002);
    /// Object does not exist in the object dictionary.
    pub const NO_OBJECT: AbortCode = AbortCode(0x0602_0000);
    /// Sub-index does not exist.
    pub const NO_SUB: AbortCode = AbortCode(0x0609_0011);
    /// General error.
    pub const GENERAL: AbortCode = AbortCode(0x0800_0000);

    /// CiA 301's wording for the code, if it is one of its codes.
    pub fn meaning(self) -> Option<&'static str> {
        Some(match self.0 {
            0x0503_0000 => "Toggle bit not alternated",
            0x0504_0000 => "SDO protocol timed out",
            0x0504_0001 => "Client/server command specifier not valid or unknown",
            0x0504_0002 => "Invalid block size",
            0x0504_0003 => "Invalid sequence number",
            0x0504_0004 => "CRC error",
            0x0504_0005 => "Out of memory",
            0x0601_0000 => "Unsupported access to an object",
            0x0601_0001 => "Attempt to read a write only object",
            0x0601_0002 => "Attempt to write a read only object",
            0x0602_0000 => "Object does not exist in the object dictionary",
            0x0604_0041 => "Object cannot be mapped to the PDO",
            0x0604_0042 => "The number and length of the objects to be mapped would exceed PDO length",
            0x0604_0043 => "General parameter incompatibility reason",
            0x0604_0047 => "General internal incompatibility in the device",
            0x0606_0000 => "Access failed due to an hardware error",
            0x0607_0010 => "Data type does not match, length of service parameter does not match",
            0x0607_0012 => "Data type does not match, length of service parameter too high",
            0x0607_0013 => "Data type does not match, length of service parameter too low",
            0x0609_0011 => "Sub-index does not exist",
            0x0609_0030 => "Invalid value for parameter (download only)",
            0x0609_0031 => "Value of parameter written too high (download only)",
            0x0609_0032 => "Value of parameter written too low (download only)",
            0x0609_0036 => "Maximum value is less than minimum value",
            0x060A_0023 => "Resource not available: SDO connection",
            0x0800_0000 => "General error",
            0x0800_0020 => "Data cannot be transferred or stored to the application",
            0x0800_0021 => {
                "Data cannot be transferred or stored to the application because of local control"
            }
            0x0800_0022 => {
                "Data cannot be transferred or stored to the application because of the present device state"
            }
            0x0800_0023 => "Object dictionary dynamic generation fails or no object dictionary is present",
            0x0800_0024 => "No data available",
            _ => return None,
        })
    }
}

impl fmt::Display for AbortCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "0x{:08X} ({})",
            self.0,
            self.meaning().unwrap_or("not a CiA 301 code")
        )
    }
}

/// A finished SDO transfer.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SdoDone {
    /// The server took the value.
    Downloaded {
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
    },
    /// The server sent the value.
    Uploaded {
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// 1–4 bytes, little-endian as on the bus.
        data: Vec<u8>,
    },
}

/// A transfer that could not start or did not succeed.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum SdoError {
    /// A transfer to this node is still pending.
    #[error("node {node}: an SDO transfer is already pending")]
    Busy {
        /// The node.
        node: NodeId,
    },
    /// Expedited downloads carry 1–4 bytes.
    #[error("expedited SDO download of {0} bytes, 1-4 fit")]
    Size(usize),
    /// The server aborted.
    #[error("node {node} aborted SDO {index:04X}h/{sub:02X}h: {code}")]
    Aborted {
        /// The node.
        node: NodeId,
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Why.
        code: AbortCode,
    },
    /// No answer in time; the client aborted with 0x05040000.
    #[error("node {node}: no answer to SDO {index:04X}h/{sub:02X}h within {timeout:?}")]
    Timeout {
        /// The node.
        node: NodeId,
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// The time allowed.
        timeout: Duration,
    },
    /// An answer that breaks the protocol; the client aborted with `code`.
    #[error("node {node}: SDO {index:04X}h/{sub:02X}h: {reason}; aborted with {code}")]
    Protocol {
        /// The node.
        node: NodeId,
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// What was wrong.
        reason: String,
        /// The abort code the client sent.
        code: AbortCode,
    },
}

#[derive(Debug, Clone, Copy)]
struct Pending {
    index: u16,
    sub: u8,
    upload: bool,
    deadline: Duration,
}

/// An expedited SDO client for one server (node). Requests and aborts go out through
/// [`SdoClient::transmit`]; the server's frames come in through [`SdoClient::receive`];
/// [`SdoClient::poll`] is told the time and times the transfer out.
#[derive(Debug, Clone)]
pub struct SdoClient {
    node: NodeId,
    timeout: Duration,
    pending: Option<Pending>,
    outbox: VecDeque<CanFrame>,
}

impl SdoClient {
    /// A client for `node`'s default SDO server; a transfer with no answer within
    /// `timeout` fails.
    pub fn new(node: NodeId, timeout: Duration) -> SdoClient {
        SdoClient {
            node,
            timeout,
            pending: None,
            outbox: VecDeque::new(),
        }
    }

    /// Whether a transfer is pending.
    pub fn is_busy(&self) -> bool {
        self.pending.is_some()
    }

    /// Starts writing `data` (1–4 bytes, little-endian) to `index`/`sub` at time `now`.
    pub fn download(
        &mut self,
        index: u16,
        sub: u8,
        data: &[u8],
        now: Duration,
    ) -> Result<(), SdoError> {
        if !(1..=4).contains(&data.len()) {
            return Err(SdoError::Size(data.len()));
        }
        self.start(index, sub, false, now)?;
        // ccs = 1, n = 4 − size, e = 1, s = 1.
        let command = 0x20 | ((4 - data.len() as u8) << 2) | 0b11;
        let mut payload = [0; 4];
        payload[..data.len()].copy_from_slice(data);
        self.send(command, index, sub, payload);
        Ok(())
    }

    /// Starts reading `index`/`sub` at time `now`.
    pub fn upload(&mut self, index: u16, sub: u8, now: Duration) -> Result<(), SdoError> {
        self.start(index, sub, true, now)?;
        self.send(0x40, index, sub, [0; 4]);
        Ok(())
    }

    fn start(&mut self, index: u16, sub: u8, upload: bool, now: Duration) -> Result<(), SdoError> {
        if self.pending.is_some() {
            return Err(SdoError::Busy { node: self.node });
        }
        self.pending = Some(Pending {
            index,
            sub,
            upload,
            deadline: now + self.timeout,
        });
        Ok(())
    }

    fn send(&mut self, command: u8, index: u16, sub: u8, payload: [u8; 4]) {
        let [lo, hi] = index.to_le_bytes();
        let data = [
            command, lo, hi, sub, payload[0], payload[1], payload[2], payload[3],
        ];
        self.outbox.push_back(
            CanFrame::standard(cob::sdo_request(self.node), &data).expect("8 bytes, 11-bit id"),
        );
    }

    /// The next frame to put on the bus.
    pub fn transmit(&mut self) -> Option<CanFrame> {
        self.outbox.pop_front()
    }

    /// Takes a frame from the bus. Frames that are not this server's SDO responses, and
    /// responses with no transfer pending (a late answer after a timeout), return `None`.
    pub fn receive(&mut self, frame: &CanFrame) -> Option<Result<SdoDone, SdoError>> {
        if standard_data_id(frame) != Some(cob::sdo_response(self.node)) {
            return None;
        }
        let pending = self.pending.take()?;
        Some(self.answer(pending, frame.data()))
    }

    fn answer(&mut self, pending: Pending, data: &[u8]) -> Result<SdoDone, SdoError> {
        let Pending { index, sub, .. } = pending;
        let node = self.node;
        if data.len() != 8 {
            let reason = format!("response of {} bytes, SDO frames have 8", data.len());
            return Err(self.fail(pending, reason, AbortCode::GENERAL));
        }
        let scs = data[0] >> 5;
        if scs == 4 {
            let code = AbortCode(u32::from_le_bytes([data[4], data[5], data[6], data[7]]));
            return Err(SdoError::Aborted {
                node,
                index,
                sub,
                code,
            });
        }
        let expected = if pending.upload { 2 } else { 3 };
        if scs != expected {
            let reason = format!("server command specifier {scs}, expected {expected}");
            return Err(self.fail(pending, reason, AbortCode::COMMAND));
        }
        let (got_index, got_sub) = (u16::from_le_bytes([data[1], data[2]]), data[3]);
        if (got_index, got_sub) != (index, sub) {
            let reason = format!("response for {got_index:04X}h/{got_sub:02X}h");
            return Err(self.fail(pending, reason, AbortCode::GENERAL));
        }
        if !pending.upload {
            return Ok(SdoDone::Downloaded { index, sub });
        }
        let (expedited, sized) = (data[0] & 0b10 != 0, data[0] & 0b01 != 0);
        if !expedited {
            let reason = "segmented upload, which this client does not implement".to_string();
            return Err(self.fail(pending, reason, AbortCode::GENERAL));
        }
        let size = if sized {
            4 - usize::from((data[0] >> 2) & 0b11)
        } else {
            4
        };
        Ok(SdoDone::Uploaded {
            index,
            sub,
            data: data[4..4 + size].to_vec(),
        })
    }

    /// Queues an abort for the pending transfer and builds the error.
    fn fail(&mut self, pending: Pending, reason: String, code: AbortCode) -> SdoError {
        self.send(0x80, pending.index, pending.sub, code.0.to_le_bytes());
        SdoError::Protocol {
            node: self.node,
            index: pending.index,
            sub: pending.sub,
            reason,
            code,
        }
    }

    /// Tells the client the time. A transfer past its deadline fails with
    /// [`SdoError::Timeout`], and an abort 0x05040000 is queued so the server forgets it.
    pub fn poll(&mut self, now: Duration) -> Option<SdoError> {
        let pending = self.pending.filter(|p| now >= p.deadline)?;
        self.pending = None;
        self.send(
            0x80,
            pending.index,
            pending.sub,
            AbortCode::TIMEOUT.0.to_le_bytes(),
        );
        Some(SdoError::Timeout {
            node: self.node,
            index: pending.index,
            sub: pending.sub,
            timeout: self.timeout,
        })
    }
}

/// One expedited SDO write.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SdoWrite {
    /// Object index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// The value, little-endian, 1–4 bytes.
    pub data: Vec<u8>,
}

impl SdoWrite {
    /// An UNSIGNED8 (or INTEGER8 as its bits).
    pub fn u8(index: u16, sub: u8, value: u8) -> SdoWrite {
        SdoWrite {
            index,
            sub,
            data: vec![value],
        }
    }

    /// An UNSIGNED16.
    pub fn u16(index: u16, sub: u8, value: u16) -> SdoWrite {
        SdoWrite {
            index,
            sub,
            data: value.to_le_bytes().to_vec(),
        }
    }

    /// An UNSIGNED32.
    pub fn u32(index: u16, sub: u8, value: u32) -> SdoWrite {
        SdoWrite {
            index,
            sub,
            data: value.to_le_bytes().to_vec(),
        }
    }

    /// An INTEGER32.
    pub fn i32(index: u16, sub: u8, value: i32) -> SdoWrite {
        SdoWrite {
            index,
            sub,
            data: value.to_le_bytes().to_vec(),
        }
    }
}

/// The value of a 1016h (consumer heartbeat time) entry: node id in bits 23–16, time in
/// milliseconds in bits 15–0 (CiA 301, object 1016h).
pub fn heartbeat_consumer_entry(node: NodeId, ms: u16) -> u32 {
    u32::from(node.get()) << 16 | u32::from(ms)
}

/// Which way a PDO goes, seen from the drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PdoDirection {
    /// RPDO: master → drive (communication 1400h+, mapping 1600h+).
    Receive,
    /// TPDO: drive → master (communication 1800h+, mapping 1A00h+).
    Transmit,
}

/// One mapped object.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MapEntry {
    /// Object index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// Width in bits.
    pub bits: u8,
}

impl MapEntry {
    /// The mapping value: index in bits 31–16, sub-index 15–8, length in bits 7–0.
    pub fn raw(self) -> u32 {
        u32::from(self.index) << 16 | u32::from(self.sub) << 8 | u32::from(self.bits)
    }
}

/// What a PDO should carry and when.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PdoConfig {
    /// RPDO or TPDO.
    pub direction: PdoDirection,
    /// Which of the four.
    pub number: PdoNumber,
    /// Transmission type: 0 acyclic synchronous, 1–240 every n-th SYNC, 252–253 on
    /// remote request, 254–255 event-driven; 241–251 are reserved.
    pub transmission: u8,
    /// The objects, in frame order.
    pub entries: Vec<MapEntry>,
}

/// Transmission type 1: synchronous, every SYNC (for a TPDO: sent after each SYNC; for an
/// RPDO: applied at the next SYNC).
pub const EVERY_SYNC: u8 = 1;

/// COB-ID bit 31: the PDO does not exist (is invalid).
pub const PDO_INVALID: u32 = 1 << 31;
/// COB-ID bit 30 of a TPDO: no remote request allowed.
pub const PDO_NO_RTR: u32 = 1 << 30;

/// The SDO writes that give `node` the PDO `config` on its predefined COB-ID, in the order
/// CiA 301's mapping procedure requires. TPDOs are made without RTR (bit 30), which
/// CiA 301 advises against and many drives refuse.
pub fn pdo_mapping(node: NodeId, config: &PdoConfig) -> Result<Vec<SdoWrite>, CanopenError> {
    if config.entries.is_empty() {
        return Err(CanopenError::EmptyMapping);
    }
    if (241..=251).contains(&config.transmission) {
        return Err(CanopenError::TransmissionType(config.transmission));
    }
    let mut bits = 0u32;
    for entry in &config.entries {
        if entry.bits == 0 {
            return Err(CanopenError::ZeroWidth {
                index: entry.index,
                sub: entry.sub,
            });
        }
        bits += u32::from(entry.bits);
    }
    if bits > 64 {
        return Err(CanopenError::MappingBits(bits));
    }
    let offset = u16::from(config.number.get() - 1);
    let (communication, mapping, cob_id) = match config.direction {
        PdoDirection::Receive => (
            0x1400 + offset,
            0x1600 + offset,
            u32::from(cob::rpdo(config.number, node)),
        ),
        PdoDirection::Transmit => (
            0x1800 + offset,
            0x1A00 + offset,
            u32::from(cob::tpdo(config.number, node)) | PDO_NO_RTR,
        ),
    };
    let mut writes = vec![
        SdoWrite::u32(communication, 1, cob_id | PDO_INVALID),
        SdoWrite::u8(communication, 2, config.transmission),
        SdoWrite::u8(mapping, 0, 0),
    ];
    for (k, entry) in config.entries.iter().enumerate() {
        writes.push(SdoWrite::u32(mapping, k as u8 + 1, entry.raw()));
    }
    writes.push(SdoWrite::u8(mapping, 0, config.entries.len() as u8));
    writes.push(SdoWrite::u32(communication, 1, cob_id));
    Ok(writes)
}

#[cfg(test)]
mod tests;
