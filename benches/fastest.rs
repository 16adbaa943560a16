//! The fastest feed (`axial_feed = "auto"`) of every example on the simulated grblHAL machine:
//! the search alone, every feed planned with its nodes measured by the engine, and with the
//! engine's measure of the whole program found besides (what `whirl plan --fastest`, and
//! `whirl stream` or `whirl dry-run` of an auto job, do).
//!
//! Run with `cargo bench --bench fastest`; docs/benchmarks.md quotes the figures, and
//! docs/planner.md the feeds and machine times found.

use divan::{black_box, Bencher};
use whirl::config::job::Job;
use whirl::config::machine::MachineProfile;

mod common;
use common::example;

fn main() {
    divan::main();
}

/// An example's job, its feed set to auto.
fn auto(name: &str) -> Job {
    let mut job = example(name);
    job.cut.auto_feed = true;
    job
}

/// The search: every feed tried planned with the measured node choice and held to the
/// machine's limits.
#[divan::bench(args = ["double-start", "left-external", "trapezoidal", "ball-screw"], sample_count = 3)]
fn planned(bencher: Bencher, name: &str) {
    let job = auto(name);
    let machine = MachineProfile::builtin_sim().unwrap();
    bencher.bench(|| {
        let plan = whirl::judge::refine::plan(&job, &machine).unwrap();
        black_box(plan.report.cycle_time_s)
    });
}

/// The search, then the engine's measure of the program found.
#[divan::bench(args = ["double-start", "left-external", "trapezoidal", "ball-screw"], sample_count = 2)]
fn measured(bencher: Bencher, name: &str) {
    let job = auto(name);
    let machine = MachineProfile::builtin_sim().unwrap();
    bencher.bench(|| {
        let found = whirl::judge::fastest::fastest(&job, &machine).unwrap();
        black_box(found.verification.max_undercut_mm)
    });
}
