//! PDOs (CiA 301): the communication and mapping objects of the four RPDOs and four TPDOs,
//! the mapping procedure's checks, and their traffic: RPDOs received and applied, TPDOs sent
//! at SYNC or on change. Apart because it is the drive's cyclic data path, separate from
//! what the data means.

use super::dictionary::abort;
use super::{Drive, Frame, NmtState};

/// EMCY code of an RPDO shorter than its mapping (CiA 301).
pub const EMCY_PDO_LENGTH: u16 = 0x8210;

/// One PDO's communication and mapping objects, and its traffic state.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) struct Pdo {
    /// Communication sub-index 1: bit 31 set for invalid, the 11-bit CAN id below.
    pub(super) cob_id: u32,
    /// Communication sub-index 2, the transmission type.
    pub(super) transmission: u8,
    /// Mapping sub-index 0: how many entries of `map` are in use.
    pub(super) count: u8,
    /// Mapping sub-indices 1–8: index, sub-index and bit length of each entry.
    pub(super) map: [u32; 8],
    /// SYNCs since the last transmission (TPDO types 1–240).
    pub(super) syncs: u8,
    /// The data last sent (TPDO), to send on change.
    pub(super) last_sent: Option<Vec<u8>>,
    /// Received data waiting for SYNC (synchronous RPDO).
    pub(super) received: Option<Vec<u8>>,
}

impl Pdo {
    fn new(cob_id: u32, transmission: u8, map: &[u32]) -> Pdo {
        let mut entries = [0; 8];
        entries[..map.len()].copy_from_slice(map);
        Pdo {
            cob_id,
            transmission,
            count: map.len() as u8,
            map: entries,
            syncs: 0,
            last_sent: None,
            received: None,
        }
    }

    fn valid(&self) -> bool {
        self.cob_id & 0x8000_0000 == 0
    }

    fn can_id(&self) -> u16 {
        (self.cob_id & 0x7FF) as u16
    }

    fn entries(&self) -> impl Iterator<Item = (u16, u8, usize)> + '_ {
        self.map[..usize::from(self.count)].iter().map(|raw| {
            (
                (raw >> 16) as u16,
                (raw >> 8) as u8,
                (raw & 0xFF) as usize / 8,
            )
        })
    }
}

impl Drive {
    /// At SYNC: the synchronous RPDOs (types 0–240) received since the last one are
    /// applied.
    pub(super) fn apply_synchronous_rpdos(&mut self) {
        for k in 0..4 {
            let pdo = &mut self.rpdo[k];
            if pdo.valid() && pdo.transmission <= 240 {
                if let Some(data) = pdo.received.take() {
                    self.apply_rpdo(k, &data);
                }
            }
        }
    }

    /// At SYNC, after the cycle: the synchronous TPDOs that are due (type 0 on change,
    /// 1–240 every n-th SYNC) are sent.
    pub(super) fn send_synchronous_tpdos(&mut self) {
        for k in 0..4 {
            let pdo = &mut self.tpdo[k];
            if !pdo.valid() || pdo.transmission > 240 {
                continue;
            }
            if pdo.transmission == 0 {
                self.send_tpdo(k, true);
            } else {
                pdo.syncs += 1;
                if pdo.syncs >= pdo.transmission {
                    pdo.syncs = 0;
                    self.send_tpdo(k, false);
                }
            }
        }
    }

    /// Event-driven TPDOs (types 254, 255) whose data changed.
    pub(super) fn send_changed_tpdos(&mut self) {
        if self.nmt != NmtState::Operational {
            return;
        }
        for k in 0..4 {
            if self.tpdo[k].valid() && self.tpdo[k].transmission >= 254 {
                self.send_tpdo(k, true);
            }
        }
    }

    /// Sends TPDO `k` (only if its data changed, with `on_change`).
    fn send_tpdo(&mut self, k: usize, on_change: bool) {
        let entries: Vec<_> = self.tpdo[k].entries().collect();
        let mut data = Vec::with_capacity(8);
        for (index, sub, bytes) in entries {
            let value = self.entry(index, sub).map_or(0, |entry| entry.value);
            data.extend_from_slice(&value.to_le_bytes()[..bytes]);
        }
        let pdo = &mut self.tpdo[k];
        if on_change && pdo.last_sent.as_ref() == Some(&data) {
            return;
        }
        let frame = Frame::data(pdo.can_id(), &data);
        pdo.last_sent = Some(data);
        self.output.push(frame);
    }

    /// A frame that may be an RPDO: kept for the next SYNC (types 0–240) or applied at
    /// once (254, 255); shorter than its mapping, dropped with EMCY 0x8210.
    pub(super) fn rpdo_frame(&mut self, id: u16, data: &[u8]) {
        if self.nmt != NmtState::Operational {
            return;
        }
        let Some(k) = self.rpdo.iter().position(|p| p.valid() && p.can_id() == id) else {
            return;
        };
        let length: usize = self.rpdo[k].entries().map(|(_, _, bytes)| bytes).sum();
        if data.len() < length {
            self.emcy(EMCY_PDO_LENGTH);
            return;
        }
        if self.rpdo[k].transmission <= 240 {
            self.rpdo[k].received = Some(data[..length].to_vec());
        } else {
            self.apply_rpdo(k, &data[..length]);
        }
    }

    fn apply_rpdo(&mut self, k: usize, data: &[u8]) {
        let entries: Vec<_> = self.rpdo[k].entries().collect();
        let mut at = 0;
        for (index, sub, bytes) in entries {
            let mut value = [0; 4];
            value[..bytes].copy_from_slice(&data[at..at + bytes]);
            at += bytes;
            // Mapped objects are writable; a value out of range (a mode the drive does
            // not have) is dropped, as a write of it by SDO would be refused.
            let _ = self.write(index, sub, u32::from_le_bytes(value));
        }
    }

    /// The PDO behind a communication or mapping index (1400h…1A03h).
    pub(super) fn pdo(&self, index: u16) -> &Pdo {
        let k = usize::from(index & 0x3);
        if index < 0x1800 {
            &self.rpdo[k]
        } else {
            &self.tpdo[k]
        }
    }

    fn pdo_mut(&mut self, index: u16) -> &mut Pdo {
        let k = usize::from(index & 0x3);
        if index < 0x1800 {
            &mut self.rpdo[k]
        } else {
            &mut self.tpdo[k]
        }
    }

    /// Writes 1400h–1403h or 1800h–1803h: sub-index 1 the COB-ID, 2 the transmission
    /// type; see the [`drive`](super) module docs for what is refused.
    pub(super) fn write_communication(
        &mut self,
        index: u16,
        sub: u8,
        value: u32,
    ) -> Result<(), u32> {
        let pdo = self.pdo_mut(index);
        if sub == 2 {
            let kind = value as u8;
            if (241..=253).contains(&kind) {
                return Err(abort::INVALID);
            }
            pdo.transmission = kind;
            return Ok(());
        }
        // Sub-index 1, the COB-ID: bits 11–29 must be 0 (11-bit identifiers only).
        let valid = value & 0x8000_0000 == 0;
        let id = value & 0x7FF;
        if value & 0x3FFF_F800 != 0 {
            return Err(abort::INVALID);
        }
        if valid && (pdo.count == 0 || id == 0 || (pdo.valid() && id != u32::from(pdo.can_id()))) {
            return Err(abort::INVALID);
        }
        pdo.cob_id = value;
        pdo.syncs = 0;
        pdo.last_sent = None;
        pdo.received = None;
        Ok(())
    }

    /// Writes 1600h–1603h or 1A00h–1A03h following CiA 301's mapping procedure.
    pub(super) fn write_mapping(&mut self, index: u16, sub: u8, value: u32) -> Result<(), u32> {
        let receive = index < 0x1800;
        let pdo = self.pdo_mut(index);
        if pdo.valid() || (sub != 0 && pdo.count != 0) {
            return Err(abort::UNSUPPORTED);
        }
        if sub != 0 {
            if !mappable(receive, value) {
                return Err(abort::CANNOT_MAP);
            }
            pdo.map[usize::from(sub) - 1] = value;
            return Ok(());
        }
        let count = value as u8;
        if count > 8 {
            return Err(abort::MAP_TOO_LONG);
        }
        let entries = &pdo.map[..usize::from(count)];
        if !entries.iter().all(|raw| mappable(receive, *raw)) {
            return Err(abort::CANNOT_MAP);
        }
        if entries.iter().map(|raw| raw & 0xFF).sum::<u32>() > 64 {
            return Err(abort::MAP_TOO_LONG);
        }
        pdo.count = count;
        Ok(())
    }
}

/// The objects a PDO can carry, as mapping values (index, sub-index, bit length).
fn mappable(receive: bool, raw: u32) -> bool {
    const RECEIVE: [u32; 4] = [0x6040_0010, 0x607A_0020, 0x6060_0008, 0x60C1_0120];
    const TRANSMIT: [u32; 3] = [0x6041_0010, 0x6064_0020, 0x6061_0008];
    if receive {
        RECEIVE.contains(&raw)
    } else {
        TRANSMIT.contains(&raw)
    }
}

/// Power-on PDOs: RPDO1 = controlword + target, TPDO1 = statusword + actual position,
/// both every SYNC; the rest invalid on their predefined identifiers.
pub(super) fn default_pdos(node: u8) -> ([Pdo; 4], [Pdo; 4]) {
    let node = u32::from(node);
    let invalid = |base: u32| Pdo::new(0x8000_0000 | (base + node), 0xFF, &[]);
    let rpdo = [
        Pdo::new(0x200 + node, 1, &[0x6040_0010, 0x607A_0020]),
        invalid(0x300),
        invalid(0x400),
        invalid(0x500),
    ];
    // TPDOs without remote request (COB-ID bit 30): the sim answers none.
    let tpdo = [
        Pdo::new(0x4000_0000 | (0x180 + node), 1, &[0x6041_0010, 0x6064_0020]),
        invalid(0x4000_0280),
        invalid(0x4000_0380),
        invalid(0x4000_0480),
    ];
    (rpdo, tpdo)
}
