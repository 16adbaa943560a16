//! The executed-path log through the real binary: a run appended after a torn write, and
//! `whirl log summary` of a log with two runs.

use crate::util;
use serde_json::Value;
use std::ffi::OsStr;
use std::path::Path;

/// `whirl dry-run` of the first linked moves of double-start's program (`program`),
/// appending to `log`. The simulator executes them and its Δ guard stops the run where the
/// groove is left uncut: whichever way it ends, the run is logged from Start to End.
fn dry_run(program: &Path, log: &Path, dir: &Path) {
    let report = dir.join("report.json");
    let o = util::whirl(&[
        OsStr::new("dry-run"),
        util::example("double-start").as_os_str(),
        OsStr::new("--program"),
        program.as_os_str(),
        OsStr::new("--log"),
        log.as_os_str(),
        OsStr::new("--report"),
        report.as_os_str(),
    ]);
    assert!(
        report.exists(),
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
}

/// `whirl log summary LOG`, parsed.
fn summary(log: &Path) -> Value {
    let o = util::whirl(&[OsStr::new("log"), OsStr::new("summary"), log.as_os_str()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap()
}

#[test]
fn a_run_after_a_torn_write_starts_on_its_own_line_and_the_summary_counts_each_run() {
    let dir = tempfile::tempdir().unwrap();
    let planned = dir.path().join("p.nc");
    let o = util::whirl(&[
        OsStr::new("plan"),
        util::example("double-start").as_os_str(),
        OsStr::new("-o"),
        planned.as_os_str(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(&planned).unwrap();
    let mut lines: Vec<&str> = text.lines().take(66).collect();
    lines.extend(["G94", "G0 X0", "M5", "M2"]);
    let program = util::write(dir.path(), "short.nc", &(lines.join("\n") + "\n"));
    let log = dir.path().join("exec.jsonl");
    dry_run(&program, &log, dir.path());
    // The disk filled up mid-event.
    let torn = br#"{"t":0.734,"event":"sta"#;
    let mut before = std::fs::read(&log).unwrap();
    before.extend_from_slice(torn);
    std::fs::write(&log, &before).unwrap();
    let torn_line = before.iter().filter(|&&b| b == b'\n').count() + 1;
    dry_run(&program, &log, dir.path());

    // Nothing was lost: the torn bytes stay, closed off by a newline, and the second run's
    // events begin on the next line.
    let after = std::fs::read(&log).unwrap();
    assert_eq!(&after[..before.len()], &before[..]);
    let rest = &after[before.len()..];
    assert_eq!(
        rest.first(),
        Some(&b'\n'),
        "{}",
        String::from_utf8_lossy(&after[before.len() - torn.len()..][..200])
    );
    let first = rest[1..].split(|&b| b == b'\n').next().unwrap();
    let first: Value = serde_json::from_slice(first).unwrap();
    assert_eq!(first["event"], "start", "{first}");

    let s = summary(&log);
    assert_eq!(s["runs"], 2, "{s:#}");
    assert_eq!(s["skipped"], 1, "{s:#}");
    assert_eq!(s["skipped_lines"][0]["line"], torn_line, "{s:#}");
    assert!(
        s["skipped_lines"][0]["reason"]
            .as_str()
            .unwrap()
            .starts_with("torn"),
        "{s:#}"
    );
    assert_eq!(s["torn_tail"], false);
    // The same lines executed by each run: none executed twice, in either run or the file.
    assert_eq!(s["executed_twice"], serde_json::json!([]), "{s:#}");
    let runs = s["per_run"].as_array().unwrap();
    assert_eq!(runs.len(), 2);
    for run in runs {
        assert_eq!(run["program"], program.display().to_string(), "{run:#}");
        assert_eq!(run["transport"], "serial", "{run:#}");
        assert_eq!(run["sent"], runs[0]["sent"], "{s:#}");
        assert!(run["executed"].as_u64().unwrap() > 0, "{run:#}");
        assert_eq!(run["executed"], runs[0]["executed"], "{s:#}");
        assert_eq!(run["executed_twice"], serde_json::json!([]), "{run:#}");
        assert_ne!(run["ended"], "interrupted", "{run:#}");
    }
    assert_eq!(
        s["executed"].as_u64(),
        Some(2 * runs[0]["executed"].as_u64().unwrap())
    );
}

#[test]
fn the_summary_says_which_run_executed_a_line_twice_and_which_run_was_interrupted() {
    let dir = tempfile::tempdir().unwrap();
    let start = r#"{"t":0.0,"event":"start","program":"p.nc","lines":2,"transport":"serial"}"#;
    let executed = |t: f64, line: usize| {
        format!(
            r#"{{"t":{t},"event":"executed","line":{line},"times":[0.2,0.8],"from":[0,0,0],"to":[1,0,0]}}"#
        )
    };
    let log = util::write(
        dir.path(),
        "exec.jsonl",
        &[
            start.to_owned(),
            executed(0.9, 1),
            executed(1.0, 2),
            r#"{"t":1.1,"event":"end","completed":true}"#.to_owned(),
            start.to_owned(),
            executed(0.9, 1),
            executed(1.0, 1),
            r#"{"t":1.1,"event":"end","completed":false,"reason":"feed hold"}"#.to_owned(),
            start.to_owned(),
            executed(0.9, 2),
            String::new(),
        ]
        .join("\n"),
    );
    let s = summary(&log);
    assert_eq!(s["runs"], 3, "{s:#}");
    assert_eq!(s["executed"], 5, "{s:#}");
    assert_eq!(s["executed_twice"], serde_json::json!([1]), "{s:#}");
    let twice: Vec<&Value> = s["per_run"]
        .as_array()
        .unwrap()
        .iter()
        .map(|run| &run["executed_twice"])
        .collect();
    assert_eq!(
        twice,
        [
            &serde_json::json!([]),
            &serde_json::json!([1]),
            &serde_json::json!([])
        ]
    );
    let ended: Vec<(&Value, &Value)> = s["per_run"]
        .as_array()
        .unwrap()
        .iter()
        .map(|run| (&run["ended"], &run["reason"]))
        .collect();
    assert_eq!(
        ended,
        [
            (&Value::from("completed"), &Value::Null),
            (&Value::from("stopped"), &Value::from("feed hold")),
            (&Value::from("interrupted"), &Value::Null),
        ]
    );
    assert_eq!(s["completed"], Value::Null, "the last run has no End");
}

/// `whirl ARGS…` under a 1.5 GB address-space limit (`ulimit -v`), as the fault matrix ran
/// it: a whirl that read an endless "log" would fail to allocate (and abort on a signal)
/// rather than take the host's memory.
fn whirl_capped(args: &[&OsStr]) -> std::process::Output {
    std::process::Command::new("sh")
        .arg("-c")
        .arg("ulimit -v 1500000 && exec \"$0\" \"$@\"")
        .arg(env!("CARGO_BIN_EXE_whirl"))
        .args(args)
        .env("WHIRL_DB", util::records_db())
        .output()
        .expect("sh runs")
}

#[test]
fn a_log_that_is_a_device_or_a_pipe_is_refused_before_anything_runs() {
    let dir = tempfile::tempdir().unwrap();
    let pipe = dir.path().join("pipe");
    assert!(std::process::Command::new("mkfifo")
        .arg(&pipe)
        .status()
        .unwrap()
        .success());
    let job = util::example("double-start");
    let program = util::write(dir.path(), "p.nc", "G21 G90 G94\nG0 X1 Z0 C0\nM2\n");
    // No port is there: a stream that got past its log would fail on the port instead.
    let port = dir.path().join("no-port");
    for (log, kind) in [
        (Path::new("/dev/full"), "a character device"),
        (Path::new("/dev/zero"), "a character device"),
        (pipe.as_path(), "a named pipe"),
    ] {
        let runs = [
            vec![OsStr::new("dry-run"), job.as_os_str()],
            vec![
                OsStr::new("stream"),
                program.as_os_str(),
                OsStr::new("--port"),
                port.as_os_str(),
            ],
        ];
        for mut args in runs {
            args.extend([OsStr::new("--log"), log.as_os_str()]);
            let o = whirl_capped(&args);
            let stderr = String::from_utf8_lossy(&o.stderr);
            assert_eq!(o.status.code(), Some(1), "{args:?}: {stderr}");
            assert!(
                stderr.contains(&format!("{} (the log (--log))", log.display()))
                    && stderr.contains(&format!("it is {kind}, not a regular file")),
                "{args:?}: {stderr}"
            );
            assert!(!stderr.contains("no-port"), "{args:?}: {stderr}");
        }
    }
    assert!(!port.exists());
}
