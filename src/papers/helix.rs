//! Seed 000's helical tool path, as a value.
//!
//! Dogrusadik's frame (seed 000, Eqs. 2–4): the helix axis (the screw axis) is y, and the tool
//! centre at tool rotation angle φ is
//!
//! ```text
//! x0 = R cos φ,   y0 = p/2 − p φ / (2π),   z0 = R sin φ.
//! ```
//!
//! The tool's own axis stays parallel to y throughout: the motion is a pure translation along
//! the helix, so every point of the tool has the same velocity. The constant p/2 is the paper's
//! "initial tool position": it puts the tool centre at y0 = 0 when φ = π, which is where the
//! helix crosses the observer plane z = 0 on its x < 0 side (x0 = −R). One turn centred on
//! φ = π (φ ∈ [0, 2π]) is the range the paper's section uses.

use glam::DVec3;
use std::f64::consts::{PI, TAU};

/// Why a helix is not usable.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum HelixError {
    /// R must be positive and finite: with R = 0 the path is a straight line along the screw
    /// axis and there is no groove "around x = −R" to describe.
    #[error("helix radius must be positive and finite, got {0}")]
    Radius(f64),
    /// p must be finite and not negative (p = 0 is the circular path the paper mentions).
    #[error("helix pitch must be finite and ≥ 0, got {0}")]
    Pitch(f64),
    /// The φ range must be finite and not empty.
    #[error("helix φ range must be finite with start ≤ end, got [{start}, {end}]")]
    Range {
        /// φ at the start, rad.
        start: f64,
        /// φ at the end, rad.
        end: f64,
    },
    /// The φ range covers more than [`MAX_TURNS`] turns: not a groove anyone cuts, and the
    /// section's work grows with the number of turns.
    #[error("helix φ range covers {0:.0} turns, more than the {MAX_TURNS} allowed")]
    Turns(f64),
}

/// The most turns a [`Helix`] may cover.
pub const MAX_TURNS: u32 = 10_000;

/// A helical motion of the tool centre about the y axis (seed 000, Eqs. 2–4), with the tool
/// axis kept parallel to y, over a range of the tool rotation angle φ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Helix {
    /// R: distance from the screw axis to the tool centre, mm.
    pub radius: f64,
    /// p: axial advance per turn (the paper's pitch), mm. Positive p moves the tool towards −y
    /// as φ grows, as in Eq. 3.
    pub pitch: f64,
    /// First φ of the motion, rad.
    pub phi_start: f64,
    /// Last φ of the motion, rad.
    pub phi_end: f64,
}

impl Helix {
    /// The paper's motion: one turn centred on φ = π, φ ∈ [0, 2π].
    pub fn one_turn(radius: f64, pitch: f64) -> Helix {
        Helix {
            radius,
            pitch,
            phi_start: 0.0,
            phi_end: TAU,
        }
    }

    /// Checks that the helix describes a real motion (see [`HelixError`]).
    pub fn validate(&self) -> Result<(), HelixError> {
        if !(self.radius.is_finite() && self.radius > 0.0) {
            return Err(HelixError::Radius(self.radius));
        }
        if !(self.pitch.is_finite() && self.pitch >= 0.0) {
            return Err(HelixError::Pitch(self.pitch));
        }
        if !(self.phi_start.is_finite() && self.phi_end.is_finite())
            || self.phi_start > self.phi_end
        {
            return Err(HelixError::Range {
                start: self.phi_start,
                end: self.phi_end,
            });
        }
        let turns = (self.phi_end - self.phi_start) / TAU;
        if turns > f64::from(MAX_TURNS) {
            return Err(HelixError::Turns(turns));
        }
        Ok(())
    }

    /// y0(φ) = p/2 − pφ/(2π) (Eq. 3): the axial position of the tool centre.
    pub fn axial(&self, phi: f64) -> f64 {
        // Written as p·(π − φ)/(2π) so that y0(π) is exactly 0, the seed's reference height.
        self.pitch * (PI - phi) / TAU
    }

    /// dy0/dφ = −p/(2π): the axial speed per radian of tool rotation.
    pub fn axial_rate(&self) -> f64 {
        -self.pitch / TAU
    }

    /// The tool centre at φ (Eqs. 2–4).
    pub fn position(&self, phi: f64) -> DVec3 {
        let (s, c) = phi.sin_cos();
        DVec3::new(self.radius * c, self.axial(phi), self.radius * s)
    }

    /// d(position)/dφ: the velocity of every point of the tool, per radian of φ (the motion is
    /// a pure translation, so this is the velocity of the whole tool).
    pub fn velocity(&self, phi: f64) -> DVec3 {
        let (s, c) = phi.sin_cos();
        DVec3::new(-self.radius * s, self.axial_rate(), self.radius * c)
    }

    /// Whether φ is in the motion's range.
    pub fn contains(&self, phi: f64) -> bool {
        phi >= self.phi_start && phi <= self.phi_end
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn follows_the_papers_equations_2_to_4() {
        let h = Helix::one_turn(20.0, 20.0);
        for k in 0..=16 {
            let phi = TAU * k as f64 / 16.0;
            let p = h.position(phi);
            assert!((p.x - 20.0 * phi.cos()).abs() < 1e-12);
            assert!((p.y - (10.0 - 20.0 * phi / TAU)).abs() < 1e-12, "Eq. 3");
            assert!((p.z - 20.0 * phi.sin()).abs() < 1e-12);
        }
        assert_eq!(
            h.position(PI).y,
            0.0,
            "the turn is centred on y0 = 0 at φ = π"
        );
        assert!((h.position(PI).x + 20.0).abs() < 1e-12);
    }

    #[test]
    fn velocity_is_the_derivative_of_position() {
        let h = Helix {
            radius: 7.0,
            pitch: 3.0,
            phi_start: -1.0,
            phi_end: 9.0,
        };
        for phi in [-0.5, 0.3, 2.0, 4.4, 8.0] {
            let d = 1e-6;
            let fd = (h.position(phi + d) - h.position(phi - d)) / (2.0 * d);
            assert!((fd - h.velocity(phi)).length() < 1e-8);
        }
        // One turn advances the tool by one pitch, towards −y.
        assert!((h.position(1.0).y - h.position(1.0 + TAU).y - 3.0).abs() < 1e-12);
    }

    #[test]
    fn refuses_meaningless_helices() {
        assert!(Helix::one_turn(20.0, 0.0).validate().is_ok());
        assert_eq!(
            Helix::one_turn(0.0, 1.0).validate(),
            Err(HelixError::Radius(0.0))
        );
        assert!(matches!(
            Helix::one_turn(f64::NAN, 1.0).validate(),
            Err(HelixError::Radius(_))
        ));
        assert_eq!(
            Helix::one_turn(1.0, -1.0).validate(),
            Err(HelixError::Pitch(-1.0))
        );
        assert!(matches!(
            Helix::one_turn(1.0, f64::INFINITY).validate(),
            Err(HelixError::Pitch(_))
        ));
        let backwards = Helix {
            phi_start: 1.0,
            phi_end: 0.0,
            ..Helix::one_turn(1.0, 1.0)
        };
        assert!(matches!(
            backwards.validate(),
            Err(HelixError::Range { .. })
        ));
        let endless = Helix {
            phi_end: 1e9,
            ..Helix::one_turn(1.0, 1.0)
        };
        assert!(matches!(endless.validate(), Err(HelixError::Turns(_))));
    }
}
