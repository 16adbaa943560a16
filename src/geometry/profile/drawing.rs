//! Profiles from CAD drawings (DXF), kept as the exact curves they are drawn with.
//!
//! A shop hands over the groove as a drawing. Its entities on one layer (LINE, ARC, CIRCLE,
//! LWPOLYLINE and old-style POLYLINE with bulges, SPLINE as NURBS) are read in the drawing's
//! units (`$INSUNITS`, or the job's `units`), chained end to end, and turned into the profile's
//! pieces without sampling: lines and arcs stay lines and arcs, splines stay NURBS
//! ([`super::Piece`]). The section is either
//! - transverse: the drawing's X/Y are the transverse section's x, y (as a points file's
//!   `x,y`); or
//! - axial: the screw axis along the drawing's X (z) and the radius along its Y (ρ), as a
//!   machinist draws a thread; its points are seen in the transverse plane by kinematics.md's
//!   rule, as standard profiles are.
//!
//! The outline is either one period of the groove as drawn (an open chain whose ends lie one
//! period apart: 2π/starts of polar angle, or one axial pitch lead/starts along z), or a closed
//! outline of more (a whole thread form with its core, a whole transverse section), from
//! which the period that starts at a crest point (the outline's largest radius) is taken.
//!
//! Everything the drawing gets wrong is refused naming the entity by its handle and layer, as
//! a draughtsman finds it in the CAD program: a gap or an overlap between entities (with the
//! distance), an open outline, several outlines, no entity on the layer, an entity of a kind
//! that is not a curve of the section, missing or implausible units, an outline that runs
//! backwards (crosses itself or doubles back), and an outline that is not one period. This
//! module takes the drawing's bytes, not a file: the job reads the file.

// A refusal names two entities by kind, handle and layer, and where: larger than clippy's
// bound for an error, and made once per job load, never in a loop that a copy would slow.
#![allow(clippy::result_large_err)]

mod chain;
mod entities;

use super::{Material, Profile};
use glam::DVec2;
use std::fmt;

pub use dxf::Drawing;

/// Two entity ends closer than this, mm, are joined; farther apart, they leave a gap. CAD
/// programs write coordinates to 15 or 16 significant digits, so ends that meet in the
/// drawing are within nanometres of each other in the file.
pub const JOIN: f64 = 1e-6;

/// Which section a drawing shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Section {
    /// The drawing's X/Y are the transverse section's x, y.
    Transverse,
    /// The drawing's X is the screw axis (z), its Y the radius (ρ).
    Axial,
}

/// The units a drawing may be in, with their length in mm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Units {
    /// The unit's name as a job writes it.
    pub name: &'static str,
    /// Its length, mm.
    pub mm: f64,
}

/// The units a thread may be drawn in: `$INSUNITS` code, name, length in mm. Other codes
/// (miles, kilometres, light years…) are refused: a screw drawn in them is a mistake.
const UNITS: [(i16, &str, f64); 10] = [
    (1, "in", 25.4),
    (2, "ft", 304.8),
    (4, "mm", 1.0),
    (5, "cm", 10.0),
    (6, "m", 1000.0),
    (8, "uin", 25.4e-6),
    (9, "mil", 0.0254),
    (12, "nm", 1e-6),
    (13, "um", 1e-3),
    (14, "dm", 100.0),
];

impl Units {
    /// The units a job names (`"mm"`, `"in"`, `"um"`…).
    pub fn named(name: &str) -> Result<Units, DrawingError> {
        let name = match name {
            "inch" => "in",
            "µm" => "um",
            other => other,
        };
        UNITS
            .iter()
            .find(|(_, n, _)| *n == name)
            .map(|&(_, name, mm)| Units { name, mm })
            .ok_or_else(|| DrawingError::UnknownUnits(name.to_owned()))
    }

    /// The units of a drawing's `$INSUNITS` code.
    fn of_code(code: i16) -> Result<Units, DrawingError> {
        if code == 0 {
            return Err(DrawingError::NoUnits);
        }
        UNITS
            .iter()
            .find(|(c, _, _)| *c == code)
            .map(|&(_, name, mm)| Units { name, mm })
            .ok_or(DrawingError::WrongUnits { code })
    }
}

/// What a profile is taken from a drawing with.
#[derive(Debug, Clone, PartialEq)]
pub struct Options {
    /// Only the entities of this layer (all of the model space's when `None`).
    pub layer: Option<String>,
    /// The drawing's units, overriding its `$INSUNITS` (needed when it has none).
    pub units: Option<Units>,
    /// Which section it shows.
    pub section: Section,
    /// Lead parameter p = ±lead / 2π (+ right hand).
    pub p: f64,
    /// Number of starts.
    pub starts: u32,
    /// Which side of the groove the material lies: inside for a screw, whose closed outline
    /// gives the groove below its crest line; outside for a nut, whose outline gives the
    /// groove above its bore.
    pub material: Material,
}

/// An entity as a CAD program shows it: its kind, handle and layer, and for a polyline, which
/// of its segments (from 1).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EntityRef {
    /// DXF entity type: `LINE`, `ARC`, `LWPOLYLINE`…
    pub kind: String,
    /// Its handle (DXF group code 5), shown in hexadecimal as DXF writes it.
    pub handle: u64,
    /// Its layer.
    pub layer: String,
    /// For a polyline, the segment (from 1).
    pub segment: Option<usize>,
}

impl fmt::Display for EntityRef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} #{:X}", self.kind, self.handle)?;
        if let Some(segment) = self.segment {
            write!(f, " segment {segment}")?;
        }
        write!(f, " on layer {:?}", self.layer)
    }
}

/// A point for a message, in mm.
struct At(DVec2);

impl fmt::Display for At {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "({:.6}, {:.6})", self.0.x, self.0.y)
    }
}

/// A distance for a message, mm, in exponent form when small.
fn mm(v: f64) -> String {
    if v != 0.0 && v.abs() < 1e-3 {
        format!("{v:.3e} mm")
    } else {
        format!("{v:.6} mm")
    }
}

/// Why a drawing gives no profile. Points are given in the drawing's own X/Y, in mm.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DrawingError {
    /// Not a DXF file the reader understands.
    #[error("not a readable DXF drawing: {0}")]
    Read(String),
    /// `$INSUNITS` is 0 (unitless) or absent, and the job gives no units.
    #[error(
        "the drawing has no units ($INSUNITS unitless or absent, as in every R12 file): give \
         units = \"mm\" (or \"in\", \"um\"…) in [groove.profile]"
    )]
    NoUnits,
    /// `$INSUNITS` names a unit no thread is drawn in.
    #[error(
        "the drawing's units ($INSUNITS = {code}) are not a unit a thread is drawn in (mm, \
         cm, dm, m, um, nm, in, ft, mil, uin): give units = \"mm\" (or the unit it is drawn \
         in) in [groove.profile]"
    )]
    WrongUnits {
        /// The `$INSUNITS` code.
        code: i16,
    },
    /// The job names units this reader does not know.
    #[error("units = {0:?}: give one of mm, cm, dm, m, um, nm, in, ft, mil, uin")]
    UnknownUnits(String),
    /// Nothing to read on the layer.
    #[error("{}", no_entity(layer, layers))]
    NoEntity {
        /// The layer asked for (`None`: the whole model space).
        layer: Option<String>,
        /// The layers that do have entities.
        layers: Vec<String>,
    },
    /// An entity that is not a curve of the section.
    #[error("{entity}: {why}")]
    Unsupported {
        /// The entity.
        entity: EntityRef,
        /// Why it cannot be read.
        why: String,
    },
    /// Two entities' ends that should meet do not.
    #[error(
        "gap of {} between {a} and {b} at {}: the ends that should meet are that far apart",
        mm(*distance), At(*at)
    )]
    Gap {
        /// One side.
        a: EntityRef,
        /// The other side.
        b: EntityRef,
        /// The end of `a`.
        at: DVec2,
        /// How far apart the ends are, mm.
        distance: f64,
    },
    /// An entity runs onto another, or more than two entities meet at one point.
    #[error("overlap: {a} and {b} lie on top of each other at {}, over {}", At(*at), mm(*distance))]
    Overlap {
        /// One entity.
        a: EntityRef,
        /// The other.
        b: EntityRef,
        /// Where.
        at: DVec2,
        /// How far `a` runs along `b` past `b`'s end (0 where three entities meet at one
        /// point), mm.
        distance: f64,
    },
    /// The outline does not close and its ends are not one period apart.
    #[error(
        "open outline: it ends at {} on {last} and starts at {} on {first}; its end lies {} \
         from its start {}: close the outline, or draw exactly one period of the groove",
        At(*end), At(*start), mm(*distance), period_shift(*section)
    )]
    Open {
        /// The entity at the outline's start.
        first: EntityRef,
        /// The entity at its end.
        last: EntityRef,
        /// Start point.
        start: DVec2,
        /// End point.
        end: DVec2,
        /// How far the end lies from the start shifted by one period, mm.
        distance: f64,
        /// The section.
        section: Section,
    },
    /// The outline's polar angle (transverse) or z (axial) decreases along an entity.
    #[error(
        "the outline turns back on {entity} at {}: its {} decreases there, so the outline \
         crosses itself or doubles back (a groove's section meets each {} once)",
        At(*at), phase_name(*section), phase_line(*section)
    )]
    Backwards {
        /// The entity.
        entity: EntityRef,
        /// Where.
        at: DVec2,
        /// The section.
        section: Section,
    },
    /// The outline spans more or less than one period.
    #[error(
        "the outline from {first} to {last} spans {} of {}, not one period ({}){}",
        show_phase(*span, *section), phase_name(*section), show_phase(*period, *section),
        if *closed { ": no point of it one period on from a crest point is an entity's end" } else { "" }
    )]
    NotOnePeriod {
        /// The entity where the span starts.
        first: EntityRef,
        /// The entity where it ends.
        last: EntityRef,
        /// The span found (radians or mm).
        span: f64,
        /// One period (radians or mm).
        period: f64,
        /// The section.
        section: Section,
        /// Whether the outline is closed (and the period was looked for along it).
        closed: bool,
    },
    /// An entity of zero length or radius.
    #[error("{entity} has no length ({why})")]
    Degenerate {
        /// The entity.
        entity: EntityRef,
        /// What is zero.
        why: String,
    },
}

fn no_entity(layer: &Option<String>, layers: &[String]) -> String {
    let found = if layers.is_empty() {
        "the drawing's model space has no entity at all".to_owned()
    } else {
        format!("layers with entities: {}", layers.join(", "))
    };
    match layer {
        Some(layer) => format!("no entity on layer {layer:?} ({found})"),
        None => format!("no entity to read ({found})"),
    }
}

fn phase_name(section: Section) -> &'static str {
    match section {
        Section::Transverse => "polar angle",
        Section::Axial => "axial position z (the drawing's X)",
    }
}

fn phase_line(section: Section) -> &'static str {
    match section {
        Section::Transverse => "ray from the screw axis",
        Section::Axial => "line across the axis",
    }
}

fn period_shift(section: Section) -> &'static str {
    match section {
        Section::Transverse => "turned by one period",
        Section::Axial => "moved one axial pitch along X",
    }
}

fn show_phase(v: f64, section: Section) -> String {
    match section {
        Section::Transverse => format!("{:.6}°", v.to_degrees()),
        Section::Axial => mm(v),
    }
}

/// Parse a DXF drawing (ASCII or binary) from its bytes.
pub fn read(bytes: &[u8]) -> Result<Drawing, DrawingError> {
    Drawing::load(&mut std::io::Cursor::new(bytes)).map_err(|e| DrawingError::Read(e.to_string()))
}

/// The profile a drawing draws: one period of the groove's transverse section, its lines,
/// arcs and splines kept exact.
pub fn profile(drawing: &Drawing, options: &Options) -> Result<Profile, DrawingError> {
    let units = match options.units {
        Some(units) => units,
        None => Units::of_code(drawing.header.default_drawing_units as i16)?,
    };
    let curves = entities::curves(drawing, options.layer.as_deref(), units.mm, options.section)?;
    let period = match options.section {
        Section::Transverse => std::f64::consts::TAU / f64::from(options.starts),
        Section::Axial => options.p.abs() * std::f64::consts::TAU / f64::from(options.starts),
    };
    let outline = chain::chain(curves, options.section)?;
    let ordered = chain::one_period(outline, options.section, period, options.material)?;
    Ok(chain::pieces(ordered, options))
}

#[cfg(test)]
mod tests;
