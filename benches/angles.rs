//! The installation-angle window: finding it (the scan over 0° to 90° and the bisected
//! edges), and `whirl angles` whole but for its files (the window and the plans across it).
//!
//! Run with `cargo bench --bench angles`; docs/planner.md ("The installation-angle window")
//! quotes the figures. Planning the ball-screw and double-start examples, which give no angle
//! and so find their window first, is `cargo bench --bench planner`'s `plan_example`.

use divan::{black_box, Bencher};
use std::path::Path;
use whirl::config::job::Job;
use whirl::config::machine::MachineProfile;
use whirl::plan::angles;

fn main() {
    divan::main();
}

fn example(name: &str) -> Job {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("examples")
        .join(name)
        .join("job.toml");
    Job::load(&path).expect("example job")
}

/// The window of a job: narrow (trapezoidal, ball screw) and wide (double-start, where the
/// interference check runs at 55 scan angles).
#[divan::bench(args = ["trapezoidal", "ball-screw", "double-start"], sample_count = 5)]
fn window(bencher: Bencher, name: &str) {
    let job = example(name);
    bencher.bench(|| black_box(angles::windows(&job).unwrap().best().1));
}

/// `whirl angles examples/trapezoidal/job.toml`: the window, and eleven angles across it
/// planned as `whirl plan` plans them (nodes measured by the engine).
#[divan::bench(sample_count = 5)]
fn whirl_angles_trapezoidal(bencher: Bencher) {
    let job = example("trapezoidal");
    let machine = MachineProfile::builtin_sim().unwrap();
    bencher.bench(|| {
        let found = angles::windows(&job).unwrap();
        let plan = |at: &Job| whirl::judge::refine::plan(at, &machine);
        black_box(angles::survey(&job, &found, 11, plan).len())
    });
}
