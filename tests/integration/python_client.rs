//! whirl-sim against a sender that is not whirl's: `tests/clients/grbl_stream.py`, written
//! from grbl's published character-counting method (grbl's `doc/script/stream.py`), streams
//! over a real pseudo-terminal. A third-party grbl sender must get exactly one `ok` per line
//! at grblHAL's 1024-byte RX buffer and at AVR grbl's 128 bytes, and whirl's own streamer
//! cannot show that, because it shares the authors' reading of the protocol.
//!
//! Likewise for CANopen: python-canopen, the stack most Python CANopen tools use, with
//! python-can's slcan interface, masters whirl-sim's three CiA 402 drives over its
//! pseudo-terminal (`tests/clients/canopen_master.py`, the drives' object dictionary from
//! `tests/data/cia402-drive.eds`), and whirl's master runs a job on three drives that
//! python-canopen serves from the same EDS (`tests/clients/canopen_drive.py`): the
//! configuration, the PDO mapping and the set-points as another stack reads them.

use crate::util;
use std::collections::HashMap;
use std::ffi::OsStr;
use std::fs::File;
use std::process::{Command, ExitStatus};
use std::time::{Duration, Instant};

/// A program of a few hundred moves inside the simulated machine's travel
/// (`machine-profiles/sim.toml`: X −5…160, Z −300…300, C unlimited), with N words, both
/// comment styles, comment-only and blank lines, spaces and lower case, ending with M2
/// (whose `[MSG:Pgm End]` the client must not take for an answer). Returns the text and
/// the number of lines that carry a block, i.e. the lines that must each get one `ok`.
fn program() -> (String, usize) {
    let mut lines = vec![
        "(independent client test: grbl character counting)".to_owned(),
        "G21 G90 G94 ; millimetres, absolute, units per minute".to_owned(),
        "G0 X20 Z0 C0".to_owned(),
    ];
    let mut blocks = 2;
    for i in 0..300_u32 {
        let n = 10 + i;
        // X zig-zags across 10…40, Z walks from −100 to +110, C turns 3.5° a line.
        let x = 10.0 + f64::from(i % 21) * 1.5;
        let z = -100.0 + f64::from(i) * 0.7;
        let c = f64::from(i) * 3.5;
        lines.push(match i % 6 {
            0 => format!("N{n} G0 X{x:.3} Z{z:.3} (rapid)"),
            1 => format!("N{n} G1 X{x:.3} Z{z:.3} C{c:.2} F2400 ; feed"),
            2 => format!("n{n} g1 x{x:.3} z{z:.3} c{c:.2} f1800"),
            3 => format!("N{n}G1X{x:.3}Z{z:.3}"),
            4 => format!("  N{n}  G1  X{x:.4}  Z{z:.4}  C{c:.3}  F3000  (wide, spaced)"),
            _ => format!("N{n} X{x:.3} Z{z:.3} C{c:.2}"),
        });
        blocks += 1;
        if i % 40 == 0 {
            lines.push(String::new());
            lines.push(format!("; pass {}", i / 40));
            lines.push("(a comment-only line)".to_owned());
        }
    }
    lines.extend(["G0 X20".to_owned(), "M2".to_owned()]);
    blocks += 2;
    (lines.join("\n") + "\n", blocks)
}

/// What the client did: its exit status, its summary (`lines=… ok=… error=… extra=…`) and
/// its stderr.
struct Run {
    status: ExitStatus,
    summary: HashMap<String, usize>,
    stderr: String,
}

/// Stream `program` with the Python client told the RX buffer is `client_rx` bytes, to a
/// whirl-sim whose buffer is `sim_rx`, each on its own pseudo-terminal in its own temp dir.
fn stream(program: &str, sim_rx: usize, client_rx: usize) -> Run {
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("grbl");
    let rx = sim_rx.to_string();
    let _sim = util::Sim::serving(
        OsStr::new("--pty"),
        &link,
        &[
            OsStr::new("--time-scale"),
            OsStr::new("50"),
            OsStr::new("--rx"),
            OsStr::new(&rx),
        ],
    );
    let file = util::write(dir.path(), "program.nc", program);
    let client_rx = client_rx.to_string();
    // The client bounds each wait by 10 s; this bounds the whole run if it still hangs.
    let (status, stdout, stderr) = python(
        dir.path(),
        "tests/clients/grbl_stream.py",
        &[
            link.as_os_str(),
            file.as_os_str(),
            OsStr::new("--rx"),
            OsStr::new(&client_rx),
        ],
        Duration::from_secs(120),
    );
    let line = stdout
        .lines()
        .find(|l| l.starts_with("lines="))
        .unwrap_or_else(|| panic!("no summary line; stdout {stdout:?}, stderr {stderr:?}"));
    let summary = line
        .split_whitespace()
        .map(|kv| {
            let (k, v) = kv.split_once('=').expect("key=value");
            (k.to_owned(), v.parse().expect("a count"))
        })
        .collect();
    Run {
        status,
        summary,
        stderr,
    }
}

/// Every line with a block sent once and answered by exactly one `ok`.
fn assert_every_line_ok(sim_rx: usize, client_rx: usize) {
    if !util::python_with("serial", "pyserial") {
        return;
    }
    let (text, blocks) = program();
    let run = stream(&text, sim_rx, client_rx);
    assert!(run.status.success(), "{}: {}", run.status, run.stderr);
    let count = |k: &str| run.summary[k];
    assert_eq!(count("lines"), blocks, "{}", run.stderr);
    assert_eq!(count("ok"), blocks, "{}", run.stderr);
    assert_eq!((count("error"), count("extra")), (0, 0), "{}", run.stderr);
}

#[test]
fn an_independent_grbl_client_gets_one_ok_per_line_from_a_1024_byte_buffer() {
    assert_every_line_ok(1024, 1024);
}

#[test]
fn an_independent_grbl_client_gets_one_ok_per_line_from_a_128_byte_buffer() {
    assert_every_line_ok(128, 128);
}

/// The check above can fail: a client that counts against more buffer than the controller
/// has overflows it, and the simulator's answers say so (it reports what grblHAL would drop
/// silently, sim/README.md).
#[test]
fn a_client_counting_on_a_larger_buffer_than_the_controller_has_gets_errors() {
    if !util::python_with("serial", "pyserial") {
        return;
    }
    let (text, _) = program();
    let run = stream(&text, 128, 1024);
    assert!(!run.status.success());
    assert!(run.summary["error"] > 0, "{:?}", run.summary);
    assert!(run.stderr.contains("RX overflow"), "{}", run.stderr);
}

/// Runs `python3 SCRIPT ARGS…` to its end (at most `limit`): (status, stdout, stderr). The
/// output goes to files in `dir`: a pipe left unread could fill and stall the client.
fn python(
    dir: &std::path::Path,
    script: &str,
    args: &[&OsStr],
    limit: Duration,
) -> (ExitStatus, String, String) {
    let (out_path, err_path) = (dir.join("stdout"), dir.join("stderr"));
    let mut client = Command::new("python3")
        .arg(util::root().join(script))
        .args(args)
        .stdout(File::create(&out_path).unwrap())
        .stderr(File::create(&err_path).unwrap())
        .spawn()
        .expect("python3 runs the client");
    let deadline = Instant::now() + limit;
    let status = loop {
        if let Some(status) = client.try_wait().unwrap() {
            break status;
        }
        if Instant::now() > deadline {
            let _ = client.kill();
            let _ = client.wait();
            panic!("{script} did not finish in {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let stdout = std::fs::read_to_string(&out_path).unwrap();
    let stderr = std::fs::read_to_string(&err_path).unwrap();
    (status, stdout, stderr)
}

/// python-canopen masters whirl-sim's drives as it would any CiA 402 drive: NMT reset and
/// boot-ups, SDO reads of the device type, the identity (1018h, which CiA 301 makes
/// mandatory: the simulator lacked it) and the modes, PDO mapping written by its pdo
/// module, BaseNode402's walk to Operation enabled, a cyclic synchronous position path,
/// heartbeats, a following error's EMCY and the fault reset. The script's checks are its
/// own, each a line on stdout; it bounds every wait by 5 s.
#[test]
fn python_canopen_masters_the_simulated_drives() {
    if !util::python_with("canopen", "canopen python-can")
        || !util::python_with("serial", "pyserial")
    {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("slcan");
    let _sim = util::Sim::serving(
        OsStr::new("--can-slcan"),
        &link,
        &[OsStr::new("--idle-exit"), OsStr::new("30")],
    );
    let eds = util::root().join("tests/data/cia402-drive.eds");
    let (status, stdout, stderr) = python(
        dir.path(),
        "tests/clients/canopen_master.py",
        &[link.as_os_str(), eds.as_os_str()],
        Duration::from_secs(120),
    );
    assert!(status.success(), "{status}\n{stdout}\n{stderr}");
    for node in 1..=3 {
        for what in [
            "device type 0x00020192, CiA 402",
            "6061h shows mode 8 (CSP)",
            "TPDO1 mapped by SDO as written",
            "Operation enabled",
            "followed 100 set-points",
            "all Operational",
            "disabled",
        ] {
            let start = format!("ok: node {node}: ");
            assert!(
                stdout
                    .lines()
                    .any(|l| l.starts_with(&start) && l.contains(what)),
                "no {start}… {what} in\n{stdout}"
            );
        }
        assert!(
            stdout.contains(&format!(
                "node {node}: vendor 0x0, product 402, revision 0x10000, serial {node}"
            )),
            "{stdout}"
        );
    }
    assert!(
        stdout.contains("ok: node 1: EMCY 0x8611, following error"),
        "{stdout}"
    );
    assert!(
        stdout.contains("ok: node 1: reset, Operation enabled"),
        "{stdout}"
    );
    assert!(stdout.ends_with("done\n"), "{stdout}");
}

/// What `tests/clients/canopen_drive.py` logged, one JSON value a line.
fn drive_log(path: &std::path::Path) -> Vec<serde_json::Value> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).expect("a JSON line"))
        .collect()
}

/// whirl's master runs a short job on three CiA 402 drives served by python-canopen
/// (LocalNodes with the EDS's object dictionary; the PDOs, the power state machine and the
/// position loop written in the script from CiA 301/402), through an slcan adapter the
/// script serves on a pseudo-terminal. Checked from the drives' side: what whirl wrote by
/// SDO, in CiA 301's order for PDO mapping, the power states, and each SYNC's targets.
#[test]
fn whirls_master_runs_a_job_on_drives_python_canopen_serves() {
    if !util::python_with("canopen", "canopen python-can") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("drives.jsonl");
    let eds = util::root().join("tests/data/cia402-drive.eds");
    let mut drives = Command::new("python3")
        .arg(util::root().join("tests/clients/canopen_drive.py"))
        .args([eds.as_os_str(), log.as_os_str()])
        .stdout(std::process::Stdio::piped())
        .stderr(File::create(dir.path().join("drives.stderr")).unwrap())
        .spawn()
        .expect("python3 runs the drives");
    let mut port = String::new();
    std::io::BufRead::read_line(
        &mut std::io::BufReader::new(drives.stdout.take().unwrap()),
        &mut port,
    )
    .unwrap();
    let port = port.trim().to_owned();
    assert!(port.starts_with("/dev/"), "no terminal: {port:?}");
    // The example drives' profile, its heartbeat watched for a second rather than 150 ms:
    // the drives are Python threads in another process on a host whose two cores other
    // builds keep busy, and this test is about configuration and set-points. Its drives'
    // data sheet is the EDS python-canopen serves them from: whirl checks the objects it
    // uses against it (an independent reader's file) before it sends anything.
    let text = std::fs::read_to_string(util::root().join("machine-profiles/canopen-drives.toml"))
        .unwrap()
        .replace("heartbeat_timeout_ms = 150", "heartbeat_timeout_ms = 1000")
        + &format!("eds = {:?}\n", eds.display().to_string());
    let profile = util::write(dir.path(), "drives.toml", &text);
    // X 1 → 2 mm, Z 0 → −1 mm, C 0 → 90° in one feed, after a rapid to X 1.
    let program = util::write(
        dir.path(),
        "job.nc",
        "G21 G90 G94\nG0 X1 Z0 C0\nG1 X2 Z-1 C90 F600\nG0 X0\nM2\n",
    );
    let run = Command::new(env!("CARGO_BIN_EXE_whirl"))
        .env("WHIRL_DB", dir.path().join("runs.sqlite"))
        .arg("stream")
        .arg(&program)
        .arg("--machine")
        .arg(&profile)
        .args(["--transport", "can-slcan", "--port", &port, "--log"])
        .arg(dir.path().join("exec.jsonl"))
        // Written by hand: it carries no provenance.
        .arg("--no-provenance-check")
        .output()
        .expect("whirl runs");
    let _ = drives.kill();
    let _ = drives.wait();
    let stderr = String::from_utf8_lossy(&run.stderr);
    let drives_stderr = std::fs::read_to_string(dir.path().join("drives.stderr")).unwrap();
    assert!(run.status.success(), "{stderr}\n{drives_stderr}");
    let events = drive_log(&log);

    for node in 1..=3u64 {
        let writes: Vec<(u64, u64, i64)> = events
            .iter()
            .filter(|e| e["sdo"][0] == node)
            .map(|e| {
                let w = &e["sdo"];
                (
                    w[1].as_u64().unwrap(),
                    w[2].as_u64().unwrap(),
                    w[3].as_i64().unwrap(),
                )
            })
            .collect();
        let last = |index: u64, sub: u64| {
            writes
                .iter()
                .rev()
                .find(|w| (w.0, w.1) == (index, sub))
                .map(|w| w.2)
        };
        // The profile's [connection.drives]: heartbeat 50 ms, CSP (CiA 402 mode 8), a
        // following error window of 10 000 counts, a 4 ms cycle as 60C2h's value × 10^index.
        assert_eq!(last(0x1017, 0), Some(50), "node {node}: {writes:?}");
        assert_eq!(last(0x6060, 0), Some(8));
        assert_eq!(last(0x6065, 0), Some(10_000));
        let (value, index) = (last(0x60C2, 1).unwrap(), last(0x60C2, 2).unwrap());
        assert!(
            (value as f64 * 10f64.powi(index as i32) - 0.004).abs() < 1e-12,
            "{value} × 10^{index} s"
        );
        // RPDO1 controlword + target position, TPDO1 statusword + position actual, both
        // synchronous every SYNC, on the predefined connection set's COB-IDs.
        for (communication, mapping, cob_id, entries) in [
            (0x1400, 0x1600, 0x200 + node, [0x6040_0010, 0x607A_0020]),
            (0x1800, 0x1A00, 0x180 + node, [0x6041_0010, 0x6064_0020]),
        ] {
            assert_eq!(last(mapping, 0), Some(2));
            assert_eq!(last(mapping, 1), Some(entries[0]));
            assert_eq!(last(mapping, 2), Some(entries[1]));
            assert_eq!(last(communication, 2), Some(1));
            // Valid (bit 31 clear) on its COB-ID; bit 30 may say no RTR (CiA 301).
            let written = last(communication, 1).unwrap();
            assert_eq!(written & !0x4000_0000, cob_id as i64, "{written:#x}");
            // CiA 301's procedure: the PDO made invalid (bit 31), the count zeroed, the
            // entries, the count, the PDO valid again.
            let at = |w: (u64, u64, i64)| writes.iter().position(|x| *x == w).unwrap();
            let invalid = writes
                .iter()
                .position(|w| (w.0, w.1) == (communication, 1) && w.2 & 0x8000_0000 != 0)
                .expect("the PDO made invalid first");
            let zeroed = at((mapping, 0, 0));
            let first = at((mapping, 1, entries[0]));
            let counted = at((mapping, 0, 2));
            let valid = at((communication, 1, written));
            assert!(
                invalid < zeroed && zeroed < first && first < counted && counted < valid,
                "node {node}: {writes:?}"
            );
        }
        // The power states: walked up to Operation enabled, and disabled at the end.
        let states: Vec<&str> = events
            .iter()
            .filter(|e| e["node"] == node && e["state"].is_string())
            .map(|e| e["state"].as_str().unwrap())
            .collect();
        assert_eq!(
            states,
            [
                "READY TO SWITCH ON",
                "SWITCHED ON",
                "OPERATION ENABLED",
                "SWITCH ON DISABLED"
            ],
            "node {node}"
        );
    }
    // Each SYNC's targets (X, Z, C in counts: 10 000 a mm, 2²⁰ a turn). Along the feed
    // they lie on its straight line, X − 1 mm, −Z and C/90° in step within a count; the
    // job ends at X 0, Z −1 mm, C 90°.
    let mut targets: std::collections::BTreeMap<u64, [f64; 3]> = Default::default();
    for e in events.iter().filter(|e| e["sync"].is_u64()) {
        let k = e["node"].as_u64().unwrap() as usize - 1;
        targets.entry(e["sync"].as_u64().unwrap()).or_default()[k] = e["target"].as_f64().unwrap();
    }
    let c_turn = 1_048_576.0;
    let mut along = 0;
    for [x, z, c] in targets.values() {
        if *z < 0.0 && *z > -10_000.0 {
            // How far along the feed, from C: its count is the finest of the three.
            let t = c / (c_turn / 4.0);
            assert!((x - (10_000.0 + t * 10_000.0)).abs() <= 1.0, "{x} {z} {c}");
            assert!((z + t * 10_000.0).abs() <= 1.0, "{x} {z} {c}");
            along += 1;
        }
    }
    // 1.42 mm of X and Z at 600 mm/min is 0.14 s: some 35 cycles of 4 ms.
    assert!(along >= 30, "{along} set-points along the feed");
    let end = targets.values().last().unwrap();
    assert_eq!(*end, [0.0, -10_000.0, c_turn / 4.0]);
}
