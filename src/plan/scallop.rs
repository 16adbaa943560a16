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

/// The feed scallop at profile points spread over the period, in table order.
#[derive(Debug, Clone, PartialEq)]
pub struct Scallops {
    /// (index of the table sample, height left there, mm).
    pub at: Vec<(usize, f64)>,
}

impl Scallops {
    /// The largest height: the share of Δ the error budget counts.
    pub fn max(&self) -> f64 {
        self.at.iter().map(|a| a.1).fold(0.0, f64::max)
    }

    /// The scallop to count at table sample `i`: the larger of the heights measured at the
    /// nearest profile points either side of it (the period wraps), since the undercut a span
    /// leaves at a profile point adds to the scallop there and not to the largest one
    /// elsewhere on the profile.
    pub fn near(&self, i: usize) -> f64 {
        let n = self.at.len();
        if n == 0 {
            return 0.0;
        }
        // The first profile point after sample i, and the one before it (at or before i);
        // both wrap round the period.
        let next = self.at.partition_point(|a| a.0 <= i);
        let prev = (next + n - 1) % n;
        if self.at[prev].0 == i {
            return self.at[prev].1;
        }
        self.at[prev].1.max(self.at[next % n].1)
    }
}

/// The feed scallop, measured rather than estimated: for profile points spread over the
/// period, the undercut left midway between two neighbouring passes of the ring over its
/// groove, each pass being the planned family of poses (X from the table) screwed along.
///
/// By screw invariance every pose of the path is the canonical pose (ψ, X(ψ), 0) screwed by
/// τ = Z/p. The point P(u) is touched at τ_u = Z_u/p; the passes before and after it are
/// the same family screwed by τ_u ∓ Δτ. Where the two meet, between them, the point is left
/// proudest: that height is the scallop.
pub fn ring(table: &Table, linkage: &Linkage, feed: f64) -> Scallops {
    let p = linkage.p;
    let spacing = pass_spacing(p, feed);
    let drift = spacing / TAU; // dτ/dψ within a pass
    let picks = 64.min(table.samples.len());
    let at = (0..picks)
        .map(|k| k * (table.samples.len() - 1) / picks)
        .map(|i| {
            let s = &table.samples[i];
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
            (
                i,
                -golden(|t| -between(t), spacing.min(0.0), spacing.max(0.0), 32).1,
            )
        })
        .collect();
    Scallops { at }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sample_counts_the_larger_scallop_of_the_profile_points_either_side() {
        let s = Scallops {
            at: vec![(0, 1.0), (10, 3.0), (20, 2.0)],
        };
        assert_eq!(s.max(), 3.0);
        // At a measured point, its own height.
        assert_eq!(s.near(10), 3.0);
        assert_eq!(s.near(20), 2.0);
        // Between two, the larger.
        assert_eq!(s.near(5), 3.0);
        assert_eq!(s.near(15), 3.0);
        // Past the last, the period wraps round to the first.
        assert_eq!(s.near(25), 2.0);
        let t = Scallops {
            at: vec![(3, 1.0), (10, 3.0)],
        };
        assert_eq!(t.near(1), 3.0);
        assert_eq!(Scallops { at: vec![] }.near(4), 0.0);
    }
}
