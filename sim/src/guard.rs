//! The Δ guard's seat in the controller: something that watches every executed block and
//! can stop the machine.
//!
//! Measuring a groove needs the swept-volume engine, which belongs to whirl; this crate
//! depends on nothing of whirl's, so the controller takes the measurement as a [`Guard`]
//! and only decides what a breach does: the motion stops at once, the queue and the line
//! being executed are dropped, and `ALARM:64` is raised with the guard's message (a
//! critical alarm, as a hard limit is: only a soft reset clears it).

use crate::record::ExecutedBlock;
use serde::{Deserialize, Serialize};
use std::fmt;

/// A watch on the executed motion; see the module docs.
pub trait Guard: fmt::Debug + Send {
    /// A block has finished executing (or was cut short). `Err` stops the machine.
    fn executed(&mut self, block: &ExecutedBlock) -> Result<(), Breach>;

    /// The program ended (M2/M30, with the queue empty): whatever was waiting for later
    /// motion is settled now. `Err` stops the machine before the line is answered.
    fn program_end(&mut self) -> Result<(), Breach>;

    /// What has been measured so far.
    fn measured(&self) -> Measured;
}

/// The guard's verdict on the motion: what was exceeded, where and by how much.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, thiserror::Error)]
#[error("{message}")]
pub struct Breach {
    /// One line for `[MSG:…]` and the logs.
    pub message: String,
}

/// The profile error measured so far.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Measured {
    /// Target points whose error is final.
    pub points: usize,
    /// Largest overcut, mm (≥ 0).
    pub max_overcut_mm: f64,
    /// Largest undercut, mm (≥ 0).
    pub max_undercut_mm: f64,
    /// The allowable error Δ, mm.
    pub delta_mm: f64,
}

impl Measured {
    /// The larger of overcut and undercut, mm.
    pub fn max_error_mm(&self) -> f64 {
        self.max_overcut_mm.max(self.max_undercut_mm)
    }
}
