//! The cusp: the material a tool of revolution leaves between two adjacent straight passes on a
//! flat floor (seed 003, Matei & Blebea), measured by the engine and checked against closed
//! forms.
//!
//! # The section the engine measures
//!
//! The tool's axis is vertical, its tip down; two straight parallel passes run a stepover `s`
//! apart. In the observer plane perpendicular to the passes (x across them, z up), the first
//! pass's centre is at x = 0 and the second's at x = s. A pass sweeps the union of the tool's
//! sections by planes parallel to its axis: a point (x, z) is cut when some radius ρ ≥ |x| of
//! the tool's meridian region covers height z. For every end mill the lowest height the solid
//! occupies at radius ρ does not fall outward (the tip surface rises from the axis), so that
//! union's lower boundary is the meridian outline itself: the widest section, the one through
//! the axis, is the pass's section. The machined surface is then the lower envelope of the two
//! passes,
//!
//! ```text
//! z(x) = min over passes p of  lo(|x − x_p|) − lo(0),    lo(ρ) = span_at(ρ).lowest,
//! ```
//!
//! measured from the floor lo(0) that both tips cut. [`section`] computes it through
//! [`Revolved::span_at`] alone, for any tool, and refuses tools whose sampled tip surface falls
//! outward (a torus, whose section is then not its meridian outline) or does not reach its
//! axis. The straight pass makes the section the same all along the pass, so the volume left
//! over a length L is the section's area times L.
//!
//! # Closed forms
//!
//! Between the passes the envelope is the tool's own tip outline up to the midpoint c = s/2,
//! mirrored beyond it. For a ball of radius r (0 ≤ c ≤ r) the outline is the arc
//! z = r − √(r² − x²), so
//!
//! ```text
//! H   = r − √(r² − c²)                                   cusp height
//! σ_h = ∫₀ᶜ (r − √(r² − x²)) dx = r·c − c·√(r² − c²)/2 − r²·asin(c/r)/2
//!     = (c·H − r²(α − sin α))/2,   α = asin(c/r)         half-cusp area
//! A   = 2·σ_h,   V = A·L
//! ```
//!
//! (the second form of σ_h is the one evaluated: it keeps its digits as c → 0, where
//! σ_h → c³/(6r)). A corner-radius mill (flat tip radius r1, corner radius r2) is flat out to
//! r1, then the corner arc: the passes' flats overlap and leave nothing while s ≤ 2·r1, and
//! beyond that the cusp is the ball's of radius r2 with c replaced by c − r1, i.e. a ball of
//! radius r2 at stepover s − 2·r1.
//!
//! # The paper's equations
//!
//! [`paper`] evaluates Eqs. 22, 23, 27 and 28 as printed, ties their symbols to the tools, and
//! gives the corrected equations; its docs say what is wrong. In short: Eq. 27 (ball) has
//! π·r_c² where the integral gives r·r_c, and Eq. 21 (corner radius) integrates under the
//! upper half of the corner circle, a + √(a² − (x − a)²), where the material left lies under
//! the lower half, a − √(a² − (x − a)²); Eqs. 22, 23 and 28 carry those errors forward.

use crate::papers::tool::{BallEnd, CornerRadius, Revolved};
use glam::DVec2;
use serde::Serialize;

/// The relative accuracy [`section`] integrates the cusp area to (see
/// [`CuspSection::area_error`]).
pub const AREA_RELATIVE_ACCURACY: f64 = 1e-12;

/// Deepest bisection of one initial chord of the polyline: 2⁻⁶⁴ of a quarter half-stepover is
/// below any double's resolution, so reaching it means the envelope cannot be resolved.
const MAX_DEPTH: u32 = 64;

/// Most Gauss–Kronrod intervals per half-section before giving up.
const MAX_INTERVALS: usize = 4096;

/// Most vertices of a polyline: far more than any sensible accuracy needs (a 25 mm ball at the
/// full width and 10⁻⁷ mm needs 25 000), few enough to refuse an accuracy far below the tool's
/// own rounding before memory runs out.
const MAX_POINTS: usize = 2_000_000;

/// Initial pieces per half-section, for the polyline and the quadrature alike: a floor on the
/// sampling so that neither accepts a chord on the strength of one lucky midpoint.
const INITIAL_PIECES: usize = 4;

/// Why a cusp cannot be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CuspError {
    /// A number that must be positive is not (or is not finite).
    #[error("{name} must be a finite number greater than 0, got {value}")]
    NotPositive {
        /// What the number is.
        name: &'static str,
        /// Its value.
        value: f64,
    },
    /// A number that must not be negative is (or is not finite).
    #[error("{name} must be a finite number at least 0, got {value}")]
    Negative {
        /// What the number is.
        name: &'static str,
        /// Its value.
        value: f64,
    },
    /// The passes are further apart than the tool is wide: stock stands uncut between them.
    #[error(
        "stepover {stepover} mm is wider than the tool ({width} mm across): the passes leave \
         uncut stock between them, not a cusp"
    )]
    TooWide {
        /// The stepover, mm.
        stepover: f64,
        /// The tool's diameter, mm.
        width: f64,
    },
    /// The tool has no material on its axis, so it cuts no floor under its centre.
    #[error("the tool has no material on its axis: it cuts no floor under the pass centre")]
    MissesAxis,
    /// The tool reports a height that is not a number.
    #[error("the tool's lowest height at radius {rho} mm is {value}, not a finite number")]
    NotFinite {
        /// The radius, mm.
        rho: f64,
        /// What the tool returned.
        value: f64,
    },
    /// No pass reaches the point: the stock is uncut there.
    #[error("neither pass reaches x = {x} mm: the stock is uncut there")]
    Uncut {
        /// Distance from the first pass's centre, mm.
        x: f64,
    },
    /// The tool's lowest height falls outward, so its section by the observer plane is not its
    /// meridian outline (a straight pass cuts deeper beside the axis plane than in it).
    #[error(
        "the tool's tip surface falls outward near radius {rho} mm: a straight pass's section \
         is not its meridian outline, and the floor is not at its tip"
    )]
    NotRisingOutward {
        /// Where the fall was seen, mm from the axis.
        rho: f64,
    },
    /// An adaptive step could not reach its accuracy.
    #[error("the {what} did not reach its accuracy near x = {x} mm")]
    NotConverged {
        /// The polyline or the quadrature.
        what: &'static str,
        /// Where, mm from the first pass's centre.
        x: f64,
    },
    /// The accuracy asked for needs more vertices than [`section`] will make.
    #[error("an accuracy of {accuracy} mm needs more than {limit} vertices; ask for less")]
    TooManyPoints {
        /// The accuracy asked for, mm.
        accuracy: f64,
        /// The most vertices made.
        limit: usize,
    },
    /// A paper equation used outside the range its derivation covers.
    #[error("Eq. {equation} does not apply: {why}")]
    OutsideEquation {
        /// The equation's number.
        equation: u8,
        /// Why not.
        why: &'static str,
    },
}

fn positive(name: &'static str, value: f64) -> Result<f64, CuspError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(CuspError::NotPositive { name, value })
    }
}

fn non_negative(name: &'static str, value: f64) -> Result<f64, CuspError> {
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err(CuspError::Negative { name, value })
    }
}

/// The cusp between two adjacent passes, as heights and areas in the plane across them.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Cusp {
    /// Height of the cusp's peak above the floor, mm.
    pub height: f64,
    /// Area between the machined surface and the floor from one pass's centre to the cusp's
    /// peak midway between the passes (the paper's σ_h), mm². Half of [`Cusp::area`]: both
    /// passes cut with the same tool, so the section is symmetric about its midpoint.
    pub half_area: f64,
    /// Area between the machined surface and the floor from one pass's centre to the next, mm².
    pub area: f64,
}

impl Cusp {
    /// The volume left between the passes over a length `length` of them, mm³: the area times
    /// the length, because a straight pass leaves the same section all along.
    pub fn volume(&self, length: f64) -> Result<f64, CuspError> {
        Ok(self.area * non_negative("pass length", length)?)
    }
}

/// The machined section between two passes, as the engine measures it.
#[derive(Debug, Clone, PartialEq)]
pub struct CuspSection {
    /// The stepover, mm.
    pub stepover: f64,
    /// The floor: the tool's lowest height, on its axis, in the tool's own h frame, mm.
    pub floor: f64,
    /// The polyline's accuracy, mm: every point of the envelope between the passes lies within
    /// this distance of the polyline, and every chord within it of the envelope (see
    /// [`section`] for what guarantees it).
    pub accuracy: f64,
    /// The machined surface from the first pass's centre (x = 0) to the second's (x = s):
    /// vertices (x, z) with z the height above the floor, each on the envelope.
    pub points: Vec<DVec2>,
    /// The highest vertex between the passes: its z is the cusp height.
    pub peak: DVec2,
    /// Height and areas: the height from [`CuspSection::peak`], the areas by adaptive
    /// Gauss–Kronrod quadrature of the envelope itself (not of the polyline).
    pub cusp: Cusp,
    /// The quadrature's error estimate for [`Cusp::area`], mm²: the sum over its intervals of
    /// |K15 − G7|, or for a piece made by bisection half the change the bisection made if that
    /// is larger (which keeps it honest at a corner arc's join with its flat, where the
    /// integrand's curvature jumps). It is at most [`AREA_RELATIVE_ACCURACY`] of the area,
    /// unless intervals reached the integrand's own rounding first (16 ε × (tool radius +
    /// |floor| + height) × width: a tool computes its heights to about ε × its radius), as at
    /// vanishing stepovers, where the area itself is as small as that rounding. For a smooth
    /// integrand |K15 − G7| overstates the Kronrod result's error by orders of magnitude.
    ///
    /// It bounds the quadrature, not the tool: the heights the tool reports carry its own
    /// rounding (about ε × r for a ball's r − √(r² − ρ²)), which can move the area by up to
    /// about 4 ε × r × s: relatively 10⁻¹⁵ at the full width, 10⁻¹² at s = 2r/100 and 10⁻⁹ at
    /// s = 2r/1000, where it is the larger of the two.
    pub area_error: f64,
}

impl CuspSection {
    /// The volume left between the passes over a length `length`, mm³ ([`Cusp::volume`]).
    pub fn volume(&self, length: f64) -> Result<f64, CuspError> {
        self.cusp.volume(length)
    }

    /// The polyline's own area above the floor (trapezoids), mm²: a second route to the cusp
    /// area, within [`CuspSection::polyline_area_bound`] of it.
    pub fn polyline_area(&self) -> f64 {
        self.points
            .windows(2)
            .map(|w| 0.5 * (w[1].x - w[0].x) * (w[0].y + w[1].y))
            .sum()
    }

    /// How far [`CuspSection::polyline_area`] can be from the envelope's area, mm²: between a
    /// chord and a convex or concave piece of the envelope lies a region no wider than the
    /// accuracy across the chord, so at most the accuracy times the polyline's length.
    pub fn polyline_area_bound(&self) -> f64 {
        self.accuracy
            * self
                .points
                .windows(2)
                .map(|w| (w[1] - w[0]).length())
                .sum::<f64>()
    }
}

/// The lower envelope of the two passes' sections.
struct Envelope<'a, T: Revolved + ?Sized> {
    tool: &'a T,
    stepover: f64,
    floor: f64,
}

impl<T: Revolved + ?Sized> Envelope<'_, T> {
    /// The lowest height of the tool at radius ρ, if it reaches ρ.
    fn lowest(&self, rho: f64) -> Result<Option<f64>, CuspError> {
        match self.tool.span_at(rho) {
            None => Ok(None),
            Some((lo, _)) if lo.is_finite() => Ok(Some(lo)),
            Some((lo, _)) => Err(CuspError::NotFinite { rho, value: lo }),
        }
    }

    /// Height of the machined surface above the floor at x.
    fn height(&self, x: f64) -> Result<f64, CuspError> {
        let a = self.lowest(x.abs())?;
        let b = self.lowest((x - self.stepover).abs())?;
        let lo = match (a, b) {
            (Some(a), Some(b)) => a.min(b),
            (Some(v), None) | (None, Some(v)) => v,
            (None, None) => return Err(CuspError::Uncut { x }),
        };
        Ok(lo - self.floor)
    }
}

/// The machined section between two straight passes of `tool` a `stepover` apart (mm), as a
/// polyline within `accuracy` (mm) of the envelope, with the cusp height and areas.
///
/// Generic over any [`Revolved`] tool: only its [`Revolved::span_at`] is used. The tool's tip
/// surface must rise outward (see the module docs); the engine checks this at every vertex of
/// the polyline and refuses the tool otherwise.
///
/// The polyline has vertices at both pass centres and at the midpoint, where the two passes'
/// sections cross (the cusp's peak, a kink). Each half is split into a few equal chords, and a
/// chord is bisected until the envelope's distance from it at the chord's midpoint and quarter
/// points is at most half the accuracy. Where the envelope is convex or concave along the
/// chord, as every end mill's tip outline is, the distance from the chord is a concave function
/// vanishing at both ends, so it is nowhere more than twice its value at the midpoint: within
/// the accuracy. Distances are measured perpendicular to the chord, so steep stretches (a ball
/// at a stepover of its diameter meets the other pass vertically) are resolved in a few
/// bisections.
///
/// The height is the highest vertex's, which for a tip rising outward is the midpoint's: the
/// envelope there, exactly (and were a dip to hide between the checked vertices, the true
/// highest point would still be no more than the accuracy above it). The areas are integrated
/// from the envelope, not the polyline (see [`CuspSection::area_error`]).
pub fn section<T: Revolved + ?Sized>(
    tool: &T,
    stepover: f64,
    accuracy: f64,
) -> Result<CuspSection, CuspError> {
    let s = non_negative("stepover", stepover)?;
    let accuracy = positive("accuracy", accuracy)?;
    let reach = positive("tool radius", tool.max_radius())?;
    if s > 2.0 * reach {
        return Err(CuspError::TooWide {
            stepover: s,
            width: 2.0 * reach,
        });
    }
    let floor = match tool.span_at(0.0) {
        None => return Err(CuspError::MissesAxis),
        Some((lo, _)) if lo.is_finite() => lo,
        Some((lo, _)) => {
            return Err(CuspError::NotFinite {
                rho: 0.0,
                value: lo,
            })
        }
    };
    let envelope = Envelope {
        tool,
        stepover: s,
        floor,
    };
    if s == 0.0 {
        let origin = DVec2::ZERO;
        return Ok(CuspSection {
            stepover: s,
            floor,
            accuracy,
            points: vec![origin],
            peak: origin,
            cusp: Cusp {
                height: 0.0,
                half_area: 0.0,
                area: 0.0,
            },
            area_error: 0.0,
        });
    }

    // The polyline, half by half, the midpoint a vertex of both.
    let mid = 0.5 * s;
    let mut points = vec![DVec2::new(0.0, envelope.height(0.0)?)];
    for (a, b) in [(0.0, mid), (mid, s)] {
        for k in 0..INITIAL_PIECES {
            let x0 = a + (b - a) * k as f64 / INITIAL_PIECES as f64;
            let x1 = if k + 1 == INITIAL_PIECES {
                b
            } else {
                a + (b - a) * (k + 1) as f64 / INITIAL_PIECES as f64
            };
            let p0 = DVec2::new(x0, envelope.height(x0)?);
            let p1 = DVec2::new(x1, envelope.height(x1)?);
            refine(&envelope, p0, p1, accuracy, 0, &mut points)?;
        }
    }

    // The tip must rise outward: the envelope may not fall from a pass centre towards the
    // midpoint (nor dip below the floor), up to rounding of the tool's heights.
    let scale = reach + floor.abs() + points.iter().fold(0.0f64, |m, p| m.max(p.y.abs()));
    let slack = 16.0 * f64::EPSILON * scale;
    let mut previous = 0.0;
    for p in points.iter().take_while(|p| p.x <= mid) {
        if p.y < previous - slack {
            return Err(CuspError::NotRisingOutward { rho: p.x });
        }
        previous = previous.max(p.y);
    }
    let mut previous = 0.0;
    for p in points.iter().rev().take_while(|p| p.x >= mid) {
        if p.y < previous - slack {
            return Err(CuspError::NotRisingOutward { rho: s - p.x });
        }
        previous = previous.max(p.y);
    }

    let peak = points
        .iter()
        .copied()
        .fold(points[0], |best, p| if p.y > best.y { p } else { best });

    // The areas, from the envelope itself: each half separately, the kink at the midpoint
    // being an end of both.
    let f = |x: f64| envelope.height(x);
    let (left, left_error) = integrate(&f, 0.0, mid, reach + floor.abs())?;
    let (right, right_error) = integrate(&f, mid, s, reach + floor.abs())?;
    let area = left + right;

    Ok(CuspSection {
        stepover: s,
        floor,
        accuracy,
        points,
        peak,
        cusp: Cusp {
            height: peak.y,
            half_area: 0.5 * area,
            area,
        },
        area_error: left_error + right_error,
    })
}

/// Bisect the chord p0–p1 until the envelope is within `accuracy` of it (see [`section`]);
/// pushes the vertices after p0, up to and including p1.
fn refine<T: Revolved + ?Sized>(
    envelope: &Envelope<'_, T>,
    p0: DVec2,
    p1: DVec2,
    accuracy: f64,
    depth: u32,
    out: &mut Vec<DVec2>,
) -> Result<(), CuspError> {
    let chord = p1 - p0;
    let length = chord.length();
    let off = |p: DVec2| {
        if length > 0.0 {
            chord.perp_dot(p - p0).abs() / length
        } else {
            (p - p0).length()
        }
    };
    let at = |t: f64| -> Result<DVec2, CuspError> {
        let x = p0.x + t * chord.x;
        Ok(DVec2::new(x, envelope.height(x)?))
    };
    let middle = at(0.5)?;
    let within = off(middle) <= 0.5 * accuracy
        && off(at(0.25)?) <= 0.5 * accuracy
        && off(at(0.75)?) <= 0.5 * accuracy;
    // A chord narrower than the doubles can split is as fine as the envelope can be sampled.
    if within || middle.x <= p0.x || middle.x >= p1.x {
        out.push(p1);
        return Ok(());
    }
    if out.len() >= MAX_POINTS {
        return Err(CuspError::TooManyPoints {
            accuracy,
            limit: MAX_POINTS,
        });
    }
    if depth >= MAX_DEPTH {
        return Err(CuspError::NotConverged {
            what: "section polyline",
            x: middle.x,
        });
    }
    refine(envelope, p0, middle, accuracy, depth + 1, out)?;
    refine(envelope, middle, p1, accuracy, depth + 1, out)
}

/// Gauss–Kronrod 7–15 abscissae on [−1, 1] (the non-negative half; QUADPACK's qk15).
const XGK: [f64; 8] = [
    0.9914553711208126,
    0.9491079123427585,
    0.8648644233597691,
    0.7415311855993945,
    0.5860872354676911,
    0.4058451513773972,
    0.20778495500789848,
    0.0,
];
/// Kronrod weights for [`XGK`].
const WGK: [f64; 8] = [
    0.022935322010529224,
    0.06309209262997856,
    0.10479001032225019,
    0.14065325971552592,
    0.1690047266392679,
    0.19035057806478542,
    0.20443294007529889,
    0.20948214108472782,
];
/// Gauss weights for the odd-indexed [`XGK`] (the 7-point Gauss rule's abscissae).
const WG: [f64; 4] = [
    0.1294849661688697,
    0.27970539148927664,
    0.3818300505051189,
    0.4179591836734694,
];

/// One interval of the adaptive quadrature.
#[derive(Debug, Clone, Copy)]
struct Piece {
    a: f64,
    b: f64,
    /// The Kronrod estimate of the integral over [a, b].
    value: f64,
    /// Its error estimate.
    error: f64,
    /// The integrand's own rounding over [a, b]: no bisection gets the error below this.
    noise: f64,
}

/// One Gauss–Kronrod 7–15 step over [a, b]. The error estimate is |K15 − G7|, except where the
/// fifteen nodes all see one value while the ends of the interval differ: a change confined
/// between the outermost nodes and the ends (a corner arc just starting at the end of a piece)
/// that neither rule sees, then estimated by the whole rise times the width. `scale` is the
/// height scale of the integrand's rounding (see [`CuspSection::area_error`]).
fn gk15(
    f: &impl Fn(f64) -> Result<f64, CuspError>,
    a: f64,
    b: f64,
    scale: f64,
) -> Result<Piece, CuspError> {
    let centre = 0.5 * (a + b);
    let half = 0.5 * (b - a);
    let fc = f(centre)?;
    let mut kronrod = WGK[7] * fc;
    let mut gauss = WG[3] * fc;
    let (mut low, mut high) = (fc, fc);
    for j in 0..7 {
        let dx = half * XGK[j];
        let (f0, f1) = (f(centre - dx)?, f(centre + dx)?);
        low = low.min(f0).min(f1);
        high = high.max(f0).max(f1);
        kronrod += WGK[j] * (f0 + f1);
        if j % 2 == 1 {
            gauss += WG[j / 2] * (f0 + f1);
        }
    }
    let mut error = ((kronrod - gauss) * half).abs();
    if low == high {
        let (fa, fb) = (f(a)?, f(b)?);
        if fa != low || fb != low {
            error = error.max((fb - fa).abs().max((fa - low).abs()) * (b - a));
        }
    }
    Ok(Piece {
        a,
        b,
        value: kronrod * half,
        error,
        noise: 16.0 * f64::EPSILON * (scale + high.abs().max(low.abs())) * (b - a),
    })
}

/// Global adaptive Gauss–Kronrod quadrature of f over [a, b]: bisect the interval with the
/// largest error estimate, among those still above their own rounding, until the estimates sum
/// to at most [`AREA_RELATIVE_ACCURACY`] of the integral or every interval is at its rounding.
/// A piece's estimate is its |K15 − G7|, or half the change its bisection made to its parent's
/// value if that is larger. Returns the integral and the summed estimate.
fn integrate(
    f: &impl Fn(f64) -> Result<f64, CuspError>,
    a: f64,
    b: f64,
    scale: f64,
) -> Result<(f64, f64), CuspError> {
    let mut parts = Vec::with_capacity(64);
    for k in 0..INITIAL_PIECES {
        let x0 = a + (b - a) * k as f64 / INITIAL_PIECES as f64;
        let x1 = if k + 1 == INITIAL_PIECES {
            b
        } else {
            a + (b - a) * (k + 1) as f64 / INITIAL_PIECES as f64
        };
        parts.push(gk15(f, x0, x1, scale)?);
    }
    loop {
        let total = neumaier(parts.iter().map(|p| p.value));
        let error = neumaier(parts.iter().map(|p| p.error));
        if error <= AREA_RELATIVE_ACCURACY * total.abs() {
            return Ok((total, error));
        }
        let worst = parts
            .iter()
            .enumerate()
            .filter(|(_, p)| p.error > p.noise)
            .max_by(|(_, p), (_, q)| p.error.total_cmp(&q.error))
            .map(|(i, _)| i);
        let Some(worst) = worst else {
            // Every interval is at the integrand's own rounding: as good as it gets.
            return Ok((total, error));
        };
        let parent = parts[worst];
        let xm = 0.5 * (parent.a + parent.b);
        if parts.len() >= MAX_INTERVALS || xm <= parent.a || xm >= parent.b {
            return Err(CuspError::NotConverged {
                what: "area quadrature",
                x: xm,
            });
        }
        let mut left = gk15(f, parent.a, xm, scale)?;
        let mut right = gk15(f, xm, parent.b, scale)?;
        // What bisecting changed is the parent's error; where the integrand is not smooth
        // (a corner arc leaving its flat: a jump in curvature) it can exceed |K15 − G7|, and
        // the child holding the join keeps at most half of it (an eighth for a curvature jump,
        // a quarter for a kink, a half for a step).
        let change = (parent.value - (left.value + right.value)).abs();
        left.error = left.error.max(0.5 * change);
        right.error = right.error.max(0.5 * change);
        parts[worst] = left;
        parts.push(right);
    }
}

/// Compensated (Neumaier) sum: thousands of interval contributions without losing the last
/// digits the relative accuracy asks for.
fn neumaier(values: impl Iterator<Item = f64>) -> f64 {
    let (mut sum, mut compensation) = (0.0f64, 0.0f64);
    for v in values {
        let t = sum + v;
        compensation += if sum.abs() >= v.abs() {
            (sum - t) + v
        } else {
            (v - t) + sum
        };
        sum = t;
    }
    sum + compensation
}

/// α − sin α without the cancellation of the direct difference for small α (a series there).
fn alpha_minus_sin(alpha: f64) -> f64 {
    if alpha >= 1.0 {
        return alpha - alpha.sin();
    }
    // α³/3! − α⁵/5! + α⁷/7! − …: at α < 1 the terms fall by α²/((2k+2)(2k+3)) each.
    let a2 = alpha * alpha;
    let mut term = alpha * a2 / 6.0;
    let mut sum = 0.0f64;
    let mut k = 1.0;
    while term.abs() > 1e-18 * sum.abs() && k < 30.0 {
        sum += term;
        term *= -a2 / ((2.0 * k + 2.0) * (2.0 * k + 3.0));
        k += 1.0;
    }
    sum
}

/// The cusp of a circular arc of radius `r` whose lowest point lies `c` (0 ≤ c ≤ r) across from
/// the cusp's peak: the ball's closed forms of the module docs, in the digit-keeping form.
fn arc_cusp(r: f64, c: f64) -> Cusp {
    let c = c.clamp(0.0, r);
    let w = ((r - c) * (r + c)).sqrt();
    // r − √(r² − c²) without the cancellation.
    let height = c * c / (r + w);
    let alpha = c.atan2(w);
    let half_area = 0.5 * (c * height - r * r * alpha_minus_sin(alpha));
    Cusp {
        height,
        half_area,
        area: 2.0 * half_area,
    }
}

/// The cusp a ball end mill leaves at stepover `stepover` (mm), from the closed forms: height
/// r − √(r² − (s/2)²), half-area r·c − c·√(r² − c²)/2 − r²·asin(c/r)/2 with c = s/2.
pub fn ball_cusp(tool: &BallEnd, stepover: f64) -> Result<Cusp, CuspError> {
    let r = positive("ball radius", tool.radius)?;
    let s = non_negative("stepover", stepover)?;
    if s > 2.0 * r {
        return Err(CuspError::TooWide {
            stepover: s,
            width: 2.0 * r,
        });
    }
    Ok(arc_cusp(r, 0.5 * s))
}

/// The cusp a corner-radius end mill leaves at stepover `stepover` (mm), from the closed
/// forms: nothing while s ≤ 2·r1 (the flats overlap), otherwise the cusp of a ball of radius
/// r2 at stepover s − 2·r1 (the two corner arcs meet s/2 − r1 out from where each leaves its
/// flat).
pub fn corner_radius_cusp(tool: &CornerRadius, stepover: f64) -> Result<Cusp, CuspError> {
    let r1 = non_negative("flat radius", tool.flat)?;
    let r2 = positive("corner radius", tool.corner)?;
    let s = non_negative("stepover", stepover)?;
    if s > 2.0 * (r1 + r2) {
        return Err(CuspError::TooWide {
            stepover: s,
            width: 2.0 * (r1 + r2),
        });
    }
    Ok(arc_cusp(r2, (0.5 * s - r1).max(0.0)))
}

/// Seed 003's cusp equations (Matei & Blebea, §2.3) as printed, their symbols tied to the
/// tools, and corrected.
///
/// The figures are missing; the symbols are read from the equations.
///
/// # Ball end mill (Eqs. 24–28)
///
/// r is the ball's radius and h the cusp's height: Eq. 11, r_c² = r² − (r − h)², is where the
/// ball's arc z = r − √(r² − x²) reaches height h, so r_c is the half-stepover s/2. The
/// half-cusp σ_h is {0 ≤ x ≤ r_c, 0 ≤ z ≤ r − √(r² − x²)}, inside the rectangle r_c × h;
/// Eq. 25 takes it as that rectangle less its complement Ω_c, the cap between the arc and
/// z = h:
///
/// ```text
/// |Ω_c| = ∫₀^{r_c} (h − r + √(r² − x²)) dx = (r²·asin(r_c/r) − (r − h)·r_c) / 2
/// σ_h   = h·r_c − |Ω_c|                    = (r·r_c + h·r_c − r²·asin(r_c/r)) / 2
/// ```
///
/// Eq. 27 prints (π·r_c² + h·r_c − r²·asin(r_c/r)) / 2: its first term, π·r_c², should be
/// r·r_c; the other two are right. (Eq. 26's inner bounds, −x to √(r_c² − x²), a circle of
/// radius r_c about the pass centre, describe Ω_c no better: Ω_c is bounded by the ball's arc
/// of radius r, centred r above the floor.) So Eq. 27 is negative while r_c < 0.308·r (it
/// tends to (π·r_c − r)·r_c / 2 as r_c → 0), and exceeds the rectangle r_c × h that holds
/// the half-cusp once r_c > 0.345·r (at s = 2r it gives (1 + π/2)·r²/2 against the rectangle's
/// r², the true value being (1 − π/4)·r²); only in between is it even possible, and it is
/// right only at r_c = r/π, where π·r_c² = r·r_c. Eq. 28 is 2L times
/// Eq. 27 (both halves over a length L) and inherits the term: the volume is
/// L·(r·r_c + h·r_c − r²·asin(r_c/r)).
///
/// # Corner-radius end mill (Eqs. 21–23)
///
/// Eq. 21's integrand a ± √(a² − (x − a)²) is a circle of radius a about (a, a): a is the
/// corner radius r2, and the circle touches x = 0 and the floor y = 0, so x runs inward from
/// the tool's periphery (the cylinder of radius r1 + r2) and the corner meets the flat floor
/// at x = a. The half-cusp runs from its peak, midway between the passes, to that point; the
/// lower limit h is therefore where the peak is: h = r1 + r2 − s/2, the distance from the
/// periphery to the midpoint (half the overlap of the two passes' footprints), and a − h =
/// s/2 − r1 is the half-cusp's width. (Here h is a horizontal distance, not the height that
/// Eq. 11 calls h: it is a limit of an integral over x.) The material left is under the
/// corner's lower half, y = a − √(a² − (x − a)²); Eq. 21 integrates the upper half,
/// a + √(a² − (x − a)²): the rectangle a × (a − h) plus the circular piece
/// K = ∫ₕᵃ √(a² − (x − a)²) dx above it, where the half-cusp is that rectangle less K. Eq. 22
/// evaluates Eq. 21 correctly and so carries the wrong sign on both circle terms (they are K);
/// the half-cusp is
///
/// ```text
/// σ_h = a(a − h) − a(a − h)/2 · √(1 − ((a − h)/a)²) − a²/2 · asin((a − h)/a)
/// ```
///
/// and the printed and correct values always sum to 2·a·(a − h). The printed value is at least
/// the rectangle a × (a − h), which is larger than the rectangle (a − h) × cusp height holding
/// the half-cusp whenever there is a cusp (the cusp is never higher than the corner radius).
/// Eq. 23 is 2L times Eq. 22 and inherits the sign: the volume is
/// L·[2a(a − h) − a(a − h)·√(1 − ((a − h)/a)²) − a²·asin((a − h)/a)]. Reading h as the cusp's
/// height instead does not rescue Eq. 21 even with its sign fixed: it then gives the area
/// between the corner arc and the tool's cylinder above height h, the half-cusp's mirror
/// image across the quarter circle's diagonal, equal to it only at a half-width of a/√2.
pub mod paper {
    use super::{ball_cusp, non_negative, CuspError};
    use crate::papers::tool::{BallEnd, CornerRadius};

    /// Eqs. 21–23's symbols for a corner-radius mill.
    #[derive(Debug, Clone, Copy, PartialEq)]
    pub struct CornerSymbols {
        /// a: the corner radius r2, mm.
        pub a: f64,
        /// h: the distance from the tool's periphery to the midpoint between the passes,
        /// r1 + r2 − s/2, mm; a − h is the half-cusp's width.
        pub h: f64,
    }

    impl CornerSymbols {
        /// The symbols for `tool` at stepover `stepover` (mm). h exceeds a when the flats
        /// overlap (s < 2·r1): no cusp, and outside Eq. 21's range.
        pub fn for_tool(tool: &CornerRadius, stepover: f64) -> Result<Self, CuspError> {
            super::corner_radius_cusp(tool, stepover)?;
            Ok(CornerSymbols {
                a: tool.corner,
                h: tool.flat + tool.corner - 0.5 * stepover,
            })
        }

        /// The half-cusp's width a − h, refusing symbols outside Eq. 21's range
        /// (a > 0, 0 ≤ h ≤ a: the corner arcs overlap).
        fn width(&self, equation: u8) -> Result<f64, CuspError> {
            super::positive("a (corner radius)", self.a)?;
            non_negative("h", self.h)?;
            if self.h > self.a {
                return Err(CuspError::OutsideEquation {
                    equation,
                    why: "h > a: the flats overlap, there is no cusp to integrate from h to a",
                });
            }
            Ok(self.a - self.h)
        }

        /// Eq. 22 as printed: a(a − h)/2·√(1 − ((a − h)/a)²) + a(a − h) + a²/2·asin((a − h)/a),
        /// the area under the corner circle's upper half (wrong; see the [module](self) docs).
        pub fn eq22(&self) -> Result<f64, CuspError> {
            let (a, d) = (self.a, self.width(22)?);
            let q = d / a;
            Ok(a * d / 2.0 * (1.0 - q * q).sqrt() + a * d + a * a / 2.0 * q.asin())
        }

        /// Eq. 23 as printed: the volume over a length `length`, 2L times Eq. 22.
        pub fn eq23(&self, length: f64) -> Result<f64, CuspError> {
            let (a, d) = (self.a, self.width(23)?);
            let length = non_negative("pass length", length)?;
            let q = d / a;
            Ok(length * (a * d * (1.0 - q * q).sqrt() + 2.0 * a * d + a * a * q.asin()))
        }

        /// Eq. 22 corrected: the half-cusp under the lower half of the corner circle,
        /// a(a − h) − a(a − h)/2·√(1 − ((a − h)/a)²) − a²/2·asin((a − h)/a); zero when the
        /// flats overlap (h ≥ a). Evaluated as printed, it loses digits to cancellation for
        /// half-widths a − h much below a (use [`super::corner_radius_cusp`] there).
        pub fn eq22_corrected(&self) -> Result<f64, CuspError> {
            let a = super::positive("a (corner radius)", self.a)?;
            let d = (a - non_negative("h", self.h)?).max(0.0);
            let q = d / a;
            Ok(a * d - a * d / 2.0 * (1.0 - q * q).sqrt() - a * a / 2.0 * q.asin())
        }

        /// Eq. 23 corrected: 2L times the corrected Eq. 22.
        pub fn eq23_corrected(&self, length: f64) -> Result<f64, CuspError> {
            Ok(2.0 * non_negative("pass length", length)? * self.eq22_corrected()?)
        }
    }

    /// Eqs. 24–28's symbols for a ball end mill.
    #[derive(Debug, Clone, Copy, PartialEq)]
    pub struct BallSymbols {
        /// r: the ball's radius, mm.
        pub r: f64,
        /// r_c: by Eq. 11, √(r² − (r − h)²): the half-stepover, mm.
        pub r_c: f64,
        /// h: the cusp's height, mm.
        pub h: f64,
    }

    impl BallSymbols {
        /// The symbols for `tool` at stepover `stepover` (mm): r_c = s/2 and h the cusp height.
        pub fn for_tool(tool: &BallEnd, stepover: f64) -> Result<Self, CuspError> {
            let cusp = ball_cusp(tool, stepover)?;
            Ok(BallSymbols {
                r: tool.radius,
                r_c: 0.5 * stepover,
                h: cusp.height,
            })
        }

        /// The symbols from r and h, r_c by Eq. 11 (0 ≤ h ≤ r).
        pub fn from_r_h(r: f64, h: f64) -> Result<Self, CuspError> {
            let r = super::positive("r (ball radius)", r)?;
            let h = non_negative("h (cusp height)", h)?;
            if h > r {
                return Err(CuspError::OutsideEquation {
                    equation: 11,
                    why: "h > r: the cusp of a ball is never higher than its radius",
                });
            }
            Ok(BallSymbols {
                r,
                r_c: (h * (2.0 * r - h)).sqrt(),
                h,
            })
        }

        fn check(&self, equation: u8) -> Result<(), CuspError> {
            super::positive("r (ball radius)", self.r)?;
            non_negative("r_c", self.r_c)?;
            non_negative("h (cusp height)", self.h)?;
            if self.r_c > self.r || self.h > self.r {
                return Err(CuspError::OutsideEquation {
                    equation,
                    why: "r_c or h exceeds r: the passes do not meet on the ball",
                });
            }
            Ok(())
        }

        /// Eq. 27 as printed: (π·r_c² + h·r_c − r²·asin(r_c/r)) / 2 (wrong; see the
        /// [module](self) docs).
        pub fn eq27(&self) -> Result<f64, CuspError> {
            self.check(27)?;
            let (r, rc, h) = (self.r, self.r_c, self.h);
            Ok(0.5 * (std::f64::consts::PI * rc * rc + h * rc - r * r * (rc / r).asin()))
        }

        /// Eq. 28 as printed: L·(π·r_c² + h·r_c − r²·asin(r_c/r)), 2L times Eq. 27.
        pub fn eq28(&self, length: f64) -> Result<f64, CuspError> {
            self.check(28)?;
            let length = non_negative("pass length", length)?;
            let (r, rc, h) = (self.r, self.r_c, self.h);
            Ok(length * (std::f64::consts::PI * rc * rc + h * rc - r * r * (rc / r).asin()))
        }

        /// Eq. 27 corrected: (r·r_c + h·r_c − r²·asin(r_c/r)) / 2. Evaluated as printed, it
        /// loses digits to cancellation for r_c much below r (use [`super::ball_cusp`] there).
        pub fn eq27_corrected(&self) -> Result<f64, CuspError> {
            self.check(27)?;
            let (r, rc, h) = (self.r, self.r_c, self.h);
            Ok(0.5 * (r * rc + h * rc - r * r * (rc / r).asin()))
        }

        /// Eq. 28 corrected: L·(r·r_c + h·r_c − r²·asin(r_c/r)).
        pub fn eq28_corrected(&self, length: f64) -> Result<f64, CuspError> {
            Ok(2.0 * non_negative("pass length", length)? * self.eq27_corrected()?)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::paper::{BallSymbols, CornerSymbols};
    use super::*;
    use crate::papers::tool::{FlatEnd, Paraboloid, Torus};
    use proptest::prelude::*;
    use std::f64::consts::PI;

    const ACCURACY: f64 = 1e-7;

    /// |a − b| ≤ rel·|b|, or both within `floor` of each other (for true zeros).
    fn close(a: f64, b: f64, rel: f64, floor: f64) -> bool {
        (a - b).abs() <= rel * b.abs() || (a - b).abs() <= floor
    }

    /// Stepovers as fractions of the ball's diameter: from vanishing to the full width.
    /// (Below 10⁻³ the tool's own rounding of r − √(r² − ρ²), about ε·r, is more than 10⁻⁹
    /// of the area: see the vanishing-stepover test.)
    const FRACTIONS: [f64; 12] = [
        0.0, 1e-3, 3e-3, 0.01, 0.05, 0.1, 0.25, 0.5, 0.75, 0.9, 0.999, 1.0,
    ];

    #[test]
    fn gauss_kronrod_weights_integrate_polynomials_to_their_degrees() {
        // K15 is exact to degree 22, G7 to degree 13: on [0, 1] ∫ x^n = 1/(n + 1).
        for n in 0..=22 {
            let f = |x: f64| Ok(x.powi(n));
            let piece = gk15(&f, 0.0, 1.0, 1.0).unwrap();
            let (k, diff) = (piece.value, piece.error);
            assert!(
                (k - 1.0 / (n + 1) as f64).abs() < 1e-15,
                "K15 at degree {n}"
            );
            if n <= 13 {
                assert!(diff < 1e-15, "G7 at degree {n}: |K − G| {diff}");
            }
        }
        assert!(gk15(&|x: f64| Ok(x.powi(14)), 0.0, 1.0, 1.0).unwrap().error > 1e-10);
        // A rise hidden between the last node and the end of the interval is not missed.
        let step = |x: f64| Ok(if x > 0.999 { x - 0.999 } else { 0.0 });
        let piece = gk15(&step, 0.0, 1.0, 1.0).unwrap();
        assert_eq!(piece.value, 0.0);
        assert!(piece.error >= 1e-3);
        let (area, _) = integrate(&step, 0.0, 1.0, 1.0).unwrap();
        assert!((area - 0.5e-6).abs() <= 1e-12 * 0.5e-6);
    }

    #[test]
    fn ball_cusp_height_is_the_arc_at_half_the_stepover() {
        for r in [0.5, 3.0, 12.7] {
            let tool = BallEnd { radius: r };
            for q in FRACTIONS {
                let s = 2.0 * r * q;
                let section = section(&tool, s, ACCURACY).unwrap();
                let expected = r - (r * r - s * s / 4.0).sqrt();
                assert!(
                    (section.cusp.height - expected).abs() <= 1e-14 * r,
                    "r {r} s {s}: {} against {expected}",
                    section.cusp.height
                );
                if s > 0.0 {
                    assert_eq!(section.peak.x, s / 2.0, "the peak is midway");
                }
            }
        }
    }

    #[test]
    fn corner_radius_cusp_height_is_the_corner_arc_beyond_the_flat() {
        let tool = CornerRadius {
            flat: 2.0,
            corner: 1.0,
        };
        for s in [0.0, 1.0, 3.9, 4.0, 4.001, 4.5, 5.0, 5.5, 5.999, 6.0] {
            let section = section(&tool, s, ACCURACY).unwrap();
            let d: f64 = s / 2.0 - 2.0;
            let expected = if d <= 0.0 {
                0.0
            } else {
                1.0 - (1.0 - d * d).sqrt()
            };
            assert!(
                (section.cusp.height - expected).abs() <= 1e-14,
                "s {s}: {} against {expected}",
                section.cusp.height
            );
        }
    }

    #[test]
    fn ball_cusp_area_agrees_with_the_closed_forms_over_stepovers() {
        for r in [0.5, 3.0, 12.7] {
            let tool = BallEnd { radius: r };
            for q in FRACTIONS {
                let s = 2.0 * r * q;
                let engine = section(&tool, s, ACCURACY).unwrap();
                let closed = ball_cusp(&tool, s).unwrap();
                assert!(
                    close(engine.cusp.area, closed.area, 1e-9, 0.0),
                    "r {r} s {s}: engine {} closed {} (rel {:e})",
                    engine.cusp.area,
                    closed.area,
                    (engine.cusp.area / closed.area - 1.0).abs()
                );
                assert!(close(engine.cusp.half_area, closed.half_area, 1e-9, 0.0));
                assert!(
                    engine.area_error <= 1e-12 * engine.cusp.area.max(f64::MIN_POSITIVE)
                        || engine.area_error <= 16.0 * f64::EPSILON * 2.0 * r * s
                );
            }
        }
    }

    #[test]
    fn corner_radius_cusp_area_agrees_with_the_closed_forms_and_vanishes_while_flats_overlap() {
        // Dyadic radii: the tool puts its edge exactly at flat + corner only when
        // (flat + corner) − flat rounds back to the corner, and the sweep ends there.
        for (flat, corner) in [(2.0, 1.0), (0.25, 2.5), (5.0, 0.25)] {
            let tool = CornerRadius { flat, corner };
            let width = 2.0 * (flat + corner);
            for q in [0.0, 0.1, 0.5, 0.999, 1.0] {
                // Flats overlapping: s ≤ 2·r1, nothing left.
                let s = 2.0 * flat * q;
                let engine = section(&tool, s, ACCURACY).unwrap();
                assert_eq!(engine.cusp.area, 0.0, "flats overlap at s {s}");
                assert_eq!(engine.cusp.height, 0.0);
                assert_eq!(corner_radius_cusp(&tool, s).unwrap().area, 0.0);
            }
            for q in [1e-2, 0.05, 0.1, 0.3, 0.5, 0.7, 0.9, 0.999, 1.0] {
                let s = 2.0 * flat + q * (width - 2.0 * flat);
                let engine = section(&tool, s, ACCURACY).unwrap();
                let closed = corner_radius_cusp(&tool, s).unwrap();
                assert!(
                    close(engine.cusp.area, closed.area, 1e-9, 0.0),
                    "r1 {flat} r2 {corner} s {s}: engine {} closed {}",
                    engine.cusp.area,
                    closed.area
                );
                // The cusp is a ball's of radius r2 at stepover s − 2·r1.
                let ball = ball_cusp(&BallEnd { radius: corner }, s - 2.0 * flat).unwrap();
                assert!(close(closed.area, ball.area, 1e-12, 0.0));
                assert!(close(closed.height, ball.height, 1e-12, 0.0));
            }
        }
    }

    #[test]
    fn vanishing_stepovers_leave_the_parabola_s_cube_over_24_r_within_the_tools_rounding() {
        // Near its tip a ball of radius r is the parabola z = x²/(2r): the cusp area tends to
        // 2∫₀^{s/2} x²/(2r) dx = s³/(24r). The engine reads the tool's heights as
        // r − √(r² − ρ²), good to about ε·r, so its area is good to about ε·r·s.
        let r = 3.0;
        let tool = BallEnd { radius: r };
        for s in [1e-2, 1e-3, 1e-4, 1e-5, 1e-6] {
            let closed = ball_cusp(&tool, s).unwrap();
            let parabola = s * s * s / (24.0 * r);
            // The next term, 2∫₀^{s/2} x⁴/(8r³) dx, is 0.0375·(s/r)² of the first.
            assert!(close(
                closed.area,
                parabola,
                0.04 * (s / r).powi(2) + 1e-13,
                0.0
            ));
            let engine = section(&tool, s, ACCURACY).unwrap();
            assert!(
                (engine.cusp.area - closed.area).abs() <= 4.0 * f64::EPSILON * r * s,
                "s {s}: engine {} closed {}",
                engine.cusp.area,
                closed.area
            );
        }
        assert_eq!(
            section(&tool, 0.0, ACCURACY).unwrap().cusp,
            ball_cusp(&tool, 0.0).unwrap()
        );
    }

    #[test]
    fn closed_forms_meet_the_geometry_at_the_full_width() {
        // At s = 2r the half-cusp is the square r × r less the quarter disc.
        let r = 3.0;
        let full = ball_cusp(&BallEnd { radius: r }, 2.0 * r).unwrap();
        assert!(close(full.height, r, 1e-15, 0.0));
        assert!(close(full.half_area, r * r * (1.0 - PI / 4.0), 1e-14, 0.0));
        // And every half-cusp lies in the rectangle half-stepover × height, and within the
        // triangle under the chord from the pass centre to the peak (the arc is convex, so it
        // runs below that chord).
        for q in [1e-3, 0.1, 0.5, 0.9, 1.0] {
            let s = 2.0 * r * q;
            let c = ball_cusp(&BallEnd { radius: r }, s).unwrap();
            assert!(c.half_area <= s / 2.0 * c.height);
            assert!(c.half_area >= 0.0);
            assert!(c.half_area <= 0.5 * s / 2.0 * c.height);
        }
    }

    #[test]
    fn the_polyline_is_within_its_accuracy_across_accuracies() {
        let tools: [(&dyn Revolved, f64); 4] = [
            (&BallEnd { radius: 3.0 }, 6.0),
            (&BallEnd { radius: 3.0 }, 2.5),
            (
                &CornerRadius {
                    flat: 2.0,
                    corner: 1.0,
                },
                5.3,
            ),
            (
                &CornerRadius {
                    flat: 2.0,
                    corner: 1.0,
                },
                6.0,
            ),
        ];
        let truth = |tool: &dyn Revolved, s: f64, x: f64| {
            let u = x.min(s - x).max(0.0);
            tool.span_at(u).unwrap().0
        };
        for (tool, s) in tools {
            for accuracy in [1e-2, 1e-4, 1e-6, 1e-8, 1e-10] {
                let section = section(tool, s, accuracy).unwrap();
                let points = &section.points;
                assert_eq!(points[0].x, 0.0);
                assert_eq!(points[points.len() - 1].x, s);
                assert!(points.windows(2).all(|w| w[1].x > w[0].x));
                // Every sampled point of the envelope is within the accuracy of the polyline:
                // of the chord over it, or of a neighbour (an upper bound on the distance).
                for k in 0..=4000 {
                    let x = s * k as f64 / 4000.0;
                    let p = DVec2::new(x, truth(tool, s, x));
                    let i = points
                        .partition_point(|q| q.x <= x)
                        .clamp(1, points.len() - 1);
                    let distance = (i.saturating_sub(2)..(i + 1).min(points.len() - 1))
                        .map(|j| {
                            let (a, b) = (points[j], points[j + 1]);
                            let d = b - a;
                            let t = ((p - a).dot(d) / d.length_squared()).clamp(0.0, 1.0);
                            (a + t * d - p).length()
                        })
                        .fold(f64::INFINITY, f64::min);
                    assert!(
                        distance <= accuracy * (1.0 + 1e-6) + 1e-14,
                        "s {s} accuracy {accuracy}: {distance} at x {x}"
                    );
                }
                // The polyline's own area is within its bound of the envelope's.
                let exact = section.cusp.area;
                assert!(
                    (section.polyline_area() - exact).abs() <= section.polyline_area_bound(),
                    "accuracy {accuracy}: {} vs {exact}",
                    section.polyline_area()
                );
            }
        }
    }

    #[test]
    fn the_volume_per_pass_is_the_area_times_the_length() {
        let tool = BallEnd { radius: 3.0 };
        let engine = section(&tool, 2.2, ACCURACY).unwrap();
        let closed = ball_cusp(&tool, 2.2).unwrap();
        for length in [0.0, 1.0, 37.5, 1000.0] {
            let v = engine.volume(length).unwrap();
            assert!(close(v, closed.area * length, 1e-9, 0.0));
            assert!(close(
                engine.volume(2.0 * length).unwrap(),
                2.0 * v,
                1e-15,
                0.0
            ));
        }
        let corner = CornerRadius {
            flat: 2.0,
            corner: 1.0,
        };
        let engine = section(&corner, 5.0, ACCURACY).unwrap();
        let closed = corner_radius_cusp(&corner, 5.0).unwrap();
        assert!(close(
            engine.volume(12.0).unwrap(),
            12.0 * closed.area,
            1e-9,
            0.0
        ));
        assert!(matches!(
            engine.volume(-1.0),
            Err(CuspError::Negative { .. })
        ));
        assert!(matches!(
            engine.volume(f64::NAN),
            Err(CuspError::Negative { .. })
        ));
    }

    proptest! {
        /// Why the section is the meridian outline and the same all along a straight pass: a
        /// tool point at horizontal offset (dx, dy) from the axis is at radius √(dx² + dy²)
        /// ≥ |dx|, and the tip never sits lower further out, so the deepest cut at offset dx
        /// across the pass is the one in the axis plane (dy = 0), wherever along the pass.
        #[test]
        fn no_tool_point_off_the_axis_plane_cuts_deeper(
            dx in 0.0..3.0f64, dy in -3.0..3.0f64, flat in 0.0..2.0f64, corner in 0.1..2.0f64,
        ) {
            let tools: [&dyn Revolved; 3] = [
                &BallEnd { radius: 3.0 },
                &CornerRadius { flat, corner },
                &FlatEnd { radius: 3.0 },
            ];
            for tool in tools {
                let rho = dx.hypot(dy);
                if let (Some(on), Some(off)) = (tool.span_at(dx), tool.span_at(rho)) {
                    prop_assert!(off.0 >= on.0 - 1e-12);
                }
            }
        }

        /// The envelope is symmetric and the two halves hold the same area.
        #[test]
        fn sections_are_symmetric_and_bounded(r in 0.1..10.0f64, q in 0.0..1.0f64) {
            let tool = BallEnd { radius: r };
            let s = 2.0 * r * q;
            let section = section(&tool, s, 1e-6).unwrap();
            let c = section.cusp;
            prop_assert!(c.half_area >= 0.0);
            prop_assert!(c.half_area <= s / 2.0 * c.height * (1.0 + 1e-12));
            let points = &section.points;
            let n = points.len();
            for (a, b) in points.iter().zip(points.iter().rev()).take(n / 2) {
                prop_assert!((a.x - (s - b.x)).abs() <= 1e-12 * r);
                prop_assert!((a.y - b.y).abs() <= 1e-12 * r);
            }
        }
    }

    #[test]
    fn the_engine_takes_any_tool_through_the_trait() {
        // A flat end mill and the paraboloid (flat below, on h = 0) leave no cusp.
        let flat: &dyn Revolved = &FlatEnd { radius: 3.0 };
        let paraboloid: &dyn Revolved = &Paraboloid { a: -0.05, b: 7.2 };
        for (tool, width) in [(flat, 6.0), (paraboloid, 24.0)] {
            // (Not at the full width: the tools' own rounding may put their edge a hair short.)
            for s in [0.5, width / 2.0, 0.999 * width] {
                let section = section(tool, s, ACCURACY).unwrap();
                assert_eq!(section.cusp.area, 0.0);
                assert_eq!(section.cusp.height, 0.0);
            }
        }
        // A ring torus has no material on its axis; a spindle torus's tip surface falls
        // outward (lowest at ρ = R), so its pass section is not its meridian outline.
        let ring = Torus {
            ring: 3.0,
            nose: 1.0,
        };
        assert_eq!(section(&ring, 1.0, ACCURACY), Err(CuspError::MissesAxis));
        let spindle = Torus {
            ring: 0.5,
            nose: 1.0,
        };
        assert!(matches!(
            section(&spindle, 2.0, ACCURACY),
            Err(CuspError::NotRisingOutward { .. })
        ));
    }

    #[test]
    fn bad_input_is_refused() {
        let ball = BallEnd { radius: 3.0 };
        for s in [-1.0, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                section(&ball, s, ACCURACY),
                Err(CuspError::Negative { .. })
            ));
            assert!(matches!(
                ball_cusp(&ball, s),
                Err(CuspError::Negative { .. })
            ));
        }
        for accuracy in [0.0, -1.0, f64::NAN] {
            assert!(matches!(
                section(&ball, 1.0, accuracy),
                Err(CuspError::NotPositive { .. })
            ));
        }
        assert!(matches!(
            section(&ball, 6.01, ACCURACY),
            Err(CuspError::TooWide { .. })
        ));
        assert!(matches!(
            section(&BallEnd { radius: 25.0 }, 50.0, 1e-15),
            Err(CuspError::TooManyPoints { .. })
        ));
        assert!(matches!(
            ball_cusp(&ball, 6.01),
            Err(CuspError::TooWide { .. })
        ));
        for radius in [0.0, -3.0, f64::NAN] {
            let bad = BallEnd { radius };
            assert!(matches!(
                ball_cusp(&bad, 1.0),
                Err(CuspError::NotPositive { .. })
            ));
            assert!(section(&bad, 1.0, ACCURACY).is_err());
        }
        let bad = CornerRadius {
            flat: -1.0,
            corner: 1.0,
        };
        assert!(matches!(
            corner_radius_cusp(&bad, 1.0),
            Err(CuspError::Negative { .. })
        ));
        let bad = CornerRadius {
            flat: 1.0,
            corner: 0.0,
        };
        assert!(matches!(
            corner_radius_cusp(&bad, 1.0),
            Err(CuspError::NotPositive { .. })
        ));
        let tool = CornerRadius {
            flat: 2.0,
            corner: 1.0,
        };
        assert!(matches!(
            corner_radius_cusp(&tool, 6.5),
            Err(CuspError::TooWide { .. })
        ));
        assert!(BallSymbols::from_r_h(3.0, 3.5).is_err());
        assert!(BallSymbols::from_r_h(-3.0, 1.0).is_err());
    }

    // The paper: ball end mill, Eqs. 11 and 24–28.

    /// Stepovers, as fractions of the diameter, where the printed forms keep their digits.
    const PAPER_FRACTIONS: [f64; 8] = [0.05, 0.1, 0.25, 0.5, 0.75, 0.9, 0.999, 1.0];

    #[test]
    fn eq_11_makes_r_c_the_half_stepover_when_h_is_the_cusp_height() {
        for q in PAPER_FRACTIONS {
            let (r, s) = (3.0, 6.0 * q);
            let symbols = BallSymbols::for_tool(&BallEnd { radius: r }, s).unwrap();
            let by_eq_11 = BallSymbols::from_r_h(r, symbols.h).unwrap();
            assert!(close(by_eq_11.r_c, s / 2.0, 1e-12, 0.0), "s {s}");
        }
    }

    #[test]
    fn eq_27_corrected_agrees_with_the_engine_and_printed_is_off_by_pi_rc2_less_r_rc() {
        for r in [0.5, 3.0, 12.7] {
            let tool = BallEnd { radius: r };
            for q in PAPER_FRACTIONS {
                let s = 2.0 * r * q;
                let engine = section(&tool, s, ACCURACY).unwrap().cusp;
                let symbols = BallSymbols::for_tool(&tool, s).unwrap();
                let corrected = symbols.eq27_corrected().unwrap();
                assert!(
                    close(corrected, engine.half_area, 1e-9, 0.0),
                    "r {r} s {s}: corrected Eq. 27 {corrected} engine {}",
                    engine.half_area
                );
                // Printed less true is exactly the wrong first term's excess.
                let rc = symbols.r_c;
                let excess = 0.5 * (PI * rc * rc - r * rc);
                let printed = symbols.eq27().unwrap();
                assert!(
                    (printed - engine.half_area - excess).abs() <= 1e-9 * (r * rc),
                    "r {r} s {s}: printed {printed} engine {} excess {excess}",
                    engine.half_area
                );
                // Eq. 28 is both halves over L, of Eq. 27 printed or corrected.
                let length = 40.0;
                assert!(close(
                    symbols.eq28(length).unwrap(),
                    2.0 * length * printed,
                    1e-12,
                    0.0
                ));
                assert!(close(
                    symbols.eq28_corrected(length).unwrap(),
                    section(&tool, s, ACCURACY).unwrap().volume(length).unwrap(),
                    1e-9,
                    0.0
                ));
            }
        }
    }

    #[test]
    fn eq_27_as_printed_gives_impossible_areas() {
        let r = 3.0;
        let tool = BallEnd { radius: r };
        // Over the whole range: below zero, or above the rectangle r_c × h that contains the
        // half-cusp, except in a narrow band around r_c = r/π.
        for k in 1..=100 {
            let rc = r * k as f64 / 100.0;
            let symbols = BallSymbols::for_tool(&tool, 2.0 * rc).unwrap();
            let printed = symbols.eq27().unwrap();
            if rc < 0.308 * r {
                assert!(printed < 0.0, "r_c {rc}: {printed}");
            } else if rc > 0.345 * r {
                assert!(printed > rc * symbols.h, "r_c {rc}: {printed}");
            }
        }
        // Small stepover: an area cannot be negative.
        let small = BallSymbols::for_tool(&tool, 0.2 * r).unwrap();
        let printed = small.eq27().unwrap();
        assert!(printed < 0.0, "Eq. 27 at s = 0.2r: {printed}");
        // Full width: the half-cusp lies inside the rectangle r_c × h, here the square r × r.
        let full = BallSymbols::for_tool(&tool, 2.0 * r).unwrap();
        let printed = full.eq27().unwrap();
        let rectangle = full.r_c * full.h;
        assert!(
            printed > rectangle,
            "Eq. 27 at s = 2r: {printed} > {rectangle}"
        );
        // Only where π·r_c² = r·r_c, r_c = r/π, does the printed form happen to be right.
        let lucky = BallSymbols::for_tool(&tool, 2.0 * r / PI).unwrap();
        let engine = section(&tool, 2.0 * r / PI, ACCURACY).unwrap().cusp;
        assert!(close(lucky.eq27().unwrap(), engine.half_area, 1e-9, 0.0));
    }

    // The paper: corner-radius end mill, Eqs. 21–23.

    #[test]
    fn eq_22_corrected_agrees_with_the_engine_and_printed_is_its_mirror_about_a_times_width() {
        for (flat, corner) in [(2.0, 1.0), (0.25, 2.5), (5.0, 0.25)] {
            let tool = CornerRadius { flat, corner };
            for q in PAPER_FRACTIONS {
                let s = 2.0 * flat + 2.0 * corner * q;
                let engine = section(&tool, s, ACCURACY).unwrap();
                let symbols = CornerSymbols::for_tool(&tool, s).unwrap();
                assert_eq!(symbols.a, corner);
                // a − h is the half-cusp's width: from where the corner leaves the flat to
                // the midpoint.
                assert!((symbols.a - symbols.h - (s / 2.0 - flat)).abs() < 1e-12);
                let corrected = symbols.eq22_corrected().unwrap();
                assert!(
                    close(corrected, engine.cusp.half_area, 1e-9, 0.0),
                    "r1 {flat} r2 {corner} s {s}: corrected Eq. 22 {corrected} engine {}",
                    engine.cusp.half_area
                );
                // Upper and lower halves of the corner circle, over the same width a − h, sum
                // to the rectangle of height 2a.
                let width = symbols.a - symbols.h;
                let printed = symbols.eq22().unwrap();
                assert!(
                    close(
                        printed + engine.cusp.half_area,
                        2.0 * symbols.a * width,
                        1e-9,
                        0.0
                    ),
                    "printed {printed} engine {}",
                    engine.cusp.half_area
                );
                let length = 25.0;
                assert!(close(
                    symbols.eq23(length).unwrap(),
                    2.0 * length * printed,
                    1e-12,
                    0.0
                ));
                assert!(close(
                    symbols.eq23_corrected(length).unwrap(),
                    engine.volume(length).unwrap(),
                    1e-9,
                    0.0
                ));
            }
        }
    }

    #[test]
    fn eq_22_as_printed_exceeds_the_rectangle_holding_the_half_cusp() {
        // The half-cusp lies in the rectangle (half-width a − h) × (cusp height); Eq. 22 is
        // at least a·(a − h), and the cusp is never higher than the corner radius a.
        let tool = CornerRadius {
            flat: 2.0,
            corner: 1.0,
        };
        for s in [4.01, 4.5, 5.0, 5.5, 6.0] {
            let symbols = CornerSymbols::for_tool(&tool, s).unwrap();
            let height = section(&tool, s, ACCURACY).unwrap().cusp.height;
            let rectangle = (symbols.a - symbols.h) * height;
            let printed = symbols.eq22().unwrap();
            assert!(printed > rectangle, "s {s}: Eq. 22 {printed} > {rectangle}");
            assert!(printed > symbols.a * (symbols.a - symbols.h));
        }
        // At the full width the printed form gives the square plus a quarter disc, a²(1 + π/4),
        // for the square less one, a²(1 − π/4).
        let full = CornerSymbols::for_tool(&tool, 6.0).unwrap();
        assert!(close(full.eq22().unwrap(), 1.0 + PI / 4.0, 1e-14, 0.0));
        assert!(close(
            full.eq22_corrected().unwrap(),
            1.0 - PI / 4.0,
            1e-14,
            0.0
        ));
    }

    #[test]
    fn eq_21_is_outside_its_range_when_the_flats_overlap() {
        let tool = CornerRadius {
            flat: 2.0,
            corner: 1.0,
        };
        let symbols = CornerSymbols::for_tool(&tool, 3.0).unwrap();
        assert!(symbols.h > symbols.a);
        assert!(matches!(
            symbols.eq22(),
            Err(CuspError::OutsideEquation { equation: 22, .. })
        ));
        assert!(matches!(
            symbols.eq23(1.0),
            Err(CuspError::OutsideEquation { equation: 23, .. })
        ));
        assert_eq!(symbols.eq22_corrected().unwrap(), 0.0);
        // At s = 2·r1 exactly, h = a: the integral from a to a is empty, in both forms.
        let edge = CornerSymbols::for_tool(&tool, 4.0).unwrap();
        assert_eq!(edge.eq22().unwrap(), 0.0);
        assert_eq!(edge.eq22_corrected().unwrap(), 0.0);
    }

    #[test]
    fn reading_eq_21_s_h_as_the_cusp_height_fails_even_with_the_sign_fixed() {
        // With h the cusp height, the sign-fixed Eq. 22 measures the half-cusp's mirror image
        // across the corner's diagonal: right only at a half-width of a/√2.
        let tool = CornerRadius {
            flat: 2.0,
            corner: 1.0,
        };
        for s in [4.5, 5.0, 5.9] {
            let engine = section(&tool, s, ACCURACY).unwrap().cusp;
            let as_height = CornerSymbols {
                a: 1.0,
                h: engine.height,
            };
            let value = as_height.eq22_corrected().unwrap();
            assert!(
                (value - engine.half_area).abs() > 0.05 * engine.half_area,
                "s {s}: {value} vs {}",
                engine.half_area
            );
        }
        let s = 4.0 + 2.0 / 2f64.sqrt();
        let engine = section(&tool, s, ACCURACY).unwrap().cusp;
        let as_height = CornerSymbols {
            a: 1.0,
            h: engine.height,
        };
        assert!(close(
            as_height.eq22_corrected().unwrap(),
            engine.half_area,
            1e-9,
            0.0
        ));
    }
}
