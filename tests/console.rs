//! `whirl serve`, the operator's console, end to end: its refusals over HTTP (no token
//! beyond loopback, actions without the token, paths out of the jobs folder, a busy
//! machine, also against `whirl stream`), and a real headless Chromium driven through
//! chromedriver (WebDriver) through a dry run with Hold, Resume, Stop and a resume.
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
        let mut child = Command::new(env!("CARGO_BIN_EXE_whirl"))
            .args(["serve", "--listen", "127.0.0.1:0", "--jobs"])
            .arg(repo().join("examples"))
            .args(args)
            .env("WHIRL_LOCK_DIR", dir.path().join("locks"))
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
        .output()
        .unwrap();
    assert!(String::from_utf8_lossy(&out.stderr).contains("at least 16"));
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

    // Run: the example dry-run at 50 times real time (17 minutes of machine time), its
    // progress advancing.
    page.open(&format!("{}#run", serve.url()));
    page.wait("the run form", long, |p| {
        (p.script("return document.getElementById('run-job').options.length")
            .as_u64()
            >= Some(1))
        .then_some(())
    });
    page.script(&format!(
        "document.getElementById('run-job').value = {JOB:?}; \
         document.getElementById('run-scale').value = '50';"
    ));
    page.click("#run-start");
    let done = |p: &Session| first_number(&p.text("run-done"));
    let first = page.wait("progress", long, |p| done(p).filter(|&n| n > 0));
    page.wait("progress to advance", long, |p| {
        done(p).filter(|&n| n > first)
    });

    // Hold: the simulator holds and stands.
    page.click("#btn-hold");
    page.wait("the hold", long, |p| {
        p.text("run-state").starts_with("Hold:0").then_some(())
    });
    let held = (page.text("run-position"), done(&page));
    std::thread::sleep(Duration::from_secs(1));
    assert_eq!((page.text("run-position"), done(&page)), held, "held still");
    assert!(page.text("run-state").starts_with("Hold"));

    // Resume: running again.
    page.click("#btn-resume");
    page.wait("the run to go on", long, |p| {
        (p.text("run-state") == "Run").then_some(())
    });
    let resumed = done(&page).unwrap();
    page.wait("progress after the resume", long, |p| {
        done(p).filter(|&n| n > resumed)
    });
    shoot(&page, "run");

    // Stop: the run ends, offering where to resume.
    page.click("#btn-stop");
    page.wait("the resume offer", long, |p| {
        p.displayed("#resume-offer").then_some(())
    });
    let offered = page.text("btn-resume-at");
    let line = first_number(&offered).expect("a line to resume at");
    assert!(page.text("run-outcome").starts_with("stopped"));
    shoot(&page, "run-stopped");

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
    // Stopped and resumed along the groove, the cut as a whole is within Δ.
    let measured = page.text("run-measured");
    assert!(measured.starts_with("within Δ"), "{measured}");
    let done_text = page.text("run-done");
    let total = first_number(done_text.split("of").nth(1).unwrap_or_default());
    assert_eq!(done(&page), total, "every line");
    shoot(&page, "run-completed");

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
