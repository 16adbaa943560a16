//! Cylindrical worms' threads, DIN 3975-1 / ISO 10828 flank forms ZA, ZN and ZI, from the axial
//! module `m`, the number of starts `z1`, the pressure angle `α` and the diameter quotient `q`.
//! Conventions as in the parent module.
//!
//! The basic dimensions (DIN 3975-1, ISO 10828): axial pitch `p_x = π·m`, lead
//! `p_z = z1·p_x`, reference diameter `d1 = q·m`, lead angle at it `tan γ = z1/q`, addendum
//! `h_a = m` (tip diameter `d1 + 2m`), dedendum `h_f = (1 + c*)·m` with the bottom clearance
//! factor `c*` (default 0.2; root diameter `d1 − 2(1 + c*)m`), axial tooth thickness and
//! axial space width `p_x/2` each on the reference cylinder.
//!
//! The flank forms differ in the section in which the flank is straight, and where `α` is
//! measured:
//! - **ZA**: straight in the axial section, at `α` from the radial direction. Its flanks are
//!   exact [`AxialPiece::Line`]s.
//! - **ZN**: straight in the section normal to the space's helix at the reference cylinder, at
//!   `α` there (the tool is a straight-sided blade set at the lead angle). Its axial section is
//!   curved: each point of the straight blade, swept along the helix back into the axial
//!   half-plane, lands at `z − p·θ`, in closed form.
//! - **ZI**: an involute helicoid, whose transverse section is an involute of the base circle
//!   `d_b = d1·cos α_t`, `tan α_t = tan α / sin γ` (`α` the normal pressure angle at the
//!   reference cylinder, as for a helical gear of helix angle `90° − γ`). Its axial section at
//!   radius `ρ` lies at `p·inv α_ρ` from where it crosses the reference cylinder,
//!   `cos α_ρ = r_b/ρ`, `inv x = tan x − x`, in closed form.
//!
//! The curved sections of ZN and ZI are fitted by tangent-continuous arcs (`standard/arc_fit.rs`) within
//! [`FLANK_TOLERANCE`]. The root flat joins the flanks with fillets of radius `ρ_f` tangent to
//! both (the standard leaves the root's form to the tool; whirl's default is `0.2·m`), found on
//! the exact flank.

use super::arc_fit::{self, Curve};
use super::designation::{Designation, DesignationError};
use super::{mirror_z, non_negative, positive, AxialPiece, StandardError};
use glam::DVec2;
use std::f64::consts::{FRAC_PI_4, PI};

/// How far the arcs standing for a curved flank may lie from it (mm): 0.01 µm.
pub const FLANK_TOLERANCE: f64 = 1e-5;

/// The bottom clearance factor `c*` when the job gives none (DIN 3975-1's usual 0.2).
pub const DEFAULT_BOTTOM_CLEARANCE: f64 = 0.2;

/// The root fillet radius, as a share of the module, when the job gives none.
pub const DEFAULT_ROOT_RADIUS_PER_MODULE: f64 = 0.2;

/// The pressure angle when the job gives none (DIN 3975-1, ISO 10828: 20°).
pub const DEFAULT_PRESSURE_ANGLE_DEG: f64 = 20.0;

/// The section in which a worm's flank is straight (or, for ZI, an involute helicoid).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WormFlank {
    /// Straight in the axial section.
    ZA,
    /// Straight in the space's normal section.
    ZN,
    /// Involute helicoid.
    ZI,
}

impl WormFlank {
    /// The standard's letters.
    pub fn name(self) -> &'static str {
        match self {
            WormFlank::ZA => "ZA",
            WormFlank::ZN => "ZN",
            WormFlank::ZI => "ZI",
        }
    }
}

/// A cylindrical worm's thread, all lengths in mm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Worm {
    flank: WormFlank,
    module: f64,
    starts: u32,
    quotient: f64,
    pressure_angle: f64,
    bottom_clearance: f64,
    root_radius: f64,
}

impl Worm {
    /// A worm of flank form `flank`, axial module `m`, `z1` starts, diameter quotient `q`,
    /// pressure angle (degrees, default 20°), bottom clearance factor `c*` (default 0.2) and
    /// root fillet radius (mm, default `0.2·m`).
    pub fn new(
        flank: WormFlank,
        module: f64,
        starts: u32,
        quotient: f64,
        pressure_angle_deg: Option<f64>,
        bottom_clearance: Option<f64>,
        root_radius: Option<f64>,
    ) -> Result<Self, StandardError> {
        let module = positive("module m", module)?;
        let quotient = positive("diameter quotient q", quotient)?;
        if starts == 0 {
            return Err(StandardError::NotPositive {
                name: "starts z1",
                value: 0.0,
            });
        }
        let deg = pressure_angle_deg.unwrap_or(DEFAULT_PRESSURE_ANGLE_DEG);
        if !(deg > 0.0 && deg < 45.0) {
            return Err(StandardError::PressureAngleOutOfRange { degrees: deg });
        }
        let worm = Self {
            flank,
            module,
            starts,
            quotient,
            pressure_angle: deg.to_radians(),
            bottom_clearance: non_negative(
                "bottom clearance c*",
                bottom_clearance.unwrap_or(DEFAULT_BOTTOM_CLEARANCE),
            )?,
            root_radius: non_negative(
                "root radius",
                root_radius.unwrap_or(DEFAULT_ROOT_RADIUS_PER_MODULE * module),
            )?,
        };
        if worm.root_diameter() <= 0.0 {
            return Err(StandardError::MinorDiameterNotPositive {
                major: worm.tip_diameter(),
                depth: 0.5 * (worm.tip_diameter() - worm.root_diameter()),
                minor: worm.root_diameter(),
            });
        }
        if flank == WormFlank::ZI && worm.base_diameter() >= worm.root_diameter() {
            return Err(StandardError::RootInsideBaseCylinder {
                root: worm.root_diameter(),
                base: worm.base_diameter(),
            });
        }
        // The flanks must not meet above the root: the groove must be open at the root.
        worm.flank_fillet()?;
        Ok(worm)
    }

    /// The flank form.
    pub fn flank(&self) -> WormFlank {
        self.flank
    }

    /// Axial module m (mm).
    pub fn module(&self) -> f64 {
        self.module
    }

    /// Number of starts z1.
    pub fn starts(&self) -> u32 {
        self.starts
    }

    /// Diameter quotient q.
    pub fn quotient(&self) -> f64 {
        self.quotient
    }

    /// Pressure angle α (radians), in the section the flank form defines it in.
    pub fn pressure_angle(&self) -> f64 {
        self.pressure_angle
    }

    /// Bottom clearance factor c*.
    pub fn bottom_clearance(&self) -> f64 {
        self.bottom_clearance
    }

    /// Root fillet radius ρ_f (mm).
    pub fn root_radius(&self) -> f64 {
        self.root_radius
    }

    /// Axial pitch p_x = π·m (mm).
    pub fn axial_pitch(&self) -> f64 {
        PI * self.module
    }

    /// Lead p_z = z1·π·m (mm).
    pub fn lead(&self) -> f64 {
        f64::from(self.starts) * self.axial_pitch()
    }

    /// Reference diameter d1 = q·m (mm).
    pub fn reference_diameter(&self) -> f64 {
        self.quotient * self.module
    }

    /// Tip diameter d_a1 = d1 + 2m (mm).
    pub fn tip_diameter(&self) -> f64 {
        self.reference_diameter() + 2.0 * self.module
    }

    /// Root diameter d_f1 = d1 − 2(1 + c*)m (mm).
    pub fn root_diameter(&self) -> f64 {
        self.reference_diameter() - 2.0 * (1.0 + self.bottom_clearance) * self.module
    }

    /// Lead angle γ at the reference cylinder, tan γ = z1/q (radians).
    pub fn lead_angle(&self) -> f64 {
        (f64::from(self.starts) / self.quotient).atan()
    }

    /// Axial pressure angle α_x at the reference cylinder (radians): α for ZA;
    /// tan α_x = tan α / cos γ for ZN and ZI, whose α is the normal one.
    pub fn axial_pressure_angle(&self) -> f64 {
        match self.flank {
            WormFlank::ZA => self.pressure_angle,
            WormFlank::ZN | WormFlank::ZI => {
                (self.pressure_angle.tan() / self.lead_angle().cos()).atan()
            }
        }
    }

    /// ZI's transverse pressure angle at the reference cylinder, tan α_t = tan α / sin γ.
    fn transverse_pressure_angle(&self) -> f64 {
        (self.pressure_angle.tan() / self.lead_angle().sin()).atan()
    }

    /// ZI's base diameter d_b = d1·cos α_t (mm); the other forms have none, 0.
    pub fn base_diameter(&self) -> f64 {
        match self.flank {
            WormFlank::ZI => self.reference_diameter() * self.transverse_pressure_angle().cos(),
            WormFlank::ZA | WormFlank::ZN => 0.0,
        }
    }

    /// Helix parameter p_z / 2π (mm per radian).
    fn helix(&self) -> f64 {
        0.5 * self.lead() / PI
    }

    /// The left flank (z < 0) at radius `rho`: its axial position.
    fn flank_z(&self, rho: f64) -> f64 {
        let r1 = 0.5 * self.reference_diameter();
        let quarter = FRAC_PI_4 * self.module; // half the axial space width p_x/4
        match self.flank {
            WormFlank::ZA => -quarter - (rho - r1) * self.pressure_angle.tan(),
            WormFlank::ZI => {
                let rb = 0.5 * self.base_diameter();
                let inv = |r: f64| {
                    let a = (rb / r).acos();
                    a.tan() - a
                };
                -quarter - self.helix() * (inv(rho) - inv(r1))
            }
            WormFlank::ZN => self.zn_flank_z(rho),
        }
    }

    /// ZN: the blade's line in the normal section, `t` along the radial direction from the
    /// reference cylinder, lies at `(r1 + t, w·sin γ, −w·cos γ)`,
    /// `w = (p_x/4)·cos γ + t·tan α` (the half normal space width, widening outward). Its
    /// radius and polar angle at `t`, and the axial position it sweeps to, `z − p·θ`; `t`
    /// for the radius `rho` by Newton's method (the radius grows with `t` at a slope near 1).
    fn zn_flank_z(&self, rho: f64) -> f64 {
        let r1 = 0.5 * self.reference_diameter();
        let (sin_g, cos_g) = self.lead_angle().sin_cos();
        let tan_a = self.pressure_angle.tan();
        let half = FRAC_PI_4 * self.module * cos_g;
        let at = |t: f64| {
            let w = half + t * tan_a;
            let (x, y) = (r1 + t, w * sin_g);
            (x.hypot(y), x, y, w)
        };
        let mut t = rho - r1;
        for _ in 0..50 {
            let (r, x, y, _) = at(t);
            let slope = (x + y * sin_g * tan_a) / r;
            let step = (r - rho) / slope;
            t -= step;
            if step.abs() < 1e-15 * rho.max(1.0) {
                break;
            }
        }
        let (_, x, y, w) = at(t);
        -w * cos_g - self.helix() * y.atan2(x)
    }

    /// The root fillet on the left flank: the radius of its tangent point on the flank and
    /// its centre. Refused when the fillets (or, with no fillet, the flanks) meet above the
    /// root.
    fn flank_fillet(&self) -> Result<(f64, DVec2), StandardError> {
        match self.fillet() {
            Some((rho_t, c)) if c.y < 0.0 => Ok((rho_t, c)),
            Some((_, c)) if self.root_radius == 0.0 => Err(StandardError::FlanksCross {
                pitch: self.axial_pitch(),
                depth: 0.5 * (self.tip_diameter() - self.root_diameter()),
                root_flat: 2.0 * c.y,
            }),
            _ => Err(self.root_radius_too_large()),
        }
    }

    /// The fillet's tangent point (its radius) and centre, wherever the centre falls; `None`
    /// when no fillet of this radius touches both the flank and the root.
    fn fillet(&self) -> Option<(f64, DVec2)> {
        let rf = 0.5 * self.root_diameter();
        let ra = 0.5 * self.tip_diameter();
        let r = self.root_radius;
        let curve = LeftFlank(self);
        if r == 0.0 {
            return Some((rf, curve.point(rf)));
        }
        // Centre of a fillet tangent to the flank at radius rho (into the groove, +z side).
        let centre = |rho: f64| {
            let t = curve.tangent(rho); // pointing outward (rho growing), z falling
            let n = DVec2::new(-t.y, t.x); // into the groove: +rho and +z components
            curve.point(rho) + r * n
        };
        // The centre's radius grows with rho: bisect for rf + r.
        let (mut lo, mut hi) = (rf, ra);
        if centre(hi).x < rf + r {
            return None;
        }
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if centre(mid).x < rf + r {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let rho_t = 0.5 * (lo + hi);
        Some((rho_t, centre(rho_t)))
    }

    /// The refusal of a root radius whose fillets do not fit, with the largest that does.
    fn root_radius_too_large(&self) -> StandardError {
        let fits = |r: f64| {
            Worm {
                root_radius: r,
                ..*self
            }
            .fillet()
            .is_some_and(|(_, c)| c.y < 0.0)
        };
        let (mut lo, mut hi) = (0.0, self.root_radius);
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if fits(mid) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        StandardError::RootRadiusTooLarge {
            radius: self.root_radius,
            max: lo,
        }
    }

    /// The axial section of one axial pitch, `p_x = π·m` (see the module documentation for
    /// the conventions); `pitch` must be that axial pitch.
    pub fn pieces(&self, pitch: f64) -> Result<Vec<AxialPiece>, StandardError> {
        let pitch = positive("pitch", pitch)?;
        let px = self.axial_pitch();
        if (pitch - px).abs() > 1e-9 * px {
            return Err(StandardError::PitchNotModule {
                pitch,
                module: self.module,
                axial_pitch: px,
            });
        }
        let ra = 0.5 * self.tip_diameter();
        let rf = 0.5 * self.root_diameter();
        let (rho_t, c) = self.flank_fillet()?;
        let curve = LeftFlank(self);
        let tip = curve.point(ra);
        if tip.y <= -0.5 * pitch {
            return Err(StandardError::GroovesOverlap {
                width: -2.0 * tip.y,
                pitch,
            });
        }
        // The left flank, from the tip down to the fillet.
        let left: Vec<AxialPiece> = match self.flank {
            WormFlank::ZA => vec![AxialPiece::Line {
                from: tip,
                to: curve.point(rho_t),
            }],
            WormFlank::ZN | WormFlank::ZI => arc_fit::fit(&curve, ra, rho_t, FLANK_TOLERANCE),
        };
        let mut pieces = vec![AxialPiece::Line {
            from: DVec2::new(ra, -0.5 * pitch),
            to: tip,
        }];
        pieces.extend(left.iter().copied());
        if self.root_radius > 0.0 {
            let flank_end = pieces.last().map(AxialPiece::end).unwrap_or(tip);
            let fillet = AxialPiece::Arc {
                centre: c,
                radius: self.root_radius,
                start: (flank_end - c).to_angle(),
                end: -PI,
            };
            pieces.push(fillet);
            // The centre lies rf + r from the axis to the bisection's last digits: the flat
            // runs at the fillet's own bottom.
            let bottom = fillet.end();
            pieces.push(AxialPiece::Line {
                from: bottom,
                to: DVec2::new(bottom.x, -bottom.y),
            });
            pieces.push(mirror_z(fillet));
        } else {
            pieces.push(AxialPiece::Line {
                from: DVec2::new(rf, c.y),
                to: DVec2::new(rf, -c.y),
            });
        }
        // The right flank mirrors the left (z → −z), traversed from the root to the tip.
        pieces.extend(left.iter().rev().copied().map(mirror_z));
        pieces.push(AxialPiece::Line {
            from: DVec2::new(tip.x, -tip.y),
            to: DVec2::new(ra, 0.5 * pitch),
        });
        Ok(pieces)
    }
}

/// The worm's left flank (z < 0) as a curve of the radius.
struct LeftFlank<'a>(&'a Worm);

impl Curve for LeftFlank<'_> {
    fn point(&self, rho: f64) -> DVec2 {
        DVec2::new(rho, self.0.flank_z(rho))
    }
}

#[cfg(test)]
mod tests;

/// Reads a worm's designation, `ZI m2 z1 q10` (DIN 3975-1's flank form, axial module `m`,
/// starts `z`, diameter quotient `q`), with an optional pressure angle `a15` (degrees,
/// default 20) and `LH`. It fixes the lead `π·m·z1` and the starts `z1`; the bottom
/// clearance and root radius are the defaults ([`DEFAULT_BOTTOM_CLEARANCE`],
/// [`DEFAULT_ROOT_RADIUS_PER_MODULE`]).
pub fn read_designation(text: &str) -> Option<Result<Designation, DesignationError>> {
    let mut words = text.split_whitespace();
    let flank = match words.next()? {
        "ZA" => WormFlank::ZA,
        "ZN" => WormFlank::ZN,
        "ZI" => WormFlank::ZI,
        _ => return None,
    };
    let refuse = |why: String| {
        Some(Err(DesignationError::Refused {
            text: text.to_string(),
            why,
        }))
    };
    let (mut module, mut starts, mut quotient, mut angle, mut left_hand) =
        (None, None, None, None, false);
    for word in words {
        if word == "LH" {
            left_hand = true;
            continue;
        }
        let (key, value) = word.split_at(word.chars().next().map_or(0, char::len_utf8));
        let number = match value.parse::<f64>() {
            Ok(v) if v.is_finite() && v > 0.0 => v,
            _ => {
                return refuse(format!(
                    "`{word}`: expected m<module>, z<starts>, q<diameter quotient>, a<pressure \
                     angle> or LH, each number above zero"
                ))
            }
        };
        let slot = match key {
            "m" => &mut module,
            "z" => &mut starts,
            "q" => &mut quotient,
            "a" => &mut angle,
            _ => {
                return refuse(format!(
                    "`{word}`: expected m<module>, z<starts>, q<diameter quotient>, a<pressure \
                     angle> or LH"
                ))
            }
        };
        if slot.replace(number).is_some() {
            return refuse(format!("`{key}` is given twice"));
        }
    }
    let (Some(m), Some(z1), Some(q)) = (module, starts, quotient) else {
        return refuse(
            "a worm's designation gives its module, starts and diameter quotient: `ZI m2 z1 q10`"
                .into(),
        );
    };
    if z1.fract() != 0.0 || z1 > f64::from(u32::MAX) {
        return refuse(format!("z{z1}: the number of starts is a whole number"));
    }
    let z1 = z1 as u32;
    let worm = match Worm::new(flank, m, z1, q, angle, None, None) {
        Ok(worm) => worm,
        Err(error) => {
            return Some(Err(DesignationError::Form {
                text: text.to_string(),
                error,
            }))
        }
    };
    Some(Ok(Designation {
        form: super::StandardProfile::Worm(worm),
        lead: Some(worm.lead()),
        starts: Some(z1),
        left_hand,
        class: None,
        row: format!(
            "DIN 3975-1:2017 / ISO 10828:2015, {}: d1 = q·m = {} mm, p_x = π·m",
            flank.name(),
            worm.reference_diameter()
        ),
    }))
}
