//! `whirl serve`, the operator's console, end to end: its refusals over HTTP (no token
//! beyond loopback, actions without the token, paths out of the jobs folder, a busy
//! machine, also against `whirl stream`), its runs in the run records and a stream to a
//! machine (`whirl-sim` on a pseudo-terminal), and a real headless Chromium driven through
//! chromedriver (WebDriver) through dry runs over serial, Modbus and CAN with Hold, Resume,
//! Stop, a resume at the offered line and the run found in the history.
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
        request(self.addr, "GET", path, &[], None)
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
    // resumed, stopped and resumed at the offered line.
    let line = dry_run_sequence(&page, &serve, None, JOB, "serial", "50", true)
        .expect("a serial dry run resumes");
    // Stopped and resumed along the groove, the cut as a whole is within Δ.
    let measured = page.text("run-measured");
    assert!(measured.starts_with("within Δ"), "{measured}");
    shoot(&page, "run-completed");
    found_in_history(&page, &serve, JOB, line, true);

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

/// On the run page: dry-runs `job` over `transport` at `scale` on `machine` (the first if
/// `None`), watches progress advance, holds (the simulator stands: a serial controller
/// says `Hold:0`; a fieldbus run's figures stand still while it runs), resumes, stops, and
/// resumes at the offered line to the end. Gives the line it resumed at.
fn dry_run_sequence(
    page: &Session,
    serve: &Serve,
    machine: Option<&str>,
    job: &str,
    transport: &str,
    scale: &str,
    shots: bool,
) -> Option<usize> {
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
    if transport == "serial" {
        page.wait("the hold", long, |p| {
            p.text("run-state").starts_with("Hold:0").then_some(())
        });
    } else {
        page.wait("the hold", long, |p| {
            p.text("run-messages")
                .contains("hold requested")
                .then_some(())
        });
        // The path slows to a stand over the machine's stop time.
        std::thread::sleep(Duration::from_secs(2));
    }
    let held = (page.text("run-position"), done(page));
    std::thread::sleep(Duration::from_secs(1));
    assert_eq!((page.text("run-position"), done(page)), held, "held still");
    assert!(page.text("run-title").contains("(running)"));
    if transport == "serial" {
        assert!(page.text("run-state").starts_with("Hold"));
    }

    // Resume: running again.
    page.click("#btn-resume");
    let resumed = held.1.unwrap_or(0);
    page.wait("progress after the resume", long, |p| {
        done(p).filter(|&n| n > resumed)
    });
    if shots {
        shoot(page, "run");
    }

    // Stop: the run ends, offering where to resume.
    page.click("#btn-stop");
    page.wait("the run to end", long, |p| {
        p.text("run-title").contains("(ended)").then_some(())
    });
    assert!(page.text("run-outcome").starts_with("stopped"));
    if transport != "serial" {
        // judge::dry_run reports no resume point of a fieldbus dry run: none offered, and
        // the page says why.
        assert!(!page.displayed("#resume-offer"));
        let messages = page.text("run-messages");
        assert!(
            messages.contains(&format!("no resume point: a {transport} dry run")),
            "{messages}"
        );
        return None;
    }
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
    Some(line)
}

/// On the history page: the runs of `job` searched for, newest first: the resume
/// completed, from line `line`, continuing the stopped run, which resumes at that line.
fn found_in_history(page: &Session, serve: &Serve, job: &str, line: usize, shots: bool) {
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

#[test]
fn the_console_in_a_browser_runs_holds_and_stops_a_modbus_dry_run() {
    let Some((chromium, chromedriver)) = browser() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let jobs = short_jobs(dir.path());
    let profiles = repo().join("machine-profiles");
    let sim = profiles.join("sim.toml");
    let serve = Serve::start_with_jobs(dir, &jobs, &["--machine", sim.to_str().unwrap()]);
    let machines = serve.get("/api/machines").json();
    let name = |needle: &str| {
        machines
            .as_array()
            .unwrap()
            .iter()
            .filter_map(|m| m.as_str())
            .find(|m| m.contains(needle))
            .unwrap()
            .to_owned()
    };
    let driver = Driver::start(&chromedriver);
    let page = Session::new(driver.1, chromium.to_str().unwrap());
    let job = "short/job.toml";
    let resumed = dry_run_sequence(
        &page,
        &serve,
        Some(&name("whirl-sim")),
        job,
        "modbus-tcp",
        "10",
        false,
    );
    assert_eq!(resumed, None);
    // The stopped run in the records, by its transport.
    let runs = serve.get("/api/history?job=short").json();
    let runs: Vec<(&str, &str)> = runs
        .as_array()
        .unwrap()
        .iter()
        .map(|r| {
            (
                r["transport"].as_str().unwrap(),
                r["outcome"].as_str().unwrap(),
            )
        })
        .collect();
    assert_eq!(runs, [("modbus-tcp", "stopped")]);
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
    let run = serve.get(&format!("/api/history/{record}")).json();
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
    assert_eq!(serve.get("/api/history/999").status, 404);
}
