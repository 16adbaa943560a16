//! The error budget of kinematics.md: how Δ is shared between interpolation, the feed scallop,
//! the insert cusp, controller blending and number rounding.
//!
//! The scallop and the cusp follow from the cut (feed, speeds) and the tool; blending and
//! rounding from the machine; interpolation gets what is left, and node choice works to it.

use crate::linkage::{Linkage, Pose, Whirling};
use crate::table::Table;
use glam::DVec3;
use serde::Serialize;
use std::f64::consts::TAU;

/// How Δ is spent, mm.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Budget {
    /// The allowable profile error Δ.
    pub delta: f64,
    /// Undercut left between neighbouring passes of the same groove.
    pub scallop: f64,
    /// Undercut left between the hits of successive inserts.
    pub cusp: f64,
    /// The controller's path blending (LinuxCNC G64 P), 0 for exact-path controllers.
    pub blend: f64,
    /// Rounding of the written numbers and of the controller's number type.
    pub rounding: f64,
    /// What is left for interpolation between nodes.
    pub interpolation: f64,
}

/// Why Δ cannot be met.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error(
    "Δ = {delta} mm is spent before interpolation: feed scallop {scallop:.5} mm, insert cusp \
     {cusp:.5} mm, blending {blend:.5} mm, rounding {rounding:.5} mm; {hint}"
)]
pub struct BudgetError {
    /// Δ.
    pub delta: f64,
    /// Scallop.
    pub scallop: f64,
    /// Cusp.
    pub cusp: f64,
    /// Blending.
    pub blend: f64,
    /// Rounding.
    pub rounding: f64,
    /// What to change.
    pub hint: String,
}

/// The least share of Δ that interpolation must keep for a sensible number of segments.
pub const MIN_INTERPOLATION_SHARE: f64 = 0.2;

impl Budget {
    /// Share Δ out; interpolation must keep at least [`MIN_INTERPOLATION_SHARE`] of it.
    pub fn new(
        delta: f64,
        scallop: f64,
        cusp: f64,
        blend: f64,
        rounding: f64,
        feed: f64,
    ) -> Result<Budget, BudgetError> {
        let interpolation = delta - scallop - cusp - blend - rounding;
        if interpolation < MIN_INTERPOLATION_SHARE * delta {
            // The scallop grows with the square of the feed.
            let room = (1.0 - MIN_INTERPOLATION_SHARE) * delta - cusp - blend - rounding;
            let hint = if room > 0.0 && scallop > 0.0 {
                format!(
                    "lower cut.axial_feed to at most {:.4} mm (scallop ∝ feed²)",
                    feed * (room / scallop).sqrt()
                )
            } else {
                "lower the workpiece speed against the ring speed (cusp), or raise Δ".into()
            };
            return Err(BudgetError {
                delta,
                scallop,
                cusp,
                blend,
                rounding,
                hint,
            });
        }
        Ok(Budget {
            delta,
            scallop,
            cusp,
            blend,
            rounding,
            interpolation,
        })
    }
}

/// The insert cusp of kinematics.md: the workpiece turns 2π·n_w / (z·n_t) between two insert
/// hits, an arc s = ρ times that, leaving s²/8 · (1/ρ ∓ 1/R) (− internal, + external); the
/// largest over the profile's radii.
pub fn cusp(
    table: &Table,
    linkage: &Linkage,
    inserts: u32,
    workpiece_rpm: f64,
    ring_rpm: f64,
) -> f64 {
    let turn = TAU * workpiece_rpm / (f64::from(inserts) * ring_rpm);
    let big_r = linkage.ring.radius;
    table
        .samples
        .iter()
        .map(|s| {
            let rho = s.pos.length();
            let arc = rho * turn;
            let relative = match linkage.ring.whirling {
                Whirling::Internal => 1.0 / rho - 1.0 / big_r,
                Whirling::External => 1.0 / rho + 1.0 / big_r,
            };
            arc * arc / 8.0 * relative.max(0.0)
        })
        .fold(0.0, f64::max)
}

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
pub fn scallop(table: &Table, linkage: &Linkage, feed: f64) -> f64 {
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
