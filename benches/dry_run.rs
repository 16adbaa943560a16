//! `whirl dry-run` end to end: plan, serve the simulator on a pseudo-terminal, stream the
//! program through the serial code, with the Δ guard measuring every executed move; the
//! simulated clock runs as fast as the host allows.
//!
//! Run with `cargo bench --bench dry_run`; the README quotes the figures. Each run prints
//! the simulated machine time and what the guard measured, so the figure can be read against
//! what was done.

use std::path::Path;
use whirl::config::job::Job;
use whirl::config::machine::MachineProfile;
use whirl::judge::dry_run::{dry_run, DryRunOptions, DryRunReport};
use whirl::log::ExecLog;
use whirl::transport::{Posted, TransportKind};

fn main() {
    divan::main();
}

#[divan::bench(
    args = ["double-start", "left-external", "trapezoidal", "ball-screw"],
    sample_count = 1,
    sample_size = 1
)]
fn example(name: &str) {
    let report = run(name, "machine-profiles/sim.toml", TransportKind::Serial);
    eprintln!(
        "{name}: {} lines, {:.0} s of machine time, error {:.4} mm of Δ {} mm, link {:.1} % busy",
        report.lines,
        report.machine_time_s,
        report.max_error_mm,
        report.delta_mm,
        100.0 * report.link_utilization
    );
}

/// The same jobs on the example CANopen machine: set-points to three simulated CiA 402
/// drives through an slcan adapter on a pseudo-terminal, in lockstep with their SYNC
/// clock (4 ms cycles), the guard judging every cycle.
#[divan::bench(
    args = ["double-start", "left-external", "trapezoidal", "ball-screw"],
    sample_count = 1,
    sample_size = 1
)]
fn can_slcan(name: &str) {
    let report = run(
        name,
        "machine-profiles/canopen-drives.toml",
        TransportKind::CanSlcan,
    );
    eprintln!(
        "{name} over can-slcan: {} set-points, {:.0} s of machine time, overcut {:.4} mm, \
         undercut {:.4} mm of Δ {} mm, bus {:.1} % busy",
        report.lines,
        report.machine_time_s,
        report.max_overcut_mm,
        report.max_undercut_mm,
        report.delta_mm,
        100.0 * report.link_utilization
    );
}

/// Plans the example `name` for the machine `profile` and dry-runs it over `transport`,
/// as `whirl dry-run` does; the job must complete within Δ.
fn run(name: &str, profile: &str, transport: TransportKind) -> DryRunReport {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let job =
        Job::load(&root.join("examples").join(name).join("job.toml")).expect("the example loads");
    let machine = MachineProfile::load(&root.join(profile)).expect("the profile loads");
    let plan = whirl::plan::plan(&job, &machine).expect("the example plans");
    let posted = Posted::read(name, &plan.text, &machine).expect("the program reads");
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .expect("a runtime");
    let options = DryRunOptions {
        transport,
        ..DryRunOptions::default()
    };
    let report = runtime
        .block_on(dry_run(
            &job,
            plan.ring,
            &machine,
            &posted,
            options,
            &mut ExecLog::discard(),
        ))
        .expect("the dry run runs");
    assert!(report.within_delta, "{report:?}");
    report
}
