//! The installation-angle window: every angle δ at which the ring fits the groove as `plan`
//! checks it, the error and segments `plan` gets across it, and the angle farthest from its
//! edges.
//!
//! A whirling ring is tilted by hand, and the tilt is off by a little: an angle near the edge
//! of what the groove allows plans, yet a ring set a little beyond it cuts a flank or a
//! neighbouring thread. So `plan`, given no angle, takes the one with the largest margin (the
//! distance in degrees to the nearer edge): the middle of the widest window.
//!
//! One source of truth: an angle is in a window when `fit` passes, and `fit` is what
//! `plan` runs at the angle it plans with: the ring clears the work, the linkage table has one
//! pose per profile point on one branch, and no other part of the ring cuts the groove, each
//! to `plan`'s tolerances. A refusal of an angle lists the windows found here.
//!
//! **The scan.** Every angle a job may give, [0°, 90°), is scanned at [`SCAN_STEP_DEG`], and
//! so are the lead angles at the groove's least, mean and greatest radius, near which a narrow
//! window is most likely (the ring's plane then holds the helix's tangent). Between a scan
//! angle that fits and a neighbour that does not, the edge is bisected to
//! [`EDGE_TOLERANCE_DEG`]. Every angle found here lies on that grid (the lead angles are
//! rounded to it): an edge as printed, "7.107°", is the angle checked, so a job that gives
//! it plans, and a job that gives the angle chosen plans the program `plan` makes when it
//! chooses. The ring's clearance and the linkage table cost about a millisecond where they
//! pass, and less where ψ turns back (`Search`); the interference check, which sweeps the
//! whole groove for every start, a few. So an edge where the table fails is bisected on the
//! clearance and the table alone, and the interference check then run at the angle found: if
//! it passes there, the edge is the table's; if not, it is bisected again on the whole check,
//! inside. The scan's angles, and then the edges, are checked on every core at once. A window
//! narrower than a scan step away from those lead angles may fall between two scan angles and
//! be missed.

use super::{clear_x, Plan, PlanError, TABLE_SHARE};
use crate::config::job::Job;
use crate::geometry::linkage::{Linkage, Ring};
use crate::plan::interference::{self, Interference};
use crate::plan::table::{Table, TableError};
use serde::Serialize;
use std::sync::atomic::{AtomicUsize, Ordering};

/// The grid every angle found here lies on: steps a degree.
const STEPS_PER_DEG: i64 = 1000;
/// The step of the scan over the installation angle, degrees.
pub const SCAN_STEP_DEG: f64 = SCAN_STEPS as f64 / STEPS_PER_DEG as f64;
/// [`SCAN_STEP_DEG`] in grid steps.
const SCAN_STEPS: i64 = 500;
/// How close bisection brings a window's edge to the angle beyond it that does not fit,
/// degrees: one grid step.
pub const EDGE_TOLERANCE_DEG: f64 = 1.0 / STEPS_PER_DEG as f64;
/// The angles a job may give run from 0° up to this, not including it.
pub const RANGE_DEG: f64 = RANGE_STEPS as f64 / STEPS_PER_DEG as f64;
/// [`RANGE_DEG`] in grid steps.
const RANGE_STEPS: i64 = 90 * STEPS_PER_DEG;

/// An angle on the grid, in degrees: `steps` / [`STEPS_PER_DEG`], the double nearest the
/// decimal it prints as (7107 steps are the 7.107 a job file's "7.107" reads as).
fn degrees(steps: i64) -> f64 {
    steps as f64 / STEPS_PER_DEG as f64
}

/// The grid step nearest `deg`.
fn steps(deg: f64) -> i64 {
    (deg * STEPS_PER_DEG as f64).round() as i64
}

/// Why the ring does not fit the groove at one installation angle: the refusals of `plan`
/// that depend on it.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Misfit {
    /// An internal-whirling ring, tilted this far, cannot enclose the work.
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
    #[error(transparent)]
    Table(TableError),
    /// The ring cuts the groove elsewhere.
    #[error(transparent)]
    Interference(Interference),
}

impl Misfit {
    /// The refusal `plan` gives for it, `hint` (the installation angles that work) appended to
    /// the linkage's and the interference check's.
    pub(crate) fn refusal(self, hint: String) -> PlanError {
        match self {
            Misfit::Clearance { reach, rho_max } => PlanError::Clearance {
                reach,
                rho_max,
                hint,
            },
            Misfit::Table(cause) => PlanError::Table { cause, hint },
            Misfit::Interference(cause) => PlanError::Interference { cause, hint },
        }
    }

    /// How far from fitting, for finding where a job that fits nowhere came nearest: the
    /// further through `plan`'s checks the nearer (the clearance, then the linkage table,
    /// then the interference check), and within the clearance and the interference check the
    /// smaller the shortfall or the depth, mm. Smaller is nearer.
    fn distance(&self) -> (u8, f64) {
        match self {
            Misfit::Clearance { reach, rho_max } => (2, rho_max - reach),
            Misfit::Table(_) => (1, 0.0),
            Misfit::Interference(i) => (0, i.depth),
        }
    }
}

/// What `plan` keeps of a fit: the linkage table and the ring's clear X.
#[derive(Debug, Clone)]
pub(crate) struct Fitted {
    /// The cutter-location table of one period.
    pub(crate) table: Table,
    /// The X at which the ring is clear of the work all round.
    pub(crate) x_clear: f64,
}

/// `plan`'s checks that depend on the installation angle, in its order and to its
/// tolerances: the ring clears the work at its clear position, the linkage table builds to
/// [`TABLE_SHARE`] of Δ (and to the engine's tolerance, which measures what `whirl plan`
/// plans), and the interference check, run on the finer of the two tables, finds nothing
/// deeper than Δ/10.
pub(crate) fn fit(job: &Job, linkage: &Linkage) -> Result<Fitted, Misfit> {
    let (_, rho_max) = job.profile.radius_range();
    let x_clear = clear_x(&linkage.ring, rho_max)?;
    let tolerance = TABLE_SHARE * job.cut.delta;
    let table = Table::build(&job.profile, linkage, tolerance).map_err(Misfit::Table)?;
    let finer = (ENGINE_TABLE_TOLERANCE < tolerance)
        .then(|| Table::build(&job.profile, linkage, ENGINE_TABLE_TOLERANCE))
        .transpose()
        .map_err(Misfit::Table)?;
    interferes(job, linkage, finer.as_ref().unwrap_or(&table))?;
    Ok(Fitted { table, x_clear })
}

/// The interference check of [`fit`] on `table`.
fn interferes(job: &Job, linkage: &Linkage, table: &Table) -> Result<(), Misfit> {
    interference::check(
        &job.profile,
        table,
        linkage,
        job.groove.starts,
        job.cut.delta / 10.0,
    )
    .map_err(Misfit::Interference)
}

/// The tolerance of the linkage table the sweep engine seeds its search with
/// (`crate::judge::measure::Target::new`), mm. A denser table samples the profile more finely
/// and finds a turn of ψ that a coarser one steps over near a window's edge; `whirl plan`
/// measures every plan with the engine, so an angle fits only where that table builds too.
const ENGINE_TABLE_TOLERANCE: f64 = 1e-4;

/// [`fit`]'s verdict at the grid angles of one job, found as cheaply as it can be.
///
/// A table to a finer tolerance samples every profile point a coarser one samples (the
/// refinement halves the same spans, and more of them), so where the finer table builds, the
/// coarser one does too: the finer of `fit`'s two tables alone decides whether the linkage
/// fits, and the interference check runs on it. It is built with [`Table::probe`], which
/// stops where ψ first turns back. Where a table is refused, its refusal may then name
/// another profile point than `fit`'s; [`Search::reason`] gives `fit`'s where one is shown.
struct Search<'a> {
    job: &'a Job,
    /// The work's outer radius, mm.
    rho_max: f64,
    /// The finer of the tables' tolerances, mm.
    finest: f64,
}

impl<'a> Search<'a> {
    fn new(job: &'a Job) -> Search<'a> {
        Search {
            job,
            rho_max: job.profile.radius_range().1,
            finest: (TABLE_SHARE * job.cut.delta).min(ENGINE_TABLE_TOLERANCE),
        }
    }

    /// The job's linkage at the grid angle `at`.
    fn linkage(&self, at: i64) -> Linkage {
        tilted(self.job, degrees(at))
    }

    /// Whether the ring fits at `at` (`None`) or why not: the clearance and the linkage table,
    /// and, if `whole`, the interference check.
    fn check(&self, at: i64, whole: bool) -> Outcome {
        let linkage = self.linkage(at);
        if let Err(misfit) = clear_x(&linkage.ring, self.rho_max) {
            return Some(misfit);
        }
        match Table::probe(&self.job.profile, &linkage, self.finest) {
            Err(e) => Some(Misfit::Table(e)),
            Ok(table) if whole => interferes(self.job, &linkage, &table).err(),
            Ok(_) => None,
        }
    }

    /// `fit`'s refusal at `at`, where [`Search::check`] found `why`: the same, but for a
    /// table's.
    fn reason(&self, at: i64, why: Misfit) -> Misfit {
        match why {
            Misfit::Table(_) => fit(self.job, &self.linkage(at))
                .expect_err("fit refuses where its finer table is refused"),
            other => other,
        }
    }
}

/// One edge of a window.
#[derive(Debug, Clone, PartialEq)]
pub struct Edge {
    /// The outermost angle found to fit, degrees, on the grid.
    pub deg: f64,
    /// The grid angle next to it outside the window, [`EDGE_TOLERANCE_DEG`] beyond, which
    /// does not fit, and why; `None` where the window runs to the end of the range a job may
    /// give.
    pub beyond: Option<(f64, Misfit)>,
}

/// A window: an interval of installation angles at which the ring fits the groove.
#[derive(Debug, Clone, PartialEq)]
pub struct Window {
    /// Its lower edge.
    pub low: Edge,
    /// Its upper edge.
    pub high: Edge,
}

impl Window {
    /// The distance of `deg` to the nearer edge, degrees (negative outside).
    pub fn margin(&self, deg: f64) -> f64 {
        (deg - self.low.deg).min(self.high.deg - deg)
    }

    /// The angle with the largest margin, degrees: the middle, on the grid (the lower of
    /// the two grid angles nearest it when it falls between them).
    pub fn middle(&self) -> f64 {
        degrees((steps(self.low.deg) + steps(self.high.deg)).div_euclid(2))
    }

    /// Whether `deg` lies in the window, its edges included.
    pub fn holds(&self, deg: f64) -> bool {
        self.margin(deg) >= 0.0
    }
}

/// The windows of a job that fits at some angle.
#[derive(Debug, Clone)]
pub struct Windows {
    /// The windows, lowest first; never empty.
    pub windows: Vec<Window>,
}

impl Windows {
    /// The window holding the angle with the largest margin, and that angle (degrees): the
    /// middle of the widest window, the lowest of equally wide ones.
    pub fn best(&self) -> (&Window, f64) {
        let mut best = &self.windows[0];
        for w in &self.windows[1..] {
            if w.margin(w.middle()) > best.margin(best.middle()) {
                best = w;
            }
        }
        (best, best.middle())
    }

    /// The window that holds `deg`, if one does.
    pub fn holding(&self, deg: f64) -> Option<&Window> {
        self.windows.iter().find(|w| w.holds(deg))
    }

    /// The windows for a message: "7.137°–8.321°, 20°–31.5°".
    pub fn list(&self) -> String {
        let list: Vec<String> = self
            .windows
            .iter()
            .map(|w| format!("{}°–{}°", show_deg(w.low.deg), show_deg(w.high.deg)))
            .collect();
        list.join(", ")
    }
}

/// An angle to the bisection's precision, trailing zeros dropped: "7.137", "20".
pub fn show_deg(deg: f64) -> String {
    let s = format!("{deg:.3}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" {
        "0".into()
    } else {
        s.into()
    }
}

/// The job's ring tilted by `deg` degrees.
fn tilted(job: &Job, deg: f64) -> Linkage {
    Linkage {
        p: job.p(),
        ring: job.ring_at(deg.to_radians()),
    }
}

/// The lead angle atan(|p|/ρ) at the groove's least, mean and greatest radius, degrees
/// (exact, not on the grid).
fn lead_angles(job: &Job) -> [f64; 3] {
    let (lo, hi) = job.profile.radius_range();
    [lo, (lo + hi) / 2.0, hi].map(|rho| (job.p().abs() / rho).atan().to_degrees())
}

/// The grid angles the scan checks, in increasing order: every [`SCAN_STEP_DEG`] from 0°, and
/// the lead angles at the groove's least, mean and greatest radius.
fn scan_angles(job: &Job) -> Vec<i64> {
    let mut angles: Vec<i64> = (0..RANGE_STEPS)
        .step_by(SCAN_STEPS as usize)
        .chain(
            lead_angles(job)
                .map(steps)
                .into_iter()
                .filter(|at| *at < RANGE_STEPS),
        )
        .collect();
    angles.sort_unstable();
    angles.dedup();
    angles
}

/// The outcome of a check at one angle: `None` where it fits.
type Outcome = Option<Misfit>;

/// Between `fits` (a grid angle that passes `check`) and `beyond` (one that does not, and
/// why), the edge: the grid angle that fits next to one that does not.
fn bisect(check: impl Fn(i64) -> Outcome, mut fits: i64, mut beyond: (i64, Misfit)) -> Edge {
    while (beyond.0 - fits).abs() > 1 {
        let mid = (fits + beyond.0).div_euclid(2);
        match check(mid) {
            None => fits = mid,
            Some(why) => beyond = (mid, why),
        }
    }
    Edge {
        deg: degrees(fits),
        beyond: Some((degrees(beyond.0), beyond.1)),
    }
}

/// Scan every installation angle a job may give and find the windows in which the ring fits
/// the groove (`fit`), their edges by bisection (see the module's docs); or, if it fits
/// nowhere, where it came nearest.
pub fn windows(job: &Job) -> Result<Windows, NoWindow> {
    let search = Search::new(job);
    let full = |at: i64| search.check(at, true);
    let cheap = |at: i64| search.check(at, false);
    let leads = lead_angles(job);
    let angles = scan_angles(job);
    let outcomes = in_parallel(&angles, |&at| full(at));
    let scan: Vec<(i64, Outcome)> = angles.into_iter().zip(outcomes).collect();
    // The edge between the scan angle `inside`, which fits, and its neighbour `outside`.
    let edge = |&(inside, outside): &(i64, usize)| {
        let (outside, why) = &scan[outside];
        let why = why.clone().expect("a scan angle that does not fit");
        let found = if matches!(why, Misfit::Interference(_)) {
            bisect(full, inside, (*outside, why))
        } else {
            let table_edge = bisect(cheap, inside, (*outside, why));
            match full(steps(table_edge.deg)) {
                None => table_edge,
                Some(why) => bisect(full, inside, (steps(table_edge.deg), why)),
            }
        };
        Edge {
            beyond: found
                .beyond
                .map(|(deg, why)| (deg, search.reason(steps(deg), why))),
            ..found
        }
    };
    // The windows as runs of scan angles that fit, first and last, and their edges to find:
    // each as the scan angle inside and the index of the scan angle beyond.
    let mut runs = Vec::new();
    let mut k = 0;
    while k < scan.len() {
        if scan[k].1.is_some() {
            k += 1;
            continue;
        }
        let first = k;
        while scan
            .get(k + 1)
            .is_some_and(|(_, outcome)| outcome.is_none())
        {
            k += 1;
        }
        runs.push((first, k));
        k += 1;
    }
    let bisections: Vec<(i64, usize)> = runs
        .iter()
        .flat_map(|&(first, last)| {
            let low = first.checked_sub(1).map(|before| (scan[first].0, before));
            let high = (last + 1 < scan.len()).then(|| (scan[last].0, last + 1));
            low.into_iter().chain(high)
        })
        .collect();
    let mut found = in_parallel(&bisections, edge).into_iter();
    // A run's end is a bisected edge, or the end of the range a job may give.
    let mut end = |at: i64, bisected: bool| {
        if bisected {
            found.next().expect("an edge for every bisection")
        } else {
            Edge {
                deg: degrees(at),
                beyond: None,
            }
        }
    };
    let windows: Vec<Window> = runs
        .iter()
        .map(|&(first, last)| Window {
            low: end(scan[first].0, first > 0),
            high: end(scan[last].0, last + 1 < scan.len()),
        })
        .collect();
    if !windows.is_empty() {
        return Ok(Windows { windows });
    }
    // Every scanned angle is refused: the nearest miss, the lowest of equals nearest the lead
    // angle at the mean radius.
    let key = |(at, why): &(i64, Misfit)| (why.distance(), (degrees(*at) - leads[1]).abs());
    let (at, why) = scan
        .into_iter()
        .filter_map(|(at, why)| why.map(|why| (at, why)))
        .min_by(|a, b| key(a).partial_cmp(&key(b)).expect("finite distances"))
        .expect("the scan holds angles, every one refused");
    Err(NoWindow {
        deg: degrees(at),
        why: search.reason(at, why),
    })
}

/// `f` of every item, in order, the items shared out over the machine's cores: the scan's
/// angles, and the edges to bisect, are checked independently of each other.
fn in_parallel<T: Sync, R: Send>(items: &[T], f: impl Fn(&T) -> R + Sync) -> Vec<R> {
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(items.len());
    if threads <= 1 {
        return items.iter().map(f).collect();
    }
    // Each thread takes the next item not yet taken: the costly ones (where the table builds
    // and the interference check runs) lie together in the scan.
    let next = AtomicUsize::new(0);
    let mut done: Vec<(usize, R)> = std::thread::scope(|scope| {
        let workers: Vec<_> = (0..threads)
            .map(|_| {
                scope.spawn(|| {
                    let mut mine = Vec::new();
                    loop {
                        let k = next.fetch_add(1, Ordering::Relaxed);
                        let Some(item) = items.get(k) else {
                            return mine;
                        };
                        mine.push((k, f(item)));
                    }
                })
            })
            .collect();
        workers
            .into_iter()
            .flat_map(|w| w.join().expect("a thread of the angle search panicked"))
            .collect()
    });
    done.sort_unstable_by_key(|(k, _)| *k);
    done.into_iter().map(|(_, r)| r).collect()
}

/// The sentence a refusal of an angle appends: the windows, or that there is none.
pub(crate) fn hint(job: &Job) -> String {
    match windows(job) {
        Ok(found) => format!(
            "\ninstallation angles that work with this ring: {} \
             (tool.installation_angle_deg); the largest margin is at {}°",
            found.list(),
            show_deg(found.best().1)
        ),
        Err(none) => format!("\n{none}"),
    }
}

/// A job whose ring fits the groove at no installation angle, and where it came nearest.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error(
    "no installation angle from 0° to {RANGE_DEG}° plans this groove with this ring without \
     interference; {}",
    nearest(*deg, why)
)]
pub struct NoWindow {
    /// The scanned angle that came nearest to fitting, degrees ([`Misfit`]'s ranking; among
    /// linkage refusals, which have no depth, the one nearest the lead angle at the mean
    /// radius, which is scanned rounded to the grid).
    pub deg: f64,
    /// Why it does not fit.
    pub why: Misfit,
}

/// Where a job that fits nowhere came nearest, in words.
fn nearest(deg: f64, why: &Misfit) -> String {
    let at = show_deg(deg);
    match why {
        Misfit::Table(_) => format!(
            "no angle gives every profile point a pose on one branch; at {at}°, the nearest to \
             the lead angle at the mean radius: {why}"
        ),
        _ => format!("it came nearest at {at}°, where {why}"),
    }
}

/// Where the angle a job plans with comes from.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "from", rename_all = "lowercase")]
pub enum AngleOrigin {
    /// The job gives it (`tool.installation_angle_deg`).
    Given,
    /// The job gives none: the angle with the largest margin in the windows found.
    Window {
        /// The window's edges, degrees.
        window_deg: [f64; 2],
        /// The distance to the nearer edge, degrees.
        margin_deg: f64,
    },
}

/// The ring `plan` plans with, and where its angle comes from: the job's, or, if it gives
/// none, the angle with the largest margin in the windows.
pub fn ring(job: &Job) -> Result<(Ring, AngleOrigin), NoWindow> {
    if let Some(deg) = job.tool.installation_angle_deg {
        return Ok((job.ring_at(deg.to_radians()), AngleOrigin::Given));
    }
    let found = windows(job)?;
    let (window, deg) = found.best();
    let origin = AngleOrigin::Window {
        window_deg: [window.low.deg, window.high.deg],
        margin_deg: window.margin(deg),
    };
    Ok((tilted(job, deg).ring, origin))
}

/// The ring a job plans with ([`ring`]), found at most once and then kept: the angle does not
/// depend on the feed (`fit`'s checks do not), so the fastest feed's search finds the window
/// of a job that gives no angle once for every feed it plans.
#[derive(Debug, Default)]
pub struct Resolved(std::sync::OnceLock<Result<(Ring, AngleOrigin), NoWindow>>);

impl Resolved {
    /// [`ring`] of `job`, or what it gave before; for jobs that differ in their feed alone.
    pub fn ring(&self, job: &Job) -> Result<(Ring, AngleOrigin), NoWindow> {
        self.0.get_or_init(|| ring(job)).clone()
    }
}

/// What `plan` makes of the job at one angle of a window.
#[derive(Debug, Clone)]
pub struct Row {
    /// The installation angle, degrees.
    pub deg: f64,
    /// Its distance to the nearer edge of its window, degrees.
    pub margin_deg: f64,
    /// The angle with the largest margin.
    pub chosen: bool,
    /// The plan's profile error (its report's `max_error_mm`, mm) and its linked segments,
    /// or why the job is refused at this angle (the error budget, the machine's limits, …).
    pub planned: Result<(f64, usize), String>,
}

/// The job planned by `plan` at `per_window` angles evenly spread over each window (to the
/// grid), edges included, and at the angle with the largest margin, in increasing angle: each
/// as a job that gives that angle, so each row is what `plan` makes of the job given the
/// angle as printed. `plan` is [`plan()`](super::plan) or one that also measures (`whirl
/// plan`'s, in `crate::judge`).
pub fn survey(
    job: &Job,
    found: &Windows,
    per_window: usize,
    plan: impl Fn(&Job) -> Result<Plan, PlanError>,
) -> Vec<Row> {
    let best = steps(found.best().1);
    let mut rows = Vec::new();
    for w in &found.windows {
        let (low, high) = (steps(w.low.deg), steps(w.high.deg));
        let spans = per_window.max(2) as i64 - 1;
        let mut angles: Vec<i64> = (0..=spans)
            .map(|i| low + ((high - low) * i + spans / 2).div_euclid(spans))
            .collect();
        if (low..=high).contains(&best) {
            // In place of a spread angle one grid step from it, which would say the same.
            angles.retain(|at| (at - best).abs() > 1);
            angles.push(best);
        }
        angles.sort_unstable();
        angles.dedup();
        for at in angles {
            let deg = degrees(at);
            let mut given = job.clone();
            given.tool.installation_angle_deg = Some(deg);
            rows.push(Row {
                deg,
                margin_deg: w.margin(deg),
                chosen: at == best,
                planned: plan(&given)
                    .map(|p| (p.report.max_error_mm, p.report.segments))
                    .map_err(|e| e.to_string()),
            });
        }
    }
    rows
}

#[cfg(test)]
mod tests;
