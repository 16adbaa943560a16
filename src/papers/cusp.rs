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
mod tests;
