//! The feed override of issue 13: capped where the insert cusp fills its share of Δ,
//! refused above it before anything is sent, carried by every transport in its own terms
//! (grbl's real-time bytes read back from `Ov:`, the Modbus map's `FEED_OVERRIDE`
//! register, the CANopen bridge's set-point clock), honoured by the simulator, and logged.
//!
//! The cusp a run leaves is measured from what the simulator executed: the workpiece's
//! turn rate in the linked moves, against the ring's, gives the turn between insert hits,
//! and the cusp grows with its square (kinematics.md). At the cap it stays within its share;
//! above it, beyond.

use std::time::{Duration, Instant};

use whirl::config::job::Job;
use whirl::config::machine::MachineProfile;
use whirl::judge::dry_run::{dry_run, DryRunOptions, DryRunReport};
use whirl::judge::simulator::machine;
use whirl::log::{Event, ExecLog, FeedOverrideState, Record};
use whirl::plan::overrides::{FeedCap, GRBL};
use whirl::post::modbus::Segment;
use whirl::program::Program;
use whirl::protocol::modbus::{Exception, RingWriter, WriterEvent, WriterOptions};
use whirl::transport::{control, Control, Posted, TransportKind};
use whirl_sim::modbus::{Bank, BankOptions};
use whirl_sim::{Controller, ControllerOptions};

use crate::modbus_map::{from_bank, to_bank};
use crate::util;

/// The double-start example, as `whirl dry-run` plans it for the simulator's profile.
fn double_start() -> (Job, MachineProfile, whirl::plan::Plan) {
    let job = Job::load(&util::example("double-start")).unwrap();
    let machine = MachineProfile::builtin_sim().unwrap();
    let plan = whirl::judge::refine::plan(&job, &machine).unwrap();
    (job, machine, plan)
}

/// The workpiece's turn rate in the linked moves the simulator executed once it ran at
/// `percent` (the median over the moves after the log says so), degrees a second.
fn executed_c_rate(records: &[Record], percent: u16) -> f64 {
    let from = records
        .iter()
        .position(|r| {
            matches!(r.event, Event::FeedOverride { percent: p, state: FeedOverrideState::Running } if p == percent)
        })
        .unwrap_or_else(|| panic!("the log never shows the controller running at {percent} %"));
    let mut rates: Vec<f64> = records[from..]
        .iter()
        .filter_map(|r| match &r.event {
            Event::Executed {
                times,
                from,
                to,
                rapid: false,
                ..
            } if (to[2] - from[2]).abs() > 1e-9 && times[1] > times[0] => {
                Some((to[2] - from[2]).abs() / (times[1] - times[0]))
            }
            _ => None,
        })
        .collect();
    assert!(
        rates.len() >= 100,
        "only {} linked moves at {percent} %",
        rates.len()
    );
    rates.sort_by(f64::total_cmp);
    rates[rates.len() / 2]
}

/// Dry-runs the double-start job over serial with `control` asked `percent` before the
/// first byte, until 300 linked moves ran at it; the report and the log.
fn run_at(
    job: &Job,
    machine: &MachineProfile,
    plan: &whirl::plan::Plan,
    cap: FeedCap,
    percent: u16,
) -> (DryRunReport, Vec<Record>) {
    let posted = Posted::read("double-start", &plan.text, machine).unwrap();
    let log = ExecLog::memory();
    let (control, commands) = control();
    control.set_feed_cap(cap);
    control
        .feed_override(percent)
        .expect("within the cap given");
    let watched = log.clone();
    let operator = std::thread::spawn(move || stop_after_linked_moves(&control, &watched, percent));
    // At 50× the whole program takes half a minute: time for grbl's override bytes, one a
    // status report, to reach the value asked long before the groove ends (as fast as the
    // host allows, the program can end first).
    let options = DryRunOptions {
        transport: TransportKind::Serial,
        time_scale: Some(50.0),
        commands: Some(commands),
        ..DryRunOptions::default()
    };
    let report = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap()
        .block_on(dry_run(
            job,
            plan.ring,
            machine,
            &posted,
            options,
            &mut log.clone(),
        ))
        .expect("the dry run is carried out");
    operator.join().expect("the operator's checks hold");
    (report, log.records())
}

/// Stops the run once 300 linked moves executed after the controller reported `percent`.
fn stop_after_linked_moves(control: &Control, log: &ExecLog, percent: u16) {
    let since = Instant::now();
    let mut follow = util::Follow::new(log);
    loop {
        let records = follow.look();
        let at = records.iter().position(|r| {
            matches!(r.event, Event::FeedOverride { percent: p, state: FeedOverrideState::Running } if p == percent)
        });
        let linked = at.map_or(0, |at| {
            records[at..]
                .iter()
                .filter(|r| matches!(&r.event, Event::Executed { from, to, rapid: false, .. } if from[2] != to[2]))
                .count()
        });
        if linked >= 300 {
            control.stop("the test has seen enough");
            return;
        }
        if let Some(end) = records
            .iter()
            .find(|r| matches!(r.event, Event::End { .. }))
        {
            panic!(
                "the run ended ({:?}) after {linked} linked moves at {percent} %",
                end.event
            );
        }
        if since.elapsed() > Duration::from_secs(300) {
            let overrides: Vec<_> = records
                .iter()
                .filter(|r| matches!(r.event, Event::FeedOverride { .. }))
                .map(|r| &r.event)
                .collect();
            panic!("waited five minutes for 300 linked moves at {percent} % ({linked} seen); the log's feed overrides: {overrides:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn at_the_cap_the_executed_cusp_stays_within_its_share_and_above_it_does_not() {
    let (job, machine, plan) = double_start();
    let cap = FeedCap::of(&plan.report, GRBL);
    // The workpiece as planned turns at n_w rpm: 6·n_w degrees a second.
    let planned_rate = 6.0 * job.cut.workpiece_rpm;
    // The cusp the executed turn rate leaves, from the planned one: ∝ (turn between hits)².
    let cusp = |rate: f64| plan.report.cusp_mm * (rate / planned_rate).powi(2);
    assert!(
        plan.report.cusp_mm > 0.0,
        "the example has a cusp to coarsen"
    );

    let (report, log) = run_at(&job, &machine, &plan, cap.clone(), cap.max_percent);
    let rate = executed_c_rate(&log, cap.max_percent);
    let k = f64::from(cap.max_percent) / 100.0;
    assert!(
        (rate / planned_rate - k).abs() < 0.005,
        "the simulator turns C at {rate} °/s at {} %, planned {planned_rate} °/s",
        cap.max_percent
    );
    assert!(
        cusp(rate) <= cap.cusp_share_mm * 1.005,
        "at the cap the cusp {} mm passes its share {} mm",
        cusp(rate),
        cap.cusp_share_mm
    );
    assert!(report.stop.is_some(), "stopped by the test: {report:?}");
    // The log says what was asked and every value the controller ran at.
    assert!(log.iter().any(|r| matches!(
        r.event,
        Event::FeedOverride { state: FeedOverrideState::Asked, percent } if percent == cap.max_percent
    )));

    // Above the cap (a control told a looser one, as a knob on the machine would be):
    // the cusp passes its share.
    if cap.max_percent < GRBL.max {
        let above = (cap.max_percent + 20).min(GRBL.max);
        let loose = FeedCap::new(plan.report.delta_mm, 0.0, plan.report.cusp_mm, GRBL);
        let (_, log) = run_at(&job, &machine, &plan, loose, above);
        let rate = executed_c_rate(&log, above);
        assert!(
            cusp(rate) > cap.cusp_share_mm,
            "at {above} % the cusp {} mm should pass its share {} mm",
            cusp(rate),
            cap.cusp_share_mm
        );
    } else {
        // grbl's range stops it first: the cusp would allow more.
        assert!(cap.cusp_limit_percent >= f64::from(GRBL.max));
    }
}

#[test]
fn the_command_line_refuses_an_override_above_the_cap_before_anything_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let job = util::example("double-start");
    let log = dir.path().join("exec.jsonl");
    let run = |percent: &str| {
        util::whirl(&[
            "dry-run".as_ref(),
            job.as_os_str(),
            "--log".as_ref(),
            log.as_os_str(),
            "--feed-override".as_ref(),
            percent.as_ref(),
        ])
    };
    // Above any cap: grbl's range ends at 200.
    let o = run("201");
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("--feed-override 201"), "{err}");
    assert!(err.contains("above the cap of"), "{err}");
    assert!(
        err.contains("insert cusp") || err.contains("range takes"),
        "{err}"
    );
    assert!(!log.exists(), "nothing is written before the refusal");
    // Below grbl's range.
    let o = run("9");
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("below 10 %"), "{err}");
    assert!(!log.exists());
    // A G-code program has no plan to take the cusp's share from.
    let program = util::write(dir.path(), "p.nc", "G21 G90\nG0 X1\n");
    let o = util::whirl(&[
        "stream".as_ref(),
        program.as_os_str(),
        "--port".as_ref(),
        dir.path().join("no-such-port").as_os_str(),
        "--log".as_ref(),
        log.as_os_str(),
        "--feed-override".as_ref(),
        "90".as_ref(),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("is a program, not a job"), "{err}");
    assert!(!log.exists());
}

/// Streams the trapezoidal example's lead-in and first linked moves through a bank, the
/// override asked before the first request; the writer's events and the controller's
/// override at the end.
fn modbus_stream(options: BankOptions, percent: u16) -> (Vec<WriterEvent>, u8) {
    let profile = MachineProfile::builtin_sim().unwrap();
    let job = Job::load(&util::example("trapezoidal")).unwrap();
    let plan = whirl::plan::plan(&job, &profile).unwrap();
    let program = Program {
        moves: plan.program.moves[..40].to_vec(),
    };
    let segments: Vec<Segment> = whirl::post::modbus::segments(&program).unwrap();
    let controller = Controller::new(&machine(&profile), ControllerOptions::default()).unwrap();
    let mut bank = Bank::new(controller, options).unwrap();
    let mut writer = RingWriter::new(segments, WriterOptions::default()).unwrap();
    writer.feed_override(percent);
    let mut now = Duration::ZERO;
    let mut events = Vec::new();
    while !writer.is_finished() {
        while let Some(request) = writer.poll(now) {
            writer.response(from_bank(bank.request(&to_bank(&request))));
        }
        events.extend(std::iter::from_fn(|| writer.next_event()));
        bank.advance(0.005).unwrap();
        bank.take_events();
        now += Duration::from_millis(5);
        assert!(now < Duration::from_secs(3600), "the stream stalled");
    }
    events.extend(std::iter::from_fn(|| writer.next_event()));
    (events, bank.controller().feed_override())
}

#[test]
fn the_modbus_register_sets_the_override_and_a_map_without_it_streams_on() {
    let (events, running) = modbus_stream(BankOptions::default(), 150);
    assert!(
        events.contains(&WriterEvent::FeedOverride(150)),
        "{events:?}"
    );
    assert_eq!(running, 150);
    assert!(events.contains(&WriterEvent::Done), "{events:?}");
    // A PLC whose map predates the register: exception 02, said, and the stream goes on.
    let old = BankOptions {
        feed_override: false,
        ..BankOptions::default()
    };
    let (events, running) = modbus_stream(old, 150);
    assert!(
        events.contains(&WriterEvent::FeedOverrideRefused {
            percent: 150,
            exception: Exception::IllegalDataAddress
        }),
        "{events:?}"
    );
    assert_eq!(running, 100);
    assert!(events.contains(&WriterEvent::Done), "{events:?}");
}
