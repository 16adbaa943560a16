//! The feed scallop of the whirling ring: what two neighbouring passes over the same groove
//! leave between them, measured by sweeping the ring rather than estimated by a formula.

use crate::geometry::linkage::{Linkage, Pose};
use crate::geometry::minimise::{golden, scan_then_golden};
use crate::plan::table::Table;
use glam::DVec3;
use std::f64::consts::TAU;

/// Screw offset τ = Z/p between two passes of the ring over the same groove, for an axial
/// feed `feed` per workpiece revolution. Along the path ψ = C + Z/p and Z = Z₀ + f·C/2π, so
/// τ advances by f / (2πp + f) per radian of ψ, and the same groove comes back every 2π of ψ.
pub fn pass_spacing(p: f64, feed: f64) -> f64 {
    TAU * feed / (TAU * p + feed)
}

/// The feed scallop, measured rather than estimated: for profile points spread over the
/// period, the undercut left midway between two neighbouring passes of the ring over its
/// groove, each pass being the planned family of poses (X from the table) screwed along.
///
/// By screw invariance every pose of the path is the canonical pose (ψ, X(ψ), 0) screwed by
/// τ = Z/p. The point P(u) is touched at τ_u = Z_u/p; the passes before and after it are
/// the same family screwed by τ_u ∓ Δτ. Where the two meet, between them, the point is left
/// proudest: that height is the scallop.
pub fn ring(table: &Table, linkage: &Linkage, feed: f64) -> f64 {
    let p = linkage.p;
    let spacing = pass_spacing(p, feed);
    let drift = spacing / TAU; // dτ/dψ within a pass
    let picks = 64.min(table.samples.len());
    (0..picks)
        .map(|k| &table.samples[k * (table.samples.len() - 1) / picks])
        .map(|s| {
            let q = DVec3::new(s.pos.x, s.pos.y, 0.0);
            let (psi_u, tau_u) = (s.contact.phase, s.contact.pose.z / p);
            // Closest approach of one pass, screwed by τ from the touching one.
            let pass = |tau: f64| {
                let gap = |psi: f64| {
                    let t = tau_u + tau + drift * (psi - psi_u);
                    let pose = Pose {
                        x: table.x_at(psi),
                        c: psi - t,
                        z: p * t,
                    };
                    linkage.gap(q, &pose)
                };
                scan_then_golden(gap, psi_u - 0.2, psi_u + 0.2, 24, 40)
            };
            let between = |tau: f64| pass(tau).min(pass(tau - spacing));
            -golden(|t| -between(t), spacing.min(0.0), spacing.max(0.0), 32).1
        })
        .fold(0.0, f64::max)
}
