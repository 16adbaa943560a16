//! The machined section in an observer plane through the screw axis: seed 000's method.
//!
//! Dogrusadik (seed 000) observes the plane z = 0, which contains the screw axis y, while a
//! tool of revolution with its axis parallel to y moves along a [`Helix`]. At each tool
//! rotation angle φ the tool's instant section in that plane is, at abscissa x, the vertical
//! chord
//!
//! ```text
//! y ∈ y0(φ) + span(ρ(φ)),    ρ(φ) = √((x − R cos φ)² + (R sin φ)²),
//! ```
//!
//! (the tool's heights at the distance ρ of the point (x, 0, 0) from its axis), and the machined
//! section is the overlap of all of them. Its upper boundary at x is therefore
//!
//! ```text
//! Y(x) = max over φ in the range, where the tool reaches the plane, of y0(φ) + top(ρ(φ)).
//! ```
//!
//! Along a whole helix every section through the screw axis is this one shifted along y, so the
//! curve is the whole machined surface.
//!
//! # How the maximum is found ([`top_at`])
//!
//! The set of φ where the tool reaches the plane is known in closed form from the tool's largest
//! radius (ρ(φ) ≤ r ⇔ x·cos φ ≥ (x² + R² − r²)/(2R)), so the scan covers exactly that set however
//! narrow it is (near the ends of the section it shrinks to a point). It is sampled at 65
//! points plus the closest approach; wherever one sample reaches and its neighbour does not,
//! the edge is bisected on `span_at` to the last bit. Every local maximum of the samples is
//! then refined by golden-section search between its neighbours, and the edge points compete
//! with their exact values. So the maximum is either interior (the derivative in φ is zero:
//! seed 000's Eqs. 8–10) or on a reach edge, where the tool only just reaches the plane
//! (seed 000's Eq. 12 for the paraboloid, whose rim lies on its centre plane).
//!
//! # Accuracy contract ([`upper_boundary`])
//!
//! The polyline's vertices lie on Y (to rounding: ~1e-14 mm) and its vertical deviation from Y
//! is at most `accuracy` everywhere between them, wherever Y is convex or concave between two
//! consecutive vertices. Each candidate interval [x0, x1] of width h is accepted only when
//!
//! 1. the slope of Y (from the envelope theorem: ∂/∂x of the chord top at the maximising φ, by
//!    a central difference, or the derivative along the reach edge) is monotone through x0,
//!    the midpoint and x1, with the chord's slope between the end slopes: Y bends one way;
//! 2. the tangent-triangle bound is at most `accuracy`: a curve that bends one way lies
//!    between its chord and its two end tangents, so its vertical distance from the chord is
//!    at most h·A·B/(A + B), A and B the differences of the end slopes from the chord's slope.
//!    Where a slope is unknown (the vertical tangent at an end of the groove) the other
//!    tangent alone bounds it: h·B. A and B are each padded by τ = accuracy/(8h), which covers
//!    slope-estimate noise up to τ (the estimates are good to ~1e-9);
//! 3. the measured deviation at the midpoint is at most `accuracy`.
//!
//! Otherwise the interval is halved, starting from 64 equal intervals. An inflection inside an
//! interval shows as a non-monotone slope and is split down; kinks where the maximising φ
//! jumps to another basin are convex corners, which the bound covers. Two escapes, both
//! documented limits rather than silent ones: an interval narrower than 64 ulp of x is accepted
//! as it is (only at a vertical tangent with an accuracy near [`MIN_ACCURACY`]; its distance
//! from Y, as opposed to its vertical deviation, is then below its width), and needing more
//! than 2 000 000 points is an error. Seed 000's section is concave throughout (Y'' ≤ −0.09
//! 1/mm by the closed form), so there the contract holds without condition for accuracies
//! down to ~1e-6 mm; finer, the 64-ulp escape is reached within ~1e-12 mm of the two ends
//! (measured at 1e-9 mm: 9e-8 mm vertically, 2e-14 mm from the end).

use super::helix::{Helix, HelixError};
use super::tool::{Paraboloid, Revolved};
use glam::DVec2;
use std::f64::consts::{PI, TAU};
use std::fmt::Write;

/// The smallest accuracy accepted, mm: below this the float resolution of x (about 7e-15 mm
/// at 32 mm) and the precision of the maximum are no longer far enough below it.
pub const MIN_ACCURACY: f64 = 1e-9;

/// Samples of the reach interval in φ for the basin scan.
const SCAN: usize = 64;
/// Equal intervals the adaptive polyline starts from, so that no feature of the tool wider
/// than 1/64 of the groove can be stepped over by the first midpoint tests.
const INITIAL_INTERVALS: usize = 64;
/// A point budget that a valid input never approaches (seed 000 needs ~700 points at 0.1 µm, ~6000 at 1 nm).
const MAX_POINTS: usize = 2_000_000;
/// Widening of the closed-form reach interval, rad: the closed form loses up to √ε ≈ 1.5e-8 rad
/// near a closest approach, and the bisection must start with its edge inside the scan.
const REACH_MARGIN: f64 = 1e-7;

/// Why a section cannot be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SectionError {
    /// The helix is not a usable motion.
    #[error(transparent)]
    Helix(#[from] HelixError),
    /// Seed 000's cap must open downwards.
    #[error(
        "paraboloid a must be negative and finite (the cap h = aρ² + b opens downwards), got {0}"
    )]
    ParaboloidA(f64),
    /// Seed 000's tip must be above the centre plane.
    #[error(
        "paraboloid b must be positive and finite (the tip height above the centre plane), got {0}"
    )]
    ParaboloidB(f64),
    /// The accuracy must be a length the computation can honour.
    #[error("accuracy must be finite and at least {MIN_ACCURACY:e} mm, got {0:e} mm")]
    Accuracy(f64),
    /// The x range is not an interval.
    #[error("x range must be finite with start < end, got [{0}, {1}]")]
    XRange(f64, f64),
    /// The tool's radius is not a finite positive length.
    #[error("the tool's largest radius must be finite and positive, got {0}")]
    ToolRadius(f64),
    /// The tool is at least as wide as the helix radius: it covers the screw axis and the two
    /// sides of the section merge, so there is no separate groove around x = −R.
    #[error(
        "the tool (radius {tool:.6} mm) reaches the screw axis from the helix radius \
         {helix:.6} mm: the groove is not a separate section"
    )]
    ReachesAxis {
        /// The tool's largest radius, mm.
        tool: f64,
        /// R, mm.
        helix: f64,
    },
    /// Within its φ range the tool never cuts the observer plane on the x < 0 side.
    #[error("the tool never reaches the observer plane on the x < 0 side within the φ range")]
    NoSection,
    /// The requested x range does not overlap the section.
    #[error("the x range [{start}, {end}] misses the section, which spans [{from}, {to}]")]
    Misses {
        /// Requested start.
        start: f64,
        /// Requested end.
        end: f64,
        /// The section's first x.
        from: f64,
        /// The section's last x.
        to: f64,
    },
    /// The tool has a shank (infinite top): the section is unbounded above.
    #[error("the tool has no finite top (a shank): the section is unbounded above")]
    Unbounded,
    /// The maximum could not be evaluated where the section should exist.
    #[error("the section's top could not be evaluated at x = {0}")]
    Evaluation(f64),
    /// The adaptive polyline ran over its point budget.
    #[error("more than {MAX_POINTS} points would be needed for this accuracy")]
    TooManyPoints,
}

/// Where the maximum over φ is attained.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Attained {
    /// Inside the reach set: the chord top is stationary in φ (seed 000's Eqs. 8–10).
    Interior,
    /// On the edge of the reach set, where the tool just stops reaching the plane (for seed
    /// 000's paraboloid: its rim, Eq. 12).
    ReachEdge,
    /// At the start or end of the helix's φ range.
    RangeEnd,
}

/// The section's upper boundary at one x.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Top {
    /// Y(x), mm.
    pub y: f64,
    /// The maximising tool rotation angle φ, rad.
    pub phi: f64,
    /// How the maximum is attained.
    pub attained: Attained,
}

/// The top of the instant chord at (x, φ): y0(φ) + top(ρ(φ)), or `None` where the tool does not
/// reach the point.
fn chord_top(tool: &dyn Revolved, helix: &Helix, x: f64, phi: f64) -> Option<f64> {
    let (s, c) = phi.sin_cos();
    let dx = x - helix.radius * c;
    let dz = helix.radius * s;
    let rho = (dx * dx + dz * dz).sqrt();
    tool.span_at(rho).map(|(_, hi)| helix.axial(phi) + hi)
}

/// The intervals of φ within the helix's range where the tool can reach (x, 0, 0), from the
/// closed form ρ(φ) ≤ r ⇔ x·cos φ ≥ (x² + R² − r²)/(2R), widened by [`REACH_MARGIN`].
/// Also returns the closest-approach angles (0 or π, mod 2π) inside them.
fn reach_intervals(helix: &Helix, x: f64, r: f64) -> (Vec<(f64, f64)>, f64) {
    let (lo, hi) = (helix.phi_start, helix.phi_end);
    let rr = helix.radius;
    let q = (x * x + rr * rr - r * r) / (2.0 * rr);
    let whole = (vec![(lo, hi)], if x < 0.0 { PI } else { 0.0 });
    if x == 0.0 {
        return if q <= 0.0 { whole } else { (vec![], 0.0) };
    }
    let c = q / x;
    // x > 0: cos φ ≥ c, around φ = 0; x < 0: cos φ ≤ c, around φ = π.
    let (centre, half) = if x > 0.0 {
        if c <= -1.0 {
            return whole;
        }
        if c > 1.0 + 1e-9 {
            return (vec![], 0.0);
        }
        (0.0, c.clamp(-1.0, 1.0).acos())
    } else {
        if c >= 1.0 {
            return whole;
        }
        if c < -1.0 - 1e-9 {
            return (vec![], PI);
        }
        (PI, PI - c.clamp(-1.0, 1.0).acos())
    };
    let half = half + REACH_MARGIN;
    if half >= PI {
        return whole;
    }
    let k0 = ((lo - centre - half) / TAU).floor() as i64;
    let k1 = ((hi - centre + half) / TAU).ceil() as i64;
    let mut out = Vec::new();
    for k in k0..=k1 {
        let mid = centre + TAU * k as f64;
        let (a, b) = ((mid - half).max(lo), (mid + half).min(hi));
        if a <= b {
            out.push((a, b));
        }
    }
    (out, centre)
}

/// The last φ (to the bit) from `inside` towards `outside` where the tool still reaches, with
/// its chord top. `inside` must reach.
fn last_reaching(f: &dyn Fn(f64) -> Option<f64>, inside: (f64, f64), outside: f64) -> (f64, f64) {
    let (mut a, mut ya) = inside;
    let mut b = outside;
    loop {
        let m = a + (b - a) / 2.0;
        if m == a || m == b {
            return (a, ya);
        }
        match f(m) {
            Some(y) => (a, ya) = (m, y),
            None => b = m,
        }
    }
}

/// Golden-section search for the largest `f` on [a, b]; `None` counts as −∞.
fn golden_max(f: &dyn Fn(f64) -> Option<f64>, mut a: f64, mut b: f64) -> (f64, f64) {
    let inv = (5f64.sqrt() - 1.0) / 2.0;
    let val = |p: f64| f(p).unwrap_or(f64::NEG_INFINITY);
    let (mut c, mut d) = (b - inv * (b - a), a + inv * (b - a));
    let (mut fc, mut fd) = (val(c), val(d));
    for _ in 0..200 {
        // 1e-10 rad leaves a value error of ½|y''|·1e-20: far below the rounding of y.
        if b - a <= 1e-10 + 4.0 * f64::EPSILON * (a.abs() + b.abs()) {
            break;
        }
        if fc >= fd {
            (b, d, fd) = (d, c, fc);
            c = b - inv * (b - a);
            fc = val(c);
        } else {
            (a, c, fc) = (c, d, fd);
            d = a + inv * (b - a);
            fd = val(d);
        }
    }
    if fc >= fd {
        (c, fc)
    } else {
        (d, fd)
    }
}

/// A point of the scan that reaches the plane.
#[derive(Clone, Copy)]
struct Reaching {
    phi: f64,
    y: f64,
    attained: Attained,
    /// Index of the contiguous run of reaching samples it belongs to.
    run: usize,
}

/// Y(x): the top of the machined section at x, the largest chord top over the φ where the tool
/// reaches the plane (see the module docs for the method); `None` where no φ in the range
/// reaches, or for an invalid helix ([`Helix::validate`]). The value is accurate to the
/// rounding of the chord top (~1e-14 mm at seed 000's sizes); `y` is `+∞` for a tool with a
/// shank.
pub fn top_at(tool: &dyn Revolved, helix: &Helix, x: f64) -> Option<Top> {
    let r = tool.max_radius();
    if !(x.is_finite() && r.is_finite() && r >= 0.0) || helix.validate().is_err() {
        return None;
    }
    let f = |phi: f64| chord_top(tool, helix, x, phi);
    let is_range_end = |phi: f64| phi == helix.phi_start || phi == helix.phi_end;
    let (intervals, centre) = reach_intervals(helix, x, r);
    let mut best: Option<Top> = None;
    let mut consider = |top: Top| {
        if best.is_none_or(|b| top.y > b.y) {
            best = Some(top);
        }
    };
    for (a, b) in intervals {
        let mut phis: Vec<f64> = (0..=SCAN)
            .map(|i| a + (b - a) * i as f64 / SCAN as f64)
            .collect();
        // The closest approach is where a barely reaching tool reaches at all.
        let k0 = ((a - centre) / TAU).ceil() as i64;
        let k1 = ((b - centre) / TAU).floor() as i64;
        phis.extend((k0..=k1).map(|k| centre + TAU * k as f64));
        phis.sort_by(f64::total_cmp);
        phis.dedup();
        let vals: Vec<Option<f64>> = phis.iter().map(|&p| f(p)).collect();
        let mut pts: Vec<Reaching> = Vec::with_capacity(phis.len() + 4);
        let mut run = 0;
        for (i, (&phi, &v)) in phis.iter().zip(&vals).enumerate() {
            let Some(y) = v else {
                if i > 0 && vals[i - 1].is_some() {
                    run += 1;
                }
                continue;
            };
            let edge = |toward: Option<f64>| {
                toward
                    .map(|out| last_reaching(&f, (phi, y), out))
                    .filter(|e| e.0 != phi)
            };
            let before = (i > 0 && vals[i - 1].is_none()).then(|| phis[i - 1]);
            let after = (i + 1 < vals.len() && vals[i + 1].is_none()).then(|| phis[i + 1]);
            let (edge_before, edge_after) = (edge(before), edge(after));
            if let Some((pe, ye)) = edge_before {
                pts.push(Reaching {
                    phi: pe,
                    y: ye,
                    attained: Attained::ReachEdge,
                    run,
                });
            }
            let attained = if is_range_end(phi) {
                Attained::RangeEnd
            } else if (before.is_some() && edge_before.is_none())
                || (after.is_some() && edge_after.is_none())
            {
                // The sample is its own edge: the bisection could not move past it.
                Attained::ReachEdge
            } else {
                Attained::Interior
            };
            pts.push(Reaching {
                phi,
                y,
                attained,
                run,
            });
            if let Some((pe, ye)) = edge_after {
                pts.push(Reaching {
                    phi: pe,
                    y: ye,
                    attained: Attained::ReachEdge,
                    run,
                });
            }
        }
        for k in 0..pts.len() {
            let p = pts[k];
            let left = (k > 0 && pts[k - 1].run == p.run).then(|| pts[k - 1]);
            let right = (k + 1 < pts.len() && pts[k + 1].run == p.run).then(|| pts[k + 1]);
            if left.is_some_and(|l| l.y > p.y) || right.is_some_and(|r| r.y > p.y) {
                continue;
            }
            consider(Top {
                y: p.y,
                phi: p.phi,
                attained: p.attained,
            });
            let (lo, hi) = (
                left.map_or(p.phi, |l| l.phi),
                right.map_or(p.phi, |r| r.phi),
            );
            if hi > lo {
                let (phi, y) = golden_max(&f, lo, hi);
                consider(Top {
                    y,
                    phi,
                    attained: Attained::Interior,
                });
            }
        }
    }
    best.filter(|t| t.y.is_finite() || t.y == f64::INFINITY)
}

/// dY/dx at x, given the maximum there: by the envelope theorem, ∂/∂x of the chord top at the
/// fixed maximising φ (interior or range-end maxima), or the derivative along the reach edge,
/// where ρ stays at the edge radius so only y0 moves: y0'(φ)·dφ/dx with
/// dφ/dx = −(x − R cos φ)/(x R sin φ). `None` where it cannot be estimated.
fn slope_at(tool: &dyn Revolved, helix: &Helix, x: f64, top: &Top) -> Option<f64> {
    let s = match top.attained {
        Attained::ReachEdge => {
            let (s, c) = top.phi.sin_cos();
            let dphi_dx = -(x - helix.radius * c) / (x * helix.radius * s);
            helix.axial_rate() * dphi_dx
        }
        Attained::Interior | Attained::RangeEnd => {
            let d = 1e-6 * (1.0 + x.abs());
            match (
                chord_top(tool, helix, x + d, top.phi),
                chord_top(tool, helix, x - d, top.phi),
            ) {
                (Some(u), Some(v)) => (u - v) / (2.0 * d),
                // Next to a reach edge only one side reaches: a second-order one-sided
                // difference when the second step still reaches, else first order.
                (Some(u), None) => match chord_top(tool, helix, x + 2.0 * d, top.phi) {
                    Some(w) => (-3.0 * top.y + 4.0 * u - w) / (2.0 * d),
                    None => (u - top.y) / d,
                },
                (None, Some(v)) => match chord_top(tool, helix, x - 2.0 * d, top.phi) {
                    Some(w) => (3.0 * top.y - 4.0 * v + w) / (2.0 * d),
                    None => (top.y - v) / d,
                },
                (None, None) => return None,
            }
        }
    };
    (!s.is_nan()).then_some(s)
}

/// How far the tool centre gets to the x < 0 side, as (the least cos φ over the range, the
/// highest y0 among the φ attaining it: the instant that reaches the ends of the groove).
fn closest_approach(helix: &Helix) -> (f64, f64) {
    let mut cands = vec![helix.phi_start, helix.phi_end];
    let k0 = ((helix.phi_start - PI) / TAU).ceil() as i64;
    let k1 = ((helix.phi_end - PI) / TAU).floor() as i64;
    // A range of absurdly many turns changes nothing past the first two.
    for k in k0..=k1.min(k0.saturating_add(2)) {
        cands.push(PI + TAU * k as f64);
    }
    let cmin = cands.iter().map(|p| p.cos()).fold(f64::INFINITY, f64::min);
    let y = cands
        .iter()
        .filter(|p| p.cos() <= cmin + 1e-15)
        .map(|&p| helix.axial(p))
        .fold(f64::NEG_INFINITY, f64::max);
    (cmin, y)
}

/// The top of the tool at its largest radius, approached from inside: `span_at` at
/// `max_radius`, or a few ulp inside it when the rim rounds to "not reached".
fn rim_top(tool: &dyn Revolved) -> Option<f64> {
    let mut rho = tool.max_radius();
    for _ in 0..64 {
        if let Some((_, hi)) = tool.span_at(rho) {
            return Some(hi);
        }
        if rho <= 0.0 {
            return None;
        }
        rho = f64::from_bits(rho.to_bits() - 1);
    }
    None
}

/// The two ends of the section around x = −R (the groove the helix passes at φ = π), far end
/// first: the x where the tool's closest approach to the point (x, 0, 0) is its largest radius
/// r, i.e. the roots of x² − 2R·c·x + R² − r² = 0 with c the least cos φ of the range (−1 for
/// any range containing π): x = −R ± r. Computed as R·c − √(r² − R²(1 − c²)) and the other
/// root from the product R² − r² = (R − r)(R + r), both without cancellation, so they are exact
/// to an ulp or two (for seed 000: −32 and −8 exactly).
///
/// For seed 000's paraboloid these are where the section's top meets y = 0: the only instant
/// reaching there is the closest one, φ = π with y0 = 0, and only its rim, at height 0.
pub fn section_ends(tool: &dyn Revolved, helix: &Helix) -> Result<(f64, f64), SectionError> {
    helix.validate()?;
    let r = tool.max_radius();
    if !(r.is_finite() && r > 0.0) {
        return Err(SectionError::ToolRadius(r));
    }
    let rr = helix.radius;
    if r >= rr {
        return Err(SectionError::ReachesAxis { tool: r, helix: rr });
    }
    let (c, _) = closest_approach(helix);
    let disc = (r - rr * (1.0 - c * c).sqrt()) * (r + rr * (1.0 - c * c).sqrt());
    if c >= 0.0 || disc < 0.0 {
        return Err(SectionError::NoSection);
    }
    let far = rr * c - disc.sqrt();
    let near = (rr - r) * (rr + r) / far;
    Ok((far, near))
}

/// A vertex of the adaptive polyline with the slope of Y there (`None`: unknown, the vertical
/// tangent at an end of the groove).
#[derive(Clone, Copy)]
struct Node {
    x: f64,
    y: f64,
    slope: Option<f64>,
}

fn check_accuracy(accuracy: f64) -> Result<(), SectionError> {
    if accuracy.is_finite() && accuracy >= MIN_ACCURACY {
        Ok(())
    } else {
        Err(SectionError::Accuracy(accuracy))
    }
}

/// Whether the chord from `a` to `b` is within `accuracy` of Y, given Y at the midpoint `m`
/// (the tests of the module docs' accuracy contract).
fn chord_is_close(a: &Node, m: &Node, b: &Node, accuracy: f64) -> bool {
    let h = b.x - a.x;
    if h <= 64.0 * f64::EPSILON * a.x.abs().max(b.x.abs()).max(1.0) {
        return true;
    }
    let chord = (b.y - a.y) / h;
    let dev = m.y - 0.5 * (a.y + b.y);
    if dev.is_nan() || dev.abs() > accuracy {
        return false;
    }
    let Some(sm) = m.slope else {
        return false;
    };
    // Concave when the midpoint is above the chord: slopes fall from left to right.
    let sigma = if dev >= 0.0 { 1.0 } else { -1.0 };
    let s0 = a.slope.unwrap_or(sigma * f64::INFINITY);
    let s1 = b.slope.unwrap_or(-sigma * f64::INFINITY);
    // Slope noise allowed in the monotonicity test: an error τ in a slope moves a tangent line
    // by at most τ·h, here accuracy/8.
    let tau = accuracy / (8.0 * h);
    let monotone = sigma * (s0 - sm) >= -tau && sigma * (sm - s1) >= -tau;
    let a_gap = sigma * (s0 - chord);
    let b_gap = sigma * (chord - s1);
    if !(monotone && a_gap >= -tau && b_gap >= -tau) {
        return false;
    }
    let (ag, bg) = (a_gap.max(0.0) + tau, b_gap.max(0.0) + tau);
    let bound = if ag.is_infinite() && bg.is_infinite() {
        f64::INFINITY
    } else if ag.is_infinite() {
        h * bg
    } else if bg.is_infinite() {
        h * ag
    } else {
        h * ag * bg / (ag + bg)
    };
    bound <= accuracy
}

/// The upper boundary of the section around x = −R over `x_range` (clipped to the section,
/// see [`section_ends`]), as points ordered by x whose polyline is within `accuracy` mm of the
/// true boundary (see the module docs for the contract and how it is met). When the range
/// covers an end of the groove, that end is a vertex, at its exact x.
pub fn upper_boundary(
    tool: &dyn Revolved,
    helix: &Helix,
    x_range: (f64, f64),
    accuracy: f64,
) -> Result<Vec<DVec2>, SectionError> {
    helix.validate()?;
    check_accuracy(accuracy)?;
    let (start, end) = x_range;
    if !(start.is_finite() && end.is_finite() && start < end) {
        return Err(SectionError::XRange(start, end));
    }
    let (from, to) = section_ends(tool, helix)?;
    let (lo, hi) = (start.max(from), end.min(to));
    // Both are finite here.
    if lo >= hi {
        return Err(SectionError::Misses {
            start,
            end,
            from,
            to,
        });
    }
    let (_, y_closest) = closest_approach(helix);
    let eval = |x: f64| -> Result<Node, SectionError> {
        if x == from || x == to {
            // Only the closest instant reaches, with its rim: Y there is its rim's top.
            let rim = rim_top(tool).ok_or(SectionError::Evaluation(x))?;
            let y = y_closest + rim;
            if !y.is_finite() {
                return Err(SectionError::Unbounded);
            }
            return Ok(Node { x, y, slope: None });
        }
        let top = top_at(tool, helix, x).ok_or(SectionError::Evaluation(x))?;
        if !top.y.is_finite() {
            return Err(SectionError::Unbounded);
        }
        Ok(Node {
            x,
            y: top.y,
            slope: slope_at(tool, helix, x, &top),
        })
    };
    let grid: Vec<Node> = (0..=INITIAL_INTERVALS)
        .map(|i| match i {
            0 => eval(lo),
            INITIAL_INTERVALS => eval(hi),
            _ => eval(lo + (hi - lo) * i as f64 / INITIAL_INTERVALS as f64),
        })
        .collect::<Result<_, _>>()?;
    let mut out = vec![DVec2::new(grid[0].x, grid[0].y)];
    let mut stack = Vec::new();
    for pair in grid.windows(2) {
        stack.push((pair[0], pair[1]));
        while let Some((a, b)) = stack.pop() {
            let m = eval(a.x + (b.x - a.x) / 2.0)?;
            if chord_is_close(&a, &m, &b, accuracy) {
                out.push(DVec2::new(b.x, b.y));
                if out.len() > MAX_POINTS {
                    return Err(SectionError::TooManyPoints);
                }
            } else {
                stack.push((m, b));
                stack.push((a, m));
            }
        }
    }
    Ok(out)
}

/// The CSV that `whirl sweep paraboloid --a A --b B --radius R --pitch P [--accuracy MM]`
/// writes: header `x,y`, then the upper boundary of seed 000's section (paraboloid tool
/// {a, b}, one turn of the helix {R, p} centred on φ = π) from the far end of the groove
/// (x = −R − r) to the near end (x = −R + r), r = √(−b/a), within `accuracy` mm (see the
/// module docs).
///
/// Numbers are written exactly (Rust's shortest representation that reads back to the same
/// f64) rather than to a fixed number of decimals: next to the ends the boundary is vertical,
/// vertices there are ~1e-8 mm apart at 0.1 µm accuracy, and rounding x to even 8 decimals
/// would cost a vertical error of the size of the accuracy. Heights within 1e-12 mm of 0 (the
/// ends, on the axis, up to the rounding of a·r² + b) are written as 0.
pub fn run_paraboloid(
    a: f64,
    b: f64,
    radius: f64,
    pitch: f64,
    accuracy: f64,
) -> Result<String, SectionError> {
    if !(a.is_finite() && a < 0.0) {
        return Err(SectionError::ParaboloidA(a));
    }
    if !(b.is_finite() && b > 0.0) {
        return Err(SectionError::ParaboloidB(b));
    }
    let helix = Helix::one_turn(radius, pitch);
    helix.validate()?;
    check_accuracy(accuracy)?;
    let tool = Paraboloid { a, b };
    let (from, to) = section_ends(&tool, &helix)?;
    if from >= to {
        // A tool so small that its section rounds to a single x.
        return Err(SectionError::NoSection);
    }
    let points = upper_boundary(&tool, &helix, (from, to), accuracy)?;
    let tidy = |v: f64| if v.abs() < 1e-12 { 0.0 } else { v };
    let mut csv = String::with_capacity(40 * (points.len() + 1));
    csv.push_str("x,y\n");
    for p in points {
        // Writing to a String cannot fail.
        let _ = writeln!(csv, "{},{}", p.x, tidy(p.y));
    }
    Ok(csv)
}

/// Seed 000's closed form (Eqs. 9, 10, 12), written from the paper for the tests of this
/// module and of [`grazing`](super::grazing).
#[cfg(test)]
pub(crate) mod seed000 {
    use std::f64::consts::{PI, TAU};

    /// Table 1.
    pub const R: f64 = 20.0;
    /// Table 1.
    pub const A: f64 = -0.05;
    /// Table 1.
    pub const B: f64 = 7.2;
    /// Table 1.
    pub const P: f64 = 20.0;

    /// The case with its pitch replaced.
    #[derive(Clone, Copy)]
    pub struct Case {
        pub r: f64,
        pub a: f64,
        pub b: f64,
        pub p: f64,
    }

    pub const TABLE_1: Case = Case {
        r: R,
        a: A,
        b: B,
        p: P,
    };

    impl Case {
        /// sin φ* = p/(4π a R x), Eq. 9's argument.
        fn s(&self, x: f64) -> f64 {
            self.p / (4.0 * PI * self.a * self.r * x)
        }

        /// Eq. 9: the maximising φ without the rim constraint.
        pub fn phi_star(&self, x: f64) -> f64 {
            PI - self.s(x).asin()
        }

        /// Eq. 10 as printed.
        pub fn eq10(&self, x: f64) -> f64 {
            let (a, r, s) = (self.a, self.r, self.s(x));
            a * x * x
                + 2.0 * a * x * r * (1.0 - s * s).sqrt()
                + a * r * r
                + self.b
                + self.p / TAU * s.asin()
        }

        /// Eq. 12 as printed.
        pub fn eq12(&self, x: f64) -> f64 {
            let (a, r) = (self.a, self.r);
            self.p / TAU * (-(a * x * x + a * r * r + self.b) / (2.0 * a * x * r)).acos()
        }

        /// The distance from the tool axis at Eq. 9's φ to the point (x, 0, 0).
        pub fn rho_star(&self, x: f64) -> f64 {
            let phi = self.phi_star(x);
            (x * x - 2.0 * x * self.r * phi.cos() + self.r * self.r).sqrt()
        }

        /// The paraboloid's base radius √(−b/a).
        pub fn rim(&self) -> f64 {
            (-self.b / self.a).sqrt()
        }

        /// The exact section: Eq. 10 where its maximising instant reaches the point with its
        /// cap (ρ* ≤ rim), else the rim's path Eq. 12.
        pub fn section(&self, x: f64) -> f64 {
            if self.rho_star(x) <= self.rim() {
                self.eq10(x)
            } else {
                self.eq12(x)
            }
        }

        /// The switch points between Eq. 12 and Eq. 10, far end then near end: where Eq. 9's
        /// instant reaches the point with its rim (ρ* = rim). Found as simple roots, not by
        /// equating Eqs. 10 and 12: those only touch there (a double root).
        pub fn switches(&self) -> (f64, f64) {
            let g = |x: f64| self.rho_star(x) - self.rim();
            let (far, near) = (-self.r - self.rim(), -self.r + self.rim());
            let root = |a: f64, b: f64| crate::geometry::brent::root(g, a, b, 1e-14, 200).unwrap();
            (root(far, -self.r), root(-self.r, near))
        }
    }
}

#[cfg(test)]
mod tests;
