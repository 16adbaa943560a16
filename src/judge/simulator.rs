//! The simulated controller (crate `whirl-sim`) as whirl embeds it: its machine description
//! from a whirl machine profile, its Δ guard ([`super::guard`]) from a job, and the simulated
//! drives' cycles merged into moves for the log ([`super::cycles`]).

use crate::config::machine::{MachineProfile, NumberType};
use whirl_sim::machine::{Axis, Machine, Number};

/// The simulator's view of a machine profile: travel, rates and accelerations per axis,
/// the controller's number type, its line length and the ring spindle's range.
pub fn machine(p: &MachineProfile) -> Machine {
    let linear = |a: &crate::config::machine::LinearAxis| Axis {
        min: Some(a.min),
        max: Some(a.max),
        max_rate: a.max_rate,
        accel: a.accel,
    };
    Machine {
        x: linear(&p.axes.x),
        z: linear(&p.axes.z),
        c: Axis {
            min: p.axes.c.min,
            max: p.axes.c.max,
            max_rate: p.axes.c.max_rate,
            accel: p.axes.c.accel,
        },
        number: match p.number {
            NumberType::F32 => Number::F32,
            NumberType::F64 => Number::F64,
        },
        max_line_length: p.max_line_length,
        spindle_rpm: p.spindle.as_ref().map(|s| (s.min_rpm, s.max_rpm)),
    }
}
