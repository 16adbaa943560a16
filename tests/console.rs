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

use console::http::{request, Answer};
use console::webdriver::Session;
use std::io::{BufRead, BufReader};
use std::net::{SocketAddr, TcpListener};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

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
        let mut child = Command::new(env!("CARGO_BIN_EXE_whirl"))
            .args(["serve", "--listen", "127.0.0.1:0", "--jobs"])
            .arg(jobs)
            .args(args)
            .env("WHIRL_LOCK_DIR", dir.path().join("locks"))
            .env("WHIRL_DB", dir.path().join("runs.sqlite"))
            .current_dir(dir.path())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .unwrap();
        let mut line = String::new();
        BufReader::new(child.stdout.take().unwrap())
            .read_line(&mut line)
            .unwrap();
        let addr = line
            .split("http://")
            .nth(1)
            .and_then(|rest| rest.split('/').next())
            .and_then(|a| a.parse().ok())
            .unwrap_or_else(|| panic!("whirl serve said no address: {line:?}"));
        Serve { child, addr, dir }
    }

    fn get(&self, path: &str) -> Answer {
        self.get_with(path, &[])
    }

    fn get_with(&self, path: &str, headers: &[(&str, &str)]) -> Answer {
        request(self.addr, "GET", path, headers, None)
    }

    fn post(&self, path: &str, headers: &[(&str, &str)], body: &str) -> Answer {
        request(self.addr, "POST", path, headers, Some(body))
    }

    fn url(&self) -> String {
        format!("http://{}/", self.addr)
    }
}

impl Drop for Serve {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
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
    // The login form sets the cookie the page's requests then carry.
    let login = serve.post(
        "/login",
        &[("Content-Type", "application/x-www-form-urlencoded")],
        &format!("token={TOKEN}"),
    );
    let cookie = login.header("set-cookie").expect("a cookie").to_owned();
    assert!(cookie.contains("HttpOnly") && cookie.contains("SameSite=Strict"));
    let pair = cookie.split(';').next().unwrap();
    assert_eq!(
        serve.post("/api/plan", &[("Cookie", pair)], &plan).status,
        200
    );
    let bad = serve.post(
        "/login",
        &[("Content-Type", "application/x-www-form-urlencoded")],
        "token=guess",
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
    let profile = dir.path().join("lathe.toml");
    let text = std::fs::read_to_string(repo().join("machine-profiles/sim.toml")).unwrap();
    std::fs::write(
        &profile,
        format!(
            "{}\n[connection]\ntransport = \"serial\"\nport = \"{}\"\n",
            text.replace(
                "name = \"whirl-sim: simulated XZC whirling lathe\"",
                "name = \"lathe 7\""
            ),
            port.display()
        ),
    )
    .unwrap();
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
    // A step past the controller's slowest is held there, saying why (the keys' rule).
    let step = serve.post(&path, &token, r#"{"step": -1000}"#);
    assert_eq!(step.status, 200, "{}", step.body);
    assert_eq!(step.json()["percent"], 10);
    wait_for(Duration::from_secs(60), "the controller at 10 %", || {
        view(&serve)["feed"]["running"] == 10
    });
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

    // Hold: the simulator holds and stands.
    page.click("#btn-hold");
    page.wait("the hold", long, |p| held_shown(p, transport).then_some(()));
    let held = (page.text("run-position"), done(page));
    std::thread::sleep(Duration::from_secs(1));
    assert_eq!((page.text("run-position"), done(page)), held, "held still");
    assert!(page.text("run-title").contains("(running)"));
    assert!(held_shown(page, transport));

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

    // Stop: the run ends, offering where to resume.
    page.click("#btn-stop");
    page.wait("the run to end", long, |p| {
        p.text("run-title").contains("(ended)").then_some(())
    });
    assert!(page.text("run-outcome").starts_with("stopped"));
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
    // Run, kind, outcome, started, machine, job, transport, resume at, why.
    let (resume, stopped) = (&found[0], &found[1]);
    assert_eq!(resume[1], "serve", "{found}");
    assert_eq!(resume[2], "completed", "{found}");
    assert_eq!(stopped[2], "stopped", "{found}");
    assert_eq!(stopped[7], line.to_string(), "{found}");
    assert!(resume[5].as_str().unwrap().contains(job), "{found}");
    assert_eq!(
        (&resume[6], &stopped[6]),
        (&transport.into(), &transport.into()),
        "{found}"
    );
    // Searched by outcome in the server: the stopped run only.
    page.script("document.getElementById('history-outcome').value = 'stopped';");
    page.click("#history-search");
    page.wait("the stopped runs", long, |p| {
        let rows = rows(p);
        let all = rows.as_array()?;
        (!all.is_empty() && all.iter().all(|r| r[2] == "stopped")).then_some(())
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
        let child = Command::new(env!("CARGO_BIN_EXE_whirl-sim"))
            .arg("--pty")
            .arg(link)
            .args(["--time-scale", "50"])
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
    let profile = dir.path().join("lathe.toml");
    let text = std::fs::read_to_string(repo().join("machine-profiles/sim.toml")).unwrap();
    std::fs::write(
        &profile,
        format!(
            "{}\n[connection]\ntransport = \"serial\"\nport = \"{}\"\n",
            text.replace(
                "name = \"whirl-sim: simulated XZC whirling lathe\"",
                "name = \"lathe 9\""
            ),
            tty.display()
        ),
    )
    .unwrap();
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
