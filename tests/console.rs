//! `whirl serve`, the operator's console, end to end: its refusals over HTTP (no token
//! beyond loopback, actions without the token, paths out of the jobs folder, a busy
//! machine, also against `whirl stream`), its runs in the run records and a stream to a
//! machine (`whirl-sim` on a pseudo-terminal), and a real headless Chromium driven through
//! chromedriver (WebDriver) through dry runs over serial, Modbus and CAN with Hold, Resume,
//! the feed override, Stop, a resume at the offered line and the runs found in the
//! history.
//!
//! Every `whirl` here records its runs in a database of the test's own (`WHIRL_DB`).
//!
//! Chromium and chromedriver come from Debian (`.ci/run` installs them). With `CI` set, a
//! missing browser fails the browser test; without it the test says it skipped.
//! Screenshots of each page go to `target/console-screenshots/`.

mod console {
    pub mod http;
    pub mod webdriver;
}
#[path = "integration/mosquitto.rs"]
#[allow(dead_code)]
mod mosquitto;

use console::http::{self, request, Answer};
use console::webdriver::Session;
use std::net::{SocketAddr, TcpListener};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};
use whirl::records::Timestamp;

const TOKEN: &str = "shop-floor-token-0123";
const JOB: &str = "trapezoidal/job.toml";

fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// A `whirl serve` of this test, ended when dropped.
struct Serve {
    child: Child,
    addr: SocketAddr,
    /// The folder of its locks (and anything else the test writes).
    dir: tempfile::TempDir,
    /// The page key its own page's actions carry (from `/api/session`).
    key: String,
}

impl Serve {
    /// `whirl serve` on a free loopback port with the examples as its jobs and `args`.
    fn start(args: &[&str]) -> Serve {
        let dir = tempfile::tempdir().unwrap();
        Serve::start_in(dir, args)
    }

    fn start_in(dir: tempfile::TempDir, args: &[&str]) -> Serve {
        Serve::start_with_jobs(dir, &repo().join("examples"), args)
    }

    /// `whirl serve` with the jobs in `jobs`, its locks and records in `dir`.
    fn start_with_jobs(dir: tempfile::TempDir, jobs: &Path, args: &[&str]) -> Serve {
        Serve::start_with_env(dir, jobs, args, &[])
    }

    /// `whirl serve` as [`Serve::start_with_jobs`], with `env` set beside (and over) what
    /// that sets.
    fn start_with_env(
        dir: tempfile::TempDir,
        jobs: &Path,
        args: &[&str],
        env: &[(&str, &std::ffi::OsStr)],
    ) -> Serve {
        let mut child = Command::new(env!("CARGO_BIN_EXE_whirl"))
            .args(["serve", "--listen", "127.0.0.1:0", "--jobs"])
            .arg(jobs)
            .args(args)
            .env("WHIRL_LOCK_DIR", dir.path().join("locks"))
            .env("WHIRL_DB", dir.path().join("runs.sqlite"))
            .envs(env.iter().copied())
            .current_dir(dir.path())
            .stdout(Stdio::piped())
            .stderr(std::fs::File::create(dir.path().join("serve.err")).unwrap())
            .spawn()
            .unwrap();
        let addr = http::listening(&mut child);
        let session = request(addr, "GET", "/api/session", &[], None).json();
        let key = session["page_key"].as_str().unwrap().to_owned();
        Serve {
            child,
            addr,
            dir,
            key,
        }
    }

    fn get(&self, path: &str) -> Answer {
        self.get_with(path, &[])
    }

    fn get_with(&self, path: &str, headers: &[(&str, &str)]) -> Answer {
        request(self.addr, "GET", path, headers, None)
    }

    /// A POST as the console's own page sends it: with the page key.
    fn post(&self, path: &str, headers: &[(&str, &str)], body: &str) -> Answer {
        let mut headers = headers.to_vec();
        headers.push(("X-Whirl-Page", &self.key));
        request(self.addr, "POST", path, &headers, Some(body))
    }

    fn url(&self) -> String {
        format!("http://{}/", self.addr)
    }

    /// What it has said on standard error (its refusals among it).
    fn said(&self) -> String {
        std::fs::read_to_string(self.dir.path().join("serve.err")).unwrap_or_default()
    }
}

impl Drop for Serve {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        if std::thread::panicking() {
            eprintln!("whirl serve said:\n{}", self.said());
        }
    }
}

fn run_request(machine: &str, scale: f64) -> String {
    serde_json::json!({"machine": machine, "job": JOB, "transport": "serial", "time_scale": scale})
        .to_string()
}

#[test]
fn beyond_loopback_without_a_token_it_refuses_to_start() {
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_whirl"))
        .args(["serve", "--listen", "0.0.0.0:0", "--jobs"])
        .arg(repo().join("examples"))
        .env("WHIRL_LOCK_DIR", dir.path())
        .env("WHIRL_DB", dir.path().join("runs.sqlite"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("reachable from other hosts"), "{stderr}");
    assert!(stderr.contains("--token"), "{stderr}");
    // Nothing said it listened.
    assert!(!String::from_utf8_lossy(&out.stdout).contains("http://"));
    // A token too short is refused too.
    let out = Command::new(env!("CARGO_BIN_EXE_whirl"))
        .args([
            "serve",
            "--listen",
            "0.0.0.0:0",
            "--token",
            "short",
            "--jobs",
        ])
        .arg(repo().join("examples"))
        .env("WHIRL_DB", dir.path().join("runs.sqlite"))
        .output()
        .unwrap();
    assert!(String::from_utf8_lossy(&out.stderr).contains("at least 16"));
    // Refused before the records were opened.
    assert!(!dir.path().join("runs.sqlite").exists());
}

#[test]
fn actions_need_the_token_and_reading_does_not() {
    let serve = Serve::start(&["--token", TOKEN]);
    let machines = serve.get("/api/machines").json();
    let machine = machines[0].as_str().unwrap().to_owned();
    assert!(serve
        .get("/api/jobs")
        .json()
        .as_array()
        .unwrap()
        .contains(&JOB.into()));
    let plan = serde_json::json!({"job": JOB, "machine": machine}).to_string();
    let refused = serve.post("/api/plan", &[], &plan);
    assert_eq!(refused.status, 401, "{}", refused.body);
    let wrong = serve.post(
        "/api/plan",
        &[("X-Whirl-Token", "shop-floor-token-0124")],
        &plan,
    );
    assert_eq!(wrong.status, 401);
    for path in ["/api/runs", "/api/runs/x/hold", "/api/verify"] {
        assert_eq!(serve.post(path, &[], &plan).status, 401, "{path}");
    }
    let planned = serve.post("/api/plan", &[("X-Whirl-Token", TOKEN)], &plan);
    assert_eq!(planned.status, 200, "{}", planned.body);
    assert!(planned.json()["segments"].as_u64().unwrap() > 0);
    // The history's list is read by anyone; one run's record, with the files it read, only
    // with the token (asked before the record is looked for: this console has run nothing).
    assert_eq!(serve.get("/api/history").status, 200);
    assert_eq!(serve.get("/api/history/1").status, 401);
    let with_token = serve.get_with("/api/history/1", &[("X-Whirl-Token", TOKEN)]);
    assert_eq!(with_token.status, 404, "{}", with_token.body);
    // The login form (with the page key its page carries) opens a session, whose random id
    // the cookie holds: never the token itself.
    let login = serve.post(
        "/login",
        &[("Content-Type", "application/x-www-form-urlencoded")],
        &format!("token={TOKEN}&page={}", serve.key),
    );
    let cookie = login.header("set-cookie").expect("a cookie").to_owned();
    assert!(cookie.contains("HttpOnly") && cookie.contains("SameSite=Strict"));
    assert!(!cookie.contains(TOKEN), "{cookie}");
    assert!(
        cookie.starts_with(&format!("whirl_session_{}=", serve.addr.port())),
        "{cookie}"
    );
    let pair = cookie.split(';').next().unwrap();
    assert_eq!(
        serve.post("/api/plan", &[("Cookie", pair)], &plan).status,
        200
    );
    let bad = serve.post(
        "/login",
        &[("Content-Type", "application/x-www-form-urlencoded")],
        &format!("token=guess&page={}", serve.key),
    );
    assert_eq!(bad.status, 401);
    assert!(bad.header("set-cookie").is_none());
}

#[test]
fn job_paths_out_of_the_jobs_folder_are_refused() {
    let serve = Serve::start(&[]);
    let machine = serve.get("/api/machines").json()[0]
        .as_str()
        .unwrap()
        .to_owned();
    let outside = repo().join("Cargo.toml").display().to_string();
    for (job, says) in [
        ("../Cargo.toml", "steps out of the jobs folder"),
        (
            "trapezoidal/../../Cargo.toml",
            "steps out of the jobs folder",
        ),
        (outside.as_str(), "absolute path"),
    ] {
        let body = serde_json::json!({"job": job, "machine": machine}).to_string();
        let answer = serve.post("/api/plan", &[], &body);
        assert_eq!(answer.status, 400, "{job}: {}", answer.body);
        assert!(
            answer.json()["error"].as_str().unwrap().contains(says),
            "{}",
            answer.body
        );
        let run = serde_json::json!({"machine": machine, "job": job, "transport": "serial", "time_scale": 1.0});
        assert_eq!(serve.post("/api/runs", &[], &run.to_string()).status, 400);
    }
    assert!(serve.get("/api/runs").json().as_array().unwrap().is_empty());
}

#[test]
fn a_busy_machine_refuses_a_second_run_and_a_stream_from_another_terminal() {
    let dir = tempfile::tempdir().unwrap();
    // A machine on a serial port (a plain file here: nothing opens it while it is locked).
    let port = dir.path().join("ttyUSB7");
    std::fs::write(&port, "").unwrap();
    let profile = lathe_on(dir.path(), "lathe 7", &port);
    let serve = Serve::start_in(dir, &["--machine", profile.to_str().unwrap()]);
    let first = serve.post("/api/runs", &[], &run_request("lathe 7", 0.5));
    assert_eq!(first.status, 200, "{}", first.body);
    let second = serve.post("/api/runs", &[], &run_request("lathe 7", 0.5));
    assert_eq!(second.status, 409, "{}", second.body);
    assert!(second.body.contains("is busy"), "{}", second.body);
    // `whirl stream` to the same machine, from another terminal.
    let stream = Command::new(env!("CARGO_BIN_EXE_whirl"))
        .arg("stream")
        .arg(repo().join("examples").join(JOB))
        .arg("--machine")
        .arg(&profile)
        .arg("--log")
        .arg(serve.dir.path().join("stream.log"))
        .env("WHIRL_LOCK_DIR", serve.dir.path().join("locks"))
        .env("WHIRL_DB", serve.dir.path().join("runs.sqlite"))
        .current_dir(serve.dir.path())
        .output()
        .unwrap();
    assert!(!stream.status.success());
    let stderr = String::from_utf8_lossy(&stream.stderr);
    assert!(stderr.contains("is busy"), "{stderr}");
    assert!(
        stderr.contains(&format!("process {}", serve.child.id())),
        "{stderr}"
    );
    assert!(
        stderr.contains("console run of trapezoidal/job.toml"),
        "{stderr}"
    );
    // Refused before the log was opened.
    assert!(!serve.dir.path().join("stream.log").exists());
    // Stopped, the machine is free again.
    let stop = serve.post("/api/runs/lathe%207/stop", &[], "{}");
    assert_eq!(stop.status, 200, "{}", stop.body);
    wait_for(Duration::from_secs(60), "the run to end", || {
        serve.get("/api/runs").json()[0]["phase"] == "ended"
    });
    let again = serve.post("/api/runs", &[], &run_request("lathe 7", 100.0));
    assert_eq!(again.status, 200, "{}", again.body);
}

#[test]
fn the_feed_override_needs_the_token_a_run_and_a_value_within_the_cap() {
    let serve = Serve::start(&["--token", TOKEN]);
    let machine = serve.get("/api/machines").json()[0]
        .as_str()
        .unwrap()
        .to_owned();
    let token = [("X-Whirl-Token", TOKEN)];
    let path = format!("/api/runs/{}/feed-override", machine.replace(' ', "%20"));
    let ask = |percent: u16| serde_json::json!({ "percent": percent }).to_string();
    // No run: nothing to override.
    let idle = serve.post(&path, &token, &ask(90));
    assert_eq!(idle.status, 409, "{}", idle.body);
    assert!(idle.body.contains("has no run going"), "{}", idle.body);
    // A dry run at half real time: running throughout the test.
    let started = serve.post("/api/runs", &token, &run_request(&machine, 0.5));
    assert_eq!(started.status, 200, "{}", started.body);
    // Without the token: refused before the request is read.
    let anonymous = serve.post(&path, &[], &ask(90));
    assert_eq!(anonymous.status, 401, "{}", anonymous.body);
    // Above the cap: refused, naming the cap and why it is there.
    let cap = feed_cap(&plan_of(&serve, JOB, &machine, &token));
    let view = |serve: &Serve| serve.get("/api/runs").json()[0].clone();
    let reason = view(&serve)["feed"]["cap"]["reason"]
        .as_str()
        .unwrap()
        .to_owned();
    assert!(reason.contains("insert cusp"), "{reason}");
    let above = serve.post(&path, &token, &ask(cap + 1));
    assert_eq!(above.status, 422, "{}", above.body);
    assert_eq!(
        above.json()["error"],
        format!(
            "a feed override of {} % is above the cap of {cap} %: {reason}",
            cap + 1
        )
    );
    // Below grbl's slowest (MIN_FEED_RATE_OVERRIDE, 10 %): refused too.
    let below = serve.post(&path, &token, &ask(9));
    assert_eq!(below.status, 422, "{}", below.body);
    assert!(below.body.contains("below 10 %"), "{}", below.body);
    // The refusals asked nothing.
    assert_eq!(view(&serve)["feed"]["asked"], 100);
    // Within the cap: asked, and the simulated grbl runs at it (its Ov: read back).
    let within = serve.post(&path, &token, &ask(90));
    assert_eq!(within.status, 200, "{}", within.body);
    assert_eq!(within.json()["percent"], 90);
    wait_for(Duration::from_secs(60), "the controller at 90 %", || {
        view(&serve)["feed"]["running"] == 90
    });
    // Seen running at 90 % by now: it began no later (the page shows what the log said).
    let seen_90 = Timestamp::now();
    // A step past the controller's slowest is held there, saying why (the keys' rule).
    let step = serve.post(&path, &token, r#"{"step": -1000}"#);
    assert_eq!(step.status, 200, "{}", step.body);
    assert_eq!(step.json()["percent"], 10);
    wait_for(Duration::from_secs(60), "the controller at 10 %", || {
        view(&serve)["feed"]["running"] == 10
    });
    let seen_10 = Timestamp::now();
    assert!(
        step.json()["held"]
            .as_str()
            .unwrap()
            .contains("the slowest grbl's range takes"),
        "{}",
        step.body
    );
    // Stopped, the run takes no more.
    let stop = serve.post(
        &format!("/api/runs/{}/stop", machine.replace(' ', "%20")),
        &token,
        "{}",
    );
    assert_eq!(stop.status, 200, "{}", stop.body);
    wait_for(Duration::from_secs(60), "the run to end", || {
        view(&serve)["phase"] == "ended"
    });
    assert_eq!(serve.post(&path, &token, &ask(90)).status, 409);
    // The run's record says every override the controller ran at, in order: 90 %, then
    // grbl's 10 % steps (0x92, each read back from Ov:) down to 10 %.
    let record = view(&serve)["record"].as_i64().expect("recorded");
    let run = serve
        .get_with(&format!("/api/history/{record}"), &token)
        .json();
    let overrides: Vec<i64> = run["notes"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|n| n["kind"] == "feed-override")
        .map(|n| n["code"].as_i64().unwrap())
        .collect();
    assert_eq!(overrides, [90, 80, 70, 60, 50, 40, 30, 20, 10], "{run}");
    // Each noted when the controller began to run at it, not when the run stopped: 90 %
    // before the test saw it (and so before it asked the steps down and the stop), each
    // step after the one before and before the test saw 10 %, all before the run ended.
    let at = |n: &serde_json::Value| Timestamp::parse(n["at"].as_str().unwrap()).unwrap();
    let noted: Vec<Timestamp> = run["notes"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|n| n["kind"] == "feed-override")
        .map(at)
        .collect();
    let ended = Timestamp::parse(run["ended_at"].as_str().unwrap()).unwrap();
    assert!(
        noted[0] <= seen_90,
        "90 % noted at {:?}, seen at {seen_90:?}: {run}",
        noted[0]
    );
    assert!(noted.windows(2).all(|w| w[0] <= w[1]), "{run}");
    assert!(noted[8] <= seen_10 && seen_10 < ended, "{run}");
}

#[test]
fn a_console_whose_postgresql_is_down_keeps_its_runs_and_their_holds_in_the_spool() {
    let dir = tempfile::tempdir().unwrap();
    // The shop's PostgreSQL, down: a loopback port nothing listens on.
    let port = TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let db = format!("postgres://whirl@127.0.0.1:{port}/shop");
    let home = dir.path().join("home");
    let spool = home
        .join(".local/share/whirl")
        .join(whirl::records::spool::file_name(&db));
    let serve = Serve::start_with_env(
        dir,
        &repo().join("examples"),
        &["--token", TOKEN],
        &[("WHIRL_DB", db.as_ref()), ("HOME", home.as_os_str())],
    );
    // It serves, saying where its runs are kept meanwhile.
    assert!(
        serve.said().contains(&spool.display().to_string()),
        "{}",
        serve.said()
    );
    // Its history cannot be read, and says which database.
    let history = serve.get("/api/history");
    assert_eq!(history.status, 503, "{}", history.body);
    assert!(history.body.contains("127.0.0.1"), "{}", history.body);
    let machine = serve.get("/api/machines").json()[0]
        .as_str()
        .unwrap()
        .to_owned();
    let token = [("X-Whirl-Token", TOKEN)];
    let view = |serve: &Serve| serve.get("/api/runs").json()[0].clone();
    // A dry run at half real time, held once it runs, then stopped.
    let started = serve.post("/api/runs", &token, &run_request(&machine, 0.5));
    assert_eq!(started.status, 200, "{}", started.body);
    wait_for(Duration::from_secs(60), "the run to run a line", || {
        view(&serve)["line"].as_u64().is_some_and(|l| l > 1)
    });
    let press = |button: &str| {
        serve.post(
            &format!("/api/runs/{}/{button}", machine.replace(' ', "%20")),
            &token,
            "{}",
        )
    };
    let held = press("hold");
    assert_eq!(held.status, 200, "{}", held.body);
    let stopped = press("stop");
    assert_eq!(stopped.status, 200, "{}", stopped.body);
    wait_for(Duration::from_secs(60), "the run to end", || {
        view(&serve)["phase"] == "ended"
    });
    // The page shows no number that is not the shop's, and says where the record is.
    let ended = view(&serve);
    assert_eq!(
        (&ended["record"], &ended["spooled"]),
        (&serde_json::Value::Null, &serde_json::Value::Bool(true)),
        "{ended}"
    );
    assert!(
        ended["messages"]
            .as_array()
            .unwrap()
            .iter()
            .any(|m| m.as_str().unwrap().contains(&spool.display().to_string())),
        "{ended}"
    );
    // The spool is a records database of its own: the run in it, its hold and its stop.
    let spooled = Command::new(env!("CARGO_BIN_EXE_whirl"))
        .args(["runs", "show", "1", "--json", "--db"])
        .arg(&spool)
        .output()
        .unwrap();
    assert!(
        spooled.status.success(),
        "{}",
        String::from_utf8_lossy(&spooled.stderr)
    );
    let run: serde_json::Value = serde_json::from_slice(&spooled.stdout).unwrap();
    assert_eq!(
        (&run["kind"], &run["outcome"]),
        (&"serve".into(), &"stopped".into())
    );
    let kinds: Vec<&str> = run["notes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| n["kind"].as_str().unwrap())
        .collect();
    assert_eq!(kinds.first(), Some(&"hold"), "{run}");
    assert_eq!(kinds.last(), Some(&"stop"), "{run}");
}

fn wait_for(limit: Duration, what: &str, mut done: impl FnMut() -> bool) {
    let start = Instant::now();
    while !done() {
        assert!(start.elapsed() < limit, "waited {limit:?} for {what}");
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// The programs of a browser test, if the host has them.
fn browser() -> Option<(PathBuf, PathBuf)> {
    let find = |names: &[&str]| {
        let path = std::env::var_os("PATH")?;
        std::env::split_paths(&path)
            .flat_map(|dir| names.iter().map(move |n| dir.join(n)))
            .find(|p| p.is_file())
    };
    let chromium = find(&["chromium", "chromium-browser"]);
    let driver = find(&["chromedriver"]);
    match (chromium, driver) {
        (Some(c), Some(d)) => Some((c, d)),
        _ if std::env::var_os("CI").is_some() => {
            panic!("CI is set and chromium or chromedriver is missing: .ci/run installs them")
        }
        _ => {
            eprintln!("skipped: chromium and chromedriver are not installed (apt-get install chromium chromium-driver)");
            None
        }
    }
}

/// chromedriver on a free loopback port, ended when dropped.
struct Driver(Child, SocketAddr);

impl Driver {
    fn start(program: &Path) -> Driver {
        let port = TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let child = Command::new(program)
            .arg(format!("--port={port}"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let addr: SocketAddr = format!("127.0.0.1:{port}").parse().unwrap();
        wait_for(Duration::from_secs(30), "chromedriver", || {
            std::net::TcpStream::connect(addr).is_ok()
                && request(addr, "GET", "/status", &[], None).json()["value"]["ready"] == true
        });
        Driver(child, addr)
    }
}

impl Drop for Driver {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Where the screenshots go: `target/console-screenshots/`.
fn screenshots() -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .parent()
        .unwrap()
        .join("console-screenshots");
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Saves the page as `name`.png, after checking it is a PNG of the window's size.
fn shoot(session: &Session, name: &str) -> PathBuf {
    let png = session.screenshot();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n", "a PNG");
    // IHDR: width and height, big-endian, at bytes 16 and 20.
    let width = u32::from_be_bytes(png[16..20].try_into().unwrap());
    assert!(width >= 1000, "the window's width, {width}");
    let path = screenshots().join(format!("{name}.png"));
    std::fs::write(&path, png).unwrap();
    eprintln!("screenshot: {}", path.display());
    path
}

/// The first number in `text`.
fn first_number(text: &str) -> Option<usize> {
    text.split(|c: char| !c.is_ascii_digit())
        .find(|s| !s.is_empty())?
        .parse()
        .ok()
}

/// The fastest feed override a plan allows, from its report: the insert cusp grows with
/// the square of the feed (the workpiece turns further between two insert hits while the
/// ring keeps its speed), and may grow into its share of Δ, the planned cusp and what the
/// plan leaves of Δ unspent; in whole percent, at most 200 % (grbl's
/// `MAX_FEED_RATE_OVERRIDE`, which the Modbus map and the CANopen bridge take too), and
/// never under the plan's own 100 %.
fn feed_cap(plan: &serde_json::Value) -> u16 {
    let figure = |key: &str| {
        plan[key]
            .as_f64()
            .unwrap_or_else(|| panic!("{key}: {plan}"))
    };
    let (cusp, held, delta) = (
        figure("cusp_mm"),
        figure("max_error_mm"),
        figure("delta_mm"),
    );
    let share = cusp + (delta - held).max(0.0);
    let by_cusp = (100.0 * (share / cusp).sqrt()).floor();
    by_cusp.clamp(100.0, 200.0) as u16
}

/// The plan report of `job` on `machine`, as the console plans it.
fn plan_of(serve: &Serve, job: &str, machine: &str, headers: &[(&str, &str)]) -> serde_json::Value {
    let body = serde_json::json!({"job": job, "machine": machine}).to_string();
    let answer = serve.post("/api/plan", headers, &body);
    assert_eq!(answer.status, 200, "{}", answer.body);
    answer.json()
}

#[test]
fn the_console_in_a_browser_runs_holds_resumes_stops_and_resumes_at_the_line() {
    let Some((chromium, chromedriver)) = browser() else {
        return;
    };
    let serve = Serve::start(&[]);
    let driver = Driver::start(&chromedriver);
    let page = Session::new(driver.1, chromium.to_str().unwrap());
    let long = Duration::from_secs(120);

    // Jobs: every example listed, one planned and verified from the page.
    page.open(&format!("{}#jobs", serve.url()));
    let row = format!("tr[data-job=\"{JOB}\"]");
    page.wait("the jobs listed", long, |p| {
        (p.script("return document.querySelectorAll('#jobs-table tbody tr').length")
            .as_u64()
            >= Some(4))
        .then_some(())
    });
    page.click(&format!("{row} button[id^=plan]"));
    page.click(&format!("{row} button[id^=verify]"));
    let verified = page.wait("the verify result", long, |p| {
        let text = p
            .script(&format!(
                "return document.querySelector('{row} .job-verify').textContent"
            ))
            .as_str()
            .unwrap_or_default()
            .to_owned();
        text.contains("Δ").then_some(text)
    });
    assert!(verified.starts_with("within Δ"), "{verified}");
    let segments = page
        .script(&format!(
            "return document.querySelector('{row} .job-segments').textContent"
        ))
        .as_str()
        .and_then(first_number);
    assert!(segments > Some(0));
    assert!(page.displayed("#jobs-table"));
    shoot(&page, "jobs");

    // Run: the example dry-run at 50 times real time (17 minutes of machine time), held,
    // resumed, its feed overridden, stopped and resumed at the offered line.
    let machine = serve.get("/api/machines").json()[0]
        .as_str()
        .unwrap()
        .to_owned();
    let cap = feed_cap(&plan_of(&serve, JOB, &machine, &[]));
    let line = dry_run_sequence(&page, &serve, None, JOB, "serial", "50", cap, true);
    shoot(&page, "run-completed");
    found_in_history(&page, &serve, JOB, "serial", line, true);

    // Groove: the executed section against the target, with the Δ band.
    page.open(&format!("{}#groove", serve.url()));
    page.wait("the groove plot", long, |p| {
        p.script("return document.querySelector('#groove-plot svg') !== null")
            .as_bool()
            .filter(|&b| b)
    });
    let svg = page
        .script("return document.getElementById('groove-plot').innerHTML")
        .as_str()
        .unwrap_or_default()
        .to_owned();
    for label in ["target", "machined", "Δ band"] {
        assert!(svg.contains(label), "the groove plot shows {label}");
    }
    shoot(&page, "groove");
    eprintln!("screenshots of every page in {}", screenshots().display());
}

/// The groove page of a run cut part way, at 1920×1080 and 1280×800: the Δ band drawn,
/// and the radius axis within the groove's own radii (the stock not yet cut, drawn as
/// machined and magnified, once made it span ±2 500 mm), with a screenshot of each.
fn groove_mid_run(page: &Session, serve: &Serve, job: &str) {
    let groove = whirl::config::job::Job::load(&repo().join("examples").join(job)).unwrap();
    let (rho_min, rho_max) = groove.profile.radius_range();
    page.open(&format!("{}#groove", serve.url()));
    for (width, height) in [(1920, 1080), (1280, 800)] {
        page.resize(width, height);
        let svg = page.wait("the groove mid-run", Duration::from_secs(60), |p| {
            p.script(
                "const s = document.querySelector('#groove-plot svg'); return s && s.outerHTML",
            )
            .as_str()
            .map(str::to_owned)
        });
        assert!(
            svg.contains("Δ band") && svg.contains("not cut yet"),
            "{svg}"
        );
        // The radius axis's tick labels (the text anchored at its end).
        let ticks: Vec<f64> = svg
            .split("text-anchor=\"end\">")
            .skip(1)
            .filter_map(|t| t.split('<').next()?.parse().ok())
            .collect();
        assert!(ticks.len() >= 2, "{svg}");
        for tick in &ticks {
            assert!(
                (rho_min - 1.0..=rho_max + 1.0).contains(tick),
                "a radius tick at {tick} mm, the groove spanning {rho_min}–{rho_max} mm"
            );
        }
        shoot(page, &format!("groove-mid-run-{width}x{height}"));
    }
    page.resize(1280, 1100);
    page.open(&format!("{}#run", serve.url()));
}

/// The run page's program lines: the one executing marked, and the same as the program
/// line shown, in one render.
fn program_around_the_line(page: &Session, long: Duration) {
    let (marked, line) = page.wait("the line executing", long, |p| {
        let both = p.script(
            "const l = document.querySelector('#run-around li.executing'); \
             return l && [l.value, document.getElementById('run-line').textContent]",
        );
        let marked = both[0].as_u64()?;
        Some((marked, both[1].as_str()?.to_owned()))
    });
    assert_eq!(first_number(&line), Some(marked as usize), "{line}");
}

/// Whether the run page shows the machine standing held, in its transport's words: grbl's
/// `Hold:0` (the hold complete, the machine at rest), the Modbus register map's `Held`,
/// the CANopen master's word once every drive stands on the path (drives report no state
/// of the job).
fn held_shown(page: &Session, transport: &str) -> bool {
    match transport {
        "serial" => page.text("run-state").starts_with("Hold:0"),
        "modbus-tcp" | "modbus-rtu" => page.text("run-state") == "Held",
        _ => page
            .text("run-messages")
            .contains("the drives stand on the path"),
    }
}

/// On the run page: dry-runs `job` over `transport` at `scale` on `machine` (the first if
/// `None`), watches progress advance, holds (the simulator stands, [`held_shown`], and
/// nothing advances), resumes, sets a feed override within the run's `cap` and sees the
/// controller run at it, is refused one above the cap with the cap's reason, goes back to
/// 100 %, stops, and resumes at the offered line to the end, the cut as a whole within Δ.
/// Gives the line it resumed at.
#[allow(clippy::too_many_arguments)]
fn dry_run_sequence(
    page: &Session,
    serve: &Serve,
    machine: Option<&str>,
    job: &str,
    transport: &str,
    scale: &str,
    cap: u16,
    shots: bool,
) -> usize {
    let long = Duration::from_secs(120);
    page.open(&format!("{}#run", serve.url()));
    page.wait("the run form", long, |p| {
        (p.script("return document.getElementById('run-job').options.length")
            .as_u64()
            >= Some(1))
        .then_some(())
    });
    if let Some(machine) = machine {
        page.script(&format!(
            "const m = document.getElementById('run-machine'); m.value = {machine:?}; \
             m.dispatchEvent(new Event('change'));"
        ));
    }
    page.script(&format!(
        "document.getElementById('run-job').value = {job:?}; \
         document.getElementById('run-transport').value = {transport:?}; \
         document.getElementById('run-scale').value = {scale:?};"
    ));
    page.click("#run-start");
    let done = |p: &Session| first_number(&p.text("run-done"));
    page.wait("the run to start", long, |p| {
        p.text("run-title").contains("(running)").then_some(())
    });
    let first = page.wait("progress", long, |p| done(p).filter(|&n| n > 0));
    page.wait("progress to advance", long, |p| {
        done(p).filter(|&n| n > first)
    });
    assert_eq!(page.text("run-banner-word"), "RUNNING");
    // The program around the line executing, that line marked: one render's both. (Only a
    // grbl controller reports the line it executes; the fieldbus ones count segments and
    // set-points.)
    if transport == "serial" {
        program_around_the_line(page, long);
    }
    assert!(page.script("return document.getElementById('btn-resume').disabled") == true);
    if shots {
        shoot(page, "run-running");
    }

    // Hold, by the space bar: the simulator holds and stands; the page says so in its
    // banner and title, and offers Resume, not Hold.
    page.script(
        "document.dispatchEvent(new KeyboardEvent('keydown', {code: 'Space', key: ' '})); return 0",
    );
    page.wait("the hold", long, |p| held_shown(p, transport).then_some(()));
    let held = (page.text("run-position"), done(page));
    std::thread::sleep(Duration::from_secs(1));
    assert_eq!((page.text("run-position"), done(page)), held, "held still");
    assert!(page.text("run-title").contains("(held)"));
    assert!(held_shown(page, transport));
    page.wait("the banner to say held", long, |p| {
        (p.text("run-banner-word") == "HELD").then_some(())
    });
    assert!(page.script("return document.getElementById('btn-hold').disabled") == true);
    let left = page.text("run-left");
    assert!(left.contains("(held: waiting)"), "{left}");
    if shots {
        shoot(page, "run-held");
        groove_mid_run(page, serve, job);
    }

    // Resume: running again.
    page.click("#btn-resume");
    let resumed = held.1.unwrap_or(0);
    page.wait("progress after the resume", long, |p| {
        done(p).filter(|&n| n > resumed)
    });

    // The feed override: offered up to the cap, with why it stops there.
    assert!(page.displayed("#feed"));
    let offered = page.text("feed-cap");
    assert!(
        offered.starts_with(&format!("Offered from 10 % up to the cap of {cap} %: ")),
        "{offered}"
    );
    let reason = offered.split_once(" %: ").unwrap().1.to_owned();
    assert!(reason.contains("insert cusp"), "{reason}");
    // Slower, within the cap: the controller runs at it, as it reports.
    let set = |percent: u16| {
        page.script(&format!(
            "document.getElementById('feed-percent').value = '{percent}';"
        ));
        page.click("#feed-set");
    };
    set(90);
    page.wait("the controller at 90 %", long, |p| {
        p.text("feed-running")
            .starts_with("in effect: 90 %")
            .then_some(())
    });
    // Above the cap: refused, naming the cap and why.
    set(cap + 1);
    let refused = page.wait("the refusal", long, |p| {
        Some(p.text("feed-error")).filter(|t| !t.is_empty())
    });
    assert_eq!(
        refused,
        format!(
            "a feed override of {} % is above the cap of {cap} %: {reason}",
            cap + 1
        )
    );
    assert!(page.text("feed-running").starts_with("in effect: 90 %"));
    if shots {
        shoot(page, "run");
    }
    // Back to the program's feed.
    page.click("#feed-reset");
    page.wait("the controller at 100 %", long, |p| {
        p.text("feed-running")
            .starts_with("in effect: 100 %")
            .then_some(())
    });
    assert_eq!(page.text("feed-error"), "");

    // Stop, asked twice: the first press only asks; the run ends, offering where to
    // resume, and the page says it is stopped, not held, and measures nothing of a part
    // cut part way.
    page.click("#btn-stop");
    assert!(page.displayed("#stop-confirm"));
    std::thread::sleep(Duration::from_millis(500));
    assert!(
        page.text("run-title").contains("(running)"),
        "one press stops nothing"
    );
    page.click("#btn-stop-confirm");
    page.wait("the run to end", long, |p| {
        p.text("run-title").contains("(ended)").then_some(())
    });
    assert!(page.text("run-outcome").starts_with("stopped"));
    assert_eq!(page.text("run-banner-word"), "STOPPED");
    assert_eq!(page.text("run-state"), "– (the run has ended)");
    assert!(page.text("run-measured").starts_with("not measured"));
    page.wait("the resume offer", long, |p| {
        p.displayed("#resume-offer").then_some(())
    });
    let offered = page.text("btn-resume-at");
    let line = first_number(&offered).expect("a line to resume at");
    assert!(page.text("run-outcome").starts_with("stopped"));
    if shots {
        shoot(page, "run-stopped");
    }

    // Resume there: re-entered along the groove, it completes.
    page.click("#btn-resume-at");
    page.wait(
        "the resumed run to complete",
        Duration::from_secs(300),
        |p| (p.text("run-outcome") == "completed").then_some(()),
    );
    assert!(
        page.text("run-title")
            .contains(&format!("resumed at line {line}")),
        "{}",
        page.text("run-title")
    );
    let done_text = page.text("run-done");
    let total = first_number(done_text.split("of").nth(1).unwrap_or_default());
    assert_eq!(done(page), total, "every line");
    // Stopped and resumed along the groove, the cut as a whole is within Δ.
    let measured = page.wait("the cut measured", long, |p| {
        Some(p.text("run-measured")).filter(|t| t != "–")
    });
    assert!(measured.starts_with("within Δ"), "{transport}: {measured}");
    line
}

/// On the history page: the runs of `job` searched for, newest first: the resume
/// completed, from line `line`, continuing the stopped run, which resumes at that line,
/// both over `transport`.
fn found_in_history(
    page: &Session,
    serve: &Serve,
    job: &str,
    transport: &str,
    line: usize,
    shots: bool,
) {
    let long = Duration::from_secs(60);
    page.open(&format!("{}#history", serve.url()));
    page.script(&format!(
        "document.getElementById('history-job').value = {job:?}; \
         document.getElementById('history-outcome').value = '';"
    ));
    page.click("#history-search");
    let rows = |p: &Session| {
        p.script(
            "return [...document.querySelectorAll('#history-table tbody tr')] \
             .map(r => [...r.cells].map(c => c.textContent))",
        )
    };
    let found = page.wait("the runs in the history", long, |p| {
        let rows = rows(p);
        (rows.as_array().map_or(0, Vec::len) >= 2).then_some(rows)
    });
    // Run, kind, sent to, outcome, started, took, machine, host, job, transport, resume
    // at, why.
    let (resume, stopped) = (&found[0], &found[1]);
    assert_eq!(resume[1], "serve", "{found}");
    // Dry runs: sent to the simulator, not to a machine.
    assert_eq!(resume[2], "simulator (dry run)", "{found}");
    assert_eq!(stopped[2], "simulator (dry run)", "{found}");
    assert_eq!(resume[3], "completed", "{found}");
    assert_eq!(stopped[3], "stopped", "{found}");
    // The host each ran on: a shop's database holds every bridge's runs.
    let host = whirl::records::Process::current().host;
    assert_eq!(
        (&resume[7], &stopped[7]),
        (&host.as_str().into(), &host.as_str().into())
    );
    assert_eq!(stopped[10], line.to_string(), "{found}");
    assert!(resume[8].as_str().unwrap().contains(job), "{found}");
    assert_eq!(
        (&resume[9], &stopped[9]),
        (&transport.into(), &transport.into()),
        "{found}"
    );
    // Searched by outcome in the server: the stopped run only.
    page.script("document.getElementById('history-outcome').value = 'stopped';");
    page.click("#history-search");
    page.wait("the stopped runs", long, |p| {
        let rows = rows(p);
        let all = rows.as_array()?;
        (!all.is_empty() && all.iter().all(|r| r[3] == "stopped")).then_some(())
    });
    page.script("document.getElementById('history-outcome').value = '';");
    page.click("#history-search");
    page.wait("every run again", long, |p| {
        (rows(p).as_array().map_or(0, Vec::len) >= 2).then_some(())
    });
    // One run in full: the resume, continuing the stopped run.
    page.click("#history-table tbody tr:first-child");
    let resumed = page.wait("the run's record", long, |p| {
        let text = p.text("history-run-figures");
        text.contains("Resumed at").then_some(text)
    });
    let stopped_id = stopped[0].as_str().unwrap();
    assert!(
        resumed.contains(&format!("line {line}, continuing run {stopped_id}")),
        "{resumed}"
    );
    assert!(resumed.contains("Program"), "{resumed}");
    assert!(page.displayed("#history-run"));
    if shots {
        shoot(page, "history");
    }
}

/// A short job for the fieldbus runs: the example's thread over 4 mm instead of 40.
fn short_jobs(dir: &Path) -> PathBuf {
    let jobs = dir.join("jobs");
    std::fs::create_dir_all(jobs.join("short")).unwrap();
    let text = std::fs::read_to_string(repo().join("examples").join(JOB)).unwrap();
    assert!(text.contains("length = 40.0"));
    std::fs::write(
        jobs.join("short/job.toml"),
        text.replace("length = 40.0", "length = 4.0"),
    )
    .unwrap();
    jobs
}

/// A fieldbus dry run in the browser: 4 mm of the example's thread on the machine of
/// `profile` over `transport` at 50 times real time, through the whole sequence
/// ([`dry_run_sequence`]), and both runs found in the history.
fn fieldbus_in_a_browser(profile: &str, transport: &str) {
    let Some((chromium, chromedriver)) = browser() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let jobs = short_jobs(dir.path());
    let profile = repo().join("machine-profiles").join(profile);
    let serve = Serve::start_with_jobs(dir, &jobs, &["--machine", profile.to_str().unwrap()]);
    let machine = serve.get("/api/machines").json()[0]
        .as_str()
        .unwrap()
        .to_owned();
    let job = "short/job.toml";
    let cap = feed_cap(&plan_of(&serve, job, &machine, &[]));
    let driver = Driver::start(&chromedriver);
    let page = Session::new(driver.1, chromium.to_str().unwrap());
    let line = dry_run_sequence(
        &page,
        &serve,
        Some(&machine),
        job,
        transport,
        "50",
        cap,
        false,
    );
    found_in_history(&page, &serve, job, transport, line, false);
    // In the records: the resume completed, the stopped run resuming where it did.
    let runs = serve.get("/api/history?job=short").json();
    let runs: Vec<(&str, &str, Option<u64>)> = runs
        .as_array()
        .unwrap()
        .iter()
        .map(|r| {
            (
                r["transport"].as_str().unwrap(),
                r["outcome"].as_str().unwrap(),
                r["resume_at"].as_u64(),
            )
        })
        .collect();
    let line = Some(line as u64);
    assert_eq!(
        runs,
        [(transport, "completed", None), (transport, "stopped", line)]
    );
}

#[test]
fn the_console_in_a_browser_runs_holds_stops_and_resumes_a_modbus_dry_run() {
    fieldbus_in_a_browser("sim.toml", "modbus-tcp");
}

#[test]
fn the_console_in_a_browser_runs_holds_stops_and_resumes_a_can_dry_run() {
    fieldbus_in_a_browser("canopen-drives.toml", "can-slcan");
}

/// `whirl-sim` serving a grblHAL controller on a pseudo-terminal it makes at `link`, at 50
/// times real time, killed when dropped.
struct Sim(Child);

impl Sim {
    fn serving(link: &Path) -> Sim {
        Sim::serving_with(link, &[])
    }

    /// As [`Sim::serving`], with more of `whirl-sim`'s options.
    fn serving_with(link: &Path, args: &[&std::ffi::OsStr]) -> Sim {
        let child = Command::new(env!("CARGO_BIN_EXE_whirl-sim"))
            .arg("--pty")
            .arg(link)
            .args(["--time-scale", "50"])
            .args(args)
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let sim = Sim(child);
        wait_for(Duration::from_secs(10), "whirl-sim's pty", || link.exists());
        sim
    }
}

impl Drop for Sim {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

#[test]
fn a_stream_to_the_machine_goes_over_its_profiles_connection_and_is_recorded() {
    let dir = tempfile::tempdir().unwrap();
    let jobs = short_jobs(dir.path());
    let tty = dir.path().join("ttyWHIRL");
    let _sim = Sim::serving(&tty);
    let profile = lathe_on(dir.path(), "lathe 9", &tty);
    let serve = Serve::start_with_jobs(
        dir,
        &jobs,
        &["--machine", profile.to_str().unwrap(), "--token", TOKEN],
    );
    let request =
        serde_json::json!({"machine": "lathe 9", "job": "short/job.toml", "stream": true})
            .to_string();
    // Streaming needs the token.
    assert_eq!(serve.post("/api/runs", &[], &request).status, 401);
    let started = serve.post("/api/runs", &[("X-Whirl-Token", TOKEN)], &request);
    assert_eq!(started.status, 200, "{}", started.body);
    wait_for(Duration::from_secs(240), "the stream to end", || {
        serve.get("/api/runs").json()[0]["phase"] == "ended"
    });
    let view = &serve.get("/api/runs").json()[0];
    assert_eq!(view["outcome"], "completed", "{view}");
    assert!(
        view["transport"]
            .as_str()
            .unwrap()
            .contains(&format!("serial to the machine ({}", tty.display())),
        "{view}"
    );
    // In the records: a serve run of the machine, to its port, completed.
    let record = view["record"].as_i64().expect("recorded");
    let run = serve
        .get_with(
            &format!("/api/history/{record}"),
            &[("X-Whirl-Token", TOKEN)],
        )
        .json();
    assert_eq!(run["kind"], "serve", "{run}");
    assert_eq!(run["outcome"], "completed", "{run}");
    assert_eq!(run["machine"], "lathe 9", "{run}");
    assert!(
        run["port"]
            .as_str()
            .unwrap()
            .contains(&tty.display().to_string()),
        "{run}"
    );
    assert_eq!(run["measured"], serde_json::Value::Null, "{run}");
    // Its provenance: the console streams what it plans, from the job's bytes as read.
    let provenance = &run["provenance"];
    assert_eq!(provenance["check"], "planned", "{run}");
    assert_eq!(provenance["header"]["machine_name"], "lathe 9", "{run}");
    let job_sha256: String = {
        use sha2::Digest;
        let bytes = std::fs::read(jobs.join("short/job.toml")).unwrap();
        sha2::Sha256::digest(bytes)
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect()
    };
    assert_eq!(provenance["header"]["job"]["sha256"], job_sha256, "{run}");
    // Searched by machine and outcome in the server.
    let found = serve
        .get("/api/history?machine=LATHE%209&outcome=completed")
        .json();
    assert_eq!(found.as_array().unwrap().len(), 1, "{found}");
    let none = serve.get("/api/history?outcome=stopped").json();
    assert!(none.as_array().unwrap().is_empty(), "{none}");
    let bad = serve.get("/api/history?outcome=done");
    assert_eq!(bad.status, 400);
    assert!(bad.body.contains("outcome \\\"done\\\""), "{}", bad.body);
    assert_eq!(
        serve
            .get_with("/api/history/999", &[("X-Whirl-Token", TOKEN)])
            .status,
        404
    );
}

/// A machine profile named `name`: the simulator's, its `[connection]` the serial port at
/// `tty`; written into `dir`.
fn lathe_on(dir: &Path, name: &str, tty: &Path) -> PathBuf {
    let profile = dir.join("lathe.toml");
    let text = std::fs::read_to_string(repo().join("machine-profiles/sim.toml")).unwrap();
    std::fs::write(
        &profile,
        format!(
            "{}\n[connection]\ntransport = \"serial\"\nport = \"{}\"\n",
            text.replace(
                "name = \"whirl-sim: simulated XZC whirling lathe\"",
                &format!("name = \"{name}\"")
            ),
            tty.display()
        ),
    )
    .unwrap();
    profile
}

/// The SHA-256 of `bytes`, lower-case hex.
fn sha256(bytes: &[u8]) -> String {
    use sha2::Digest;
    sha2::Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// The run page's buttons, enabled or not: Hold, Resume, Stop.
fn buttons(page: &Session) -> [bool; 3] {
    let enabled = page.script(
        "return ['btn-hold', 'btn-resume', 'btn-stop'].map(id => !document.getElementById(id).disabled)",
    );
    let at = |i: usize| enabled[i].as_bool().unwrap();
    [at(0), at(1), at(2)]
}

/// The run page in the state whose banner says `word` (coloured as `class`), with Hold,
/// Resume and Stop `enabled` as given, checked at 1920×1080 and 1280×800 and saved as
/// `run-{state}-{width}x{height}.png`: nothing wider than the window (no sideways
/// scrolling), and at the tablet's size every button a touch target of at least 48 CSS
/// pixels each way (Material Design's and WCAG 2.5.5's size for a finger).
fn state_at_both_sizes(page: &Session, state: &str, word: &str, class: &str, enabled: [bool; 3]) {
    for (width, height) in [(1920, 1080), (1280, 800)] {
        page.resize(width, height);
        page.wait(word, Duration::from_secs(120), |p| {
            (p.text("run-banner-word") == word).then_some(())
        });
        let banner = page.script("return document.getElementById('run-banner').className");
        assert_eq!(banner, format!("banner {class}"), "{state}");
        // Its words readable on its colour: WCAG 2.1's contrast ratio for large text (the
        // banner's is over 24 px), at least 3:1, from the two colours as drawn.
        let contrast = page.script(
            "const s = getComputedStyle(document.getElementById('run-banner-word')); \
             const b = getComputedStyle(document.getElementById('run-banner')); \
             const lum = (c) => { const v = c.match(/[0-9.]+/g).slice(0, 3).map(Number) \
               .map((x) => x / 255).map((x) => x <= 0.03928 ? x / 12.92 : \
               Math.pow((x + 0.055) / 1.055, 2.4)); \
               return 0.2126 * v[0] + 0.7152 * v[1] + 0.0722 * v[2]; }; \
             const [l1, l2] = [lum(s.color), lum(b.backgroundColor)]; \
             return (Math.max(l1, l2) + 0.05) / (Math.min(l1, l2) + 0.05);",
        );
        assert!(
            contrast.as_f64() >= Some(3.0),
            "{state} at {width}×{height}: the banner's words contrast {contrast}:1 with it"
        );
        assert_eq!(buttons(page), enabled, "{state} at {width}×{height}");
        let overflow =
            page.script("return [document.documentElement.scrollWidth, window.innerWidth]");
        assert!(
            overflow[0].as_u64() <= overflow[1].as_u64(),
            "{state} at {width}×{height}: the page is {} px wide in a {} px window",
            overflow[0],
            overflow[1]
        );
        if width == 1280 {
            let sizes = page.script(
                "return [...document.querySelectorAll('.buttons button')] \
                 .filter(b => b.offsetParent !== null) \
                 .map(b => { const r = b.getBoundingClientRect(); return [b.id, r.width, r.height]; })",
            );
            let sizes = sizes.as_array().unwrap();
            assert!(sizes.len() >= 3, "{sizes:?}");
            for size in sizes {
                assert!(
                    size[1].as_f64() >= Some(48.0) && size[2].as_f64() >= Some(48.0),
                    "{state}: {size} is smaller than a 48 px touch target"
                );
            }
        }
        shoot(page, &format!("run-{state}-{width}x{height}"));
    }
}

/// The run page an operator reads at a glance, in the four states they meet: running,
/// held, in alarm and stopped, each at 1920×1080 and 1280×800 (a desk and a tablet), with a
/// screenshot of each; beside it, what the page says of itself: how the console is reached
/// and guarded (no secret shown), who holds the machine's lock since when, what the
/// program was planned from (the job's and the machine profile's hashes, Δ and the
/// installation angle), the history telling a dry run from a stream with each one's
/// duration, and a job's TOML error on lines of its own.
///
/// The alarm is the simulator's Δ guard (`ALARM:64`): the console streams the job to a
/// `whirl-sim` whose guard measures the cut against the same groove held to a Δ of
/// 0.1 µm, which the plan (made for the job's 10 µm) exceeds as soon as it cuts.
#[test]
fn the_run_page_reads_at_a_glance_running_held_in_alarm_and_stopped_at_both_sizes() {
    let Some((chromium, chromedriver)) = browser() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let jobs = short_jobs(dir.path());
    let job = "short/job.toml";
    let job_bytes = std::fs::read(jobs.join(job)).unwrap();
    // A job with TOML errors: a value with no closing quote, and keys the schema lacks.
    std::fs::create_dir_all(jobs.join("broken")).unwrap();
    std::fs::write(
        jobs.join("broken/job.toml"),
        "[groove]\nlead = \"14\nstarts = 2\n[spindle]\nrpm = 3\n",
    )
    .unwrap();
    let tight = dir.path().join("tight.toml");
    let text = String::from_utf8(job_bytes.clone()).unwrap();
    assert!(text.contains("delta = 0.01\n"));
    std::fs::write(&tight, text.replace("delta = 0.01\n", "delta = 0.0001\n")).unwrap();
    let tty = dir.path().join("ttyWHIRL");
    let _sim = Sim::serving_with(&tty, &["--job".as_ref(), tight.as_os_str()]);
    let profile = lathe_on(dir.path(), "lathe 9", &tty);
    let profile_sha = sha256(&std::fs::read(&profile).unwrap());
    let serve = Serve::start_with_jobs(dir, &jobs, &["--machine", profile.to_str().unwrap()]);
    let driver = Driver::start(&chromedriver);
    let page = Session::new(driver.1, chromium.to_str().unwrap());
    let long = Duration::from_secs(120);
    page.open(&format!("{}#run", serve.url()));
    page.wait("the run form", long, |p| {
        (p.script("return document.getElementById('run-job').options.length")
            .as_u64()
            >= Some(2))
        .then_some(())
    });

    // How the console is reached and guarded: on loopback, the names it answers to, no
    // token; the page key (a secret of the page) not shown.
    let safety = page.wait("the safety line", long, |p| {
        Some(p.text("safety")).filter(|t| t.contains("Loopback"))
    });
    let port = serve.addr.port();
    assert!(
        safety.starts_with(&format!("Loopback only (127.0.0.1:{port})"))
            && safety.contains(&format!("localhost:{port}"))
            && safety.contains("no token"),
        "{safety}"
    );
    assert!(!safety.contains(&serve.key), "{safety}");
    page.wait("the machine's lock, free", long, |p| {
        p.text("run-lock").starts_with("Machine free").then_some(())
    });

    // A TOML error keeps its lines: the position, the source line and the caret under it.
    page.script("document.getElementById('run-job').value = 'broken/job.toml';");
    page.click("#run-start");
    let lines = page.wait("the TOML error", long, |p| {
        let lines = p.script(
            "const e = document.getElementById('run-error'); \
             const line = parseFloat(getComputedStyle(e).lineHeight); \
             return e.textContent && [e.innerText.split('\\n').length, \
                                      Math.round(e.getBoundingClientRect().height / line)]",
        );
        lines
            .as_array()
            .map(|l| (l[0].as_u64().unwrap(), l[1].as_u64().unwrap()))
    });
    let error = page.text("run-error");
    assert!(
        error.contains("broken/job.toml") && error.contains("line 2"),
        "{error}"
    );
    assert!(lines.0 >= 3 && lines.1 >= 3, "{lines:?} lines: {error}");
    shoot(&page, "run-toml-error");

    // Running: a dry run of 4 mm of the example at 10× real time.
    page.script(&format!(
        "document.getElementById('run-job').value = {job:?}; \
         document.getElementById('run-transport').value = 'serial'; \
         document.getElementById('run-scale').value = '10';"
    ));
    page.click("#run-start");
    let done = |p: &Session| first_number(&p.text("run-done"));
    let first = page.wait("progress", long, |p| done(p).filter(|&n| n > 0));
    let running_seen = Instant::now();
    page.wait("progress to advance", long, |p| {
        done(p).filter(|&n| n > first)
    });
    assert_eq!(page.text("run-error"), "");
    state_at_both_sizes(&page, "running", "RUNNING", "run", [true, false, true]);
    // Stop asks first, on the page, its buttons as large.
    page.click("#btn-stop");
    assert!(page.displayed("#stop-confirm"));
    let confirm = page.script(
        "const r = document.getElementById('btn-stop-confirm').getBoundingClientRect(); \
         return [r.right <= window.innerWidth, r.height]",
    );
    assert_eq!(confirm[0], true, "{confirm}");
    shoot(&page, "run-stop-confirm-1280x800");
    page.click("#btn-stop-cancel");
    assert!(!page.displayed("#stop-confirm"));
    // Who holds the machine, since when: this console's run, started from this page.
    let lock = page.wait("the machine's lock, held", long, |p| {
        Some(p.text("run-lock")).filter(|t| t.starts_with("Machine locked"))
    });
    assert!(
        lock.contains("console run of short/job.toml started by 127.0.0.1:")
            && lock.contains(" since ")
            && lock.contains(&format!("process {}", serve.child.id())),
        "{lock}"
    );
    // What the program was planned from: the job's and the profile's hashes (short), Δ and
    // the installation angle of the job.
    let planned = page.text("run-provenance");
    for fact in [
        format!("from job {job} (sha256 {}…)", &sha256(&job_bytes)[..12]),
        format!(
            "for machine lathe 9 (profile sha256 {}…)",
            &profile_sha[..12]
        ),
        "planned Δ 0.01 mm".to_owned(),
        "installation angle 7.800°".to_owned(),
    ] {
        assert!(planned.contains(&fact), "{fact}: {planned}");
    }

    // Held: Resume and Stop, not Hold.
    page.click("#btn-hold");
    page.wait("the hold", long, |p| held_shown(p, "serial").then_some(()));
    state_at_both_sizes(&page, "held", "HELD", "held", [false, true, true]);

    // Stopped: nothing to press but the resume offered. The run had started before the
    // test saw it progress, and ends after Stop is pressed.
    page.click("#btn-stop");
    let stop_pressed = Instant::now();
    page.click("#btn-stop-confirm");
    state_at_both_sizes(&page, "stopped", "STOPPED", "held", [false, false, false]);
    assert!(page.displayed("#resume-offer"));
    page.wait("the machine's lock, free again", long, |p| {
        p.text("run-lock").starts_with("Machine free").then_some(())
    });

    // In alarm: streamed to the machine, whose Δ guard stops it; nothing to press once the
    // run has ended.
    page.click("#run-stream");
    page.wait("the stream to start", long, |p| {
        p.text("run-title").contains("to the machine").then_some(())
    });
    page.wait("the stream to end", Duration::from_secs(240), |p| {
        p.text("run-title").contains("(ended)").then_some(())
    });
    state_at_both_sizes(&page, "alarm", "ALARM", "alarm", [false, false, false]);
    let todo = page.text("run-banner-todo");
    assert!(todo.starts_with("ALARM:64"), "{todo}");
    assert!(todo.contains("clear the alarm at the machine"), "{todo}");

    // The history: the dry run on the simulator, the stream to the machine, and how long
    // each took; the dry run no shorter than the test watched it go.
    page.resize(1920, 1080);
    page.open(&format!("{}#history", serve.url()));
    let rows = page.wait("both runs in the history", long, |p| {
        let rows = p.script(
            "return [...document.querySelectorAll('#history-table tbody tr')] \
             .map(r => [...r.cells].map(c => c.textContent))",
        );
        (rows.as_array().map_or(0, Vec::len) >= 2).then_some(rows)
    });
    let (stream, dry) = (&rows[0], &rows[1]);
    assert_eq!(stream[2], "MACHINE (stream)", "{rows}");
    assert_eq!(dry[2], "simulator (dry run)", "{rows}");
    for row in [stream, dry] {
        assert!(row[5].as_str().unwrap().ends_with(" s"), "{rows}");
    }
    let runs = serve.get("/api/history").json();
    let watched = stop_pressed.duration_since(running_seen).as_secs_f64();
    let took = runs[1]["duration_s"].as_f64().unwrap();
    assert_eq!(runs[1]["mode"], "dry-run", "{runs}");
    assert_eq!(runs[0]["mode"], "stream", "{runs}");
    // The record's times are whole milliseconds: 2 ms for the two ends.
    assert!(
        took >= watched - 0.002,
        "took {took} s, watched {watched} s"
    );
    shoot(&page, "history-modes");
}

// ---------------------------------------------------------------------------------------
// Attacks: requests that must change nothing (docs/console.md, "Security").

/// A dry run of the trapezoidal example at real time on `serve` (minutes long, so it runs
/// through every attack), and its machine's name; the run's id.
fn long_run(serve: &Serve, headers: &[(&str, &str)]) -> (String, u64) {
    let machine = serve.get("/api/machines").json()[0]
        .as_str()
        .unwrap()
        .to_owned();
    let started = serve.post("/api/runs", headers, &run_request(&machine, 1.0));
    assert_eq!(started.status, 200, "{}", started.body);
    let id = started.json()["id"].as_u64().unwrap();
    (machine, id)
}

/// That `serve`'s run `id` on `machine` goes on as it was: the same run, running, never
/// held (a hold or resume pressed would be noted in its record), no other run started.
fn untouched(serve: &Serve, machine: &str, id: u64, headers: &[(&str, &str)]) {
    let views = serve.get("/api/runs").json();
    let view = views
        .as_array()
        .unwrap()
        .iter()
        .find(|v| v["machine"] == machine)
        .unwrap_or_else(|| panic!("no run on {machine}: {views}"))
        .clone();
    assert_eq!(view["id"], id, "{view}");
    assert_eq!(view["phase"], "running", "{view}");
    let state = view["state"].as_str().unwrap_or_default();
    assert!(!state.starts_with("Hold"), "{view}");
    let record = view["record"].as_u64().expect("the run's record");
    let shown = serve
        .get_with(&format!("/api/history/{record}"), headers)
        .json();
    assert_eq!(shown["notes"].as_array().map(Vec::len), Some(0), "{shown}");
}

#[test]
fn requests_from_other_origins_and_hosts_change_nothing_and_are_said() {
    let serve = Serve::start(&[]);
    let (machine, id) = long_run(&serve, &[]);
    let port = serve.addr.port();
    let other = "http://127.0.0.1:18490";
    let rebound = format!("evil.example:{port}");
    let actions = ["hold", "stop", "resume", "resume-at"];
    for button in actions {
        let path = format!("/api/runs/{}/{button}", machine.replace(' ', "%20"));
        for (headers, status) in [
            // A simple request from another site: no page key.
            (
                vec![
                    ("Content-Type", "text/plain"),
                    ("Origin", "http://evil.example"),
                ],
                403,
            ),
            (
                vec![
                    ("Content-Type", "application/x-www-form-urlencoded"),
                    ("Sec-Fetch-Site", "cross-site"),
                ],
                403,
            ),
            // Another port of this host, with a key it guessed.
            (
                vec![("Origin", other), ("X-Whirl-Page", "0".repeat(32).as_str())],
                403,
            ),
            // The console's own key from another origin (a leaked key is no pass).
            (
                vec![("Origin", other), ("X-Whirl-Page", serve.key.as_str())],
                403,
            ),
            // A rebound name: the right key, the wrong Host.
            (
                vec![
                    ("Host", rebound.as_str()),
                    ("X-Whirl-Page", serve.key.as_str()),
                ],
                403,
            ),
        ] {
            let answer = request(serve.addr, "POST", &path, &headers, Some("{}"));
            assert_eq!(
                answer.status, status,
                "{button} {headers:?}: {}",
                answer.body
            );
        }
        // No action by GET.
        let answer = serve.get(&path);
        assert_eq!(answer.status, 405, "GET {button}: {}", answer.body);
    }
    // Reading under a rebound name is refused too: the page, its key, the runs, the jobs and
    // what a job's profile shows.
    for path in [
        "/",
        "/api/session",
        "/api/runs",
        "/api/events",
        "/api/jobs",
        "/api/profile?job=job.toml",
    ] {
        let answer = serve.get_with(path, &[("Host", &rebound)]);
        assert_eq!(answer.status, 403, "{path}: {}", answer.body);
        assert!(!answer.body.contains(&serve.key), "{path}");
    }
    untouched(&serve, &machine, id, &[]);
    // Every answer keeps the page out of frames and says what it is.
    let page = serve.get("/");
    assert_eq!(page.header("x-frame-options"), Some("DENY"));
    assert!(page
        .header("content-security-policy")
        .is_some_and(|csp| csp.contains("frame-ancestors 'none'")));
    assert_eq!(page.header("x-content-type-options"), Some("nosniff"));
    // Each refusal is said, with the client's address.
    let said = serve.said();
    assert!(
        said.contains(&format!(
            "refused POST /api/runs/{}/hold from 127.0.0.1:",
            machine.replace(' ', "%20")
        )),
        "{said}"
    );
    assert!(said.contains(&format!("not to Host {rebound}")), "{said}");
}

#[test]
fn the_login_is_slowed_after_five_wrong_tokens_and_weak_tokens_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    for weak in ["aaaaaaaaaaaaaaaa", "abababababababababab"] {
        let out = Command::new(env!("CARGO_BIN_EXE_whirl"))
            .args([
                "serve",
                "--listen",
                "127.0.0.1:0",
                "--token",
                weak,
                "--jobs",
            ])
            .arg(repo().join("examples"))
            .env("WHIRL_DB", dir.path().join("runs.sqlite"))
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success());
        assert!(stderr.contains("different characters"), "{stderr}");
    }
    let serve = Serve::start(&["--token", TOKEN]);
    let form = [("Content-Type", "application/x-www-form-urlencoded")];
    let guess = |token: &str| {
        serve.post(
            "/login",
            &form,
            &format!("token={token}&page={}", serve.key),
        )
    };
    // Five wrong tokens are told wrong; the sixth, at once, is not even tried: not the
    // right token either, until the bucket has a try again (2 s a try).
    for k in 0..5 {
        assert_eq!(guess(&format!("guess-{k}")).status, 401);
    }
    let slowed = guess(TOKEN);
    assert_eq!(slowed.status, 429, "{}", slowed.body);
    assert!(slowed.header("set-cookie").is_none());
    // A login without the page key (a form on another site) is refused before the token
    // is looked at.
    let keyless = serve.post("/login", &form, &format!("token={TOKEN}"));
    assert_eq!(keyless.status, 403, "{}", keyless.body);
    wait_for(Duration::from_secs(10), "a login try again", || {
        guess(TOKEN).status == 303
    });
    assert!(serve
        .said()
        .contains("a wrong access token from 127.0.0.1:"));
}

/// A page of another origin, served on a free loopback port for as long as the test
/// process lives: `html` for every request.
fn attacker(html: String) -> u16 {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    std::thread::spawn(move || {
        for stream in listener.incoming() {
            let Ok(mut stream) = stream else { continue };
            let mut head = [0u8; 4096];
            let _ = std::io::Read::read(&mut stream, &mut head);
            let answer = format!(
                "HTTP/1.1 200 OK\r\nContent-Type: text/html\r\nContent-Length: {}\r\n\
                 Connection: close\r\n\r\n{html}",
                html.len()
            );
            let _ = std::io::Write::write_all(&mut stream, answer.as_bytes());
        }
    });
    port
}

/// The attacker's page: every way a page may send a request without asking, to each of
/// `console`'s actions on `machine` (a form of each encoding into a hidden frame, `fetch`
/// with each simple body and the browser's cookies, an image, a beacon), a JSON `fetch`
/// that would need a preflight, and the console framed under it. Its title is `done`
/// once every request has gone.
fn attack_page(console: &str, machine: &str) -> String {
    let machine = machine.replace(':', "%3A").replace(' ', "%20");
    let mut urls: Vec<String> = ["hold", "stop", "resume", "resume-at"]
        .iter()
        .map(|b| format!("{console}/api/runs/{machine}/{b}"))
        .collect();
    urls.push(format!("{console}/api/runs"));
    attack_of(console, &urls, machine.as_str())
}

/// The attacker's page of [`attack_page`], sending to `urls`, `console` framed, the form
/// field `machine`.
fn attack_of(console: &str, urls: &[String], machine: &str) -> String {
    let urls = serde_json::to_string(urls).unwrap();
    format!(
        r#"<!doctype html><html><head><title>attacking</title></head><body>
<iframe name="sink" hidden></iframe>
<iframe id="framed" src="{console}/" width="800" height="600"></iframe>
<script>
const urls = {urls};
const pause = (ms) => new Promise((r) => setTimeout(r, ms));
async function attack() {{
  for (const url of urls) {{
    for (const enctype of ["text/plain", "application/x-www-form-urlencoded", "multipart/form-data"]) {{
      const form = document.createElement("form");
      form.method = "POST"; form.action = url; form.enctype = enctype; form.target = "sink";
      const field = document.createElement("input");
      field.name = "machine"; field.value = {machine:?};
      form.appendChild(field);
      document.body.appendChild(form);
      form.submit();
      await pause(150);
    }}
    for (const type of ["text/plain", "application/x-www-form-urlencoded", "multipart/form-data", null]) {{
      const init = {{ method: "POST", mode: "no-cors", credentials: "include", body: "{{}}" }};
      if (type) init.headers = {{ "Content-Type": type }};
      try {{ await fetch(url, init); }} catch (e) {{}}
    }}
    try {{
      await fetch(url, {{ method: "POST", credentials: "include",
        headers: {{ "Content-Type": "application/json", "X-Whirl-Page": "0" }}, body: "{{}}" }});
    }} catch (e) {{}}
    navigator.sendBeacon(url, "{{}}");
    new Image().src = url;
  }}
  await pause(1000);
  document.title = "done";
}}
attack();
</script></body></html>"#
    )
}

/// Runs the attacker's page at `url` in `page` and waits until it has sent everything.
fn attacked(page: &Session, url: &str) {
    page.open(url);
    page.wait("the attack to end", Duration::from_secs(120), |p| {
        (p.script("return document.title").as_str() == Some("done")).then_some(())
    });
}

#[test]
fn no_page_of_another_origin_or_rebound_name_can_press_a_button_in_a_real_browser() {
    let Some((chromium, chromedriver)) = browser() else {
        return;
    };
    let driver = Driver::start(&chromedriver);
    // Two names of the test's own for 127.0.0.1: a page of another site, and a name
    // rebound to the console (as DNS rebinding leaves it).
    let page = Session::with_args(
        driver.1,
        chromium.to_str().unwrap(),
        &["--host-resolver-rules=MAP evil.test 127.0.0.1, MAP rebound.test 127.0.0.1"],
    );

    // A console on loopback without a token, as the README starts it, cutting.
    let open = Serve::start(&[]);
    let (machine, id) = long_run(&open, &[]);
    let console = format!("http://127.0.0.1:{}", open.addr.port());
    let evil = attacker(attack_page(&console, &machine));
    attacked(&page, &format!("http://evil.test:{evil}/"));
    // Framed under another site's page, the console does not show.
    page.frame(Some(0));
    assert_eq!(page.count("#nav-run"), 0, "the console showed in a frame");
    page.frame(None);
    untouched(&open, &machine, id, &[]);
    let said = open.said();
    // As the page's encodeURIComponent wrote the machine's name.
    let path = machine.replace(':', "%3A").replace(' ', "%20");
    for button in ["hold", "stop", "resume", "resume-at"] {
        let refused = format!("refused POST /api/runs/{path}/{button} from 127.0.0.1:");
        assert!(said.contains(&refused), "{said}");
    }
    assert!(
        said.contains(&format!("another origin (http://evil.test:{evil})")),
        "{said}"
    );

    // Rebound: the browser thinks the console is rebound.test, whose page it may read and
    // script; the console answers that name nothing, so a script there acts on nothing.
    let rebound = format!("http://rebound.test:{}/", open.addr.port());
    page.open(&rebound);
    assert_eq!(
        page.count("#nav-run"),
        0,
        "the console served a rebound name"
    );
    let status = page.script(&format!(
        "return fetch('/api/runs/' + encodeURIComponent({machine:?}) + '/hold', \
         {{method: 'POST', headers: {{'Content-Type': 'application/json'}}, body: '{{}}'}})\
         .then((r) => r.status)"
    ));
    assert_eq!(status, 403);
    untouched(&open, &machine, id, &[]);
    assert!(
        open.said()
            .contains(&format!("not to Host rebound.test:{}", open.addr.port())),
        "{}",
        open.said()
    );

    // A console with a token, the operator logged in: another port of the same host
    // shares the host's cookies, and still cannot act.
    let guarded = Serve::start(&["--token", TOKEN]);
    let token = [("X-Whirl-Token", TOKEN)];
    let (machine, id) = long_run(&guarded, &token);
    page.open(&format!("{}login", guarded.url()));
    page.script(&format!(
        "document.getElementById('token').value = {TOKEN:?}; return 0"
    ));
    page.click("#login");
    page.wait("the login", Duration::from_secs(30), |p| {
        (p.script("return document.cookie.length === 0 && location.pathname === '/'")
            .as_bool()
            == Some(true))
        .then_some(())
    });
    let console = format!("http://127.0.0.1:{}", guarded.addr.port());
    let neighbour = attacker(attack_page(&console, &machine));
    attacked(&page, &format!("http://127.0.0.1:{neighbour}/"));
    untouched(&guarded, &machine, id, &token);
    let said = guarded.said();
    assert!(
        said.contains(&format!("another origin (http://127.0.0.1:{neighbour})")),
        "{said}"
    );
}

// ---------------------------------------------------------------------------------------
// A console that ends.

/// `whirl serve` on `profile` with a page open on its run, cutting over `transport`, then
/// `signal`: the run is stopped as `whirl stream` stops one (held, then ended where it
/// stands, its resume point in the record), the page says at once, in red, that the console
/// is gone, and the console exits 0 once its run has ended.
fn ended_by_a_signal(profile: &str, transport: &str, signal: &str) {
    let Some((chromium, chromedriver)) = browser() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let jobs = short_jobs(dir.path());
    let db = dir.path().join("runs.sqlite");
    let profile = repo().join("machine-profiles").join(profile);
    let mut serve = Serve::start_with_jobs(dir, &jobs, &["--machine", profile.to_str().unwrap()]);
    let machine = serve.get("/api/machines").json()[0]
        .as_str()
        .unwrap()
        .to_owned();
    let driver = Driver::start(&chromedriver);
    let page = Session::new(driver.1, chromium.to_str().unwrap());
    page.open(&format!("{}#run", serve.url()));
    let body = serde_json::json!({
        "machine": machine, "job": "short/job.toml", "transport": transport, "time_scale": 1.0
    });
    let started = serve.post("/api/runs", &[], &body.to_string());
    assert_eq!(started.status, 200, "{}", started.body);
    let cutting = || {
        let views = serve.get("/api/runs").json();
        views[0]["done"].as_u64().unwrap_or(0) > 0
    };
    wait_for(Duration::from_secs(120), "the run to cut", cutting);
    page.wait("the page live", Duration::from_secs(30), |p| {
        (p.text("link-state") == "live").then_some(())
    });
    let killed = Command::new("kill")
        .args([&format!("-{signal}"), &serve.child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    page.wait(
        "the page to say the console is gone",
        Duration::from_secs(60),
        |p| {
            let said = p.text("link-state");
            let red = p.script(
                "return getComputedStyle(document.getElementById('link-state')).backgroundColor",
            );
            (said.starts_with("CONSOLE GONE") || said.starts_with("The console does not answer"))
                .then_some((said, red))
        },
    );
    let (said, red) = (
        page.text("link-state"),
        page.script(
            "return getComputedStyle(document.getElementById('link-state')).backgroundColor",
        ),
    );
    assert_eq!(red, "rgb(198, 40, 40)", "{said}");
    shoot(&page, &format!("console-gone-{transport}"));
    let start = Instant::now();
    let status = loop {
        if let Some(status) = serve.child.try_wait().unwrap() {
            break status;
        }
        assert!(
            start.elapsed() < Duration::from_secs(90),
            "whirl serve did not end"
        );
        std::thread::sleep(Duration::from_millis(100));
    };
    assert!(status.success(), "{status:?}: {}", serve.said());
    assert!(
        serve
            .said()
            .contains(&format!("whirl serve: SIG{signal}: stopping every run")),
        "{}",
        serve.said()
    );
    // The record: stopped where it stood, by the console's end, with where to resume.
    let listed = Command::new(env!("CARGO_BIN_EXE_whirl"))
        .args(["runs", "list", "--json"])
        .env("WHIRL_DB", &db)
        .output()
        .unwrap();
    let runs: serde_json::Value = serde_json::from_slice(&listed.stdout).unwrap();
    let run = &runs[0];
    assert_eq!(run["outcome"], "stopped", "{runs}");
    assert!(run["resume_at"].as_u64().is_some_and(|l| l > 1), "{runs}");
    assert!(
        run["reason"]
            .as_str()
            .unwrap_or_default()
            .contains("whirl serve ended"),
        "{runs}"
    );
}

#[test]
fn sigint_to_the_console_stops_its_serial_run_and_the_page_says_it_is_gone() {
    ended_by_a_signal("sim.toml", "serial", "INT");
}

#[test]
fn sigterm_to_the_console_stops_its_modbus_run_and_the_page_says_it_is_gone() {
    ended_by_a_signal("sim.toml", "modbus-tcp", "TERM");
}

#[test]
fn sigint_to_the_console_stops_its_can_run_and_the_page_says_it_is_gone() {
    ended_by_a_signal("canopen-drives.toml", "can-slcan", "INT");
}

/// The job page's profile, over HTTP: what `whirl profile` says of the job, to anyone who
/// may read the job list (no token: it changes nothing), and the same refusals as a plan's
/// for a job out of the folder or one that does not load.
#[test]
fn a_job_s_profile_is_read_without_the_token_and_refused_out_of_the_jobs_folder() {
    let dir = tempfile::tempdir().unwrap();
    let jobs = dir.path().join("jobs");
    std::fs::create_dir_all(&jobs).unwrap();
    let trapezoidal = std::fs::read_to_string(repo().join("examples").join(JOB)).unwrap();
    std::fs::write(jobs.join("tr.toml"), &trapezoidal).unwrap();
    std::fs::write(jobs.join("broken.toml"), "[groove]\nlead = \"x\"\n").unwrap();
    let serve = Serve::start_with_jobs(dir, &jobs, &["--token", TOKEN]);
    let answer = serve.get("/api/profile?job=tr.toml");
    assert_eq!(answer.status, 200, "{}", answer.body);
    let profile = answer.json();
    let fact = |name: &str| {
        profile["facts"]
            .as_array()
            .unwrap()
            .iter()
            .find(|f| f["name"] == name)
            .and_then(|f| f["value"].as_str())
            .unwrap_or_else(|| panic!("{name} in {profile}"))
            .to_owned()
    };
    // ISO 2904, Tr 40x14 P7: h3 = 0.5·P + a_c = 4 mm, the thread angle 30°.
    assert_eq!(fact("thread height h3"), "4.0000 mm");
    assert_eq!(fact("flank angle"), "30.00°");
    assert_eq!(fact("starts"), "2");
    let svg = profile["svg"].as_str().unwrap();
    assert!(svg.starts_with("<svg ") && svg.contains("thread height h3"));
    for (job, status, says) in [
        ("../Cargo.toml", 400, "steps out of the jobs folder"),
        ("broken.toml", 422, "line 2, column 8"),
        ("none.toml", 400, "none.toml"),
    ] {
        let answer = serve.get(&format!("/api/profile?job={job}"));
        assert_eq!(answer.status, status, "{job}: {}", answer.body);
        let error = answer.json()["error"].as_str().unwrap().to_owned();
        assert!(error.contains(says), "{job}: {error}");
    }
}

/// The job page in a browser: the Profile button of a job shows its dimensions and the plot
/// of its axial section (the groove's path, the dimensions labelled), with a screenshot.
#[test]
fn the_job_page_shows_the_profile_of_the_job_picked() {
    let Some((chromium, chromedriver)) = browser() else {
        return;
    };
    let serve = Serve::start(&[]);
    let driver = Driver::start(&chromedriver);
    let page = Session::new(driver.1, chromium.to_str().unwrap());
    let long = Duration::from_secs(60);
    page.open(&format!("{}#jobs", serve.url()));
    let row = format!("tr[data-job=\"{JOB}\"]");
    page.wait("the jobs listed", long, |p| {
        (p.count(&format!("{row} button[id^=profile]")) == 1).then_some(())
    });
    assert!(
        !page.displayed("#job-profile"),
        "no profile before one is picked"
    );
    page.click(&format!("{row} button[id^=profile]"));
    page.wait("the profile's plot", long, |p| {
        p.script("return document.querySelector('#profile-plot svg') !== null")
            .as_bool()
            .filter(|&b| b)
    });
    assert!(page.displayed("#job-profile"));
    assert!(page.text("profile-title").contains(JOB));
    let facts = page
        .script("return document.getElementById('profile-facts').innerText")
        .as_str()
        .unwrap_or_default()
        .to_owned();
    // ISO 2904, Tr 40x14 P7 with the example's 0.5 mm root fillets.
    for words in [
        "thread height h3",
        "4.0000 mm",
        "flank angle",
        "30.00°",
        "root radius",
        "0.5000 mm",
        "ISO 2904",
    ] {
        assert!(facts.contains(words), "the table lists {words:?}: {facts}");
    }
    // The groove is one path of the section's points; the dimensions are labelled in it.
    let longest_path = page
        .script(
            "return Math.max(...[...document.querySelectorAll('#profile-plot svg path')]\
             .map((p) => (p.getAttribute('d').match(/L/g) || []).length))",
        )
        .as_u64()
        .unwrap_or(0);
    assert!(
        longest_path >= 1000,
        "the groove's path has {longest_path} lines"
    );
    let labels = page
        .script("return document.querySelector('#profile-plot svg').textContent")
        .as_str()
        .unwrap_or_default()
        .to_owned();
    assert!(
        labels.contains("thread height h3") && labels.contains("crest"),
        "{labels}"
    );
    page.script("document.getElementById('profile-plot').scrollIntoView()");
    shoot(&page, "job-profile");
}

#[test]
fn the_shop_overview_in_a_browser_follows_a_bridges_run_holds_it_and_shows_it_offline_when_killed()
{
    let Some((chromium, chromedriver)) = browser() else {
        return;
    };
    let Some(broker) = mosquitto::Mosquitto::start() else {
        return;
    };
    // The overview and a bridge (a console of the built-in simulator) share the broker,
    // the run records and the shop's token, as a shop's do.
    let shared = tempfile::tempdir().unwrap();
    let db = shared.path().join("shop.sqlite");
    let db = db.to_str().unwrap();
    let url = broker.url();
    let shop = Serve::start(&["--shop", "--mqtt", &url, "--db", db, "--token", TOKEN]);
    let mut bridge = Serve::start(&["--mqtt", &url, "--db", db, "--token", TOKEN]);
    let token = [("X-Whirl-Token", TOKEN)];
    let driver = Driver::start(&chromedriver);
    let page = Session::with_args(
        driver.1,
        chromium.to_str().unwrap(),
        &["--host-resolver-rules=MAP evil.test 127.0.0.1"],
    );
    let long = Duration::from_secs(120);
    page.open(&shop.url());
    let state = |p: &Session| {
        p.script("const c = document.querySelector('#machines-table tbody td.state'); return c ? c.textContent : ''")
            .as_str()
            .unwrap_or_default()
            .to_owned()
    };
    let shows = |word: &'static str| move |p: &Session| (state(p) == word).then_some(());
    page.wait("the bridge's machine, idle", long, shows("IDLE"));
    // A dry run at 50 times real time, started at the bridge.
    let machine = bridge.get("/api/machines").json()[0]
        .as_str()
        .unwrap()
        .to_owned();
    let started = bridge.post("/api/runs", &token, &run_request(&machine, 50.0));
    assert_eq!(started.status, 200, "{}", started.body);
    page.wait("the run", long, shows("RUNNING"));
    page.wait("its progress", long, |p| {
        p.script(
            "const b = document.querySelector('#machines-table progress'); return b ? b.value : 0",
        )
        .as_f64()
        .filter(|&v| v > 0.0)
    });
    let job = page
        .script("return document.querySelector('#machines-table tbody tr').cells[2].textContent");
    assert_eq!(job.as_str(), Some(JOB), "the run's job");
    shoot(&page, "shop-running");
    let topic = page
        .script("return document.querySelector('#machines-table tbody tr').dataset.machine")
        .as_str()
        .unwrap()
        .to_owned();

    // Another site's page cannot send the overview's Hold, nor can the page before the
    // operator has logged in.
    let overview = format!("http://127.0.0.1:{}", shop.addr.port());
    let hold_url = format!("{overview}/api/shop/{topic}/hold");
    let evil = attacker(attack_of(
        &overview,
        std::slice::from_ref(&hold_url),
        &topic,
    ));
    attacked(&page, &format!("http://evil.test:{evil}/"));
    let said = shop.said();
    assert!(
        said.contains(&format!("refused POST /api/shop/{topic}/hold")),
        "{said}"
    );
    assert!(!said.contains("a Hold sent"), "{said}");
    page.open(&shop.url());
    page.wait("the run again", long, shows("RUNNING"));
    page.click("#machines-table button.hold");
    let refused = page.wait("the Hold refused without the token", long, |p| {
        let text = p.text("hold-error");
        (!text.is_empty()).then_some(text)
    });
    assert!(refused.contains("token"), "{refused}");
    assert!(page.displayed("#login-link"));
    // Logged in, the operator holds the machine from the overview; the bridge takes it
    // with its console's token, the shop's.
    page.open(&format!("{}login", shop.url()));
    page.script(&format!(
        "document.getElementById('token').value = {TOKEN:?}; return 0"
    ));
    page.click("#login");
    page.wait("the login", long, |p| {
        (p.script("return location.pathname === '/'").as_bool() == Some(true)).then_some(())
    });
    page.wait("the run after the login", long, shows("RUNNING"));
    page.click("#machines-table button.hold");
    page.wait("the hold", long, shows("HELD"));
    assert!(shop.said().contains("a Hold sent"), "{}", shop.said());
    shoot(&page, "shop-held");
    let press = |button: &str| {
        let path = format!(
            "/api/runs/{}/{button}",
            machine.replace(' ', "%20").replace(':', "%3A")
        );
        let answer = bridge.post(&path, &token, "");
        assert_eq!(answer.status, 200, "{button}: {}", answer.body);
    };
    press("resume");
    page.wait("the resume", long, shows("RUNNING"));
    press("stop");
    page.wait("the stop", long, |p| {
        let text = p
            .script(
                "return document.querySelector('#machines-table tbody tr').cells[6].textContent",
            )
            .as_str()
            .unwrap_or_default()
            .to_owned();
        (state(p) == "IDLE" && text.contains("resumes at line")).then_some(text)
    });
    // The history, read from the shared records, has the bridge's run and the overview's
    // Hold in its notes (its record closed just after its end: searched again until it is).
    page.wait("the run in the history", long, |p| {
        p.click("#history-form button");
        p.script(
            "return document.querySelector('#history-table tbody tr td:nth-child(4)')?.textContent",
        )
        .as_str()
        .filter(|outcome| *outcome == "stopped")
        .map(str::to_owned)
    });
    let id = page.script("return document.querySelector('#history-table tbody tr td').textContent");
    let run = bridge
        .get_with(&format!("/api/history/{}", id.as_str().unwrap()), &token)
        .json();
    let notes = run["notes"].to_string();
    assert!(notes.contains("the shop overview"), "{notes}");
    // Killed outright: the broker publishes the bridge's will, and the overview shows it
    // offline.
    bridge.child.kill().unwrap();
    bridge.child.wait().unwrap();
    page.wait("the bridge offline", long, shows("OFFLINE"));
    shoot(&page, "shop-offline");
    drop(shop);
}
