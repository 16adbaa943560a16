//! Ball screws' raceways on the shaft: the gothic arch and the circular arc, as ISO 3408-1 and
//! the makers' catalogues (THK, HIWIN, NSK) define them. Conventions as in the parent module.
//!
//! Both raceways are built from the ball: its diameter `D_w`, the ball-centre (pitch-circle)
//! diameter `d_0` its centre runs on, the conformity `f = r_g / D_w` (the raceway radius over
//! the ball diameter; the catalogues' 0.52 to 0.56) and, for the gothic arch, the contact
//! angle `β` (45° in every catalogue consulted) measured in the axial section from the radial
//! direction.
//!
//! - **Circular arc**: one arc of radius `r_g` whose centre lies on the ball's radial line; the
//!   ball touches it at the bottom (contact angle 0 until a load or a preload moves it).
//!   This is [`BallArc`].
//! - **Gothic arch**: two arcs of radius `r_g`, one per flank, each centred on the line from
//!   the ball's centre through its contact point, `r_g − D_w/2` beyond the ball's centre. So
//!   the ball touches each flank exactly at `β`: the two circles are internally tangent to
//!   the ball there. The arcs cross below the ball at a cusp, which no round nose cuts; an
//!   optional relief arc of radius `r_r` tangent to both flanks rounds it (grinding wheels
//!   and whirling inserts for gothic arches leave such a relief below the ball, which never
//!   touches there).

use super::{positive, AxialPiece, BallArc, StandardError};
use glam::DVec2;
use std::f64::consts::PI;

/// The raceway's form in the axial section.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Raceway {
    /// Two arcs, the ball touching each at the contact angle.
    GothicArch,
    /// One arc, the ball touching it at the bottom.
    CircularArc,
}

/// The contact angle of the gothic arch the catalogues give (THK, HIWIN, NSK: 45°).
pub const CATALOGUE_CONTACT_ANGLE_DEG: f64 = 45.0;

/// The range of conformity `r_g / D_w` the catalogues give for ground and whirled raceways.
pub const CATALOGUE_CONFORMITY: (f64, f64) = (0.52, 0.56);

/// A ball screw shaft's raceway, all lengths in mm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BallScrew {
    raceway: Raceway,
    ball_diameter: f64,
    conformity: f64,
    contact_angle: f64,
    pitch_circle_diameter: f64,
    outer_diameter: f64,
    relief_radius: Option<f64>,
}

impl BallScrew {
    /// A raceway for balls of diameter `D_w` running on the ball-centre diameter `d_0`, cut
    /// into a shaft of outer diameter `d`, with conformity `r_g / D_w`.
    ///
    /// The gothic arch takes a contact angle (degrees, default 45°) and an optional relief
    /// radius `r_r` at the bottom; the circular arc takes neither (its contact angle is 0 by
    /// construction).
    pub fn new(
        raceway: Raceway,
        ball_diameter: f64,
        conformity: f64,
        contact_angle_deg: Option<f64>,
        pitch_circle_diameter: f64,
        outer_diameter: f64,
        relief_radius: Option<f64>,
    ) -> Result<Self, StandardError> {
        let ball_diameter = positive("ball diameter D_w", ball_diameter)?;
        let conformity = positive("conformity r_g/D_w", conformity)?;
        let pitch_circle_diameter = positive("ball-centre diameter d_0", pitch_circle_diameter)?;
        let outer_diameter = positive("outer diameter d", outer_diameter)?;
        if conformity <= 0.5 {
            return Err(StandardError::GrooveRadiusTooSmall {
                groove_radius: conformity * ball_diameter,
                ball_radius: 0.5 * ball_diameter,
            });
        }
        let contact_angle = match raceway {
            Raceway::CircularArc => {
                if let Some(angle) = contact_angle_deg.filter(|a| *a != 0.0) {
                    return Err(StandardError::NotForRaceway {
                        name: "contact angle",
                        value: angle,
                    });
                }
                if let Some(r) = relief_radius {
                    return Err(StandardError::NotForRaceway {
                        name: "relief radius",
                        value: r,
                    });
                }
                0.0
            }
            Raceway::GothicArch => {
                let deg = contact_angle_deg.unwrap_or(CATALOGUE_CONTACT_ANGLE_DEG);
                if !(deg > 0.0 && deg < 90.0) {
                    return Err(StandardError::ContactAngleOutOfRange { degrees: deg });
                }
                deg.to_radians()
            }
        };
        let screw = Self {
            raceway,
            ball_diameter,
            conformity,
            contact_angle,
            pitch_circle_diameter,
            outer_diameter,
            relief_radius: relief_radius
                .map(|r| positive("relief radius r_r", r))
                .transpose()?,
        };
        match raceway {
            Raceway::CircularArc => {
                screw.circular_arc()?;
            }
            Raceway::GothicArch => screw.check_gothic_arch()?,
        }
        Ok(screw)
    }

    /// The raceway's form.
    pub fn raceway(&self) -> Raceway {
        self.raceway
    }

    /// Ball diameter D_w (mm).
    pub fn ball_diameter(&self) -> f64 {
        self.ball_diameter
    }

    /// Conformity r_g / D_w.
    pub fn conformity(&self) -> f64 {
        self.conformity
    }

    /// Raceway radius r_g = conformity · D_w (mm).
    pub fn groove_radius(&self) -> f64 {
        self.conformity * self.ball_diameter
    }

    /// Contact angle β (radians), from the radial direction; 0 for the circular arc.
    pub fn contact_angle(&self) -> f64 {
        self.contact_angle
    }

    /// Ball-centre (pitch-circle) diameter d_0 (mm).
    pub fn pitch_circle_diameter(&self) -> f64 {
        self.pitch_circle_diameter
    }

    /// Outer diameter d (mm).
    pub fn outer_diameter(&self) -> f64 {
        self.outer_diameter
    }

    /// The gothic arch's relief radius r_r (mm), if the bottom is relieved.
    pub fn relief_radius(&self) -> Option<f64> {
        self.relief_radius
    }

    /// The ball's centre (rho, z) in the groove's axial section.
    pub fn ball_centre(&self) -> DVec2 {
        DVec2::new(0.5 * self.pitch_circle_diameter, 0.0)
    }

    /// The circular arc as the single-arc groove it is.
    fn circular_arc(&self) -> Result<BallArc, StandardError> {
        BallArc::new(
            self.ball_diameter,
            self.groove_radius(),
            self.pitch_circle_diameter,
            self.outer_diameter,
        )
    }

    /// Offset `e = r_g − D_w/2` of each flank's centre from the ball's centre.
    fn offset(&self) -> f64 {
        self.groove_radius() - 0.5 * self.ball_diameter
    }

    /// Centre of the gothic arch's flank on the −z side (the right flank's is its mirror):
    /// `r_g − D_w/2` from the ball's centre, away from the contact point.
    pub fn flank_centre(&self) -> DVec2 {
        let beta = self.contact_angle;
        self.ball_centre() + self.offset() * DVec2::new(beta.cos(), beta.sin())
    }

    /// Where the ball touches the flank on the −z side.
    pub fn contact_point(&self) -> DVec2 {
        let beta = self.contact_angle;
        self.ball_centre() - 0.5 * self.ball_diameter * DVec2::new(beta.cos(), beta.sin())
    }

    /// Radius of the groove's bottom (mm): the cusp where the flanks cross, or the relief
    /// arc's bottom; for the circular arc `d_0/2 − D_w/2`.
    pub fn bottom_radius(&self) -> f64 {
        match self.raceway {
            Raceway::CircularArc => 0.5 * (self.pitch_circle_diameter - self.ball_diameter),
            Raceway::GothicArch => {
                let o = self.flank_centre();
                match self.relief_radius {
                    None => o.x - (self.groove_radius().powi(2) - o.y * o.y).sqrt(),
                    Some(r) => self.relief_centre(r) - r,
                }
            }
        }
    }

    /// Depth of the groove below the outer diameter (mm).
    pub fn depth(&self) -> f64 {
        0.5 * self.outer_diameter - self.bottom_radius()
    }

    /// Axial width of the groove at the outer diameter (mm).
    pub fn groove_width(&self) -> f64 {
        match self.raceway {
            Raceway::CircularArc => {
                let centre =
                    0.5 * (self.pitch_circle_diameter - self.ball_diameter) + self.groove_radius();
                let below = centre - 0.5 * self.outer_diameter;
                2.0 * (self.groove_radius().powi(2) - below * below).sqrt()
            }
            Raceway::GothicArch => {
                let o = self.flank_centre();
                let below = o.x - 0.5 * self.outer_diameter;
                2.0 * ((self.groove_radius().powi(2) - below * below).sqrt() - o.y)
            }
        }
    }

    /// Radius (rho) of the relief arc's centre, on z = 0, internally tangent to both flanks.
    fn relief_centre(&self, relief: f64) -> f64 {
        let o = self.flank_centre();
        o.x - ((self.groove_radius() - relief).powi(2) - o.y * o.y).sqrt()
    }

    /// Checks that the gothic arch exists on this shaft: the ball touches both flanks below
    /// the outer diameter and above the bottom, the flanks do not overhang, the relief fits.
    fn check_gothic_arch(&self) -> Result<(), StandardError> {
        let o = self.flank_centre();
        let outer = 0.5 * self.outer_diameter;
        if self.ball_centre().x <= 0.5 * self.ball_diameter {
            return Err(StandardError::GrooveBottomNotAboveAxis {
                pitch_circle_diameter: self.pitch_circle_diameter,
                ball_diameter: self.ball_diameter,
            });
        }
        if outer >= o.x {
            return Err(StandardError::GrooveOverhangs {
                outer: self.outer_diameter,
                centre: 2.0 * o.x,
            });
        }
        let contact = self.contact_point();
        if contact.x >= outer {
            return Err(StandardError::ContactAboveOuterDiameter {
                contact: 2.0 * contact.x,
                outer: self.outer_diameter,
            });
        }
        if let Some(relief) = self.relief_radius {
            // The relief touches each flank at the angle δ_r from the flank's centre, with
            // sin δ_r = e·sin β / (r_g − r_r); δ_r < β, below the contact point, holds exactly
            // while r_r < r_g − e = D_w/2: a relief as large as the ball is the ball itself.
            if relief >= 0.5 * self.ball_diameter {
                return Err(StandardError::ReliefReachesContact {
                    relief,
                    max: 0.5 * self.ball_diameter,
                });
            }
        }
        if self.bottom_radius() >= outer {
            return Err(StandardError::OuterDiameterNotAboveGrooveBottom {
                outer: self.outer_diameter,
                bottom: 2.0 * self.bottom_radius(),
            });
        }
        Ok(())
    }

    /// The axial section of one pitch (see the module documentation for the conventions).
    pub fn pieces(&self, pitch: f64) -> Result<Vec<AxialPiece>, StandardError> {
        if self.raceway == Raceway::CircularArc {
            return self.circular_arc()?.pieces(pitch);
        }
        let pitch = positive("pitch", pitch)?;
        let width = self.groove_width();
        if width >= pitch {
            return Err(StandardError::GroovesOverlap { width, pitch });
        }
        let r_g = self.groove_radius();
        let left = self.flank_centre();
        let right = DVec2::new(left.x, -left.y);
        let outer = 0.5 * self.outer_diameter;
        // Angle, from −rho, of the flank's end on the outer diameter, seen from its centre.
        let below = left.x - outer;
        let top = (r_g * r_g - below * below).sqrt().atan2(below);
        // Angle, from −rho, where each flank ends at the bottom: the cusp, or the relief's
        // tangent point.
        let bottom = match self.relief_radius {
            None => (left.y / r_g).asin(),
            Some(relief) => (left.y / (r_g - relief)).asin(),
        };
        // Both flanks turn clockwise, as the ball-arc does: the left from its top to its
        // bottom, the right from its bottom to its top.
        let left_arc = AxialPiece::Arc {
            centre: left,
            radius: r_g,
            start: -PI + top,
            end: -PI + bottom,
        };
        let right_arc = AxialPiece::Arc {
            centre: right,
            radius: r_g,
            start: PI - bottom,
            end: PI - top,
        };
        let mut pieces = vec![
            AxialPiece::Line {
                from: DVec2::new(outer, -0.5 * pitch),
                to: left_arc.start(),
            },
            left_arc,
        ];
        if let Some(relief) = self.relief_radius {
            pieces.push(AxialPiece::Arc {
                centre: DVec2::new(self.relief_centre(relief), 0.0),
                radius: relief,
                start: -PI + bottom,
                end: -PI - bottom,
            });
        }
        pieces.push(right_arc);
        pieces.push(AxialPiece::Line {
            from: right_arc.end(),
            to: DVec2::new(outer, 0.5 * pitch),
        });
        Ok(pieces)
    }
}

#[cfg(test)]
mod tests;
