//! A CAN 2.0 frame as a value: an 11-bit (2.0A) or 29-bit (2.0B) identifier, and either
//! 0–8 data bytes or a remote request (RTR) with its data length code.
//!
//! Every constructor checks what ISO 11898-1 allows, so a frame that exists can always be
//! put on the bus: the codecs ([`super::slcan`], and socketcan later) never have to refuse
//! one. A remote frame carries no data but does carry a DLC, the length it asks for, which
//! is why RTR is a kind of frame here and not a flag beside a data slice.

use std::fmt;

use thiserror::Error;

/// The largest 11-bit identifier.
pub const MAX_STANDARD_ID: u16 = 0x7FF;
/// The largest 29-bit identifier.
pub const MAX_EXTENDED_ID: u32 = 0x1FFF_FFFF;
/// The most data bytes a classic CAN frame holds.
pub const MAX_DATA: usize = 8;

/// A frame that cannot exist.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Error)]
pub enum FrameError {
    /// An 11-bit identifier above 0x7FF.
    #[error("standard CAN id 0x{0:X} is above 0x7FF")]
    StandardId(u32),
    /// A 29-bit identifier above 0x1FFFFFFF.
    #[error("extended CAN id 0x{0:X} is above 0x1FFFFFFF")]
    ExtendedId(u32),
    /// More than 8 data bytes.
    #[error("{0} data bytes, a CAN 2.0 frame holds at most 8")]
    TooLong(usize),
    /// A remote frame asking for more than 8 bytes.
    #[error("remote frame DLC {0}, at most 8")]
    Dlc(u8),
}

/// A CAN identifier: its width is part of it (0x123 standard and 0x123 extended are
/// different identifiers on the bus).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum CanId {
    /// 11 bits, CAN 2.0A.
    Standard(u16),
    /// 29 bits, CAN 2.0B.
    Extended(u32),
}

impl CanId {
    /// An 11-bit identifier, 0..=0x7FF.
    pub fn standard(id: u16) -> Result<CanId, FrameError> {
        if id > MAX_STANDARD_ID {
            return Err(FrameError::StandardId(u32::from(id)));
        }
        Ok(CanId::Standard(id))
    }

    /// A 29-bit identifier, 0..=0x1FFFFFFF.
    pub fn extended(id: u32) -> Result<CanId, FrameError> {
        if id > MAX_EXTENDED_ID {
            return Err(FrameError::ExtendedId(id));
        }
        Ok(CanId::Extended(id))
    }

    /// The identifier's value, whatever its width.
    pub fn raw(self) -> u32 {
        match self {
            CanId::Standard(id) => u32::from(id),
            CanId::Extended(id) => id,
        }
    }

    /// Whether it is a 29-bit identifier.
    pub fn is_extended(self) -> bool {
        matches!(self, CanId::Extended(_))
    }
}

/// Shown as candump writes identifiers: three hex digits standard, eight extended.
impl fmt::Display for CanId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CanId::Standard(id) => write!(f, "{id:03X}"),
            CanId::Extended(id) => write!(f, "{id:08X}"),
        }
    }
}

/// A classic CAN frame. Fields are private so that only valid frames exist.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct CanFrame {
    id: CanId,
    remote: bool,
    dlc: u8,
    data: [u8; MAX_DATA],
}

impl CanFrame {
    /// A data frame with `data` (0–8 bytes).
    pub fn new(id: CanId, data: &[u8]) -> Result<CanFrame, FrameError> {
        if data.len() > MAX_DATA {
            return Err(FrameError::TooLong(data.len()));
        }
        let mut bytes = [0; MAX_DATA];
        bytes[..data.len()].copy_from_slice(data);
        Ok(CanFrame {
            id,
            remote: false,
            dlc: data.len() as u8,
            data: bytes,
        })
    }

    /// A remote (RTR) frame asking for `dlc` bytes (0–8).
    pub fn remote(id: CanId, dlc: u8) -> Result<CanFrame, FrameError> {
        if usize::from(dlc) > MAX_DATA {
            return Err(FrameError::Dlc(dlc));
        }
        Ok(CanFrame {
            id,
            remote: true,
            dlc,
            data: [0; MAX_DATA],
        })
    }

    /// A data frame on a standard identifier: the shape of every CANopen frame.
    pub fn standard(id: u16, data: &[u8]) -> Result<CanFrame, FrameError> {
        CanFrame::new(CanId::standard(id)?, data)
    }

    /// The identifier.
    pub fn id(&self) -> CanId {
        self.id
    }

    /// Whether this is a remote request.
    pub fn is_remote(&self) -> bool {
        self.remote
    }

    /// The data length code: the number of data bytes, or for a remote frame the number
    /// asked for.
    pub fn dlc(&self) -> u8 {
        self.dlc
    }

    /// The data bytes (none for a remote frame).
    pub fn data(&self) -> &[u8] {
        if self.remote {
            &[]
        } else {
            &self.data[..usize::from(self.dlc)]
        }
    }

    /// Bit times the frame holds the bus, without stuff bits: ISO 11898-1's fields (start
    /// of frame, arbitration, control, data, CRC and its delimiter, acknowledgement, end of
    /// frame) and the 3-bit intermission before the next. Stuffing adds up to a fifth.
    pub fn bits(&self) -> u32 {
        // SOF 1, ID 11, RTR 1, IDE 1, r0 1, DLC 4, CRC 15 + 1, ACK 2, EOF 7, IFS 3; the
        // extended format adds SRR 1 and 18 more ID bits, its r1 taking RTR's place.
        let overhead = match self.id {
            CanId::Standard(_) => 47,
            CanId::Extended(_) => 67,
        };
        overhead + 8 * self.data().len() as u32
    }
}

/// candump's format: `123#DEADBEEF`, `123#R2` for a remote frame.
impl fmt::Display for CanFrame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}#", self.id)?;
        if self.remote {
            return write!(f, "R{}", self.dlc);
        }
        for byte in self.data() {
            write!(f, "{byte:02X}")?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_holds_the_bus_for_its_fields_and_data() {
        // ISO 11898-1 without stuffing: a full 8-byte base frame is 108 bits plus the
        // 3-bit intermission; a SYNC (no data) 44 + 3; an extended remote request 64 + 3.
        assert_eq!(CanFrame::standard(0x181, &[0; 8]).unwrap().bits(), 111);
        assert_eq!(CanFrame::standard(0x080, &[]).unwrap().bits(), 47);
        let remote = CanFrame::remote(CanId::extended(0x1234).unwrap(), 8).unwrap();
        assert_eq!(remote.bits(), 67);
    }

    #[test]
    fn identifier_ranges_are_the_standards() {
        // ISO 11898-1: base format 11 bits, extended format 29 bits.
        assert_eq!(CanId::standard(0x7FF), Ok(CanId::Standard(0x7FF)));
        assert_eq!(CanId::standard(0x800), Err(FrameError::StandardId(0x800)));
        assert_eq!(
            CanId::extended(0x1FFF_FFFF),
            Ok(CanId::Extended(0x1FFF_FFFF))
        );
        assert_eq!(
            CanId::extended(0x2000_0000),
            Err(FrameError::ExtendedId(0x2000_0000))
        );
        assert!(CanId::extended(5).unwrap().is_extended());
        assert!(!CanId::standard(5).unwrap().is_extended());
        assert_ne!(CanId::Standard(0x123), CanId::Extended(0x123));
        assert_eq!(CanId::Extended(0x123).raw(), 0x123);
    }

    #[test]
    fn data_frames_hold_zero_to_eight_bytes() {
        let empty = CanFrame::standard(0x080, &[]).unwrap();
        assert_eq!((empty.dlc(), empty.data()), (0, &[][..]));
        let full = CanFrame::standard(0x601, &[1, 2, 3, 4, 5, 6, 7, 8]).unwrap();
        assert_eq!(full.dlc(), 8);
        assert_eq!(full.data(), &[1, 2, 3, 4, 5, 6, 7, 8]);
        assert!(!full.is_remote());
        assert_eq!(
            CanFrame::standard(0x601, &[0; 9]),
            Err(FrameError::TooLong(9))
        );
        assert_eq!(
            CanFrame::standard(0x800, &[]),
            Err(FrameError::StandardId(0x800))
        );
    }

    #[test]
    fn remote_frames_carry_a_dlc_and_no_data() {
        let rtr = CanFrame::remote(CanId::Standard(0x701), 1).unwrap();
        assert!(rtr.is_remote());
        assert_eq!(rtr.dlc(), 1);
        assert!(rtr.data().is_empty());
        assert_eq!(
            CanFrame::remote(CanId::Standard(0x701), 9),
            Err(FrameError::Dlc(9))
        );
    }

    #[test]
    fn display_is_candumps() {
        let frame = CanFrame::standard(0x18A, &[0x27, 0x06]).unwrap();
        assert_eq!(frame.to_string(), "18A#2706");
        let ext = CanFrame::new(CanId::Extended(0x1234), &[0xFF]).unwrap();
        assert_eq!(ext.to_string(), "00001234#FF");
        let rtr = CanFrame::remote(CanId::Standard(0x701), 1).unwrap();
        assert_eq!(rtr.to_string(), "701#R1");
        assert_eq!(
            FrameError::TooLong(9).to_string(),
            "9 data bytes, a CAN 2.0 frame holds at most 8"
        );
    }
}
