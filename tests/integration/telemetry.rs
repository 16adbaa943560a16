//! Live telemetry against a real broker (mosquitto) and an independent subscriber
//! (mosquitto_sub): what a run publishes is what docs/shop.md says; a broker that is down,
//! never answers or refuses the login never slows or stops a run; what the broker missed
//! arrives when it is back, each message once and in order. The same over TLS, with
//! certificates as the logins: `telemetry_tls.rs`, which shares the helpers here.

use std::ffi::OsStr;
use std::io::BufRead;
use std::net::TcpListener;
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use serde_json::Value;
use whirl::config::job::Job;
use whirl::config::machine::MachineProfile;
use whirl::config::telemetry::TelemetrySettings;
use whirl::judge::dry_run::{dry_run, DryRunOptions};
use whirl::log::ExecLog;
use whirl::telemetry::{RunContext, Telemetry};
use whirl::transport::{control, Posted};

use crate::http;
use crate::mosquitto::{on, Got, Mosquitto, Subscriber};
use crate::util;

/// The built-in simulator's profile name, "whirl-sim: simulated XZC whirling lathe", made
/// one topic level by docs/shop.md's rule (lower case, other characters one `-`).
const ROOT: &str = "whirl/whirl-sim-simulated-xzc-whirling-lathe";

/// How long a test waits for messages a broker has taken to reach its subscriber: they
/// come in milliseconds; the margin is a busy host's.
pub(crate) const DELIVERY: Duration = Duration::from_secs(30);

/// mosquitto_sub on `broker`, subscribed to `whirl/#` at QoS 1, each message a line of
/// topic, QoS, retained flag and payload; its lines come over the channel. It is known to
/// be subscribed once a probe published after its start has come back. `extra`: more of
/// its options (over TLS, the CA and the subscriber's certificate and key).
pub(crate) fn mosquitto_sub(
    broker: &Mosquitto,
    extra: &[&str],
) -> (std::process::Child, mpsc::Receiver<String>) {
    let port = broker.port.to_string();
    let mut child = Command::new("mosquitto_sub")
        .args([
            "-h",
            "127.0.0.1",
            "-p",
            &port,
            "-q",
            "1",
            "-t",
            "whirl/#",
            "-F",
            "%t\t%q\t%r\t%p",
        ])
        .args(extra)
        .stdout(Stdio::piped())
        .spawn()
        .expect("mosquitto_sub runs");
    let (lines, receiver) = mpsc::channel();
    let stdout = std::io::BufReader::new(child.stdout.take().unwrap());
    std::thread::spawn(move || {
        for line in stdout.lines().map_while(Result::ok) {
            if lines.send(line).is_err() {
                return;
            }
        }
    });
    (child, receiver)
}

/// One line of mosquitto_sub: (topic, QoS, retained, payload).
pub(crate) fn parse(line: &str) -> (String, u8, bool, Value) {
    let mut fields = line.splitn(4, '\t');
    let mut next = || fields.next().unwrap_or_else(|| panic!("{line}"));
    let topic = next().to_owned();
    let qos = next().parse().unwrap();
    let retained = next() == "1";
    let payload = serde_json::from_str(next()).unwrap_or_else(|e| panic!("{line}: {e}"));
    (topic, qos, retained, payload)
}

/// What mosquitto_sub printed, parsed, up to and with the bridge's goodbye.
pub(crate) fn until_goodbye(lines: &mpsc::Receiver<String>) -> Vec<(String, u8, bool, Value)> {
    let mut got = Vec::new();
    loop {
        let line = lines.recv_timeout(DELIVERY).expect("the goodbye comes");
        let message = parse(&line);
        let goodbye = message.0.ends_with("/status") && message.3["online"] == false;
        got.push(message);
        if goodbye {
            return got;
        }
    }
}

/// Waits until mosquitto_sub has subscribed: publishes a probe until it comes back, with
/// mosquitto_pub's `login` options (over TLS, the CA and a certificate and key).
pub(crate) fn until_subscribed(broker: &Mosquitto, lines: &mpsc::Receiver<String>, login: &[&str]) {
    let started = Instant::now();
    loop {
        assert!(
            started.elapsed() < DELIVERY,
            "mosquitto_sub never subscribed"
        );
        Command::new("mosquitto_pub")
            .args([
                "-h",
                "127.0.0.1",
                "-p",
                &broker.port.to_string(),
                "-t",
                "whirl/probe",
                "-m",
                "{}",
            ])
            .args(login)
            .status()
            .unwrap();
        if let Ok(line) = lines.recv_timeout(Duration::from_millis(200)) {
            assert!(line.starts_with("whirl/probe\t"), "{line}");
            return;
        }
    }
}

/// `whirl dry-run` of the double-start example, its report in `dir`, with `extra`.
pub(crate) fn dry_run_args<'a>(
    dir: &'a std::path::Path,
    extra: &[&'a str],
) -> Vec<std::ffi::OsString> {
    let mut args: Vec<std::ffi::OsString> = vec![
        "dry-run".into(),
        util::example("double-start").into(),
        "--report".into(),
        dir.join("report.json").into(),
    ];
    args.extend(extra.iter().map(Into::into));
    args
}

/// The shop overview's row (`/api/shop`) of the machine publishing as `topic` once it shows
/// a run that completed: the overview is followed as its page follows it, asked again until
/// it shows; the wait's margin is a busy host's.
pub(crate) fn until_the_overview_shows(overview: std::net::SocketAddr, topic: &str) -> Value {
    let started = Instant::now();
    loop {
        let rows = http::request(overview, "GET", "/api/shop", &[], None).json();
        let row = rows
            .as_array()
            .unwrap()
            .iter()
            .find(|r| r["topic"] == topic && r["last"]["completed"] == true)
            .cloned();
        if let Some(row) = row {
            return row;
        }
        assert!(
            started.elapsed() < DELIVERY,
            "the overview never showed the run: {rows}"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// `whirl` with `args` (from [`dry_run_args`]): what it said, and the report it wrote.
pub(crate) fn whirl(args: &[std::ffi::OsString]) -> (std::process::Output, Value) {
    let dir = std::path::Path::new(args[3].as_os_str());
    let refs: Vec<&OsStr> = args.iter().map(|a| a.as_os_str()).collect();
    let output = util::whirl(&refs);
    let report = std::fs::read_to_string(dir)
        .unwrap_or_else(|_| panic!("no report: {}", String::from_utf8_lossy(&output.stderr)));
    (output, serde_json::from_str(&report).unwrap())
}

#[test]
fn a_dry_run_is_published_as_documented_and_mosquitto_sub_reads_it() {
    let Some(broker) = Mosquitto::start() else {
        return;
    };
    let (mut sub, lines) = mosquitto_sub(&broker, &[]);
    until_subscribed(&broker, &lines, &[]);
    let dir = tempfile::tempdir().unwrap();
    let (output, report) = whirl(&dry_run_args(dir.path(), &["--mqtt", &broker.url()]));
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(
        output.stderr.is_empty(),
        "a broker that answers is not mentioned: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    // The bridge's goodbye is its last message; it is acknowledged before whirl ends.
    let got = until_goodbye(&lines);
    let _ = sub.kill();
    for (topic, qos, _, _) in &got {
        assert!(topic.starts_with(&format!("{ROOT}/")), "{topic}");
        let level = topic.rsplit('/').next().unwrap();
        let expected = if level == "progress" { 0 } else { 1 };
        assert_eq!(*qos, expected, "{topic} at QoS {qos}");
    }
    let level = |name: &str| -> Vec<&Value> {
        got.iter()
            .filter(|m| m.0 == format!("{ROOT}/{name}"))
            .map(|m| &m.3)
            .collect()
    };
    // Status: the birth, then the goodbye, of one session.
    let status = level("status");
    assert_eq!(status.len(), 2, "{status:?}");
    assert_eq!(status[0]["online"], true);
    assert_eq!(
        status[0]["machine"],
        "whirl-sim: simulated XZC whirling lathe"
    );
    assert_eq!(status[1]["reason"], "the bridge stopped");
    let session = status[0]["session"].clone();
    assert_eq!(status[1]["session"], session);
    // States and events: one numbering, from 1, each number once.
    let mut numbered: Vec<&Value> = level("state");
    numbered.extend(level("event"));
    let mut seqs: Vec<u64> = numbered
        .iter()
        .map(|m| m["seq"].as_u64().unwrap())
        .collect();
    seqs.sort_unstable();
    assert_eq!(seqs, (1..=seqs.len() as u64).collect::<Vec<_>>());
    assert!(numbered.iter().all(|m| m["session"] == session));
    // The run: started, ended complete, as the job and the report say.
    let events = level("event");
    let kinds: Vec<&str> = events.iter().map(|e| e["kind"].as_str().unwrap()).collect();
    assert_eq!(kinds.first(), Some(&"start"), "{kinds:?}");
    assert_eq!(kinds.last(), Some(&"end"), "{kinds:?}");
    let run = &events[0]["run"];
    assert_eq!(run["kind"], "dry-run");
    assert_eq!(run["transport"], "serial");
    assert_eq!(run["lines"], report["lines"]);
    assert!(run["job"]
        .as_str()
        .unwrap()
        .ends_with("double-start/job.toml"));
    let job = Job::load(&util::example("double-start")).unwrap();
    assert_eq!(run["provenance"]["delta_mm"].as_f64(), Some(job.cut.delta));
    assert_eq!(run["program_sha256"].as_str().map(str::len), Some(64));
    assert_eq!(events.last().unwrap()["completed"], true);
    let last_state = level("state").last().copied().unwrap().clone();
    assert_eq!(last_state["state"], "idle");
    assert_eq!(last_state["last"]["completed"], true);
    // Progress: forward only, at most one each half second (and the last), to 100 %.
    let progress = level("progress");
    let percents: Vec<f64> = progress
        .iter()
        .map(|p| p["percent"].as_f64().unwrap())
        .collect();
    assert!(percents.windows(2).all(|w| w[0] <= w[1]), "{percents:?}");
    assert_eq!(percents.last(), Some(&100.0));
    let wall = report["wall_time_s"].as_f64().unwrap();
    assert!(
        progress.len() as f64 <= (wall / 0.5).ceil() + 2.0,
        "{} progress messages in {wall} s",
        progress.len()
    );
    // What a subscriber that comes later gets at once: the retained status and state.
    let (mut late, lines) = mosquitto_sub(&broker, &["--retained-only", "-W", "5"]);
    let retained: Vec<_> = lines.iter().map(|l| parse(&l)).collect();
    let _ = late.wait();
    let retained_levels: Vec<&str> = retained
        .iter()
        .map(|m| m.0.rsplit('/').next().unwrap())
        .collect();
    assert_eq!(retained_levels.len(), 2, "{retained:?}");
    assert!(
        retained.iter().all(|m| m.2),
        "the retained flag: {retained:?}"
    );
    let find = |level: &str| &retained.iter().find(|m| m.0.ends_with(level)).unwrap().3;
    assert_eq!(find("/status")["online"], false);
    assert_eq!(find("/state"), &last_state);
}

/// The report's figures a run's telemetry must not change.
fn run_figures(report: &Value) -> (Value, Value, Value) {
    (
        report["lines_acked"].clone(),
        report["machine_time_s"].clone(),
        report["within_delta"].clone(),
    )
}

/// Checks that a run whose broker failed it (`what`) went on as if it had none: it succeeded
/// with the figures of the run `without` telemetry, and said once that the broker cannot be
/// reached and the run goes on. What it said, for what the failure was.
pub(crate) fn went_on_without_the_broker(
    output: &std::process::Output,
    report: &Value,
    without: &Value,
    what: &str,
) -> String {
    let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
    assert!(output.status.success(), "{what}: {stderr}");
    assert_eq!(run_figures(report), run_figures(without), "{what}");
    assert_eq!(
        stderr.matches("cannot be reached").count(),
        1,
        "{what}: said once: {stderr}"
    );
    assert!(stderr.contains("the run goes on"), "{what}: {stderr}");
    stderr
}

#[test]
fn a_broker_that_never_answers_neither_slows_nor_stops_the_run() {
    // A port that takes connections and never says a word (a hung broker), and one where
    // nothing listens (a broker down).
    let hung = TcpListener::bind("127.0.0.1:0").unwrap();
    let hung_url = format!("mqtt://{}", hung.local_addr().unwrap());
    std::thread::spawn(move || {
        let held: Vec<_> = hung.incoming().collect();
        drop(held);
    });
    let down = TcpListener::bind("127.0.0.1:0").unwrap();
    let down_url = format!("mqtt://{}", down.local_addr().unwrap());
    drop(down);
    let dir = tempfile::tempdir().unwrap();
    let (plain, without) = whirl(&dry_run_args(dir.path(), &[]));
    assert!(plain.status.success());
    for url in [hung_url, down_url] {
        let (output, report) = whirl(&dry_run_args(dir.path(), &["--mqtt", &url]));
        went_on_without_the_broker(&output, &report, &without, &url);
    }
}

/// A broker that lets in only these users, by their passwords (its password file in `dir`).
fn password_broker(dir: &std::path::Path, logins: &[(&str, &str)]) -> Option<Mosquitto> {
    let passwords = Mosquitto::password_file(dir, logins);
    Mosquitto::with(&format!(
        "allow_anonymous false\npassword_file {}\n",
        passwords.display()
    ))
}

/// The profile `lathe3.toml` in `dir`: the built-in simulator as Lathe 3, reporting to
/// `broker` logged in as lathe3 with its password.
fn lathe3_logged_in(dir: &std::path::Path, broker: &Mosquitto) -> String {
    let sim = std::fs::read_to_string(util::root().join("machine-profiles/sim.toml")).unwrap();
    let profile = util::write(
        dir,
        "lathe3.toml",
        &format!(
            "{sim}\n[telemetry]\nmqtt = \"{}\"\nmachine = \"Lathe 3\"\nuser = \"lathe3\"\n\
             password = \"s3cret-word\"\n",
            broker.url()
        ),
    );
    profile.to_str().unwrap().to_owned()
}

/// `whirl serve --shop` following `mqtt`, its records in `dir`, listening on a free port of
/// loopback (its address the first line it prints); the caller adds the login and stdio.
pub(crate) fn overview(dir: &std::path::Path, mqtt: &str) -> Command {
    let mut command = Command::new(env!("CARGO_BIN_EXE_whirl"));
    command
        .arg("--db")
        .arg(dir.join("shop.sqlite"))
        .args(["serve", "--shop", "--listen", "127.0.0.1:0", "--jobs"])
        .arg(util::root().join("examples"))
        .args(["--mqtt", mqtt]);
    command
}

#[test]
fn a_broker_that_refuses_the_login_is_said_once_and_the_profiles_login_is_let_in() {
    let dir = tempfile::tempdir().unwrap();
    let Some(broker) = password_broker(dir.path(), &[("lathe3", "s3cret-word")]) else {
        return;
    };
    let (output, report) = whirl(&dry_run_args(dir.path(), &["--mqtt", &broker.url()]));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    assert_eq!(report["lines_acked"], report["lines"]);
    assert_eq!(stderr.matches("cannot be reached").count(), 1, "{stderr}");
    assert!(stderr.contains("NotAuthorized"), "{stderr}");
    // The profile's user and password: the run is published.
    let profile = lathe3_logged_in(dir.path(), &broker);
    let subscriber =
        Subscriber::with_login(&broker, "whirl/lathe-3/#", Some(("lathe3", "s3cret-word")));
    let (output, _) = whirl(&dry_run_args(dir.path(), &["--machine", &profile]));
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let got = subscriber.wait(DELIVERY, |got| on(got, "event").len() >= 2);
    let kinds: Vec<&Value> = on(&got, "event").iter().map(|g| &g.json["kind"]).collect();
    assert_eq!(
        kinds.first().copied(),
        Some(&Value::from("start")),
        "{kinds:?}"
    );
}

#[test]
fn the_shop_overview_logs_in_with_its_user_and_the_password_from_the_environment() {
    let dir = tempfile::tempdir().unwrap();
    let logins = [("lathe3", "s3cret-word"), ("overview", "0verview-word")];
    let Some(broker) = password_broker(dir.path(), &logins) else {
        return;
    };
    let mut overview = overview(dir.path(), &broker.url())
        .args(["--mqtt-user", "overview"])
        .env("WHIRL_MQTT_PASSWORD", "0verview-word")
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let overview_at = http::listening(&mut overview);
    let profile = lathe3_logged_in(dir.path(), &broker);
    let (output, report) = whirl(&dry_run_args(dir.path(), &["--machine", &profile]));
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let row = until_the_overview_shows(overview_at, "lathe-3");
    assert_eq!(row["run"]["lines"], report["lines"], "{row}");
    let _ = overview.kill();
    let _ = overview.wait();
    // Not anonymous: the broker let the overview in by its user name.
    let log = broker.log();
    assert!(
        log.lines()
            .any(|l| l.contains(" as whirl-shop-") && l.contains("u'overview'")),
        "{log}"
    );
}

#[test]
fn a_shop_overview_password_without_its_user_is_refused_before_anything_listens() {
    let dir = tempfile::tempdir().unwrap();
    let o = overview(dir.path(), "mqtt://127.0.0.1:1")
        .env("WHIRL_MQTT_PASSWORD", "0verview-word")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{stderr}");
    assert!(
        stderr.contains("WHIRL_MQTT_PASSWORD") && stderr.contains("needs a `user`"),
        "{stderr}"
    );
    assert!(
        o.stdout.is_empty(),
        "it listened: {}",
        String::from_utf8_lossy(&o.stdout)
    );
}

#[test]
fn a_bad_mqtt_url_is_refused_before_anything_runs() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("run.jsonl");
    for (url, says) in [
        ("broker.shop.lan", "not a URL"),
        ("broker:1883", "the scheme must be mqtt://"),
        ("http://broker", "the scheme must be mqtt://"),
        ("mqtt://user:pw@broker", "`user` and `password`"),
    ] {
        let o = util::whirl(&[
            OsStr::new("dry-run"),
            util::example("double-start").as_os_str(),
            OsStr::new("--log"),
            log.as_os_str(),
            OsStr::new("--mqtt"),
            OsStr::new(url),
        ]);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{url}");
        assert!(
            stderr.contains("--mqtt") && stderr.contains(says),
            "{url}: {stderr}"
        );
        assert!(!log.exists(), "{url}: a log was opened");
    }
}

#[test]
fn what_the_broker_missed_while_stopped_arrives_after_once_and_in_order() {
    let Some(mut broker) = Mosquitto::start() else {
        return;
    };
    let subscriber = Subscriber::new(&broker, "whirl/#");
    let job = Job::load(&util::example("double-start")).unwrap();
    let machine = MachineProfile::builtin_sim().unwrap();
    let plan = whirl::plan::plan(&job, &machine).unwrap();
    let posted = Posted::read("double-start", &plan.text, &machine).unwrap();
    let telemetry =
        Telemetry::start(&TelemetrySettings::for_broker(&broker.url()), &machine.name).unwrap();
    let handle = telemetry.handle();
    handle.prepare(RunContext {
        kind: "dry-run".into(),
        ..RunContext::default()
    });
    let log = ExecLog::memory();
    let (control, commands) = control();
    // At 100× the run takes some 16 s, the 30 s the broker is away outlast it: its end
    // too waits for the broker.
    let options = DryRunOptions {
        commands: Some(commands),
        progress: Some(handle.progress(None)),
        time_scale: Some(100.0),
        ..DryRunOptions::default()
    };
    let mut tapped = log.clone().tapped(handle.tap());
    // The operator: once the start has come, the broker stops; the run is held and
    // resumed while it is away; it stays away 30 s.
    let operator = {
        let log = log.clone();
        std::thread::scope(|scope| {
            let operating = scope.spawn(|| {
                subscriber.wait(DELIVERY, |got| !on(got, "event").is_empty());
                broker.stop();
                let stopped = Instant::now();
                let mut follow = util::Follow::new(&log);
                while follow
                    .look()
                    .iter()
                    .all(|r| !matches!(r.event, whirl::log::Event::Executed { .. }))
                {
                    std::thread::sleep(Duration::from_millis(5));
                }
                assert!(control.hold());
                std::thread::sleep(Duration::from_millis(500));
                assert!(control.resume());
                std::thread::sleep(Duration::from_secs(30).saturating_sub(stopped.elapsed()));
                broker.run();
            });
            let report = tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
                .unwrap()
                .block_on(dry_run(
                    &job,
                    plan.ring,
                    &machine,
                    &posted,
                    options,
                    &mut tapped,
                ))
                .expect("the dry run is carried out");
            operating.join().expect("the operator's steps");
            report
        })
    };
    assert!(
        operator.within_delta,
        "the run completed within Δ while its broker was away"
    );
    let got = subscriber.wait(DELIVERY, |got| {
        on(got, "event").iter().any(|g| g.json["kind"] == "end")
    });
    let closed = telemetry.close();
    assert_eq!((closed.dropped, closed.lost), (0, 0));
    let events = on(&got, "event");
    // Each once (a second delivery of a number would be a redelivery, told by its seq) and
    // in order: start, hold, resume, end.
    let mut seqs: Vec<u64> = events
        .iter()
        .map(|g| g.json["seq"].as_u64().unwrap())
        .collect();
    seqs.dedup();
    assert!(seqs.windows(2).all(|w| w[0] < w[1]), "{seqs:?}");
    let kinds: Vec<&str> = events
        .iter()
        .map(|g| g.json["kind"].as_str().unwrap())
        .filter(|k| *k != "feed_override")
        .collect();
    assert_eq!(
        kinds,
        ["start", "hold", "resume", "end"],
        "{}",
        broker.log()
    );
    let states = on(&got, "state");
    let mut numbered: Vec<u64> = states
        .iter()
        .chain(&events)
        .map(|g| g.json["seq"].as_u64().unwrap())
        .collect();
    numbered.sort_unstable();
    numbered.dedup();
    assert_eq!(
        numbered,
        (1..=numbered.len() as u64).collect::<Vec<_>>(),
        "no number missed"
    );
    assert_eq!(states.last().unwrap().json["state"], "idle");
}

#[test]
fn a_bridge_killed_outright_is_shown_offline_by_its_last_will_within_one_and_a_half_keepalives() {
    let Some(broker) = Mosquitto::start() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let sim = std::fs::read_to_string(util::root().join("machine-profiles/sim.toml")).unwrap();
    let profile = util::write(
        dir.path(),
        "lathe.toml",
        &format!(
            "{sim}\n[telemetry]\nmqtt = \"{}\"\nmachine = \"Lathe 7\"\nkeepalive_s = 2\n",
            broker.url()
        ),
    );
    let mut serve = Command::new(env!("CARGO_BIN_EXE_whirl"))
        .arg("--db")
        .arg(dir.path().join("runs.sqlite"))
        .args(["serve", "--listen", "127.0.0.1:0", "--jobs"])
        .arg(util::root().join("examples"))
        .arg("--machine")
        .arg(&profile)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let subscriber = Subscriber::new(&broker, "whirl/lathe-7/#");
    let online =
        |got: &[crate::mosquitto::Got]| on(got, "status").iter().any(|g| g.json["online"] == true);
    let got = subscriber.wait(DELIVERY, online);
    assert!(online(&got), "the bridge never came online");
    // A subscriber that comes later gets the birth at once, retained.
    let birth = on(
        &Subscriber::new(&broker, "whirl/lathe-7/status").wait(DELIVERY, online),
        "status",
    )[0]
    .clone();
    assert!(
        birth.retained && birth.json["keepalive_s"] == 2,
        "{birth:?}"
    );
    serve.kill().unwrap();
    let killed = Instant::now();
    serve.wait().unwrap();
    let got = subscriber.wait(DELIVERY, |got| {
        on(got, "status").iter().any(|g| g.json["online"] == false)
    });
    let will = on(&got, "status")
        .into_iter()
        .find(|g| g.json["online"] == false)
        .expect("the last will")
        .clone();
    assert!(
        will.json["reason"].as_str().unwrap().contains("last will"),
        "{will:?}"
    );
    assert_eq!(will.json["session"], birth.json["session"]);
    // MQTT 3.1.1 §3.1.2.10: the broker ends a connection silent for 1.5 keep-alives and
    // publishes its will. mosquitto looks at its connections once a second, and the margin
    // is that second.
    let after = will.at.duration_since(killed);
    assert!(
        after <= Duration::from_secs_f64(1.5 * 2.0 + 1.0),
        "offline {after:?} after the kill"
    );
}

#[test]
fn a_stream_to_the_machine_is_published_with_its_program_and_what_it_was_planned_from() {
    let Some(broker) = Mosquitto::start() else {
        return;
    };
    let subscriber = Subscriber::new(&broker, "whirl/#");
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("grbl");
    let _sim = util::Sim::serving(
        OsStr::new("--pty"),
        &link,
        &[OsStr::new("--time-scale"), OsStr::new("50")],
    );
    let (program, lines) = util::short_planned_program(dir.path());
    let log = dir.path().join("exec.jsonl");
    let url = broker.url();
    let o = util::whirl(&[
        OsStr::new("stream"),
        program.as_os_str(),
        OsStr::new("--port"),
        link.as_os_str(),
        OsStr::new("--log"),
        log.as_os_str(),
        OsStr::new("--mqtt"),
        OsStr::new(&url),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let got = subscriber.wait(DELIVERY, |got| {
        on(got, "event").iter().any(|g| g.json["kind"] == "end")
    });
    let events = on(&got, "event");
    let run = &events[0].json["run"];
    assert_eq!(events[0].json["kind"], "start");
    assert_eq!(run["kind"], "stream");
    assert_eq!(run["transport"], "serial");
    assert_eq!(run["lines"], lines.len());
    assert!(
        run["program"].as_str().unwrap().ends_with("short.nc"),
        "{run}"
    );
    // The program's header says what it was planned from: the example and the simulator.
    assert!(
        run["provenance"]["job"]["path"]
            .as_str()
            .unwrap()
            .ends_with("double-start/job.toml"),
        "{run}"
    );
    assert_eq!(
        run["provenance"]["machine_name"],
        "whirl-sim: simulated XZC whirling lathe"
    );
    let end = events.iter().find(|g| g.json["kind"] == "end").unwrap();
    assert_eq!(end.json["completed"], true);
}

#[test]
fn a_runs_end_handed_over_just_before_the_bridge_closes_is_published_before_its_goodbye() {
    let Some(broker) = Mosquitto::start() else {
        return;
    };
    let subscriber = Subscriber::new(&broker, "whirl/#");
    let machine = MachineProfile::builtin_sim().unwrap();
    let telemetry =
        Telemetry::start(&TelemetrySettings::for_broker(&broker.url()), &machine.name).unwrap();
    let handle = telemetry.handle();
    handle.prepare(RunContext {
        kind: "dry-run".into(),
        ..RunContext::default()
    });
    // A run's events handed over faster than the thread takes them, the bridge closing
    // at once: the thread finds its close and the run's events waiting together.
    let overrides: Vec<u16> = (0..100).map(|k| 50 + k % 2 * 10).collect();
    let tap = handle.tap();
    let mut log = ExecLog::memory().tapped(tap);
    log.write(
        0.0,
        whirl::log::Event::Start {
            program: "job.nc".into(),
            lines: 10,
            transport: "serial".into(),
        },
    )
    .unwrap();
    for &percent in &overrides {
        let state = whirl::log::FeedOverrideState::Running;
        log.write(0.0, whirl::log::Event::FeedOverride { percent, state })
            .unwrap();
    }
    log.write(
        0.0,
        whirl::log::Event::End {
            completed: true,
            reason: None,
        },
    )
    .unwrap();
    drop(log);
    let closed = telemetry.close();
    assert_eq!((closed.undelivered, closed.lost), (0, 0), "{closed:?}");
    let got = subscriber.wait(DELIVERY, |got| {
        on(got, "status").iter().any(|m| m.json["online"] == false)
    });
    let after_birth: Vec<&Got> = got.iter().filter(|m| !m.retained).collect();
    let kinds: Vec<&str> = after_birth
        .iter()
        .filter(|m| m.topic.ends_with("/event"))
        .map(|m| m.json["kind"].as_str().unwrap())
        .collect();
    let mut expected = vec!["start"];
    expected.extend(std::iter::repeat_n("feed_override", overrides.len()));
    expected.push("end");
    assert_eq!(kinds, expected);
    let last = after_birth.last().unwrap();
    assert!(
        last.topic.ends_with("/status") && last.json["reason"] == "the bridge stopped",
        "the goodbye is the last message: {:?}",
        last.topic
    );
}
