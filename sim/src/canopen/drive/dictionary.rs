//! The object dictionary and its expedited SDO server: every object's size, access and
//! value, writes with their range checks, and the SDO protocol's answers and aborts. Apart
//! because it is the one table of what the drive exposes, read by SDO and PDO alike.

use super::{Drive, NmtState, MODE_CSP, MODE_IP};

/// SDO abort codes the server gives (CiA 301).
pub(super) mod abort {
    pub const COMMAND: u32 = 0x0504_0001;
    pub const UNSUPPORTED: u32 = 0x0601_0000;
    pub const READ_ONLY: u32 = 0x0601_0002;
    pub const NO_OBJECT: u32 = 0x0602_0000;
    pub const CANNOT_MAP: u32 = 0x0604_0041;
    pub const MAP_TOO_LONG: u32 = 0x0604_0042;
    pub const TOO_LONG: u32 = 0x0607_0012;
    pub const TOO_SHORT: u32 = 0x0607_0013;
    pub const NO_SUB: u32 = 0x0609_0011;
    pub const INVALID: u32 = 0x0609_0030;
}

/// 1000h: CiA 402 (0x0192) in the low word, servo drive (0x02) above it.
pub const DEVICE_TYPE: u32 = 0x0002_0192;
/// 1018h sub-index 1, the vendor-ID: CiA assigns them to manufacturers, and a simulator
/// has none.
pub const VENDOR_ID: u32 = 0;
/// 1018h sub-index 2, the product code: the manufacturer's own; the profile's number here.
pub const PRODUCT_CODE: u32 = 402;
/// 1018h sub-index 3, the revision number: major revision 1 in the high word, minor 0 in
/// the low one (CiA 301's layout).
pub const REVISION: u32 = 0x0001_0000;
/// The interpolation time indices the drive takes: 1 µs to 1 s units.
const INTERPOLATION_INDICES: std::ops::RangeInclusive<i8> = -6..=0;

/// An object dictionary entry as the SDO server sees it.
pub(super) struct Entry {
    size: usize,
    writable: bool,
    /// The value, in the low `size` bytes.
    pub(super) value: u32,
}

impl Drive {
    /// An SDO request on 0x600 + node: the answer, or an abort, on 0x580 + node.
    pub(super) fn sdo_request(&mut self, data: &[u8]) {
        if self.nmt == NmtState::Stopped || data.len() != 8 {
            return;
        }
        let index = u16::from_le_bytes([data[1], data[2]]);
        let sub = data[3];
        let answer = match data[0] >> 5 {
            1 => self.sdo_download(data[0], index, sub, &data[4..]),
            2 => self.sdo_upload(index, sub),
            4 => return, // the client aborted: nothing to answer
            _ => Err(abort::COMMAND),
        };
        let [lo, hi] = index.to_le_bytes();
        let reply = match answer {
            Ok((command, value)) => [command, lo, hi, sub, value[0], value[1], value[2], value[3]],
            Err(code) => {
                let c = code.to_le_bytes();
                [0x80, lo, hi, sub, c[0], c[1], c[2], c[3]]
            }
        };
        self.send(0x580, &reply);
    }

    fn sdo_download(
        &mut self,
        command: u8,
        index: u16,
        sub: u8,
        payload: &[u8],
    ) -> Result<(u8, [u8; 4]), u32> {
        if command & 0b10 == 0 {
            return Err(abort::COMMAND);
        }
        let entry = self.entry(index, sub)?;
        if !entry.writable {
            return Err(abort::READ_ONLY);
        }
        if command & 0b01 != 0 {
            let given = 4 - usize::from((command >> 2) & 0b11);
            if given > entry.size {
                return Err(abort::TOO_LONG);
            }
            if given < entry.size {
                return Err(abort::TOO_SHORT);
            }
        }
        let mut value = [0; 4];
        value[..entry.size].copy_from_slice(&payload[..entry.size]);
        self.write(index, sub, u32::from_le_bytes(value))?;
        Ok((0x60, [0; 4]))
    }

    fn sdo_upload(&self, index: u16, sub: u8) -> Result<(u8, [u8; 4]), u32> {
        let entry = self.entry(index, sub)?;
        let command = 0x43 | ((4 - entry.size as u8) << 2);
        let mut value = entry.value.to_le_bytes();
        value[entry.size..].fill(0);
        Ok((command, value))
    }

    /// The object dictionary.
    pub(super) fn entry(&self, index: u16, sub: u8) -> Result<Entry, u32> {
        let var = |size, writable, value| {
            if sub == 0 {
                Ok(Entry {
                    size,
                    writable,
                    value,
                })
            } else {
                Err(abort::NO_SUB)
            }
        };
        match index {
            0x1000 => var(4, false, DEVICE_TYPE),
            0x1001 => var(1, false, self.error_register.into()),
            0x1017 => var(2, true, self.heartbeat_ms.into()),
            // The identity object, which CiA 301 makes mandatory (sub-index 1 at least):
            // vendor-ID, product code, revision and serial number (the node-ID here).
            0x1018 => {
                let value = match sub {
                    0 => 4,
                    1 => VENDOR_ID,
                    2 => PRODUCT_CODE,
                    3 => REVISION,
                    4 => self.config.node.into(),
                    _ => return Err(abort::NO_SUB),
                };
                Ok(Entry {
                    size: if sub == 0 { 1 } else { 4 },
                    writable: false,
                    value,
                })
            }
            0x6040 => var(2, true, self.controlword.into()),
            0x6041 => var(2, false, self.statusword().into()),
            0x6060 => var(1, true, u32::from(self.mode as u8)),
            0x6061 => var(1, false, u32::from(self.mode as u8)),
            0x6064 => var(4, false, self.actual as u32),
            0x6065 => var(4, true, self.window),
            0x607A => var(4, true, self.target as u32),
            0x60C1 => {
                let (size, writable, value) = match sub {
                    0 => (1, false, 1),
                    1 => (4, true, self.interpolation_data as u32),
                    _ => return Err(abort::NO_SUB),
                };
                Ok(Entry {
                    size,
                    writable,
                    value,
                })
            }
            0x60C2 => {
                let (value, index) = self.interpolation;
                let (writable, value) = match sub {
                    0 => (false, 2),
                    1 => (true, value.into()),
                    2 => (true, u32::from(index as u8)),
                    _ => return Err(abort::NO_SUB),
                };
                Ok(Entry {
                    size: 1,
                    writable,
                    value,
                })
            }
            0x1400..=0x1403 | 0x1800..=0x1803 => {
                let pdo = self.pdo(index);
                let (size, writable, value) = match sub {
                    0 => (1, false, 2),
                    1 => (4, true, pdo.cob_id),
                    2 => (1, true, pdo.transmission.into()),
                    _ => return Err(abort::NO_SUB),
                };
                Ok(Entry {
                    size,
                    writable,
                    value,
                })
            }
            0x1600..=0x1603 | 0x1A00..=0x1A03 => {
                let pdo = self.pdo(index);
                match sub {
                    0 => Ok(Entry {
                        size: 1,
                        writable: true,
                        value: pdo.count.into(),
                    }),
                    1..=8 => Ok(Entry {
                        size: 4,
                        writable: true,
                        value: pdo.map[usize::from(sub) - 1],
                    }),
                    _ => Err(abort::NO_SUB),
                }
            }
            _ => Err(abort::NO_OBJECT),
        }
    }

    /// Writes a writable object (its existence and size already checked).
    pub(super) fn write(&mut self, index: u16, sub: u8, value: u32) -> Result<(), u32> {
        match index {
            0x1017 => {
                self.heartbeat_ms = value as u16;
                self.restart_heartbeat();
            }
            0x6040 => self.command(value as u16),
            0x6060 => match value as u8 as i8 {
                mode @ (0 | MODE_IP | MODE_CSP) => self.mode = mode,
                _ => return Err(abort::INVALID),
            },
            0x6065 => self.window = value,
            0x607A => self.target = value as i32,
            // Sub-index 0 is read-only: only sub-index 1 gets here.
            0x60C1 => self.interpolation_data = value as i32,
            0x60C2 => self.write_interpolation(sub, value as u8)?,
            0x1400..=0x1403 | 0x1800..=0x1803 => self.write_communication(index, sub, value)?,
            0x1600..=0x1603 | 0x1A00..=0x1A03 => self.write_mapping(index, sub, value)?,
            _ => return Err(abort::READ_ONLY),
        }
        Ok(())
    }

    /// 60C2h sub-index 1 (value) or 2 (index); see the [`drive`](super) module docs for what
    /// is refused.
    fn write_interpolation(&mut self, sub: u8, byte: u8) -> Result<(), u32> {
        if sub == 1 {
            if byte == 0 {
                return Err(abort::INVALID);
            }
            self.interpolation.0 = byte;
        } else {
            let index = byte as i8;
            if !INTERPOLATION_INDICES.contains(&index) {
                return Err(abort::INVALID);
            }
            self.interpolation.1 = index;
        }
        Ok(())
    }
}
