//! The path: one period's nodes → the machine moves of the whole groove.
//!
//! The workpiece turns at a constant rate (C), the unit feeds along the groove by `f` per
//! workpiece revolution (Z = Z_s + f·C / 2π) and X follows the nodes: each node ψ_k of the
//! period pattern, repeated every period, becomes the pose with C = (ψ − Z_s/p) / (1 + f/2πp)
//! (from ψ = C + Z/p with C starting at 0) and X = X(ψ_k). Consecutive nodes are one linked
//! G1 move in inverse time, so C (and Z) keep the rate the job sets whatever X does.
//!
//! Lead-in: X to its clear position at rapid (it only moves the ring away from the work, see
//! [`PathSpec::x_clear`]), C to the first node at rapid, then Z, the ring spindle on, X in at
//! the plunge feed. Lead-out: X back to clear at rapid, the spindle off. C and Z are
//! positioned one after the other, never together: a controller that does not know a rapid
//! from a feed (CiA 402 drives take bare set-points) would otherwise see the workpiece turn
//! while Z goes the wrong way, which is what a helical cut looks like, and the simulator's
//! Δ guard would judge it as one.
//!
//! C is written as it is, however many turns it reaches: grbl-family controllers compute
//! every target as a 32-bit *machine* position, so renaming C with G92 would win no
//! precision back, and grbl stops all motion for every G92 (a dwell mark on the groove).
//! The planner counts C's resolution at its largest value in the error budget instead.

use crate::program::{Move, Program};
use std::f64::consts::TAU;

/// One node of the period's pattern: a phase and the ring-centre X the program gives it there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Node {
    /// ψ, rad.
    pub phase: f64,
    /// X, mm: the table's X(ψ), or off it by what the node choice chose
    /// ([`crate::plan::segment`]).
    pub x: f64,
}

/// What the path needs besides the nodes.
#[derive(Debug, Clone, Copy)]
pub struct PathSpec {
    /// Lead parameter p, mm/rad.
    pub p: f64,
    /// Polar period 2π / starts.
    pub period: f64,
    /// Axial feed per workpiece revolution, mm.
    pub feed: f64,
    /// Workpiece speed, rpm.
    pub workpiece_rpm: f64,
    /// Ring speed, rpm.
    pub ring_rpm: f64,
    /// Feed of the plunge, mm/min.
    pub plunge_feed: f64,
    /// Ring-centre Z where the linked motion starts and ends, mm.
    pub z_from: f64,
    /// See `z_from`.
    pub z_to: f64,
    /// X at which the ring is clear of the work all round: moving X there from a cutting pose
    /// only moves the cutting side of the ring away from the axis.
    pub x_clear: f64,
}

/// The moves of the whole groove, and how many linked segments they hold.
#[derive(Debug, Clone)]
pub struct Path {
    /// The program.
    pub program: Program,
    /// Linked (cutting) segments.
    pub segments: usize,
    /// Workpiece revolutions of the linked motion.
    pub revolutions: f64,
}

/// Build the program for the groove from the nodes of one period, ψ increasing, the last the
/// first one period on.
pub fn build(nodes: &[Node], spec: &PathSpec, title: &str) -> Path {
    let PathSpec { p, feed, .. } = *spec;
    let rate = 1.0 + feed / (TAU * p); // dψ/dC
    let c_of = |psi: f64| (psi - spec.z_from / p) / rate;
    let z_of = |c: f64| spec.z_from + feed * c / TAU;
    let pattern = &nodes[..nodes.len() - 1];
    let base = pattern[0].phase;
    // The first node at or after ψ(C = 0), the last before Z passes z_to.
    let psi_start = spec.z_from / p;
    let mut period_index = ((psi_start - base) / spec.period).floor() as i64;
    let mut k = 0;
    let mut poses = Vec::new();
    loop {
        let psi = pattern[k].phase + period_index as f64 * spec.period;
        if psi >= psi_start {
            let c = c_of(psi);
            let z = z_of(c);
            if z > spec.z_to {
                break;
            }
            poses.push((pattern[k].x, z, c.to_degrees()));
        }
        k += 1;
        if k == pattern.len() {
            k = 0;
            period_index += 1;
        }
    }
    let mut moves = vec![Move::Comment(title.to_owned())];
    let (x0, z0, c0) = poses[0];
    moves.push(Move::Rapid {
        x: Some(spec.x_clear),
        z: None,
        c: None,
    });
    moves.push(Move::Rapid {
        x: None,
        z: None,
        c: Some(c0),
    });
    moves.push(Move::Rapid {
        x: None,
        z: Some(z0),
        c: None,
    });
    moves.push(Move::SpindleOn { rpm: spec.ring_rpm });
    moves.push(Move::Feed {
        x: Some(x0),
        z: None,
        c: None,
        feed: spec.plunge_feed,
    });
    let deg_per_min = 360.0 * spec.workpiece_rpm;
    let mut prev_c = c0;
    for &(x, z, c) in &poses[1..] {
        moves.push(Move::Linked {
            x,
            z,
            c,
            minutes: (c - prev_c) / deg_per_min,
        });
        prev_c = c;
    }
    moves.push(Move::Rapid {
        x: Some(spec.x_clear),
        z: None,
        c: None,
    });
    moves.push(Move::SpindleOff);
    let revolutions = (prev_c - c0) / 360.0;
    Path {
        program: Program { moves },
        segments: poses.len() - 1,
        revolutions,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::program::Position;
    use std::f64::consts::PI;

    /// One start, four nodes a quarter period apart with X rocking between 10 and 11 mm.
    fn nodes() -> Vec<Node> {
        (0..=4)
            .map(|k| Node {
                phase: k as f64 * PI / 2.0,
                x: 10.0 + (k % 2) as f64,
            })
            .collect()
    }

    /// A 2 mm lead, 20 mm of groove: 10 workpiece turns, 3600° of C.
    fn spec() -> PathSpec {
        PathSpec {
            p: 2.0 / TAU,
            period: TAU,
            feed: 2.0,
            workpiece_rpm: 10.0,
            ring_rpm: 3000.0,
            plunge_feed: 100.0,
            z_from: 0.0,
            z_to: 20.0,
            x_clear: 30.0,
        }
    }

    #[test]
    fn c_turns_on_unrenamed_to_the_end_and_the_ring_retracts_before_it_stops() {
        let path = build(&nodes(), &spec(), "plain");
        let moves = &path.program.moves;
        let n = moves.len();
        assert_eq!(moves[n - 1], Move::SpindleOff);
        assert_eq!(
            moves[n - 2],
            Move::Rapid {
                x: Some(30.0),
                z: None,
                c: None
            }
        );
        // 10 turns: C rises steadily to 3600°, written as it is.
        let steps: Vec<_> = path.program.steps(Position::UNKNOWN).collect();
        let end = steps[n - 1].to.c.unwrap();
        assert!((end - 3600.0).abs() < 1e-9, "{end}");
        let c_rises = steps.windows(2).all(|w| match (w[0].to.c, w[1].to.c) {
            (Some(a), Some(b)) => b >= a,
            _ => true,
        });
        assert!(c_rises);
        assert!((path.revolutions - 10.0).abs() < 1e-9);
    }
}
