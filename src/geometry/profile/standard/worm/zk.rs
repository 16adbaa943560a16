//! ZK (DIN 3975-1, ISO/TR 10828): the flank a double-cone wheel generates. The wheel, a disc
//! whose axial section is straight-sided at the profile angle `α0` (a grinding wheel or a
//! disc cutter), stands with its mid-plane along the space's helix at the reference
//! cylinder: its axis is crossed with the worm's at `90° − γ`, at the centre distance
//! `a0 = (d1 + d0)/2`, `d0` the wheel's diameter where it meets that cylinder. The worm turns
//! and feeds one lead per turn past it; the flank is the envelope of the wheel's cone.
//!
//! In the worm's frame (axis z, the wheel's centre at `(a0, 0, 0)`), with
//! `e1 = (−1, 0, 0)` towards the worm's axis, `e2 = (0, cos γ, sin γ)` along the helix and the
//! wheel's axis `u = (0, −sin γ, cos γ)`, the cone facing −z (the left flank) is
//!
//! `P(R, θ) = C + R·(cos θ·e1 + sin θ·e2) − w(R)·u`, `w(R) = w0 − (R − r0)·tan α0`,
//!
//! `R` the radius on the wheel, `w0` its half thickness at `r0 = d0/2`. Its normal is
//! `n = tan α0·(cos θ·e1 + sin θ·e2) − u`. A point of the cone lies on the flank where the
//! worm's screw motion (velocity `(−y, x, p)` per radian, `p = p_z/2π`) slides along the
//! cone: `n·v = 0`, the envelope condition, solved for `θ` at each `R`. The contact point
//! swept along the helix into the axial half-plane lands at `(√(x² + y²), z − p·atan2(y, x))`.
//!
//! `w0` is the thickness that leaves the axial space width `p_x/2` on the reference cylinder
//! (DIN 3975-1's basic dimension for every flank form): the wheel is dressed to the space.

use crate::geometry::brent;
use glam::{DVec2, DVec3};
use std::f64::consts::FRAC_PI_2;

/// Tolerance of every root here, in its own unit (radians or mm): far below the flank's
/// [`super::FLANK_TOLERANCE`].
const ROOT_TOLERANCE: f64 = 1e-14;

/// The double-cone wheel of a ZK worm, set against the worm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Wheel {
    /// `r0 = d0/2` (mm).
    radius: f64,
    /// Centre distance `a0 = r1 + r0` (mm).
    centre_distance: f64,
    /// `tan α0`.
    tan_profile: f64,
    /// `(sin γ, cos γ)`.
    lead: (f64, f64),
    /// `p = p_z/2π` (mm per radian).
    helix: f64,
    /// Half thickness `w0` at `r0` (mm).
    half_width: f64,
}

impl Wheel {
    /// The wheel of diameter `d0` and profile angle `α0` (radians) that cuts a worm of
    /// reference radius `r1`, lead angle `γ` and helix parameter `p` with its left flank
    /// through `(r1, z1)`; `None` when no thickness of that wheel does.
    pub fn dressed(
        diameter: f64,
        profile_angle: f64,
        r1: f64,
        lead_angle: f64,
        helix: f64,
        z1: f64,
    ) -> Option<Self> {
        let wheel = |half_width: f64| Wheel {
            radius: 0.5 * diameter,
            centre_distance: r1 + 0.5 * diameter,
            tan_profile: profile_angle.tan(),
            lead: lead_angle.sin_cos(),
            helix,
            half_width,
        };
        // The blade's width in the normal section is a first guess; a thicker wheel moves
        // the flank to −z about one for one.
        let guess = -z1 * lead_angle.cos();
        let miss = |w: f64| wheel(w).flank_z(r1).map_or(f64::NAN, |z| z - z1);
        let w0 = bracketed(miss, guess, 1e-3 * guess, guess)?;
        Some(wheel(w0))
    }

    /// The wheel's diameter `d0` (mm).
    pub fn diameter(&self) -> f64 {
        2.0 * self.radius
    }

    /// The wheel's thickness at `d0` (mm), as dressed.
    pub fn thickness(&self) -> f64 {
        2.0 * self.half_width
    }

    /// The left flank's axial position at radius `rho`; `None` when the wheel generates no
    /// flank there.
    pub fn flank_z(&self, rho: f64) -> Option<f64> {
        let start = self.centre_distance - rho;
        let big_r = bracketed(
            |r| self.axial(r).map_or(f64::NAN, |p| p.x - rho),
            start,
            1e-6 * start,
            0.5 * start,
        )?;
        self.axial(big_r).map(|p| p.y)
    }

    /// The contact point on the wheel's circle of radius `big_r`, in the worm's frame.
    fn contact(&self, big_r: f64) -> Option<DVec3> {
        // The contact lies near the mid-plane; a quarter turn away the cone faces elsewhere.
        let theta = bracketed(|t| self.envelope(big_r, t), 0.0, 1e-6, FRAC_PI_2)?;
        Some(self.cone(big_r, theta))
    }

    /// The contact point at `big_r` swept into the axial half-plane: `(ρ, z)`.
    fn axial(&self, big_r: f64) -> Option<DVec2> {
        let p = self.contact(big_r)?;
        Some(DVec2::new(
            p.x.hypot(p.y),
            p.z - self.helix * p.y.atan2(p.x),
        ))
    }

    /// The point of the −z cone at wheel radius `big_r` and angle `theta` from `e1`.
    fn cone(&self, big_r: f64, theta: f64) -> DVec3 {
        let w = self.half_width - (big_r - self.radius) * self.tan_profile;
        DVec3::new(self.centre_distance, 0.0, 0.0) + big_r * self.radial(theta) - w * self.axis()
    }

    /// `n·v` at `(big_r, theta)`: zero where the cone touches the flank.
    fn envelope(&self, big_r: f64, theta: f64) -> f64 {
        let p = self.cone(big_r, theta);
        let n = self.tan_profile * self.radial(theta) - self.axis();
        n.dot(DVec3::new(-p.y, p.x, self.helix))
    }

    /// `cos θ·e1 + sin θ·e2`.
    fn radial(&self, theta: f64) -> DVec3 {
        let (sin_g, cos_g) = self.lead;
        let (s, c) = theta.sin_cos();
        DVec3::new(-c, s * cos_g, s * sin_g)
    }

    /// The wheel's axis `u`.
    fn axis(&self) -> DVec3 {
        let (sin_g, cos_g) = self.lead;
        DVec3::new(0.0, -sin_g, cos_g)
    }
}

/// The root of `f` nearest `x0`: a bracket grown from `x0 ± step`, doubling, until `f` changes
/// sign across it, then Brent's method. `None` when `f` is undefined (NaN) before a bracket is
/// found, or none is within `reach` of `x0`.
fn bracketed(f: impl Fn(f64) -> f64, x0: f64, step: f64, reach: f64) -> Option<f64> {
    let mut h = step.abs();
    while h <= reach {
        let (a, b) = (x0 - h, x0 + h);
        let (fa, fb) = (f(a), f(b));
        if fa.is_nan() || fb.is_nan() {
            return None;
        }
        if fa.signum() != fb.signum() {
            return brent::root(&f, a, b, ROOT_TOLERANCE * x0.abs().max(1.0), 200);
        }
        h *= 2.0;
    }
    None
}

#[cfg(test)]
mod tests;
