//! Simulated CAN equipment: a Lawicel (slcan) serial adapter and CiA 402 servo drives,
//! sans-I/O like the rest of the crate: frames and bytes in, frames and bytes out,
//! simulated time passed in by the caller.
//!
//! The bridge (whirl's `can` module) streams set-points to three drives, X, Z and C as
//! nodes 1, 2 and 3, through an slcan adapter. This module is the other end of that wire,
//! written apart from the bridge's code on purpose: the two meet in end-to-end tests, and
//! a misreading of CiA 301 or 402 shared by both would pass every test of either.
//!
//! - [`slcan`]: the adapter. Host commands (`S`, `O`, `C`, `Z`, `t`, `T`, `r`, `R`) in,
//!   replies and received frames out; frames the host sent go to the bus.
//! - [`drive`]: a CiA 402 drive. NMT with boot-up and heartbeat, an expedited SDO server
//!   over a small object dictionary, the power state machine, cyclic synchronous position
//!   (and interpolated position) mode driven by RPDO1 on SYNC, TPDO1 back, following-error faults with EMCY.
//! - [`bus`]: the whirling lathe's three drives (X, Z, C) behind an adapter as one unit,
//!   each SYNC's cycle recorded as an executed move, with the Δ guard's seat, travel
//!   limits, a cable to pull, a fault to inject and a clock that SYNC can drive.
//! - [`serve`]: the bus on a byte stream (a pseudo-terminal), clocked by the master's
//!   SYNCs or the wall (the only async part).
//!
//! Wiring an adapter and drives is otherwise a loop the caller writes (the tests below
//! do): host bytes into the adapter, the adapter's transmitted frames to every drive,
//! every drive's frames to the adapter and to the other drives.

pub mod bus;
pub mod drive;
pub mod serve;
pub mod slcan;

pub use bus::{Bus, BusConfig, BusError, BusEvent};
pub use drive::{Drive, DriveConfig, DriveEvent, NmtState, PowerState};
pub use slcan::SlcanAdapter;

/// A CAN frame as the simulator passes it around. Fields are open; the drives ignore
/// frames that could not be on a bus (more than 8 bytes) rather than trusting them.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Frame {
    /// The identifier: 11 bits, or 29 with `extended`.
    pub id: u32,
    /// A 29-bit identifier.
    pub extended: bool,
    /// A remote request: `data` is empty and `dlc` is the length asked for.
    pub remote: bool,
    /// Data length code.
    pub dlc: u8,
    /// The data bytes.
    pub data: Vec<u8>,
}

impl Frame {
    /// A data frame on an 11-bit identifier, the only kind CANopen uses.
    pub fn data(id: u16, data: &[u8]) -> Frame {
        Frame {
            id: u32::from(id),
            extended: false,
            remote: false,
            dlc: data.len() as u8,
            data: data.to_vec(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An adapter and drives on one bus.
    struct Bench {
        adapter: SlcanAdapter,
        drives: Vec<Drive>,
        host: Vec<u8>,
    }

    impl Bench {
        fn new(nodes: &[u8]) -> Bench {
            let drives = nodes
                .iter()
                .map(|node| Drive::new(DriveConfig::new(*node)).unwrap())
                .collect();
            let mut bench = Bench {
                adapter: SlcanAdapter::new(),
                drives,
                host: Vec::new(),
            };
            bench.settle();
            bench
        }

        /// Moves frames until nothing is in flight.
        fn settle(&mut self) {
            for _ in 0..100 {
                let mut on_bus: Vec<(Option<usize>, Frame)> = self
                    .adapter
                    .take_transmitted()
                    .into_iter()
                    .map(|frame| (None, frame))
                    .collect();
                for (k, drive) in self.drives.iter_mut().enumerate() {
                    on_bus.extend(drive.take_output().into_iter().map(|f| (Some(k), f)));
                }
                if on_bus.is_empty() {
                    self.host.extend(self.adapter.take_output());
                    return;
                }
                for (sender, frame) in on_bus {
                    if sender.is_some() {
                        self.adapter.deliver(&frame);
                    }
                    for (k, drive) in self.drives.iter_mut().enumerate() {
                        if sender != Some(k) {
                            drive.receive(&frame);
                        }
                    }
                }
            }
            panic!("the bus never went quiet");
        }

        fn send(&mut self, bytes: &[u8]) -> String {
            self.adapter.receive(bytes);
            self.settle();
            String::from_utf8(std::mem::take(&mut self.host)).unwrap()
        }
    }

    #[test]
    fn three_drives_behind_an_adapter_boot_and_answer() {
        let mut bench = Bench::new(&[1, 2, 3]);
        // The boot-up messages went by while the channel was closed: nothing reached the
        // host.
        assert_eq!(bench.send(b"S8\rO\r"), "\r\r");
        // NMT start for all nodes; no answer on the bus, the adapter acknowledges.
        assert_eq!(bench.send(b"t00020100\r"), "z\r");
        for drive in &bench.drives {
            assert_eq!(drive.nmt_state(), NmtState::Operational);
        }
        // SDO upload of 6041h from node 2: expedited 2-byte answer 0x0250, Switch on
        // disabled with voltage enabled and remote.
        assert_eq!(
            bench.send(b"t60284041600000000000\r"),
            "z\rt58284B41600050020000\r"
        );
        // A SYNC: every drive's TPDO1 (statusword, position actual) on 0x180 + node.
        let answer = bench.send(b"t0800\r");
        assert_eq!(
            answer,
            "z\rt1816500200000000\rt1826500200000000\rt1836500200000000\r"
        );
    }

    #[test]
    fn a_drive_is_enabled_and_moved_through_the_adapter() {
        let mut bench = Bench::new(&[1]);
        bench.send(b"S8\rO\rt00020101\r");
        // 6060h = 8 (CSP) by SDO, then the controlword walk by RPDO1 + SYNC:
        // 6040h (2 bytes) then 607Ah (4 bytes).
        assert_eq!(
            bench.send(b"t60182F60600008000000\r"),
            "z\rt58186060600000000000\r"
        );
        for word in ["06", "07", "0F"] {
            bench.send(format!("t2016{word}0000000000\rt0800\r").as_bytes());
        }
        assert_eq!(bench.drives[0].power_state(), PowerState::OperationEnabled);
        // Target 500 counts with the default 1000 counts a cycle: there at the next SYNC.
        bench.send(b"t20160F00F4010000\r");
        let answer = bench.send(b"t0800\r");
        assert_eq!(answer, "z\rt18163712F4010000\r");
        assert_eq!(bench.drives[0].position(), 500);
    }
}
