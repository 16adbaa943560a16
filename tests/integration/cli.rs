//! `whirl plan` end to end: every example plans; every refusal exits non-zero, says what is
//! wrong and where, and writes nothing.

use crate::util;
use std::ffi::OsStr;
use std::path::Path;

struct Run {
    ok: bool,
    stdout: String,
    stderr: String,
}

fn plan(job: &Path, out: &Path, report: &Path, machine: Option<&Path>) -> Run {
    let mut args: Vec<&OsStr> = vec![
        OsStr::new("plan"),
        job.as_os_str(),
        OsStr::new("-o"),
        out.as_os_str(),
        OsStr::new("--report"),
        report.as_os_str(),
    ];
    if let Some(m) = machine {
        args.push(OsStr::new("--machine"));
        args.push(m.as_os_str());
    }
    let o = util::whirl(&args);
    Run {
        ok: o.status.success(),
        stdout: String::from_utf8_lossy(&o.stdout).into(),
        stderr: String::from_utf8_lossy(&o.stderr).into(),
    }
}

/// Run a job that must be refused; check nothing was written and return the message.
fn refused(job: &Path, machine: Option<&Path>) -> String {
    let dir = tempfile::tempdir().unwrap();
    let (out, report) = (dir.path().join("p.nc"), dir.path().join("r.json"));
    let run = plan(job, &out, &report, machine);
    assert!(!run.ok, "must be refused: {}", run.stdout);
    assert!(!out.exists() && !report.exists(), "nothing may be written");
    assert!(
        std::fs::read_dir(dir.path()).unwrap().next().is_none(),
        "no temporary files left behind"
    );
    assert!(run.stderr.starts_with("error: "), "{}", run.stderr);
    assert!(!run.stderr.contains("panicked") && !run.stderr.contains("backtrace"));
    run.stderr
}

/// A copy of an example job with `edit` applied to its text, in `dir`, with its profile.
fn edited(dir: &Path, name: &str, edit: impl Fn(String) -> String) -> std::path::PathBuf {
    let src = util::example(name);
    let text = std::fs::read_to_string(&src).unwrap();
    let profile = src.parent().unwrap().join("profile.csv");
    if profile.exists() {
        std::fs::copy(&profile, dir.join("profile.csv")).unwrap();
    }
    util::write(dir, "job.toml", &edit(text))
}

#[test]
fn every_example_plans_within_delta_and_writes_program_and_report() {
    let machine_limit = 256; // grblHAL's line length, machine-profiles/sim.toml
    for job in util::examples() {
        let dir = tempfile::tempdir().unwrap();
        let (out, report) = (dir.path().join("p.nc"), dir.path().join("r.json"));
        let run = plan(&job, &out, &report, None);
        assert!(run.ok, "{}: {}", job.display(), run.stderr);
        let text = std::fs::read_to_string(&out).unwrap();
        assert!(text.lines().all(|l| l.len() <= machine_limit));
        assert!(
            text.lines().any(|l| util::block(l).starts_with("G93")),
            "linked moves in inverse time"
        );
        let r: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
        for key in [
            "segments",
            "nodes_per_period",
            "interp_error_mm",
            "scallop_mm",
            "max_error_mm",
            "delta_mm",
            "cycle_time_s",
        ] {
            assert!(r[key].is_number(), "{}: report lacks {key}", job.display());
        }
        assert!(r["max_error_mm"].as_f64().unwrap() <= r["delta_mm"].as_f64().unwrap());
        let linked = text
            .lines()
            .filter(|l| l.contains(" F") && l.contains('C'))
            .count();
        assert!(linked >= r["segments"].as_u64().unwrap() as usize);
    }
}

#[test]
fn han_liu_points_are_refused_naming_the_outlier() {
    let dir = tempfile::tempdir().unwrap();
    let csv = std::fs::read_to_string(util::root().join("tests/data/han-liu-table1.csv")).unwrap();
    util::write(dir.path(), "han-liu.csv", &csv);
    let job = util::write(
        dir.path(),
        "job.toml",
        r#"
[groove]
lead = 88.0
starts = 2
hand = "right"
z_start = 0.0
length = 20.0
[groove.profile]
section = "transverse"
points = "han-liu.csv"
mirror = true
[tool]
whirling = "internal"
ring_radius = 120.0
nose_radius = 1.2
inserts = 4
installation_angle_deg = 10.0
[cut]
delta = 0.01
axial_feed = 0.1
workpiece_rpm = 10.0
ring_rpm = 1500.0
"#,
    );
    let msg = refused(&job, None);
    assert!(
        msg.contains("han-liu.csv") && msg.contains("line 9"),
        "{msg}"
    );
    assert!(
        msg.contains("25.8") && msg.contains("12.78") && msg.contains("outlier"),
        "{msg}"
    );
}

#[test]
fn an_unknown_key_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let job = edited(dir.path(), "double-start", |t| {
        t.replace("inserts = 4", "insert = 4")
    });
    let msg = refused(&job, None);
    assert!(msg.contains("insert"), "{msg}");
}

#[test]
fn a_missing_profile_file_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let job = edited(dir.path(), "double-start", |t| {
        t.replace("profile.csv", "nowhere.csv")
    });
    let msg = refused(&job, None);
    assert!(msg.contains("nowhere.csv"), "{msg}");
}

#[test]
fn a_value_out_of_range_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let job = edited(dir.path(), "double-start", |t| {
        t.replace("delta = 0.005", "delta = -1.0")
    });
    let msg = refused(&job, None);
    assert!(msg.contains("cut.delta"), "{msg}");
}

#[test]
fn a_feed_whose_scallop_eats_delta_is_refused_with_the_feed_that_would_do() {
    let dir = tempfile::tempdir().unwrap();
    let job = edited(dir.path(), "double-start", |t| {
        t.replace("axial_feed = 0.1 ", "axial_feed = 0.6 ")
    });
    let msg = refused(&job, None);
    assert!(
        msg.contains("scallop") && msg.contains("axial_feed"),
        "{msg}"
    );
}

#[test]
fn a_nose_too_big_for_the_root_is_refused_with_the_depth_left() {
    let dir = tempfile::tempdir().unwrap();
    // The ball groove's radius is 3.429 mm: a 4 mm nose cannot follow it.
    let job = edited(dir.path(), "ball-screw", |t| {
        t.replace("nose_radius = 1.6", "nose_radius = 4.0")
    });
    let msg = refused(&job, None);
    assert!(
        msg.contains("concave") && msg.contains("radius 3.4"),
        "{msg}"
    );
    assert!(
        msg.contains("material") || msg.contains("does not fit"),
        "{msg}"
    );
}

#[test]
fn a_mismatched_installation_angle_is_refused_with_the_angles_that_work() {
    let dir = tempfile::tempdir().unwrap();
    let job = edited(dir.path(), "trapezoidal", |t| {
        t.replace(
            "installation_angle_deg = 7.8",
            "installation_angle_deg = 12.0",
        )
    });
    let msg = refused(&job, None);
    assert!(msg.contains("interference"), "{msg}");
    assert!(msg.contains("installation angles that work"), "{msg}");
}

#[test]
fn a_program_past_the_machine_travel_is_refused_naming_the_axis() {
    let dir = tempfile::tempdir().unwrap();
    let sim = std::fs::read_to_string(util::root().join("machine-profiles/sim.toml")).unwrap();
    // The double-start example needs Z from about −13.5 to 13.5 mm.
    let small = sim.replacen("min = -300.0", "min = -5.0", 1); // Z's lower travel
    assert_ne!(
        small, sim,
        "the edit must apply to machine-profiles/sim.toml"
    );
    let machine = util::write(dir.path(), "small.toml", &small);
    let job = edited(dir.path(), "double-start", |t| t);
    let msg = refused(&job, Some(&machine));
    assert!(msg.contains("Z") && msg.contains("-5"), "{msg}");
}

#[test]
fn a_program_faster_than_an_axis_can_move_is_refused_naming_the_move() {
    let dir = tempfile::tempdir().unwrap();
    // At 150 rpm the lobe's X swings 8 mm in a quarter of a workpiece turn (0.1 s): about
    // 4800 mm/min, beyond the simulator's 3000 mm/min. The ring speed goes up too, so the
    // insert cusp stays small and the limit, not the budget, is what refuses it.
    let job = edited(dir.path(), "double-start", |t| {
        t.replace("workpiece_rpm = 10.0", "workpiece_rpm = 150.0")
            .replace("ring_rpm = 1500.0", "ring_rpm = 12000.0")
    });
    let msg = refused(&job, None);
    assert!(
        msg.contains("X speed") && msg.contains("max_rate 3000"),
        "{msg}"
    );
    assert!(msg.contains("move "), "{msg}");
}

#[test]
fn a_linuxcnc_plan_blends_within_its_share_and_writes_diameters() {
    let dir = tempfile::tempdir().unwrap();
    let (out, report) = (dir.path().join("p.ngc"), dir.path().join("r.json"));
    let machine = util::root().join("machine-profiles/linuxcnc-lathe.toml");
    let run = plan(
        &util::example("double-start"),
        &out,
        &report,
        Some(&machine),
    );
    assert!(run.ok, "{}", run.stderr);
    let text = std::fs::read_to_string(&out).unwrap();
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let blend = r["blend_mm"].as_f64().unwrap();
    assert!(blend > 0.0 && blend <= r["delta_mm"].as_f64().unwrap() / 5.0);
    assert!(
        text.lines()
            .any(|l| l.starts_with("G64 P") && l.ends_with("Q0")),
        "G64 P… Q0"
    );
    assert!(text.starts_with("%\n") && text.trim_end().ends_with('%'));
    // Internal whirling plunges to X = R − (ρ + r) at most: written as a diameter, above R.
    let first_plunge = text.lines().find(|l| l.starts_with("G1 X")).unwrap();
    let x: f64 = first_plunge[4..]
        .split(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!(
        x > 2.0 * (60.0 - 34.0 - 1.2) && x < 2.0 * 60.0,
        "{first_plunge}"
    );
}

#[test]
fn sweep_paraboloid_writes_seed_000_s_section() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("section.csv");
    let o = util::whirl(&[
        OsStr::new("sweep"),
        OsStr::new("paraboloid"),
        OsStr::new("--a"),
        OsStr::new("-0.05"),
        OsStr::new("--b"),
        OsStr::new("7.2"),
        OsStr::new("--radius"),
        OsStr::new("20"),
        OsStr::new("--pitch"),
        OsStr::new("20"),
        OsStr::new("--accuracy"),
        OsStr::new("0.0001"),
        OsStr::new("-o"),
        out.as_os_str(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(&out).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("x,y"));
    let pts: Vec<(f64, f64)> = lines
        .map(|l| {
            let (x, y) = l.split_once(',').unwrap();
            (x.parse().unwrap(), y.parse().unwrap())
        })
        .collect();
    // Seed 000: the section meets the axis where a(x + R)² = −b, at x = −32 and x = −8,
    // and is ordered by x from one end to the other.
    assert_eq!(pts.first().unwrap(), &(-32.0, 0.0));
    assert_eq!(pts.last().unwrap(), &(-8.0, 0.0));
    assert!(pts.windows(2).all(|w| w[0].0 < w[1].0));
    // In the middle the boundary is the paper's Eq. 10.
    let (a, b, r, p) = (-0.05f64, 7.2f64, 20.0f64, 20.0f64);
    let eq10 = |x: f64| {
        let s = p / (4.0 * std::f64::consts::PI * a * r * x);
        a * x * x
            + 2.0 * a * x * r * (1.0 - s * s).sqrt()
            + a * r * r
            + b
            + p / (2.0 * std::f64::consts::PI) * s.asin()
    };
    for &(x, y) in pts.iter().filter(|(x, _)| (-30.0..=-10.0).contains(x)) {
        assert!(
            (y - eq10(x)).abs() < 1e-4,
            "x {x}: {y} vs Eq. 10 {}",
            eq10(x)
        );
    }
    let bad = util::whirl(&[
        OsStr::new("sweep"),
        OsStr::new("paraboloid"),
        OsStr::new("--a"),
        OsStr::new("0.05"),
        OsStr::new("--b"),
        OsStr::new("7.2"),
        OsStr::new("--radius"),
        OsStr::new("20"),
        OsStr::new("--pitch"),
        OsStr::new("20"),
        OsStr::new("-o"),
        dir.path().join("bad.csv").as_os_str(),
    ]);
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("must be negative"));
    assert!(!dir.path().join("bad.csv").exists());
}

#[test]
fn log_summary_and_plot_read_an_executed_path_log() {
    let dir = tempfile::tempdir().unwrap();
    let log = util::write(
        dir.path(),
        "exec.jsonl",
        concat!(
            r#"{"t":0.0,"event":"start","program":"p.nc","lines":1,"transport":"serial"}"#,
            "\n",
            r#"{"t":0.1,"event":"sent","line":1,"text":"G1 X1 F100"}"#,
            "\n",
            r#"{"t":0.2,"event":"ack","line":1}"#,
            "\n",
            r#"{"t":0.4,"event":"status","state":"Run","pos":[0.5,0.0,0.0]}"#,
            "\n",
            r#"{"t":0.9,"event":"executed","line":1,"times":[0.2,0.8],"from":[0,0,0],"to":[1,0,0]}"#,
            "\n",
            r#"{"t":1.0,"event":"end","completed":true}"#,
            "\n",
        ),
    );
    let o = util::whirl(&[OsStr::new("log"), OsStr::new("summary"), log.as_os_str()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(
        (
            s["sent"].as_u64(),
            s["acked"].as_u64(),
            s["executed"].as_u64()
        ),
        (Some(1), Some(1), Some(1))
    );
    assert_eq!(s["completed"], true);
    let svg = dir.path().join("p.svg");
    let o = util::whirl(&[
        OsStr::new("log"),
        OsStr::new("plot"),
        log.as_os_str(),
        OsStr::new("-o"),
        svg.as_os_str(),
    ]);
    assert!(o.status.success());
    let text = std::fs::read_to_string(&svg).unwrap();
    assert_eq!(text.matches("over time").count(), 3, "X, Z and C panels");
    let bad = util::write(
        dir.path(),
        "bad.jsonl",
        "{\"t\":0}\nnonsense\n{\"t\":1,\"event\":\"ack\",\"line\":1}\n",
    );
    // Lines that are not events are skipped and named, not fatal.
    let o = util::whirl(&[OsStr::new("log"), OsStr::new("summary"), bad.as_os_str()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(
        (s["acked"].as_u64(), s["skipped"].as_u64()),
        (Some(1), Some(2))
    );
    let skipped: Vec<&serde_json::Value> = s["skipped_lines"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| &l["line"])
        .collect();
    assert_eq!(skipped, [1, 2]);
}

#[test]
fn a_groove_too_long_for_a_32_bit_controllers_c_is_refused_naming_how_far_c_goes() {
    // 400 mm of the ball screw at 0.06 mm a turn: C passes 2.4 million degrees, where a
    // 32-bit float holds C to ±0.125°; by screw invariance that is up to
    // 0.125° · π/180 · p = 3.5 µm off the surface (p = 10/2π mm), over half of Δ = 5 µm.
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(util::example("ball-screw")).unwrap();
    let long = text.replace("length = 100.0", "length = 400.0");
    assert_ne!(long, text);
    let job = util::write(dir.path(), "long.toml", &long);
    let message = refused(&job, None);
    assert!(message.contains("32-bit positions"), "{message}");
    assert!(message.contains("±0.125°"), "{message}");
    // A controller with 64-bit positions plans it.
    let linuxcnc = util::root().join("machine-profiles/linuxcnc-lathe.toml");
    let (out, report) = (dir.path().join("p.nc"), dir.path().join("r.json"));
    let run = plan(&job, &out, &report, Some(&linuxcnc));
    assert!(run.ok, "{}", run.stderr);
}

/// `whirl ARGS…` that must fail: its exit code 1 and its message.
fn fails(args: &[&OsStr]) -> String {
    let o = util::whirl(args);
    assert_eq!(
        o.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
    String::from_utf8_lossy(&o.stderr).into()
}

#[test]
fn can_transports_without_drives_or_a_port_are_refused_before_anything_is_opened() {
    let dir = tempfile::tempdir().unwrap();
    let job = util::example("double-start");
    let log = dir.path().join("exec.jsonl");
    // The built-in simulator's profile is a grblHAL machine: it says nothing of CAN drives.
    let message = fails(&[
        OsStr::new("dry-run"),
        job.as_os_str(),
        OsStr::new("--transport"),
        OsStr::new("can-slcan"),
        OsStr::new("--log"),
        log.as_os_str(),
    ]);
    assert!(message.contains("has no CAN drives"), "{message}");
    assert!(
        message.contains("machine-profiles/canopen-drives.toml"),
        "{message}"
    );
    // The simulated drives hang off an slcan adapter, not a socketcan interface.
    let profile = util::root().join("machine-profiles/canopen-drives.toml");
    let message = fails(&[
        OsStr::new("dry-run"),
        job.as_os_str(),
        OsStr::new("--machine"),
        profile.as_os_str(),
        OsStr::new("--transport"),
        OsStr::new("can"),
    ]);
    assert!(message.contains("--transport can-slcan"), "{message}");
    // No --port and a profile whose [connection] is for another transport.
    let program = util::write(dir.path(), "p.nc", "G21 G90 G94\nG0 X1 Z0 C0\n");
    let message = fails(&[
        OsStr::new("stream"),
        program.as_os_str(),
        OsStr::new("--machine"),
        profile.as_os_str(),
        OsStr::new("--transport"),
        OsStr::new("modbus-tcp"),
        OsStr::new("--log"),
        log.as_os_str(),
    ]);
    assert!(message.contains("no port given"), "{message}");
    assert!(message.contains("modbus-tcp"), "{message}");
    // Nothing was run: the log was never opened.
    assert!(!log.exists());
}

#[test]
fn a_can_stream_to_a_port_that_does_not_exist_names_it() {
    let dir = tempfile::tempdir().unwrap();
    let profile = util::root().join("machine-profiles/canopen-drives.toml");
    let program = util::write(dir.path(), "p.nc", "G21 G90 G94\nG0 X1 Z0 C0\n");
    let missing = dir.path().join("no-adapter");
    let message = fails(&[
        OsStr::new("stream"),
        program.as_os_str(),
        // Written here, not planned: it carries no provenance.
        OsStr::new("--no-provenance-check"),
        OsStr::new("--machine"),
        profile.as_os_str(),
        OsStr::new("--port"),
        missing.as_os_str(),
        OsStr::new("--log"),
        dir.path().join("exec.jsonl").as_os_str(),
    ]);
    assert!(message.contains("cannot open slcan adapter"), "{message}");
    assert!(message.contains("no-adapter"), "{message}");
}

#[test]
fn each_cause_is_said_once() {
    let dir = tempfile::tempdir().unwrap();
    // A points file with a bad number, a missing points file, a job that is not TOML, a
    // log in a folder that does not exist, an unreadable machine profile: each error and
    // its causes, printed as one chain, name each thing once.
    let bad_points = edited(dir.path(), "double-start", |t| t);
    util::write(dir.path(), "profile.csv", "x,y\n30,0\n29,abc\n");
    let missing = util::write(
        dir.path(),
        "missing.toml",
        &std::fs::read_to_string(util::example("double-start"))
            .unwrap()
            .replace("profile.csv", "nowhere.csv"),
    );
    let not_toml = util::write(dir.path(), "broken.toml", "[groove\nlead = ");
    let nowhere = dir.path().join("no/such/folder/run.jsonl");
    let example = util::example("double-start");
    let out = dir.path().join("p.nc");
    let cases: Vec<Vec<&OsStr>> = vec![
        vec![
            OsStr::new("plan"),
            bad_points.as_os_str(),
            OsStr::new("-o"),
            out.as_os_str(),
        ],
        vec![
            OsStr::new("plan"),
            missing.as_os_str(),
            OsStr::new("-o"),
            out.as_os_str(),
        ],
        vec![
            OsStr::new("plan"),
            not_toml.as_os_str(),
            OsStr::new("-o"),
            out.as_os_str(),
        ],
        vec![
            OsStr::new("dry-run"),
            example.as_os_str(),
            OsStr::new("--log"),
            nowhere.as_os_str(),
        ],
        vec![
            OsStr::new("plan"),
            example.as_os_str(),
            OsStr::new("--machine"),
            nowhere.as_os_str(),
            OsStr::new("-o"),
            out.as_os_str(),
        ],
    ];
    for args in cases {
        let message = fails(&args);
        let line = message.trim_end();
        assert!(line.starts_with("error: "), "{line}");
        // No stretch of the message (a cause's text) comes twice.
        let parts: Vec<&str> = line.split(": ").map(str::trim).collect();
        for (i, part) in parts.iter().enumerate() {
            if part.len() > 12 {
                assert!(
                    !parts[i + 1..].contains(part),
                    "{part:?} said twice in {line:?}"
                );
            }
        }
        for os_error in ["No such file or directory", "invalid digit"] {
            assert!(line.matches(os_error).count() <= 1, "{line}");
        }
    }
    assert!(!out.exists());
}
