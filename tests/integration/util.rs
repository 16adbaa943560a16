//! Helpers shared by the integration tests: paths, the CLI runner, temp dirs.

use std::path::{Path, PathBuf};
use std::process::Output;

/// The repository root.
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// An example job file.
pub fn example(name: &str) -> PathBuf {
    root().join("examples").join(name).join("job.toml")
}

/// Every example job.
pub fn examples() -> Vec<PathBuf> {
    let mut jobs: Vec<PathBuf> = std::fs::read_dir(root().join("examples"))
        .expect("examples/")
        .filter_map(|e| e.ok())
        .map(|e| e.path().join("job.toml"))
        .filter(|p| p.exists())
        .collect();
    jobs.sort();
    jobs
}

/// The run records of every `whirl` a test starts (`WHIRL_DB`): a SQLite file in the
/// build's temporary folder, never the user's own (`~/.local/share/whirl/runs.sqlite`).
/// The tests share it, as concurrent runs on a shop's host do: the store waits its turn
/// to write (SQLite's busy timeout). A test that looks at records makes a database of its
/// own (`tests/integration/records.rs`).
pub fn records_db() -> PathBuf {
    Path::new(env!("CARGO_TARGET_TMPDIR")).join("whirl-test-runs.sqlite")
}

/// Run the `whirl` binary with `args`.
pub fn whirl(args: &[&std::ffi::OsStr]) -> Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_whirl"))
        .env("WHIRL_DB", records_db())
        .args(args)
        .output()
        .expect("the whirl binary runs")
}

/// Write `text` to `dir/name` and return the path.
pub fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).expect("write a test file");
    path
}

/// The double-start example planned (its provenance header kept), cut to the lead-in and
/// 60 linked moves, then a retract: a real program that streams in a second. Its path in
/// `dir` and its lines.
pub fn short_planned_program(dir: &Path) -> (PathBuf, Vec<String>) {
    let planned = dir.join("p.nc");
    let o = whirl(&[
        std::ffi::OsStr::new("plan"),
        example("double-start").as_os_str(),
        std::ffi::OsStr::new("-o"),
        planned.as_os_str(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(&planned).unwrap();
    let header = text
        .lines()
        .take_while(|l| l.contains("whirl provenance"))
        .count();
    let mut lines: Vec<String> = text.lines().take(header + 66).map(str::to_owned).collect();
    lines.extend(["G94", "G0 X0", "M5", "M2"].map(str::to_owned));
    let program = write(dir, "short.nc", &(lines.join("\n") + "\n"));
    (program, lines)
}

/// A program line without its N word (grblHAL programs number every line).
pub fn block(line: &str) -> &str {
    match line.strip_prefix('N') {
        Some(rest) => {
            let digits = rest.len() - rest.trim_start_matches(|c: char| c.is_ascii_digit()).len();
            rest[digits..].trim_start()
        }
        None => line,
    }
}

/// `job`'s planned program with every other linked move dropped where Z is within ±2 mm,
/// written to `dir/coarse.nc`: the chords there span two segments, so their interpolation
/// error is about four times what the planner allowed, beyond Δ.
pub fn coarse_program(job: &Path, dir: &Path) -> PathBuf {
    let planned = dir.join("planned.nc");
    let o = whirl(&[
        std::ffi::OsStr::new("plan"),
        job.as_os_str(),
        std::ffi::OsStr::new("-o"),
        planned.as_os_str(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(&planned).expect("the planned program");
    let (mut last_z, mut k) = (f64::NAN, 0);
    let coarse: Vec<&str> = text
        .lines()
        .filter(|line| {
            if let Some(z) = line.split(' ').find_map(|w| w.strip_prefix('Z')) {
                last_z = z.parse().expect("a Z word");
            }
            let linked = block(line).starts_with("G1") && line.contains(" C");
            if linked && (-2.0..=2.0).contains(&last_z) {
                k += 1;
                return k % 2 == 1;
            }
            true
        })
        .collect();
    write(dir, "coarse.nc", &(coarse.join("\n") + "\n"))
}

/// whirl-sim, killed when dropped.
pub struct Sim(pub std::process::Child);

impl Sim {
    /// whirl-sim started with `flag LINK args…` (`--pty`, `--modbus-rtu`), once the
    /// pseudo-terminal it makes at `link` exists.
    pub fn serving(flag: &std::ffi::OsStr, link: &Path, args: &[&std::ffi::OsStr]) -> Sim {
        let child = std::process::Command::new(env!("CARGO_BIN_EXE_whirl-sim"))
            .args([flag, link.as_os_str()])
            .args(args)
            .stderr(std::process::Stdio::null())
            .spawn()
            .expect("whirl-sim starts");
        // Owned at once, so that it is killed even if the link never appears.
        let sim = Sim(child);
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(10);
        while !link.exists() {
            assert!(
                std::time::Instant::now() < deadline,
                "whirl-sim made no pseudo-terminal"
            );
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
        sim
    }
}

impl Drop for Sim {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Whether `python3` can import `module` (the pip package `package`). CI installs the
/// clients' packages (`.ci/run`) and sets `CI`, and there a missing peer fails the test; a
/// developer's machine without them says why a test did nothing instead.
pub fn python_with(module: &str, package: &str) -> bool {
    let missing = match std::process::Command::new("python3")
        .args(["-c", &format!("import {module}")])
        .output()
    {
        Err(e) => format!("python3 cannot be run ({e})"),
        Ok(o) if !o.status.success() => format!(
            "python3 cannot import {package} (python3 -m pip install {package}): {}",
            String::from_utf8_lossy(&o.stderr)
                .lines()
                .last()
                .unwrap_or("")
        ),
        Ok(_) => return true,
    };
    assert!(
        std::env::var_os("CI").is_none(),
        "on CI the peer must be there: {missing}"
    );
    eprintln!("skipped: {missing}");
    false
}

/// The double-start example planned for `profile`, cut to its first 200 blocks (lead-in,
/// M3, plunge, linked moves) and its lead-out (the blocks after the last linked move:
/// retract, M5): a stretch of real whirling path that runs in seconds.
pub fn short_double_start(
    profile: &whirl::config::machine::MachineProfile,
) -> whirl::program::Program {
    use whirl::program::{Move, Program};
    let job = whirl::config::job::Job::load(&example("double-start")).unwrap();
    let blocks = whirl::plan::plan(&job, profile).unwrap().program.moves;
    let last_linked = blocks
        .iter()
        .rposition(|b| matches!(b, Move::Linked { .. }))
        .unwrap();
    let mut short: Vec<Move> = blocks[..200].to_vec();
    short.extend_from_slice(&blocks[last_linked + 1..]);
    assert!(matches!(short.last(), Some(Move::SpindleOff)));
    Program { moves: short }
}

/// `whirl-sim --modbus-tcp` on a free loopback port in real time, logging to `log`; its
/// address. Its stderr is drained for as long as it runs (a closed pipe would end it at
/// its next word: a connection that ends).
pub fn modbus_tcp_sim(log: &Path) -> (Sim, std::net::SocketAddr) {
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_whirl-sim"))
        .args([
            std::ffi::OsStr::new("--modbus-tcp"),
            std::ffi::OsStr::new("127.0.0.1:0"),
            std::ffi::OsStr::new("--time-scale"),
            std::ffi::OsStr::new("1"),
            std::ffi::OsStr::new("--idle-exit"),
            std::ffi::OsStr::new("60"),
            std::ffi::OsStr::new("--log"),
            log.as_os_str(),
        ])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("whirl-sim starts");
    let mut stderr = std::io::BufReader::new(child.stderr.take().unwrap());
    let mut banner = String::new();
    std::io::BufRead::read_line(&mut stderr, &mut banner).unwrap();
    std::thread::spawn(move || std::io::copy(&mut stderr, &mut std::io::sink()));
    let address = banner
        .trim()
        .strip_prefix("whirl-sim: serving Modbus on ")
        .unwrap_or_else(|| panic!("{banner}"))
        .parse()
        .unwrap();
    (Sim(child), address)
}

/// Runs `whirl dry-run JOB --report --log [extra…]`; returns the exit code, the report and
/// the log as read back.
pub fn dry_run(
    job: &Path,
    dir: &Path,
    extra: &[&std::ffi::OsStr],
) -> (Option<i32>, serde_json::Value, whirl::log::Read) {
    use std::ffi::OsStr;
    let (report, log) = (dir.join("report.json"), dir.join("exec.jsonl"));
    let mut args = vec![
        OsStr::new("dry-run"),
        job.as_os_str(),
        OsStr::new("--report"),
        report.as_os_str(),
        OsStr::new("--log"),
        log.as_os_str(),
    ];
    args.extend_from_slice(extra);
    let o = whirl(&args);
    let text = std::fs::read_to_string(&report).unwrap_or_else(|_| {
        panic!(
            "no report: {}{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        )
    });
    let read = whirl::log::read(&log).expect("the log reads back");
    (o.status.code(), serde_json::from_str(&text).unwrap(), read)
}

/// A memory log read as its run writes it: each look copies only the records new since the
/// last, so a test polling a long run does not hold the log's lock copying all of it again
/// while the run waits to write.
pub struct Follow {
    log: whirl::log::ExecLog,
    seen: Vec<whirl::log::Record>,
}

impl Follow {
    /// Follows `log` from its start.
    pub fn new(log: &whirl::log::ExecLog) -> Follow {
        Follow {
            log: log.clone(),
            seen: Vec::new(),
        }
    }

    /// Every record so far.
    pub fn look(&mut self) -> &[whirl::log::Record] {
        let new = self.log.records_from(self.seen.len());
        self.seen.extend(new);
        &self.seen
    }
}
