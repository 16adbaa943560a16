//! The single circular-arc ("ball-arc") ball-screw groove with zero contact angle.
//! Conventions as in the parent module.

use super::{positive, AxialPiece, StandardError};
use glam::DVec2;
use std::f64::consts::PI;

/// Single circular-arc ball-screw groove ("ball-arc"), zero contact angle.
///
/// The groove is one arc of radius `r_g > D_w/2` (conformity `r_g/D_w`, typically 0.52 to
/// 0.56), placed so that the ball, centred on the ball-centre (pitch-circle) diameter `d_0`,
/// touches it at the groove bottom: groove bottom at `rho = d_0/2 − D_w/2`, arc centre at
/// `rho = d_0/2 − D_w/2 + r_g`, `z = 0`. The arc runs up to the outer diameter `d`; between
/// grooves the crest is the outer diameter, a line at `rho = d/2`. The corners where the arc
/// meets the outer diameter are sharp.
///
/// The outer diameter must lie above the groove bottom and below the arc centre (else the
/// flanks would overhang); the pitch must leave a crest between grooves.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BallArc {
    ball_diameter: f64,
    groove_radius: f64,
    pitch_circle_diameter: f64,
    outer_diameter: f64,
}

impl BallArc {
    /// A ball-arc groove for balls of diameter `D_w`, groove radius `r_g`, ball-centre diameter
    /// `d_0` and shaft outer diameter `d`, all in mm.
    pub fn new(
        ball_diameter: f64,
        groove_radius: f64,
        pitch_circle_diameter: f64,
        outer_diameter: f64,
    ) -> Result<Self, StandardError> {
        let ball_diameter = positive("ball diameter D_w", ball_diameter)?;
        let groove_radius = positive("groove radius r_g", groove_radius)?;
        let pitch_circle_diameter = positive("ball-centre diameter d_0", pitch_circle_diameter)?;
        let outer_diameter = positive("outer diameter d", outer_diameter)?;
        if groove_radius <= 0.5 * ball_diameter {
            return Err(StandardError::GrooveRadiusTooSmall {
                groove_radius,
                ball_radius: 0.5 * ball_diameter,
            });
        }
        if pitch_circle_diameter <= ball_diameter {
            return Err(StandardError::GrooveBottomNotAboveAxis {
                pitch_circle_diameter,
                ball_diameter,
            });
        }
        let groove = Self {
            ball_diameter,
            groove_radius,
            pitch_circle_diameter,
            outer_diameter,
        };
        let bottom = groove.groove_bottom_radius();
        let centre = groove.arc_centre().x;
        let outer = 0.5 * outer_diameter;
        if outer <= bottom {
            return Err(StandardError::OuterDiameterNotAboveGrooveBottom {
                outer: outer_diameter,
                bottom: 2.0 * bottom,
            });
        }
        if outer >= centre {
            return Err(StandardError::GrooveOverhangs {
                outer: outer_diameter,
                centre: 2.0 * centre,
            });
        }
        Ok(groove)
    }

    /// Ball diameter D_w (mm).
    pub fn ball_diameter(&self) -> f64 {
        self.ball_diameter
    }

    /// Groove radius r_g (mm).
    pub fn groove_radius(&self) -> f64 {
        self.groove_radius
    }

    /// Ball-centre (pitch-circle) diameter d_0 (mm).
    pub fn pitch_circle_diameter(&self) -> f64 {
        self.pitch_circle_diameter
    }

    /// Outer diameter d (mm).
    pub fn outer_diameter(&self) -> f64 {
        self.outer_diameter
    }

    /// Conformity `r_g / D_w`.
    pub fn conformity(&self) -> f64 {
        self.groove_radius / self.ball_diameter
    }

    /// Radius of the groove bottom, `d_0/2 − D_w/2` (mm).
    pub fn groove_bottom_radius(&self) -> f64 {
        0.5 * (self.pitch_circle_diameter - self.ball_diameter)
    }

    /// Centre (rho, z) of the groove arc.
    pub fn arc_centre(&self) -> DVec2 {
        DVec2::new(self.groove_bottom_radius() + self.groove_radius, 0.0)
    }

    /// Groove depth below the outer diameter, `d/2 − (d_0/2 − D_w/2)` (mm).
    pub fn depth(&self) -> f64 {
        0.5 * self.outer_diameter - self.groove_bottom_radius()
    }

    /// Axial width of the groove at the outer diameter (mm).
    pub fn groove_width(&self) -> f64 {
        let below_centre = self.arc_centre().x - 0.5 * self.outer_diameter;
        2.0 * (self.groove_radius * self.groove_radius - below_centre * below_centre).sqrt()
    }

    /// The axial section of one pitch (see the module documentation for the conventions).
    pub fn pieces(&self, pitch: f64) -> Result<Vec<AxialPiece>, StandardError> {
        let pitch = positive("pitch", pitch)?;
        let width = self.groove_width();
        if width >= pitch {
            return Err(StandardError::GroovesOverlap { width, pitch });
        }
        let centre = self.arc_centre();
        let outer = 0.5 * self.outer_diameter;
        // Angle between the arc's radius to its end on the outer diameter and the −rho
        // direction; the arc passes through the bottom (angle ±π) clockwise.
        let half_sweep = (0.5 * width).atan2(centre.x - outer);
        let arc = AxialPiece::Arc {
            centre,
            radius: self.groove_radius,
            start: -PI + half_sweep,
            end: -PI - half_sweep,
        };
        Ok(vec![
            AxialPiece::Line {
                from: DVec2::new(outer, -0.5 * pitch),
                to: arc.start(),
            },
            arc,
            AxialPiece::Line {
                from: arc.end(),
                to: DVec2::new(outer, 0.5 * pitch),
            },
        ])
    }
}
