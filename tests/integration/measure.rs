//! `whirl measure` end to end: a part cut with a tool off the job's (ring radius +0.02 mm,
//! installation angle +0.3°) is measured in an axial section, the tool is fitted, the job
//! corrected, and the part cut again with the same real tool comes back within Δ; and every
//! kind of bad input is refused naming the file line and the reason, with nothing written.
//!
//! "Cutting" is the swept-volume engine: the program planned for the job, swept with the
//! real tool ([`Target::error_at_u`] for the measured section, [`Target::measure`] for the
//! whole groove). The measured points are the engine's section, each moved along the section's
//! normal by the error there, with a measuring machine's noise, written as a CMM file in
//! the format of docs/measure.md.

use crate::util;
use glam::DVec2;
use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use whirl::config::job::Job;
use whirl::config::machine::MachineProfile;
use whirl::geometry::linkage::{Linkage, Ring};
use whirl::geometry::profile::surface_normal;
use whirl::judge::measure::{Motion, Target};
use whirl::post::gcode::parse::read_program;

/// The injected setup error: ring radius, mm, and installation angle, degrees.
const RING_OFF: f64 = 0.02;
const ANGLE_OFF: f64 = 0.3;
/// The measuring machine's noise along the section's normal, mm (a standard deviation).
const NOISE: f64 = 0.0005;

/// The ring the parts are really cut with: the one their program was planned with, set up
/// off by the injected error.
fn real(ring: Ring) -> Ring {
    Ring {
        radius: ring.radius + RING_OFF,
        installation: ring.installation + ANGLE_OFF.to_radians(),
        ..ring
    }
}

/// `job`'s groove over its formed length, as `ring` cuts it.
fn cut_by(job: &Job, ring: Ring) -> Target {
    Target::new(
        job.profile.clone(),
        Linkage { p: job.p(), ring },
        job.groove.starts,
        (job.groove.z_start, job.groove.z_start + job.groove.length),
        job.cut.axial_feed,
    )
    .unwrap()
}

/// The motion of `job` planned for the simulator, as `whirl plan` plans it, and the ring it
/// was planned with.
fn planned(job: &Job) -> (Motion, Ring) {
    let machine = MachineProfile::builtin_sim().unwrap();
    let plan = whirl::judge::refine::plan(job, &machine).unwrap();
    let program = read_program(&plan.text, machine.x_diameter()).unwrap();
    (Motion::new(&program).unwrap(), plan.ring)
}

/// Normal deviates, deterministic: xorshift64* and Box–Muller.
struct Noise(u64);

impl Noise {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        ((self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    fn normal(&mut self) -> f64 {
        let (a, b) = (self.uniform(), self.uniform());
        (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
    }
}

/// The axial section at polar angle 0 that `tool` cut with `motion`, at the profile
/// parameters `us`, each on the copy nearest `z_mid` (those within the formed length): a CMM
/// file, z first and measured from `z_mid`, to 4 decimals, with [`NOISE`].
fn measured_csv(job: &Job, tool: &Target, motion: &Motion, us: &[f64], z_mid: f64) -> String {
    let p = job.p();
    let pitch = p * job.period();
    let starts = i64::from(job.groove.starts);
    let mut noise = Noise(0x9E37_79B9_7F4A_7C15);
    let mut csv = format!(
        "# measured by CMM, probe 1 mm\n# section = axial\n# angle_deg = 0\n# units = mm\n\
         # columns = z, rho\n# origin = {z_mid}, 0\nz,rho\n"
    );
    for &u in us {
        let point = job.profile.point(u);
        let phi = point.pos.to_angle();
        // kinematics.md's axial rule: polar angle φ lies at z = −p·φ (plus whole pitches).
        let j = ((z_mid + p * phi) / pitch).round();
        let z = -p * phi + j * pitch;
        if z < job.groove.z_start || z > job.groove.z_start + job.groove.length {
            continue;
        }
        // Turning start s by z/p brings it to polar angle 0 when s ≡ −j (mod starts).
        let start = (-(j as i64)).rem_euclid(starts) as u32;
        let error = tool.error_at_u(motion, u, start, z);
        let n = surface_normal(point.pos, point.tangent, p);
        let radial = point.pos.normalize();
        let in_plane = DVec2::new(n.x * radial.x + n.y * radial.y, n.z);
        let share = in_plane.length();
        let at = DVec2::new(point.pos.length(), z)
            + in_plane / share * (error / share + NOISE * noise.normal());
        csv.push_str(&format!("{:.4},{:.4}\n", at.y - z_mid, at.x));
    }
    csv
}

/// Points within this distance of an edge of the profile are not measured, mm.
const EDGE_CLEARANCE: f64 = 0.1;

/// `count` profile parameters spread evenly over one period, those on its surfaces clear of
/// its edges. The measured points are the target moved along its normal by the engine's
/// error, which is the machined surface only where that surface is the offset of one face:
/// within the error's size of a convex edge an overcut flank's offset runs under the crest's.
/// (A scan steers clear of edges too.)
fn spread(job: &Job, count: usize) -> Vec<f64> {
    let at = |u: f64| job.profile.point(u).pos;
    let length = job.profile.length();
    // The edges: where the profile point stays put while the parameter runs on.
    let n = 20_000;
    let edges: Vec<_> = (0..=n)
        .map(|k| length * k as f64 / n as f64)
        .filter(|&u| (at(u + 1e-6) - at(u - 1e-6)).length() < 1e-9)
        .map(at)
        .collect();
    (0..count)
        .map(|k| length * (k as f64 + 0.5) / count as f64)
        .filter(|&u| edges.iter().all(|e| (at(u) - *e).length() > EDGE_CLEARANCE))
        .collect()
}

fn run(args: &[&OsStr]) -> (Option<i32>, String, String) {
    let o = util::whirl(args);
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stdout).into(),
        String::from_utf8_lossy(&o.stderr).into(),
    )
}

/// `whirl measure JOB SECTION --fit --correct -o JOB2 --report R --svg S`, with `extra`.
fn measure(
    job: &Path,
    section: &Path,
    dir: &Path,
    extra: &[&str],
) -> (Option<i32>, String, String) {
    let (out, report, svg) = outputs(dir);
    let mut args: Vec<&OsStr> = vec![
        OsStr::new("measure"),
        job.as_os_str(),
        section.as_os_str(),
        OsStr::new("--fit"),
        OsStr::new("--correct"),
        OsStr::new("-o"),
        out.as_os_str(),
        OsStr::new("--report"),
        report.as_os_str(),
        OsStr::new("--svg"),
        svg.as_os_str(),
    ];
    args.extend(extra.iter().map(OsStr::new));
    run(&args)
}

/// The corrected job, the report and the picture `measure` writes into `dir`.
fn outputs(dir: &Path) -> (PathBuf, PathBuf, PathBuf) {
    (
        dir.join("corrected.toml"),
        dir.join("report.json"),
        dir.join("section.svg"),
    )
}

fn nothing_written(dir: &Path) {
    let (a, b, c) = outputs(dir);
    for path in [a, b, c] {
        assert!(!path.exists(), "{} was written", path.display());
    }
}

#[test]
fn a_part_cut_with_the_wrong_tool_is_fitted_corrected_and_cut_again_within_delta() {
    let job_path = util::example("trapezoidal");
    let job = Job::load(&job_path).unwrap();
    let delta = job.cut.delta;
    let (motion, ring) = planned(&job);
    let tool = cut_by(&job, real(ring));
    let dir = tempfile::tempdir().unwrap();
    let z_mid = job.groove.z_start + job.groove.length / 2.0;
    let csv = measured_csv(&job, &tool, &motion, &spread(&job, 200), z_mid);
    let section = util::write(dir.path(), "section.csv", &csv);
    let rows = csv
        .lines()
        .filter(|l| l.starts_with(|c: char| c.is_ascii_digit() || c == '-'))
        .count();

    let (code, out, err) = measure(&job_path, &section, dir.path(), &[]);
    // The first part is beyond Δ (exit 2), and the corrected job is written all the same.
    assert_eq!(code, Some(2), "{out}\n{err}");
    let (corrected, report, svg) = outputs(dir.path());
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(r["within_delta"], false);
    let worst = r["max_overcut_mm"]
        .as_f64()
        .unwrap()
        .max(r["max_undercut_mm"].as_f64().unwrap());
    assert!(worst > delta, "{worst}");
    assert_eq!(r["points"].as_array().unwrap().len(), rows);
    assert!(std::fs::read_to_string(&svg)
        .unwrap()
        .contains("fitted tool"));

    // The injected tool, recovered within three standard errors, and those errors small
    // enough to mean something: a tenth of the injected offsets.
    let truth = [
        ("ring_radius_mm", ring.radius + RING_OFF, RING_OFF / 10.0),
        ("nose_radius_mm", ring.nose, RING_OFF / 10.0),
        (
            "installation_angle_deg",
            ring.installation.to_degrees() + ANGLE_OFF,
            ANGLE_OFF / 10.0,
        ),
    ];
    for (key, value, resolution) in truth {
        let fitted = r["fit"][key]["fitted"].as_f64().unwrap();
        let se = r["fit"][key]["standard_error"].as_f64().unwrap();
        assert!(
            (fitted - value).abs() <= 3.0 * se,
            "{key}: fitted {fitted} ± {se}, injected {value}\n{out}"
        );
        assert!(3.0 * se < resolution, "{key}: standard error {se}\n{out}");
    }
    // The residuals are the measuring machine's noise.
    let rms = r["fit"]["rms_residual_mm"].as_f64().unwrap();
    assert!(rms < 2.0 * NOISE, "{rms}");

    // The first part, over the whole groove, every start: beyond Δ. Cut again with the same
    // real tool, by the corrected job's program: within it.
    let first = tool.measure(&motion).unwrap();
    assert!(
        first.max_overcut_mm.max(first.max_undercut_mm) > delta,
        "the first part: overcut {} undercut {} mm",
        first.max_overcut_mm,
        first.max_undercut_mm
    );
    let again = Job::load(&corrected).unwrap();
    assert_eq!(again.groove.lead, job.groove.lead);
    let m = tool.measure(&planned(&again).0).unwrap();
    assert!(
        m.max_overcut_mm <= delta && m.max_undercut_mm <= delta,
        "the corrected part: overcut {} undercut {} mm\n{out}",
        m.max_overcut_mm,
        m.max_undercut_mm
    );
    // The figures docs/measure.md quotes (`--nocapture` shows them).
    let shown = |key: &str| {
        format!(
            "{key} {:.5} ± {:.5}",
            r["fit"][key]["fitted"].as_f64().unwrap(),
            r["fit"][key]["standard_error"].as_f64().unwrap()
        )
    };
    eprintln!(
        "closed loop, {rows} points: {}; {}; {}; rms residual {:.5} mm; groove uncertainty \
         {:.5} mm (3σ); first part overcut {:.5} undercut {:.5} mm over {} points; corrected \
         part overcut {:.5} undercut {:.5} mm",
        shown("ring_radius_mm"),
        shown("nose_radius_mm"),
        shown("installation_angle_deg"),
        rms,
        r["fit"]["groove_uncertainty_mm"].as_f64().unwrap(),
        first.max_overcut_mm,
        first.max_undercut_mm,
        first.points,
        m.max_overcut_mm,
        m.max_undercut_mm
    );
}

#[test]
fn a_job_corrected_into_another_folder_names_its_profile_points_from_there() {
    let job_path = util::example("double-start");
    let job = Job::load(&job_path).unwrap();
    let (motion, ring) = planned(&job);
    let tool = cut_by(&job, real(ring));
    let dir = tempfile::tempdir().unwrap();
    let csv = measured_csv(&job, &tool, &motion, &spread(&job, 80), 0.0);
    let section = util::write(dir.path(), "section.csv", &csv);
    let (code, out, err) = measure(&job_path, &section, dir.path(), &[]);
    assert_eq!(code, Some(2), "{out}\n{err}");
    let (corrected, report, _) = outputs(dir.path());
    let again = Job::load(&corrected).unwrap();
    let text = std::fs::read_to_string(&corrected).unwrap();
    assert!(
        text.starts_with("# Corrected by `whirl measure --correct`"),
        "{text}"
    );
    assert!(!text.contains("points = \"profile.csv\""), "{text}");
    assert_eq!(again.profile.radius_range(), job.profile.radius_range());
    // The job's tool is the fitted one, to the 0.1 µm and 0.0001° it is written to.
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let fitted = |key: &str| r["fit"][key]["fitted"].as_f64().unwrap();
    assert!((again.tool.ring_radius - fitted("ring_radius_mm")).abs() <= 0.5e-4);
    assert!((again.tool.nose_radius - fitted("nose_radius_mm")).abs() <= 0.5e-4);
    let angle = again.tool.installation_angle_deg.unwrap();
    assert!((angle - fitted("installation_angle_deg")).abs() <= 0.5e-4);
}

#[test]
fn a_job_without_an_angle_is_fitted_from_the_angle_it_was_planned_at() {
    // The double-start job gives no installation angle: `whirl plan` planned it at the middle
    // of its window, and its part was cut by that program with the ring set up 0.3° off it.
    // The fit starts from the angle the program was planned at, reports it as the job's, and
    // finds the angle the part was cut with.
    let job_path = util::example("double-start");
    let job = Job::load(&job_path).unwrap();
    assert_eq!(job.tool.installation_angle_deg, None);
    let (motion, ring) = planned(&job);
    let (window_angle, _) = whirl::plan::angles::ring(&job).unwrap();
    assert_eq!(ring, window_angle);
    let tool = cut_by(&job, real(ring));
    let dir = tempfile::tempdir().unwrap();
    let csv = measured_csv(&job, &tool, &motion, &spread(&job, 200), 0.0);
    let section = util::write(dir.path(), "section.csv", &csv);
    let (code, out, err) = measure(&job_path, &section, dir.path(), &[]);
    assert_eq!(code, Some(2), "{out}\n{err}");
    let (corrected, report, _) = outputs(dir.path());
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let angle = &r["fit"]["installation_angle_deg"];
    let planned_at = ring.installation.to_degrees();
    assert!(
        (angle["job"].as_f64().unwrap() - planned_at).abs() < 1e-9,
        "{angle}: planned at {planned_at}°"
    );
    let (fitted, se) = (
        angle["fitted"].as_f64().unwrap(),
        angle["standard_error"].as_f64().unwrap(),
    );
    assert!(
        (fitted - (planned_at + ANGLE_OFF)).abs() <= 3.0 * se && 3.0 * se < ANGLE_OFF / 10.0,
        "fitted {fitted} ± {se}°, cut at {}°\n{out}",
        planned_at + ANGLE_OFF
    );
    // The corrected job says what it changed from: the angle the program was planned at.
    let text = std::fs::read_to_string(&corrected).unwrap();
    let note = format!(
        "installation_angle_deg {} -> ",
        whirl::plan::angles::show_deg(planned_at)
    );
    assert!(text.contains(&note), "{text}");
}

/// A CMM file of the trapezoidal example with `header` and `rows` after it.
fn bad_input(header: &str, rows: &str, extra: &[&str]) -> (Option<i32>, String, tempfile::TempDir) {
    let dir = tempfile::tempdir().unwrap();
    let section = util::write(dir.path(), "section.csv", &format!("{header}{rows}"));
    let (code, _, err) = measure(&util::example("trapezoidal"), &section, dir.path(), extra);
    (code, err, dir)
}

const HEADER: &str =
    "# section = axial\n# angle_deg = 0\n# units = mm\n# columns = z, rho\n# origin = 0, 0\n";

/// `count` points of the trapezoidal example's root flat (its least radius) in the axial
/// section at polar angle 0, on the copy nearest z = 20 mm, as (z, ρ).
fn root(count: usize) -> Vec<(f64, f64)> {
    let job = Job::load(&util::example("trapezoidal")).unwrap();
    let (rho_min, _) = job.profile.radius_range();
    let (p, pitch, n) = (job.p(), job.p() * job.period(), 20_000);
    let flat: Vec<(f64, f64)> = (0..=n)
        .map(|k| {
            job.profile
                .point(job.profile.length() * k as f64 / n as f64)
                .pos
        })
        .filter(|pos| pos.length() < rho_min + 1e-9)
        .map(|pos| {
            let z = -p * pos.to_angle();
            (z + ((20.0 - z) / pitch).round() * pitch, pos.length())
        })
        .collect();
    (0..count)
        .map(|k| flat[(flat.len() - 1) * (2 * k + 1) / (2 * count)])
        .collect()
}

/// [`root`]'s points as CSV rows, z first.
fn root_rows(count: usize) -> String {
    root(count)
        .iter()
        .map(|(z, rho)| format!("{z:.4},{rho:.4}\n"))
        .collect()
}

#[test]
fn a_file_whose_frame_is_not_stated_is_refused_before_anything_is_written() {
    let (code, err, dir) = bad_input(
        "# angle_deg = 0\n# units = mm\n# columns = z, rho\n# origin = 0, 0\n",
        &root_rows(8),
        &[],
    );
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("section.csv: the frame is not stated: no section (axial or transverse)"),
        "{err}"
    );
    nothing_written(dir.path());
}

#[test]
fn a_frame_option_that_contradicts_the_header_is_refused_naming_the_line() {
    let (code, err, dir) = bad_input(HEADER, &root_rows(8), &["--frame", "units=in"]);
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("section.csv: --frame: units = in, but line 3 says units = mm"),
        "{err}"
    );
    nothing_written(dir.path());
}

#[test]
fn a_bad_number_is_refused_naming_its_line() {
    let rows = format!("{}20.0,16.0x\n", root_rows(5));
    let (code, err, dir) = bad_input(HEADER, &rows, &[]);
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("section.csv: line 11: \"16.0x\" is not a number"),
        "{err}"
    );
    nothing_written(dir.path());
}

#[test]
fn too_few_points_for_the_fit_are_refused_naming_their_lines() {
    let (code, err, dir) = bad_input(HEADER, &root_rows(3), &[]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("3 measured points (lines 6 to 8)"), "{err}");
    assert!(err.contains("needs at least 4"), "{err}");
    nothing_written(dir.path());
}

#[test]
fn a_point_far_from_the_groove_is_refused_naming_its_line_and_distance() {
    // Half the groove's depth (ISO 2904 Tr 40 × 7: major diameter 40 mm, minor 32 mm) above
    // the root flat: more than a tenth of the depth from any of it.
    let (z, rho) = root(1)[0];
    let rows = format!("{}{z:.4},{:.4}\n", root_rows(5), rho + 2.0);
    let (code, err, dir) = bad_input(HEADER, &rows, &[]);
    assert_eq!(code, Some(1), "{err}");
    let point = format!(
        "section.csv: line 11: the point ({:.4}, {z:.4}) lies",
        rho + 2.0
    );
    assert!(err.contains(&point), "{err}");
    assert!(
        err.contains("more than 0.4000 mm (a tenth of the groove's depth)"),
        "{err}"
    );
    nothing_written(dir.path());
}

#[test]
fn a_point_outside_the_formed_length_is_refused_naming_its_line() {
    // The root four pitches on, past the formed length's end at 40 mm.
    let (z, rho) = root(1)[0];
    let z = z + 28.0;
    let rows = format!("{}{z:.4},{rho:.4}\n", root_rows(5));
    let (code, err, dir) = bad_input(HEADER, &rows, &[]);
    assert_eq!(code, Some(1), "{err}");
    let message = format!(
        "section.csv: line 11: z = {z:.4} mm lies outside the groove's formed length, z from 0 to 40 mm"
    );
    assert!(err.contains(&message), "{err}");
    nothing_written(dir.path());
}

#[test]
fn points_on_the_root_alone_do_not_determine_the_tool_and_correct_nothing() {
    // At the root a larger ring and a larger nose move the surface alike (and the angle not
    // at all): the fit cannot tell them apart from these points.
    let (code, err, dir) = bad_input(HEADER, &root_rows(40), &[]);
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("cannot tell the tool's parameters apart")
            || err.contains("does not determine the tool well enough"),
        "{err}"
    );
    nothing_written(dir.path());
}

#[test]
fn the_corrected_job_may_not_replace_the_job_it_corrects() {
    let dir = tempfile::tempdir().unwrap();
    let section = util::write(
        dir.path(),
        "section.csv",
        &format!("{HEADER}{}", root_rows(8)),
    );
    let job = util::example("trapezoidal");
    let before = std::fs::read_to_string(&job).unwrap();
    let (code, _, err) = run(&[
        OsStr::new("measure"),
        job.as_os_str(),
        section.as_os_str(),
        OsStr::new("--correct"),
        OsStr::new("-o"),
        job.as_os_str(),
    ]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("refusing to write"), "{err}");
    assert!(err.contains("it is the job file this run reads"), "{err}");
    assert_eq!(std::fs::read_to_string(&job).unwrap(), before);
}

#[test]
fn a_section_in_inches_declared_in_millimetres_is_refused_at_its_first_point() {
    // The root's points in inches, the header saying mm: read as millimetres they lie near
    // the axis, 25.4 times nearer than the groove, and far from its section.
    let rows: String = root(8)
        .iter()
        .map(|(z, rho)| format!("{:.5},{:.5}\n", z / 25.4, rho / 25.4))
        .collect();
    let (code, err, dir) = bad_input(HEADER, &rows, &[]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("section.csv: line 6: the point ("), "{err}");
    assert!(err.contains("check the frame"), "{err}");
    nothing_written(dir.path());
}

/// The trapezoidal example's transverse section at z = 20 mm, every start, as (x, y) rows:
/// kinematics.md's transverse rule, the profile turned by z/p and each start's share of the
/// turn.
fn transverse_rows() -> String {
    let job = Job::load(&util::example("trapezoidal")).unwrap();
    let starts = job.groove.starts;
    let mut rows = String::new();
    for start in 0..starts {
        let turn = 20.0 / job.p() + std::f64::consts::TAU * f64::from(start) / f64::from(starts);
        for k in 0..40 {
            let u = job.profile.length() * (f64::from(k) + 0.5) / 40.0;
            let at = DVec2::from_angle(turn).rotate(job.profile.point(u).pos);
            rows.push_str(&format!("{:.4},{:.4}\n", at.x, at.y));
        }
    }
    rows
}

#[test]
fn a_transverse_section_declared_axial_is_refused_naming_the_line() {
    // Its column names are a transverse section's: refused on their own line.
    let header = "# section = axial\n# angle_deg = 0\n# units = mm\n# origin = 0, 0\n";
    let (code, err, dir) = bad_input(header, &format!("x,y\n{}", transverse_rows()), &[]);
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains(
            "section.csv: line 5: columns = x,y: the columns of an axial section are rho and z"
        ),
        "{err}"
    );
    nothing_written(dir.path());
    // Its columns declared as ρ and z: the points are no axial section of this groove (x
    // and y run through negative values and across the whole bore), and the first that lies
    // off it is refused with its line.
    let header = "# section = axial\n# angle_deg = 0\n# units = mm\n# columns = rho, z\n\
                  # origin = 0, 20\n";
    let (code, err, dir) = bad_input(header, &transverse_rows(), &[]);
    assert_eq!(code, Some(1), "{err}");
    let line: usize = err
        .split("section.csv: line ")
        .nth(1)
        .and_then(|rest| rest.split(':').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no line named: {err}"));
    assert!(line > 5, "{err}");
    assert!(
        err.contains("from the target section") || err.contains("outside the groove's formed"),
        "{err}"
    );
    nothing_written(dir.path());
}

#[test]
fn an_unparsable_line_is_refused_naming_it() {
    let rows = format!("{}20.0;16.0\n{}", root_rows(4), root_rows(4));
    let (code, err, dir) = bad_input(HEADER, &rows, &[]);
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("section.csv: line 10: expected two comma-separated values, found 1"),
        "{err}"
    );
    nothing_written(dir.path());
}

#[test]
fn an_output_that_is_a_device_or_the_measured_section_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let text = format!("{HEADER}{}", root_rows(8));
    let section = util::write(dir.path(), "section.csv", &text);
    let job = util::example("trapezoidal");
    for (option, path, why) in [
        ("-o", Path::new("/dev/null"), "it is a character device"),
        (
            "-o",
            section.as_path(),
            "it is the measured section this run reads",
        ),
    ] {
        let mut args: Vec<&OsStr> = vec![
            OsStr::new("measure"),
            job.as_os_str(),
            section.as_os_str(),
            OsStr::new("--correct"),
            OsStr::new(option),
            path.as_os_str(),
        ];
        let (code, _, err) = run(&args);
        assert_eq!(code, Some(1), "{err}");
        assert!(
            err.contains(&format!(
                "refusing to write {} ({option}): {why}",
                path.display()
            )),
            "{err}"
        );
        // The same as --svg and --report, without --correct.
        for other in ["--svg", "--report"] {
            args = vec![
                OsStr::new("measure"),
                job.as_os_str(),
                section.as_os_str(),
                OsStr::new(other),
                path.as_os_str(),
            ];
            let (code, _, err) = run(&args);
            assert_eq!(code, Some(1), "{err}");
            assert!(err.contains(&format!("({other}): {why}")), "{err}");
        }
    }
    assert_eq!(std::fs::read_to_string(&section).unwrap(), text);
    let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert_eq!(names.len(), 1, "{names:?}");
}

#[test]
fn correct_without_an_output_is_refused_before_anything_is_read() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("no-such-section.csv");
    let (code, _, err) = run(&[
        OsStr::new("measure"),
        util::example("trapezoidal").as_os_str(),
        missing.as_os_str(),
        OsStr::new("--correct"),
    ]);
    // A usage error (clap's exit code), naming the option that is missing.
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("--output <OUTPUT>"), "{err}");
    assert!(!err.contains("no-such-section"), "{err}");
}
