//! `whirl plan`: job + machine → a checked program and its report.
//!
//! The arrows of the data flow, in order: profile (validated) → linkage table X(ψ) →
//! interference check → error budget → nodes → path → limits → post (on LinuxCNC, then the
//! blend-speed cap of linked moves and the post again). Every step that can refuse does so
//! before anything is written.

pub mod angles;
pub mod blocks;
pub mod budget;
pub mod feed;
pub mod interference;
pub mod overrides;
pub mod path;
pub mod scallop;
pub mod segment;
pub mod table;
#[cfg(test)]
mod tests;

use crate::config::job::{depth_refusal, show_figure, show_number, Job};
use crate::config::machine::{Dialect, MachineProfile};
use crate::geometry::linkage::{Linkage, Ring, Whirling};
use crate::geometry::profile::ConcaveStretch;
use crate::plan::table::TableError;
use crate::post::gcode::format::{decimals_for, MAX_DECIMALS};
use crate::post::gcode::read_program;
use crate::post::gcode::writer::{self, PostSettings};
use crate::program::blending::{self, Accels};
use crate::program::limits::{check_limits, LimitError};
use crate::program::timing::cycle_time_s;
use crate::program::Program;
use angles::Misfit;
use budget::{Budget, BudgetError, Spent, MIN_INTERPOLATION_SHARE};
use interference::Interference;
use path::PathSpec;
use serde::Serialize;
use std::fmt::Write as _;

/// Extra radial room between the ring and the work at the clear X, mm.
const CLEARANCE: f64 = 2.0;
/// Share of the interpolation budget the table's own sampling may use.
const TABLE_SHARE: f64 = 0.05;

/// A planned job: the program, its text for the machine, the report, and the ring planned with.
#[derive(Debug, Clone)]
pub struct Plan {
    /// The program, dialect-free.
    pub program: Program,
    /// The program as the machine's controller reads it.
    pub text: String,
    /// Figures for the engineer.
    pub report: Report,
    /// The ring the program was planned with, tilted by the job's installation angle or, where
    /// it gives none, by the window's angle of largest margin ([`angles::ring`]): what the
    /// engine must measure the program with.
    pub ring: Ring,
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
    /// Controller blending allowed, mm. On LinuxCNC it is held by capping the blend speed
    /// of linked moves (`blend_slowed_moves`), not by `G64 P`, which does not bound the
    /// parabolic blends of moves that turn C ([`crate::program::blending`]).
    pub blend_mm: f64,
    /// Linked moves slowed so that LinuxCNC's parabolic blends stay within `blend_mm`; 0 on
    /// controllers that do not blend.
    pub blend_slowed_moves: usize,
    /// The largest corner cut LinuxCNC's blends are predicted to make once capped (at most
    /// `blend_mm` / [`blending::MARGIN`]), mm; 0 on controllers that do not blend.
    pub blend_predicted_mm: f64,
    /// Cycle time the blend-speed cap added (counted in `cycle_time_s`), s.
    pub blend_time_added_s: f64,
    /// Rounding of the numbers written and held by the controller, mm.
    pub rounding_mm: f64,
    /// Material left in concave stretches tighter than the nose but too shallow to refuse
    /// (at most [`CONCAVE_SHARE`] of Δ), mm.
    pub concave_mm: f64,
    /// How far the profile fitted to rounded or measured points lies from them at most, mm
    /// (0 for exact points and standard forms): counted in the budget.
    pub fit_mm: f64,
    /// The profile error the program is held to, mm: the error budget's bound (each side's
    /// shares added where they meet), or, when `measured`, what the sweep engine measured
    /// with what it cannot see added.
    pub max_error_mm: f64,
    /// What the sweep engine measured of the nodes' program, when `whirl plan` measured it.
    pub measured: Option<segment::Measured>,
    /// Δ, mm.
    pub delta_mm: f64,
    /// Estimated cycle time (junction slow-downs not counted; the blend-speed cap counted), s.
    pub cycle_time_s: f64,
    /// Installation angle used, degrees.
    pub installation_angle_deg: f64,
    /// Why that angle: the job gives it, or it gives none and this is the angle with the
    /// largest margin in the window ([`angles`]).
    pub installation_angle_origin: angles::AngleOrigin,
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
    /// Axial feed planned, mm per workpiece revolution: the job's, or the fastest found.
    pub axial_feed_mm: f64,
    /// With `axial_feed = "auto"`: the limit that refuses a feed 5 % higher, and why
    /// ([`feed::FeedBound`]); absent when the job gave its feed.
    pub feed_bound: Option<feed::FeedBound>,
}

impl Report {
    /// One line on LinuxCNC's blending for the console, `None` for a controller that does
    /// not blend: the share, and that it is held by capping the blend speed.
    pub fn blending_summary(&self) -> Option<String> {
        (self.blend_mm > 0.0).then(|| {
            format!(
                "LinuxCNC blending held within {} mm by capping the blend speed: {} of {} \
                 linked moves slowed, +{:.1} s; largest predicted corner cut {:.5} mm",
                show_figure(self.blend_mm),
                self.blend_slowed_moves,
                self.segments,
                self.blend_time_added_s,
                self.blend_predicted_mm,
            )
        })
    }
}

/// Why a job cannot be planned.
#[derive(Debug, thiserror::Error)]
pub enum PlanError {
    /// Concave stretches the nose cannot follow, leaving more material than is tolerated.
    #[error("{}", concave_message(stretches, *nose, *limit, *points))]
    Concave {
        /// The stretches.
        stretches: Vec<ConcaveStretch>,
        /// The nose radius, mm.
        nose: f64,
        /// The most material a tolerated stretch may leave, mm ([`CONCAVE_SHARE`] of Δ).
        limit: f64,
        /// Whether the profile was fitted to points written to decimals: their scatter may
        /// be wider than the decimals say.
        points: bool,
    },
    /// An internal-whirling ring too small to enclose the work at this installation angle.
    #[error(
        "the ring is too small to enclose the work: R·cos δ − r = {reach:.3} mm does not \
         clear the outer radius {rho_max:.3} mm{hint}"
    )]
    Clearance {
        /// How far the ring reaches from its centre when tilted, R·cos δ − r, mm.
        reach: f64,
        /// The work's outer radius, mm.
        rho_max: f64,
        /// Installation angles that would work, if any: a smaller tilt may clear the work.
        hint: String,
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
    /// Δ out of what this job can mean: finer than the numbers can hold, or beyond the
    /// groove's depth.
    #[error("cut.delta = {} mm is {why}", show_number(*.value))]
    Delta {
        /// Δ, mm.
        value: f64,
        /// The bound it passes, mm.
        bound: f64,
        /// Which bound and why.
        why: String,
        /// A higher feed lifts the bound: the controller's numbers hold C less finely the
        /// farther it turns, and fewer turns take it less far. Δ against the groove's depth
        /// or the post's decimals is the same at any feed.
        higher_feed_lifts: bool,
    },
    /// The job gives no installation angle, and the ring fits the groove at none.
    #[error("tool.installation_angle_deg is not given, and {0}")]
    NoAngle(#[from] angles::NoWindow),
    /// Δ cannot be met.
    #[error(transparent)]
    Budget(#[from] BudgetError),
    /// No choice of nodes is within Δ.
    #[error(transparent)]
    Nodes(#[from] segment::NodeError),
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
    /// The machine cannot run it.
    #[error("machine limits: move {index} of the planned path: {limit}", index = .limit.index())]
    Limits {
        /// What the planned path asks too much of.
        limit: LimitError,
    },
    /// The post-processor refused it.
    #[error(transparent)]
    Post(#[from] writer::PostError),
    /// A linked move shorter than the block every move must last on the machine.
    #[error(transparent)]
    BlockTime(#[from] blocks::TooShort),
    /// No feed plans an `axial_feed = "auto"` job.
    #[error(transparent)]
    Feed(#[from] feed::FeedError),
}

/// The share of Δ that a concave stretch tighter than the nose may leave before the job is
/// refused; what the deepest such stretch leaves is counted in the error budget. A spline
/// through dense points follows their rounding, kinking tighter than any nose wherever the
/// rounding zig-zags: at 10 decimals and 0.05 µm apart that leaves 10⁻¹¹ mm, which is no reason
/// to refuse a job, while a root too tight for the nose leaves a good share of Δ or more.
pub const CONCAVE_SHARE: f64 = 0.01;

/// Stretches listed in a refusal; a dense profile (a million points) can have hundreds of
/// thousands, and the deepest say what there is to say.
const CONCAVE_LISTED: usize = 10;

fn concave_message(stretches: &[ConcaveStretch], nose: f64, limit: f64, points: bool) -> String {
    let mut s = format!(
        "the profile has concave stretches tighter than the nose radius {nose} mm, which the \
         insert cannot reach, leaving more than {} mm of material (Δ/{:.0}):",
        show_figure(limit),
        1.0 / CONCAVE_SHARE
    );
    let mut listed: Vec<&ConcaveStretch> = stretches.iter().collect();
    if listed.len() > CONCAVE_LISTED {
        // The deepest first (the nose not fitting in at all is deepest), then in profile order.
        listed.sort_by(|a, b| b.depth_left.total_cmp(&a.depth_left));
        listed.truncate(CONCAVE_LISTED);
    }
    for c in stretches
        .iter()
        .filter(|c| listed.iter().any(|l| std::ptr::eq(*l, *c)))
    {
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
    if stretches.len() > CONCAVE_LISTED {
        let _ = write!(
            s,
            "\n  … and {} more, none deeper ({} in all)",
            stretches.len() - CONCAVE_LISTED,
            stretches.len()
        );
    }
    s.push_str("\nuse a smaller nose radius or a profile with larger root radii");
    if points {
        s.push_str(
            "; if the points scatter more than their decimals say (a measurement), give how \
             far they may be off as [groove.profile] fit_tolerance, and the profile is fitted \
             within it",
        );
    }
    s
}

/// Plan `job` for `machine`, its nodes held within Δ by the error budget's estimate.
pub fn plan(job: &Job, machine: &MachineProfile) -> Result<Plan, PlanError> {
    plan_with(job, machine, &segment::Estimated)
}

/// Plan `job` for `machine`, `choice` choosing the nodes (the other choice is the judge's
/// plan → measure → re-plan loop, `crate::judge::refine`).
pub fn plan_with(
    job: &Job,
    machine: &MachineProfile,
    choice: &dyn segment::NodeChoice,
) -> Result<Plan, PlanError> {
    // `axial_feed = "auto"`: the fastest feed the job and the machine allow, every feed
    // planned with this node choice.
    if job.cut.auto_feed {
        return feed::fastest(job, machine, choice).map(|fastest| fastest.plan);
    }
    plan_resolved(job, machine, choice, &angles::Resolved::default())
}

/// [`plan_with`] of a job whose feed is given, its ring taken from `angle` (found there once
/// for every feed of the job).
pub(crate) fn plan_resolved(
    job: &Job,
    machine: &MachineProfile,
    choice: &dyn segment::NodeChoice,
    angle: &angles::Resolved,
) -> Result<Plan, PlanError> {
    let profile = &job.profile;
    let p = job.p();
    let nose = job.tool.nose_radius;
    let delta = job.cut.delta;
    let (rho_min, rho_max) = profile.radius_range();
    // Numbers. A turn δc of the ring about the workpiece axis moves it off the groove's
    // surface by p·n_z·δc (screw invariance: turning by δc and shifting by p·δc maps the
    // groove onto itself), so C's rounding costs at most |p|·δc whatever the radius. The
    // decimals written keep each axis's rounding below Δ/60, unless the controller's digit
    // limit leaves C fewer (its rounding is then counted as it is). A controller that holds
    // 32-bit floats adds half a unit in the last place of each axis's *machine* position:
    // grbl and grblHAL compute every target as a 32-bit machine position (G92 only renames
    // it), so C's share grows with the turns the groove takes. That share is a fixed cost of
    // the job; beyond Δ/2 the job is refused.
    let mm_per_deg = p.abs().to_radians();
    let written = |d: u32| 0.5 * 10f64.powi(-(d as i32));
    // Half the spacing of the controller's numbers: how far a held value can be from the
    // one asked for.
    let held = |v: f64| machine.number.spacing_at(v) / 2.0;
    // An absurd Δ is refused before any work: one the numbers cannot hold, or one beyond the
    // groove's depth. What passes gets its decimals here.
    let tool = &job.tool;
    let x_clear_least = clear_position(tool.whirling, tool.ring_radius, tool.nose_radius, rho_max);
    let (linear, angular) = check_delta(job, machine, (rho_min, rho_max), x_clear_least)?;
    // Concave stretches tighter than the nose: the shallow ones are a cost, the others refused.
    let limit = CONCAVE_SHARE * delta;
    let (stretches, shallow): (Vec<_>, Vec<_>) = profile
        .concave_stretches(p, nose)
        .into_iter()
        .partition(|c| c.depth_left > limit || c.depth_left.is_nan());
    let concave = shallow.iter().map(|c| c.depth_left).fold(0.0, f64::max);
    if !stretches.is_empty() {
        return Err(PlanError::Concave {
            stretches,
            nose,
            limit,
            points: profile.rounding().is_some(),
        });
    }
    // The installation angle: the job's, or the one with the largest margin in its windows.
    let (ring, angle_origin) = angle.ring(job)?;
    let linkage = Linkage { p, ring };
    let tolerance = TABLE_SHARE * delta;
    let angles::Fitted { table, x_clear } =
        angles::fit(job, &linkage).map_err(|misfit| misfit.refusal(angles::hint(job)))?;

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
    let mut angular = angular;
    if let Some(digits) = machine.dialect.max_number_digits() {
        let whole = c_max.log10().floor() as usize + 1;
        angular = angular.min(digits.saturating_sub(whole) as u32);
    }
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
    let scallops = crate::plan::scallop::ring(&table, &linkage, feed);
    let scallop = scallops.max();
    let cusp = budget::cusp(
        &table,
        &linkage,
        job.tool.inserts,
        job.cut.workpiece_rpm,
        job.cut.ring_rpm,
    );
    let spent = Spent {
        scallop,
        cusp,
        blend,
        rounding,
        concave,
        fit: profile.fit().map_or(0.0, |fit| fit.deviation),
    };
    let budget = Budget::new(delta, spent, feed)?;
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
    let chosen = choice.choose(&segment::Problem {
        job,
        linkage: &linkage,
        table: &table,
        budget: &budget,
        scallops: &scallops,
        table_accuracy: tolerance,
        rounding: [
            written(linear) + linear_held,
            written(angular) * mm_per_deg + c_held,
        ],
        spec: &spec,
    })?;
    let nodes = &chosen.nodes;
    let title = format!(
        "whirl: {}-start {} hand groove, lead {} mm, {} whirling, R {} r {}, delta {} mm",
        job.groove.starts,
        match job.groove.hand {
            crate::config::job::Hand::Right => "right",
            crate::config::job::Hand::Left => "left",
        },
        job.groove.lead,
        ring.whirling.name(),
        ring.radius,
        ring.nose,
        delta
    );
    let mut path = path::build(&nodes.nodes, &spec, &title);
    check_limits(&path.program, machine).map_err(|limit| PlanError::Limits { limit })?;
    let settings = PostSettings {
        dialect: machine.dialect,
        linear_decimals: linear,
        angular_decimals: angular,
        x_diameter: machine.x_diameter(),
        blend_tolerance_mm: machine.blend_tolerance_mm.map(|_| blend),
        max_line_length: machine.max_line_length,
    };
    let mut text = writer::write(&path.program, &settings)?;
    // LinuxCNC blends consecutive linked moves parabolically, and G64 P does not bound those
    // blends: slow the moves until they are within the blend share. The corners are those of
    // the polyline as posted, read back from the text; slowing only lowers speeds, so the
    // limits checked above still hold, and the text is written again with the new F words.
    let capped = match (machine.dialect, machine.blend_tolerance_mm) {
        (Dialect::LinuxCnc, Some(_)) => {
            let accels = Accels::of(machine);
            let capped = match read_program(&text, machine.x_diameter()) {
                Ok(posted) => {
                    blending::cap_linked_feeds_as_posted(&mut path.program, &posted, accels, blend)
                }
                // The post's text always reads back; were it not to, its own corners.
                Err(_) => blending::cap_linked_feeds(&mut path.program, accels, blend),
            };
            if capped.slowed > 0 {
                text = writer::write(&path.program, &settings)?;
            }
            capped
        }
        _ => blending::Capped::default(),
    };
    blocks::check(&path.program, &text, machine, job.cut.workpiece_rpm)?;
    let report = Report {
        segments: path.segments,
        nodes_per_period: nodes.per_period(),
        interp_error_mm: nodes.overcut.max(nodes.undercut),
        scallop_mm: scallop,
        cusp_mm: cusp,
        blend_mm: blend,
        blend_slowed_moves: capped.slowed,
        blend_predicted_mm: capped.max_deviation_mm,
        blend_time_added_s: capped.added_s,
        rounding_mm: rounding,
        concave_mm: concave,
        fit_mm: budget.fit,
        max_error_mm: chosen.max_error,
        measured: chosen.measured,
        delta_mm: delta,
        cycle_time_s: cycle_time_s(&path.program, machine),
        installation_angle_deg: ring.installation.to_degrees(),
        installation_angle_origin: angle_origin,
        revolutions: path.revolutions,
        z_range_mm: [z_from, z_to],
        overrun_mm: (z_hi - z_lo) + 2.0 * feed,
        decimals: [linear, angular],
        lines: text.lines().count(),
        axial_feed_mm: feed,
        feed_bound: None,
    };
    Ok(Plan {
        program: path.program,
        text,
        report,
        ring,
    })
}

/// Refuse an absurd Δ at once, before any heavy work, naming `cut.delta`, its value and the
/// bound it passes; otherwise return the decimals for X/Z and for C (before any digit limit of
/// the controller).
///
/// - **Above the groove's depth** (ρ_max − ρ_min): an error that large bounds nothing; every
///   groove would be "within Δ" of a plain cylinder.
/// - **Below what the post can write:** the decimals keep each axis's rounding below Δ/60, and
///   the post writes at most [`MAX_DECIMALS`] of them (±0.5·10⁻⁶ mm, and ±0.5·10⁻⁶° of C,
///   |p|·π/180 mm a degree), so Δ must exceed 60·0.5·10⁻⁶·max(1, |p|·π/180) mm.
/// - **Below what the controller's numbers hold at the groove's size:** rounding is a fixed
///   cost that must leave interpolation [`MIN_INTERPOLATION_SHARE`] of Δ. Its least possible
///   value follows from the decimals and from the number type's spacing at the smallest
///   positions the program must reach whatever the table: X at the clear position, |Z| at
///   least half the ring centre's run (the formed length and four feeds), and C at least
///   `360°·(run/feed + 1)`. Any Δ refused here would be refused by the error budget after the
///   table, the interference check and the scallop sweep (at Δ = 10⁻¹² mm: half a minute and
///   more than a gigabyte).
fn check_delta(
    job: &Job,
    machine: &MachineProfile,
    (rho_min, rho_max): (f64, f64),
    x_clear: f64,
) -> Result<(u32, u32), PlanError> {
    let delta = job.cut.delta;
    let written = |d: u32| 0.5 * 10f64.powi(-(d as i32));
    let held = |v: f64| machine.number.spacing_at(v) / 2.0;
    if let Some(why) = depth_refusal(delta, rho_min, rho_max) {
        return Err(PlanError::Delta {
            value: delta,
            bound: rho_max - rho_min,
            why,
            higher_feed_lifts: false,
        });
    }
    let share = delta / 30.0;
    let mm_per_deg = job.p().abs().to_radians();
    let finest = 0.5 * 10f64.powi(-(MAX_DECIMALS as i32));
    let post_bound = 60.0 * finest * mm_per_deg.max(1.0);
    let (Ok(linear), Ok(angular)) = (
        decimals_for(share / 2.0),
        decimals_for((share / 2.0) / mm_per_deg),
    ) else {
        return Err(PlanError::Delta {
            value: delta,
            bound: post_bound,
            why: format!(
                "below {} mm, the finest the post can write for this groove: at most \
                 {MAX_DECIMALS} decimals, ±{} mm of X and Z and ±{}° of C ({} mm a degree), \
                 and each axis's rounding must stay below Δ/60",
                show_figure(post_bound),
                show_figure(finest),
                show_figure(finest),
                show_figure(mm_per_deg),
            ),
            higher_feed_lifts: false,
        });
    };
    let feed = job.cut.axial_feed;
    let run = job.groove.length + 4.0 * feed;
    let (x_or_z, c_min) = (x_clear.abs().max(run / 2.0), 360.0 * (run / feed + 1.0));
    let held_least = 2.0 * held(x_or_z) + held(c_min) * mm_per_deg;
    let rounding_least = held_least + 2.0 * written(linear) + written(angular) * mm_per_deg;
    let room = 1.0 - MIN_INTERPOLATION_SHARE;
    if rounding_least > room * delta {
        return Err(PlanError::Delta {
            value: delta,
            bound: rounding_least / room,
            why: format!(
                "below what the controller's numbers hold at this groove's size: X and Z reach \
                 at least {} mm, where they are held to ±{} mm, and C at least {:.0}°, held to \
                 ±{}° ({} mm); with the decimals written that is {} mm of rounding, more than \
                 {:.0} % of Δ, which leaves interpolation less than the rest it needs (Δ must be \
                 above {} mm)",
                show_figure(x_or_z),
                show_figure(held(x_or_z)),
                c_min,
                show_figure(held(c_min)),
                show_figure(held(c_min) * mm_per_deg),
                show_figure(rounding_least),
                room * 100.0,
                show_figure(rounding_least / room),
            ),
            higher_feed_lifts: true,
        });
    }
    Ok((linear, angular))
}

/// The X at which a ring of radius `radius` and nose `nose` is clear of the work all round,
/// whatever its tilt, if it clears it at all: internal, centred on the axis (X = 0); external,
/// the disk beside the work, its nearest point at X − R − r from the axis; a bore head,
/// centred in the bore (X = 0), where it is R + r from the axis all round and the job has
/// made sure that is inside the bore ([`crate::config::job`]).
fn clear_position(whirling: Whirling, radius: f64, nose: f64, rho_max: f64) -> f64 {
    match whirling {
        Whirling::Internal | Whirling::Bore => 0.0,
        Whirling::External => radius + nose + rho_max + CLEARANCE,
    }
}

/// The X at which the ring is clear of the work all round ([`clear_position`]), or why it
/// cannot be: an internal ring's tip circle, tilted by δ, stays at least R·cos δ from the
/// axis, so it clears a workpiece of radius ρ_max when R·cos δ − r > ρ_max.
fn clear_x(ring: &Ring, rho_max: f64) -> Result<f64, Misfit> {
    let reach = ring.radius * ring.installation.cos() - ring.nose;
    if ring.whirling == Whirling::Internal && reach <= rho_max {
        return Err(Misfit::Clearance { reach, rho_max });
    }
    Ok(clear_position(
        ring.whirling,
        ring.radius,
        ring.nose,
        rho_max,
    ))
}
