//! The error budget of kinematics.md: how Δ is shared between interpolation, the feed scallop,
//! the insert cusp, controller blending, number rounding, the material left in concave
//! stretches too shallow to refuse, and the profile's fit to rounded or measured points.
//!
//! The scallop and the cusp follow from the cut (feed, speeds) and the tool; blending and
//! rounding from the machine; the concave stretches from the profile and the nose; the fit
//! from the points ([`crate::geometry::profile::smoothing`]): the program is measured
//! against the fitted curve, which may lie that far from a point, either side;
//! interpolation gets what is left, and node choice works to it.
//!
//! The shares do not all add up at one point, nor on one side of the surface. The scallop,
//! the cusp and a concave stretch only ever leave material (undercut); an overcut is what one
//! pass cut too deep, and no other pass puts material back, so only blending and rounding add
//! to it. Nor do they peak together: the scallop, the cusp and the rounding of the numbers
//! each have their own profile points where they are largest. Interpolation therefore gets two
//! rooms at every profile point, how deep it may cut there and how much it may leave, each Δ
//! less what adds to it *there* ([`crate::plan::segment::Problem::rooms`]).

use crate::geometry::linkage::{Linkage, Whirling};
use crate::plan::table::Table;
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
    /// The controller's path blending, 0 for exact-path controllers. On LinuxCNC, written as
    /// `G64 P`, which bounds its arc blends; the parabolic blends of linked moves, which P
    /// does not bound, are held to it by capping their speed
    /// ([`crate::program::blending::cap_linked_feeds`]).
    pub blend: f64,
    /// Rounding of the written numbers and of the controller's number type.
    pub rounding: f64,
    /// Material left in concave stretches tighter than the nose but too shallow to refuse.
    pub concave: f64,
    /// The fitted profile's largest distance from its points (0 for exact points and
    /// standard forms).
    pub fit: f64,
    /// What is left for interpolation between nodes where every share peaks at once: Δ less
    /// the largest scallop and cusp and the blending, rounding, concave and fit shares. The node
    /// choice works to each sample's own rooms instead ([`crate::plan::segment::Problem::rooms`]).
    pub interpolation: f64,
}

/// What Δ is spent on before interpolation, mm (see [`Budget`]'s fields).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spent {
    /// The feed scallop.
    pub scallop: f64,
    /// The insert cusp.
    pub cusp: f64,
    /// Blending.
    pub blend: f64,
    /// Rounding.
    pub rounding: f64,
    /// Concave stretches.
    pub concave: f64,
    /// The profile's fit.
    pub fit: f64,
}

/// Why Δ cannot be met.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error(
    "Δ = {delta} mm is spent before interpolation: feed scallop {scallop:.5} mm, insert cusp \
     {cusp:.5} mm, blending {blend:.5} mm, rounding {rounding:.5} mm, concave stretches \
     {concave:.5} mm, profile fit {fit:.5} mm; {hint}"
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
    /// Concave stretches.
    pub concave: f64,
    /// The profile's fit.
    pub fit: f64,
    /// What to change.
    pub hint: String,
}

/// The least share of Δ that interpolation must keep for a sensible number of segments.
pub const MIN_INTERPOLATION_SHARE: f64 = 0.2;

impl Budget {
    /// Share Δ out; interpolation must keep at least [`MIN_INTERPOLATION_SHARE`] of it.
    pub fn new(delta: f64, spent: Spent, feed: f64) -> Result<Budget, BudgetError> {
        let Spent {
            scallop,
            cusp,
            blend,
            rounding,
            concave,
            fit,
        } = spent;
        // In this order: subtracting a concave or fit share of 0 leaves the other figures
        // exactly as they were.
        let interpolation = delta - scallop - cusp - blend - rounding - concave - fit;
        if interpolation < MIN_INTERPOLATION_SHARE * delta {
            // The scallop grows with the square of the feed.
            let room =
                (1.0 - MIN_INTERPOLATION_SHARE) * delta - cusp - blend - rounding - concave - fit;
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
                concave,
                fit,
                hint,
            });
        }
        Ok(Budget {
            delta,
            scallop,
            cusp,
            blend,
            rounding,
            concave,
            fit,
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
    let turn = insert_turn(inserts, workpiece_rpm, ring_rpm);
    table
        .samples
        .iter()
        .map(|s| cusp_at(s.pos.length(), linkage, turn))
        .fold(0.0, f64::max)
}

/// The workpiece's turn between the hits of two successive inserts, 2π·n_w / (z·n_t), rad.
pub fn insert_turn(inserts: u32, workpiece_rpm: f64, ring_rpm: f64) -> f64 {
    TAU * workpiece_rpm / (f64::from(inserts) * ring_rpm)
}

/// The insert cusp at polar radius `rho` for a workpiece turn `turn` between insert hits
/// (clipped at zero where the ring is flatter than the work). A bore head's convex tip
/// circle inside a nut's concave surface: `1/R − 1/ρ`.
pub fn cusp_at(rho: f64, linkage: &Linkage, turn: f64) -> f64 {
    let big_r = linkage.ring.radius;
    let arc = rho * turn;
    let relative = match linkage.ring.whirling {
        Whirling::Internal => 1.0 / rho - 1.0 / big_r,
        Whirling::External => 1.0 / rho + 1.0 / big_r,
        Whirling::Bore => 1.0 / big_r - 1.0 / rho,
    };
    arc * arc / 8.0 * relative.max(0.0)
}
