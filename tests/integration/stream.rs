//! `whirl stream` to `whirl-sim` over a real pseudo-terminal, end to end.

use crate::util::{self, Sim};
use std::ffi::OsStr;

/// whirl-sim on a pseudo-terminal linked at `link`, 50 times real time.
fn sim(link: &std::path::Path) -> Sim {
    sim_with(link, &[OsStr::new("--time-scale"), OsStr::new("50")])
}

/// whirl-sim on a pseudo-terminal linked at `link`, with `args`.
fn sim_with(link: &std::path::Path, args: &[&OsStr]) -> Sim {
    Sim::serving(OsStr::new("--pty"), link, args)
}

#[test]
fn a_program_streams_to_the_simulator_with_every_line_acknowledged_and_logged() {
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("grbl");
    let _sim = sim(&link);
    let (program, lines) = util::short_planned_program(dir.path());
    let log = dir.path().join("exec.jsonl");
    let o = util::whirl(&[
        OsStr::new("stream"),
        program.as_os_str(),
        OsStr::new("--port"),
        link.as_os_str(),
        OsStr::new("--log"),
        log.as_os_str(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let read = whirl::log::read(&log).unwrap();
    let s = whirl::log::Summary::of(&read);
    assert_eq!(
        (s.sent, s.acked, s.errors, s.alarms),
        (lines.len(), lines.len(), 0, 0)
    );
    assert_eq!(s.completed, Some(true));
    // Lines were sent in order, each exactly once.
    let sent: Vec<usize> = read
        .records
        .iter()
        .filter_map(|r| match &r.event {
            whirl::log::Event::Sent { line, .. } => Some(*line),
            _ => None,
        })
        .collect();
    assert!(sent.windows(2).all(|w| w[1] == w[0] + 1), "{sent:?}");
}

#[test]
fn a_program_past_the_travel_is_refused_before_the_port_is_opened() {
    let dir = tempfile::tempdir().unwrap();
    let program = util::write(dir.path(), "far.nc", "G21 G90\nG0 X0 Z0 C0\nG0 Z900\nM2\n");
    let log = dir.path().join("exec.jsonl");
    let o = util::whirl(&[
        OsStr::new("stream"),
        program.as_os_str(),
        OsStr::new("--port"),
        OsStr::new("/nonexistent/port"),
        OsStr::new("--log"),
        log.as_os_str(),
    ]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("Z") && !err.contains("/nonexistent/port"),
        "the limit, not the port: {err}"
    );
}

#[test]
fn whirl_sim_with_a_job_stops_a_coarse_program_with_alarm_64_and_logs_why() {
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("grbl");
    let job = util::example("double-start");
    let sim_log = dir.path().join("sim.jsonl");
    let _sim = sim_with(
        &link,
        &[
            OsStr::new("--time-scale"),
            OsStr::new("0"),
            OsStr::new("--job"),
            job.as_os_str(),
            OsStr::new("--log"),
            sim_log.as_os_str(),
        ],
    );
    let program = util::coarse_program(&job, dir.path());
    let log = dir.path().join("exec.jsonl");
    let o = util::whirl(&[
        OsStr::new("stream"),
        program.as_os_str(),
        OsStr::new("--port"),
        link.as_os_str(),
        OsStr::new("--log"),
        log.as_os_str(),
    ]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("stopped: ALARM:64"), "{err}");
    // The simulator's own log: the alarm with what the guard found, and executed moves
    // that end before the coarse stretch does.
    let text = std::fs::read_to_string(&sim_log).unwrap();
    let events: Vec<serde_json::Value> = text
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let alarm = events
        .iter()
        .find(|e| e["event"] == "alarm")
        .expect("an alarm event");
    assert_eq!(alarm["alarm"], "ProfileError");
    let message = alarm["breach"]["message"].as_str().unwrap();
    assert!(message.contains("beyond delta 0.005 mm"), "{message}");
    let executed: Vec<&serde_json::Value> =
        events.iter().filter(|e| e["event"] == "executed").collect();
    assert!(!executed.is_empty());
    assert!(executed
        .iter()
        .all(|e| e["to"]["z"].as_f64().unwrap() < 2.0));
}

#[test]
fn resume_at_streams_from_that_line_behind_a_preamble_and_runs_nothing_before_it() {
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("grbl");
    let sim_log = dir.path().join("sim.jsonl");
    let _sim = sim_with(
        &link,
        &[
            OsStr::new("--time-scale"),
            OsStr::new("0"),
            OsStr::new("--log"),
            sim_log.as_os_str(),
        ],
    );
    // Feeds at F3000 along X: the first G1 sets the feed, which the resumed run must restore.
    let mut lines = vec!["N1 G21 G90 G94".to_owned(), "N2 G0 X0 Z0 C0".to_owned()];
    lines.push("N3 G1 X1 F3000".to_owned());
    lines.extend((4..=40).map(|n| format!("N{n} G1 X{n}")));
    lines.push("N41 M2".to_owned());
    let program = util::write(dir.path(), "p.nc", &(lines.join("\n") + "\n"));
    let o = util::whirl(&[
        OsStr::new("stream"),
        program.as_os_str(),
        // Written here, not planned: it carries no provenance.
        OsStr::new("--no-provenance-check"),
        OsStr::new("--port"),
        link.as_os_str(),
        OsStr::new("--log"),
        dir.path().join("exec.jsonl").as_os_str(),
        OsStr::new("--resume-at"),
        OsStr::new("20"),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // The simulator's own log: lines N20 to N40 each executed once, nothing before N20.
    let text = std::fs::read_to_string(&sim_log).unwrap();
    let mut executed: Vec<u64> = text
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .filter(|e| e["event"] == "executed")
        .filter_map(|e| e["n"].as_u64())
        .collect();
    executed.sort_unstable();
    assert_eq!(executed, (20..=40).collect::<Vec<u64>>());
}

#[test]
fn whirl_stream_sends_a_program_through_the_modbus_map_to_whirl_sim_over_tcp() {
    let dir = tempfile::tempdir().unwrap();
    let sim_log = dir.path().join("sim.jsonl");
    let (_sim, address) = util::modbus_tcp_sim(&sim_log);
    let address = address.to_string();
    stream_through_the_modbus_map(dir.path(), "modbus-tcp", &address, &sim_log);
}

#[test]
fn whirl_stream_takes_the_plcs_address_and_unit_from_the_machine_profile() {
    let dir = tempfile::tempdir().unwrap();
    let sim_log = dir.path().join("sim.jsonl");
    let (_sim, address) = util::modbus_tcp_sim(&sim_log);
    let address = address.to_string();
    let plc = std::fs::read_to_string(util::root().join("machine-profiles/modbus-plc.toml"))
        .unwrap()
        .replace("192.168.0.10:502", &address)
        .replace("timeout_ms = 500", "timeout_ms = 100");
    let program = util::write(
        dir.path(),
        "short.nc",
        "G21 G90 G94\nG0 X0 Z0 C0\nG1 X5 F3000\nG0 X0\nM2\n",
    );
    let stream = |profile: &std::path::Path| {
        util::whirl(&[
            OsStr::new("stream"),
            program.as_os_str(),
            // Written here, not planned: it carries no provenance.
            OsStr::new("--no-provenance-check"),
            OsStr::new("--machine"),
            profile.as_os_str(),
            OsStr::new("--log"),
            dir.path().join("exec.jsonl").as_os_str(),
        ])
    };
    // No --transport, no --port: the profile's [connection] says Modbus TCP at the
    // simulator's address, unit 1.
    let unit_1 = util::write(dir.path(), "plc.toml", &plc);
    let o = stream(&unit_1);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stdout).contains(&format!("Modbus TCP {address}")));
    // Unit 2: the simulator serves unit 1 only and, as a device on a shared line, does
    // not answer another's requests; the bridge gives up after its retries.
    let unit_2 = util::write(
        dir.path(),
        "plc2.toml",
        &plc.replace("unit = 1 ", "unit = 2 "),
    );
    let o = stream(&unit_2);
    assert!(!o.status.success());
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        stderr.contains("read 8 registers at 0: no answer after"),
        "{stderr}"
    );
}

#[test]
fn whirl_stream_sends_a_program_through_the_modbus_map_to_whirl_sim_over_rtu() {
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("rtu");
    let sim_log = dir.path().join("sim.jsonl");
    let _sim = Sim::serving(
        OsStr::new("--modbus-rtu"),
        &link,
        &[
            OsStr::new("--time-scale"),
            OsStr::new("1"),
            OsStr::new("--idle-exit"),
            OsStr::new("10"),
            OsStr::new("--log"),
            sim_log.as_os_str(),
        ],
    );
    stream_through_the_modbus_map(dir.path(), "modbus-rtu", link.to_str().unwrap(), &sim_log);
}

/// Streams a short program with `whirl stream --transport TRANSPORT --port PORT` to a
/// whirl-sim serving the Modbus map, and checks from the simulator's own log that every
/// moving segment executed once, in order.
fn stream_through_the_modbus_map(
    dir: &std::path::Path,
    transport: &str,
    port: &str,
    sim_log: &std::path::Path,
) {
    // 30 feeds of 1 mm along X at 3000 mm/min, linked moves turning C, and the way back.
    let mut lines = vec!["G21 G90 G94".to_owned(), "G0 X0 Z0 C0".to_owned()];
    lines.extend((1..=30).map(|k| format!("G1 X{k} F3000")));
    lines.extend((1..=10).map(|k| format!("G93 G1 X30 Z{k} C{} F600", 36 * k)));
    lines.extend(["G94 G0 X0".to_owned(), "M2".to_owned()]);
    let program = util::write(dir, "short.nc", &(lines.join("\n") + "\n"));
    let o = util::whirl(&[
        OsStr::new("stream"),
        program.as_os_str(),
        // Written here, not planned: it carries no provenance.
        OsStr::new("--no-provenance-check"),
        OsStr::new("--transport"),
        OsStr::new(transport),
        OsStr::new("--port"),
        OsStr::new(port),
        OsStr::new("--log"),
        dir.join("exec.jsonl").as_os_str(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(sim_log).unwrap();
    let executed: Vec<u64> = text
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .filter(|e| e["event"] == "executed")
        .filter_map(|e| e["n"].as_u64())
        .collect();
    // 30 feeds, 10 linked moves and the retract; the initial rapid to where the machine
    // already stands moves nothing.
    assert_eq!(executed.len(), 41, "{executed:?}");
    assert!(executed.windows(2).all(|w| w[0] < w[1]), "{executed:?}");
}

#[test]
fn whirl_stream_runs_a_program_on_whirl_sims_can_drives_through_slcan() {
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("slcan");
    let sim_log = dir.path().join("sim.jsonl");
    // The example drives, their heartbeat watched for a second rather than 150 ms: the
    // bridge and the simulator are two processes of a test host that a loaded test run may
    // pause for longer than any bus would (a lost heartbeat is tested in can_wire).
    let example = util::root().join("machine-profiles/canopen-drives.toml");
    let text = std::fs::read_to_string(example).unwrap();
    let watched = "heartbeat_timeout_ms = 150";
    assert!(
        text.contains(watched),
        "the example profile's heartbeat timeout"
    );
    let profile = util::write(
        dir.path(),
        "drives.toml",
        &text.replace(watched, "heartbeat_timeout_ms = 1000"),
    );
    let _sim = Sim::serving(
        OsStr::new("--can-slcan"),
        &link,
        &[
            OsStr::new("--machine"),
            profile.as_os_str(),
            OsStr::new("--idle-exit"),
            OsStr::new("10"),
            OsStr::new("--log"),
            sim_log.as_os_str(),
        ],
    );
    // 1 mm of Z at 600 mm/min (0.1 s, 25 cycles of 4 ms), a quarter turn of C at
    // 3600 deg/min (0.25 s, 63 cycles: 62.5 rounded up), in real time. The profile names
    // the transport (can-slcan); the port is the simulator's.
    let program = util::write(
        dir.path(),
        "short.nc",
        "G21 G90 G94\nG0 X1 Z0 C0\nG1 Z-1 F600\nG1 C90 F3600\nG0 X0\n",
    );
    let log = dir.path().join("exec.jsonl");
    let o = util::whirl(&[
        OsStr::new("stream"),
        program.as_os_str(),
        // Written here, not planned: it carries no provenance.
        OsStr::new("--no-provenance-check"),
        OsStr::new("--machine"),
        profile.as_os_str(),
        OsStr::new("--port"),
        link.as_os_str(),
        OsStr::new("--log"),
        log.as_os_str(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("over slcan adapter"), "{stdout}");
    // The simulator's drives end where the program does: X back to 0, Z at -1, C at 90°.
    let events: Vec<serde_json::Value> = std::fs::read_to_string(&sim_log)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let last = events
        .iter()
        .rev()
        .find(|e| e["event"] == "executed")
        .expect("the drives executed cycles");
    let end: Vec<f64> = ["x", "z", "c"]
        .iter()
        .map(|k| last["to"][k].as_f64().unwrap())
        .collect();
    // X and Z to a count (0.1 µm), C to a count of its 2^20-count encoder.
    assert!(
        end[0].abs() < 1e-4 && (end[1] + 1.0).abs() < 1e-4,
        "{end:?}"
    );
    assert!((end[2] - 90.0).abs() <= 360.0 / 1_048_576.0, "{end:?}");
    let bridge = std::fs::read_to_string(&log).unwrap();
    assert!(bridge.contains("\"transport\":\"can-slcan\""));
    assert!(
        bridge.contains("finished; the drives are disabled"),
        "{bridge}"
    );
}
