//! The path: one period's nodes → the machine moves of the whole groove.
//!
//! The workpiece turns at a constant rate (C), the unit feeds along the groove by `f` per
//! workpiece revolution (Z = Z_s + f·C / 2π) and X follows the nodes: each node ψ_k of the
//! period pattern, repeated every period, becomes the pose with C = (ψ − Z_s/p) / (1 + f/2πp)
//! (from ψ = C + Z/p with C starting at 0) and X = X(ψ_k). Consecutive nodes are one linked
//! G1 move in inverse time, so C (and Z) keep the rate the job sets whatever X does.
//!
//! Lead-in: X to its clear position at rapid (it only moves the ring away from the work, see
//! [`PathSpec::x_clear`]), Z and C to the first node at rapid, the ring spindle on, X in at the
//! plunge feed. Lead-out: X back to clear at rapid, the spindle off.

use crate::gcode::program::{Block, Program};
use crate::segment::Nodes;
use std::f64::consts::TAU;

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
    /// On controllers with 32-bit coordinates: rebase C (G92) before |C| passes this, degrees.
    pub c_limit_deg: Option<f64>,
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

/// Build the program for the groove from the nodes of one period.
pub fn build(nodes: &Nodes, spec: &PathSpec, title: &str) -> Path {
    let PathSpec { p, feed, .. } = *spec;
    let rate = 1.0 + feed / (TAU * p); // dψ/dC
    let c_of = |psi: f64| (psi - spec.z_from / p) / rate;
    let z_of = |c: f64| spec.z_from + feed * c / TAU;
    let pattern = &nodes.nodes[..nodes.nodes.len() - 1];
    let base = pattern[0].contact.phase;
    // The first node at or after ψ(C = 0), the last before Z passes z_to.
    let psi_start = spec.z_from / p;
    let mut period_index = ((psi_start - base) / spec.period).floor() as i64;
    let mut k = 0;
    let mut poses = Vec::new();
    loop {
        let psi = pattern[k].contact.phase + period_index as f64 * spec.period;
        if psi >= psi_start {
            let c = c_of(psi);
            let z = z_of(c);
            if z > spec.z_to {
                break;
            }
            poses.push((pattern[k].contact.pose.x, z, c.to_degrees()));
        }
        k += 1;
        if k == pattern.len() {
            k = 0;
            period_index += 1;
        }
    }
    let mut blocks = vec![Block::Comment(title.to_owned())];
    let (x0, z0, c0) = poses[0];
    blocks.push(Block::Rapid {
        x: Some(spec.x_clear),
        z: None,
        c: None,
    });
    blocks.push(Block::Rapid {
        x: None,
        z: Some(z0),
        c: Some(c0),
    });
    blocks.push(Block::SpindleOn { rpm: spec.ring_rpm });
    blocks.push(Block::Feed {
        x: Some(x0),
        z: None,
        c: None,
        feed: spec.plunge_feed,
    });
    let deg_per_min = 360.0 * spec.workpiece_rpm;
    let mut offset = 0.0; // degrees of C renamed away by G92
    let mut prev_c = c0;
    for &(x, z, c) in &poses[1..] {
        blocks.push(Block::Linked {
            x,
            z,
            c: c - offset,
            minutes: (c - prev_c) / deg_per_min,
        });
        prev_c = c;
        if let Some(limit) = spec.c_limit_deg {
            // One more turn must still fit below the limit.
            if (c - offset).abs() > limit - 360.0 {
                let turns = ((c - offset) / 360.0).floor();
                offset += 360.0 * turns;
                blocks.push(Block::RebaseC { c: c - offset });
            }
        }
    }
    blocks.push(Block::Rapid {
        x: Some(spec.x_clear),
        z: None,
        c: None,
    });
    blocks.push(Block::SpindleOff);
    let revolutions = (prev_c - c0) / 360.0;
    Path {
        program: Program { blocks },
        segments: poses.len() - 1,
        revolutions,
    }
}
