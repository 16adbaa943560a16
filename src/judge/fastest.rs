//! The fastest feed, measured: `axial_feed = "auto"` and `whirl plan --fastest`.
//!
//! Every feed the search tries ([`crate::plan::feed`]) is planned as `whirl plan` plans it,
//! with the nodes the engine measures ([`Refine`], `judge::refine`), and held to the machine's
//! limits; a feed at which no choice of nodes measures within Δ is refused by Δ. So the program
//! found is the one [`crate::judge::refine::plan`] writes for the job at that feed, the program
//! `whirl stream` and `whirl dry-run` send for the auto job. The node choice measures a short
//! stretch of the program; the sweep engine ([`verify`]) then measures the whole program found,
//! as `whirl verify` does. Within Δ, that is the feed. Beyond (the stretch did not stand for
//! the whole), the same search runs again from there down, each feed planned, held to the
//! machine's limits and the whole program measured, and [`Limit::Delta`] is what stops it.
//! Either way a feed 5 % higher is refused, by the engine or by the limit named.

use crate::config::job::{show_figure, Job};
use crate::config::machine::MachineProfile;
use crate::judge::refine::Refine;
use crate::judge::verify::{verify, CheckError, Verification};
use crate::plan::angles::Resolved;
use crate::plan::feed::{self, FeedBound, Limit, Outcome};
use crate::plan::{Plan, PlanError};

/// The fastest feed, planned and measured.
#[derive(Debug)]
pub struct Fastest {
    /// The job at that feed, as measured (its `axial_feed` the feed, no longer auto).
    pub job: Job,
    /// The program planned there; its report carries the feed and what bounds it.
    pub plan: Plan,
    /// What the engine measured of it: within Δ.
    pub verification: Verification,
}

/// Why the fastest feed cannot be found.
#[derive(Debug, thiserror::Error)]
pub enum FastestError {
    /// The planner refuses every feed, or the job itself.
    #[error(transparent)]
    Plan(#[from] PlanError),
    /// A program planned could not be measured.
    #[error("cannot measure the program planned at {} mm per revolution: {error}", show_figure(*feed))]
    Measure {
        /// Its feed, mm per revolution.
        feed: f64,
        /// Why.
        error: CheckError,
    },
}

/// The fastest feed for `job` on `machine` whose program the engine measures within Δ; see
/// the module docs.
pub fn fastest(job: &Job, machine: &MachineProfile) -> Result<Fastest, FastestError> {
    fastest_within(job, machine, job.cut.delta)
}

/// [`fastest`], the engine holding the program to `tolerance` (mm, at most Δ) rather than to Δ
/// itself: for a shop that plans to Δ but wants the measured part within less.
pub fn fastest_within(
    job: &Job,
    machine: &MachineProfile,
    tolerance: f64,
) -> Result<Fastest, FastestError> {
    let within = |v: &Verification| v.max_overcut_mm <= tolerance && v.max_undercut_mm <= tolerance;
    let planned = feed::fastest(job, machine, &Refine)?;
    let measured = measure(&planned.job, machine, &planned.plan)?;
    if within(&measured) {
        return Ok(Fastest {
            job: planned.job,
            plan: planned.plan,
            verification: measured,
        });
    }
    let start = planned.job.cut.axial_feed;
    let refused = beyond(start, &measured, tolerance);
    let angle = Resolved::default();
    let found = feed::search(start, Some(refused), |f| {
        let at = feed::at(job, f);
        Ok::<_, FastestError>(match feed::evaluate(job, machine, f, &Refine, &angle)? {
            Outcome::Passes(plan) => {
                let measured = measure(&at, machine, &plan)?;
                if within(&measured) {
                    Outcome::Passes((plan, measured))
                } else {
                    Outcome::TooFast(beyond(f, &measured, tolerance))
                }
            }
            Outcome::TooFast(bound) => Outcome::TooFast(bound),
            Outcome::TooSlow(e) => Outcome::TooSlow(e),
        })
    })?;
    let (plan, verification) = found.passed;
    let mut plan = *plan;
    plan.report.feed_bound = Some(found.bound);
    Ok(Fastest {
        job: feed::at(job, found.feed),
        plan,
        verification,
    })
}

/// The engine's measure of `plan`'s program against `job` (at the plan's feed).
fn measure(job: &Job, machine: &MachineProfile, plan: &Plan) -> Result<Verification, FastestError> {
    verify(job, plan.ring, machine, &plan.text, false).map_err(|error| FastestError::Measure {
        feed: job.cut.axial_feed,
        error,
    })
}

/// The bound a program measured beyond `tolerance` at `feed` sets.
fn beyond(feed: f64, measured: &Verification, tolerance: f64) -> FeedBound {
    let what = if tolerance == measured.delta_mm {
        format!("Δ = {tolerance} mm")
    } else {
        format!("{tolerance} mm (Δ = {} mm)", measured.delta_mm)
    };
    FeedBound {
        limit: Limit::Delta,
        refused_feed_mm: feed,
        why: format!(
            "the engine measures {:.5} mm overcut and {:.5} mm undercut, beyond {what}",
            measured.max_overcut_mm, measured.max_undercut_mm
        ),
    }
}
