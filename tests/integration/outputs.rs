//! What the command lines may write, and how they end, through the real binaries: an output
//! that is a device, a named pipe, a socket, a directory, a symbolic link, in no folder, one
//! of the run's own inputs or named twice is refused before anything is written, naming the
//! option, the path and why, and every file is left as it was; whirl-sim's `--pty` replaces
//! nothing but its own stale link and removes its link when it stops, idle or signalled; a
//! closed standard output ends a command quietly with the work's exit code, a full one is an
//! error; every number of both command lines is checked by clap, naming the option.

use crate::util;
use std::ffi::OsStr;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

fn os(s: &str) -> &OsStr {
    OsStr::new(s)
}

/// The names in `dir`, sorted.
fn listing(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// `whirl ARGS…` that must be refused (exit 1, no panic) with a message naming `path` and
/// the `option` that gave it, and saying `why`.
fn refused(args: &[&OsStr], path: &Path, option: &str, why: &str) -> String {
    let o = util::whirl(args);
    let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(
        o.status.code(),
        Some(1),
        "{args:?} must be refused\nstdout: {}\nstderr: {stderr}",
        String::from_utf8_lossy(&o.stdout)
    );
    assert!(stderr.starts_with("error: refusing"), "{args:?}: {stderr}");
    assert!(
        stderr.contains(&path.display().to_string())
            && stderr.contains(option)
            && stderr.contains(why),
        "{args:?}: the message must name {} and {option}, and say {why:?}: {stderr}",
        path.display()
    );
    assert!(!stderr.contains("panicked"), "{stderr}");
    stderr
}

/// A copy of the double-start example (job and profile points) in `dir`.
fn job_in(dir: &Path) -> (PathBuf, PathBuf) {
    let example = util::example("double-start");
    let points = dir.join("profile.csv");
    std::fs::copy(example.with_file_name("profile.csv"), &points).unwrap();
    let job = dir.join("job.toml");
    std::fs::copy(&example, &job).unwrap();
    (job, points)
}

/// A short executed-path log in `dir`.
fn log_in(dir: &Path) -> PathBuf {
    util::write(
        dir,
        "exec.jsonl",
        concat!(
            r#"{"t":0.0,"event":"start","program":"p.nc","lines":1,"transport":"serial"}"#,
            "\n",
            r#"{"t":0.4,"event":"status","state":"Run","pos":[0.5,0.0,0.0]}"#,
            "\n",
            r#"{"t":1.0,"event":"end","completed":true}"#,
            "\n",
        ),
    )
}

/// Every command that writes a file, told to write it to `special` (a device, a named pipe,
/// a socket): each is refused, naming it and saying it is `what`, and it is still what it
/// was afterwards.
fn every_command_refuses(special: &Path, what: &str) {
    let dir = tempfile::tempdir().unwrap();
    let (job, _) = job_in(dir.path());
    let program = util::write(dir.path(), "p.nc", "G21 G90 G94\nG0 X1 Z0 C0\n");
    let log = log_in(dir.path());
    let out = dir.path().join("out");
    let kind = || std::fs::symlink_metadata(special).unwrap().file_type();
    let before = kind();
    let d = special.as_os_str();
    let (j, p, o) = (job.as_os_str(), program.as_os_str(), out.as_os_str());
    let sweep = [
        "sweep",
        "paraboloid",
        "--a",
        "-0.05",
        "--b",
        "7.2",
        "--radius",
        "20",
        "--pitch",
        "20",
        "-o",
    ]
    .map(os);
    let cases: Vec<(Vec<&OsStr>, &str)> = vec![
        (vec![os("plan"), j, os("-o"), d], "(-o)"),
        (
            vec![os("plan"), j, os("-o"), o, os("--report"), d],
            "(--report)",
        ),
        (
            vec![os("verify"), p, os("--job"), j, os("--report"), d],
            "(--report)",
        ),
        (
            vec![
                os("verify"),
                p,
                os("--job"),
                j,
                os("--report"),
                o,
                os("--svg"),
                d,
            ],
            "(--svg)",
        ),
        ([&sweep[..], &[d]].concat(), "(-o)"),
        (vec![os("dry-run"), j, os("--report"), d], "(--report)"),
        (
            vec![os("log"), os("plot"), log.as_os_str(), os("-o"), d],
            "(-o)",
        ),
    ];
    for (args, option) in cases {
        refused(&args, special, option, what);
        assert_eq!(kind(), before, "{args:?} replaced {}", special.display());
    }
    assert!(!out.exists(), "nothing written");
}

#[test]
fn a_device_as_an_output_is_refused_by_every_command() {
    let dir = tempfile::tempdir().unwrap();
    // Nodes of its own, like /dev/full (char 1, 7) and /dev/loop0 (block 7, 0): making
    // them needs root, and so does replacing one, which a regression would do.
    let (full, loop0) = (dir.path().join("full"), dir.path().join("loop0"));
    let made = Command::new("mknod")
        .arg(&full)
        .args(["c", "1", "7"])
        .output()
        .and_then(|o| {
            Command::new("mknod")
                .arg(&loop0)
                .args(["b", "7", "0"])
                .output()
                .map(|b| (o, b))
        });
    match made {
        Ok((c, b)) if c.status.success() && b.status.success() => {
            every_command_refuses(&full, "a character device");
            every_command_refuses(&loop0, "a block device");
        }
        // Without root, /dev/null: a run that cannot write in /dev could not replace it
        // even if the refusal were gone (the test still fails then, on the message).
        made if tempfile::tempfile_in("/dev").is_err() => {
            eprintln!("cannot make device nodes ({made:?}); testing on /dev/null");
            every_command_refuses(Path::new("/dev/null"), "a character device");
        }
        made => eprintln!(
            "skipped: cannot make device nodes ({made:?}), and /dev is writable here, so a \
             regression would replace /dev/null"
        ),
    }
}

#[test]
fn a_named_pipe_or_a_socket_as_an_output_is_refused_by_every_command() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("fifo");
    let made = Command::new("mkfifo").arg(&fifo).status().unwrap();
    assert!(made.success());
    every_command_refuses(&fifo, "a named pipe");
    let socket = dir.path().join("socket");
    let _listener = std::os::unix::net::UnixListener::bind(&socket).unwrap();
    every_command_refuses(&socket, "a socket");
}

/// `whirl plan JOB -o OUTPUT --report REPORT`.
fn plan_args<'a>(job: &'a Path, output: &'a Path, report: &'a Path) -> Vec<&'a OsStr> {
    vec![
        os("plan"),
        job.as_os_str(),
        os("-o"),
        output.as_os_str(),
        os("--report"),
        report.as_os_str(),
    ]
}

#[test]
fn a_directory_as_the_report_leaves_the_program_as_it_was() {
    let dir = tempfile::tempdir().unwrap();
    let (job, _) = job_in(dir.path());
    let keep = util::write(dir.path(), "keep.nc", "the program to keep\n");
    let adir = dir.path().join("adir");
    std::fs::create_dir(&adir).unwrap();
    let plan = |report| plan_args(&job, &keep, report);
    let kept = || {
        assert_eq!(
            std::fs::read_to_string(&keep).unwrap(),
            "the program to keep\n"
        );
        assert_eq!(
            listing(dir.path()),
            ["adir", "job.toml", "keep.nc", "profile.csv"],
            "no temporary file left"
        );
        assert!(listing(&adir).is_empty());
    };
    let slashed = PathBuf::from(format!("{}/", adir.display()));
    refused(&plan(&adir), &adir, "(--report)", "it is a directory");
    kept();
    refused(
        &plan(&slashed),
        &adir,
        "(--report)",
        "it names a directory, not a file",
    );
    kept();
    // A folder that does not exist, or is no folder, is said before anything is computed.
    let nowhere = dir.path().join("no/such/r.json");
    refused(
        &plan(&nowhere),
        &nowhere,
        "(--report)",
        "no/such does not exist",
    );
    kept();
    let in_a_file = keep.join("r.json");
    refused(
        &plan(&in_a_file),
        &in_a_file,
        "(--report)",
        "keep.nc is not a directory",
    );
    kept();
    // A name the file system cannot hold (255 bytes at most).
    let too_long = dir.path().join("r".repeat(300));
    refused(
        &plan(&too_long),
        &too_long,
        "(--report)",
        "cannot look at it: File name too long",
    );
    kept();
    // And existing files are replaced, both, with nothing left beside them.
    let report = util::write(dir.path(), "r.json", "old report");
    let o = util::whirl(&plan(&report));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(std::fs::read_to_string(&keep).unwrap().contains("G93"));
    assert!(std::fs::read_to_string(&report)
        .unwrap()
        .contains("segments"));
    assert_eq!(
        listing(dir.path()),
        ["adir", "job.toml", "keep.nc", "profile.csv", "r.json"]
    );
}

#[test]
fn a_symbolic_link_as_an_output_is_refused_and_left_with_its_target() {
    let dir = tempfile::tempdir().unwrap();
    let (job, _) = job_in(dir.path());
    let target = util::write(dir.path(), "target.nc", "the target\n");
    let link = dir.path().join("link.nc");
    std::os::unix::fs::symlink(&target, &link).unwrap();
    // Dangling, too: the rename would put a file where the link is.
    let dangling = dir.path().join("dangling.nc");
    std::os::unix::fs::symlink(dir.path().join("nowhere.nc"), &dangling).unwrap();
    for output in [&link, &dangling] {
        refused(
            &[os("plan"), job.as_os_str(), os("-o"), output.as_os_str()],
            output,
            "(-o)",
            "it is a symbolic link",
        );
        assert!(std::fs::symlink_metadata(output)
            .unwrap()
            .file_type()
            .is_symlink());
    }
    assert_eq!(std::fs::read_to_string(&target).unwrap(), "the target\n");
    assert!(!dir.path().join("nowhere.nc").exists());
}

#[test]
fn the_same_file_twice_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let (job, _) = job_in(dir.path());
    let f = dir.path().join("f");
    // The same file, spelled otherwise: through `.`, and through a link to its folder.
    let dotted = dir.path().join(".").join("f");
    let alias = dir.path().join("alias");
    std::os::unix::fs::symlink(dir.path(), &alias).unwrap();
    let aliased = alias.join("f");
    for report in [&f, &dotted, &aliased] {
        refused(
            &[
                os("plan"),
                job.as_os_str(),
                os("-o"),
                f.as_os_str(),
                os("--report"),
                report.as_os_str(),
            ],
            report,
            "(--report)",
            "-o names the same file",
        );
        assert!(!f.exists(), "nothing written");
    }
    // Two names of one file: each would be replaced apart, the link between them broken.
    let old = util::write(dir.path(), "f", "old\n");
    let hard = dir.path().join("hard");
    std::fs::hard_link(&old, &hard).unwrap();
    refused(
        &[
            os("plan"),
            job.as_os_str(),
            os("-o"),
            f.as_os_str(),
            os("--report"),
            hard.as_os_str(),
        ],
        &hard,
        "(--report)",
        "-o names the same file",
    );
    assert_eq!(std::fs::read_to_string(&f).unwrap(), "old\n");
    std::fs::remove_file(&hard).unwrap();
    std::fs::remove_file(&f).unwrap();
    let program = util::write(dir.path(), "p.nc", "G21 G90 G94\nG0 X1 Z0 C0\n");
    refused(
        &[
            os("verify"),
            program.as_os_str(),
            os("--job"),
            job.as_os_str(),
            os("--report"),
            f.as_os_str(),
            os("--svg"),
            f.as_os_str(),
        ],
        &f,
        "(--svg)",
        "--report names the same file",
    );
    assert_eq!(
        listing(dir.path()),
        ["alias", "job.toml", "p.nc", "profile.csv"]
    );
}

#[test]
fn an_input_of_the_run_is_refused_as_an_output_and_left_as_it_was() {
    let dir = tempfile::tempdir().unwrap();
    let (job, points) = job_in(dir.path());
    let machine = dir.path().join("machine.toml");
    std::fs::copy(util::root().join("machine-profiles/sim.toml"), &machine).unwrap();
    let program = util::write(dir.path(), "p.nc", "G21 G90 G94\nG0 X1 Z0 C0\n");
    let log = log_in(dir.path());
    let out = dir.path().join("out.nc");
    let before: Vec<(PathBuf, Vec<u8>)> = [&job, &points, &machine, &program, &log]
        .iter()
        .map(|p| (p.to_path_buf(), std::fs::read(p).unwrap()))
        .collect();
    let j = job.as_os_str();
    let cases: Vec<(Vec<&OsStr>, &Path, &str, &str)> = vec![
        (
            vec![os("plan"), j, os("-o"), j],
            &job,
            "(-o)",
            "the job file this run reads",
        ),
        (
            vec![
                os("plan"),
                j,
                os("-o"),
                out.as_os_str(),
                os("--report"),
                points.as_os_str(),
            ],
            &points,
            "(--report)",
            "the job's profile points this run reads",
        ),
        (
            vec![
                os("plan"),
                j,
                os("--machine"),
                machine.as_os_str(),
                os("-o"),
                machine.as_os_str(),
            ],
            &machine,
            "(-o)",
            "the machine profile (--machine) this run reads",
        ),
        (
            vec![
                os("verify"),
                program.as_os_str(),
                os("--job"),
                j,
                os("--report"),
                program.as_os_str(),
            ],
            &program,
            "(--report)",
            "the program this run reads",
        ),
        (
            vec![
                os("dry-run"),
                j,
                os("--program"),
                program.as_os_str(),
                os("--report"),
                program.as_os_str(),
            ],
            &program,
            "(--report)",
            "the program (--program) this run reads",
        ),
        (
            vec![
                os("dry-run"),
                j,
                os("--log"),
                log.as_os_str(),
                os("--report"),
                log.as_os_str(),
            ],
            &log,
            "(--report)",
            "the log (--log) this run appends to",
        ),
        (
            vec![os("dry-run"), j, os("--log"), j],
            &job,
            "(--log)",
            "it is the job file this run reads",
        ),
        (
            vec![
                os("stream"),
                j,
                os("--port"),
                os("/nowhere"),
                os("--log"),
                points.as_os_str(),
            ],
            &points,
            "(--log)",
            "it is the job's profile points this run reads",
        ),
        (
            vec![
                os("log"),
                os("plot"),
                log.as_os_str(),
                os("-o"),
                log.as_os_str(),
            ],
            &log,
            "(-o)",
            "the log this run reads",
        ),
        (
            vec![
                os("log"),
                os("plot"),
                log.as_os_str(),
                os("--job"),
                j,
                os("-o"),
                points.as_os_str(),
            ],
            &points,
            "(-o)",
            "the job's profile points this run reads",
        ),
    ];
    for (args, path, option, why) in cases {
        refused(&args, path, option, why);
        for (path, bytes) in &before {
            assert_eq!(
                &std::fs::read(path).unwrap(),
                bytes,
                "{args:?} changed {path:?}"
            );
        }
    }
    assert!(!out.exists());
}

/// `whirl ARGS…` with its standard output closed before it writes a byte (`| true`): it
/// must end as the work did, saying nothing of the pipe.
fn with_stdout_closed(args: &[&OsStr]) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_whirl"))
        .env("WHIRL_DB", util::records_db())
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let o = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        !stderr.contains("panicked") && !stderr.contains("Broken pipe") && stderr.is_empty(),
        "{args:?}: {stderr}"
    );
    o
}

#[test]
fn a_closed_standard_output_ends_the_command_quietly_with_the_works_exit_code() {
    let dir = tempfile::tempdir().unwrap();
    let job = util::example("double-start");
    let (program, report) = (dir.path().join("x.nc"), dir.path().join("r.json"));
    // whirl plan JOB -o x.nc | true: planned and written, exit 0.
    let o = with_stdout_closed(&[os("plan"), job.as_os_str(), os("-o"), program.as_os_str()]);
    assert_eq!(o.status.code(), Some(0));
    assert!(std::fs::read_to_string(&program).unwrap().contains("G93"));
    // whirl dry-run JOB | head -1: run to the end within Δ, exit 0.
    let o = with_stdout_closed(&[
        os("dry-run"),
        job.as_os_str(),
        os("--report"),
        report.as_os_str(),
    ]);
    assert_eq!(o.status.code(), Some(0));
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(r["within_delta"], true);
    // A program measured beyond Δ still says so by its exit code.
    let coarse = util::coarse_program(&job, dir.path());
    let o = with_stdout_closed(&[
        os("verify"),
        coarse.as_os_str(),
        os("--job"),
        job.as_os_str(),
        os("--report"),
        report.as_os_str(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    let log = log_in(dir.path());
    let o = with_stdout_closed(&[os("log"), os("summary"), log.as_os_str()]);
    assert_eq!(o.status.code(), Some(0));
    let section = dir.path().join("s.csv");
    let o = with_stdout_closed(&[
        os("sweep"),
        os("paraboloid"),
        os("--a"),
        os("-0.05"),
        os("--b"),
        os("7.2"),
        os("--radius"),
        os("20"),
        os("--pitch"),
        os("20"),
        os("-o"),
        section.as_os_str(),
    ]);
    assert_eq!(o.status.code(), Some(0));
    assert!(section.exists());
}

#[test]
fn a_full_standard_output_is_an_error_said_once() {
    let Ok(full) = std::fs::OpenOptions::new().write(true).open("/dev/full") else {
        eprintln!("skipped: no /dev/full to write to");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let log = log_in(dir.path());
    let o = Command::new(env!("CARGO_BIN_EXE_whirl"))
        .env("WHIRL_DB", util::records_db())
        .args([os("log"), os("summary"), log.as_os_str()])
        .stdout(full)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(
        String::from_utf8_lossy(&o.stderr),
        "error: cannot write to standard output: No space left on device (os error 28)\n"
    );
}

/// `whirl ARGS…` refused by its command line naming `option`, before anything runs: exit 2
/// with the command line's "invalid value" (a run that ends beyond Δ exits 2 too, and
/// says nothing of the kind).
fn bad_number(args: &[&OsStr], option: &str) {
    let o = util::whirl(args);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {stderr}");
    assert!(
        stderr.contains("invalid value") && stderr.contains(option),
        "{args:?}: {stderr}"
    );
    assert!(!stderr.contains("panicked"), "{stderr}");
}

#[test]
fn every_number_of_whirl_is_checked_naming_the_option() {
    let dir = tempfile::tempdir().unwrap();
    let program = util::write(dir.path(), "p.nc", "G21 G90 G94\nG0 X1 Z0 C0\n");
    let log = dir.path().join("exec.jsonl");
    let job = util::example("double-start");
    // A port, so that nothing but the number stops the run before the log is opened.
    let port = dir.path().join("grbl0");
    let stream = |option: &'static str, value: &'static str| {
        vec![
            os("stream"),
            program.as_os_str(),
            os("--port"),
            port.as_os_str(),
            os("--log"),
            log.as_os_str(),
            os(option),
            os(value),
        ]
    };
    let dry_run = |option: &'static str, value: &'static str| {
        vec![os("dry-run"), job.as_os_str(), os(option), os(value)]
    };
    let mut cases: Vec<(Vec<&OsStr>, &str)> = Vec::new();
    for value in ["nan", "inf", "1e30", "0", "-1"] {
        cases.push((stream("--stall-timeout", value), "--stall-timeout"));
    }
    cases.push((stream("--baud", "0"), "--baud"));
    cases.push((stream("--resume-at", "0"), "--resume-at"));
    for value in ["nan", "inf", "1e308", "-1"] {
        cases.push((dry_run("--time-scale", value), "--time-scale"));
    }
    cases.push((dry_run("--baud", "0"), "--baud"));
    for value in ["0", "1", "1e9"] {
        cases.push((dry_run("--rx", value), "--rx"));
    }
    let sweep = |option: &'static str, value: &'static str| {
        let mut args = vec![
            os("sweep"),
            os("paraboloid"),
            os("--a"),
            os("-0.05"),
            os("--b"),
            os("7.2"),
            os("--radius"),
            os("20"),
            os("--pitch"),
            os("20"),
            os("-o"),
            os("/nowhere/s.csv"),
        ];
        let at = args.iter().position(|a| *a == os(option));
        match at {
            Some(at) => args[at + 1] = os(value),
            None => args.extend([os(option), os(value)]),
        }
        args
    };
    for (option, value) in [
        ("--a", "nan"),
        ("--b", "inf"),
        ("--radius", "-inf"),
        ("--pitch", "nan"),
        ("--accuracy", "nan"),
        ("--accuracy", "0"),
        ("--accuracy", "1e-10"),
    ] {
        cases.push((sweep(option, value), option));
    }
    for (args, option) in cases {
        bad_number(&args, option);
    }
    assert!(!log.exists(), "nothing was run");
}

/// whirl-sim with `args`, given up to `limit` to end by itself (it is killed then).
fn sim_run(args: &[&OsStr], limit: Duration) -> (Option<i32>, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_whirl-sim"))
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let code = wait_for(&mut child, limit);
    let mut stderr = String::new();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut stderr)
        .unwrap();
    (code, stderr)
}

/// The exit code of `child` if it ends within `limit`; `None` (and killed) if not.
fn wait_for(child: &mut Child, limit: Duration) -> Option<i32> {
    let deadline = Instant::now() + limit;
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            return status.code();
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            return None;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn every_number_of_whirl_sim_is_checked_naming_the_option() {
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("grbl0");
    let cases: [(&str, &str, &str); 13] = [
        ("--pty", "--time-scale", "nan"),
        ("--pty", "--time-scale", "1e308"),
        ("--pty", "--time-scale", "-1"),
        ("--pty", "--baud", "0"),
        ("--pty", "--rx", "0"),
        ("--pty", "--rx", "1"),
        ("--pty", "--idle-exit", "nan"),
        ("--pty", "--idle-exit", "inf"),
        ("--pty", "--idle-exit", "-1"),
        ("--can-slcan", "--can-cycle-us", "249"),
        ("--can-slcan", "--can-counts", "10000,nan,10000"),
        ("--can-slcan", "--can-counts", "10000,0,10000"),
        ("--modbus-rtu", "--time-scale", "inf"),
    ];
    for (front, option, value) in cases {
        let args = [os(front), link.as_os_str(), os(option), os(value)];
        let (code, stderr) = sim_run(&args, Duration::from_secs(10));
        assert_eq!(code, Some(2), "{args:?}: {stderr}");
        assert!(
            stderr.contains("invalid value") && stderr.contains(option),
            "{args:?}: {stderr}"
        );
        assert!(
            std::fs::symlink_metadata(&link).is_err(),
            "no terminal made"
        );
    }
}

#[test]
fn whirl_sim_refuses_a_pty_path_that_is_not_its_own_link() {
    let dir = tempfile::tempdir().unwrap();
    let file = util::write(dir.path(), "keep", "not a terminal\n");
    let elsewhere = dir.path().join("elsewhere");
    std::os::unix::fs::symlink(&file, &elsewhere).unwrap();
    let folder = dir.path().join("folder");
    std::fs::create_dir(&folder).unwrap();
    for (flag, path, what) in [
        ("--pty", &file, "a file"),
        ("--pty", &elsewhere, "a symbolic link to"),
        ("--pty", &folder, "a directory"),
        ("--modbus-rtu", &file, "a file"),
        ("--can-slcan", &file, "a file"),
    ] {
        let args = [os(flag), path.as_os_str(), os("--idle-exit"), os("2")];
        let (code, stderr) = sim_run(&args, Duration::from_secs(10));
        assert_eq!(code, Some(1), "{args:?}: {stderr}");
        assert!(
            stderr.contains(&path.display().to_string())
                && stderr.contains(what)
                && stderr.contains("/dev/pts/N")
                && stderr.contains("earlier run"),
            "{args:?}: {stderr}"
        );
    }
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "not a terminal\n");
    assert_eq!(std::fs::read_link(&elsewhere).unwrap(), file);
    assert!(folder.is_dir());
    // A second whirl-sim on the first one's path: its terminal is still open.
    let link = dir.path().join("grbl0");
    let mut first = serving(&link);
    let device = std::fs::read_link(&link).unwrap();
    let args = [os("--pty"), link.as_os_str(), os("--idle-exit"), os("2")];
    let (code, stderr) = sim_run(&args, Duration::from_secs(10));
    assert_eq!(code, Some(1), "{stderr}");
    assert!(
        stderr.contains(&format!(
            "refusing --pty {}: a link to {}, a terminal still open",
            link.display(),
            device.display()
        )),
        "{stderr}"
    );
    assert_eq!(std::fs::read_link(&link).unwrap(), device);
    let _ = first.kill();
    let _ = first.wait();
}

/// A whirl-sim serving on a pseudo-terminal linked at `link`, once the link is there.
fn serving(link: &Path) -> Child {
    let mut child = Command::new(env!("CARGO_BIN_EXE_whirl-sim"))
        .args([os("--pty"), link.as_os_str(), os("--idle-exit"), os("0")])
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let deadline = Instant::now() + Duration::from_secs(10);
    while std::fs::symlink_metadata(link).is_err() {
        if Instant::now() > deadline || child.try_wait().unwrap().is_some() {
            let _ = child.kill();
            panic!("whirl-sim made no link at {}", link.display());
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child
}

#[test]
fn whirl_sim_removes_its_link_when_stopped_by_a_signal() {
    let dir = tempfile::tempdir().unwrap();
    for (signal, number) in [("INT", 2), ("TERM", 15), ("HUP", 1)] {
        let link = dir.path().join(format!("grbl-{signal}"));
        let mut child = serving(&link);
        let sent = Command::new("kill")
            .args([format!("-{signal}"), child.id().to_string()])
            .status()
            .unwrap();
        assert!(sent.success());
        let code = wait_for(&mut child, Duration::from_secs(10));
        // Ended as a shell reports a command a signal ended: 128 + its number.
        assert_eq!(code, Some(128 + number), "SIG{signal}");
        assert!(
            std::fs::symlink_metadata(&link).is_err(),
            "SIG{signal}: the link is removed"
        );
    }
}

#[test]
fn whirl_sim_replaces_its_own_earlier_link_and_removes_its_link_when_it_stops() {
    let dir = tempfile::tempdir().unwrap();
    for flag in ["--pty", "--modbus-rtu"] {
        let link = dir.path().join(format!("link{flag}"));
        // Left by a whirl-sim that was killed: a link to a terminal long gone.
        std::os::unix::fs::symlink("/dev/pts/987654", &link).unwrap();
        let args = [os(flag), link.as_os_str(), os("--idle-exit"), os("1")];
        let (code, stderr) = sim_run(&args, Duration::from_secs(20));
        assert_eq!(
            code,
            Some(0),
            "{flag}: stopped on its own when idle: {stderr}"
        );
        assert!(
            stderr.contains("replacing") && stderr.contains("/dev/pts/987654"),
            "{flag}: {stderr}"
        );
        assert!(
            stderr.contains(&format!("serving on {} -> /dev/pts/", link.display())),
            "{flag}: {stderr}"
        );
        assert!(
            std::fs::symlink_metadata(&link).is_err(),
            "{flag}: the link is removed when whirl-sim stops"
        );
    }
    // --idle-exit 0: never stops by itself.
    let link = dir.path().join("forever");
    let mut child = Command::new(env!("CARGO_BIN_EXE_whirl-sim"))
        .args([os("--pty"), link.as_os_str(), os("--idle-exit"), os("0")])
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    assert_eq!(wait_for(&mut child, Duration::from_millis(1500)), None);
}
