//! The caller's hand on a run, on every transport: a job dry-run on the simulator through
//! the library's one entry ([`whirl::judge::dry_run::dry_run`]) while an operator thread
//! watches the run's log as it is written (a memory log) and presses hold, resume and
//! abort through a [`Control`].
//!
//! A hold must bring the simulated machine to a stand (nothing executed while held) and a
//! resume must finish the groove within Δ, as the simulator's Δ guard measures it: a hold
//! and resume leaves no mark. An abort must end the run, not completed, with the machine
//! stopped.

use std::time::{Duration, Instant};

use whirl::config::job::Job;
use whirl::config::machine::MachineProfile;
use whirl::geometry::linkage::Ring;
use whirl::judge::dry_run::{dry_run, DryRunOptions, DryRunReport};
use whirl::log::{Event, ExecLog, Record};
use whirl::program::Position;
use whirl::transport::{control, Control, Posted, TransportKind};

use crate::util;

/// The double-start example planned for `profile`: the job, the machine, the ring it was
/// planned with and the program as the machine gets it.
fn posted(profile: &str) -> (Job, MachineProfile, Ring, Posted) {
    let job = Job::load(&util::example("double-start")).unwrap();
    let machine = MachineProfile::load(&util::root().join(profile)).unwrap();
    let plan = whirl::plan::plan(&job, &machine).unwrap();
    let posted = Posted::read("double-start", &plan.text, &machine).unwrap();
    (job, machine, plan.ring, posted)
}

/// The double-start example planned for `profile`, dry-run over `transport` while
/// `operator` watches the log and presses `control`'s buttons.
fn run_with(
    transport: TransportKind,
    profile: &str,
    operator: impl FnOnce(Control, ExecLog) + Send + 'static,
) -> (DryRunReport, Vec<Record>) {
    let (job, machine, ring, posted) = posted(profile);
    let log = ExecLog::memory();
    let (control, commands) = control();
    let watched = log.clone();
    let operator = std::thread::spawn(move || operator(control, watched));
    let options = DryRunOptions {
        transport,
        commands: Some(commands),
        ..DryRunOptions::default()
    };
    let report = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap()
        .block_on(dry_run(
            &job,
            ring,
            &machine,
            &posted,
            options,
            &mut log.clone(),
        ))
        .expect("the dry run is carried out");
    operator.join().expect("the operator's checks hold");
    (report, log.records())
}

/// Waits until the log shows `what` (within a minute of wall time).
fn wait_for(log: &ExecLog, what: &str, seen: impl Fn(&[Record]) -> bool) {
    let since = Instant::now();
    let mut follow = util::Follow::new(log);
    while !seen(follow.look()) {
        assert!(
            since.elapsed() < Duration::from_secs(60),
            "waited a minute for {what}"
        );
        std::thread::sleep(Duration::from_millis(1));
    }
}

/// Moves the simulator executed so far.
fn executed(records: &[Record]) -> usize {
    records
        .iter()
        .filter(|r| matches!(r.event, Event::Executed { .. }))
        .count()
}

fn has_status(records: &[Record], state: &str) -> bool {
    records
        .iter()
        .any(|r| matches!(&r.event, Event::Status { state: s, .. } if s.starts_with(state)))
}

fn has_message(records: &[Record], text: &str) -> bool {
    records
        .iter()
        .any(|r| matches!(&r.event, Event::Message { text: t } if t.contains(text)))
}

/// How each transport says the machine stands held.
fn held(transport: TransportKind) -> fn(&[Record]) -> bool {
    match transport {
        // grbl: `Hold:0`, the hold complete and the machine at rest.
        TransportKind::Serial => |r| has_status(r, "Hold:0"),
        // The register map's state.
        TransportKind::ModbusTcp | TransportKind::ModbusRtu => |r| has_status(r, "Held"),
        // The master's own word once the path stands.
        TransportKind::CanSlcan | TransportKind::Can => {
            |r| has_message(r, "the drives stand on the path")
        }
        // LinuxCNC's program state (its own test: linuxcnc.rs).
        TransportKind::Linuxcnc => |r| has_status(r, "PAUSED"),
    }
}

/// The operator of a hold and resume: hold a while into the cut, check that nothing moves
/// while held, resume.
fn hold_and_resume(transport: TransportKind) -> impl FnOnce(Control, ExecLog) + Send {
    move |control: Control, log: ExecLog| {
        wait_for(&log, "the cut under way", |r| executed(r) >= 50);
        assert!(control.hold());
        wait_for(&log, "the machine held", held(transport));
        // The drives' cycles are merged into moves as they end: give the last one time.
        std::thread::sleep(Duration::from_millis(100));
        let at_rest = executed(&log.records());
        std::thread::sleep(Duration::from_millis(300));
        assert_eq!(
            executed(&log.records()),
            at_rest,
            "{transport}: the machine moved while held"
        );
        assert!(control.resume());
    }
}

fn assert_held_and_finished(transport: TransportKind, report: &DryRunReport, log: &[Record]) {
    assert!(
        has_message(log, "requested"),
        "{transport}: no command logged"
    );
    assert!(held(transport)(log), "{transport}: never held");
    assert!(
        report.within_delta,
        "{transport}: after a hold and resume the groove must still be within Δ: {report:?}"
    );
}

#[test]
fn a_hold_stands_the_machine_and_a_resume_finishes_within_delta_over_serial() {
    let transport = TransportKind::Serial;
    let (report, log) = run_with(
        transport,
        "machine-profiles/sim.toml",
        hold_and_resume(transport),
    );
    assert_held_and_finished(transport, &report, &log);
}

#[test]
fn a_hold_stands_the_machine_and_a_resume_finishes_within_delta_over_modbus() {
    let transport = TransportKind::ModbusTcp;
    let (report, log) = run_with(
        transport,
        "machine-profiles/sim.toml",
        hold_and_resume(transport),
    );
    assert_held_and_finished(transport, &report, &log);
}

#[test]
fn a_hold_stands_the_machine_and_a_resume_finishes_within_delta_over_can() {
    let transport = TransportKind::CanSlcan;
    let (report, log) = run_with(
        transport,
        "machine-profiles/canopen-drives.toml",
        hold_and_resume(transport),
    );
    assert_held_and_finished(transport, &report, &log);
}

/// Each transport the simulator serves, with a machine profile it runs on.
const EVERY_TRANSPORT: [(TransportKind, &str); 3] = [
    (TransportKind::Serial, "machine-profiles/sim.toml"),
    (TransportKind::ModbusTcp, "machine-profiles/sim.toml"),
    (
        TransportKind::CanSlcan,
        "machine-profiles/canopen-drives.toml",
    ),
];

#[test]
fn an_abort_ends_the_run_with_the_machine_stopped_on_every_transport() {
    for (transport, profile) in EVERY_TRANSPORT {
        let (report, log) = run_with(transport, profile, |control, log| {
            wait_for(&log, "the cut under way", |r| executed(r) >= 50);
            assert!(control.abort());
        });
        assert!(!report.completed, "{transport}: {report:?}");
        assert!(!report.within_delta, "{transport}");
        assert!(report.stop.is_some(), "{transport}: {report:?}");
        assert!(has_message(&log, "requested"), "{transport}");
        // Stopped for good: the run's last event is its end, not completed.
        let ended = log.iter().rev().find_map(|r| match &r.event {
            Event::End { completed, .. } => Some(*completed),
            _ => None,
        });
        assert_eq!(ended, Some(false), "{transport}");
        // Far from the whole groove.
        assert!(
            report.lines_acked < report.lines / 2,
            "{transport}: {report:?}"
        );
    }
}

/// Every transport's stop. Each transport reads its resume point off what the controller
/// reported executed (grbl's status, the register map's `EXECUTED_SEQ`, the drives' actual
/// positions), so the machine stands on the move of the resume line: at or past its start,
/// not past its end (a linked move feeds Z one way). The report and the log say the same
/// line, and it is a line that moves the machine.
#[test]
fn a_stop_says_where_to_resume_and_the_machine_stands_on_that_line_on_every_transport() {
    for (transport, profile) in EVERY_TRANSPORT {
        let (report, log) = run_with(transport, profile, |control, log| {
            wait_for(&log, "the cut under way", |r| executed(r) >= 200);
            assert!(control.stop("the operator's stop"));
        });
        assert!(!report.completed, "{transport}: {report:?}");
        let line = report
            .resume_at
            .unwrap_or_else(|| panic!("{transport}: no resume line: {report:?}"));
        let logged = log.iter().rev().find_map(|r| match r.event {
            Event::ResumeAt { line, .. } => Some(line),
            _ => None,
        });
        assert_eq!(logged, Some(line), "{transport}: the log's resume line");
        let (_, _, _, posted) = posted(profile);
        let index = posted
            .move_lines
            .iter()
            .position(|&l| l == line)
            .unwrap_or_else(|| panic!("{transport}: line {line} moves nothing"));
        let step = posted.program.steps(Position::UNKNOWN).nth(index).unwrap();
        let stand = log
            .iter()
            .rev()
            .find_map(|r| match r.event {
                Event::Executed { to, .. } => Some(to),
                _ => None,
            })
            .expect("the machine moved");
        let (from, to) = (step.from.z.unwrap(), step.to.z.unwrap());
        let (low, high) = (from.min(to) - 1e-4, from.max(to) + 1e-4);
        assert!(
            (low..=high).contains(&stand[1]),
            "{transport}: the machine stands at Z {}, the resume line {line} runs Z {from} to {to}",
            stand[1]
        );
    }
}
