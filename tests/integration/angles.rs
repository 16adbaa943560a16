//! `whirl angles` end to end: on the trapezoidal example the window the refusal of an angle
//! names, an angle picked inside it that `plan`, `dry-run` and `stream` then take for a job
//! that gives none (and the engine measures that plan within Δ), the segments of each row as
//! `whirl plan` writes them at its angle, and the refusals: a bad `--svg`, a ring that fits at
//! no angle, an angle outside the window, each before anything is written.

use crate::util::{self, Sim};
use serde_json::Value;
use std::ffi::OsStr;
use std::path::{Path, PathBuf};

fn os(s: &str) -> &OsStr {
    OsStr::new(s)
}

struct Run {
    ok: bool,
    stdout: String,
    stderr: String,
}

fn whirl(args: &[&OsStr]) -> Run {
    let o = util::whirl(args);
    Run {
        ok: o.status.success(),
        stdout: String::from_utf8_lossy(&o.stdout).into(),
        stderr: String::from_utf8_lossy(&o.stderr).into(),
    }
}

/// The trapezoidal example in `dir` with its installation-angle line replaced by `angle`
/// (a whole line of TOML, or nothing) and `edit` applied.
fn trapezoidal(dir: &Path, angle: &str, edit: impl Fn(String) -> String) -> PathBuf {
    let text = std::fs::read_to_string(util::example("trapezoidal")).unwrap();
    let line = "installation_angle_deg = 7.8\n";
    assert!(text.contains(line), "the example gives its angle");
    util::write(dir, "job.toml", &edit(text.replace(line, angle)))
}

/// An angle as `whirl angles` prints it, "7.107°", and its value.
fn degrees(word: &str) -> f64 {
    word.trim_end_matches('°')
        .parse()
        .unwrap_or_else(|_| panic!("{word}"))
}

/// One row of `whirl angles`'s table.
#[derive(Debug, Clone)]
struct Row {
    /// The angle as printed, and its value.
    angle: String,
    deg: f64,
    margin: f64,
    chosen: bool,
    /// The max error as printed ("0.0100") and the segments, where the job planned.
    planned: Option<(String, usize)>,
}

/// What `whirl angles` printed: the window and its edges, and the table's rows.
struct Printed {
    window: String,
    edges: (f64, f64),
    rows: Vec<Row>,
}

impl Printed {
    /// The row marked as the angle with the largest margin.
    fn chosen(&self) -> &Row {
        let chosen: Vec<&Row> = self.rows.iter().filter(|r| r.chosen).collect();
        assert_eq!(chosen.len(), 1, "{:?}", self.rows);
        chosen[0]
    }
}

fn printed(stdout: &str) -> Printed {
    let first = stdout.lines().next().unwrap();
    let (_, rest) = first
        .split_once("installation angles that plan without interference: ")
        .unwrap_or_else(|| panic!("{stdout}"));
    let window = rest.split(' ').next().unwrap().to_string();
    let (low, high) = window.split_once('–').unwrap();
    let edges = (degrees(low), degrees(high));
    let rows = stdout
        .lines()
        .filter(|l| l.contains("° ") && (l.starts_with("  ") || l.starts_with("* ")))
        .filter_map(|l| {
            let words: Vec<&str> = l[1..].split_whitespace().collect();
            (words.len() >= 2 && words[0].ends_with('°')).then(|| Row {
                angle: words[0].trim_end_matches('°').to_string(),
                deg: degrees(words[0]),
                margin: degrees(words[1]),
                chosen: l.starts_with('*'),
                planned: (words.len() == 5 && words[3] == "mm")
                    .then(|| (words[2].to_string(), words[4].parse().unwrap())),
            })
        })
        .collect();
    Printed {
        window,
        edges,
        rows,
    }
}

#[test]
fn on_the_trapezoidal_example_the_window_is_the_refusals_and_the_pick_lies_inside() {
    let dir = tempfile::tempdir().unwrap();
    let svg = dir.path().join("angles.svg");
    let job = util::example("trapezoidal");
    let run = whirl(&[os("angles"), job.as_os_str(), os("--svg"), svg.as_os_str()]);
    assert!(run.ok, "{}{}", run.stdout, run.stderr);
    let p = printed(&run.stdout);
    let (low, high) = p.edges;
    // The example plans at 7.8°; the lead angle at the mean radius, 7.06°, is refused.
    assert!(low < 7.8 && 7.8 < high, "{}", run.stdout);
    assert!(!(low..=high).contains(&7.06), "{}", run.stdout);
    // Refused at 7.06°, `plan` names the same window.
    let refused_job = trapezoidal(dir.path(), "installation_angle_deg = 7.06\n", |t| t);
    let out = dir.path().join("p.nc");
    let plan = whirl(&[
        os("plan"),
        refused_job.as_os_str(),
        os("-o"),
        out.as_os_str(),
    ]);
    assert!(!plan.ok && !out.exists());
    assert!(
        plan.stderr.contains(&format!(
            "installation angles that work with this ring: {} ",
            p.window
        )),
        "{}\n{}",
        p.window,
        plan.stderr
    );
    // Tilted so far that the ring cannot enclose the work (cos 89° ≈ 0.017), the refusal
    // names the same window.
    let tilted_job = trapezoidal(dir.path(), "installation_angle_deg = 89\n", |t| t);
    let plan = whirl(&[
        os("plan"),
        tilted_job.as_os_str(),
        os("-o"),
        out.as_os_str(),
    ]);
    assert!(!plan.ok && !out.exists());
    assert!(
        plan.stderr
            .contains("the ring is too small to enclose the work")
            && plan.stderr.contains(&format!(
                "installation angles that work with this ring: {} ",
                p.window
            )),
        "{}\n{}",
        p.window,
        plan.stderr
    );
    // The rows run from edge to edge, where the margin is zero; the one marked has the
    // largest margin, the middle to the 0.001° the edges are found to.
    assert_eq!(p.rows.first().map(|r| (r.deg, r.margin)), Some((low, 0.0)));
    assert_eq!(p.rows.last().map(|r| (r.deg, r.margin)), Some((high, 0.0)));
    let chosen = p.chosen();
    assert!(low < chosen.deg && chosen.deg < high);
    assert!(
        p.rows
            .iter()
            .all(|r| r.margin <= chosen.margin && r.margin >= 0.0),
        "{}",
        run.stdout
    );
    assert!(
        (chosen.deg - (low + high) / 2.0).abs() <= 0.0005 + 1e-9,
        "{}",
        run.stdout
    );
    // Every angle of the window planned, within Δ = 0.01 mm.
    for row in &p.rows {
        let (error, _) = row.planned.as_ref().expect("planned");
        assert!(degrees(error) <= 0.01, "{row:?}");
    }
    // The job's own angle, 7.8°, lies inside.
    assert!(
        run.stdout.contains(&format!(
            "the job's installation_angle_deg = 7.8° lies in {}, ",
            p.window
        )),
        "{}",
        run.stdout
    );
    // The plot: the error bound and the segments, each with the window and the pick.
    let picture = std::fs::read_to_string(&svg).unwrap();
    assert!(picture.starts_with("<svg ") && picture.trim_end().ends_with("</svg>"));
    assert_eq!(picture.matches("<svg ").count(), 3, "two plots stacked");
    assert_eq!(picture.matches(&format!("window {}", p.window)).count(), 2);
    assert_eq!(picture.matches("largest margin").count(), 2);
}

#[test]
fn a_job_without_an_angle_plans_at_the_pick_and_measures_within_delta() {
    let dir = tempfile::tempdir().unwrap();
    let job = trapezoidal(dir.path(), "", |t| t);
    let run = whirl(&[os("angles"), job.as_os_str()]);
    assert!(run.ok, "{}{}", run.stdout, run.stderr);
    let p = printed(&run.stdout);
    let pick = p.chosen().deg;
    let (out, report) = (dir.path().join("p.nc"), dir.path().join("r.json"));
    // `--verify`: the engine measures the program with the ring it was planned with.
    let plan = whirl(&[
        os("plan"),
        job.as_os_str(),
        os("-o"),
        out.as_os_str(),
        os("--report"),
        report.as_os_str(),
        os("--verify"),
    ]);
    assert!(plan.ok, "{}{}", plan.stdout, plan.stderr);
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    // The angle printed is the angle planned, to the last bit.
    assert_eq!(r["installation_angle_deg"].as_f64(), Some(pick), "{r}");
    let origin = &r["installation_angle_origin"];
    assert_eq!(origin["from"], "window", "{r}");
    assert_eq!(origin["window_deg"][0].as_f64(), Some(p.edges.0), "{r}");
    assert_eq!(origin["window_deg"][1].as_f64(), Some(p.edges.1), "{r}");
    assert!(r["verify"]["within_delta"].as_bool().unwrap(), "{r}");
}

#[test]
fn a_bad_svg_path_is_refused_before_anything_is_computed_or_written() {
    let dir = tempfile::tempdir().unwrap();
    let job = trapezoidal(dir.path(), "installation_angle_deg = 7.8\n", |t| t);
    let before = std::fs::read_to_string(&job).unwrap();
    let folder = dir.path().join("folder");
    std::fs::create_dir(&folder).unwrap();
    let link = dir.path().join("link.svg");
    std::os::unix::fs::symlink(dir.path().join("elsewhere.svg"), &link).unwrap();
    let machine = util::root().join("machine-profiles/grblhal-lathe.toml");
    let cases = [
        (folder.clone(), "it is a directory"),
        (dir.path().join("nowhere/a.svg"), "does not exist"),
        (job.clone(), "it is the job file this run reads"),
        (
            machine.clone(),
            "it is the machine profile (--machine) this run reads",
        ),
        (link.clone(), "symbolic link"),
        (PathBuf::from("/dev/null"), "it is a character device"),
    ];
    for (svg, why) in cases {
        let run = whirl(&[
            os("angles"),
            job.as_os_str(),
            os("--machine"),
            machine.as_os_str(),
            os("--svg"),
            svg.as_os_str(),
        ]);
        assert!(!run.ok, "{}", run.stdout);
        assert!(run.stdout.is_empty(), "nothing computed: {}", run.stdout);
        assert!(
            run.stderr.starts_with("error: refusing to write")
                && run.stderr.contains("(--svg)")
                && run.stderr.contains(why),
            "{}",
            run.stderr
        );
    }
    assert_eq!(std::fs::read_to_string(&job).unwrap(), before);
    assert!(!dir.path().join("elsewhere.svg").exists());
    assert_eq!(std::fs::read_dir(&folder).unwrap().count(), 0);
}

#[test]
fn a_ring_that_fits_at_no_angle_is_refused_naming_where_it_came_nearest() {
    // A 20.3 mm ring with a 0.4 mm nose reaches 19.9 mm from its centre untilted, and less
    // tilted: it encloses the 20 mm work at no angle, least short at 0°.
    let dir = tempfile::tempdir().unwrap();
    let job = trapezoidal(dir.path(), "", |t| {
        t.replace("ring_radius = 32.0", "ring_radius = 20.3")
    });
    let svg = dir.path().join("angles.svg");
    let run = whirl(&[os("angles"), job.as_os_str(), os("--svg"), svg.as_os_str()]);
    assert!(!run.ok && !svg.exists(), "{}", run.stdout);
    assert!(
        run.stderr.contains(&format!(
            "{}: no installation angle from 0° to 90°",
            job.display()
        )) && run
            .stderr
            .contains("it came nearest at 0°, where the ring is too small"),
        "{}",
        run.stderr
    );
    let out = dir.path().join("p.nc");
    let plan = whirl(&[os("plan"), job.as_os_str(), os("-o"), out.as_os_str()]);
    assert!(!plan.ok && !out.exists());
    assert!(
        plan.stderr
            .contains("tool.installation_angle_deg is not given, and no installation angle"),
        "{}",
        plan.stderr
    );
}

/// The number of segments `whirl plan` says it wrote, and its max error as printed:
/// "p.nc: 25084 segments (…), max error 0.0100 mm of Δ …".
fn plan_says(stdout: &str) -> (String, usize) {
    let (_, rest) = stdout
        .split_once(": ")
        .unwrap_or_else(|| panic!("{stdout}"));
    let segments = rest.split(' ').next().unwrap().parse().unwrap();
    let (_, error) = rest.split_once("max error ").unwrap();
    (error.split(' ').next().unwrap().to_string(), segments)
}

#[test]
fn each_rows_segments_and_error_are_what_whirl_plan_writes_at_that_angle() {
    let dir = tempfile::tempdir().unwrap();
    let run = whirl(&[os("angles"), util::example("trapezoidal").as_os_str()]);
    assert!(run.ok, "{}{}", run.stdout, run.stderr);
    let p = printed(&run.stdout);
    assert!(p.rows.len() >= 11, "{}", run.stdout);
    for row in &p.rows {
        let line = format!("installation_angle_deg = {}\n", row.angle);
        let job = trapezoidal(dir.path(), &line, |t| t);
        let out = dir.path().join("p.nc");
        let plan = whirl(&[os("plan"), job.as_os_str(), os("-o"), out.as_os_str()]);
        assert!(plan.ok, "{row:?}: {}", plan.stderr);
        let (error, segments) = plan_says(&plan.stdout);
        assert_eq!(row.planned, Some((error, segments)), "{}", plan.stdout);
    }
}

/// The plan report recorded for the newest run of `kind` in the records database `db`.
fn recorded_plan(db: &Path, kind: &str) -> Value {
    let o = util::whirl(&[
        os("runs"),
        os("list"),
        os("--json"),
        os("--db"),
        db.as_os_str(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let runs: Value = serde_json::from_slice(&o.stdout).unwrap();
    let run = runs
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["kind"] == kind)
        .unwrap_or_else(|| panic!("a {kind} run in {runs}"));
    let id = run["id"].to_string();
    let o = util::whirl(&[
        os("runs"),
        os("show"),
        os(&id),
        os("--json"),
        os("--db"),
        db.as_os_str(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let shown: Value = serde_json::from_slice(&o.stdout).unwrap();
    shown["plan_report"].clone()
}

#[test]
fn a_job_without_an_angle_dry_runs_and_streams_at_the_pick() {
    // The trapezoidal groove 1 mm long, no angle given: its window is the whole groove's
    // (it does not depend on the length), and it runs in moments.
    let dir = tempfile::tempdir().unwrap();
    let job = trapezoidal(dir.path(), "", |t| {
        t.replace("length = 40.0", "length = 1.0")
    });
    let db = dir.path().join("runs.sqlite");
    let run = whirl(&[os("angles"), job.as_os_str()]);
    assert!(run.ok, "{}{}", run.stdout, run.stderr);
    let pick = printed(&run.stdout).chosen().deg;

    let dry = util::whirl(&[os("dry-run"), job.as_os_str(), os("--db"), db.as_os_str()]);
    assert!(
        dry.status.success(),
        "{}",
        String::from_utf8_lossy(&dry.stderr)
    );
    let link = dir.path().join("grbl");
    let sim = Sim::serving(os("--pty"), &link, &[os("--time-scale"), os("0")]);
    let log = dir.path().join("stream.jsonl");
    let stream = util::whirl(&[
        os("stream"),
        job.as_os_str(),
        os("--port"),
        link.as_os_str(),
        os("--log"),
        log.as_os_str(),
        os("--db"),
        db.as_os_str(),
    ]);
    drop(sim);
    assert!(
        stream.status.success(),
        "{}",
        String::from_utf8_lossy(&stream.stderr)
    );
    for kind in ["dry-run", "stream"] {
        let report = recorded_plan(&db, kind);
        assert_eq!(
            report["installation_angle_deg"].as_f64(),
            Some(pick),
            "{kind}: {report}"
        );
        assert_eq!(
            report["installation_angle_origin"]["from"], "window",
            "{kind}: {report}"
        );
    }
}

#[test]
fn an_angle_outside_the_window_is_refused_by_plan_dry_run_and_stream_before_anything_is_written() {
    let dir = tempfile::tempdir().unwrap();
    // 7.06°: the lead angle at the mean radius, below the window.
    let job = trapezoidal(dir.path(), "installation_angle_deg = 7.06\n", |t| t);
    let run = whirl(&[os("angles"), job.as_os_str()]);
    assert!(run.ok, "{}{}", run.stdout, run.stderr);
    let p = printed(&run.stdout);
    assert!(
        run.stdout
            .contains("the job's installation_angle_deg = 7.06° lies outside every window"),
        "{}",
        run.stdout
    );
    let says_window = format!(
        "installation angles that work with this ring: {} (tool.installation_angle_deg); the \
         largest margin is at {}°",
        p.window,
        p.chosen().angle
    );
    let (out, report, log) = (
        dir.path().join("p.nc"),
        dir.path().join("r.json"),
        dir.path().join("l.jsonl"),
    );
    let plan = whirl(&[
        os("plan"),
        job.as_os_str(),
        os("-o"),
        out.as_os_str(),
        os("--report"),
        report.as_os_str(),
    ]);
    let dry = whirl(&[
        os("dry-run"),
        job.as_os_str(),
        os("--log"),
        log.as_os_str(),
        os("--report"),
        report.as_os_str(),
    ]);
    // No simulator behind the port: the refusal comes before it is opened.
    let stream = whirl(&[
        os("stream"),
        job.as_os_str(),
        os("--port"),
        dir.path().join("grbl").as_os_str(),
        os("--log"),
        log.as_os_str(),
    ]);
    for (command, run) in [("plan", plan), ("dry-run", dry), ("stream", stream)] {
        assert!(!run.ok, "{command}: {}", run.stdout);
        assert!(
            run.stderr.contains("cannot plan") && run.stderr.contains(&says_window),
            "{command}: {}",
            run.stderr
        );
    }
    for path in [&out, &report, &log] {
        assert!(!path.exists(), "{}", path.display());
    }
}
