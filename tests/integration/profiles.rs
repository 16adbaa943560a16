//! `whirl plan` on sampled profiles as CAD exports write them: dense, rounded to a number of
//! decimals, sometimes with an absurd value; and on an absurd Δ. The groove throughout is the
//! double-start example's, ρ = 30 − 4·cos 2φ (root 26 mm at φ = 0, crest 34 mm at φ = 90°),
//! given as half a period (0 ≤ φ ≤ 90°, both ends included) and mirrored, as its own profile is.
//!
//! The runs go through the real binary. Each is watched by [`WATCHDOG`], a guard against a run
//! that never ends (the outlier check was once quadratic: a million points took hours), not a
//! measure of speed: that is `cargo bench --bench planner -- dense_profile`
//! (docs/benchmarks.md).

use crate::util;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Far beyond any sound run on a slow, busy machine (the million points plan in about a second
/// on the 2-core development machine), far below the hours of a quadratic check.
const WATCHDOG: Duration = Duration::from_secs(600);

/// `n` points of half a period of ρ = 30 − 4·cos 2φ, written to `decimals`, after an `x,y`
/// header (point k is on line k + 2).
fn half_period_csv(n: usize, decimals: usize) -> String {
    let mut csv = String::with_capacity(n * (2 * decimals + 8));
    csv.push_str("x,y\n");
    for k in 0..n {
        let phi = std::f64::consts::FRAC_PI_2 * k as f64 / (n - 1) as f64;
        let rho = 30.0 - 4.0 * (2.0 * phi).cos();
        csv.push_str(&format!(
            "{:.decimals$},{:.decimals$}\n",
            rho * phi.cos(),
            rho * phi.sin()
        ));
    }
    csv
}

/// The double-start example's job in `dir`, with `edit` applied to its text, reading its points
/// from `dir/profile.csv` (`csv`).
fn job(dir: &Path, csv: &str, edit: impl Fn(String) -> String) -> PathBuf {
    let text = std::fs::read_to_string(util::example("double-start")).unwrap();
    assert!(text.contains("points = \"profile.csv\"") && text.contains("mirror = true"));
    util::write(dir, "profile.csv", csv);
    util::write(dir, "job.toml", &edit(text))
}

/// What a `whirl plan` run of `job` gave: whether it succeeded, its report (if written) and its
/// standard error.
struct Planned {
    ok: bool,
    report: Option<serde_json::Value>,
    stderr: String,
}

/// Run `whirl plan job -o … --report …`, killed if it outlives [`WATCHDOG`].
fn plan(job: &Path) -> Planned {
    let dir = job.parent().unwrap();
    let (out, report) = (dir.join("p.nc"), dir.join("r.json"));
    let mut child = Command::new(env!("CARGO_BIN_EXE_whirl"))
        .env("WHIRL_DB", util::records_db())
        .arg("plan")
        .arg(job)
        .arg("-o")
        .arg(&out)
        .arg("--report")
        .arg(&report)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the whirl binary runs");
    let deadline = Instant::now() + WATCHDOG;
    while child.try_wait().unwrap().is_none() {
        if Instant::now() > deadline {
            child.kill().unwrap();
            child.wait().unwrap();
            panic!(
                "whirl plan {} did not end within {WATCHDOG:?}",
                job.display()
            );
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let output = child.wait_with_output().unwrap();
    Planned {
        ok: output.status.success(),
        report: std::fs::read_to_string(&report)
            .ok()
            .map(|text| serde_json::from_str(&text).unwrap()),
        stderr: String::from_utf8_lossy(&output.stderr).into(),
    }
}

/// Plan `n` points at `decimals` and check the program keeps within Δ.
fn plans_within_delta(n: usize, decimals: usize) {
    let dir = tempfile::tempdir().unwrap();
    let job = job(dir.path(), &half_period_csv(n, decimals), |t| t);
    let run = plan(&job);
    assert!(run.ok, "{n} points at {decimals} decimals: {}", run.stderr);
    let report = run.report.expect("a report");
    let (bound, delta) = (report["max_error_mm"].as_f64(), report["delta_mm"].as_f64());
    assert!(bound.unwrap() <= delta.unwrap(), "{report}");
}

#[test]
fn five_hundred_points_at_four_decimals_plan_within_delta() {
    // 0.1 mm apart, each within 0.00005 mm of the curve in x and in y: the rounding makes the
    // points zig-zag, by far less than 1 % of their spacing. (Line 20 was refused as "0.011 mm
    // off the curve": the distance was measured to 4000 samples of the curve, 0.01 mm apart.)
    plans_within_delta(500, 4);
}

#[test]
fn four_hundred_thousand_points_at_ten_decimals_plan_within_delta() {
    // 0.13 µm apart (one was refused as an outlier after two minutes).
    plans_within_delta(400_000, 10);
}

#[test]
fn a_million_points_at_ten_decimals_plan_within_delta() {
    // 0.05 µm apart: two million spline knots once mirrored.
    plans_within_delta(1_000_000, 10);
}

#[test]
fn points_packed_closer_than_their_decimals_resolve_are_fitted_within_them_and_plan() {
    // 20 000 points 2.5 µm apart at 4 decimals: rounding moves them by up to 0.07 µm, a
    // twenty-fifth of their spacing, so a spline through them would kink at every point
    // (they were refused for concave stretches). Fitted within their rounding, they plan,
    // and not as outliers.
    plans_within_delta(20_000, 4);
}

/// `n` points of one whole period (0 ≤ φ < 180°) of ρ = 30 − 4·cos 2φ, each moved by
/// `scatter(k)` along its radius, written to `decimals`, after an `x,y` header.
fn period_csv(n: usize, decimals: usize, scatter: impl Fn(usize) -> f64) -> String {
    let mut csv = String::with_capacity(n * (2 * decimals + 8));
    csv.push_str("x,y\n");
    for k in 0..n {
        let phi = std::f64::consts::PI * k as f64 / n as f64;
        let rho = 30.0 - 4.0 * (2.0 * phi).cos() + scatter(k);
        csv.push_str(&format!(
            "{:.decimals$},{:.decimals$}\n",
            rho * phi.cos(),
            rho * phi.sin()
        ));
    }
    csv
}

/// The double-start job in `dir` on the whole period of `csv`, `extra` added to its
/// `[groove.profile]`; planned, its report, and `whirl verify`'s verdict on the program.
fn plan_and_verify(dir: &Path, csv: &str, extra: &str) -> (serde_json::Value, bool) {
    let job = job(dir, csv, |t| {
        t.replace("mirror = true", &format!("mirror = false\n{extra}"))
    });
    let run = plan(&job);
    assert!(run.ok, "{}", run.stderr);
    let verified = util::whirl(&[
        std::ffi::OsStr::new("verify"),
        dir.join("p.nc").as_os_str(),
        std::ffi::OsStr::new("--job"),
        job.as_os_str(),
        std::ffi::OsStr::new("--report"),
        dir.join("v.json").as_os_str(),
    ]);
    let said = String::from_utf8_lossy(&verified.stdout);
    (
        run.report.unwrap(),
        verified.status.success() && said.contains("within"),
    )
}

#[test]
fn the_double_starts_curve_at_four_decimals_plans_as_the_exact_curve_from_2000_and_200000_points() {
    // Issue 23: at the exact curve's installation angle ±0.05°, within 5 % of its segments,
    // within Δ by whirl verify; the fit's distance from the points counted.
    let dir = tempfile::tempdir().unwrap();
    let (exact, verified) = plan_and_verify(dir.path(), &period_csv(2000, 12, |_| 0.0), "");
    assert!(verified);
    let angle = |r: &serde_json::Value| r["installation_angle_deg"].as_f64().unwrap();
    let segments = |r: &serde_json::Value| r["segments"].as_f64().unwrap();
    for n in [2000, 200_000] {
        let dir = tempfile::tempdir().unwrap();
        let (rounded, verified) = plan_and_verify(dir.path(), &period_csv(n, 4, |_| 0.0), "");
        assert!(verified, "{n} points");
        assert!(
            (angle(&rounded) - angle(&exact)).abs() <= 0.05,
            "{n}: {rounded}"
        );
        assert!(
            (segments(&rounded) / segments(&exact) - 1.0).abs() <= 0.05,
            "{n}: {rounded}"
        );
        // Half the 4th decimal in x and y at most.
        let fit = rounded["fit_mm"].as_f64().unwrap();
        assert!(
            fit > 0.0 && fit <= 0.00005f64.hypot(0.00005),
            "{n}: {rounded}"
        );
    }
}

#[test]
fn a_scan_with_two_micrometres_of_scatter_plans_with_its_tolerance_stated() {
    // 4 000 points 24 µm apart, each off the curve by up to ±2 µm (a fixed sequence of a
    // linear congruential generator), written to 4 decimals as a measuring machine would.
    let scatter = |k: usize| {
        let x = (k as u64)
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((x >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0) * 0.002
    };
    let csv = period_csv(4000, 4, scatter);
    // Fitted within the 4th decimal alone, the scatter stays in the curve: its kinks are
    // tighter than the nose, and the refusal names the tolerance to state.
    let dir = tempfile::tempdir().unwrap();
    let job = job(dir.path(), &csv, |t| {
        t.replace("mirror = true", "mirror = false")
    });
    let run = plan(&job);
    assert!(
        !run.ok && run.stderr.contains("fit_tolerance"),
        "{}",
        run.stderr
    );
    // With the scan's tolerance (2 µm, plus the 4th decimal's rounding) it plans within Δ,
    // and the report says how far the fit lies from the points: within that tolerance.
    let dir = tempfile::tempdir().unwrap();
    let (report, verified) = plan_and_verify(dir.path(), &csv, "fit_tolerance = 0.0021");
    assert!(verified, "{report}");
    let fit = report["fit_mm"].as_f64().unwrap();
    assert!(fit > 0.0 && fit <= 0.0021, "{report}");
}

#[test]
fn a_point_at_1e308_is_refused_naming_its_line() {
    // Once every other pair of points looked like a duplicate next to it (the tolerance was
    // relative to the largest radius), and line 3 was blamed.
    let dir = tempfile::tempdir().unwrap();
    let own = std::fs::read_to_string(util::root().join("examples/double-start/profile.csv"));
    let own = own.unwrap();
    assert_eq!(own.lines().nth(7), Some("21.2132,21.2132"), "line 8");
    let job = job(
        dir.path(),
        &own.replace("21.2132,21.2132", "1e308,1e308"),
        |t| t,
    );
    let run = plan(&job);
    assert!(!run.ok && run.report.is_none(), "must be refused");
    assert!(
        run.stderr.contains("profile.csv: line 8 (1e308, 1e308)"),
        "{}",
        run.stderr
    );
}

#[test]
fn an_absurd_delta_is_refused_at_once_naming_cut_delta() {
    let own = std::fs::read_to_string(util::root().join("examples/double-start/profile.csv"));
    let own = own.unwrap();
    for (delta, why) in [
        // Beyond the groove's 8 mm depth (radii 26 to 34 mm) it bounds nothing; 10³⁰⁸ once
        // planned, with a first line no controller could receive.
        ("1e308", "depth, 8.0000 mm"),
        // Below what 6 decimals can hold to Δ/60: 60 × 0.5·10⁻⁶ mm (10⁻¹² once took half a
        // minute and 1.27 GB to be refused).
        ("1e-12", "below 0.00003 mm"),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let job = job(dir.path(), &own, |t| {
            t.replace("delta = 0.005", &format!("delta = {delta}"))
        });
        let run = plan(&job);
        assert!(
            !run.ok && run.report.is_none(),
            "Δ = {delta} must be refused"
        );
        assert!(
            run.stderr.contains(&format!("cut.delta = {delta}")) && run.stderr.contains(why),
            "{}",
            run.stderr
        );
    }
}
