//! `whirl plan`'s node choice: plan, measure with the sweep engine, plan again.
//!
//! The error budget's rooms ([`Problem::rooms`]) rest on a first-order model of what an X error
//! does at a contact, with the table's accuracy counted whole. The engine measures what the ring
//! really cuts. So the nodes are chosen as the budget allows, the program they make is
//! measured, the rooms interpolation gets are scaled by what the measurement shows, and the
//! nodes chosen again: at most [`ROUNDS`] choices, ending on the one with the fewest spans
//! among those that measure within Δ. When none does, the plan is refused, never written.
//!
//! **What is measured.** The program repeats one period's pattern of nodes, and a stretch of
//! it anywhere along the groove is the same stretch elsewhere screwed along the helix (a pose
//! (C, X, Z) touches, turned by t, what (C − t, X, Z + p·t) touches). So a short program of the
//! same nodes, a few passes long, stands for the whole groove, and measuring it costs what a few
//! passes cost rather than the whole length (`whirl verify` takes seconds over the 100 mm
//! ball-screw groove). On it the engine measures, at the profile points where the nodes'
//! errors peak (a span's worst on each side, the worst [`PROBES`] spans each side), the error
//! where the pass touches: what the nodes cut too deep or left. To what a pass leaves at its
//! own profile point the scallop to the next pass adds, as the planner's sweep of two passes
//! measured it there. The insert cusp, controller blending and the rounding of the numbers
//! the controller moves to are not in the engine's swept torus; they are counted on top, each
//! where it is.

use crate::config::job::Job;
use crate::config::machine::MachineProfile;
use crate::judge::measure::{Motion, Target};
use crate::plan::path::{self, PathSpec};
use crate::plan::segment::{approximate, Choice, Measured, NodeChoice, NodeError, Nodes, Problem};
use crate::plan::{Plan, PlanError};
use std::f64::consts::TAU;

/// Node choices planned and measured, at most.
pub const ROUNDS: usize = 3;
/// Spans measured on each side (overcut, undercut) of every choice: those the budget puts
/// nearest Δ.
pub const PROBES: usize = 12;
/// The share of Δ the measured error is aimed at when the rooms are scaled: the probes sit
/// where the first-order model puts a span's peak, and the true peak may be a little off it.
const AIM: f64 = 0.98;
/// The most a round may scale a room by, either way.
const STEP: f64 = 2.0;

/// Plan `job` for `machine`, its nodes measured by the sweep engine: the one plan of a job,
/// whichever command makes it (`whirl plan`, `stream` and `dry-run` of a job, `angles`, the
/// console), so that what `plan` wrote is what `stream` sends. [`crate::plan::plan`] stays the
/// engine-free planner the library's own layers use.
pub fn plan(job: &Job, machine: &MachineProfile) -> Result<Plan, PlanError> {
    crate::plan::plan_with(job, machine, &Refine)
}

/// The node choice of the plan → measure → re-plan loop.
#[derive(Debug, Clone, Copy, Default)]
pub struct Refine;

impl NodeChoice for Refine {
    fn choose(&self, problem: &Problem) -> Result<Choice, NodeError> {
        let stretch = Stretch::new(problem)?;
        refine(problem, |nodes, probes| stretch.errors(nodes, probes))
    }
}

/// The loop itself, `measure` giving the engine's error where the pass touches each probed
/// table sample of the program the nodes make.
fn refine(
    problem: &Problem,
    mut measure: impl FnMut(&Nodes, &[usize]) -> Vec<f64>,
) -> Result<Choice, NodeError> {
    let shares = Shares::of(problem);
    let delta = problem.budget.delta;
    let base = problem.rooms();
    let pass = problem.pass();
    let (mut over_scale, mut under_scale) = (1.0, 1.0);
    let mut best: Option<Choice> = None;
    let mut last = None;
    for round in 1..=ROUNDS {
        let nodes = approximate(problem.table, &base.scaled(over_scale, under_scale), &pass);
        // Rooms grown from a choice within Δ that give no fewer spans gain nothing.
        if best
            .as_ref()
            .is_some_and(|b| nodes.per_period() >= b.nodes.per_period())
        {
            break;
        }
        let probes = shares.probes(&nodes);
        let errors = measure(&nodes, &probes);
        let found = shares.tally(&probes, &errors);
        let choice = Choice {
            max_error: found.over.total.max(found.under.total),
            nodes,
            measured: Some(Measured {
                overcut_mm: found.overcut,
                undercut_mm: found.undercut,
                points: probes.len(),
                rounds: round,
            }),
        };
        if choice.max_error <= delta
            && best.as_ref().is_none_or(|b| {
                (choice.nodes.per_period(), choice.max_error) < (b.nodes.per_period(), b.max_error)
            })
        {
            best = Some(choice);
        }
        // Interpolation's part of each side grows with its room.
        over_scale *= found.over.factor(delta);
        under_scale *= found.under.factor(delta);
        last = Some(found);
    }
    best.ok_or_else(|| {
        let found = last.expect("the first round is always measured");
        NodeError(format!(
            "no choice of nodes measured within Δ = {delta} mm in {ROUNDS} rounds: the last \
             measured {:.5} mm overcut and {:.5} mm undercut (scallop and cusp included), \
             {:.5} mm with blending and rounding; the error budget's model does not hold for \
             this groove",
            found.overcut,
            found.undercut,
            found.over.total.max(found.under.total),
        ))
    })
}

/// What adds to interpolation's error at every table sample, mm.
struct Shares<'a> {
    problem: &'a Problem<'a>,
    /// On either side: blending and the rounding there.
    both: Vec<f64>,
    /// What a pass leaves besides its own error: the scallop and the cusp there.
    left: Vec<f64>,
    /// The concave stretches' material, wherever it is.
    concave: f64,
}

impl<'a> Shares<'a> {
    fn of(problem: &'a Problem<'a>) -> Shares<'a> {
        let b = problem.budget;
        let both = problem
            .roundings()
            .iter()
            .map(|r| b.blend + b.fit + r)
            .collect();
        let left = problem
            .cusps()
            .iter()
            .enumerate()
            .map(|(i, c)| c + problem.scallops.near(i))
            .collect();
        Shares {
            problem,
            both,
            left,
            concave: b.concave,
        }
    }

    /// The samples to measure: in every span the one whose first-order error, with what adds
    /// to it, is largest on each side; of those, the [`PROBES`] largest each side.
    fn probes(&self, nodes: &Nodes) -> Vec<usize> {
        let errors = nodes.errors(self.problem.table);
        let samples = &self.problem.table.samples;
        let over = |i: usize| self.both[i] - errors[i];
        let under = |i: usize| self.both[i] + self.left[i] + self.concave + errors[i];
        let (mut overs, mut unders) = (Vec::new(), Vec::new());
        let mut k = 0;
        for span in nodes.nodes.windows(2) {
            let first = k;
            while k + 1 < samples.len() && samples[k + 1].contact.phase <= span[1].phase {
                k += 1;
            }
            let worst = |side: &dyn Fn(usize) -> f64| {
                (first..=k)
                    .max_by(|&a, &b| side(a).total_cmp(&side(b)))
                    .map(|i| (side(i), i))
            };
            overs.extend(worst(&over));
            unders.extend(worst(&under));
        }
        let mut probes = Vec::new();
        for mut side in [overs, unders] {
            side.sort_by(|a, b| b.0.total_cmp(&a.0));
            probes.extend(side.into_iter().take(PROBES).map(|(_, i)| i));
        }
        probes.sort_unstable();
        probes.dedup();
        probes
    }

    /// The measured `errors` at the `probes`, with what adds to them.
    fn tally(&self, probes: &[usize], errors: &[f64]) -> Found {
        let mut found = Found::default();
        for (&i, &e) in probes.iter().zip(errors) {
            found.overcut = found.overcut.max(-e);
            found.undercut = found.undercut.max(e + self.left[i]);
            found.over.take(self.both[i] - e, self.both[i]);
            let fixed = self.both[i] + self.left[i] + self.concave;
            found.under.take(e + fixed, fixed);
        }
        found
    }
}

/// The worst point of one side (overcut or undercut) of a measurement, mm.
#[derive(Debug, Clone, Copy, Default)]
struct Worst {
    /// The error there with everything that adds to it.
    total: f64,
    /// The part of it that does not grow with interpolation's room.
    fixed: f64,
}

impl Worst {
    fn take(&mut self, total: f64, fixed: f64) {
        if total > self.total {
            *self = Worst { total, fixed };
        }
    }

    /// The factor that brings this side to [`AIM`] of `delta` when interpolation's room is
    /// scaled by it, within [`STEP`] either way.
    fn factor(&self, delta: f64) -> f64 {
        let (scaled, aim) = (self.total - self.fixed, AIM * delta - self.fixed);
        if scaled <= 0.0 || aim <= 0.0 {
            return 1.0;
        }
        (aim / scaled).clamp(1.0 / STEP, STEP)
    }
}

/// What one measurement found.
#[derive(Debug, Clone, Copy, Default)]
struct Found {
    /// The engine's largest overcut, mm.
    overcut: f64,
    /// Its largest undercut with the scallop and the insert cusp there, mm.
    undercut: f64,
    /// The worst overcut with blending and rounding.
    over: Worst,
    /// The worst undercut with blending, rounding, scallop, cusp and concave stretches.
    under: Worst,
}

/// A stretch of the groove a few passes long, made by the nodes as the whole groove is, and
/// the engine's target over it.
struct Stretch<'a> {
    problem: &'a Problem<'a>,
    target: Target,
    /// The short path: the whole path's but for where Z runs.
    spec: PathSpec,
    /// Where the measured stretch of groove starts, mm.
    z: f64,
    /// Axial distance between passes over the same groove, mm.
    spacing: f64,
}

impl<'a> Stretch<'a> {
    fn new(problem: &'a Problem<'a>) -> Result<Stretch<'a>, NodeError> {
        let spec = *problem.spec;
        let (p, feed) = (spec.p, spec.feed);
        // Each turn of ψ brings the path back over the same groove f / (1 + f/2πp) further.
        let spacing = feed / (1.0 + feed / (TAU * p));
        let (z_lo, z_hi) = problem.table.z_range();
        let z = (spec.z_from + spec.z_to) / 2.0;
        let length = 2.0 * spacing;
        // Formed over [z, z + length] as the whole groove is over its length.
        let short = PathSpec {
            z_from: z + z_lo - 2.0 * feed,
            z_to: z + length + z_hi + 2.0 * feed,
            ..spec
        };
        let job = problem.job;
        let target = Target::new(
            job.profile.clone(),
            *problem.linkage,
            job.groove.starts,
            (z, z + length),
            feed,
        )
        .map_err(|e| NodeError(format!("the sweep engine cannot measure this groove: {e}")))?;
        Ok(Stretch {
            problem,
            target,
            spec: short,
            z,
            spacing,
        })
    }

    /// Where the short path's pass touches table sample `i` within the measured stretch.
    fn touch(&self, i: usize) -> f64 {
        let s = &self.problem.table.samples[i];
        let PathSpec {
            p, feed, z_from, ..
        } = self.spec;
        // Along the path Z = Z₀ + f·C/2π and ψ = C + Z/p; the pose at ψ touches its profile
        // point at z = Z(ψ) − Z_u, and every turn of ψ brings it back one spacing further on.
        let rate = 1.0 + feed / (TAU * p);
        let z_at = z_from + feed / (TAU * rate) * (s.contact.phase - z_from / p) - s.contact.pose.z;
        z_at + ((self.z - z_at) / self.spacing).ceil() * self.spacing
    }

    /// The engine's error where the short program of `nodes` touches each of the `probes`.
    fn errors(&self, nodes: &Nodes, probes: &[usize]) -> Vec<f64> {
        let program = path::build(&nodes.nodes, &self.spec, "").program;
        // The short path turns C one way over several revolutions and feeds Z one way.
        let motion = Motion::new(&program).expect("the short path turns C");
        let samples = &self.problem.table.samples;
        probes
            .iter()
            .map(|&i| {
                self.target
                    .error_at_u(&motion, samples[i].u, 0, self.touch(i))
            })
            .collect()
    }
}

#[cfg(test)]
mod tests;
