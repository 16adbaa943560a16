//! A measured section of a cut groove: the points a profile projector or a coordinate
//! measuring machine took in one plane, read in the frame their file states, and each
//! point's deviation from the target groove along its normal (`docs/measure.md`).
//!
//! The file is CSV with a header of `# key = value` lines that states the frame: which
//! section (the axial half-plane at a polar angle of the workpiece frame W, or the
//! transverse plane at a z of W), the units, which axis each column is, and where the file's
//! zero lies in W. Every key must be stated, in the header or by the caller (`--frame`), and
//! where both state one they must agree: a measurement read in the wrong frame would be
//! taken for a badly cut part, so nothing is assumed.
//!
//! The target section is the helical surface of kinematics.md cut by that plane: in the
//! axial half-plane at polar angle φ₀ the profile point P(u) (radius ρ(u), polar angle φ(u))
//! lies at `z = p·(φ₀ − φ(u)) + j·p·T` for every whole j (one copy per start and turn); in
//! the transverse plane at z₀ it is P(u) turned by `z₀/p + j·T`. A measured point's foot on
//! that curve is where the line from the curve to the point is along the curve's normal
//! (found by sign changes over dense samples, polished by Brent's method, the nearest
//! root kept), so a convex edge, where the normal fans round a fixed point, has a foot too.
//!
//! Two deviations are reported at each point, both signed as kinematics.md's error
//! (negative overcut, positive undercut; the outward normal runs from the material into the
//! groove): `in_section_mm`, along the section curve's normal in the measured plane, which
//! is what a projector shows; and `deviation_mm`, along the surface's own normal, which is
//! what Δ bounds and what the engine measures. The surface moved by e along its normal
//! cuts the plane in the curve moved by e/s along the curve's normal, s being the length of
//! the unit surface normal's projection on the plane, so `deviation_mm = s·in_section_mm`.

use crate::config::job::Job;
use crate::geometry::brent;
use crate::geometry::profile::Profile;
use crate::judge::svg::{Plot, Series};
use crate::judge::verify::magnification;
use glam::{DVec2, DVec3};
use serde::Serialize;
use std::f64::consts::{PI, TAU};
use std::fmt;

/// The header's keys.
const KEYS: [&str; 6] = ["section", "angle_deg", "z", "units", "columns", "origin"];

/// Samples of the profile per period for the foot search (piece joints are added).
const CURVE_SAMPLES: usize = 2048;

/// A point farther than this share of the groove's depth from the target section is taken
/// for a point of something else (a wrong frame, a stray probe hit), not for a deviation.
pub const FAR_SHARE: f64 = 0.1;

/// Where a frame value came from: a line of the file, or the caller's `--frame`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Source {
    /// A file line (1-based).
    Line(usize),
    /// A `--frame KEY=VALUE` option.
    Option,
}

impl fmt::Display for Source {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Source::Line(n) => write!(f, "line {n}"),
            Source::Option => f.write_str("--frame"),
        }
    }
}

/// The plane the points were measured in.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "section", rename_all = "lowercase")]
pub enum Plane {
    /// The half-plane through the screw axis at polar angle `angle_deg` of W; the points are
    /// (ρ, z).
    Axial {
        /// Polar angle of the half-plane, degrees.
        angle_deg: f64,
    },
    /// The plane at `z_mm` of W, across the screw axis; the points are (x, y).
    Transverse {
        /// Its axial position, mm.
        z_mm: f64,
    },
}

impl Plane {
    /// The section's two coordinates, in the order points are held: (ρ, z) or (x, y).
    pub fn axes(&self) -> [&'static str; 2] {
        match self {
            Plane::Axial { .. } => ["rho", "z"],
            Plane::Transverse { .. } => ["x", "y"],
        }
    }
}

impl fmt::Display for Plane {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Plane::Axial { angle_deg } => write!(f, "the axial section at {angle_deg}°"),
            Plane::Transverse { z_mm } => write!(f, "the transverse section at z = {z_mm} mm"),
        }
    }
}

/// The frame of a measured file, resolved.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Frame {
    /// The plane measured.
    #[serde(flatten)]
    pub plane: Plane,
    /// Millimetres per file unit (1 for `mm`, 25.4 for `in`).
    pub mm_per_unit: f64,
    /// The file's columns, as the section's axes.
    pub columns: [&'static str; 2],
    /// Where the file's zero lies in W, in the section's axis order ((ρ, z) or (x, y)), mm.
    pub origin_mm: [f64; 2],
}

/// One measured point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeasuredPoint {
    /// The file line.
    pub line: usize,
    /// The point in W, in the section's axis order ((ρ, z) or (x, y)), mm.
    pub at: DVec2,
}

/// A measured file, read: its frame and its points.
#[derive(Debug, Clone)]
pub struct Measured {
    /// The frame.
    pub frame: Frame,
    /// Where the plane's position was stated (to name it if the groove does not reach it).
    pub position_at: Source,
    /// The points, in file order.
    pub points: Vec<MeasuredPoint>,
}

/// What is wrong with a measured file or its frame.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SectionError {
    /// A line that is not the points it should be.
    #[error("line {line}: {what}")]
    Syntax {
        /// File line.
        line: usize,
        /// What was found.
        what: String,
    },
    /// A `--frame` option that is not `KEY=VALUE`.
    #[error("--frame {text:?}: expected KEY=VALUE, with a key of the header ({})", KEYS.join(", "))]
    Option {
        /// The option's text.
        text: String,
    },
    /// A key the header does not have.
    #[error("{at}: unknown key {key:?}; the frame's keys are {}", KEYS.join(", "))]
    UnknownKey {
        /// Where.
        at: Source,
        /// The key.
        key: String,
    },
    /// A frame key after the first point.
    #[error(
        "line {line}: {key} comes after the points; the frame is stated in the header, before them"
    )]
    KeyAfterPoints {
        /// File line.
        line: usize,
        /// The key.
        key: String,
    },
    /// A value out of what the key allows.
    #[error("{at}: {key} = {value}: {why}")]
    BadValue {
        /// Where.
        at: Source,
        /// The key.
        key: &'static str,
        /// Its value.
        value: String,
        /// What is allowed.
        why: String,
    },
    /// Two statements of one key that disagree.
    #[error("{at}: {key} = {value}, but {other} says {key} = {other_value}")]
    Contradiction {
        /// The later statement.
        at: Source,
        /// The key.
        key: &'static str,
        /// Its value there.
        value: String,
        /// The earlier one.
        other: Source,
        /// Its value there.
        other_value: String,
    },
    /// A key stated for the other kind of section.
    #[error("{at}: {key} places {wants} section, but section = {section} ({section_at})")]
    OtherSection {
        /// Where the key is.
        at: Source,
        /// The key.
        key: &'static str,
        /// "an axial" or "a transverse".
        wants: &'static str,
        /// The section stated.
        section: String,
        /// Where it is stated.
        section_at: Source,
    },
    /// A key the frame needs and nobody stated.
    #[error(
        "the frame is not stated: no {key} ({what}); state it in the file's header \
         (`# {key} = …`, before the points) or with --frame {key}=…"
    )]
    Missing {
        /// The key.
        key: &'static str,
        /// What it says.
        what: &'static str,
    },
    /// No point at all.
    #[error("no points: after the header, one point a line, two comma-separated values")]
    NoPoints,
    /// A point that is no point of this groove's section.
    #[error(
        "line {line}: the point ({:.4}, {:.4}) lies {distance:.4} mm from the target section \
         (nearest ({:.4}, {:.4})), more than {limit:.4} mm (a tenth of the groove's depth): \
         not a deviation but a point of something else; check the frame (section, angle or z, \
         columns, origin, units) or remove the point",
        at[0], at[1], nearest[0], nearest[1]
    )]
    Far {
        /// File line.
        line: usize,
        /// The point in W, mm.
        at: [f64; 2],
        /// Its distance from the target section, mm.
        distance: f64,
        /// The nearest point of the target section, mm.
        nearest: [f64; 2],
        /// The most a point may lie off, mm.
        limit: f64,
    },
    /// A point (or the transverse plane) outside the groove's formed length.
    #[error(
        "{at}: z = {z:.4} mm lies outside the groove's formed length, z from {from} to {to} mm, \
         where the ring has not cut the full profile"
    )]
    OutsideLength {
        /// The point's line, or where the plane's z is stated.
        at: Source,
        /// Its axial position, mm.
        z: f64,
        /// Start of the formed length, mm.
        from: f64,
        /// End of the formed length, mm.
        to: f64,
    },
}

/// One statement of a key.
#[derive(Debug, Clone)]
struct Stated {
    key: &'static str,
    value: String,
    at: Source,
}

/// The header's statements, each key at most once (or the same again).
#[derive(Debug, Default)]
struct Statements(Vec<Stated>);

impl Statements {
    fn get(&self, key: &str) -> Option<&Stated> {
        self.0.iter().find(|s| s.key == key)
    }

    /// Adds a statement; one that disagrees with an earlier statement of its key is refused.
    fn add(&mut self, key: &'static str, value: &str, at: Source) -> Result<(), SectionError> {
        let value = value.trim().to_owned();
        if let Some(earlier) = self.get(key) {
            if !same_value(&earlier.value, &value) {
                return Err(SectionError::Contradiction {
                    at,
                    key,
                    value,
                    other: earlier.at,
                    other_value: earlier.value.clone(),
                });
            }
            return Ok(());
        }
        self.0.push(Stated { key, value, at });
        Ok(())
    }
}

/// Whether two values say the same: item by item (comma-separated), as numbers where both
/// are numbers, otherwise as words regardless of case.
fn same_value(a: &str, b: &str) -> bool {
    let items = |s: &str| -> Vec<String> { s.split(',').map(|i| i.trim().to_owned()).collect() };
    let (a, b) = (items(a), items(b));
    a.len() == b.len()
        && a.iter()
            .zip(&b)
            .all(|(x, y)| match (x.parse::<f64>(), y.parse::<f64>()) {
                (Ok(x), Ok(y)) => x == y,
                _ => x.eq_ignore_ascii_case(y),
            })
}

/// The key and value of a header line's text (after `#`), if it is `word = value`.
fn key_line(text: &str) -> Option<(&str, &str)> {
    let (key, value) = text.split_once('=')?;
    let key = key.trim();
    let word = key.chars().next().is_some_and(|c| c.is_ascii_alphabetic())
        && key.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
    word.then_some((key, value))
}

/// The header key `key`, if it is one.
fn known(key: &str) -> Option<&'static str> {
    KEYS.iter().copied().find(|k| *k == key)
}

/// Reads a measured section's CSV text; `options` are the caller's `KEY=VALUE` statements of
/// the frame (`--frame`), which must agree with the header's.
pub fn read(text: &str, options: &[String]) -> Result<Measured, SectionError> {
    let mut stated = Statements::default();
    let mut raw: Vec<(usize, [f64; 2])> = Vec::new();
    let mut names_seen = false;
    for (i, line_text) in text.lines().enumerate() {
        let line = i + 1;
        let content = line_text.trim();
        if content.is_empty() {
            continue;
        }
        if let Some(comment) = content.strip_prefix('#') {
            if let Some((key, value)) = key_line(comment) {
                let Some(key) = known(key) else {
                    return Err(SectionError::UnknownKey {
                        at: Source::Line(line),
                        key: key.to_owned(),
                    });
                };
                if names_seen || !raw.is_empty() {
                    return Err(SectionError::KeyAfterPoints {
                        line,
                        key: key.to_owned(),
                    });
                }
                stated.add(key, value, Source::Line(line))?;
            }
            continue;
        }
        let fields: Vec<&str> = content.split(',').map(str::trim).collect();
        let numbers: Vec<Option<f64>> = fields.iter().map(|f| f.parse::<f64>().ok()).collect();
        if !names_seen && raw.is_empty() && numbers.iter().all(Option::is_none) {
            // The column names, as the first line after the header.
            names_seen = true;
            stated.add("columns", content, Source::Line(line))?;
            continue;
        }
        if fields.len() != 2 {
            return Err(SectionError::Syntax {
                line,
                what: format!(
                    "expected two comma-separated values, found {}: {content:?}",
                    fields.len()
                ),
            });
        }
        let mut point = [0.0; 2];
        for (k, (field, number)) in fields.iter().zip(&numbers).enumerate() {
            point[k] = match number {
                Some(v) if v.is_finite() => *v,
                Some(_) => {
                    return Err(SectionError::Syntax {
                        line,
                        what: format!("{field:?} is not a finite number"),
                    })
                }
                None => {
                    return Err(SectionError::Syntax {
                        line,
                        what: format!("{field:?} is not a number"),
                    })
                }
            };
        }
        raw.push((line, point));
    }
    for option in options {
        let Some((key, value)) = option.split_once('=') else {
            return Err(SectionError::Option {
                text: option.clone(),
            });
        };
        let Some(key) = known(key.trim()) else {
            return Err(SectionError::UnknownKey {
                at: Source::Option,
                key: key.trim().to_owned(),
            });
        };
        // The file's statement is the earlier one: a disagreement names its line.
        stated.add(key, value, Source::Option)?;
    }
    let (frame, position_at) = resolve(&stated)?;
    if raw.is_empty() {
        return Err(SectionError::NoPoints);
    }
    let swapped = frame.columns[0] != frame.plane.axes()[0];
    let points = raw
        .into_iter()
        .map(|(line, [a, b])| {
            let (first, second) = if swapped { (b, a) } else { (a, b) };
            MeasuredPoint {
                line,
                at: DVec2::new(first, second) * frame.mm_per_unit + DVec2::from(frame.origin_mm),
            }
        })
        .collect();
    Ok(Measured {
        frame,
        position_at,
        points,
    })
}

/// A statement's value as a finite number.
fn finite(s: &Stated) -> Result<f64, SectionError> {
    s.value
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| SectionError::BadValue {
            at: s.at,
            key: s.key,
            value: s.value.clone(),
            why: "must be a finite number".into(),
        })
}

/// The frame from the statements, each key checked; and where the plane's position is.
fn resolve(stated: &Statements) -> Result<(Frame, Source), SectionError> {
    let need = |key: &'static str, what: &'static str| {
        stated.get(key).ok_or(SectionError::Missing { key, what })
    };
    let section = need("section", "axial or transverse")?;
    let axial = match section.value.to_ascii_lowercase().as_str() {
        "axial" => true,
        "transverse" => false,
        _ => {
            return Err(SectionError::BadValue {
                at: section.at,
                key: "section",
                value: section.value.clone(),
                why: "must be axial or transverse".into(),
            })
        }
    };
    let (wanted, other, wants) = if axial {
        ("angle_deg", "z", "a transverse")
    } else {
        ("z", "angle_deg", "an axial")
    };
    if let Some(s) = stated.get(other) {
        return Err(SectionError::OtherSection {
            at: s.at,
            key: s.key,
            wants,
            section: section.value.clone(),
            section_at: section.at,
        });
    }
    let units = need("units", "mm or in")?;
    let mm_per_unit = match units.value.to_ascii_lowercase().as_str() {
        "mm" => 1.0,
        "in" => 25.4,
        _ => {
            return Err(SectionError::BadValue {
                at: units.at,
                key: "units",
                value: units.value.clone(),
                why: "must be mm or in".into(),
            })
        }
    };
    let position = need(
        wanted,
        if axial {
            "the axial half-plane's polar angle in the workpiece frame, degrees"
        } else {
            "the transverse plane's z in the workpiece frame"
        },
    )?;
    let value = finite(position)?;
    let plane = if axial {
        Plane::Axial { angle_deg: value }
    } else {
        Plane::Transverse {
            z_mm: value * mm_per_unit,
        }
    };
    let axes = plane.axes();
    let columns = need(
        "columns",
        if axial {
            "which column is rho and which z"
        } else {
            "which column is x and which y"
        },
    )?;
    let names: Vec<String> = columns
        .value
        .split(',')
        .map(|n| n.trim().to_ascii_lowercase())
        .collect();
    let order = match names.iter().map(String::as_str).collect::<Vec<_>>()[..] {
        [a, b] if a == axes[0] && b == axes[1] => [axes[0], axes[1]],
        [a, b] if a == axes[1] && b == axes[0] => [axes[1], axes[0]],
        _ => {
            return Err(SectionError::BadValue {
                at: columns.at,
                key: "columns",
                value: columns.value.clone(),
                why: format!(
                    "the columns of {} are {} and {}, in either order",
                    if axial {
                        "an axial section"
                    } else {
                        "a transverse section"
                    },
                    axes[0],
                    axes[1]
                ),
            })
        }
    };
    let origin = need(
        "origin",
        "where the file's zero lies in the workpiece frame, in the columns' order",
    )?;
    let parts: Vec<Option<f64>> = origin
        .value
        .split(',')
        .map(|v| v.trim().parse::<f64>().ok().filter(|v| v.is_finite()))
        .collect();
    let [Some(o1), Some(o2)] = parts[..] else {
        return Err(SectionError::BadValue {
            at: origin.at,
            key: "origin",
            value: origin.value.clone(),
            why: "must be two finite numbers, in the columns' order and the file's units".into(),
        });
    };
    let origin_mm = if order[0] == axes[0] {
        [o1, o2]
    } else {
        [o2, o1]
    }
    .map(|v| v * mm_per_unit);
    Ok((
        Frame {
            plane,
            mm_per_unit,
            columns: order,
            origin_mm,
        },
        position.at,
    ))
}

/// One measured point's deviation from the target.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Deviation {
    /// The file line.
    pub line: usize,
    /// The measured point in W, in the section's axis order ((ρ, z) or (x, y)), mm.
    pub at: [f64; 2],
    /// Its foot on the target section, mm.
    pub nearest: [f64; 2],
    /// Signed distance along the surface's normal, mm: negative overcut, positive undercut.
    pub deviation_mm: f64,
    /// Signed distance along the target section's normal in the measured plane, mm.
    pub in_section_mm: f64,
    /// The foot's profile parameter.
    pub profile_u: f64,
    /// The foot's start (0-based).
    pub start: u32,
    /// The foot's axial position in W, mm.
    pub z_mm: f64,
    /// The section curve's unit normal at the foot, in the section's axis order.
    #[serde(skip)]
    pub normal: [f64; 2],
    /// The length of the unit surface normal's projection on the plane at the foot:
    /// `deviation_mm = share · in_section_mm`.
    #[serde(skip)]
    pub share: f64,
    /// Where the foot lies along the section curve (for drawing it in order).
    #[serde(skip)]
    pub chain: f64,
}

/// The deviations of a measured section, with the largest over- and undercut.
#[derive(Debug, Clone, Serialize)]
pub struct Deviations {
    /// Every point's.
    pub points: Vec<Deviation>,
    /// Largest overcut, mm (≥ 0).
    pub max_overcut_mm: f64,
    /// The line of the largest overcut.
    pub max_overcut_line: usize,
    /// Largest undercut, mm (≥ 0).
    pub max_undercut_mm: f64,
    /// The line of the largest undercut.
    pub max_undercut_line: usize,
}

/// A sample of the profile for the foot search.
#[derive(Debug, Clone, Copy)]
struct Node {
    u: f64,
    pos: DVec2,
    /// Polar angle, unwrapped along the profile.
    phi: f64,
    normal: DVec3,
}

/// A point of the target section: where, its unit normal in the plane, and the length s of
/// the unit surface normal's projection on the plane.
#[derive(Debug, Clone, Copy)]
struct CurvePoint {
    at: DVec2,
    normal: DVec2,
    share: f64,
}

/// A foot on the target section.
#[derive(Debug, Clone, Copy)]
struct Foot {
    u: f64,
    copy: i64,
    point: CurvePoint,
}

/// The target groove cut by a measured plane.
#[derive(Debug, Clone)]
pub struct SectionTarget<'a> {
    profile: &'a Profile,
    plane: Plane,
    p: f64,
    period: f64,
    starts: u32,
    z_range: (f64, f64),
    far: f64,
    nodes: Vec<Node>,
}

impl<'a> SectionTarget<'a> {
    /// `job`'s groove cut by `plane`.
    pub fn new(job: &'a Job, plane: Plane) -> SectionTarget<'a> {
        let profile = &job.profile;
        let p = job.p();
        let mut us: Vec<f64> = (0..=CURVE_SAMPLES)
            .map(|k| profile.length() * k as f64 / CURVE_SAMPLES as f64)
            .chain(profile.breaks().iter().copied())
            .collect();
        us.sort_by(f64::total_cmp);
        us.dedup_by(|b, a| *b - *a < 1e-12);
        let mut nodes: Vec<Node> = Vec::with_capacity(us.len());
        for u in us {
            let point = profile.point(u);
            let hint = nodes
                .last()
                .map_or(point.pos.y.atan2(point.pos.x), |n| n.phi);
            nodes.push(Node {
                u,
                pos: point.pos,
                phi: unwrap(point.pos.y.atan2(point.pos.x), hint),
                normal: profile.normal(&point, p),
            });
        }
        let (rho_min, rho_max) = profile.radius_range();
        SectionTarget {
            profile,
            plane,
            p,
            period: job.period(),
            starts: job.groove.starts,
            z_range: (job.groove.z_start, job.groove.z_start + job.groove.length),
            far: FAR_SHARE * (rho_max - rho_min),
            nodes,
        }
    }

    /// The section point of profile position (`pos`, polar angle `phi`, surface normal
    /// `normal`) in copy `copy`.
    fn place(&self, pos: DVec2, phi: f64, normal: DVec3, copy: i64) -> CurvePoint {
        let (at, in_plane) = match self.plane {
            Plane::Axial { angle_deg } => {
                let z =
                    self.p * (angle_deg.to_radians() - phi) + copy as f64 * self.p * self.period;
                let radial = DVec2::from_angle(phi);
                (
                    DVec2::new(pos.length(), z),
                    DVec2::new(normal.x * radial.x + normal.y * radial.y, normal.z),
                )
            }
            Plane::Transverse { z_mm } => {
                let turn = DVec2::from_angle(z_mm / self.p + copy as f64 * self.period);
                (
                    turn.rotate(pos),
                    turn.rotate(DVec2::new(normal.x, normal.y)),
                )
            }
        };
        let share = in_plane.length();
        CurvePoint {
            at,
            normal: in_plane / share,
            share,
        }
    }

    /// The section point at profile parameter `u` of copy `copy`, its polar angle unwrapped
    /// next to `hint`.
    fn at_u(&self, u: f64, hint: f64, copy: i64) -> CurvePoint {
        let point = self.profile.point(u);
        let phi = unwrap(point.pos.y.atan2(point.pos.x), hint);
        let normal = self.profile.normal(&point, self.p);
        self.place(point.pos, phi, normal, copy)
    }

    /// The copies of the profile that can hold the foot of `q`.
    fn copies(&self, q: DVec2) -> Vec<i64> {
        match self.plane {
            Plane::Axial { angle_deg } => {
                // Copy j spans z from p·(φ₀ − φ(0)) + j·p·T over one pitch (towards −p·T).
                let middle =
                    self.p * (angle_deg.to_radians() - self.nodes[0].phi - self.period / 2.0);
                let j0 = ((q.y - middle) / (self.p * self.period)).round() as i64;
                vec![j0 - 1, j0, j0 + 1]
            }
            Plane::Transverse { .. } => (0..i64::from(self.starts)).collect(),
        }
    }

    /// The foot of `q` on the section curve: among the points where `q` lies on the curve's
    /// normal line, the nearest; where there is none (`q` far off), the nearest sample.
    fn foot(&self, q: DVec2) -> Foot {
        let along = |c: &CurvePoint| (q - c.at).perp_dot(c.normal);
        let mut feet: Vec<Foot> = Vec::new();
        let mut nearest: Option<Foot> = None;
        for copy in self.copies(q) {
            let points: Vec<CurvePoint> = self
                .nodes
                .iter()
                .map(|n| self.place(n.pos, n.phi, n.normal, copy))
                .collect();
            for (k, pair) in points.windows(2).enumerate() {
                let (h0, h1) = (along(&pair[0]), along(&pair[1]));
                if h0 == 0.0 {
                    feet.push(Foot {
                        u: self.nodes[k].u,
                        copy,
                        point: pair[0],
                    });
                } else if h1 != 0.0 && h0.signum() != h1.signum() {
                    let hint = self.nodes[k].phi;
                    let f = |u: f64| along(&self.at_u(u, hint, copy));
                    if let Some(u) =
                        brent::root(f, self.nodes[k].u, self.nodes[k + 1].u, 1e-13, 100)
                    {
                        feet.push(Foot {
                            u,
                            copy,
                            point: self.at_u(u, hint, copy),
                        });
                    }
                }
            }
            for (node, point) in self.nodes.iter().zip(&points) {
                if nearest.is_none_or(|n| (q - point.at).length() < (q - n.point.at).length()) {
                    nearest = Some(Foot {
                        u: node.u,
                        copy,
                        point: *point,
                    });
                }
            }
        }
        feet.into_iter()
            .min_by(|a, b| {
                (q - a.point.at)
                    .length()
                    .total_cmp(&(q - b.point.at).length())
            })
            .or(nearest)
            .expect("a profile has samples")
    }

    /// The deviations of `measured`'s points; a point far from the section, or outside the
    /// formed length, is refused naming its line.
    pub fn deviations(&self, measured: &Measured) -> Result<Deviations, SectionError> {
        if let Plane::Transverse { z_mm } = self.plane {
            self.within_length(z_mm, measured.position_at)?;
        }
        if measured.points.is_empty() {
            return Err(SectionError::NoPoints);
        }
        let mut points = Vec::with_capacity(measured.points.len());
        for m in &measured.points {
            let foot = self.foot(m.at);
            let d = (m.at - foot.point.at).dot(foot.point.normal);
            let distance = (m.at - foot.point.at).length();
            if distance > self.far {
                return Err(SectionError::Far {
                    line: m.line,
                    at: m.at.to_array(),
                    distance,
                    nearest: foot.point.at.to_array(),
                    limit: self.far,
                });
            }
            let (start, z, chain) = match self.plane {
                Plane::Axial { .. } => {
                    self.within_length(m.at.y, Source::Line(m.line))?;
                    let z = foot.point.at.y;
                    // Turning start s by θ = z/p brings its point to polar angle
                    // φ(u) + s·T + z/p = φ₀ + j·T + s·T: the start is −j modulo the starts.
                    let start = (-foot.copy).rem_euclid(i64::from(self.starts)) as u32;
                    (start, z, foot.u - foot.copy as f64 * self.profile.length())
                }
                Plane::Transverse { z_mm } => (
                    foot.copy as u32,
                    z_mm,
                    foot.u + foot.copy as f64 * self.profile.length(),
                ),
            };
            points.push(Deviation {
                line: m.line,
                at: m.at.to_array(),
                nearest: foot.point.at.to_array(),
                deviation_mm: d * foot.point.share,
                in_section_mm: d,
                profile_u: foot.u,
                start,
                z_mm: z,
                normal: foot.point.normal.to_array(),
                share: foot.point.share,
                chain,
            });
        }
        let over = points
            .iter()
            .min_by(|a, b| a.deviation_mm.total_cmp(&b.deviation_mm))
            .copied()
            .expect("points were checked");
        let under = points
            .iter()
            .max_by(|a, b| a.deviation_mm.total_cmp(&b.deviation_mm))
            .copied()
            .expect("points were checked");
        Ok(Deviations {
            points,
            max_overcut_mm: (-over.deviation_mm).max(0.0),
            max_overcut_line: over.line,
            max_undercut_mm: under.deviation_mm.max(0.0),
            max_undercut_line: under.line,
        })
    }

    fn within_length(&self, z: f64, at: Source) -> Result<(), SectionError> {
        let (from, to) = self.z_range;
        if (from..=to).contains(&z) {
            Ok(())
        } else {
            Err(SectionError::OutsideLength { at, z, from, to })
        }
    }

    /// The target section under the measured points, the band a surface within `delta`
    /// (along its normal) cuts in the plane, the points with their deviations magnified
    /// along the section's normal, and (given) the deviations a fitted tool predicts at
    /// them, magnified alike. A surface moved by Δ along its normal cuts the plane Δ/s off
    /// the section curve (s: the unit surface normal's share in the plane), so the band's
    /// edges lie Δ/s off the target, magnified as the points are.
    pub fn plot(&self, deviations: &Deviations, predicted: Option<&[f64]>, delta: f64) -> Plot {
        let mut ordered: Vec<(usize, &Deviation)> = deviations.points.iter().enumerate().collect();
        ordered.sort_by(|a, b| a.1.chain.total_cmp(&b.1.chain));
        let largest = deviations
            .points
            .iter()
            .map(|d| d.in_section_mm.abs())
            .fold(0.0, f64::max);
        let pitch = (self.p * self.period).abs();
        // Magnified so that the points and the band both show: by the larger of the two.
        let magnify = magnification(largest.max(delta), pitch);
        let (axial, x_label, y_label) = match self.plane {
            Plane::Axial { .. } => (true, "z, mm", "radius, mm"),
            Plane::Transverse { .. } => (false, "x, mm", "y, mm"),
        };
        // Axial sections are drawn z across, radius up, as `whirl verify` draws them.
        let show = |v: DVec2| if axial { (v.y, v.x) } else { (v.x, v.y) };
        let moved = |d: &Deviation, by: f64| {
            show(DVec2::from(d.nearest) + DVec2::from(d.normal) * by * magnify)
        };
        let length = self.profile.length();
        let (lo, hi) = (
            ordered.first().map_or(0.0, |o| o.1.chain),
            ordered.last().map_or(0.0, |o| o.1.chain),
        );
        let margin = length / 20.0;
        let n = 800;
        let curve: Vec<CurvePoint> = (0..=n)
            .map(|k| {
                let chain = lo - margin + (hi - lo + 2.0 * margin) * k as f64 / n as f64;
                let (u, copy) = match self.plane {
                    Plane::Axial { .. } => {
                        let copy = -(chain / length).floor();
                        (chain + copy * length, copy as i64)
                    }
                    Plane::Transverse { .. } => {
                        let copy = (chain / length).floor();
                        (chain - copy * length, copy as i64)
                    }
                };
                let hint = self.nodes[self
                    .nodes
                    .partition_point(|n| n.u < u)
                    .min(self.nodes.len() - 1)]
                .phi;
                self.at_u(u, hint, copy)
            })
            .collect();
        let band = |side: f64| -> Vec<(f64, f64)> {
            curve
                .iter()
                .map(|c| show(c.at + c.normal * (side * delta / c.share * magnify)))
                .collect()
        };
        let mut series = vec![
            Series {
                label: "target".into(),
                colour: "black",
                points: curve.iter().map(|c| show(c.at)).collect(),
            },
            Series {
                label: format!("Δ = {delta} mm, undercut side (× {magnify})"),
                colour: "darkgray",
                points: band(1.0),
            },
            Series {
                label: format!("Δ = {delta} mm, overcut side (× {magnify})"),
                colour: "darkgray",
                points: band(-1.0),
            },
            Series {
                label: format!("measured (deviation × {magnify})"),
                colour: "crimson",
                points: ordered
                    .iter()
                    .map(|(_, d)| moved(d, d.in_section_mm))
                    .collect(),
            },
        ];
        if let Some(predicted) = predicted {
            series.push(Series {
                label: format!("fitted tool (× {magnify})"),
                colour: "steelblue",
                points: ordered
                    .iter()
                    .map(|(i, d)| moved(d, predicted[*i] / d.share))
                    .collect(),
            });
        }
        Plot {
            title: format!("{}, deviations magnified {magnify}×", self.plane),
            x_label: x_label.into(),
            y_label: y_label.into(),
            series,
            equal_scale: true,
        }
    }
}

/// `angle` (−π … π) moved by whole turns to within half a turn of `hint`.
fn unwrap(angle: f64, hint: f64) -> f64 {
    hint + (angle - hint + PI).rem_euclid(TAU) - PI
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    /// The trapezoidal example's groove (a standard profile: no points file to read).
    fn trapezoidal() -> Job {
        let text = std::fs::read_to_string(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/trapezoidal/job.toml"),
        )
        .unwrap();
        Job::from_toml(&text, Path::new("job.toml")).unwrap()
    }

    const AXIAL: &str = "# section = axial\n# angle_deg = 0\n# units = mm\n# origin = 0, 0\n";

    fn read_ok(text: &str, options: &[&str]) -> Measured {
        let options: Vec<String> = options.iter().map(|s| s.to_string()).collect();
        read(text, &options).unwrap()
    }

    fn read_err(text: &str, options: &[&str]) -> SectionError {
        let options: Vec<String> = options.iter().map(|s| s.to_string()).collect();
        read(text, &options).unwrap_err()
    }

    #[test]
    fn inches_swapped_columns_and_an_origin_give_the_same_points_in_w() {
        let mm = read_ok(&format!("{AXIAL}rho,z\n16.5,3.25\n17.0,-1.5\n"), &[]);
        // The same points in inches, z first, measured from z = 2 mm and ρ = 12.7 mm (0.5 in).
        let inch = format!(
            "# a projector's export\n# section = axial\n# angle_deg = 0\n# units = in\n\
             # columns = z, rho\n# origin = {}, 0.5\nz,rho\n{},{}\n{},{}\n",
            2.0 / 25.4,
            (3.25 - 2.0) / 25.4,
            (16.5 - 12.7) / 25.4,
            (-1.5 - 2.0) / 25.4,
            (17.0 - 12.7) / 25.4
        );
        let inch = read_ok(&inch, &[]);
        assert_eq!(inch.frame.mm_per_unit, 25.4);
        assert_eq!(inch.frame.columns, ["z", "rho"]);
        for (a, b) in mm.points.iter().zip(&inch.points) {
            assert!((a.at - b.at).length() < 1e-12, "{:?} {:?}", a.at, b.at);
        }
        assert_eq!(inch.points[0].line, 8);
    }

    #[test]
    fn options_state_what_the_header_leaves_out_and_may_repeat_it() {
        let m = read_ok(
            "# section = transverse\n# units = mm\n1,2\n",
            &["z=5", "columns=y,x", "origin=0,0", "units=mm"],
        );
        assert_eq!(m.frame.plane, Plane::Transverse { z_mm: 5.0 });
        assert_eq!(m.points[0].at, DVec2::new(2.0, 1.0));
        assert_eq!(m.position_at, Source::Option);
    }

    #[test]
    fn every_key_of_the_frame_must_be_stated() {
        let full = [
            "# section = axial",
            "# angle_deg = 0",
            "# units = mm",
            "# columns = rho, z",
            "# origin = 0, 0",
        ];
        for (i, key) in ["section", "angle_deg", "units", "columns", "origin"]
            .iter()
            .enumerate()
        {
            let mut lines: Vec<&str> = full.to_vec();
            lines.remove(i);
            let text = format!("{}\n16,1\n", lines.join("\n"));
            match read_err(&text, &[]) {
                SectionError::Missing { key: k, .. } => assert_eq!(k, *key),
                e => panic!("{key}: {e}"),
            }
        }
        let e = read_err(
            "# section = transverse\n# units = mm\n# columns = x, y\n# origin = 0, 0\n1,2\n",
            &[],
        );
        assert!(matches!(e, SectionError::Missing { key: "z", .. }), "{e}");
        assert!(e.to_string().contains("--frame z="), "{e}");
    }

    #[test]
    fn a_statement_that_disagrees_is_refused_naming_both() {
        let e = read_err(&format!("{AXIAL}rho,z\n16,1\n"), &["units=in"]);
        assert_eq!(
            e.to_string(),
            "--frame: units = in, but line 3 says units = mm"
        );
        let e = read_err(&format!("{AXIAL}# units = in\nrho,z\n16,1\n"), &[]);
        assert!(
            e.to_string().starts_with("line 5: units = in, but line 3"),
            "{e}"
        );
        let e = read_err(&format!("{AXIAL}# columns = z, rho\nrho,z\n16,1\n"), &[]);
        assert!(
            e.to_string()
                .starts_with("line 6: columns = rho,z, but line 5"),
            "{e}"
        );
        // The same statement again, however spelt, is no contradiction.
        read_ok(
            &format!("{AXIAL}# angle_deg = 0.0\n# units = MM\nrho, z\n16,1\n"),
            &["origin=0.0,0"],
        );
    }

    #[test]
    fn keys_of_the_other_section_are_refused() {
        let e = read_err(&format!("{AXIAL}# z = 3\nrho,z\n16,1\n"), &[]);
        assert_eq!(
            e.to_string(),
            "line 5: z places a transverse section, but section = axial (line 1)"
        );
    }

    #[test]
    fn bad_values_name_their_key_and_line() {
        let cases = [
            ("# section = radial\n", "line 1: section = radial: must be axial or transverse"),
            ("# section = axial\n# angle_deg = north\n# units = mm\n", "line 2: angle_deg = north: must be a finite number"),
            ("# section = axial\n# angle_deg = 0\n# units = cm\n", "line 3: units = cm: must be mm or in"),
            ("# section = axial\n# angle_deg = 0\n# units = mm\n# columns = x, y\n", "line 4: columns = x, y: the columns of an axial section are rho and z"),
            ("# section = axial\n# angle_deg = 0\n# units = mm\n# columns = rho, z\n# origin = 1\n", "line 5: origin = 1: must be two finite numbers"),
        ];
        for (header, message) in cases {
            let e = read_err(&format!("{header}16,1\n"), &[]);
            assert!(e.to_string().starts_with(message), "{e}");
        }
    }

    #[test]
    fn unknown_keys_late_keys_and_bad_options_are_refused() {
        let e = read_err("# secton = axial\n16,1\n", &[]);
        assert!(
            e.to_string().starts_with("line 1: unknown key \"secton\""),
            "{e}"
        );
        let e = read_err(&format!("{AXIAL}rho,z\n16,1\n"), &["angle=0"]);
        assert!(
            e.to_string().starts_with("--frame: unknown key \"angle\""),
            "{e}"
        );
        let e = read_err(&format!("{AXIAL}rho,z\n16,1\n"), &["units"]);
        assert!(matches!(e, SectionError::Option { .. }), "{e}");
        let e = read_err(&format!("{AXIAL}rho,z\n16,1\n# units = mm\n"), &[]);
        assert_eq!(
            e.to_string(),
            "line 7: units comes after the points; the frame is stated in the header, before them"
        );
        // A comment that is no `key = value` is a comment, wherever it is.
        read_ok(
            &format!("{AXIAL}rho,z\n16,1\n# probe 2, after recalibration\n17,1\n"),
            &[],
        );
    }

    #[test]
    fn bad_numbers_name_their_line() {
        let cases = [
            (
                "16,1,3",
                "line 6: expected two comma-separated values, found 3",
            ),
            ("16.0.1,1", "line 6: \"16.0.1\" is not a number"),
            ("16,NaN", "line 6: \"NaN\" is not a finite number"),
            ("inf,1", "line 6: \"inf\" is not a finite number"),
        ];
        for (row, message) in cases {
            let e = read_err(&format!("{AXIAL}rho,z\n{row}\n"), &[]);
            assert!(e.to_string().starts_with(message), "{e}");
        }
        let e = read_err(&format!("{AXIAL}rho,z\n"), &[]);
        assert_eq!(e, SectionError::NoPoints);
    }

    /// The target's (ρ, z) at profile parameter `u` in the axial half-plane at polar angle
    /// 0 (copy `j`), from the profile alone: kinematics.md's axial rule.
    fn axial_point(job: &Job, u: f64, phi0: f64) -> DVec2 {
        let pos = job.profile.point(u).pos;
        let phi = unwrap(pos.y.atan2(pos.x), phi0);
        DVec2::new(pos.length(), job.p() * (0.0 - phi))
    }

    /// The surface point S(u, θ) = Rz(θ)·P(u) + p·θ·ẑ of start 0.
    fn surface(job: &Job, u: f64, theta: f64) -> DVec3 {
        let pos = DVec2::from_angle(theta).rotate(job.profile.point(u).pos);
        DVec3::new(pos.x, pos.y, job.p() * theta)
    }

    #[test]
    fn a_point_moved_along_the_axial_section_s_normal_deviates_by_that_much() {
        let job = trapezoidal();
        let target = SectionTarget::new(&job, Plane::Axial { angle_deg: 0.0 });
        let length = job.profile.length();
        let phi0 = job.profile.point(0.0).pos.to_angle();
        let mut points = Vec::new();
        let mut expected = Vec::new();
        for k in 1..40 {
            let u = length * k as f64 / 40.0;
            let h = 1e-6;
            // The section's normal from its own tangent (finite differences), outward: the
            // groove lies at larger radii than the material, so its ρ component is positive.
            let t = (axial_point(&job, u + h, phi0) - axial_point(&job, u - h, phi0)).normalize();
            let mut m = t.perp();
            if m.x < 0.0 {
                m = -m;
            }
            if t.length() < 0.5
                || (axial_point(&job, u + h, phi0) - axial_point(&job, u - h, phi0)).length() < 1e-9
            {
                continue; // on a corner the point stays put
            }
            let at = axial_point(&job, u, phi0);
            // The surface normal from the surface's own derivatives, and its share in the
            // plane through the axis at the point's polar angle.
            let theta = -job.profile.point(u).pos.to_angle();
            let su = surface(&job, u + h, theta) - surface(&job, u - h, theta);
            let st = surface(&job, u, theta + h) - surface(&job, u, theta - h);
            let n = su.cross(st).normalize();
            let q = surface(&job, u, theta);
            let radial = DVec3::new(q.x, q.y, 0.0).normalize();
            let share = DVec2::new(n.dot(radial), n.z).length();
            let d = 0.003 * if k % 2 == 0 { 1.0 } else { -1.0 };
            points.push(MeasuredPoint {
                line: k,
                at: at + m * d,
            });
            expected.push((d, d * share, at));
        }
        let measured = Measured {
            frame: read_ok(&format!("{AXIAL}rho,z\n16,1\n"), &[]).frame,
            position_at: Source::Line(2),
            points,
        };
        // Within the formed length: the trapezoid's starts at z = 0.
        let shifted: Vec<MeasuredPoint> = measured
            .points
            .iter()
            .map(|p| MeasuredPoint {
                at: p.at + DVec2::new(0.0, 2.0 * job.groove.lead),
                ..*p
            })
            .collect();
        let measured = Measured {
            points: shifted,
            ..measured
        };
        let got = target.deviations(&measured).unwrap();
        for (g, (d, e, at)) in got.points.iter().zip(&expected) {
            assert!(
                (g.in_section_mm - d).abs() < 1e-6,
                "line {}: {} against {d}",
                g.line,
                g.in_section_mm
            );
            assert!(
                (g.deviation_mm - e).abs() < 1e-6,
                "line {}: {} against {e}",
                g.line,
                g.deviation_mm
            );
            let foot = DVec2::from(g.nearest) - DVec2::new(0.0, 2.0 * job.groove.lead);
            assert!((foot - *at).length() < 1e-6, "line {}", g.line);
            // The engine's surface point of the foot (start s turned by θ = z/p) lies in the
            // measured half-plane, at the foot.
            let turn = TAU / f64::from(job.groove.starts) * f64::from(g.start) + g.z_mm / job.p();
            let s = DVec2::from_angle(turn).rotate(job.profile.point(g.profile_u).pos);
            assert!(s.y.abs() < 1e-9 && s.x > 0.0, "line {}: {s:?}", g.line);
            assert!((DVec2::new(s.x, g.z_mm) - DVec2::from(g.nearest)).length() < 1e-9);
        }
        assert!(got.max_overcut_mm > 0.0029 && got.max_undercut_mm > 0.0029);
    }

    #[test]
    fn above_the_root_is_undercut_below_it_overcut_and_off_a_crest_edge_the_distance_to_it() {
        let job = trapezoidal();
        let target = SectionTarget::new(&job, Plane::Axial { angle_deg: 0.0 });
        let (rho_min, rho_max) = job.profile.radius_range();
        // The root and crest flats, from the profile: the samples at the least and most radius.
        let n = 20_000;
        let length = job.profile.length();
        let phi0 = job.profile.point(0.0).pos.to_angle();
        let at = |k: usize| axial_point(&job, length * k as f64 / n as f64, phi0);
        let root: Vec<DVec2> = (0..=n).map(at).filter(|p| p.x < rho_min + 1e-9).collect();
        let z0 = 2.0 * job.groove.lead;
        let mid_root = root[root.len() / 2] + DVec2::new(0.0, z0);
        // A crest edge: a joint of the profile's pieces on the crest after which the flank
        // falls away. The fan of outward normals there turns from radial to the flank's
        // normal, 75° on (ISO 2904 flanks are 15° off radial): 30° on lies inside it.
        let edge_u = job
            .profile
            .breaks()
            .iter()
            .copied()
            .find(|&b| {
                job.profile.point(b).pos.length() > rho_max - 1e-9
                    && job.profile.point(b + 1e-3).pos.length() < rho_max - 1e-6
            })
            .unwrap();
        let edge = axial_point(&job, edge_u, phi0);
        let side = (axial_point(&job, edge_u + 1e-3, phi0) - edge).y.signum();
        let edge = edge + DVec2::new(0.0, z0);
        let out = DVec2::new(30f64.to_radians().cos(), side * 30f64.to_radians().sin());
        let points = [
            (mid_root + DVec2::new(0.004, 0.0), 0.004),
            (mid_root - DVec2::new(0.004, 0.0), -0.004),
            (edge + out * 0.005, 0.005),
        ];
        let measured = Measured {
            frame: read_ok(&format!("{AXIAL}rho,z\n16,1\n"), &[]).frame,
            position_at: Source::Line(2),
            points: points
                .iter()
                .enumerate()
                .map(|(i, (at, _))| MeasuredPoint {
                    line: i + 10,
                    at: *at,
                })
                .collect(),
        };
        let got = target.deviations(&measured).unwrap();
        for (g, (_, d)) in got.points.iter().zip(&points) {
            assert!(
                (g.in_section_mm - d).abs() < 1e-9,
                "line {}: {} against {d}",
                g.line,
                g.in_section_mm
            );
        }
        // At the root the surface normal is radial: all of it lies in the plane.
        assert!((got.points[0].deviation_mm - 0.004).abs() < 1e-9);
        assert!((DVec2::from(got.points[2].nearest) - edge).length() < 1e-9);
        assert_eq!((got.max_overcut_line, got.max_undercut_line), (11, 12));
    }

    #[test]
    fn a_transverse_point_moved_along_the_section_s_normal_deviates_by_that_much() {
        let job = trapezoidal();
        let z0 = 20.0;
        let target = SectionTarget::new(&job, Plane::Transverse { z_mm: z0 });
        let length = job.profile.length();
        let theta = z0 / job.p();
        let mut points = Vec::new();
        let mut expected = Vec::new();
        for start in 0..job.groove.starts {
            for k in 1..15 {
                let u = length * (k as f64 + 0.3) / 15.0;
                let turn = theta + TAU / f64::from(job.groove.starts) * f64::from(start);
                let at_u = |u: f64| DVec2::from_angle(turn).rotate(job.profile.point(u).pos);
                let h = 1e-6;
                let t = at_u(u + h) - at_u(u - h);
                if t.length() < 1e-9 {
                    continue;
                }
                // Outward is to the right of the tangent run with increasing polar angle.
                let m = -t.normalize().perp();
                let d = 0.002;
                points.push(MeasuredPoint {
                    line: points.len() + 1,
                    at: at_u(u) + m * d,
                });
                expected.push((d, start));
            }
        }
        let measured = Measured {
            frame: read_ok("# section = transverse\n# z = 20\n# units = mm\n# columns = x, y\n# origin = 0, 0\n1,1\n", &[]).frame,
            position_at: Source::Line(2),
            points,
        };
        let got = target.deviations(&measured).unwrap();
        for (g, (d, start)) in got.points.iter().zip(&expected) {
            assert!(
                (g.in_section_mm - d).abs() < 1e-6,
                "line {}: {}",
                g.line,
                g.in_section_mm
            );
            assert!(g.deviation_mm > 0.0 && g.deviation_mm <= g.in_section_mm + 1e-12);
            assert_eq!((g.start, g.z_mm), (*start, z0));
        }
    }

    #[test]
    fn a_point_far_off_or_outside_the_formed_length_is_refused_naming_its_line() {
        let job = trapezoidal();
        let target = SectionTarget::new(&job, Plane::Axial { angle_deg: 0.0 });
        let frame = read_ok(&format!("{AXIAL}rho,z\n16,1\n"), &[]).frame;
        let (rho_min, rho_max) = job.profile.radius_range();
        let phi0 = job.profile.point(0.0).pos.to_angle();
        let measured = |at: DVec2| Measured {
            frame,
            position_at: Source::Line(2),
            points: vec![
                MeasuredPoint {
                    line: 7,
                    at: axial_point(&job, job.profile.length() / 2.0, phi0)
                        + DVec2::new(0.0, 2.0 * job.groove.lead),
                },
                MeasuredPoint { line: 8, at },
            ],
        };
        // Half the groove's depth above a crest point: its distance from the section, by
        // brute force over dense samples of three pitches, is well above a tenth of the depth.
        let n = 20_000;
        let length = job.profile.length();
        let z0 = 2.0 * job.groove.lead;
        let crest = (0..=n)
            .map(|k| axial_point(&job, length * k as f64 / n as f64, phi0))
            .find(|p| p.x > rho_max - 1e-9)
            .unwrap()
            + DVec2::new(0.0, z0);
        let far = crest + DVec2::new((rho_max - rho_min) / 2.0, 0.0);
        let pitch = job.p() * job.period();
        let nearest = (0..=n)
            .flat_map(|k| [-1.0, 0.0, 1.0].map(|j| (k, j)))
            .map(|(k, j)| {
                let p = axial_point(&job, length * k as f64 / n as f64, phi0);
                (far - p - DVec2::new(0.0, z0 + j * pitch)).length()
            })
            .fold(f64::INFINITY, f64::min);
        let e = target.deviations(&measured(far)).unwrap_err();
        match &e {
            SectionError::Far {
                line,
                distance,
                limit,
                ..
            } => {
                assert_eq!(*line, 8);
                assert!((distance - nearest).abs() < 1e-5, "{distance} {nearest}");
                assert!((limit - (rho_max - rho_min) / 10.0).abs() < 1e-12);
            }
            e => panic!("{e}"),
        }
        assert!(e.to_string().starts_with("line 8: the point"), "{e}");
        let none = Measured {
            points: Vec::new(),
            ..measured(far)
        };
        assert_eq!(
            target.deviations(&none).unwrap_err(),
            SectionError::NoPoints
        );
        let e = target
            .deviations(&measured(DVec2::new(rho_max, 45.0)))
            .unwrap_err();
        assert!(e.to_string().starts_with("line 8: z = 4"), "{e}");
        let transverse = SectionTarget::new(&job, Plane::Transverse { z_mm: -1.0 });
        let frame = read_ok("# section = transverse\n# z = -1\n# units = mm\n# columns = x, y\n# origin = 0, 0\n1,1\n", &[]);
        let e = transverse.deviations(&frame).unwrap_err();
        assert!(
            e.to_string().starts_with(
                "line 2: z = -1.0000 mm lies outside the groove's formed length, z from 0 to 40"
            ),
            "{e}"
        );
    }

    #[test]
    fn the_plot_draws_the_target_the_delta_band_the_points_and_the_fit() {
        let job = trapezoidal();
        let target = SectionTarget::new(&job, Plane::Axial { angle_deg: 0.0 });
        let (rho_min, _) = job.profile.radius_range();
        let m = read_ok(
            &format!(
                "{AXIAL}rho,z\n{},20.1\n{},20.2\n",
                rho_min + 0.001,
                rho_min + 0.002
            ),
            &[],
        );
        let d = target.deviations(&m).unwrap();
        let predicted: Vec<f64> = d.points.iter().map(|p| p.deviation_mm).collect();
        let delta = job.cut.delta;
        let plot = target.plot(&d, Some(&predicted), delta);
        let labels: Vec<&str> = plot.series.iter().map(|s| s.label.as_str()).collect();
        assert_eq!(labels.len(), 5, "{labels:?}");
        let [curve, under, over, measured, fitted] = &plot.series[..] else {
            unreachable!()
        };
        assert_eq!(measured.points.len(), 2);
        // The measured points and the fit that predicts them exactly coincide.
        assert_eq!(measured.points, fitted.points);
        // Magnified by Δ, which is larger than these deviations: the band's edges lie
        // Δ × magnification off the target where the surface normal lies in the plane (the
        // flat at the least radius, whose outward normal is +ρ: the undercut side above it).
        let magnify = magnification(delta, (job.p() * job.period()).abs());
        assert!(labels[1].contains(&format!("× {magnify}")), "{labels:?}");
        let on_flat: Vec<usize> = (0..curve.points.len())
            .filter(|&k| (curve.points[k].1 - rho_min).abs() < 1e-9)
            .collect();
        assert!(on_flat.len() > 10, "{}", on_flat.len());
        for k in on_flat {
            let (z, rho) = curve.points[k];
            let band = delta * magnify;
            assert!((under.points[k].0 - z).abs() < 1e-9);
            assert!((under.points[k].1 - (rho + band)).abs() < 1e-9);
            assert!((over.points[k].1 - (rho - band)).abs() < 1e-9);
        }
        // Everywhere, the band's edges lie at least Δ × magnification off the target (Δ/s,
        // s ≤ 1), on opposite sides.
        for k in 0..curve.points.len() {
            let at = |p: (f64, f64)| DVec2::new(p.0, p.1);
            let (c, u, o) = (at(curve.points[k]), at(under.points[k]), at(over.points[k]));
            assert!((u - c).length() >= delta * magnify * (1.0 - 1e-9));
            assert!(((u - c) + (o - c)).length() < 1e-9, "point {k}");
        }
    }
}
