//! The feed scallop of the whirling ring: what two neighbouring passes over the same groove
//! leave between them, measured by sweeping the ring rather than estimated by a formula.

use crate::linkage::{Linkage, Pose};
use crate::table::Table;
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
                minimise(gap, psi_u - 0.2, psi_u + 0.2, 24, 40)
            };
            let between = |tau: f64| pass(tau).min(pass(tau - spacing));
            -minimise(|t| -between(t), spacing.min(0.0), spacing.max(0.0), 0, 32)
        })
        .fold(0.0, f64::max)
}

/// Minimum of `f` over `[a, b]`: a scan of `scan` steps (0: none) to find the basin, then
/// `steps` golden-section steps in it (each shrinks the bracket by 0.618).
fn minimise(f: impl Fn(f64) -> f64, a: f64, b: f64, scan: usize, steps: usize) -> f64 {
    let (mut lo, mut hi) = (a, b);
    if scan > 0 {
        let step = (b - a) / scan as f64;
        let best = (0..=scan)
            .map(|k| a + step * k as f64)
            .map(|x| (x, f(x)))
            .min_by(|x, y| x.1.total_cmp(&y.1))
            .map_or(a, |(x, _)| x);
        lo = (best - step).max(a);
        hi = (best + step).min(b);
    }
    let g = (5f64.sqrt() - 1.0) / 2.0;
    let (mut x1, mut x2) = (hi - g * (hi - lo), lo + g * (hi - lo));
    let (mut f1, mut f2) = (f(x1), f(x2));
    for _ in 0..steps {
        if f1 < f2 {
            hi = x2;
            (x2, f2) = (x1, f1);
            x1 = hi - g * (hi - lo);
            f1 = f(x1);
        } else {
            lo = x1;
            (x1, f1) = (x2, f2);
            x2 = lo + g * (hi - lo);
            f2 = f(x2);
        }
    }
    f1.min(f2)
}
