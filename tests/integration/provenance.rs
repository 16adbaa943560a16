//! A program's provenance through the real binaries (docs/streaming.md#provenance): `whirl
//! plan` writes what the program was planned from at its top; `whirl stream` refuses, before
//! anything is opened, a program whose job has changed since (the case: the ring
//! radius 2 mm larger), whose machine profile has changed, that was planned for another
//! machine or that carries no provenance, on every transport; `--no-provenance-check`
//! streams it all the same, and the run's record says so.
//!
//! "Nothing was sent" is checked on the peer's side: the simulator's log holds no event
//! (whirl-sim writes one for every line it answers and every request it serves), and for
//! LinuxCNC a listener on the port whirl is given was never connected to.

use sha2::{Digest, Sha256};
use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::Output;

use crate::util::{self, Sim};

fn os(s: &str) -> &OsStr {
    OsStr::new(s)
}

/// SHA-256 of a file's bytes, lower-case hex (FIPS 180-4), computed here.
fn sha256(path: &Path) -> String {
    Sha256::digest(std::fs::read(path).unwrap())
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// A folder with a job (the trapezoidal example cut to 3 mm, so that it streams in
/// seconds) in `jobs/` and a folder `programs/` for what is planned from it.
struct Shop {
    dir: tempfile::TempDir,
}

impl Shop {
    fn new() -> Shop {
        let dir = tempfile::tempdir().unwrap();
        let text = std::fs::read_to_string(util::example("trapezoidal")).unwrap();
        let short = text.replace("length = 40.0", "length = 3.0");
        assert_ne!(short, text);
        std::fs::create_dir(dir.path().join("jobs")).unwrap();
        std::fs::create_dir(dir.path().join("programs")).unwrap();
        std::fs::write(dir.path().join("jobs/job.toml"), short).unwrap();
        Shop { dir }
    }

    fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }

    fn job(&self) -> PathBuf {
        self.path("jobs/job.toml")
    }

    /// `whirl plan` of the job for `machine` (the built-in simulator's if `None`) to
    /// `programs/NAME`.
    fn plan(&self, name: &str, machine: Option<&Path>) -> PathBuf {
        let program = self.path("programs").join(name);
        let job = self.job();
        let mut args = vec![os("plan"), job.as_os_str()];
        if let Some(m) = machine {
            args.extend([os("--machine"), m.as_os_str()]);
        }
        args.extend([os("-o"), program.as_os_str()]);
        let o = self.whirl(&args);
        assert!(o.status.success(), "{}", text(&o.stderr));
        program
    }

    /// The stale job: the ring radius 2 mm larger than it was planned with.
    fn grow_ring(&self) {
        let text = std::fs::read_to_string(self.job()).unwrap();
        let grown = text.replace("ring_radius = 32.0", "ring_radius = 34.0");
        assert_ne!(grown, text);
        std::fs::write(self.job(), grown).unwrap();
    }

    /// `whirl` with `args`, its records in this shop's own database.
    fn whirl(&self, args: &[&OsStr]) -> Output {
        std::process::Command::new(env!("CARGO_BIN_EXE_whirl"))
            .env("WHIRL_DB", self.path("runs.sqlite"))
            .args(args)
            .output()
            .expect("the whirl binary runs")
    }

    /// `whirl stream PROGRAM --log LOG` with `args`.
    fn stream(&self, program: &Path, args: &[&OsStr]) -> Output {
        let log = self.path("stream.jsonl");
        let mut all = vec![
            os("stream"),
            program.as_os_str(),
            os("--log"),
            log.as_os_str(),
        ];
        all.extend_from_slice(args);
        self.whirl(&all)
    }

    /// The newest run's whole record.
    fn last_run(&self) -> serde_json::Value {
        let o = self.whirl(&[os("runs"), os("list"), os("--json"), os("--limit"), os("1")]);
        let list: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        let id = list[0]["id"].to_string();
        let o = self.whirl(&[os("runs"), os("show"), os(&id), os("--json")]);
        serde_json::from_slice(&o.stdout).unwrap()
    }
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// The program's provenance comments, `key=value` each, N words and parentheses off.
fn header(program: &Path) -> Vec<(String, String)> {
    std::fs::read_to_string(program)
        .unwrap()
        .lines()
        .filter_map(|l| {
            let inside = util::block(l).strip_prefix("(whirl provenance: ")?;
            let (k, v) = inside.strip_suffix(')')?.split_once('=')?;
            Some((k.to_owned(), v.to_owned()))
        })
        .collect()
}

fn value<'a>(header: &'a [(String, String)], key: &str) -> &'a str {
    &header
        .iter()
        .find(|(k, _)| k == key)
        .unwrap_or_else(|| panic!("no {key} in {header:?}"))
        .1
}

/// A refusal of `program` for the reasons `why` (each a piece of its message), the stream
/// log never opened.
fn refused(shop: &Shop, o: &Output, program: &Path, why: &[&str]) {
    let err = text(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    for piece in why {
        assert!(err.contains(piece), "{piece:?} in {err}");
    }
    assert!(
        err.contains(&format!("refusing to stream {}", program.display()))
            && err.contains("Nothing was sent")
            && err.contains("--no-provenance-check"),
        "{err}"
    );
    assert!(!shop.path("stream.jsonl").exists(), "the log was opened");
}

/// Whether a simulator's log holds any event: it writes one for every line it answers,
/// every block it runs and every request it serves. A CAN simulator's drives say at its
/// start the states they power up in (CiA 402's Switch on disabled, CiA 301's
/// Pre-operational): those are no one's doing.
fn sim_heard_nothing(log: &Path) {
    let events = std::fs::read_to_string(log).unwrap_or_default();
    let heard: Vec<&str> = events
        .lines()
        .filter(|line| {
            let e: serde_json::Value = serde_json::from_str(line).unwrap();
            let powered_up = e["event"] == "drive"
                && ((e["kind"] == "power" && e["state"] == "SwitchOnDisabled")
                    || (e["kind"] == "nmt" && e["state"] == "PreOperational"));
            !powered_up
        })
        .collect();
    assert!(heard.is_empty(), "the simulator heard: {heard:?}");
}

#[test]
fn the_header_names_the_files_and_what_the_program_was_planned_at_in_both_dialects() {
    let shop = Shop::new();
    let grbl = shop.plan("grbl.nc", None);
    let h = header(&grbl);
    // Paths from the program's folder to the file.
    assert_eq!(value(&h, "job"), "../jobs/job.toml");
    assert_eq!(value(&h, "job-sha256"), sha256(&shop.job()));
    assert_eq!(value(&h, "version"), env!("CARGO_PKG_VERSION"));
    let sim = util::root().join("machine-profiles/sim.toml");
    assert_eq!(value(&h, "machine-sha256"), sha256(&sim));
    assert_eq!(
        value(&h, "machine-file"),
        "built-in:machine-profiles/sim.toml"
    );
    // The job's own numbers: Δ, the installation angle it gives, its feed.
    assert_eq!(value(&h, "delta-mm"), "0.01");
    assert_eq!(value(&h, "installation-angle-deg"), "7.8");
    assert_eq!(value(&h, "axial-feed-mm-per-rev"), "0.05");
    // grblHAL: every line still numbered with its file line.
    let program = std::fs::read_to_string(&grbl).unwrap();
    for (i, line) in program.lines().enumerate() {
        assert!(line.starts_with(&format!("N{} ", i + 1)), "{line}");
    }
    assert!(program.lines().next().unwrap().contains("whirl provenance"));
    // Same inputs, same bytes: no time in it.
    let again = shop.plan("again.nc", None);
    assert_eq!(std::fs::read(&again).unwrap(), program.as_bytes());

    let lathe = util::root().join("machine-profiles/linuxcnc-lathe.toml");
    let linuxcnc = shop.plan("lathe.ngc", Some(&lathe));
    let text = std::fs::read_to_string(&linuxcnc).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[0], "%", "LinuxCNC's program opens with %");
    assert!(lines[1].starts_with("(whirl provenance: "), "{}", lines[1]);
    let h = header(&linuxcnc);
    assert_eq!(value(&h, "machine-sha256"), sha256(&lathe));
    // The profile's path, from the program's folder, leads to the profile.
    let from_program = shop.path("programs").join(value(&h, "machine-file"));
    assert_eq!(
        from_program.canonicalize().unwrap(),
        lathe.canonicalize().unwrap()
    );
    // Read back whole by the library: the profile's name, as it is in the profile.
    let read = whirl::post::gcode::header::read(&text).unwrap().unwrap();
    let profile = whirl::config::machine::MachineProfile::load(&lathe).unwrap();
    assert_eq!(read.machine_name, profile.name);
    assert_eq!(read.points, None, "a standard profile has no points file");
}

#[test]
fn a_stale_program_is_refused_over_serial_before_the_simulator_hears_a_byte() {
    let shop = Shop::new();
    let program = shop.plan("p.nc", None);
    shop.grow_ring();
    let (link, sim_log) = (shop.path("grbl"), shop.path("sim.jsonl"));
    let _sim = Sim::serving(
        os("--pty"),
        &link,
        &[
            os("--log"),
            sim_log.as_os_str(),
            os("--idle-exit"),
            os("30"),
        ],
    );
    let o = shop.stream(&program, &[os("--port"), link.as_os_str()]);
    let job = Path::new("jobs").join("job.toml");
    refused(
        &shop,
        &o,
        &program,
        &[
            "has changed since",
            &job.display().to_string(),
            // The command that plans it again, from the program's own folder's job.
            "whirl plan ",
            &format!("-o {}", program.display()),
        ],
    );
    sim_heard_nothing(&sim_log);
}

#[test]
fn a_stale_program_is_refused_over_modbus_before_the_plc_is_asked_anything() {
    let shop = Shop::new();
    let program = shop.plan("p.nc", None);
    shop.grow_ring();
    let sim_log = shop.path("sim.jsonl");
    let (_sim, address) = util::modbus_tcp_sim(&sim_log);
    let address = address.to_string();
    let o = shop.stream(
        &program,
        &[
            os("--transport"),
            os("modbus-tcp"),
            os("--port"),
            os(&address),
        ],
    );
    refused(&shop, &o, &program, &["has changed since"]);
    sim_heard_nothing(&sim_log);
}

#[test]
fn a_stale_program_is_refused_over_can_before_a_frame_goes_out() {
    let shop = Shop::new();
    let profile = util::root().join("machine-profiles/canopen-drives.toml");
    let program = shop.plan("p.nc", Some(&profile));
    shop.grow_ring();
    let (link, sim_log) = (shop.path("slcan"), shop.path("sim.jsonl"));
    let _sim = Sim::serving(
        os("--can-slcan"),
        &link,
        &[
            os("--machine"),
            profile.as_os_str(),
            os("--idle-exit"),
            os("30"),
            os("--log"),
            sim_log.as_os_str(),
        ],
    );
    let o = shop.stream(
        &program,
        &[
            os("--machine"),
            profile.as_os_str(),
            os("--transport"),
            os("can-slcan"),
            os("--port"),
            link.as_os_str(),
        ],
    );
    refused(
        &shop,
        &o,
        &program,
        &[
            "has changed since",
            &format!("--machine {}", profile.display()),
        ],
    );
    sim_heard_nothing(&sim_log);
}

#[test]
fn a_stale_program_is_refused_for_linuxcnc_before_linuxcncrsh_is_connected_to() {
    let shop = Shop::new();
    let profile = util::root().join("machine-profiles/linuxcnc-lathe.toml");
    let program = shop.plan("p.ngc", Some(&profile));
    shop.grow_ring();
    // A port that answers: whirl would connect to it, were it to go on.
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let address = listener.local_addr().unwrap().to_string();
    let o = shop.stream(
        &program,
        &[
            os("--machine"),
            profile.as_os_str(),
            os("--transport"),
            os("linuxcnc"),
            os("--port"),
            os(&address),
        ],
    );
    refused(&shop, &o, &program, &["has changed since"]);
    listener.set_nonblocking(true).unwrap();
    // whirl has exited: any connection it made is in the backlog by now.
    assert_eq!(
        listener.accept().map(|_| ()).unwrap_err().kind(),
        std::io::ErrorKind::WouldBlock,
        "whirl connected to linuxcncrsh"
    );
}

#[test]
fn a_program_for_another_machine_a_changed_profile_and_one_without_header_are_refused() {
    let shop = Shop::new();
    // Planned for the simulator, streamed as if to the grblHAL lathe.
    let program = shop.plan("p.nc", None);
    let other = util::root().join("machine-profiles/grblhal-lathe.toml");
    let port = shop.path("no-such-port");
    let o = shop.stream(
        &program,
        &[
            os("--machine"),
            other.as_os_str(),
            os("--port"),
            port.as_os_str(),
        ],
    );
    refused(
        &shop,
        &o,
        &program,
        &[
            "was planned for the machine \"whirl-sim: simulated XZC whirling lathe\"",
            "\"grblHAL XZC whirling lathe (ER32 workpiece spindle, 60 mm ring)\"",
        ],
    );

    // A profile of the same name whose numbers changed since.
    let profile = shop.path("lathe.toml");
    std::fs::copy(util::root().join("machine-profiles/sim.toml"), &profile).unwrap();
    let program = shop.plan("q.nc", Some(&profile));
    let text = std::fs::read_to_string(&profile).unwrap();
    std::fs::write(&profile, format!("{text}\n# the X axis re-measured\n")).unwrap();
    let o = shop.stream(
        &program,
        &[
            os("--machine"),
            profile.as_os_str(),
            os("--port"),
            port.as_os_str(),
        ],
    );
    refused(
        &shop,
        &o,
        &program,
        &["the machine profile \"whirl-sim: simulated XZC whirling lathe\" has changed"],
    );

    // The header cut off: no provenance, and the flag that goes on named.
    let plain: String = std::fs::read_to_string(shop.plan("r.nc", None))
        .unwrap()
        .lines()
        .filter(|l| !l.contains("whirl provenance"))
        .map(|l| format!("{l}\n"))
        .collect();
    let bare = util::write(&shop.path("programs"), "bare.nc", &plain);
    let o = shop.stream(&bare, &[os("--port"), port.as_os_str()]);
    refused(&shop, &o, &bare, &["carries no provenance"]);

    // The job gone from where the header says it is.
    let program = shop.plan("s.nc", None);
    std::fs::rename(shop.job(), shop.path("jobs/moved.toml")).unwrap();
    let o = shop.stream(&program, &[os("--port"), port.as_os_str()]);
    refused(&shop, &o, &program, &["cannot be read"]);
}

#[test]
fn a_program_that_matches_streams_and_the_override_streams_a_stale_one_on_the_record() {
    let shop = Shop::new();
    let program = shop.plan("p.nc", None);
    let link = shop.path("grbl");
    let _sim = Sim::serving(
        os("--pty"),
        &link,
        &[os("--time-scale"), os("0"), os("--idle-exit"), os("60")],
    );
    // From another working directory: the header's paths are the program's folder's.
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_whirl"))
        .env("WHIRL_DB", shop.path("runs.sqlite"))
        .current_dir(util::root())
        .args([
            os("stream"),
            program.as_os_str(),
            os("--port"),
            link.as_os_str(),
        ])
        .args([os("--log"), shop.path("first.jsonl").as_os_str()])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o.stderr));
    let run = shop.last_run();
    assert_eq!(run["provenance"]["check"], "matched", "{run}");
    assert_eq!(
        run["provenance"]["header"]["job"]["sha256"],
        sha256(&shop.job())
    );

    shop.grow_ring();
    let o = shop.stream(
        &program,
        &[os("--port"), link.as_os_str(), os("--no-provenance-check")],
    );
    let err = text(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("warning:") && err.contains("has changed since"),
        "{err}"
    );
    let run = shop.last_run();
    assert_eq!(run["provenance"]["check"], "overridden", "{run}");
    assert!(
        run["provenance"]["finding"]
            .as_str()
            .is_some_and(|f| f.contains("has changed since")),
        "{run}"
    );
    assert_eq!(run["outcome"], "completed", "{run}");
}

#[test]
fn a_plan_records_its_provenance_and_a_dry_run_of_a_stale_program_says_so() {
    let shop = Shop::new();
    let program = shop.plan("p.nc", None);
    let run = shop.last_run();
    assert_eq!(run["kind"], "plan");
    assert_eq!(run["provenance"]["check"], "planned", "{run}");
    assert_eq!(
        run["provenance"]["header"]["job"]["sha256"],
        sha256(&shop.job())
    );
    shop.grow_ring();
    // The dry run measures the old program against the job as it is now, and says first
    // that the program was not planned from it.
    let o = shop.whirl(&[
        os("dry-run"),
        shop.job().as_os_str(),
        os("--program"),
        program.as_os_str(),
    ]);
    let err = text(&o.stderr);
    assert!(
        err.contains("was not planned from the job") && err.contains("whirl plan "),
        "{err}"
    );
    let run = shop.last_run();
    assert_eq!(run["provenance"]["check"], "reported", "{run}");
    // whirl verify, given the job too, says the same.
    let report = shop.path("verify.json");
    let o = shop.whirl(&[
        os("verify"),
        program.as_os_str(),
        os("--job"),
        shop.job().as_os_str(),
        os("--report"),
        report.as_os_str(),
    ]);
    let err = text(&o.stderr);
    assert!(err.contains("was not planned from the job"), "{err}");
    assert!(report.exists(), "{err}");
}
