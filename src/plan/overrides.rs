//! The feed override a planned program may run at: slowing down only refines the insert
//! cusp, speeding up coarsens it, so the largest override offered is the one that keeps the
//! cusp within its share of Δ, and the controller's range caps it too.
//!
//! A feed override scales the programmed feeds: the C turn and the Z feed of the linked
//! moves (inverse time, so both together) and the plunge. The ring is a spindle and keeps
//! its speed. So at an override k the workpiece turns k times as far between the hits of
//! two successive inserts, 2π·k·n_w / (z·n_t), and the cusp those hits leave,
//! s²/8 · (1/ρ ∓ 1/R) with s = ρ·turn ([`crate::plan::budget::cusp_at`]), grows with k².
//! The feed per workpiece revolution is the program's, whatever the rate, so the feed
//! scallop does not change, nor do blending (none on the controllers that take an override
//! from whirl) or the rounding of the numbers.
//!
//! The cusp's share of Δ at an override is what the plan gave it plus what the plan leaves
//! unspent: Δ less the error the program is held to (`max_error_mm`, which counts the cusp
//! where it is). Adding the whole growth of the cusp, (k² − 1) times its largest, to that
//! bound assumes it peaks where everything else does, which it need not: the cap errs on
//! the safe side.

use crate::config::job::show_figure;
use crate::plan::Report;
use serde::Serialize;

/// The range of feed overrides a controller takes, percent.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct OverrideRange {
    /// The slowest, percent.
    pub min: u16,
    /// The fastest, percent.
    pub max: u16,
    /// Who sets this range, for the messages ("grblHAL's", "the Modbus map's").
    pub whose: &'static str,
}

/// grbl's and grblHAL's feed override range (`config.h`: `MIN_FEED_RATE_OVERRIDE` 10,
/// `MAX_FEED_RATE_OVERRIDE` 200), reached in steps of 10 and 1 (0x91–0x94).
pub const GRBL: OverrideRange = OverrideRange {
    min: 10,
    max: 200,
    whose: "grbl's",
};

/// The `FEED_OVERRIDE` register of the Modbus map (docs/modbus.md): the same range as grbl,
/// so that the keys and the console do the same on every controller.
pub const MODBUS: OverrideRange = OverrideRange {
    min: 10,
    max: 200,
    whose: "the Modbus map's",
};

/// The bridge's own interpolation of CiA 402 set-points (docs/canopen.md): the same range.
pub const CANOPEN: OverrideRange = OverrideRange {
    min: 10,
    max: 200,
    whose: "the CANopen bridge's",
};

/// The overrides a planned program may run at, and why the fastest is where it is.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FeedCap {
    /// The slowest override the controller takes, percent.
    pub min_percent: u16,
    /// Whose range that is.
    pub whose: &'static str,
    /// The fastest override offered, percent: the least of the cusp's and the controller's
    /// limits, never below 100 (the plan itself).
    pub max_percent: u16,
    /// The override at which the cusp reaches its share exactly (may be fractional, and
    /// beyond the controller's range); infinite when the cusp is nil.
    pub cusp_limit_percent: f64,
    /// The insert cusp as planned, at 100 %, mm.
    pub cusp_mm: f64,
    /// The cusp's share of Δ at an override: the planned cusp and what the plan leaves
    /// unspent, mm.
    pub cusp_share_mm: f64,
    /// Δ, mm.
    pub delta_mm: f64,
    /// Why the fastest override is where it is, in words.
    pub reason: String,
}

/// Why an override was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum OverrideError {
    /// Faster than the cap.
    #[error("a feed override of {asked} % is above the cap of {max} %: {reason}")]
    AboveCap {
        /// What was asked, percent.
        asked: u16,
        /// The cap, percent.
        max: u16,
        /// Why the cap is there.
        reason: String,
    },
    /// Slower than the controller takes.
    #[error("a feed override of {asked} % is below {min} %, the slowest {whose} range takes")]
    BelowRange {
        /// What was asked, percent.
        asked: u16,
        /// The slowest, percent.
        min: u16,
        /// Whose range.
        whose: &'static str,
    },
}

impl FeedCap {
    /// The cap of a program planned as `report` says, on a controller taking `range`.
    pub fn of(report: &Report, range: OverrideRange) -> FeedCap {
        FeedCap::new(report.delta_mm, report.max_error_mm, report.cusp_mm, range)
    }

    /// The cap for Δ = `delta`, a program held to `max_error` with an insert cusp of `cusp`
    /// in it (mm), on a controller taking `range`.
    pub fn new(delta: f64, max_error: f64, cusp: f64, range: OverrideRange) -> FeedCap {
        let unspent = (delta - max_error).max(0.0);
        let share = cusp + unspent;
        // cusp·k² = share.
        let cusp_limit_percent = if cusp > 0.0 {
            100.0 * (share / cusp).sqrt()
        } else {
            f64::INFINITY
        };
        // Whole percent (grbl steps by 1); the tolerance keeps an exact 100 % at 100.
        let by_cusp = (cusp_limit_percent + 1e-9).floor().min(f64::from(u16::MAX));
        let max_percent = (by_cusp as u16).min(range.max).max(100);
        let reason = if f64::from(range.max) <= by_cusp {
            if cusp > 0.0 {
                format!(
                    "{} % is the fastest {} range takes; the insert cusp would stay within \
                     its share of Δ = {} mm up to {:.0} %",
                    range.max,
                    range.whose,
                    show_figure(delta),
                    cusp_limit_percent.floor(),
                )
            } else {
                format!(
                    "{} % is the fastest {} range takes; the insert cusp is nil on this \
                     profile, so the feed does not coarsen it",
                    range.max, range.whose,
                )
            }
        } else if max_percent == 100 {
            format!(
                "the plan already spends Δ = {} mm (held to {} mm): 101 % would coarsen the \
                 insert cusp past its share",
                show_figure(delta),
                show_figure(max_error),
            )
        } else {
            format!(
                "at {max_percent} % the insert cusp reaches {} mm of its share of {} mm (the \
                 planned {} mm and the {} mm of Δ = {} mm the plan leaves unspent): the \
                 workpiece turns further between insert hits while the ring keeps its speed, \
                 and the cusp grows with the square of the feed",
                show_figure(cusp * (f64::from(max_percent) / 100.0).powi(2)),
                show_figure(share),
                show_figure(cusp),
                show_figure(unspent),
                show_figure(delta),
            )
        };
        FeedCap {
            min_percent: range.min,
            whose: range.whose,
            max_percent,
            cusp_limit_percent,
            cusp_mm: cusp,
            cusp_share_mm: share,
            delta_mm: delta,
            reason,
        }
    }

    /// The insert cusp at `percent`, mm: the planned one times (percent/100)².
    pub fn cusp_at(&self, percent: u16) -> f64 {
        self.cusp_mm * (f64::from(percent) / 100.0).powi(2)
    }

    /// `percent` if the cap and the controller allow it.
    pub fn check(&self, percent: u16) -> Result<u16, OverrideError> {
        if percent > self.max_percent {
            return Err(OverrideError::AboveCap {
                asked: percent,
                max: self.max_percent,
                reason: self.reason.clone(),
            });
        }
        if percent < self.min_percent {
            return Err(OverrideError::BelowRange {
                asked: percent,
                min: self.min_percent,
                whose: self.whose,
            });
        }
        Ok(percent)
    }

    /// `percent` brought within the range offered, and why if it had to be (a key pressed
    /// once too often).
    pub fn clamp(&self, percent: i32) -> (u16, Option<String>) {
        let max = i32::from(self.max_percent);
        let min = i32::from(self.min_percent);
        if percent > max {
            (
                self.max_percent,
                Some(format!(
                    "feed override held at {} %: {}",
                    self.max_percent, self.reason
                )),
            )
        } else if percent < min {
            (
                self.min_percent,
                Some(format!(
                    "feed override held at {} %, the slowest {} range takes",
                    self.min_percent, self.whose
                )),
            )
        } else {
            // Within min..=max, both u16.
            (percent as u16, None)
        }
    }
}

#[cfg(test)]
mod tests;
