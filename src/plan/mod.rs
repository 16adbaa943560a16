//! `whirl plan`: job + machine → a checked program and its report.
//!
//! The arrows of the data flow, in order: profile (validated) → linkage table X(ψ) →
//! interference check → error budget → nodes → path → limits. Every step that can refuse does
//! so before anything is written.

pub mod budget;
pub mod interference;
pub mod path;
pub mod scallop;
pub mod segment;
pub mod table;

use crate::config::job::Job;
use crate::config::machine::MachineProfile;
use crate::geometry::linkage::{Linkage, Ring, Whirling};
use crate::geometry::profile::{ConcaveStretch, Profile};
use crate::plan::table::{Table, TableError};
use crate::post::gcode::format::{decimals_for, FormatError};
use crate::post::gcode::writer::{self, PostSettings};
use crate::program::limits::{check_limits, LimitError};
use crate::program::timing::cycle_time_s;
use crate::program::Program;
use budget::{Budget, BudgetError};
use interference::Interference;
use path::PathSpec;
use serde::Serialize;
use std::fmt::Write as _;

/// Extra radial room between the ring and the work at the clear X, mm.
const CLEARANCE: f64 = 2.0;
/// Share of the interpolation budget the table's own sampling may use.
const TABLE_SHARE: f64 = 0.05;

/// A planned job: the program, its text for the machine, and the report.
#[derive(Debug, Clone)]
pub struct Plan {
    /// The program, dialect-free.
    pub program: Program,
    /// The program as the machine's controller reads it.
    pub text: String,
    /// Figures for the engineer.
    pub report: Report,
}

/// What `whirl plan --report` writes.
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    /// Linked (cutting) segments in the program.
    pub segments: usize,
    /// Linear spans per period of the profile.
    pub nodes_per_period: usize,
    /// Largest interpolation error of the chosen nodes (measured on the table), mm.
    pub interp_error_mm: f64,
    /// Feed scallop between neighbouring passes, mm.
    pub scallop_mm: f64,
    /// Insert cusp, mm.
    pub cusp_mm: f64,
    /// Controller blending allowed, mm.
    pub blend_mm: f64,
    /// Rounding of the numbers written and held by the controller, mm.
    pub rounding_mm: f64,
    /// Bound on the profile error: the sum of the parts above plus the table's accuracy, mm.
    pub max_error_mm: f64,
    /// Δ, mm.
    pub delta_mm: f64,
    /// Estimated cycle time (junction slow-downs not counted), s.
    pub cycle_time_s: f64,
    /// Installation angle used, degrees.
    pub installation_angle_deg: f64,
    /// Workpiece revolutions of the linked motion.
    pub revolutions: f64,
    /// Ring-centre Z range of the linked motion, mm.
    pub z_range_mm: [f64; 2],
    /// Axial run-out on each side of the formed length that the ring's contact reaches, mm.
    pub overrun_mm: f64,
    /// Decimals written for X/Z and for C.
    pub decimals: [u32; 2],
    /// Lines of program text.
    pub lines: usize,
}

/// Why a job cannot be planned.
#[derive(Debug, thiserror::Error)]
pub enum PlanError {
    /// Concave stretches the nose cannot follow.
    #[error("{}", concave_message(.0, *.1))]
    Concave(Vec<ConcaveStretch>, f64),
    /// An internal-whirling ring too small to enclose the work.
    #[error(
        "the ring is too small to enclose the work: R·cos δ − r = {reach:.3} mm does not \
         clear the outer radius {rho_max:.3} mm"
    )]
    Clearance {
        /// How far the ring reaches from its centre when tilted, R·cos δ − r, mm.
        reach: f64,
        /// The work's outer radius, mm.
        rho_max: f64,
    },
    /// The linkage failed somewhere on the profile.
    #[error("{cause}{hint}")]
    Table {
        /// Where and why.
        cause: TableError,
        /// Installation angles that would work, if any.
        hint: String,
    },
    /// The ring cuts the groove elsewhere.
    #[error("{cause}{hint}")]
    Interference {
        /// Where.
        cause: Interference,
        /// Installation angles that would work, if any.
        hint: String,
    },
    /// Δ cannot be met.
    #[error(transparent)]
    Budget(#[from] BudgetError),
    /// A 32-bit controller cannot hold C precisely enough over the whole groove.
    #[error(
        "on a controller with 32-bit positions C reaches {c_max:.0}° over this groove, where it \
         is held only to ±{resolution_deg}°: up to {error_mm:.4} mm off the groove, more than \
         half of Δ = {delta} mm (G92 cannot help: grbl keeps machine positions as 32-bit \
         floats). Cut the groove in shorter jobs, raise the axial feed (fewer turns), or use a \
         controller with 64-bit positions"
    )]
    CPrecision {
        /// The largest C the program reaches, degrees.
        c_max: f64,
        /// Half a unit in the last place of a 32-bit float there, degrees.
        resolution_deg: f64,
        /// That as a distance off the groove's surface, at most, mm.
        error_mm: f64,
        /// Δ, mm.
        delta: f64,
    },
    /// Numbers cannot be written precisely enough.
    #[error("number format: {0}")]
    Format(FormatError),
    /// The machine cannot run it.
    #[error("machine limits: move {index} of the planned path: {limit}", index = .limit.index())]
    Limits {
        /// What the planned path asks too much of.
        limit: LimitError,
    },
    /// The post-processor refused it.
    #[error(transparent)]
    Post(#[from] writer::PostError),
}

fn concave_message(stretches: &[ConcaveStretch], nose: f64) -> String {
    let mut s = format!(
        "the profile has concave stretches tighter than the nose radius {nose} mm, which the \
         insert cannot reach:"
    );
    for c in stretches {
        let depth = if c.depth_left.is_finite() {
            format!("leaves {:.4} mm of material", c.depth_left)
        } else {
            "the nose does not fit in at all".to_owned()
        };
        let _ = write!(
            s,
            "\n  at ({:.4}, {:.4}): radius {:.4} mm, {depth}",
            c.at.x, c.at.y, c.min_radius
        );
    }
    s.push_str("\nuse a smaller nose radius or a profile with larger root radii");
    s
}

/// Plan `job` for `machine`.
pub fn plan(job: &Job, machine: &MachineProfile) -> Result<Plan, PlanError> {
    let profile = &job.profile;
    let p = job.p();
    let nose = job.tool.nose_radius;
    let concave = profile.concave_stretches(p, nose);
    if !concave.is_empty() {
        return Err(PlanError::Concave(concave, nose));
    }
    let ring = job.ring();
    let linkage = Linkage { p, ring };
    let (_, rho_max) = profile.radius_range();
    let x_clear = clear_x(&ring, rho_max)?;
    let delta = job.cut.delta;
    let tolerance = TABLE_SHARE * delta;
    let table = Table::build(profile, &linkage, tolerance).map_err(|cause| PlanError::Table {
        cause,
        hint: angle_hint(profile, &linkage, job.groove.starts),
    })?;
    interference::check(profile, &table, &linkage, job.groove.starts, delta / 10.0).map_err(
        |cause| PlanError::Interference {
            cause,
            hint: angle_hint(profile, &linkage, job.groove.starts),
        },
    )?;

    // Numbers. A turn δc of the ring about the workpiece axis moves it off the groove's
    // surface by p·n_z·δc (screw invariance: turning by δc and shifting by p·δc maps the
    // groove onto itself), so C's rounding costs at most |p|·δc whatever the radius. The
    // decimals written keep each axis's rounding below Δ/60, unless the controller's digit
    // limit leaves C fewer (its rounding is then counted as it is). A controller that holds
    // 32-bit floats adds half a unit in the last place of each axis's *machine* position:
    // grbl and grblHAL compute every target as a 32-bit machine position (G92 only renames
    // it), so C's share grows with the turns the groove takes. That share is a fixed cost of
    // the job; beyond Δ/2 the job is refused.
    let share = delta / 30.0;
    let mm_per_deg = p.abs().to_radians();
    let (z_lo, z_hi) = table.z_range();
    let feed = job.cut.axial_feed;
    let z_from = job.groove.z_start + z_lo - 2.0 * feed;
    let z_to = job.groove.z_start + job.groove.length + z_hi + 2.0 * feed;
    let x_max = table
        .samples
        .iter()
        .map(|s| s.contact.pose.x.abs())
        .fold(x_clear.abs(), f64::max);
    // The linked motion's turns, and one for where C starts.
    let c_max = 360.0 * ((z_to - z_from) / feed + 1.0);
    let linear = decimals_for(share / 2.0).map_err(PlanError::Format)?;
    let mut angular = decimals_for((share / 2.0) / mm_per_deg).map_err(PlanError::Format)?;
    if let Some(digits) = machine.dialect.max_number_digits() {
        let whole = c_max.log10().floor() as usize + 1;
        angular = angular.min(digits.saturating_sub(whole) as u32);
    }
    let written = |d: u32| 0.5 * 10f64.powi(-(d as i32));
    // Half the spacing of the controller's numbers: how far a held value can be from the
    // one asked for.
    let held = |v: f64| machine.number.spacing_at(v) / 2.0;
    let c_held = held(c_max) * mm_per_deg;
    if c_held > delta / 2.0 {
        return Err(PlanError::CPrecision {
            c_max,
            resolution_deg: held(c_max),
            error_mm: c_held,
            delta,
        });
    }
    let linear_held = held(x_max).max(held(z_from.abs().max(z_to.abs())));
    let rounding = (written(linear) + linear_held) * 2.0 + written(angular) * mm_per_deg + c_held;

    let blend = machine
        .blend_tolerance_mm
        .map_or(0.0, |b| b.min(delta / 5.0));
    let scallop = crate::plan::scallop::ring(&table, &linkage, feed);
    let cusp = budget::cusp(
        &table,
        &linkage,
        job.tool.inserts,
        job.cut.workpiece_rpm,
        job.cut.ring_rpm,
    );
    let budget = Budget::new(delta, scallop, cusp, blend, rounding, feed)?;
    let nodes = segment::choose(&table, budget.interpolation - tolerance);

    let spec = PathSpec {
        p,
        period: job.period(),
        feed,
        workpiece_rpm: job.cut.workpiece_rpm,
        ring_rpm: job.cut.ring_rpm,
        plunge_feed: job.cut.plunge_feed.unwrap_or(50.0),
        z_from,
        z_to,
        x_clear,
    };
    let title = format!(
        "whirl: {}-start {} hand groove, lead {} mm, {} whirling, R {} r {}, delta {} mm",
        job.groove.starts,
        match job.groove.hand {
            crate::config::job::Hand::Right => "right",
            crate::config::job::Hand::Left => "left",
        },
        job.groove.lead,
        match ring.whirling {
            Whirling::Internal => "internal",
            Whirling::External => "external",
        },
        ring.radius,
        ring.nose,
        delta
    );
    let path = path::build(&nodes, &spec, &title);
    check_limits(&path.program, machine).map_err(|limit| PlanError::Limits { limit })?;
    let settings = PostSettings {
        dialect: machine.dialect,
        linear_decimals: linear,
        angular_decimals: angular,
        x_diameter: machine.x_diameter(),
        blend_tolerance_mm: machine.blend_tolerance_mm.map(|_| blend),
        max_line_length: machine.max_line_length,
    };
    let text = writer::write(&path.program, &settings)?;
    let report = Report {
        segments: path.segments,
        nodes_per_period: nodes.per_period(),
        interp_error_mm: nodes.max_error,
        scallop_mm: scallop,
        cusp_mm: cusp,
        blend_mm: blend,
        rounding_mm: rounding,
        max_error_mm: nodes.max_error + tolerance + scallop + cusp + blend + rounding,
        delta_mm: delta,
        cycle_time_s: cycle_time_s(&path.program, machine),
        installation_angle_deg: ring.installation.to_degrees(),
        revolutions: path.revolutions,
        z_range_mm: [z_from, z_to],
        overrun_mm: (z_hi - z_lo) + 2.0 * feed,
        decimals: [linear, angular],
        lines: text.lines().count(),
    };
    Ok(Plan {
        program: path.program,
        text,
        report,
    })
}

/// The X at which the ring is clear of the work all round.
///
/// Internal: the ring centred on the axis (X = 0); its tip circle, tilted by δ, stays at least
/// R·cos δ from the axis, so it clears a workpiece of radius ρ_max when R·cos δ − r > ρ_max.
/// External: the disk beside the work, its nearest point at X − R − r from the axis.
fn clear_x(ring: &Ring, rho_max: f64) -> Result<f64, PlanError> {
    match ring.whirling {
        Whirling::Internal => {
            let room = ring.radius * ring.installation.cos() - ring.nose - rho_max;
            if room <= 0.0 {
                return Err(PlanError::Clearance {
                    reach: ring.radius * ring.installation.cos() - ring.nose,
                    rho_max,
                });
            }
            Ok(0.0)
        }
        Whirling::External => Ok(ring.radius + ring.nose + rho_max + CLEARANCE),
    }
}

/// Installation angles (whole degrees) at which the linkage and the interference check pass,
/// as a sentence to append to an error; empty when none is found.
fn angle_hint(profile: &Profile, linkage: &Linkage, starts: u32) -> String {
    let works = |deg: f64| {
        let mut l = *linkage;
        l.ring.installation = deg.to_radians();
        Table::build(profile, &l, 1e-3)
            .ok()
            .is_some_and(|t| interference::check(profile, &t, &l, starts, 1e-3).is_ok())
    };
    let mut ranges: Vec<(f64, f64)> = Vec::new();
    for d in 0..=45 {
        let d = f64::from(d);
        if works(d) {
            match ranges.last_mut() {
                Some(r) if r.1 == d - 1.0 => r.1 = d,
                _ => ranges.push((d, d)),
            }
        }
    }
    if ranges.is_empty() {
        return "\nno installation angle from 0° to 45° avoids it with this ring".into();
    }
    let list: Vec<String> = ranges
        .iter()
        .map(|(a, b)| {
            if a == b {
                format!("{a}°")
            } else {
                format!("{a}°–{b}°")
            }
        })
        .collect();
    format!(
        "\ninstallation angles that work with this ring: {} (tool.installation_angle_deg)",
        list.join(", ")
    )
}
