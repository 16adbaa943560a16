//! The simulated drives' control cycles merged back into the straight moves they make up,
//! for the executed-path log.
//!
//! The CAN drives record one executed block per SYNC: a ball screw's 17 000 s at 4 ms is
//! four million of them, a gigabyte of log. But the set-points of one planned move are
//! equal steps along it (up to a count of rounding each), so consecutive cycles that step
//! alike are one straight move at one speed, and the log can say so in one entry without
//! losing anything a replay needs: the merged move passes within a count of every cycle's
//! end. A cycle that steps differently (the next planned move, a stop) starts a new one.
//!
//! The Δ guard judges the same stretches ([`MergedGuard`]): measuring each point against
//! every 4 ms cycle costs it fourteen times the work of the planned moves for nothing, as
//! a stretch is the cycles' path to within a count (0.1 µm of X or Z on the example CAN
//! drives, 0.00034° of C: far below any Δ).

use whirl_sim::{Breach, ExecutedBlock, Guard, Measured, MoveKind};

/// A straight move made of cycles.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stretch {
    /// Start and end time, s.
    pub times: [f64; 2],
    /// X, Z (mm), C (degrees) at the start.
    pub from: [f64; 3],
    /// At the end.
    pub to: [f64; 3],
    /// Cycles merged.
    pub cycles: usize,
    /// The first cycle's line (the drives' SYNC ordinal).
    pub line: u64,
}

impl Stretch {
    /// The stretch as one executed straight move, for a guard.
    pub fn block(&self) -> ExecutedBlock {
        let [t0, t1] = self.times;
        let distance = (0..3)
            .map(|k| (self.to[k] - self.from[k]).powi(2))
            .sum::<f64>()
            .sqrt();
        ExecutedBlock {
            line: self.line,
            n: None,
            kind: MoveKind::InverseTime,
            from: whirl_sim::Position::from_array(self.from),
            target: whirl_sim::Position::from_array(self.to),
            to: whirl_sim::Position::from_array(self.to),
            start_time: t0,
            end_time: t1,
            completed: true,
            phases: vec![whirl_sim::Phase {
                start: t0,
                distance: 0.0,
                speed: if t1 > t0 { distance / (t1 - t0) } else { 0.0 },
                accel: 0.0,
            }],
        }
    }
}

/// Merges consecutive cycles that step alike; see the module docs.
#[derive(Debug)]
pub struct Merger {
    /// How far a cycle's step may differ from the stretch's mean step, per axis: a count
    /// (and a hair for the floating point of the units).
    tolerance: [f64; 3],
    open: Option<Stretch>,
}

impl Merger {
    /// A merger for drives with `counts_per_unit` (X, Z per mm, C per degree).
    pub fn new(counts_per_unit: [f64; 3]) -> Merger {
        Merger {
            tolerance: counts_per_unit.map(|c| 1.000_001 / c),
            open: None,
        }
    }

    /// Takes the next cycle; returns the stretch it ended, if it does not continue it.
    pub fn push(&mut self, block: &ExecutedBlock) -> Option<Stretch> {
        let (from, to) = (block.from.to_array(), block.to.to_array());
        let cycle = Stretch {
            times: [block.start_time, block.end_time],
            from,
            to,
            cycles: 1,
            line: block.line,
        };
        let Some(open) = self.open.as_mut() else {
            self.open = Some(cycle);
            return None;
        };
        let n = open.cycles as f64;
        let continues = open.to == from
            && (0..3).all(|k| {
                let mean = (open.to[k] - open.from[k]) / n;
                ((to[k] - from[k]) - mean).abs() <= self.tolerance[k]
            });
        if continues {
            open.to = to;
            open.times[1] = block.end_time;
            open.cycles += 1;
            None
        } else {
            self.open.replace(cycle)
        }
    }

    /// The stretch still open, at the end.
    pub fn finish(&mut self) -> Option<Stretch> {
        self.open.take()
    }
}

/// A guard shown the drives' cycles merged into stretches (see the module docs): each
/// stretch once the cycle after it has begun another, the last at the program's end.
#[derive(Debug)]
pub struct MergedGuard<G> {
    inner: G,
    merger: Merger,
}

impl<G: Guard> MergedGuard<G> {
    /// `inner`, for drives with `counts_per_unit`.
    pub fn new(inner: G, counts_per_unit: [f64; 3]) -> MergedGuard<G> {
        MergedGuard {
            inner,
            merger: Merger::new(counts_per_unit),
        }
    }
}

impl<G: Guard> Guard for MergedGuard<G> {
    fn executed(&mut self, block: &ExecutedBlock) -> Result<(), Breach> {
        match self.merger.push(block) {
            Some(stretch) => self.inner.executed(&stretch.block()),
            None => Ok(()),
        }
    }

    fn program_end(&mut self) -> Result<(), Breach> {
        if let Some(stretch) = self.merger.finish() {
            self.inner.executed(&stretch.block())?;
        }
        self.inner.program_end()
    }

    fn measured(&self) -> Measured {
        self.inner.measured()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use whirl_sim::{MoveKind, Position};

    /// A cycle of 4 ms from `from` to `to`, starting at cycle `k`.
    fn cycle(k: usize, from: [f64; 3], to: [f64; 3]) -> ExecutedBlock {
        ExecutedBlock {
            line: k as u64 + 1,
            n: None,
            kind: MoveKind::InverseTime,
            from: Position::from_array(from),
            target: Position::from_array(to),
            to: Position::from_array(to),
            start_time: k as f64 * 0.004,
            end_time: (k + 1) as f64 * 0.004,
            completed: true,
            phases: Vec::new(),
        }
    }

    /// Cycles through `points`, from the first.
    fn cycles(points: &[[f64; 3]]) -> Vec<ExecutedBlock> {
        points
            .windows(2)
            .enumerate()
            .map(|(k, w)| cycle(k, w[0], w[1]))
            .collect()
    }

    fn merge(blocks: &[ExecutedBlock], scale: [f64; 3]) -> Vec<Stretch> {
        let mut merger = Merger::new(scale);
        let mut out: Vec<Stretch> = blocks.iter().filter_map(|b| merger.push(b)).collect();
        out.extend(merger.finish());
        out
    }

    const SCALE: [f64; 3] = [10_000.0, 10_000.0, 1_000.0];

    #[test]
    fn equal_steps_with_a_count_of_rounding_are_one_move_and_a_turn_starts_another() {
        // 10 cycles along X by 0.0333 mm rounded to counts (333 or 334), then 5 along Z.
        let mut points = vec![[0.0, 0.0, 0.0]];
        for k in 1..=10 {
            let counts = (k as f64 * 333.3_f64).round();
            points.push([counts / SCALE[0], 0.0, 0.0]);
        }
        let corner = *points.last().unwrap();
        for k in 1..=5 {
            points.push([corner[0], -(k as f64) * 0.01, 0.0]);
        }
        let stretches = merge(&cycles(&points), SCALE);
        assert_eq!(stretches.len(), 2);
        assert_eq!(stretches[0].cycles, 10);
        assert_eq!(stretches[0].from, [0.0; 3]);
        assert_eq!(stretches[0].to, corner);
        assert_eq!(stretches[1].from, corner);
        assert_eq!(stretches[1].cycles, 5);
        assert!((stretches[1].times[0] - 0.04).abs() < 1e-12);
        assert!((stretches[1].times[1] - 0.06).abs() < 1e-12);
    }

    /// A guard that records what it is shown.
    #[derive(Debug, Default)]
    struct Recorder(Vec<ExecutedBlock>, bool);

    impl Guard for Recorder {
        fn executed(&mut self, block: &ExecutedBlock) -> Result<(), Breach> {
            self.0.push(block.clone());
            Ok(())
        }
        fn program_end(&mut self) -> Result<(), Breach> {
            self.1 = true;
            Ok(())
        }
        fn measured(&self) -> Measured {
            Measured::default()
        }
    }

    #[test]
    fn a_merged_guard_sees_each_stretch_once_and_the_last_at_the_end() {
        let blocks = cycles(&[
            [0.0; 3],
            [0.1, 0.0, 0.0],
            [0.2, 0.0, 0.0],
            [0.2, 0.1, 0.0],
            [0.2, 0.2, 0.0],
        ]);
        let mut guard = MergedGuard::new(Recorder::default(), SCALE);
        for block in &blocks {
            guard.executed(block).unwrap();
        }
        // The X stretch ended when the first Z cycle came; the Z stretch is still open.
        assert_eq!(guard.inner.0.len(), 1);
        guard.program_end().unwrap();
        let shown = &guard.inner.0;
        assert!(guard.inner.1);
        assert_eq!(shown.len(), 2);
        assert_eq!(shown[0].from.to_array(), [0.0; 3]);
        assert_eq!(shown[0].to.to_array(), [0.2, 0.0, 0.0]);
        assert_eq!(shown[1].from.to_array(), [0.2, 0.0, 0.0]);
        assert_eq!(shown[1].to.to_array(), [0.2, 0.2, 0.0]);
        assert_eq!((shown[1].line, shown[1].start_time), (3, 0.008));
        // 0.2 mm in 8 ms.
        assert!((shown[1].phases[0].speed - 25.0).abs() < 1e-9);
    }

    #[test]
    fn a_change_of_speed_or_a_gap_or_a_hold_is_a_new_move() {
        // Two cycles of 0.1 mm, two of 0.2 mm along the same line.
        let speed = cycles(&[[0.0; 3], [0.1, 0.0, 0.0], [0.2, 0.0, 0.0], [0.4, 0.0, 0.0]]);
        assert_eq!(merge(&speed, SCALE).len(), 2);
        // A cycle that does not start where the last ended.
        let gap = [
            cycle(0, [0.0; 3], [0.1, 0.0, 0.0]),
            cycle(1, [0.2, 0.0, 0.0], [0.3, 0.0, 0.0]),
        ];
        assert_eq!(merge(&gap, SCALE).len(), 2);
        // Standing still for three cycles after a move: the hold is one entry of its own.
        let hold = cycles(&[[0.0; 3], [0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [0.0, 0.0, 1.0]]);
        let stretches = merge(&hold, SCALE);
        assert_eq!(stretches.len(), 2);
        assert_eq!(stretches[1].cycles, 2);
        assert_eq!(stretches[1].from, stretches[1].to);
    }
}
