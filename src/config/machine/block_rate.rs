//! The controller's sustainable block rate: how many linked moves a second it runs at their
//! programmed durations. A profile may give it (`max_block_rate`); otherwise each controller
//! family has a default, from what the project models of it (docs/planner.md, "The fastest
//! feed", says why each):
//!
//! | family | default | from |
//! |---|---|---|
//! | grbl/grblHAL | 100 blocks/s | one step segment tick a block (`ACCELERATION_TICKS_PER_SECOND`) |
//! | LinuxCNC | 980 blocks/s | a segment lasts 1.02 trajectory periods (`TP_MIN_SEGMENT_CYCLES`, 1 ms) |
//! | Modbus PLC | 100 blocks/s | one segment a PLC scan of 10 ms (`MAX_SEGMENT_RATE`) |
//! | CANopen drives | 10⁶ / `cycle_us` | one set-point a SYNC cycle |
//!
//! On LinuxCNC, Modbus and CAN the rate bounds every move: each linked move must last at least
//! 1 / rate. The Modbus map refuses a shorter segment outright, the CAN sampler stretches a move
//! to whole cycles, and LinuxCNC slows a shorter segment until it lasts 1.02 trajectory periods. grblHAL prepares its blocks
//! ahead: its stepper runs from a buffer of step segments, and a block shorter than a tick
//! only ends its segment early, eating into the lead the buffer keeps. So there the rate is
//! sustained, not per move: the moves must not outrun a block a tick for longer than the
//! buffer's [`GRBLHAL_SEGMENTS_AHEAD`] segments cover.

use super::{Dialect, MachineProfile};
use crate::config::connection::Connection;

/// grblHAL's `ACCELERATION_TICKS_PER_SECOND` (`config.h`): its stepper runs a planner block as
/// step segments of at most 1/100 s, and a block shorter than that as one shorter segment.
pub const GRBLHAL_TICKS_PER_SECOND: f64 = 100.0;

/// Step segments grblHAL holds prepared ahead of the one running: `SEGMENT_BUFFER_SIZE` (10,
/// `config.h`) less the ring buffer's empty slot.
pub const GRBLHAL_SEGMENTS_AHEAD: usize = 9;

/// LinuxCNC's trajectory period, s: `TRAJ_PERIOD`, which motmod takes equal to `SERVO_PERIOD`
/// unless given (1 ms in its sample configurations and in the one
/// `whirl dry-run --controller linuxcnc` writes, which gives only `SERVO_PERIOD`).
pub const LINUXCNC_TRAJ_PERIOD_S: f64 = 0.001;

/// The fewest trajectory periods a LinuxCNC segment lasts: its planner caps a segment's speed at
/// its length over `cycleTime · TP_MIN_SEGMENT_CYCLES` ("must be greater than 1 to ensure each
/// segment is hit at least once", `src/emc/tp/tp_types.h`, 2.9), so a shorter move runs slower
/// than programmed.
pub const LINUXCNC_MIN_SEGMENT_CYCLES: f64 = 1.02;

/// The PLC scan `machine-profiles/modbus-plc.toml` assumes, s: a PLC that takes one segment
/// from the ring a scan executes at most one a scan.
pub const PLC_SCAN_S: f64 = 0.010;

/// The controller families whose block rates differ.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Family {
    /// grbl/grblHAL: G-code over a serial line.
    Grbl,
    /// LinuxCNC.
    LinuxCnc,
    /// A PLC taking segments through the Modbus ring of `docs/modbus.md`.
    Modbus,
    /// CiA 402 drives over CANopen, one set-point a SYNC cycle.
    CanOpen {
        /// The SYNC cycle, µs.
        cycle_us: u32,
    },
}

/// The block rate a plan is held to, and where it comes from.
#[derive(Debug, Clone, PartialEq)]
pub struct BlockRate {
    /// Linked moves a second the controller sustains.
    pub per_second: f64,
    /// Blocks the controller prepares ahead of the one running, over which the rate is
    /// sustained; `None`: none, every move lasts at least 1 / `per_second`.
    pub ahead: Option<usize>,
    /// Where the figure comes from, for a message: the profile's key or the family default.
    pub source: String,
}

impl Family {
    /// The family's default block rate, and why.
    pub fn default_rate(self) -> BlockRate {
        let ahead = match self {
            Family::Grbl => Some(GRBLHAL_SEGMENTS_AHEAD),
            _ => None,
        };
        let (per_second, source) = match self {
            Family::Grbl => (
                GRBLHAL_TICKS_PER_SECOND,
                "grblHAL's default: one step segment tick (ACCELERATION_TICKS_PER_SECOND = 100) \
                 a block"
                    .to_owned(),
            ),
            Family::LinuxCnc => (
                1.0 / (LINUXCNC_TRAJ_PERIOD_S * LINUXCNC_MIN_SEGMENT_CYCLES),
                "LinuxCNC's default: a segment lasts at least 1.02 trajectory periods of 1 ms \
                 (TP_MIN_SEGMENT_CYCLES)"
                    .to_owned(),
            ),
            Family::Modbus => (
                1.0 / PLC_SCAN_S,
                "the Modbus PLC's default: one segment a 10 ms scan".to_owned(),
            ),
            Family::CanOpen { cycle_us } => (
                1e6 / f64::from(cycle_us),
                format!(
                    "the CANopen drives' cycle: one set-point a {cycle_us} µs SYNC cycle \
                     (connection.drives.cycle_us)"
                ),
            ),
        };
        BlockRate {
            per_second,
            ahead,
            source,
        }
    }
}

impl MachineProfile {
    /// The controller's family: a Modbus or CAN `[connection]` says it, else the dialect.
    pub fn family(&self) -> Family {
        match &self.connection {
            Some(Connection::ModbusTcp(_) | Connection::ModbusRtu(_)) => Family::Modbus,
            Some(c) if c.drives().is_some() => Family::CanOpen {
                cycle_us: c.drives().map_or(0, |d| d.cycle_us),
            },
            _ => match self.dialect {
                Dialect::GrblHal => Family::Grbl,
                Dialect::LinuxCnc => Family::LinuxCnc,
            },
        }
    }

    /// The block rate plans are held to: `max_block_rate` if the profile gives it, else the
    /// family's default.
    pub fn block_rate(&self) -> BlockRate {
        match self.max_block_rate {
            Some(per_second) => BlockRate {
                per_second,
                source: "the machine profile's max_block_rate".to_owned(),
                ..self.family().default_rate()
            },
            None => self.family().default_rate(),
        }
    }
}

/// `max_block_rate` checked: a finite number above zero, and on CAN drives no more than one
/// set-point a cycle (a move shorter than a cycle is stretched to one whatever the profile
/// says). As (key, problem).
pub(super) fn check(profile: &MachineProfile) -> Result<(), (String, String)> {
    let Some(rate) = profile.max_block_rate else {
        return Ok(());
    };
    let key = "max_block_rate".to_owned();
    if !(rate.is_finite() && rate > 0.0) {
        return Err((
            key,
            format!("{rate} must be a finite number of blocks a second above zero"),
        ));
    }
    if let Family::CanOpen { cycle_us } = profile.family() {
        let most = 1e6 / f64::from(cycle_us);
        if rate > most {
            return Err((
                key,
                format!(
                    "{rate} blocks/s is more than the drives take: one set-point a SYNC cycle, \
                     {most} a second at connection.drives.cycle_us = {cycle_us}"
                ),
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::testing::{machine, machine_text};

    #[test]
    fn each_profile_gets_its_familys_rate() {
        // One segment tick (10 ms), 1.02 trajectory periods of 1 ms, one PLC scan (10 ms), one
        // 4 ms SYNC cycle.
        for (file, family, rate) in [
            ("sim", Family::Grbl, 100.0),
            ("grblhal-lathe", Family::Grbl, 100.0),
            ("linuxcnc-lathe", Family::LinuxCnc, 1000.0 / 1.02),
            ("modbus-plc", Family::Modbus, 100.0),
            ("canopen-drives", Family::CanOpen { cycle_us: 4000 }, 250.0),
        ] {
            let p = machine(file);
            assert_eq!(p.family(), family, "{file}");
            let got = p.block_rate().per_second;
            assert!((got / rate - 1.0).abs() < 1e-12, "{file}: {got}");
        }
    }

    #[test]
    fn a_profiles_own_rate_wins() {
        let t = format!("max_block_rate = 40.0\n{}", machine_text("sim"));
        let p = MachineProfile::from_toml(&t, "sim.toml").unwrap();
        let rate = p.block_rate();
        assert_eq!(rate.per_second, 40.0);
        assert!(rate.source.contains("max_block_rate"), "{}", rate.source);
    }

    #[test]
    fn a_rate_of_zero_or_less_is_refused_naming_the_file_and_the_key() {
        for bad in ["0", "0.0", "-5.0", "nan", "inf"] {
            let t = format!("max_block_rate = {bad}\n{}", machine_text("grblhal-lathe"));
            let e = MachineProfile::from_toml(&t, "machine-profiles/grblhal-lathe.toml")
                .unwrap_err()
                .to_string();
            assert!(
                e.starts_with(
                    "machine profile machine-profiles/grblhal-lathe.toml: max_block_rate:"
                ),
                "{bad}: {e}"
            );
            assert!(e.contains("above zero"), "{bad}: {e}");
        }
    }

    #[test]
    fn can_drives_take_no_more_than_one_set_point_a_cycle() {
        // 4 ms cycles: 250 a second at most.
        let t = format!("max_block_rate = 251.0\n{}", machine_text("canopen-drives"));
        let e = MachineProfile::from_toml(&t, "canopen-drives.toml")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("max_block_rate") && e.contains("250 a second") && e.contains("cycle_us"),
            "{e}"
        );
        let t = format!("max_block_rate = 250.0\n{}", machine_text("canopen-drives"));
        assert!(MachineProfile::from_toml(&t, "canopen-drives.toml").is_ok());
    }
}
