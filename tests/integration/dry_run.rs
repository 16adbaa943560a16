//! `whirl dry-run` end to end: the planned program streamed over a pseudo-terminal to the
//! simulated controller, whose Δ guard measures what it executed.

use crate::util;
use std::ffi::OsStr;
use whirl::log::{self, Event};

/// An executed move of a log.
struct Move {
    /// Where it ended: X, Z, C.
    to: [f64; 3],
    /// A rapid (positioning).
    rapid: bool,
}

/// The executed moves of a log.
fn executed(log: &log::Read) -> Vec<Move> {
    log.records
        .iter()
        .filter_map(|r| match &r.event {
            Event::Executed { to, rapid, .. } => Some(Move {
                to: *to,
                rapid: *rapid,
            }),
            _ => None,
        })
        .collect()
}

#[test]
fn every_example_dry_runs_to_the_end_within_delta() {
    for job in util::examples() {
        let dir = tempfile::tempdir().unwrap();
        let planned = dir.path().join("p.nc");
        let o = util::whirl(&[
            OsStr::new("plan"),
            job.as_os_str(),
            OsStr::new("-o"),
            planned.as_os_str(),
        ]);
        assert!(o.status.success());
        let program = std::fs::read_to_string(&planned).unwrap();
        let (code, r, log) = util::dry_run(&job, dir.path(), &[]);
        let name = job.display();
        assert_eq!(code, Some(0), "{name}: {r:#}");
        assert_eq!(r["within_delta"], true, "{name}");
        assert_eq!(r["completed"], true, "{name}");
        // The program the dry run streamed is the one `whirl plan` writes but for its
        // provenance header (a program file's), every line acked.
        let header = program
            .lines()
            .filter(|l| l.contains("(whirl provenance: "))
            .count();
        assert!(header > 0, "{name}: no provenance header");
        let lines = (program.lines().count() - header) as u64;
        assert_eq!(r["lines"].as_u64(), Some(lines), "{name}");
        assert_eq!(r["lines_acked"].as_u64(), Some(lines), "{name}");
        assert!(r["max_error_mm"].as_f64().unwrap() <= r["delta_mm"].as_f64().unwrap());
        assert_eq!(
            r["points_measured"], r["points"],
            "{name}: the whole groove measured"
        );
        let u = r["link_utilization"].as_f64().unwrap();
        assert!((0.0..=1.0).contains(&u), "{name}: {u}");
        assert_eq!(r["alarms"].as_array().map(Vec::len), Some(0), "{name}");
        // The simulator's record: every linked move executed exactly once, each naming its
        // file line (grblHAL programs carry their line numbers as N words).
        let moves = executed(&log);
        let linked = program
            .lines()
            .filter(|l| util::block(l).starts_with("G1") && l.contains(" C"))
            .count();
        let cutting = moves.iter().filter(|m| !m.rapid).count();
        assert!(
            cutting >= linked,
            "{name}: {cutting} moves for {linked} lines"
        );
        let summary = log::Summary::of(&log);
        assert!(summary.executed_twice.is_empty(), "{name}");
        assert_eq!(summary.completed, Some(true), "{name}");
    }
}

#[test]
fn a_coarse_stretch_trips_the_delta_alarm_inside_the_stretch() {
    let dir = tempfile::tempdir().unwrap();
    let job = util::example("double-start");
    let program = util::coarse_program(&job, dir.path());
    let (code, r, log) = util::dry_run(
        &job,
        dir.path(),
        &[OsStr::new("--program"), program.as_os_str()],
    );
    assert_eq!(code, Some(2), "beyond Δ exits 2: {r:#}");
    assert_eq!(r["within_delta"], false);
    assert_eq!(r["completed"], false);
    let alarms = r["alarms"].as_array().unwrap();
    assert_eq!(alarms.len(), 1, "{r:#}");
    assert_eq!(alarms[0]["code"], 64);
    let detail = alarms[0]["detail"].as_str().unwrap();
    assert!(detail.contains("beyond delta 0.005 mm"), "{detail}");
    assert!(r["max_error_mm"].as_f64().unwrap() > 0.005);
    assert!(r["lines_acked"].as_u64() < r["lines"].as_u64());
    // The machine stopped inside the stretch: no move ends past it, and the last one ends in it.
    let moves = executed(&log);
    let last_z = moves.last().unwrap().to[1];
    assert!((-2.0..2.0).contains(&last_z), "stopped at Z {last_z}");
    assert!(moves.iter().all(|m| m.to[1] < 2.0));
}

#[test]
fn the_log_of_a_dry_run_draws_the_machined_section_against_the_target() {
    let dir = tempfile::tempdir().unwrap();
    let job = util::example("double-start");
    let (code, _, _) = util::dry_run(&job, dir.path(), &[]);
    assert_eq!(code, Some(0));
    let svg = dir.path().join("run.svg");
    let o = util::whirl(&[
        OsStr::new("log"),
        OsStr::new("plot"),
        dir.path().join("exec.jsonl").as_os_str(),
        OsStr::new("-o"),
        svg.as_os_str(),
        OsStr::new("--job"),
        job.as_os_str(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(&svg).unwrap();
    for title in ["X over time", "Z over time", "C over time", "axial section"] {
        assert!(text.contains(title), "{title}");
    }
    assert!(text.contains("machined (error"));
}

#[test]
fn a_program_past_the_travel_is_refused_before_the_simulator_starts() {
    let dir = tempfile::tempdir().unwrap();
    let program = util::write(
        dir.path(),
        "far.nc",
        "N1 G21 G90 G94\nN2 G0 X0 Z0 C0\nN3 G1 X500 F100\nN4 M2\n",
    );
    let (report, log) = (dir.path().join("r.json"), dir.path().join("l.jsonl"));
    let o = util::whirl(&[
        OsStr::new("dry-run"),
        util::example("double-start").as_os_str(),
        OsStr::new("--program"),
        program.as_os_str(),
        OsStr::new("--report"),
        report.as_os_str(),
        OsStr::new("--log"),
        log.as_os_str(),
    ]);
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("X") && err.contains("160"),
        "names the axis and limit: {err}"
    );
    assert!(!report.exists());
    // Nothing was sent: the log holds no line.
    let sent = std::fs::read_to_string(&log).unwrap_or_default();
    assert!(!sent.contains("\"sent\""), "{sent}");
}

#[test]
fn every_example_dry_runs_within_delta_over_modbus_tcp_and_rtu() {
    // The two transports side by side: at 200 times real time the simulator mostly waits
    // on the link, so they share the host's cores without slowing each other, and a host
    // busy for a third of a second still feeds the controller's watchdog in time.
    std::thread::scope(|scope| {
        for transport in ["modbus-tcp", "modbus-rtu"] {
            scope.spawn(move || {
                for job in util::examples() {
                    let dir = tempfile::tempdir().unwrap();
                    let (code, r, log) = util::dry_run(
                        &job,
                        dir.path(),
                        &[
                            OsStr::new("--transport"),
                            OsStr::new(transport),
                            OsStr::new("--time-scale"),
                            OsStr::new("200"),
                        ],
                    );
                    let name = format!("{} over {transport}", job.display());
                    assert_eq!(code, Some(0), "{name}: {r:#}");
                    assert_eq!(r["within_delta"], true, "{name}");
                    assert_eq!(r["completed"], true, "{name}");
                    assert_eq!(
                        r["lines_acked"], r["lines"],
                        "{name}: every segment published"
                    );
                    assert_eq!(r["points_measured"], r["points"], "{name}");
                    assert!(r["max_error_mm"].as_f64().unwrap() <= r["delta_mm"].as_f64().unwrap());
                    assert_eq!(r["alarms"].as_array().map(Vec::len), Some(0), "{name}");
                    let u = r["link_utilization"].as_f64().unwrap();
                    assert!((0.0..=1.0).contains(&u), "{name}: {u}");
                    // The simulator's own record: every segment's move executed once.
                    let summary = log::Summary::of(&log);
                    assert!(summary.executed_twice.is_empty(), "{name}");
                    assert_eq!(summary.sent as u64, r["lines"].as_u64().unwrap(), "{name}");
                    assert_eq!(summary.completed, Some(true), "{name}");
                }
            });
        }
    });
}

#[test]
fn every_example_dry_runs_within_delta_on_can_drives_over_slcan() {
    use whirl::config::machine::Axis;
    use whirl::program::Position;
    let profile_path = util::root().join("machine-profiles/canopen-drives.toml");
    let profile = whirl::config::machine::MachineProfile::load(&profile_path).unwrap();
    let drives = profile
        .connection
        .as_ref()
        .and_then(|c| c.drives())
        .unwrap();
    let (period, scale) = (drives.period().as_secs_f64(), drives.counts_per_unit());
    // Two at a time: a CAN dry run waits on the pseudo-terminal about half the time.
    let jobs = util::examples();
    std::thread::scope(|scope| {
        for half in jobs.chunks(jobs.len().div_ceil(2)) {
            let (profile, profile_path) = (&profile, &profile_path);
            scope.spawn(move || {
                for job in half {
                    let dir = tempfile::tempdir().unwrap();
                    let (code, r, log) = util::dry_run(
                        job,
                        dir.path(),
                        &[
                            OsStr::new("--machine"),
                            profile_path.as_os_str(),
                            OsStr::new("--transport"),
                            OsStr::new("can-slcan"),
                        ],
                    );
                    let name = format!("{} over can-slcan", job.display());
                    assert_eq!(code, Some(0), "{name}: {r:#}");
                    assert_eq!(r["within_delta"], true, "{name}");
                    assert_eq!(r["completed"], true, "{name}");
                    assert_eq!(r["lines_acked"], r["lines"], "{name}: every set-point sent");
                    assert_eq!(r["points_measured"], r["points"], "{name}");
                    assert!(r["max_error_mm"].as_f64().unwrap() <= r["delta_mm"].as_f64().unwrap());
                    assert_eq!(r["alarms"].as_array().map(Vec::len), Some(0), "{name}");
                    // The bus's load: a cycle's seven frames of up to 6 bytes and a SYNC
                    // take under 800 bit times of the 4000 a 4 ms cycle has at 1 Mbit/s.
                    let load = r["link_utilization"].as_f64().unwrap();
                    assert!(load > 0.0 && load < 0.2, "{name}: {load}");
                    // The simulator's own record: the drives' path is one unbroken line
                    // of set-point cycles, as long as the set-points, ending where the
                    // program does: the one `whirl dry-run` planned and sent, its nodes
                    // measured by the engine.
                    let job = whirl::config::job::Job::load(job).unwrap();
                    // The program as written (its decimals), which is what was sent.
                    let planned = whirl::judge::refine::plan(&job, profile).unwrap();
                    let written = whirl::transport::Posted::read("p", &planned.text, profile)
                        .unwrap()
                        .program;
                    let end = written
                        .steps(Position::known(0.0, 0.0, 0.0))
                        .last()
                        .unwrap()
                        .to;
                    let moves: Vec<([f64; 2], [f64; 3], [f64; 3])> = log
                        .records
                        .iter()
                        .filter_map(|rec| match &rec.event {
                            Event::Executed {
                                times, from, to, ..
                            } => Some((*times, *from, *to)),
                            _ => None,
                        })
                        .collect();
                    for pair in moves.windows(2) {
                        assert_eq!(pair[0].2, pair[1].1, "{name}: a gap in the path");
                        assert!((pair[0].0[1] - pair[1].0[0]).abs() < 1e-9, "{name}");
                    }
                    let last = moves.last().unwrap().2;
                    for (k, axis) in Axis::ALL.into_iter().enumerate() {
                        let want = end.get(axis).unwrap();
                        assert!((last[k] - want).abs() <= 1.0 / scale[k], "{name}: {axis}");
                    }
                    // Machine time: the set-points' cycles, then the few the drives take to
                    // settle on the last one.
                    let cycles = r["lines"].as_f64().unwrap() * period;
                    let moving = r["machine_time_s"].as_f64().unwrap();
                    assert!(
                        moving >= cycles - 1e-6 && moving < cycles + 0.5,
                        "{name}: {moving} s for {cycles} s of set-points"
                    );
                }
            });
        }
    });
}
