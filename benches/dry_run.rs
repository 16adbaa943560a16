//! `whirl dry-run` end to end: plan, serve the simulator on a pseudo-terminal, stream the
//! program through the serial code, with the Δ guard measuring every executed move; the
//! simulated clock runs as fast as the host allows.
//!
//! Run with `cargo bench --bench dry_run`; the README quotes the figures. Each run prints
//! the simulated machine time and what the guard measured, so the figure can be read against
//! what was done.

use std::path::Path;
use whirl::dry_run::{dry_run, DryRunOptions};
use whirl::exec_log::ExecLog;
use whirl::job::Job;
use whirl::machine::MachineProfile;

fn main() {
    divan::main();
}

#[divan::bench(
    args = ["double-start", "left-external", "trapezoidal", "ball-screw"],
    sample_count = 1,
    sample_size = 1
)]
fn example(name: &str) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("examples")
        .join(name)
        .join("job.toml");
    let job = Job::load(&path).expect("the example loads");
    let machine = MachineProfile::builtin_sim().expect("the built-in profile");
    let plan = whirl::plan::plan(&job, &machine).expect("the example plans");
    let lines = plan.text.lines().map(str::to_owned).collect();
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .expect("a runtime");
    let report = runtime
        .block_on(dry_run(
            &job,
            &machine,
            name,
            lines,
            DryRunOptions::default(),
            &mut ExecLog::discard(),
        ))
        .expect("the dry run runs");
    assert!(report.within_delta, "{report:?}");
    eprintln!(
        "{name}: {} lines, {:.0} s of machine time, error {:.4} mm of Δ {} mm, link {:.1} % busy",
        report.lines,
        report.machine_time_s,
        report.max_error_mm,
        report.delta_mm,
        100.0 * report.link_utilization
    );
}
