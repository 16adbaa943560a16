//! The installation-angle window: finding it (the scan over 0° to 90° and the bisected
//! edges), one interference check (the costliest of the checks the scan runs at each angle),
//! and `whirl angles` whole but for its files (the window and the plans across it).
//!
//! Run with `cargo bench --bench angles`; docs/benchmarks.md quotes the figures. Planning the
//! ball-screw and double-start examples, which give no angle and so find their window first,
//! is `cargo bench --bench planner`'s `plan_example`.

use divan::{black_box, Bencher};
use whirl::config::job::Job;
use whirl::config::machine::MachineProfile;
use whirl::geometry::linkage::Linkage;
use whirl::plan::angles;
use whirl::plan::interference;
use whirl::plan::table::Table;

mod common;
use common::example;

fn main() {
    divan::main();
}

/// The window of a job: narrow (trapezoidal, ball screw) and wide (double-start, where the
/// interference check runs at 58 scan angles: 55 on the grid and its three lead angles).
#[divan::bench(args = ["trapezoidal", "ball-screw", "double-start"], sample_count = 10)]
fn window(bencher: Bencher, name: &str) {
    let job = example(name);
    bencher.bench(|| black_box(angles::windows(&job).unwrap().best().1));
}

/// The interference check at the angle `plan` chooses, on the table the window search builds
/// there (to the engine's 0.1 µm): 64 poses, every helix of the groove's surface.
#[divan::bench(args = ["ball-screw", "double-start"], sample_count = 20)]
fn interference_check(bencher: Bencher, name: &str) {
    let job = example(name);
    let (ring, _) = angles::ring(&job).unwrap();
    let linkage = Linkage { p: job.p(), ring };
    let table = Table::build(&job.profile, &linkage, 1e-4).unwrap();
    bencher.bench(|| {
        interference::check(
            &job.profile,
            &table,
            &linkage,
            job.groove.starts,
            job.cut.delta / 10.0,
        )
        .unwrap()
    });
}

/// `whirl angles JOB`: the window, and eleven angles across it planned as `whirl plan` plans
/// them (nodes measured by the engine).
#[divan::bench(args = ["trapezoidal", "ball-screw", "double-start"], sample_count = 5)]
fn whirl_angles(bencher: Bencher, name: &str) {
    let job = example(name);
    let machine = MachineProfile::builtin_sim().unwrap();
    bencher.bench(|| {
        let found = angles::windows(&job).unwrap();
        let plan = |at: &Job| whirl::judge::refine::plan(at, &machine);
        black_box(angles::survey(&job, &found, 11, plan).len())
    });
}
