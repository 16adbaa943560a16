//! Sampled profile points: reading, validation, and the spline fit.
//!
//! Points come from a CSV file, `x,y` for a transverse section or `rho,z` for an axial one,
//! one point a line, with an optional header line. Axial points are turned into transverse
//! ones by kinematics.md's rule (radius ρ, polar angle −z/p) before the fit, so every profile
//! is one periodic spline. A half period (`mirror = true`) is completed by mirroring the points
//! about the last point's polar angle.
//!
//! Validation names the file line of the offending point: too few points, values that are not
//! numbers, duplicates, points on the axis, polar angle not increasing, a span that is not one
//! period (or exactly half of one when mirrored), and outliers: points where the profile
//! zig-zags or doubles back and which lie off the cubic through their neighbours by more than
//! the data's own resolution allows (see `check_outliers`). Every check is linear in the
//! number of points (a million are read, checked, fitted and planned in about a second:
//! docs/benchmarks.md), and none overflows on absurd values: a point at 10³⁰⁸ is named by its
//! own line.

use super::smoothing::{self, Spread};
use super::spline::Spline;
use super::{Fit, Piece, Profile, Rounding};
use num_complex::Complex64;
use std::f64::consts::PI;
use std::fmt;

/// Which section the points describe.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Section {
    /// `x, y` in the plane z = 0.
    Transverse,
    /// `rho, z` in the axial half-plane φ = 0.
    Axial,
}

/// One point as read, with the file line it came from (1-based).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Row {
    /// File line.
    pub line: usize,
    /// First value (x or ρ).
    pub a: f64,
    /// Second value (y or z).
    pub b: f64,
}

impl fmt::Display for Row {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "line {} ({}, {})",
            self.line,
            Number(self.a),
            Number(self.b)
        )
    }
}

/// A value as it was most likely written: Rust's shortest form, in exponent form from 10¹⁵ on
/// (where the plain form would spell out hundreds of digits).
struct Number(f64);

impl fmt::Display for Number {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.0.abs() >= 1e15 {
            write!(f, "{:e}", self.0)
        } else {
            write!(f, "{}", self.0)
        }
    }
}

/// A distance in mm to three decimals, in exponent form where that would be unreadable.
fn mm(v: f64) -> String {
    if v.abs() >= 1e9 {
        format!("{v:.3e}")
    } else {
        format!("{v:.3}")
    }
}

/// What is wrong with a set of profile points.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PointsError {
    /// A line that is not two numbers.
    #[error("line {line}: {what}")]
    Syntax {
        /// File line.
        line: usize,
        /// What was found.
        what: String,
    },
    /// A value that is NaN or infinite.
    #[error("{row}: {name} is not a finite number")]
    NotFinite {
        /// The point.
        row: Row,
        /// Which value.
        name: &'static str,
    },
    /// Not enough points for a spline.
    #[error("{found} points given; a {what} needs at least {needed}")]
    TooFew {
        /// Points found.
        found: usize,
        /// Points needed.
        needed: usize,
        /// Full or half period.
        what: &'static str,
    },
    /// Two consecutive points coincide.
    #[error("{row} repeats the point before it ({prev})")]
    Duplicate {
        /// The repeated point.
        row: Row,
        /// Its predecessor.
        prev: Row,
    },
    /// A point on the screw axis has no polar angle.
    #[error("{row} lies on the screw axis, where the polar angle is undefined")]
    OnAxis {
        /// The point.
        row: Row,
    },
    /// The polar angle turns back.
    #[error(
        "{row}: the polar angle goes back from {from_deg:.3}° to {to_deg:.3}°; \
         profile points must run one way round the axis"
    )]
    NotIncreasing {
        /// The point where it turns back.
        row: Row,
        /// Polar angle of the point before, degrees.
        from_deg: f64,
        /// Polar angle of this point, degrees.
        to_deg: f64,
    },
    /// The points do not cover one period (or half of one with `mirror`).
    #[error(
        "the points span {span_deg:.3}° of polar angle, from {first} to {last}; {expected} of a \
         {starts}-start groove"
    )]
    NotOnePeriod {
        /// Span of the points.
        span_deg: f64,
        /// The first point.
        first: Row,
        /// The last point (before a closing point that repeats the first).
        last: Row,
        /// What was expected.
        expected: String,
        /// Number of starts.
        starts: u32,
    },
    /// A point far off the curve through its neighbours.
    #[error(
        "{row} is an outlier: it lies {} mm off the curve through its neighbours (which passes \
         ({near_a:.3}, {near_b:.3}) there), more than the {} mm that the spacing and the \
         decimals of the points allow, so the profile's curvature spikes (if the points are a \
         measurement that scatters more than its decimals say, state how far they may be off \
         as [groove.profile] fit_tolerance)",
        mm(*off_mm),
        mm(*limit_mm)
    )]
    Outlier {
        /// The point.
        row: Row,
        /// Distance from the curve through its neighbours, mm.
        off_mm: f64,
        /// Nearest point of that curve, in the input's section coordinates.
        near_a: f64,
        /// Second coordinate of it.
        near_b: f64,
        /// The most a point of a smooth curve could lie off it, given the local spacing and the
        /// decimals the points are written to, mm (see `check_outliers`).
        limit_mm: f64,
    },
}

/// Read `x,y` / `rho,z` rows from CSV text. A first line that does not parse as numbers is a
/// header; blank lines and lines starting with `#` are skipped.
pub fn read_csv(text: &str) -> Result<Vec<Row>, PointsError> {
    let mut rows = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let content = raw.trim();
        if content.is_empty() || content.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = content.split(',').map(str::trim).collect();
        let numbers: Vec<Option<f64>> = fields.iter().map(|f| f.parse::<f64>().ok()).collect();
        if rows.is_empty()
            && line == first_content_line(text)
            && numbers.iter().all(Option::is_none)
        {
            continue; // header
        }
        if fields.len() != 2 {
            return Err(PointsError::Syntax {
                line,
                what: format!("expected two values, found {}: {content:?}", fields.len()),
            });
        }
        match (numbers[0], numbers[1]) {
            (Some(a), Some(b)) => rows.push(Row { line, a, b }),
            _ => {
                let bad = if numbers[0].is_none() {
                    fields[0]
                } else {
                    fields[1]
                };
                return Err(PointsError::Syntax {
                    line,
                    what: format!("{bad:?} is not a number"),
                });
            }
        }
    }
    Ok(rows)
}

fn first_content_line(text: &str) -> usize {
    text.lines()
        .position(|l| !l.trim().is_empty() && !l.trim().starts_with('#'))
        .map_or(0, |i| i + 1)
}

/// A validated point in the transverse plane, tied to its row.
#[derive(Debug, Clone, Copy)]
struct Point {
    row: Row,
    z: Complex64,
    /// How far, at most, the point can lie from where its values were before they were
    /// rounded to the decimals they are written to, mm (0 for exact data).
    err: f64,
    /// Whether this is the mirror image of the row (a completed half period).
    mirrored: bool,
}

/// Fit the periodic spline profile to `rows`, after validating them, within the points'
/// rounding ([`profile_within`] with no tolerance).
///
/// `p` is the lead parameter (needed to turn axial points into transverse ones) and `starts`
/// the number of starts (the period is `2π / starts`).
pub fn profile(
    rows: &[Row],
    section: Section,
    mirror: bool,
    p: f64,
    starts: u32,
) -> Result<Profile, PointsError> {
    profile_within(rows, section, mirror, p, starts, None)
}

/// Fit the periodic spline profile to `rows`, after validating them: within each point's
/// rounding (half its last decimal), or within `tolerance` mm of each (measured points,
/// their scatter random across it) where that is wider; see [`super::smoothing`]. The
/// outlier check allows the same band.
pub fn profile_within(
    rows: &[Row],
    section: Section,
    mirror: bool,
    p: f64,
    starts: u32,
    tolerance: Option<f64>,
) -> Result<Profile, PointsError> {
    let period = 2.0 * PI / f64::from(starts);
    let needed = 3;
    if rows.len() < needed {
        return Err(PointsError::TooFew {
            found: rows.len(),
            needed,
            what: if mirror { "half period" } else { "period" },
        });
    }
    for row in rows {
        for (value, name) in [(row.a, first_name(section)), (row.b, second_name(section))] {
            if !value.is_finite() {
                return Err(PointsError::NotFinite { row: *row, name });
            }
        }
    }
    // The data's own resolution, each column on its own; none in a column of evenly
    // spaced values, which is the one the points were sampled along (z = 0, 0.5, 1, …):
    // its values are where the points are, not readings rounded to that many decimals.
    let resolution = |values: Vec<f64>| {
        if evenly_spaced(&values) {
            0.0
        } else {
            half_unit(values.into_iter())
        }
    };
    let (half_a, half_b) = (
        resolution(rows.iter().map(|r| r.a).collect()),
        resolution(rows.iter().map(|r| r.b).collect()),
    );
    let mut points = Vec::with_capacity(rows.len());
    for row in rows {
        let (z, err) = match section {
            Section::Transverse => (Complex64::new(row.a, row.b), half_a.hypot(half_b)),
            // ρ off by w_ρ moves the point radially, z off by w_z turns it by w_z/|p|.
            Section::Axial => (
                Complex64::from_polar(row.a, -row.b / p),
                half_a + row.a.abs() * half_b / p.abs(),
            ),
        };
        if z.norm() < 1e-9 || (section == Section::Axial && row.a <= 0.0) {
            return Err(PointsError::OnAxis { row: *row });
        }
        points.push(Point {
            row: *row,
            z,
            err: err.max(tolerance.unwrap_or(0.0)),
            mirrored: false,
        });
    }
    // The profile's size, for the tolerances of "the same point": the median radius, which a
    // single absurd point (at 10³⁰⁸, say) cannot inflate until every other pair looks alike.
    let scale = median(points.iter().map(|q| q.z.norm()).collect());
    for pair in points.windows(2) {
        if (half(pair[1].z) - half(pair[0].z)).norm() <= 0.5e-9 * scale {
            return Err(PointsError::Duplicate {
                row: pair[1].row,
                prev: pair[0].row,
            });
        }
    }
    let angles = unwrapped_angles(&points);
    let dir = direction(&angles);
    check_increasing(&points, &angles, dir)?;
    let span = (angles[angles.len() - 1] - angles[0]).abs();
    let full = if mirror {
        check_span(
            span,
            period / 2.0,
            1e-4,
            "half",
            starts,
            (points[0].row, points[points.len() - 1].row),
        )?;
        mirrored(&points)
    } else {
        let mut pts = points.clone();
        // A closing point equal to the first turned by one period is dropped.
        let turned = pts[0].z * Complex64::from_polar(1.0, dir * period);
        if (half(pts[pts.len() - 1].z) - half(turned)).norm() <= 0.5e-9 * scale {
            pts.pop();
        }
        let span = (angles[pts.len() - 1] - angles[0]).abs();
        if span >= period || pts.len() < needed {
            return Err(PointsError::NotOnePeriod {
                span_deg: span.to_degrees(),
                first: pts[0].row,
                last: pts[pts.len() - 1].row,
                expected: format!("one period is {:.3}°", period.to_degrees()),
                starts,
            });
        }
        pts
    };
    let mut full = full;
    if dir < 0.0 {
        full.reverse();
    }
    check_outliers(&full, period, section, p)?;
    let zs: Vec<Complex64> = full.iter().map(|q| q.z).collect();
    let bends = rounding(&full, period);
    // Rounding matters where it can bend the curve through the points by a hundredth of
    // its mean curvature (the period's turn over the curve's length): dense points written
    // to few decimals. Sparse ones keep the curve through them: between knots far apart,
    // smoothing would move the curve by more than it moves the points.
    let length: f64 = zs
        .iter()
        .zip(zs.iter().skip(1))
        .map(|(a, b)| (b - a).norm())
        .sum();
    let matters = bends.is_some_and(|b| b.bend > 0.01 * period / length);
    let spread = match tolerance {
        Some(_) => Some(Spread::Scatter),
        None => matters.then_some(Spread::Rounding),
    };
    let (spline, fit) = match spread {
        Some(spread) => {
            let band: Vec<f64> = full.iter().map(|q| q.err).collect();
            let curve = smoothing::fit(&zs, &band, spread, period);
            let fit = Fit {
                deviation: curve.deviation,
                line: full[curve.worst].row.line,
                band: band.iter().copied().fold(0.0, f64::max),
                spread,
            };
            (curve.spline, Some(fit))
        }
        None => (Spline::periodic(&zs, period), None),
    };
    let mut fitted = Profile::new(vec![Piece::Spline(spline)], period);
    fitted.rounding = bends;
    fitted.fit = fit;
    Ok(fitted)
}

/// How much the rounding of the points can bend the spline through them (`None` for exact
/// points), from the spline's own equations (`Spline::periodic`): moving the points by up to
/// `e_k` changes the slope of chord `k` by at most `(e_k + e_{k+1})/h_k` and so the right-hand
/// side of row `k` by at most six times the changes of its two slopes, while the row's diagonal
/// exceeds its other entries by `h_{k−1} + h_k`. The second derivatives therefore move by at most
/// the largest ratio of the two (to first order: the chord lengths move a little too).
fn rounding(full: &[Point], period: f64) -> Option<Rounding> {
    let n = full.len();
    let turn = Complex64::from_polar(1.0, period);
    let h: Vec<f64> = (0..n)
        .map(|k| {
            let next = if k + 1 == n {
                full[0].z * turn
            } else {
                full[k + 1].z
            };
            (half(next) - half(full[k].z)).norm() * 2.0
        })
        .collect();
    (0..n)
        .map(|k| {
            let (prev, next) = ((k + n - 1) % n, (k + 1) % n);
            let slopes =
                (full[k].err + full[next].err) / h[k] + (full[prev].err + full[k].err) / h[prev];
            Rounding {
                bend: 6.0 * slopes / (h[prev] + h[k]),
                spacing: h[prev].min(h[k]),
                err: full[prev].err.max(full[k].err).max(full[next].err),
            }
        })
        .filter(|r| r.bend > 0.0)
        .max_by(|a, b| a.bend.total_cmp(&b.bend))
}

fn first_name(section: Section) -> &'static str {
    match section {
        Section::Transverse => "x",
        Section::Axial => "rho",
    }
}

fn second_name(section: Section) -> &'static str {
    match section {
        Section::Transverse => "y",
        Section::Axial => "z",
    }
}

/// Half of `z`: differences of halves never overflow, whatever the finite values.
fn half(z: Complex64) -> Complex64 {
    z * 0.5
}

/// Decimals beyond which values count as exact. Rounding at 12 decimals (0.5·10⁻¹² mm) is far
/// below 1 % of the closest spacing the duplicate check lets through (10⁻⁹ of the profile's
/// size), so a resolution that fine could not change a verdict; below it the check on the
/// value itself stops being exact (|v|·10ᵈ nears 2⁵²).
const MAX_DECIMALS: i32 = 12;

/// Whether `values` step by one amount from first to last, to the precision their size
/// allows (a sampling grid read back from its decimals: 0.0125 and 0.025 are exact).
fn evenly_spaced(values: &[f64]) -> bool {
    let &[first, second, ..] = values else {
        return false;
    };
    let step = second - first;
    let size = values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    step != 0.0
        && values
            .windows(2)
            .all(|pair| ((pair[1] - pair[0]) - step).abs() <= 1e-12 * size)
}

/// The resolution of a column of values: half a unit in the last of the fewest decimals
/// (at most [`MAX_DECIMALS`]) that write every value exactly, or 0 when some value needs more
/// (exact floating-point data, or data given as fractions). `25.8, 12.78, 0` are written to two
/// decimals: 0.005.
fn half_unit(values: impl Iterator<Item = f64>) -> f64 {
    let mut decimals = 0;
    for v in values {
        while !written_to(v, decimals) {
            decimals += 1;
            if decimals > MAX_DECIMALS {
                return 0.0;
            }
        }
    }
    0.5 / 10f64.powi(decimals)
}

/// Whether `v` is the value of a decimal with `d` decimals: `10^d` is exact and the division
/// correctly rounded, so `round(v·10^d) / 10^d` is what parsing that decimal gives.
fn written_to(v: f64, d: i32) -> bool {
    let scale = 10f64.powi(d);
    let scaled = v * scale;
    // From 2⁵² on an f64 holds no fraction at all: v carries no further decimals.
    scaled.abs() >= 4_503_599_627_370_496.0 || scaled.round() / scale == v
}

/// The median of `values` (not empty), in linear time.
fn median(mut values: Vec<f64>) -> f64 {
    let mid = values.len() / 2;
    *values.select_nth_unstable_by(mid, f64::total_cmp).1
}

fn unwrapped_angles(points: &[Point]) -> Vec<f64> {
    let mut out: Vec<f64> = Vec::with_capacity(points.len());
    for q in points {
        let mut a = q.z.arg();
        if let Some(&prev) = out.last() {
            while a - prev > PI {
                a -= 2.0 * PI;
            }
            while a - prev < -PI {
                a += 2.0 * PI;
            }
        }
        out.push(a);
    }
    out
}

/// The way round the points run: the sense of most steps of polar angle (of the first step on a
/// tie), so that one bad point, the first included, cannot set it.
fn direction(angles: &[f64]) -> f64 {
    let steps = angles.len() - 1;
    let up = angles.windows(2).filter(|w| w[1] > w[0]).count();
    match (2 * up).cmp(&steps) {
        std::cmp::Ordering::Greater => 1.0,
        std::cmp::Ordering::Less => -1.0,
        std::cmp::Ordering::Equal => (angles[1] - angles[0]).signum(),
    }
}

/// Every step must keep the direction. Where it turns back, the point named is the one out of
/// order, of the two either side of the step: the later one, unless leaving it out does not
/// mend the order and leaving out the earlier one does, or both would and the earlier one lies
/// farther off the line through the nearest points that are neither (a point far out at a
/// polar angle beyond its successors, a value with a slipped exponent).
fn check_increasing(points: &[Point], angles: &[f64], dir: f64) -> Result<(), PointsError> {
    let n = points.len();
    // Whether point k lies beyond point j the way the points run, compared directly (not
    // through the unwrapping chain, which a wild point can shift by a turn).
    let beyond = |j: usize, k: usize| {
        let d = (points[k].z.arg() - points[j].z.arg()).rem_euclid(2.0 * PI);
        let d = if d > PI { d - 2.0 * PI } else { d };
        d * dir > 0.0
    };
    for i in 1..n {
        if (angles[i] - angles[i - 1]) * dir > 0.0 {
            continue;
        }
        let without_this = i + 1 >= n || beyond(i - 1, i + 1);
        let without_prev = i < 2 || beyond(i - 2, i);
        let culprit = match (without_this, without_prev) {
            (false, true) => i - 1,
            (true, true) if farther_off(points, i - 1) => i - 1,
            _ => i,
        };
        return Err(PointsError::NotIncreasing {
            row: points[culprit].row,
            from_deg: angles[i - 1].to_degrees(),
            to_deg: angles[i].to_degrees(),
        });
    }
    Ok(())
}

/// Whether point `first` lies farther than point `first + 1` off the line through the two
/// nearest points that are neither: the one before and the one after them, or the next two
/// on the side where there are such points.
fn farther_off(points: &[Point], first: usize) -> bool {
    let n = points.len();
    let (a, b) = match (first.checked_sub(1), first + 2 < n) {
        (Some(before), true) => (before, first + 2),
        (None, true) if first + 3 < n => (first + 2, first + 3),
        (Some(before), false) if before >= 1 => (before - 1, before),
        _ => return false,
    };
    let (pa, pb) = (half(points[a].z), half(points[b].z));
    let along = pb - pa;
    if along.norm() == 0.0 {
        return false;
    }
    let unit = along / along.norm();
    // Distances from the line, of halved points alike: never overflows.
    let off = |k: usize| ((half(points[k].z) - pa) * unit.conj()).im.abs();
    off(first) > off(first + 1)
}

fn check_span(
    span: f64,
    want: f64,
    tol: f64,
    what: &str,
    starts: u32,
    (first, last): (Row, Row),
) -> Result<(), PointsError> {
    if (span - want).abs() > tol {
        return Err(PointsError::NotOnePeriod {
            span_deg: span.to_degrees(),
            first,
            last,
            expected: format!(
                "a {what} period (mirror = true) must span exactly {:.3}°",
                want.to_degrees()
            ),
            starts,
        });
    }
    Ok(())
}

/// Complete a half period by its mirror image about the last point's polar angle. The mirror of
/// the first point is the first point of the next period, so it is left out.
///
/// The mirror line runs through the last point as written, which is up to `err` off its true
/// place, so the line is turned by up to `asin(err / ρ)` and every image by up to twice that
/// about the axis: the images' error bounds grow by that much.
fn mirrored(half: &[Point]) -> Vec<Point> {
    let last = half[half.len() - 1];
    let axis = Complex64::from_polar(1.0, 2.0 * last.z.arg());
    let line_turn = (last.err / last.z.norm()).min(1.0).asin();
    let mut full = half.to_vec();
    for q in half[1..half.len() - 1].iter().rev() {
        full.push(Point {
            row: q.row,
            z: axis * q.z.conj(),
            err: q.err + 2.0 * line_turn * q.z.norm(),
            mirrored: true,
        });
    }
    full
}

/// Relative share of the local spacing a point may lie off the cubic through its neighbours
/// before it counts as off the curve (on top of what the data's rounding allows).
const SPACING_SHARE: f64 = 0.01;

/// Flag points where the profile zig-zags or doubles back and which lie off the curve through
/// their neighbours by more than the data can explain.
///
/// **Suspects.** A smooth curve sampled finely enough to be whirled turns one way over any three
/// consecutive samples, and never by more than a right angle at one sample. A point is a
/// suspect when the turn at it has the opposite sense to the turns at both neighbours (a
/// zig-zag), or when the path doubles back at it (a turn beyond 90°: a spike, whose sense of
/// turning is arbitrary). A real sharp edge (the flank meeting the crest in Han & Liu's profile)
/// turns the same way as its neighbours and is not a suspect.
///
/// **The curve through the neighbours.** For suspect `i`, the cubic `c(t)` through the two
/// points on each side, `i−2, i−1, i+1, i+2`, in the chord length of those four; the point
/// itself sits at `t_i`, the chord fraction `|P_i − P_{i−1}| / (|P_i − P_{i−1}| +
/// |P_{i+1} − P_i|)` of the way from `i−1` to `i+1`. Its distance `d_i` from the curve is the
/// exact one: the smallest `|c(t) − P_i|` over the whole stencil, found by a scan and polished
/// to machine precision, not a distance to samples of the curve. Each suspect costs the same
/// few operations, so the check is linear in the number of points.
///
/// **The threshold.** The point is an outlier when
///
/// ```text
/// d_i > 1 % · s_i + e_i + Σ_k |ℓ_k(t_i)| · e_k
/// ```
///
/// with `s_i` the mean of the two chords at the point, `ℓ_k` the Lagrange basis of the cubic
/// (`Σ_k |ℓ_k(t_i)|` is 5/3 for even spacing), and `e_k` how far point `k` can lie from where it
/// was before it was rounded: half a unit in the last decimal of each column (the fewest
/// decimals, at most [`MAX_DECIMALS`], that write every value of the column exactly; 0 for exact
/// floating-point data), `hypot(w_x, w_y)` for transverse points, `w_ρ + ρ·w_z/|p|` for axial
/// ones, plus the turn of the mirror line for mirrored images.
///
/// Rounding alone cannot reach it. The cubic through the rounded neighbours is the cubic
/// through the true neighbours plus the cubic through their rounding errors ε_k, which at
/// `t_i` is `Σ_k ℓ_k(t_i)·ε_k`, at most `Σ_k |ℓ_k(t_i)|·e_k` long; the point itself is at most
/// `e_i` from its true place; and the distance to the curve is at most the distance to
/// `c(t_i)`. So a point of a smooth curve lies within `e_i + Σ|ℓ_k|·e_k` of the rounded
/// neighbours' cubic, plus the cubic's own error on the true curve, which is O(s⁴·curvature
/// change) and, as in the check this replaces, well within 1 % of the spacing for any profile
/// sampled finely enough to be whirled. (Chord lengths measured on rounded points shift the
/// parameters; for points that are nearly in line that changes the cubic only to second order.)
/// A dense exact profile written to 4 decimals (e ≈ 7·10⁻⁵ mm) thus passes however close its
/// points, while Han & Liu's (25.8, 12.78), written to 2 decimals, lies 0.68 mm off against a
/// threshold of about 0.05 mm.
///
/// A bad point makes its neighbours zig-zag too; the one reported is the one farthest over its
/// threshold.
///
/// Everything is computed relative to the suspect and scaled by a power of two (exact), so
/// absurd values neither overflow nor let a neighbour take the blame: a point at 10³⁰⁸ lies
/// about 100 spacings off the curve through its neighbours, while its neighbours, whose
/// spacing it inflates, lie well within theirs.
fn check_outliers(
    full: &[Point],
    period: f64,
    section: Section,
    p: f64,
) -> Result<(), PointsError> {
    let n = full.len();
    if n < 5 {
        return Ok(());
    }
    let turn_fwd = Complex64::from_polar(1.0, period);
    let index = |i: isize| i.rem_euclid(n as isize) as usize;
    let at = |i: isize| -> Complex64 {
        let wraps = i.div_euclid(n as isize) as i32;
        full[index(i)].z * turn_fwd.powi(wraps)
    };
    // Direction of the chord from point i to point i + 1, and the turn at each point.
    let heading: Vec<f64> = (0..n as isize)
        .map(|i| (half(at(i + 1)) - half(at(i))).arg())
        .collect();
    let turning: Vec<f64> = (0..n)
        .map(|i| {
            // The chord arriving at point 0 is the last one turned back by a period.
            let arriving = if i == 0 {
                heading[n - 1] - period
            } else {
                heading[i - 1]
            };
            let d = (heading[i] - arriving).rem_euclid(2.0 * PI);
            if d > PI {
                d - 2.0 * PI
            } else {
                d
            }
        })
        .collect();
    let mut worst: Option<(f64, PointsError)> = None;
    for i in 0..n {
        if full[i].mirrored {
            continue; // its original gives the same verdict, in the user's coordinates
        }
        let (before, here, after) = (turning[(i + n - 1) % n], turning[i], turning[(i + 1) % n]);
        let zig_zag = here.signum() != before.signum() && here.signum() != after.signum();
        let spike = here.abs() > PI / 2.0;
        if !(zig_zag || spike) {
            continue;
        }
        // Three neighbours each side, leaving out the point's own mirror image (the same
        // row, no evidence of its own).
        let line = full[i].row.line;
        let i = i as isize;
        let side = |step: isize| {
            let mut found = [0isize; 3];
            let (mut k, mut count) = (i, 0);
            while count < 3 {
                k += step;
                if full[index(k)].row.line != line {
                    found[count] = k;
                    count += 1;
                }
            }
            found
        };
        let (left, right) = (side(-1), side(1));
        let judge = |stencil: [isize; 4]| {
            off_neighbours(
                at(i),
                full[index(i)].err,
                stencil.map(at),
                stencil.map(|k| full[index(k)].err),
            )
        };
        let mut verdict = judge([left[1], left[0], right[0], right[1]]);
        if verdict.far && n >= 9 {
            // Far from both neighbours: either the point is absurd, or its neighbours are (a
            // point next to an absurd one and its mirror image). Judged against the points
            // beyond them as well, it is an outlier only if it is far from those too.
            let wider = judge([left[2], left[1], right[1], right[2]]);
            if wider.ratio < verdict.ratio {
                verdict = wider;
            }
        }
        if verdict.ratio > 1.0 && worst.as_ref().is_none_or(|(r, _)| verdict.ratio > *r) {
            let near = verdict.near;
            let (near_a, near_b) = match section {
                Section::Transverse => (near.re, near.im),
                Section::Axial => (near.norm(), -near.arg() * p),
            };
            let error = PointsError::Outlier {
                row: full[index(i)].row,
                off_mm: verdict.off,
                near_a,
                near_b,
                limit_mm: verdict.limit,
            };
            worst = Some((verdict.ratio, error));
        }
    }
    if let Some((_, error)) = worst {
        return Err(error);
    }
    Ok(())
}

/// How a point lies against the curve through its neighbours.
#[derive(Debug, Clone, Copy)]
struct Verdict {
    /// Distance from the curve, mm.
    off: f64,
    /// The most a point of a smooth curve could lie off it, mm.
    limit: f64,
    /// `off / limit`, computed without overflow.
    ratio: f64,
    /// The nearest point of the curve.
    near: Complex64,
    /// Whether the point lies far beyond its neighbours' stencil (judged by distance alone).
    far: bool,
}

/// Offsets beyond this many times the inner neighbours' distance count as far: the cubic
/// through such a stencil means nothing, and a point that far is judged by its distance alone.
const FAR: f64 = 1_048_576.0;

/// The point `point` (error bound `err`) against the cubic through `stencil` (the two points
/// before it and the two after, with their error bounds `errs`): see [`check_outliers`].
///
/// Coordinates are taken relative to the midpoint of the inner neighbours and divided by a
/// power of two `m` of their distance (exact), so the stencil keeps its precision and nothing
/// overflows, whatever the magnitudes: a point at 10³⁰⁸ next to ordinary neighbours is judged
/// by its distance from them, and ordinary points next to it lose nothing.
fn off_neighbours(point: Complex64, err: f64, stencil: [Complex64; 4], errs: [f64; 4]) -> Verdict {
    let centre = half(stencil[1]) + half(stencil[2]);
    // Half a distance from the centre: never overflows.
    let from_centre = |q: Complex64| (half(q) - half(centre)).norm();
    let inner = from_centre(stencil[1]);
    let size = if inner > 0.0 {
        inner
    } else {
        // The inner neighbours coincide: size the stencil by everything else.
        stencil
            .iter()
            .chain([&point])
            .map(|&q| from_centre(q))
            .fold(0.0, f64::max)
    };
    // Half the mean of the two chords at the point, as a sum of quarters: never overflows.
    let half_spacing = (half(point) - half(stencil[1])).norm() / 2.0
        + (half(stencil[2]) - half(point)).norm() / 2.0;
    let nothing = Verdict {
        off: 0.0,
        limit: 0.0,
        ratio: 0.0,
        near: point,
        far: false,
    };
    if size.is_nan() || size <= 0.0 {
        return nothing; // every point of the stencil in one place: nothing to judge by
    }
    if from_centre(point) > FAR * size {
        // Millions of stencil sizes away: the distance to the curve is the distance to the
        // neighbours, to a millionth.
        let off_half = from_centre(point);
        let limit_half = SPACING_SHARE * half_spacing + (err + errs[1].max(errs[2])) / 2.0;
        return Verdict {
            off: (2.0 * off_half).min(f64::MAX),
            limit: (2.0 * limit_half).min(f64::MAX),
            ratio: off_half / limit_half,
            near: centre,
            far: true,
        };
    }
    let m = 2f64.powi((size.log2().floor() as i32 + 2).clamp(-1022, 1023));
    let d = stencil.map(|q| q / m - centre / m);
    let pd = point / m - centre / m;
    let (a, b) = ((pd - d[1]).norm(), (d[2] - pd).norm());
    let h = [
        (d[1] - d[0]).norm(),
        (d[2] - d[1]).norm(),
        (d[3] - d[2]).norm(),
    ];
    let t = [0.0, h[0], h[0] + h[1], h[0] + h[1] + h[2]];
    let share = if a + b > 0.0 { a / (a + b) } else { 0.5 };
    let t_point = t[1] + (t[2] - t[1]) * share;
    let outer_near = d[0].norm() <= 4.0 * FAR && d[3].norm() <= 4.0 * FAR;
    let cubic = outer_near
        .then(|| Cubic::through(t, d.map(|q| q - pd)))
        .flatten();
    let (near, neighbour_err) = match cubic {
        Some(cubic) => {
            let u = cubic.nearest_to_origin(t[0], t[3]);
            let weights = lagrange_weights(t, t_point);
            let spread = weights.iter().zip(errs).map(|(l, e)| l.abs() * e).sum();
            (pd + cubic.eval(u).0, spread)
        }
        // An absurd outer neighbour, or nodes that coincide in f64: the chord between the
        // inner neighbours, whose weights are at most 1 in all.
        None => {
            let chord = d[2] - d[1];
            let s = if chord.norm_sqr() > 0.0 {
                ((pd - d[1]).conj() * chord).re / chord.norm_sqr()
            } else {
                0.0
            };
            (d[1] + chord * s.clamp(0.0, 1.0), errs[1].max(errs[2]))
        }
    };
    let limit = SPACING_SHARE * 2.0 * (half_spacing / m) + (err + neighbour_err) / m;
    let off = (pd - near).norm();
    Verdict {
        off: off * m,
        limit: limit * m,
        ratio: off / limit,
        near: centre + near * m,
        far: false,
    }
}

/// The Lagrange weights of the cubic through nodes `t` at `u`: the cubic's value there is
/// `Σ_k ℓ_k(u)·P_k`, so errors `e_k` of the points add up to at most `Σ_k |ℓ_k(u)|·e_k`.
fn lagrange_weights(t: [f64; 4], u: f64) -> [f64; 4] {
    std::array::from_fn(|k| {
        (0..4)
            .filter(|&j| j != k)
            .map(|j| (u - t[j]) / (t[k] - t[j]))
            .product()
    })
}

/// A cubic through four points, in Newton form.
#[derive(Debug, Clone, Copy)]
struct Cubic {
    /// The first three nodes.
    t: [f64; 3],
    /// Divided differences: `c(u) = c0 + (u − t0)(c1 + (u − t1)(c2 + (u − t2)·c3))`.
    c: [Complex64; 4],
}

impl Cubic {
    /// The cubic through `points` at nodes `t`; `None` unless the nodes strictly increase and
    /// the differences are finite.
    fn through(t: [f64; 4], points: [Complex64; 4]) -> Option<Cubic> {
        if !(t[0] < t[1] && t[1] < t[2] && t[2] < t[3]) {
            return None;
        }
        let d1: [Complex64; 3] =
            std::array::from_fn(|k| (points[k + 1] - points[k]) / (t[k + 1] - t[k]));
        let d2: [Complex64; 2] = std::array::from_fn(|k| (d1[k + 1] - d1[k]) / (t[k + 2] - t[k]));
        let d3 = (d2[1] - d2[0]) / (t[3] - t[0]);
        let c = [points[0], d1[0], d2[0], d3];
        c.iter()
            .all(|z| z.re.is_finite() && z.im.is_finite())
            .then_some(Cubic {
                t: [t[0], t[1], t[2]],
                c,
            })
    }

    /// Position, first and second derivative at `u`.
    fn eval(&self, u: f64) -> (Complex64, Complex64, Complex64) {
        let zero = Complex64::new(0.0, 0.0);
        let (mut p, mut d1, mut d2) = (self.c[3], zero, zero);
        for k in (0..3).rev() {
            let x = u - self.t[k];
            d2 = d2 * x + d1 * 2.0;
            d1 = d1 * x + p;
            p = p * x + self.c[k];
        }
        (p, d1, d2)
    }

    /// The parameter in `[lo, hi]` of the point nearest the origin: a scan for the basin, then
    /// Newton's method on the derivative of the squared distance, safeguarded by bisection
    /// inside the basin, to machine precision.
    fn nearest_to_origin(&self, lo: f64, hi: f64) -> f64 {
        const SCAN: usize = 16;
        let dist = |u: f64| self.eval(u).0.norm_sqr();
        let at = |k: usize| lo + (hi - lo) * k as f64 / SCAN as f64;
        let best = (0..=SCAN)
            .min_by(|&j, &k| dist(at(j)).total_cmp(&dist(at(k))))
            .unwrap_or(0);
        let (mut a, mut b) = (at(best.saturating_sub(1)), at((best + 1).min(SCAN)));
        let mut u = at(best);
        for _ in 0..100 {
            let (p, d1, d2) = self.eval(u);
            // g = ½·d|c|²/du, and its derivative.
            let g = (p.conj() * d1).re;
            let dg = d1.norm_sqr() + (p.conj() * d2).re;
            if g > 0.0 {
                b = u;
            } else if g < 0.0 {
                a = u;
            } else {
                break;
            }
            let newton = u - g / dg;
            let next = if dg > 0.0 && newton > a && newton < b {
                newton
            } else {
                (a + b) / 2.0
            };
            let converged = (next - u).abs() <= 4.0 * f64::EPSILON * (hi - lo);
            u = next;
            if converged {
                break;
            }
        }
        // The nearest point may be an end of the basin (an end of the stencil).
        [a, u, b]
            .into_iter()
            .min_by(|&x, &y| dist(x).total_cmp(&dist(y)))
            .unwrap_or(u)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    const HAN_LIU: &str = include_str!(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/han-liu-table1.csv"
    ));
    const P_HAN_LIU: f64 = 88.0 / (2.0 * PI);

    fn rows(pts: &[(f64, f64)]) -> Vec<Row> {
        pts.iter()
            .enumerate()
            .map(|(i, &(a, b))| Row { line: i + 1, a, b })
            .collect()
    }

    #[test]
    fn reads_csv_with_and_without_header() {
        let r = read_csv("x,y\n1,2\n\n# note\n3.5, -4\n").unwrap();
        assert_eq!(
            r,
            vec![
                Row {
                    line: 2,
                    a: 1.0,
                    b: 2.0
                },
                Row {
                    line: 5,
                    a: 3.5,
                    b: -4.0
                }
            ]
        );
        assert_eq!(read_csv("1,2\n3,4\n").unwrap().len(), 2);
    }

    #[test]
    fn csv_errors_name_the_line() {
        let e = read_csv("x,y\n1,2\n3,abc\n").unwrap_err();
        assert!(matches!(e, PointsError::Syntax { line: 3, .. }), "{e}");
        assert!(e.to_string().contains("\"abc\""));
        let e = read_csv("1,2\n1,2,3\n").unwrap_err();
        assert!(matches!(e, PointsError::Syntax { line: 2, .. }), "{e}");
    }

    #[test]
    fn han_liu_outlier_is_reported_by_row_and_coordinates() {
        let r = read_csv(HAN_LIU).unwrap();
        let e = profile(&r, Section::Transverse, true, P_HAN_LIU, 2).unwrap_err();
        let PointsError::Outlier { row, near_a, .. } = &e else {
            panic!("expected the outlier, got {e}");
        };
        // The file has a header, so Table 1's 8th point is on line 9.
        assert_eq!((row.line, row.a, row.b), (9, 25.8, 12.78));
        // Its neighbours put it near x = 25.08 (tests/data/README.md).
        assert!((near_a - 25.08).abs() < 0.1, "{e}");
        let text = e.to_string();
        assert!(text.contains("line 9") && text.contains("25.8") && text.contains("12.78"));
    }

    #[test]
    fn han_liu_with_the_point_corrected_is_accepted() {
        let fixed = HAN_LIU.replace("25.8,12.78", "25.08,12.78");
        let r = read_csv(&fixed).unwrap();
        let prof = profile(&r, Section::Transverse, true, P_HAN_LIU, 2).unwrap();
        // The mirrored full period is symmetric about the crest (90°) and closes at 180°.
        let (lo, hi) = prof.radius_range();
        assert!((lo - 27.5).abs() < 0.05 && hi >= 42.5 - 1e-9, "{lo} {hi}");
    }

    #[test]
    fn every_validation_error_names_its_point() {
        let ok = [
            (30.0, 0.0),
            (29.0, 8.0),
            (26.0, 15.0),
            (21.0, 21.0),
            (15.0, 26.0),
            (0.0, 35.0),
        ];
        let prof =
            |pts: &[(f64, f64)], mirror| profile(&rows(pts), Section::Transverse, mirror, 14.0, 2);
        assert!(prof(&ok, true).is_ok());
        let e = prof(&ok[..2], true).unwrap_err();
        assert!(matches!(e, PointsError::TooFew { found: 2, .. }), "{e}");
        let mut nan = ok;
        nan[2].1 = f64::NAN;
        assert!(matches!(
            prof(&nan, true).unwrap_err(),
            PointsError::NotFinite {
                row: Row { line: 3, .. },
                name: "y"
            }
        ));
        let mut dup = ok.to_vec();
        dup.insert(3, ok[2]);
        assert!(matches!(
            prof(&dup, true).unwrap_err(),
            PointsError::Duplicate {
                row: Row { line: 4, .. },
                ..
            }
        ));
        let mut axis = ok;
        axis[3] = (0.0, 0.0);
        assert!(matches!(
            prof(&axis, true).unwrap_err(),
            PointsError::OnAxis {
                row: Row { line: 4, .. }
            }
        ));
        let mut back = ok;
        back.swap(2, 3);
        assert!(matches!(
            prof(&back, true).unwrap_err(),
            PointsError::NotIncreasing {
                row: Row { line: 4, .. },
                ..
            }
        ));
        let short = [
            (30.0, 0.0),
            (29.0, 8.0),
            (26.0, 15.0),
            (21.0, 21.0),
            (15.0, 26.0),
        ];
        let e = prof(&short, true).unwrap_err();
        assert!(matches!(e, PointsError::NotOnePeriod { .. }), "{e}");
        assert!(e.to_string().contains("90.000°"), "{e}");
        // A full period of a 2-start groove may not reach 180°.
        let too_long = [(30.0, 0.0), (0.0, 30.0), (-30.0, 1.0), (-20.0, -10.0)];
        assert!(matches!(
            prof(&too_long, false).unwrap_err(),
            PointsError::NotOnePeriod { .. }
        ));
    }

    #[test]
    fn a_closing_point_is_dropped_and_direction_may_be_reversed() {
        // ρ(φ) = 30 − 5 cos(3φ), a full period of a 3-start groove, 12 points.
        let pts: Vec<(f64, f64)> = (0..=12)
            .map(|i| {
                let phi = 2.0 * PI / 3.0 * i as f64 / 12.0;
                let rho = 30.0 - 5.0 * (3.0 * phi).cos();
                (rho * phi.cos(), rho * phi.sin())
            })
            .collect();
        let forward = profile(&rows(&pts), Section::Transverse, false, 10.0, 3).unwrap();
        let mut rev = pts.clone();
        rev.reverse();
        let backward = profile(&rows(&rev), Section::Transverse, false, 10.0, 3).unwrap();
        for prof in [forward, backward] {
            let a0 = prof.point(0.0).pos.to_angle();
            let a1 = prof.point(prof.length() * 0.01).pos.to_angle();
            assert!(a1 > a0, "polar angle increases along the profile");
            for k in 0..200 {
                let q = prof.point(prof.length() * k as f64 / 200.0).pos;
                let rho = 30.0 - 5.0 * (3.0 * q.to_angle()).cos();
                assert!(
                    (q.length() - rho).abs() < 0.05,
                    "close to the sampled curve"
                );
            }
        }
    }

    #[test]
    fn axial_points_are_turned_by_minus_z_over_p() {
        // A circle-ish groove given axially, half a period of a 1-start, 10 mm lead thread.
        let p = 10.0 / (2.0 * PI);
        let half: Vec<(f64, f64)> = (0..=10)
            .map(|i| {
                let z = 5.0 * i as f64 / 10.0; // 0 … half the lead
                (20.0 - 2.0 * (PI * z / 5.0).cos(), z)
            })
            .collect();
        let prof = profile(&rows(&half), Section::Axial, true, p, 1).unwrap();
        for k in 0..100 {
            let q = prof.point(prof.length() * k as f64 / 100.0).pos;
            let z = -q.to_angle() * p;
            let rho = 20.0 - 2.0 * (PI * z / 5.0).cos();
            assert!((q.length() - rho).abs() < 0.01, "{} vs {rho}", q.length());
        }
    }

    /// `n` points of one period of ρ = 30 − 4·cos 2φ (a 2-start groove, 0 ≤ φ < π), written
    /// to `decimals` (`None`: at full precision), a header on line 1.
    fn two_lobes(n: usize, decimals: Option<usize>) -> Vec<Row> {
        let written = |v: f64| match decimals {
            Some(d) => format!("{v:.d$}").parse::<f64>().unwrap(),
            None => v,
        };
        (0..n)
            .map(|k| {
                let phi = PI * k as f64 / n as f64;
                let rho = 30.0 - 4.0 * (2.0 * phi).cos();
                Row {
                    line: k + 2,
                    a: written(rho * phi.cos()),
                    b: written(rho * phi.sin()),
                }
            })
            .collect()
    }

    /// Largest radial distance of the fitted profile from ρ = 30 − 4·cos 2φ.
    fn off_two_lobes(prof: &Profile) -> f64 {
        (0..4000)
            .map(|k| prof.point(prof.length() * k as f64 / 4000.0).pos)
            .map(|q| (q.length() - (30.0 - 4.0 * (2.0 * q.to_angle()).cos())).abs())
            .fold(0.0, f64::max)
    }

    #[test]
    fn dense_profiles_pass_at_the_decimals_they_are_written_to() {
        // 4 decimals 0.09 mm apart, 6 decimals 5 µm apart, exact values 0.5 µm apart: the
        // rounding zig-zags everywhere, but never beyond what the decimals allow.
        for (n, decimals, close) in [
            (1000, Some(4), 1e-3),
            (20_000, Some(6), 1e-4),
            (200_000, None, 1e-9),
        ] {
            let prof = profile(&two_lobes(n, decimals), Section::Transverse, false, 10.0, 2)
                .unwrap_or_else(|e| panic!("{n} points at {decimals:?} decimals: {e}"));
            let off = off_two_lobes(&prof);
            assert!(off < close, "{n} points: {off} mm off the groove");
        }
        // The same groove given axially (ρ, z) at 4 decimals: a z rounded by w turns the point
        // by w/|p|, ρ·w/|p| at its radius.
        let p = 60.0 / TAU;
        let axial: Vec<Row> = (0..1000)
            .map(|k| {
                let phi = PI * k as f64 / 1000.0;
                let four = |v: f64| format!("{v:.4}").parse::<f64>().unwrap();
                Row {
                    line: k + 1,
                    a: four(30.0 - 4.0 * (2.0 * phi).cos()),
                    b: four(-phi * p),
                }
            })
            .collect();
        let prof = profile(&axial, Section::Axial, false, p, 2).unwrap();
        assert!(off_two_lobes(&prof) < 1e-3);
    }

    #[test]
    fn an_outlier_among_dense_points_is_named_by_its_line() {
        // 20 000 points at 6 decimals, 4.7 µm apart; one pushed out by 2 µm, 40 % of the
        // spacing and far beyond the rounding.
        let mut rows = two_lobes(20_000, Some(6));
        let bad = &mut rows[12_345];
        let six = |v: f64| format!("{v:.6}").parse::<f64>().unwrap();
        let scale = 1.0 + 0.002 / bad.a.hypot(bad.b);
        (bad.a, bad.b) = (six(bad.a * scale), six(bad.b * scale));
        let line = bad.line;
        let e = profile(&rows, Section::Transverse, false, 10.0, 2).unwrap_err();
        let PointsError::Outlier { row, off_mm, .. } = &e else {
            panic!("expected the outlier, got {e}");
        };
        assert_eq!(row.line, line, "{e}");
        assert!((off_mm - 0.002).abs() < 2e-4, "{e}");
    }

    #[test]
    fn a_point_at_1e308_is_named_by_its_own_line() {
        // The double-start example's half period (header on line 1), with one point made
        // absurd: every other pair once looked like a duplicate next to it, and sums of
        // its offsets overflowed.
        let half: Vec<(f64, f64)> = (0..13)
            .map(|k| {
                let phi = PI / 2.0 * k as f64 / 12.0;
                let rho = 30.0 - 4.0 * (2.0 * phi).cos();
                (rho * phi.cos(), rho * phi.sin())
            })
            .collect();
        let max = f64::MAX;
        for absurd in [
            (1e308, 1e308),
            (1e308, 9.0),
            (25.0, 1e308),
            (-1e308, 5.0),
            (-1e308, -1e308),
            (5.0, -1e308),
            (max, max),
            (-max, max),
            (1e20, 1e20),
        ] {
            for k in 0..half.len() {
                let mut pts = half.clone();
                pts[k] = absurd;
                let rows: Vec<Row> = pts
                    .iter()
                    .enumerate()
                    .map(|(i, &(a, b))| Row { line: i + 2, a, b })
                    .collect();
                let e = profile(&rows, Section::Transverse, true, 60.0 / TAU, 2).unwrap_err();
                let text = e.to_string();
                assert!(
                    text.contains(&format!("line {} (", k + 2)),
                    "{absurd:?} on line {}: {text}",
                    k + 2
                );
                assert!(text.len() < 600, "numbers spelt out: {text}");
            }
        }
    }

    #[test]
    fn the_resolution_is_half_the_last_decimal_every_value_needs() {
        let of = |v: &[f64]| half_unit(v.iter().copied());
        assert_eq!(of(&[25.8, 12.78, 0.0]), 0.005);
        assert_eq!(of(&[30.0, -8.0]), 0.5);
        assert_eq!(of(&[25.9127, 3.4115, 1e308]), 0.00005);
        // Exact floating-point data has no resolution of its own.
        assert_eq!(of(&[1.0 / 3.0]), 0.0);
        assert_eq!(of(&[(2.0f64).sqrt() * 30.0]), 0.0);
        assert_eq!(of(&[0.123_456_789_012]), 0.5e-12);
    }

    /// The spline piece of a profile fitted from points.
    fn spline_of(prof: &Profile) -> &Spline {
        match &prof.pieces[..] {
            [Piece::Spline(spline)] => spline,
            _ => panic!("a profile from points is one spline"),
        }
    }

    #[test]
    fn the_rounding_bound_holds_the_spline_through_rounded_points_to_the_exact_one() {
        // 2000 points 0.05 mm apart at 4 and at 6 decimals, against the same points unrounded:
        // the second derivatives at the knots differ by no more than the bound.
        let exact = profile(&two_lobes(2000, None), Section::Transverse, false, 10.0, 2).unwrap();
        assert_eq!(exact.rounding(), None, "exact points have nothing to round");
        let exact = spline_of(&exact);
        for decimals in [4, 6] {
            let prof = profile(
                &two_lobes(2000, Some(decimals)),
                Section::Transverse,
                false,
                10.0,
                2,
            )
            .unwrap();
            let bound = prof.rounding().expect("rounded points");
            // Half a unit of the last decimal in x and in y.
            let half = 0.5 * 10f64.powi(-(decimals as i32));
            assert_eq!(bound.err, half.hypot(half));
            let rounded = spline_of(&prof);
            let moved = (0..2000)
                .map(|k| {
                    let at = |s: &Spline| s.eval(s.knots()[k]).d2;
                    (at(rounded) - at(exact)).norm()
                })
                .fold(0.0, f64::max);
            assert!(
                moved <= bound.bend,
                "{decimals} decimals: {moved} > {bound:?}"
            );
            // For evenly spaced points the bound is 12·e/h² (6·4e/h over 2h).
            let h = bound.spacing;
            let even = 12.0 * bound.err / (h * h);
            assert!(
                (bound.bend - even).abs() < 1e-3 * even,
                "{bound:?} vs {even}"
            );
        }
    }
}
