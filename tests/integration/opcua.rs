//! OPC UA for Machine Tools against an independent client (asyncua, `tests/clients/
//! opcua_browse.py`): a machine is found and read by the standards' names, its runs and
//! alarms followed by subscriptions; a login and message security are OPC UA's own; an
//! address beyond loopback is refused unsecured before anything listens.

use std::ffi::OsStr;
use std::io::{BufRead, BufReader, Write};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::Duration;

use serde_json::Value;
use whirl::config::job::Job;
use whirl::config::machine::MachineProfile;
use whirl::config::opcua::{Nameplate, OpcUaSettings};
use whirl::config::telemetry::TelemetrySettings;
use whirl::judge::dry_run::{dry_run, DryRunOptions};
use whirl::log::ExecLog;
use whirl::opcua::{Identity, OpcUa};
use whirl::telemetry::tracker::Out;
use whirl::telemetry::{RunContext, Telemetry};
use whirl::transport::Posted;

use crate::util;

/// How long the client may take to connect, subscribe or see what the server says: a
/// second or two, or a minute when async-opcua holds a change until the client's next
/// Publish request (docs/opcua.md); the client gives up after 240 s, and the margin is a
/// busy host's.
const PATIENCE: Duration = Duration::from_secs(300);

const MACHINE_TOOL: &str = "http://opcfoundation.org/UA/MachineTool/";

/// `tests/clients/opcua_browse.py URL MACHINE args…`, its stdout's lines over a channel.
struct Client {
    child: Child,
    lines: mpsc::Receiver<String>,
}

impl Client {
    fn start(url: &str, machine: &str, args: &[&str]) -> Client {
        let mut child = Command::new("python3")
            .arg(util::root().join("tests/clients/opcua_browse.py"))
            .args([url, machine])
            .args(args)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .expect("python3 runs");
        let (sender, lines) = mpsc::channel();
        let stdout = BufReader::new(child.stdout.take().unwrap());
        std::thread::spawn(move || {
            for line in stdout.lines().map_while(Result::ok) {
                if sender.send(line).is_err() {
                    return;
                }
            }
        });
        Client { child, lines }
    }

    /// The next JSON line it prints.
    fn next(&self) -> Value {
        let line = self
            .lines
            .recv_timeout(PATIENCE)
            .expect("the client says something");
        serde_json::from_str(&line).unwrap_or_else(|e| panic!("{line}: {e}"))
    }

    /// Its one answer, and its exit code.
    fn answer(mut self) -> (Value, Option<i32>) {
        let answer = self.next();
        let _ = self.child.stdin.take().map(|mut s| s.flush());
        (answer, self.child.wait().unwrap().code())
    }
}

impl Drop for Client {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// `whirl serve` on free loopback ports with `args`, and the OPC UA URL it prints.
struct Serve(Child);

impl Serve {
    fn start(dir: &Path, args: &[&OsStr]) -> (Serve, String) {
        let mut child = Command::new(env!("CARGO_BIN_EXE_whirl"))
            .arg("--db")
            .arg(dir.join("runs.sqlite"))
            .args(["serve", "--listen", "127.0.0.1:0", "--jobs"])
            .arg(util::root().join("examples"))
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let stdout = BufReader::new(child.stdout.take().unwrap());
        let mut serve = Serve(child);
        for line in stdout.lines().map_while(Result::ok) {
            if let Some(at) = line.find("opc.tcp://") {
                let url = line[at..].trim().to_owned();
                return (serve, url);
            }
        }
        let mut stderr = String::new();
        let _ = std::io::Read::read_to_string(serve.0.stderr.as_mut().unwrap(), &mut stderr);
        panic!("whirl serve served no OPC UA: {stderr}");
    }
}

impl Drop for Serve {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// `whirl serve args…` that must refuse to start: its standard error, once it has ended.
/// `homeless`: without HOME and XDG_DATA_HOME.
fn serve_refused(dir: &Path, args: &[&OsStr], homeless: bool) -> String {
    let mut command = Command::new(env!("CARGO_BIN_EXE_whirl"));
    if homeless {
        command.env_remove("HOME").env_remove("XDG_DATA_HOME");
    }
    let child = command
        .arg("--db")
        .arg(dir.join("runs.sqlite"))
        .args(["serve", "--listen", "127.0.0.1:0", "--jobs"])
        .arg(util::root().join("examples"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let (sender, ended) = mpsc::channel();
    let waiter = std::thread::spawn(move || {
        let output = child.wait_with_output().unwrap();
        let _ = sender.send(());
        output
    });
    ended
        .recv_timeout(PATIENCE)
        .expect("a refused serve ends by itself");
    let output = waiter.join().unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(!output.status.success(), "{stdout}");
    assert!(
        !stdout.contains("http://") && !stdout.contains("opc.tcp://"),
        "nothing listened: {stdout}"
    );
    String::from_utf8_lossy(&output.stderr).into_owned()
}

/// The built-in simulator's profile with `telemetry` as its `[telemetry]`.
fn profile(dir: &Path, telemetry: &str) -> std::path::PathBuf {
    let sim = std::fs::read_to_string(util::root().join("machine-profiles/sim.toml")).unwrap();
    util::write(
        dir,
        "lathe.toml",
        &format!("{sim}\n[telemetry]\n{telemetry}\n"),
    )
}

/// The same, written to `dir/NAME.toml` and named NAME.
fn named_profile(dir: &Path, name: &str, telemetry: &str) -> std::path::PathBuf {
    let sim = std::fs::read_to_string(util::root().join("machine-profiles/sim.toml")).unwrap();
    let renamed: String = sim
        .lines()
        .map(|line| {
            if line.starts_with("name = ") {
                format!("name = \"{name}\"\n")
            } else {
                format!("{line}\n")
            }
        })
        .collect();
    util::write(
        dir,
        &format!("{name}.toml"),
        &format!("{renamed}\n[telemetry]\n{telemetry}\n"),
    )
}

/// Consecutive repeats dropped: the states a value went through.
fn went_through(values: &Value) -> Vec<Value> {
    let mut out: Vec<Value> = Vec::new();
    for v in values.as_array().unwrap() {
        if out.last() != Some(v) {
            out.push(v.clone());
        }
    }
    out
}

#[test]
fn an_mes_follows_a_machines_runs_and_alarm_as_opc_40501_says() {
    if !util::python_with("asyncua", "asyncua") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let machine = MachineProfile::builtin_sim().unwrap();
    let job_path = util::example("double-start");
    let job = Job::load(&job_path).unwrap();
    let plan = whirl::plan::plan(&job, &machine).unwrap();
    let planned = Posted::read("double-start", &plan.text, &machine).unwrap();
    let coarse_text = std::fs::read_to_string(util::coarse_program(&job_path, dir.path())).unwrap();
    let coarse = Posted::read("coarse", &coarse_text, &machine).unwrap();

    let settings = OpcUaSettings::new(
        "127.0.0.1:0".parse().unwrap(),
        "opcua",
        None,
        (None, None),
        None,
    )
    .unwrap();
    let nameplate = Nameplate {
        manufacturer: Some("Acme Whirling".into()),
        serial_number: Some("W-17".into()),
        ..Nameplate::default()
    };
    let server = OpcUa::start(
        &settings,
        "opcua",
        &[Identity::new(&machine.name, &nameplate)],
    )
    .unwrap();
    let feed = server.feed(&machine.name).unwrap();
    let telemetry = Telemetry::start_observed(
        &TelemetrySettings::nowhere(),
        &machine.name,
        Some(Box::new(move |out: &Out| feed.apply(out))),
    )
    .unwrap();
    let url = format!("opc.tcp://{}/", server.address());
    let client = Client::start(
        &url,
        &machine.name,
        &[
            "--watch",
            "--until-runs",
            "2",
            "--until-alerts",
            "1",
            "--until-state",
            "Aborted",
        ],
    );
    assert_eq!(client.next(), serde_json::json!({"ready": true}));

    // Two runs of the job that complete, then a coarse program of it that the Δ guard stops.
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let handle = telemetry.handle();
    for (posted, completes) in [(&planned, true), (&planned, true), (&coarse, false)] {
        handle.prepare(RunContext {
            kind: "dry-run".into(),
            job: Some(job_path.display().to_string()),
            ..RunContext::default()
        });
        let options = DryRunOptions {
            progress: Some(handle.progress(None)),
            ..DryRunOptions::default()
        };
        let mut log = ExecLog::memory().tapped(handle.tap());
        let report = runtime
            .block_on(dry_run(
                &job, plan.ring, &machine, posted, options, &mut log,
            ))
            .expect("the dry run is carried out");
        assert_eq!(report.completed, completes, "{}", posted.name);
    }
    let (seen, code) = client.answer();
    assert_eq!(code, Some(0), "{seen}");
    assert_eq!(seen["timeout"], false, "{seen:#}");

    // Found as an MES finds it: under Machines, a MachineToolType, its nameplate DI's.
    assert_eq!(seen["machines"], serde_json::json!([machine.name]));
    assert_eq!(
        seen["type_definition"],
        serde_json::json!({"namespace": MACHINE_TOOL, "id": 13})
    );
    let id = &seen["identification"];
    assert_eq!(id["Manufacturer"], "Acme Whirling");
    assert_eq!(id["Model"], machine.name.as_str());
    assert_eq!(id["SerialNumber"], "W-17");
    assert_eq!(id["SoftwareRevision"], env!("CARGO_PKG_VERSION"));
    assert!(id["ProductInstanceUri"]
        .as_str()
        .unwrap()
        .starts_with("urn:"));
    // IA's SignalColor: red 1, yellow 4, green 2.
    assert_eq!(
        seen["signal_colors"],
        serde_json::json!({"Red": 1, "Yellow": 4, "Green": 2})
    );
    // Before any run: automatic (1), channel reset (2), nothing lit, nothing run.
    let before = &seen["values"];
    assert_eq!(
        (
            &before["OperationMode"],
            &before["ChannelState"],
            &before["ProgramState"],
            &before["RunsCompleted"]
        ),
        (
            &Value::from(1),
            &Value::from(2),
            &Value::from("Initializing"),
            &Value::from(0)
        )
    );
    assert_eq!(before["FeedOverride"], 100.0);
    // Each run: the channel active (0), then reset (2); the alarm leaves it interrupted (1).
    let changes = &seen["changes"];
    let ints = |v: Vec<i64>| v.into_iter().map(Value::from).collect::<Vec<_>>();
    assert_eq!(
        went_through(&changes["ChannelState"]),
        ints(vec![2, 0, 2, 0, 2, 0, 1])
    );
    // The program's and the job's state machines; the last change, Aborted, may reach a
    // subscriber late (docs/opcua.md), and is read.
    for state in ["ProgramState", "JobState"] {
        let mut states = went_through(&changes[state]);
        if states.last() == Some(&Value::from("Aborted")) {
            states.pop();
        }
        assert_eq!(
            states,
            [
                "Initializing",
                "Running",
                "Ended",
                "Running",
                "Ended",
                "Running",
                "Interrupted"
            ]
            .map(Value::from),
            "{state}"
        );
        assert_eq!(seen["final"][state], "Aborted", "{state}");
    }
    // The runs that completed are counted; the job is the job file all three ran.
    assert_eq!(went_through(&changes["RunsCompleted"]), ints(vec![0, 1, 2]));
    assert_eq!(
        went_through(&changes["JobIdentifier"]),
        ["", job_path.to_str().unwrap()].map(Value::from)
    );
    assert_eq!(
        went_through(&changes["ProgramName"]),
        ["", "double-start", "coarse"].map(Value::from)
    );
    // The green lamp lit for each run, the red one for the alarm, and it stays.
    assert_eq!(
        went_through(&changes["Lamp_Green"]),
        [false, true, false, true, false, true, false].map(Value::from)
    );
    assert_eq!(
        went_through(&changes["Lamp_Red"]),
        [false, true].map(Value::from)
    );
    let last = &seen["final"];
    assert_eq!(
        (&last["Lamp_Red"], &last["ChannelState"]),
        (&Value::from(true), &Value::from(1))
    );
    // A feed override is a percentage the controller ran at.
    for percent in changes["FeedOverride"].as_array().unwrap() {
        assert!(
            (10.0..=200.0).contains(&percent.as_f64().unwrap()),
            "{percent}"
        );
    }
    // The alarm: one AlertType event, the controller's code and words.
    let events = seen["events"].as_array().unwrap();
    assert_eq!(events.len(), 1, "{events:?}");
    let alert = &events[0];
    assert_eq!(alert["ErrorCode"], "64");
    assert!(
        alert["Message"].as_str().unwrap().contains("Δ guard"),
        "{alert}"
    );
    assert_eq!(alert["Retain"], true);
    assert_eq!(alert["SourceName"], machine.name.as_str());
    assert_eq!(alert["ActiveState/Id"], true);
    assert_eq!(alert["Severity"], 900);
    telemetry.close();
    assert_eq!(server.close(), 0, "no message lost");
}

#[test]
fn whirl_serve_serves_its_machines_at_opcua_and_a_profiles_login_is_required() {
    if !util::python_with("asyncua", "asyncua") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let sim = MachineProfile::builtin_sim().unwrap();
    // `--opcua` alone: anonymous, on loopback, the built-in simulator.
    let (serve, url) = Serve::start(
        dir.path(),
        &[OsStr::new("--opcua"), OsStr::new("127.0.0.1:0")],
    );
    let (seen, code) = Client::start(&url, &sim.name, &[]).answer();
    assert_eq!(code, Some(0), "{seen}");
    assert_eq!(seen["machines"], serde_json::json!([sim.name]));
    assert_eq!(seen["identification"]["Manufacturer"], "whirl");
    assert_eq!(seen["values"]["ChannelState"], 2);
    drop(serve);

    // A profile's `opcua` with a login: only that user, with that password, gets in.
    let lathe = profile(
        dir.path(),
        "opcua = \"127.0.0.1:0\"\nopcua_user = \"mes\"\nopcua_password = \"s3cret-word\"\n\
         opcua_model = \"WX-40\"",
    );
    let (_serve, url) = Serve::start(dir.path(), &[OsStr::new("--machine"), lathe.as_os_str()]);
    for login in [
        vec![],
        vec!["--user", "mes", "--password", "wrong"],
        vec!["--user", "other", "--password", "s3cret-word"],
    ] {
        let (seen, code) = Client::start(&url, &sim.name, &login).answer();
        assert_eq!(code, Some(3), "{login:?} let in: {seen}");
        assert!(seen["refused"].is_string(), "{seen}");
    }
    let (seen, code) = Client::start(
        &url,
        &sim.name,
        &["--user", "mes", "--password", "s3cret-word"],
    )
    .answer();
    assert_eq!(code, Some(0), "{seen}");
    assert_eq!(seen["identification"]["Model"], "WX-40");
}

#[test]
fn a_secured_server_trusts_a_client_once_the_operator_moves_its_certificate() {
    if !util::python_with("asyncua", "asyncua") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let sim = MachineProfile::builtin_sim().unwrap();
    let pki = dir.path().join("pki");
    let lathe = profile(
        dir.path(),
        &format!(
            "opcua = \"127.0.0.1:0\"\nopcua_security = \"sign-and-encrypt\"\n\
             opcua_user = \"mes\"\nopcua_password = \"s3cret-word\"\nopcua_pki = \"{}\"",
            pki.display()
        ),
    );
    let (_serve, url) = Serve::start(dir.path(), &[OsStr::new("--machine"), lathe.as_os_str()]);
    assert!(
        pki.join("own/cert.der").exists(),
        "the server made its certificate"
    );
    let client_pki = dir.path().join("client").display().to_string();
    let secured = |password: &str| {
        Client::start(
            &url,
            &sim.name,
            &[
                "--mode",
                "sign-and-encrypt",
                "--pki",
                &client_pki,
                "--user",
                "mes",
                "--password",
                password,
            ],
        )
        .answer()
    };
    // Unsecured: no such endpoint. Unknown certificate: refused, and kept in rejected/.
    let (seen, code) = Client::start(
        &url,
        &sim.name,
        &["--user", "mes", "--password", "s3cret-word"],
    )
    .answer();
    assert_eq!(code, Some(3), "unsecured let in: {seen}");
    let (seen, code) = secured("s3cret-word");
    assert_eq!(code, Some(3), "an unknown certificate let in: {seen}");
    let rejected: Vec<_> = std::fs::read_dir(pki.join("rejected"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(rejected.len(), 1, "{rejected:?}");
    let name = rejected[0].file_name().unwrap();
    std::fs::rename(&rejected[0], pki.join("trusted").join(name)).unwrap();
    // Trusted: the login decides.
    let (seen, code) = secured("wrong");
    assert_eq!(code, Some(3), "a wrong password let in: {seen}");
    let (seen, code) = secured("s3cret-word");
    assert_eq!(code, Some(0), "{seen}");
    assert_eq!(seen["machines"], serde_json::json!([sim.name]));
}

#[test]
fn an_unsafe_or_unusable_opcua_address_is_refused_before_anything_listens() {
    let dir = tempfile::tempdir().unwrap();
    let refused = |args: &[&OsStr]| serve_refused(dir.path(), args, false);
    // Beyond loopback without a login: refused naming the flag and the key.
    let stderr = refused(&[OsStr::new("--opcua"), OsStr::new("0.0.0.0:0")]);
    assert!(
        stderr.contains("opcua_user") && stderr.contains("--opcua"),
        "{stderr}"
    );
    // Unsecured beyond loopback, even with a login.
    let open = profile(
        dir.path(),
        "opcua = \"0.0.0.0:0\"\nopcua_security = \"none\"\nopcua_user = \"mes\"\n\
         opcua_password = \"pw\"",
    );
    let stderr = refused(&[OsStr::new("--machine"), open.as_os_str()]);
    assert!(stderr.contains("telemetry.opcua_security"), "{stderr}");
    // A name, not an address of this host.
    let stderr = refused(&[OsStr::new("--opcua"), OsStr::new("lathe3.shop.lan:4840")]);
    assert!(
        stderr.contains("--opcua") && stderr.contains("IP address"),
        "{stderr}"
    );
    // An address in use.
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let at = taken.local_addr().unwrap().to_string();
    let stderr = refused(&[OsStr::new("--opcua"), OsStr::new(&at)]);
    assert!(
        stderr.contains("--opcua") && stderr.contains("cannot listen"),
        "{stderr}"
    );
    // Two machines on one server, secured otherwise.
    let open = named_profile(dir.path(), "lathe-a", "opcua = \"127.0.0.1:0\"");
    let login = named_profile(
        dir.path(),
        "lathe-b",
        "opcua = \"127.0.0.1:0\"\nopcua_user = \"mes\"\nopcua_password = \"pw\"",
    );
    let stderr = refused(&[
        OsStr::new("--machine"),
        open.as_os_str(),
        OsStr::new("--machine"),
        login.as_os_str(),
    ]);
    assert!(
        stderr.contains("lathe-b") && stderr.contains("secured alike"),
        "{stderr}"
    );
    // A secured server with no folder named and no home to keep its certificate in.
    let signed = profile(
        dir.path(),
        "opcua = \"127.0.0.1:0\"\nopcua_security = \"sign\"\nopcua_user = \"mes\"\n\
         opcua_password = \"pw\"",
    );
    let stderr = serve_refused(
        dir.path(),
        &[OsStr::new("--machine"), signed.as_os_str()],
        true,
    );
    assert!(stderr.contains("opcua_pki"), "{stderr}");
}
