//! Opening the port: whirl-sim leaves its power-up banner waiting in the terminal as a
//! board leaves it in its port, or with `--reset-on-open` boots when the port is opened,
//! dropping what arrives meanwhile, and prints its banner after; `whirl stream` streams every
//! line to either.

use crate::util::{self, Sim};
use std::ffi::OsStr;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

const BANNER: &str = "\r\nGrblHAL 1.1f ['$' or '$HELP' for help]\r\n";

/// whirl-sim on a pseudo-terminal at `link`, 50 times real time, with `args`.
fn sim(link: &Path, args: &[&str]) -> Sim {
    let mut all: Vec<&OsStr> = vec![OsStr::new("--time-scale"), OsStr::new("50")];
    all.extend(args.iter().map(OsStr::new));
    Sim::serving(OsStr::new("--pty"), link, &all)
}

/// The terminal at `link`, opened as a client opens a port: nothing cleared; closed when
/// dropped.
fn open(link: &Path) -> Box<dyn tokio_serial::SerialPort> {
    tokio_serial::new(link.to_string_lossy(), 115_200)
        .timeout(Duration::from_millis(20))
        .open()
        .expect("the terminal opens")
}

/// What arrives within `within`, up to and including the first `end`.
fn read_until(port: &mut Box<dyn tokio_serial::SerialPort>, end: &str, within: Duration) -> String {
    let deadline = Instant::now() + within;
    let mut text = Vec::new();
    let mut byte = [0u8; 1];
    while !text.ends_with(end.as_bytes()) && Instant::now() < deadline {
        if let Ok(1) = port.read(&mut byte) {
            text.push(byte[0]);
        }
    }
    String::from_utf8_lossy(&text).into_owned()
}

/// A short planned program: its lead-in and first linked moves, then the retract.
fn program(dir: &Path) -> (PathBuf, usize) {
    let planned = dir.join("p.nc");
    let o = util::whirl(&[
        OsStr::new("plan"),
        util::example("double-start").as_os_str(),
        OsStr::new("-o"),
        planned.as_os_str(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(&planned).unwrap();
    let mut lines: Vec<&str> = text.lines().take(46).collect();
    lines.extend(["G94", "G0 X0", "M5", "M2"]);
    let path = util::write(dir, "short.nc", &(lines.join("\n") + "\n"));
    (path, lines.len())
}

/// `whirl stream` of `program` to the terminal at `link`: every line sent and
/// acknowledged, once, with no error, alarm or reset, and the run completed.
fn streams_every_line(program: &Path, lines: usize, link: &Path, log: &Path) {
    let o = util::whirl(&[
        OsStr::new("stream"),
        program.as_os_str(),
        // Written here, not planned: it carries no provenance.
        OsStr::new("--no-provenance-check"),
        OsStr::new("--port"),
        link.as_os_str(),
        OsStr::new("--log"),
        log.as_os_str(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let read = whirl::log::read(log).unwrap();
    let s = whirl::log::Summary::of(&read);
    assert_eq!((s.sent, s.acked, s.errors, s.alarms), (lines, lines, 0, 0));
    assert_eq!(s.completed, Some(true));
    let reset = read
        .records
        .iter()
        .any(|r| matches!(&r.event, whirl::log::Event::Message { text } if text.contains("reset")));
    assert!(!reset, "no reset: {:?}", read.records);
}

#[test]
fn the_power_up_banner_waits_for_the_first_client() {
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("grbl");
    let _sim = sim(&link, &[]);
    // Long after power-up, the first client to open the port finds the banner there.
    std::thread::sleep(Duration::from_millis(300));
    let mut port = open(&link);
    assert_eq!(
        read_until(&mut port, BANNER, Duration::from_secs(5)),
        BANNER
    );
}

#[test]
fn whirl_stream_streams_every_line_to_a_controller_whose_banner_waits() {
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("grbl");
    let _sim = sim(&link, &[]);
    let (program, lines) = program(dir.path());
    streams_every_line(&program, lines, &link, &dir.path().join("exec.jsonl"));
}

#[test]
fn a_board_that_resets_on_open_drops_what_comes_while_it_boots() {
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("grbl");
    let _sim = sim(&link, &["--reset-on-open", "--boot-time", "0.5"]);
    for _ in 0..2 {
        let opened = Instant::now();
        let mut port = open(&link);
        // Sent at once, while it boots: lost, so no answer, no move.
        port.write_all(b"?G0 X5\n").unwrap();
        assert_eq!(
            read_until(&mut port, BANNER, Duration::from_secs(5)),
            BANNER
        );
        assert!(opened.elapsed() >= Duration::from_millis(500));
        port.write_all(b"?").unwrap();
        let report = read_until(&mut port, ">\r\n", Duration::from_secs(5));
        assert!(
            report.starts_with("<Idle|MPos:0.000,0.000,0.000,0.000|"),
            "{report}"
        );
        // Closing the port and opening it again resets the board again (a client does
        // not reopen within microseconds; the simulator sees the close as it reads).
        drop(port);
        std::thread::sleep(Duration::from_millis(100));
    }
}

#[test]
fn whirl_stream_streams_every_line_to_a_board_that_resets_on_open() {
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("grbl");
    let _sim = sim(&link, &["--reset-on-open", "--boot-time", "0.5"]);
    let (program, lines) = program(dir.path());
    // Twice: each opening boots the board again.
    for run in ["first.jsonl", "second.jsonl"] {
        streams_every_line(&program, lines, &link, &dir.path().join(run));
    }
}
