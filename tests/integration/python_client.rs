//! whirl-sim against a sender that is not whirl's: `tests/clients/grbl_stream.py`, written
//! from grbl's published character-counting method (grbl's `doc/script/stream.py`), streams
//! over a real pseudo-terminal. A third-party grbl sender must get exactly one `ok` per line
//! at grblHAL's 1024-byte RX buffer and at AVR grbl's 128 bytes, and whirl's own streamer
//! cannot show that, because it shares the authors' reading of the protocol.

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
    // Output goes to files: a pipe left unread could fill and stall the client.
    let (out_path, err_path) = (dir.path().join("stdout"), dir.path().join("stderr"));
    let mut client = Command::new("python3")
        .arg(util::root().join("tests/clients/grbl_stream.py"))
        .args([link.as_os_str(), file.as_os_str()])
        .args([OsStr::new("--rx"), OsStr::new(&client_rx.to_string())])
        .stdout(File::create(&out_path).unwrap())
        .stderr(File::create(&err_path).unwrap())
        .spawn()
        .expect("python3 runs the client");
    // The client bounds each wait by 10 s; this bounds the whole run if it still hangs.
    let deadline = Instant::now() + Duration::from_secs(120);
    let status = loop {
        if let Some(status) = client.try_wait().unwrap() {
            break status;
        }
        if Instant::now() > deadline {
            let _ = client.kill();
            let _ = client.wait();
            panic!("the Python client did not finish in 120 s");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let stdout = std::fs::read_to_string(&out_path).unwrap();
    let stderr = std::fs::read_to_string(&err_path).unwrap();
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
