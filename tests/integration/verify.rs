//! `whirl verify` and `whirl plan --verify` end to end.

use crate::util;
use std::ffi::OsStr;
use std::path::Path;

fn run(args: &[&OsStr]) -> (Option<i32>, String, String) {
    let o = util::whirl(args);
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stdout).into(),
        String::from_utf8_lossy(&o.stderr).into(),
    )
}

/// Plan an example into `dir`, return the program path.
fn planned(dir: &Path, name: &str) -> std::path::PathBuf {
    let out = dir.join(format!("{name}.nc"));
    let (code, _, err) = run(&[
        OsStr::new("plan"),
        util::example(name).as_os_str(),
        OsStr::new("-o"),
        out.as_os_str(),
    ]);
    assert_eq!(code, Some(0), "{err}");
    out
}

fn verify(
    program: &Path,
    name: &str,
    report: &Path,
    svg: Option<&Path>,
) -> (Option<i32>, serde_json::Value, String) {
    let job = util::example(name);
    let mut args = vec![
        OsStr::new("verify"),
        program.as_os_str(),
        OsStr::new("--job"),
        job.as_os_str(),
        OsStr::new("--report"),
        report.as_os_str(),
    ];
    if let Some(s) = svg {
        args.push(OsStr::new("--svg"));
        args.push(s.as_os_str());
    }
    let (code, _, err) = run(&args);
    let json = std::fs::read_to_string(report)
        .map(|t| serde_json::from_str(&t).unwrap())
        .unwrap_or(serde_json::Value::Null);
    (code, json, err)
}

#[test]
fn a_planned_program_verifies_within_delta_with_a_picture() {
    let dir = tempfile::tempdir().unwrap();
    let program = planned(dir.path(), "double-start");
    let (report, svg) = (dir.path().join("v.json"), dir.path().join("s.svg"));
    let (code, r, err) = verify(&program, "double-start", &report, Some(&svg));
    assert_eq!(code, Some(0), "{err}");
    let delta = r["delta_mm"].as_f64().unwrap();
    for key in ["max_overcut_mm", "max_undercut_mm"] {
        let v = r[key].as_f64().unwrap();
        assert!((0.0..=delta).contains(&v), "{key} {v}");
    }
    assert_eq!(r["within_delta"], true);
    assert!(r["worst_overcut"]["at"].is_array() && r["points"].as_u64().unwrap() > 1000);
    let picture = std::fs::read_to_string(&svg).unwrap();
    assert!(
        picture.starts_with("<svg") && picture.contains("target") && picture.contains("machined")
    );
}

#[test]
fn a_stretch_thirty_microns_off_is_seen_where_it_is() {
    let dir = tempfile::tempdir().unwrap();
    let program = planned(dir.path(), "double-start");
    // Push X out by 0.03 mm on the linked moves whose Z lies in [−2, 2]: for internal
    // whirling a larger X moves the cutting side of the ring towards the axis, so the ring
    // cuts up to 0.03·|n·x̂| too deep there (30 µm at the radial-normal root and crest).
    let text = std::fs::read_to_string(&program).unwrap();
    let mut last_z = f64::NAN;
    let edited: Vec<String> = text
        .lines()
        .map(|line| {
            let word = |c: char| {
                line.split(' ')
                    .find(|w| w.starts_with(c))
                    .and_then(|w| w[1..].parse::<f64>().ok())
            };
            if let Some(z) = word('Z') {
                last_z = z;
            }
            match word('X') {
                Some(x)
                    if util::block(line).starts_with("G1")
                        && line.contains('F')
                        && (-2.0..=2.0).contains(&last_z) =>
                {
                    let old = line.split(' ').find(|w| w.starts_with('X')).unwrap();
                    line.replacen(old, &format!("X{:.4}", x + 0.03), 1)
                }
                _ => line.to_owned(),
            }
        })
        .collect();
    let bad = dir.path().join("bad.nc");
    std::fs::write(&bad, edited.join("\n") + "\n").unwrap();
    let report = dir.path().join("v.json");
    let (code, r, err) = verify(&bad, "double-start", &report, None);
    assert_eq!(code, Some(2), "beyond Δ exits 2: {err}");
    assert_eq!(r["within_delta"], false);
    let over = r["max_overcut_mm"].as_f64().unwrap();
    assert!(
        over > 0.02 && over < 0.035,
        "about 30 µm of overcut: {over}"
    );
    let z = r["worst_overcut"]["at"][2].as_f64().unwrap();
    // The ring reaches about R·sin δ + r = 19.4 mm axially from its centre; the contact stays
    // within a few mm of it. The worst point must be near the edited stretch.
    assert!((-8.0..=8.0).contains(&z), "worst overcut at z {z}");
}

#[test]
fn plan_verify_records_the_measurement() {
    let dir = tempfile::tempdir().unwrap();
    let (out, report) = (dir.path().join("p.nc"), dir.path().join("r.json"));
    let (code, stdout, err) = run(&[
        OsStr::new("plan"),
        util::example("left-external").as_os_str(),
        OsStr::new("-o"),
        out.as_os_str(),
        OsStr::new("--report"),
        report.as_os_str(),
        OsStr::new("--verify"),
    ]);
    assert_eq!(code, Some(0), "{err}");
    assert!(stdout.contains("verified"));
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let v = &r["verify"];
    assert!(v["max_overcut_mm"].as_f64().unwrap() <= r["delta_mm"].as_f64().unwrap());
    assert!(v["max_undercut_mm"].as_f64().unwrap() <= r["delta_mm"].as_f64().unwrap());
}

#[test]
fn programs_that_cannot_be_measured_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("v.json");
    let still = util::write(
        dir.path(),
        "still.nc",
        "G21 G90 G94\nG0 X0 Z0 C0\nG1 X10 F100\nM2\n",
    );
    let (code, _, err) = verify(&still, "double-start", &report, None);
    assert_eq!(code, Some(1));
    assert!(err.contains("never turns C"), "{err}");
    let broken = util::write(dir.path(), "broken.nc", "G21 G90\nG1 X1 Q\n");
    let (code, _, err) = verify(&broken, "double-start", &report, None);
    assert_eq!(code, Some(1));
    assert!(err.contains("line 2"), "{err}");
    assert!(!report.exists(), "nothing written on errors");
}
