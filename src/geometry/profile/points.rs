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
//! period (or exactly half of one when mirrored), and outliers: points that make the curvature
//! spike, found by comparing each point with the spline through all the others.

use super::spline::Spline;
use super::{Piece, Profile};
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
        write!(f, "line {} ({}, {})", self.line, self.a, self.b)
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
        "the points span {span_deg:.3}° of polar angle; {expected} of a {starts}-start groove"
    )]
    NotOnePeriod {
        /// Span of the points.
        span_deg: f64,
        /// What was expected.
        expected: String,
        /// Number of starts.
        starts: u32,
    },
    /// A point far off the curve through its neighbours.
    #[error(
        "{row} is an outlier: it lies {off_mm:.3} mm off the curve through the other points \
         (which passes ({near_a:.3}, {near_b:.3}) there), so the profile's curvature spikes"
    )]
    Outlier {
        /// The point.
        row: Row,
        /// Distance from the curve through the others, mm.
        off_mm: f64,
        /// Nearest point of that curve, in the input's section coordinates.
        near_a: f64,
        /// Second coordinate of it.
        near_b: f64,
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
    /// Whether this is the mirror image of the row (a completed half period).
    mirrored: bool,
}

/// Fit the periodic spline profile through `rows`, after validating them.
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
    let period = 2.0 * PI / f64::from(starts);
    let needed = 3;
    if rows.len() < needed {
        return Err(PointsError::TooFew {
            found: rows.len(),
            needed,
            what: if mirror { "half period" } else { "period" },
        });
    }
    let mut points = Vec::with_capacity(rows.len());
    for row in rows {
        for (value, name) in [(row.a, first_name(section)), (row.b, second_name(section))] {
            if !value.is_finite() {
                return Err(PointsError::NotFinite { row: *row, name });
            }
        }
        let z = match section {
            Section::Transverse => Complex64::new(row.a, row.b),
            Section::Axial => Complex64::from_polar(row.a, -row.b / p),
        };
        if z.norm() < 1e-9 || (section == Section::Axial && row.a <= 0.0) {
            return Err(PointsError::OnAxis { row: *row });
        }
        points.push(Point {
            row: *row,
            z,
            mirrored: false,
        });
    }
    let scale = points.iter().map(|q| q.z.norm()).fold(0.0, f64::max);
    for pair in points.windows(2) {
        if (pair[1].z - pair[0].z).norm() <= 1e-9 * scale {
            return Err(PointsError::Duplicate {
                row: pair[1].row,
                prev: pair[0].row,
            });
        }
    }
    let angles = unwrapped_angles(&points);
    // One way round: the first step sets the direction, every step must keep it.
    let dir = (angles[1] - angles[0]).signum();
    for i in 1..points.len() {
        if (angles[i] - angles[i - 1]) * dir <= 0.0 {
            return Err(PointsError::NotIncreasing {
                row: points[i].row,
                from_deg: angles[i - 1].to_degrees(),
                to_deg: angles[i].to_degrees(),
            });
        }
    }
    let span = (angles[angles.len() - 1] - angles[0]).abs();
    let full = if mirror {
        check_span(span, period / 2.0, 1e-4, "half", starts)?;
        mirrored(&points)
    } else {
        let mut pts = points.clone();
        // A closing point equal to the first turned by one period is dropped.
        let turned = pts[0].z * Complex64::from_polar(1.0, dir * period);
        if (pts[pts.len() - 1].z - turned).norm() <= 1e-9 * scale {
            pts.pop();
        }
        let span = (angles[pts.len() - 1] - angles[0]).abs();
        if span >= period || pts.len() < needed {
            return Err(PointsError::NotOnePeriod {
                span_deg: span.to_degrees(),
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
    let spline = Spline::periodic(&full.iter().map(|q| q.z).collect::<Vec<_>>(), period);
    Ok(Profile::new(vec![Piece::Spline(spline)], period))
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

fn check_span(span: f64, want: f64, tol: f64, what: &str, starts: u32) -> Result<(), PointsError> {
    if (span - want).abs() > tol {
        return Err(PointsError::NotOnePeriod {
            span_deg: span.to_degrees(),
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
fn mirrored(half: &[Point]) -> Vec<Point> {
    let last = half[half.len() - 1].z;
    let axis = Complex64::from_polar(1.0, 2.0 * last.arg());
    let mut full = half.to_vec();
    for q in half[1..half.len() - 1].iter().rev() {
        full.push(Point {
            row: q.row,
            z: axis * q.z.conj(),
            mirrored: true,
        });
    }
    full
}

/// Flag points whose removal straightens a zig-zag: the turn at the point has the opposite
/// sense to the turns at both neighbours, and the point lies more than 1 % of the local spacing
/// off the spline through all the other points. A smooth curve sampled finely enough to be
/// whirled turns one way over any three consecutive samples; a real sharp edge (the flank meeting
/// the crest in Han & Liu's profile) turns the same way at the edge and its neighbours.
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
    let at = |i: isize| -> Complex64 {
        let k = i.rem_euclid(n as isize) as usize;
        let wraps = i.div_euclid(n as isize) as i32;
        full[k].z * turn_fwd.powi(wraps)
    };
    let turning = |i: isize| ((at(i + 1) - at(i)) / (at(i) - at(i - 1))).arg();
    // A bad point makes its neighbours zig-zag too; the one to report is the one that lies
    // farthest off the curve through the others, relative to the local spacing.
    let mut worst: Option<(f64, PointsError)> = None;
    for i in 0..n as isize {
        if full[i as usize].mirrored {
            continue; // its original gives the same verdict, in the user's coordinates
        }
        let (before, here, after) = (turning(i - 1), turning(i), turning(i + 1));
        if here.signum() == before.signum() || here.signum() == after.signum() {
            continue;
        }
        let others: Vec<Complex64> = (0..n)
            .filter(|&k| full[k].row.line != full[i as usize].row.line)
            .map(|k| full[k].z)
            .collect();
        if others.len() < 3 {
            continue;
        }
        let spline = Spline::periodic(&others, period);
        let point = at(i);
        let (near, off) = (0..=4000)
            .map(|k| spline.eval(spline.length() * k as f64 / 4000.0).p)
            .map(|q| (q, (q - point).norm()))
            .fold(
                (point, f64::INFINITY),
                |best, c| if c.1 < best.1 { c } else { best },
            );
        let spacing = ((at(i) - at(i - 1)).norm() + (at(i + 1) - at(i)).norm()) / 2.0;
        let ratio = off / spacing;
        if ratio > 0.01 && worst.as_ref().is_none_or(|(r, _)| ratio > *r) {
            let (near_a, near_b) = match section {
                Section::Transverse => (near.re, near.im),
                Section::Axial => (near.norm(), -near.arg() * p),
            };
            let error = PointsError::Outlier {
                row: full[i as usize].row,
                off_mm: off,
                near_a,
                near_b,
            };
            worst = Some((ratio, error));
        }
    }
    if let Some((_, error)) = worst {
        return Err(error);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
