//! The fastest feed (`axial_feed = "auto"`): the largest axial feed at which the planner plans
//! the job within Δ and the program stays within what the machine sustains.
//!
//! A shop pays for machine time, and the time of a groove is its revolutions, which fall as
//! the feed per revolution rises. What rises with the feed:
//!
//! - the feed scallop, which the error budget takes from interpolation until the planner
//!   refuses the job ([`Limit::Budget`]); nodes get denser on the way, so moves get shorter;
//! - the rate at which the controller must take blocks ([`Limit::BlockRate`]): every linked
//!   move must last at least 1 / the profile's `max_block_rate`, or its family's default
//!   ([`MachineProfile::block_rate`]; on CANopen drives, one set-point a SYNC cycle), which
//!   the planner itself refuses ([`crate::plan::blocks`]), or on grbl the moves must not outrun
//!   the blocks it prepares ahead;
//! - the link's bytes ([`Limit::Link`]): on a serial line to grbl every line must arrive
//!   within the time its move runs (else the planner starves), and on Modbus RTU every
//!   segment's frames;
//! - the chip an insert takes, if the tool gives its largest ([`Limit::Chip`],
//!   [`chip_thickness`]);
//! - the axes' travel and speed ([`Limit::Axes`], the planner's own limit check), and the
//!   axial pitch, which no feed reaches ([`Limit::Pitch`]).
//!
//! None of these falls as the feed rises, though node choice makes the shortest move jump
//! about from feed to feed, so a feed may pass above one refused: the search ([`search`])
//! brackets, steps down 5 % at a time from the refused end to the first feed that passes,
//! bisects, and then plans 5 % above what it found; should that pass too, it searches on from
//! there. So the feed it returns plans, and 5 % more does not, for the reason [`FeedBound`]
//! names.
//!
//! Every feed is planned with the node choice the caller gives ([`NodeChoice`]), so the
//! program the search returns is the one that choice plans for the job at that feed: with
//! `whirl plan`'s (the judge's measured choice, `judge::refine`), the program every command
//! writes or sends. A choice that finds no nodes within Δ at a feed refuses it
//! ([`Limit::Delta`]): the measured choice does so where the engine measures every choice it
//! tries beyond Δ.

use crate::config::connection::Connection;
use crate::config::job::show_figure;
use crate::config::job::Job;
use crate::config::machine::{Axis, Dialect, MachineProfile};
use crate::geometry::linkage::Whirling;
use crate::plan::angles::Resolved;
use crate::plan::budget::MIN_INTERPOLATION_SHARE;
use crate::plan::scallop::pass_spacing;
use crate::plan::segment::NodeChoice;
use crate::plan::{Plan, PlanError};
use crate::post::gcode::parse::read_program_with_lines;
use crate::program::limits::LimitError;
use crate::program::{Move, Position, Program};
use serde::Serialize;

/// How close the bisection brings the feed that plans to the one that does not.
const RESOLUTION: f64 = 1.005;
/// How much faster the feed found must not go: the search ends only where the feed this many
/// times higher is refused.
pub const MARGIN: f64 = 1.05;
/// How far below its starting feed the search looks for one that plans.
const LOWEST: f64 = 1.0 / 16.0;
/// The step up from a feed that passes while bracketing.
const UP: f64 = 1.5;
/// Profile radii sampled for the stock a pass meets ([`chip_thickness`]).
const STOCK_SAMPLES: usize = 64;

/// Bytes a linked move costs on Modbus RTU: the slot's FC16 (41 bytes) and its answer (8),
/// the `HEAD` write (8) and its answer (8), each of the four frames after a silence of 3.5
/// characters (docs/modbus.md, "Writing a segment").
const RTU_CHARACTERS_PER_SEGMENT: f64 = 41.0 + 8.0 + 8.0 + 8.0 + 4.0 * 3.5;
/// Bits a character takes on a serial line: 8N1, a start and a stop bit.
const BITS_PER_CHARACTER: f64 = 10.0;
/// The baud rate a grbl controller is streamed at when the profile names no connection, as
/// `whirl stream` and `whirl dry-run` default to.
const DEFAULT_BAUD: u32 = 115_200;
/// Lines a grbl controller holds parsed ahead of the block running: a planner of 35 blocks,
/// whirl-sim's (grblHAL's is 100 by default, `$398`), less the one running. The receive
/// buffer's lines are not counted.
const GRBL_PLANNER_AHEAD: usize = 34;
/// Segments a Modbus PLC holds ahead of the one running: whirl-sim's ring of 32 slots keeps
/// at most 31 published.
const MODBUS_RING_AHEAD: usize = 31;

/// What stops a faster feed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Limit {
    /// The sweep engine measures the program beyond Δ: the node choice finds no nodes within
    /// it, or the engine measures the whole program beyond it (`judge::fastest`).
    Delta,
    /// The feed scallop leaves interpolation less than its least share of Δ.
    Budget,
    /// A linked move shorter than the controller's block rate allows.
    BlockRate,
    /// A line (or Modbus RTU segment) that takes longer on the link than its move runs.
    Link,
    /// A chip thicker than the insert takes.
    Chip,
    /// The axes' travel or speed.
    Axes,
    /// The axial pitch: a feed of a whole pitch passes over the next groove.
    Pitch,
}

impl Limit {
    /// The limit's name in a sentence.
    pub fn name(self) -> &'static str {
        match self {
            Limit::Delta => "Δ as the engine measures it",
            Limit::Budget => "the error budget",
            Limit::BlockRate => "the controller's block rate",
            Limit::Link => "the link's byte rate",
            Limit::Chip => "the insert's chip thickness",
            Limit::Axes => "the axes' limits",
            Limit::Pitch => "the axial pitch",
        }
    }
}

/// Which limit stops the feed going [`MARGIN`] higher, and what it refuses there.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FeedBound {
    /// The limit.
    pub limit: Limit,
    /// The feed it refuses, mm per workpiece revolution ([`MARGIN`] times the feed planned).
    pub refused_feed_mm: f64,
    /// What it refuses there.
    pub why: String,
}

/// A feed tried: it passes (carrying what the search returns for it), or a limit refuses it
/// that a lower feed may meet, or one that only a higher feed lifts.
#[derive(Debug)]
pub enum Outcome<T> {
    /// Planned, and within every limit tried.
    Passes(T),
    /// Too fast: refused by this limit (its `refused_feed_mm` the feed tried).
    TooFast(FeedBound),
    /// Too slow: the planner's refusal, which only a higher feed can lift (C turns too far
    /// for a 32-bit controller, or past the axis's travel).
    TooSlow(PlanError),
}

/// Why no feed plans.
#[derive(Debug, thiserror::Error)]
pub enum FeedError {
    /// Every feed from the lowest tried up is refused by a limit that higher feeds only break
    /// more.
    #[error(
        "no feed plans this job: down to {lowest} mm per revolution, {limit} refuses it ({why})",
        lowest = show_figure(bound.refused_feed_mm),
        limit = bound.limit.name(),
        why = bound.why
    )]
    TooFast {
        /// What refuses the lowest feed tried.
        bound: FeedBound,
    },
    /// A feed high enough for the controller's numbers is already refused as too fast.
    #[error(
        "no feed plans this job: at {slow} mm per revolution the planner refuses it ({low}), \
         and at {fast} mm {limit} does ({why})",
        slow = show_figure(*slow_feed),
        fast = show_figure(bound.refused_feed_mm),
        limit = bound.limit.name(),
        why = bound.why
    )]
    Between {
        /// The highest feed refused as too slow.
        slow_feed: f64,
        /// Its refusal.
        low: Box<PlanError>,
        /// What refuses the lowest feed refused as too fast.
        bound: FeedBound,
    },
    /// The posted program does not read back (the post's own text always does).
    #[error("the posted program does not read back: {0}")]
    Readback(#[from] crate::post::gcode::parse::ParseError),
}

/// The fastest feed found.
#[derive(Debug)]
pub struct Fastest {
    /// The job with that feed.
    pub job: Job,
    /// Its plan; its report carries the feed and what stops a feed [`MARGIN`] higher
    /// (`feed_bound`).
    pub plan: Plan,
}

/// What [`search`] finds: the feed, what passed there, the bound at [`MARGIN`] times it, and
/// the lowest feed refused that it tried.
#[derive(Debug)]
pub struct Found<T> {
    /// The fastest feed that passes, mm per revolution.
    pub feed: f64,
    /// What passed there.
    pub passed: T,
    /// What refuses [`MARGIN`] times the feed.
    pub bound: FeedBound,
    /// The lowest feed tried above `feed` that is refused.
    pub nearest_refused: FeedBound,
}

/// `job` with its feed set to `feed` mm per revolution, to plan as it is.
pub fn at(job: &Job, feed: f64) -> Job {
    let mut job = job.clone();
    job.cut.axial_feed = feed;
    job.cut.auto_feed = false;
    job
}

/// Plan `job` at `feed`, `choice` choosing the nodes, and hold the program to the machine's
/// limits; the ring from `angle`, which the search shares over its feeds.
pub fn evaluate(
    job: &Job,
    machine: &MachineProfile,
    feed: f64,
    choice: &dyn NodeChoice,
    angle: &Resolved,
) -> Result<Outcome<Box<Plan>>, PlanError> {
    let pitch = job.groove.lead / f64::from(job.groove.starts);
    if feed >= pitch {
        return Ok(Outcome::TooFast(FeedBound {
            limit: Limit::Pitch,
            refused_feed_mm: feed,
            why: format!(
                "a feed of the axial pitch, lead / starts = {} mm, passes over the next groove",
                show_figure(pitch)
            ),
        }));
    }
    let bound = |limit, why| {
        Ok(Outcome::TooFast(FeedBound {
            limit,
            refused_feed_mm: feed,
            why,
        }))
    };
    match crate::plan::plan_resolved(&at(job, feed), machine, choice, angle) {
        Ok(plan) => match sustained(job, machine, &plan, feed)? {
            None => Ok(Outcome::Passes(Box::new(plan))),
            Some((limit, why)) => bound(limit, why),
        },
        Err(PlanError::Budget(e)) => bound(
            Limit::Budget,
            format!(
                "the feed scallop, {:.5} mm, leaves interpolation {:.5} mm, less than {:.0} % \
                 of Δ = {} mm",
                e.scallop,
                e.delta - e.scallop - e.cusp - e.blend - e.rounding - e.concave - e.fit,
                MIN_INTERPOLATION_SHARE * 100.0,
                e.delta
            ),
        ),
        // No choice of nodes within Δ: the measured error grows with the feed's scallop.
        Err(PlanError::Nodes(e)) => bound(Limit::Delta, e.0),
        // A move shorter than a block on a controller whose rate bounds every move.
        Err(PlanError::BlockTime(e)) => bound(Limit::BlockRate, e.to_string()),
        // Fewer turns take C less far: only a travel limit of C is lifted by a higher feed.
        Err(PlanError::Limits { limit })
            if !matches!(limit, LimitError::Travel { axis: Axis::C, .. }) =>
        {
            bound(Limit::Axes, limit.to_string())
        }
        Err(
            e @ (PlanError::CPrecision { .. }
            | PlanError::Limits { .. }
            | PlanError::Delta {
                higher_feed_lifts: true,
                ..
            }),
        ) => Ok(Outcome::TooSlow(e)),
        Err(e) => Err(e),
    }
}

/// The fastest feed for `job` on `machine`, every feed planned with `choice`, starting at the
/// job's feed (an auto job's start, or the feed a job gives when asked for its fastest); see
/// [`search`].
pub fn fastest(
    job: &Job,
    machine: &MachineProfile,
    choice: &dyn NodeChoice,
) -> Result<Fastest, PlanError> {
    let angle = Resolved::default();
    let found = search(job.cut.axial_feed, None, |feed| {
        evaluate(job, machine, feed, choice, &angle)
    })?;
    let mut plan = *found.passed;
    plan.report.feed_bound = Some(found.bound);
    Ok(Fastest {
        job: at(job, found.feed),
        plan,
    })
}

/// The largest feed that `try_feed` passes, from `start`: bracket (down by halves to a
/// sixteenth of the start while refused as too fast, up by half while it passes; up by
/// doubling while refused as too slow), step down from the refused end by [`MARGIN`] to the
/// first feed that passes, bisect in the ratio of the feeds to half a percent, then try
/// [`MARGIN`] times the feed found and, should that pass, search on above it. `refused`, if
/// known, is a feed above `start` already refused as too fast.
pub fn search<T, E: From<PlanError>>(
    start: f64,
    refused: Option<FeedBound>,
    mut try_feed: impl FnMut(f64) -> Result<Outcome<T>, E>,
) -> Result<Found<T>, E> {
    let mut high = refused;
    let mut slow: Option<(f64, PlanError)> = None;
    let mut feed = start;
    let (mut low_feed, mut passed) = loop {
        match try_feed(feed)? {
            Outcome::Passes(passed) => break (feed, passed),
            Outcome::TooFast(bound) => {
                if let Some((slow_feed, low)) = slow {
                    let low = Box::new(low);
                    return Err(PlanError::from(FeedError::Between {
                        slow_feed,
                        low,
                        bound,
                    })
                    .into());
                }
                if feed <= start * LOWEST {
                    return Err(PlanError::from(FeedError::TooFast { bound }).into());
                }
                high = Some(bound);
                feed /= 2.0;
            }
            Outcome::TooSlow(e) => {
                if let Some(bound) = high {
                    let low = Box::new(e);
                    return Err(PlanError::from(FeedError::Between {
                        slow_feed: feed,
                        low,
                        bound,
                    })
                    .into());
                }
                slow = Some((feed, e));
                feed *= 2.0;
            }
        }
    };
    loop {
        // Up until refused.
        let mut nearest = match high.take() {
            Some(bound) if bound.refused_feed_mm > low_feed => bound,
            _ => loop {
                let up = low_feed * UP;
                match try_feed(up)? {
                    Outcome::Passes(p) => (low_feed, passed) = (up, p),
                    Outcome::TooFast(bound) => break bound,
                    // Above a feed that plans, nothing is too slow that it was not.
                    Outcome::TooSlow(e) => return Err(e.into()),
                }
            },
        };
        // Down from the refused feed by the margin's steps to the first that passes: a limit
        // that jumps about from feed to feed (the shortest move) may pass there though a lower
        // feed was refused. Then bisect in the ratio of the feeds.
        let mut feed = nearest.refused_feed_mm / MARGIN;
        while feed > low_feed {
            match try_feed(feed)? {
                Outcome::Passes(p) => {
                    (low_feed, passed) = (feed, p);
                    break;
                }
                Outcome::TooFast(bound) => {
                    nearest = bound;
                    feed /= MARGIN;
                }
                Outcome::TooSlow(e) => return Err(e.into()),
            }
        }
        while nearest.refused_feed_mm / low_feed > RESOLUTION {
            let middle = (low_feed * nearest.refused_feed_mm).sqrt();
            match try_feed(middle)? {
                Outcome::Passes(p) => (low_feed, passed) = (middle, p),
                Outcome::TooFast(bound) => nearest = bound,
                Outcome::TooSlow(e) => return Err(e.into()),
            }
        }
        // The margin: a feed 5 % higher must be refused; if it passes, search on above it.
        let faster = low_feed * MARGIN;
        match try_feed(faster)? {
            Outcome::TooFast(bound) => {
                return Ok(Found {
                    feed: low_feed,
                    passed,
                    bound,
                    nearest_refused: nearest,
                })
            }
            Outcome::Passes(p) => (low_feed, passed) = (faster, p),
            Outcome::TooSlow(e) => return Err(e.into()),
        }
    }
}

/// Whether the machine sustains `plan`'s program, cut at `feed`: its block rate, its link,
/// the insert's chip. `None` if it does, else the limit broken and what breaks it.
pub fn sustained(
    job: &Job,
    machine: &MachineProfile,
    plan: &Plan,
    feed: f64,
) -> Result<Option<(Limit, String)>, FeedError> {
    // The program as the controller reads it: its durations are the posted ones (inverse-time
    // feeds rounded down), and each move has its line.
    let (posted, lines) = read_program_with_lines(&plan.text, machine.x_diameter())?;
    let text: Vec<&str> = plan.text.lines().collect();
    let moves: Vec<(usize, f64)> = posted
        .moves
        .iter()
        .zip(&lines)
        .filter_map(|(m, &line)| match *m {
            Move::Linked { minutes, .. } => Some((line, minutes * 60.0)),
            _ => None,
        })
        .collect();
    let runs: Vec<f64> = moves.iter().map(|&(_, seconds)| seconds).collect();
    // A rate that bounds every move `plan` holds every move to (crate::plan::blocks); one the
    // controller sustains over blocks it prepares ahead is the program's as a whole.
    let rate = machine.block_rate();
    let per_block = 1.0 / rate.per_second;
    if let Some(i) = rate
        .ahead
        .and_then(|ahead| first_wait(&runs, |_| per_block, ahead))
    {
        let (line, seconds) = moves[i];
        return Ok(Some((
            Limit::BlockRate,
            format!(
                "the move on line {line} ({:.2} ms) comes faster than {} blocks a second ({}): \
                 the moves before it run out the {} blocks the controller prepares ahead",
                seconds * 1e3,
                rate.per_second,
                rate.source,
                rate.ahead.unwrap_or_default()
            ),
        )));
    }
    if let Some(link) = link_of(machine) {
        let length = |i: usize| text.get(moves[i].0 - 1).map_or(0, |t| t.len());
        let sending = |i: usize| link.characters(length(i)) * BITS_PER_CHARACTER / link.baud;
        if let Some(i) = first_wait(&runs, sending, link.ahead) {
            return Ok(Some((
                Limit::Link,
                format!(
                    "the move on line {} ({:.2} ms) waits for its {}: at {} baud the lines \
                     before it run out the {} moves the controller holds ahead",
                    moves[i].0,
                    runs[i] * 1e3,
                    link.what(),
                    link.baud,
                    link.ahead
                ),
            )));
        }
    }
    if let Some(most) = job.tool.max_chip_thickness {
        let chip = chip_thickness(job, &posted, feed);
        if chip > most {
            return Ok(Some((
                Limit::Chip,
                format!(
                    "the insert's largest chip is {chip:.4} mm, above tool.max_chip_thickness = \
                     {most} mm"
                ),
            )));
        }
    }
    Ok(None)
}

/// The first move the machine waits for (its index in `runs`), if any: move i runs `runs[i]`
/// seconds and takes `making(i)` seconds to be made ready (a block prepared, a line received),
/// one at a time; at most `ahead` ready moves wait behind the one running, and a move is made
/// ready only once there is room. The first `ahead` moves are ready when the linked motion
/// starts: the plunge before it gives the controller time to fill its buffers.
pub fn first_wait(runs: &[f64], making: impl Fn(usize) -> f64, ahead: usize) -> Option<usize> {
    let mut starts = vec![0.0; runs.len()];
    let (mut ready, mut end) = (0.0f64, 0.0f64);
    for (i, &run) in runs.iter().enumerate() {
        if i >= ahead {
            // Room once move i − ahead has left the buffer to run.
            ready = ready.max(starts[i - ahead]) + making(i);
        }
        // A little slack for the sums' rounding.
        if i > 0 && ready > end * (1.0 + 1e-12) {
            return Some(i);
        }
        starts[i] = end;
        end += run;
    }
    None
}

/// A link that carries the program byte by byte at a baud rate.
#[derive(Debug, Clone, Copy, PartialEq)]
struct ByteLink {
    /// Baud rate.
    baud: f64,
    kind: LinkKind,
    /// Moves the controller holds received ahead of the one running.
    ahead: usize,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum LinkKind {
    /// G-code lines to grbl, each with its line end.
    Serial,
    /// Segments through the Modbus ring over RTU.
    ModbusRtu,
}

impl ByteLink {
    /// The characters a linked move costs, its line `length` long.
    fn characters(&self, length: usize) -> f64 {
        match self.kind {
            LinkKind::Serial => length as f64 + 1.0,
            LinkKind::ModbusRtu => RTU_CHARACTERS_PER_SEGMENT,
        }
    }

    fn what(&self) -> &'static str {
        match self.kind {
            LinkKind::Serial => "line",
            LinkKind::ModbusRtu => "segment's frames",
        }
    }
}

/// The byte-rate link a program reaches `machine` over: a serial line to grbl (the profile's
/// baud, or 115 200 when it names no connection), or Modbus RTU; `None` for links whose bytes
/// do not grow with the program's rate (Modbus TCP, CAN, whose traffic is a fixed load a
/// cycle, LinuxCNC, which reads its program from a file).
fn link_of(machine: &MachineProfile) -> Option<ByteLink> {
    let serial = |baud: u32| ByteLink {
        baud: f64::from(baud),
        kind: LinkKind::Serial,
        ahead: GRBL_PLANNER_AHEAD,
    };
    match &machine.connection {
        Some(Connection::Serial(settings)) => Some(serial(settings.baud)),
        Some(Connection::ModbusRtu(rtu)) => Some(ByteLink {
            baud: f64::from(rtu.baud),
            kind: LinkKind::ModbusRtu,
            ahead: MODBUS_RING_AHEAD,
        }),
        None if machine.dialect == Dialect::GrblHal => Some(serial(DEFAULT_BAUD)),
        _ => None,
    }
}

/// The largest undeformed chip an insert takes over `program` (its linked moves) cut at
/// `feed` mm per revolution, mm: docs/planner.md ("Chip thickness") derives it.
///
/// In the axial section (turning with the groove's screw), every point of the ring moves
/// between two insert hits by the same step, (ΔX, p·Δψ) over the time of a hit,
/// 60 / (inserts · ring rpm) s: the feed per insert f_z, largest over the moves. Each pass
/// meets new stock where the ring's imprint rises out of the groove along the helix: a pass
/// spacing τ apart in screw angle, the imprints at radius ρ differ by
/// a(ρ) = ρ·τ·√(2·(ρ_max − ρ)·κ(ρ)) at the work's surface, κ = 1/ρ ∓ 1/R the relative
/// curvature of groove and ring along the helix (− internal, + external); a bore head meets
/// the stock of a nut, `a(ρ) = ρ·τ·√(2·(ρ − ρ_min)·(1/R − 1/ρ))`. A round nose of
/// radius r taking a step f_z into stock a thick cuts a chip of f_z·sin κ_r, with
/// cos κ_r = 1 − a/r (a ≥ r: f_z), as a round turning insert does. The largest step and the
/// deepest stock are taken together, wherever each is: an upper bound.
pub fn chip_thickness(job: &Job, program: &Program, feed: f64) -> f64 {
    let p = job.p();
    let hit_s = 60.0 / (f64::from(job.tool.inserts) * job.cut.ring_rpm);
    let mut step = 0.0f64;
    for s in program.steps(Position::UNKNOWN) {
        if let (Move::Linked { minutes, .. }, Some(from), Some(to)) =
            (s.action, known(&s.from), known(&s.to))
        {
            let dx = to[0] - from[0];
            let axial = p * (to[2] - from[2]).to_radians() + (to[1] - from[1]);
            step = step.max(dx.hypot(axial) / (minutes * 60.0) * hit_s);
        }
    }
    let r = job.tool.nose_radius;
    step * sin_entry(stock(job, feed) / r)
}

/// The deepest stock a pass meets at the work's surface, mm (see [`chip_thickness`]).
pub fn stock(job: &Job, feed: f64) -> f64 {
    let tau = pass_spacing(job.p(), feed).abs();
    let big_r = job.tool.ring_radius;
    let (rho_min, rho_max) = job.profile.radius_range();
    (0..STOCK_SAMPLES)
        .map(|k| {
            let rho = rho_min + (rho_max - rho_min) * k as f64 / STOCK_SAMPLES as f64;
            // The depth of stock above the surface at ρ, and the curvature of the tool
            // relative to the work there: a bore head cuts outward from the bore, its convex
            // tip circle inside the nut's concave surface.
            let (depth, curvature) = match job.tool.whirling {
                Whirling::Internal => (rho_max - rho, 1.0 / rho - 1.0 / big_r),
                Whirling::External => (rho_max - rho, 1.0 / rho + 1.0 / big_r),
                Whirling::Bore => (rho - rho_min, 1.0 / big_r - 1.0 / rho),
            };
            rho * tau * (2.0 * depth * curvature.max(0.0)).sqrt()
        })
        .fold(0.0, f64::max)
}

/// sin κ_r of a round nose entering stock `depth` nose radii deep: cos κ_r = 1 − depth.
fn sin_entry(depth: f64) -> f64 {
    let cos = 1.0 - depth.min(1.0);
    (1.0 - cos * cos).sqrt()
}

/// The axial feed a program cuts at, mm per workpiece revolution: Z's advance over C's turn
/// across its linked moves (Z = Z₀ + f·C/360°, kinematics.md); `None` if no linked move turns
/// C forward.
pub fn program_feed(program: &Program) -> Option<f64> {
    let mut span: Option<([f64; 3], [f64; 3])> = None;
    for s in program.steps(Position::UNKNOWN) {
        if let (Move::Linked { .. }, Some(from), Some(to)) =
            (s.action, known(&s.from), known(&s.to))
        {
            span = Some((span.map_or(from, |(first, _)| first), to));
        }
    }
    let (first, last) = span?;
    let turn = last[2] - first[2];
    (turn > 0.0).then(|| 360.0 * (last[1] - first[1]) / turn)
}

fn known(p: &Position) -> Option<[f64; 3]> {
    Some([p.x?, p.z?, p.c?])
}

impl crate::plan::Report {
    /// One line on the fastest feed for the console, `None` when the job gave its feed.
    pub fn fastest_summary(&self) -> Option<String> {
        self.feed_bound.as_ref().map(|b| {
            format!(
                "fastest feed {} mm per revolution, machine time {:.1} s; bound by {}: at {} mm \
                 {}",
                show_figure(self.axial_feed_mm),
                self.cycle_time_s,
                b.limit.name(),
                show_figure(b.refused_feed_mm),
                b.why
            )
        })
    }
}

#[cfg(test)]
mod tests;
