//! Profiles from CAD drawings written by ezdxf, an independent DXF writer
//! (`tests/clients/dxf_drawings.py`), in R12 and R2018 forms and every entity kind.
//!
//! Each good drawing must plan to the same program as the same geometry given otherwise: the
//! eccentric circle as 3600 points at 10 decimals, the closed outline of a whole Tr 40×14 form
//! as whirl's ISO 2904 standard. "The same" is stated as: the two profiles within 0.1 µm of
//! each other (radially, at the same polar angle), and the two programs of the same length,
//! planned at the same installation angle, every position within one unit of the last decimal
//! written (a number that moved by less than 0.1 µm can round either way, no further).
//! Every malformed drawing must be refused naming its entities by handle.

use crate::util;
use std::path::Path;
use whirl::config::job::Job;
use whirl::config::machine::MachineProfile;
use whirl::geometry::profile::Profile;
use whirl::program::Move;

/// The eccentric lobe's job: one start, transverse section, profile given by `profile`
/// (the `[groove.profile]` lines).
fn eccentric_job(profile: &str) -> String {
    format!(
        "[groove]\nlead = 40.0\nstarts = 1\nhand = \"right\"\nz_start = 0.0\nlength = 10.0\n\n\
         [groove.profile]\nsection = \"transverse\"\n{profile}\n\n\
         [tool]\nwhirling = \"internal\"\nring_radius = 60.0\nnose_radius = 1.2\ninserts = 4\n\n\
         [cut]\ndelta = 0.005\naxial_feed = 0.1\nworkpiece_rpm = 10.0\nring_rpm = 1500.0\n"
    )
}

/// The trapezoidal example's job with its `[groove.profile]` replaced by `profile`.
fn trapezoid_job(profile: &str) -> String {
    example_job("trapezoidal", profile)
}

/// The job of `example` with its `[groove.profile]` replaced by `profile`.
fn example_job(example: &str, profile: &str) -> String {
    let text = std::fs::read_to_string(util::example(example)).unwrap();
    let start = text.find("[groove.profile]").unwrap();
    let end = text.find("[tool]").unwrap();
    format!(
        "{}[groove.profile]\n{profile}\n\n{}",
        &text[..start],
        &text[end..]
    )
}

fn load(dir: &Path, name: &str, text: &str) -> Result<Job, String> {
    let path = util::write(dir, name, text);
    Job::load(&path).map_err(|e| e.to_string())
}

/// The largest radial distance between two profiles of the same period at the same polar
/// angle (the profiles' polar angle increases along them, so the point of `b` at an angle is
/// found by bisection).
fn radial_gap(a: &Profile, b: &Profile) -> f64 {
    let period = a.period();
    let b0 = b.point(0.0).pos.to_angle();
    let along_b = |u: f64| {
        let q = b.point(u).pos.to_angle() - b0;
        // Unwrapped within the period: the end of b is its start turned by one period.
        if u > b.length() / 2.0 && q.rem_euclid(std::f64::consts::TAU) < period / 4.0 {
            q.rem_euclid(std::f64::consts::TAU) + period
        } else {
            q.rem_euclid(std::f64::consts::TAU)
        }
    };
    let mut worst: f64 = 0.0;
    for k in 0..=4000 {
        let p = a.point(a.length() * k as f64 / 4000.0).pos;
        let target = (p.to_angle() - b0).rem_euclid(period);
        let (mut lo, mut hi) = (0.0, b.length());
        for _ in 0..80 {
            let mid = (lo + hi) / 2.0;
            if along_b(mid) < target {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let q = b.point((lo + hi) / 2.0).pos;
        worst = worst.max((p.length() - q.length()).abs());
    }
    worst
}

/// The linked moves of a plan: (x, z, c).
fn linked(plan: &whirl::plan::Plan) -> Vec<(f64, f64, f64)> {
    plan.program
        .moves
        .iter()
        .filter_map(|m| match *m {
            Move::Linked { x, z, c, .. } => Some((x, z, c)),
            _ => None,
        })
        .collect()
}

/// The drawing's job and the reference job plan to the same program.
fn same_program(drawn: &Job, reference: &Job, machine: &MachineProfile, what: &str) {
    let gap = radial_gap(&drawn.profile, &reference.profile)
        .max(radial_gap(&reference.profile, &drawn.profile));
    assert!(gap < 1e-4, "{what}: the profiles are {gap} mm apart");
    let a = whirl::plan::plan(drawn, machine).unwrap();
    let b = whirl::plan::plan(reference, machine).unwrap();
    assert_eq!(a.report.segments, b.report.segments, "{what}: segments");
    assert!(
        (a.ring.installation - b.ring.installation).abs() < 1e-9,
        "{what}: installation angle {} vs {}",
        a.ring.installation,
        b.ring.installation
    );
    assert_eq!(a.report.decimals, b.report.decimals, "{what}: decimals");
    let unit = |d: u32| 10f64.powi(-(d as i32)) * (1.0 + 1e-9);
    let (mm, deg) = (unit(a.report.decimals[0]), unit(a.report.decimals[1]));
    let (la, lb) = (linked(&a), linked(&b));
    assert_eq!(la.len(), lb.len(), "{what}: linked moves");
    for (i, (p, q)) in la.iter().zip(&lb).enumerate() {
        assert!(
            (p.0 - q.0).abs() <= mm && (p.1 - q.1).abs() <= mm && (p.2 - q.2).abs() <= deg,
            "{what}: linked move {i}: {p:?} vs {q:?}"
        );
    }
}

/// Run the ezdxf writer into a temp dir; `None` (skipped) when ezdxf is missing outside CI.
fn drawings() -> Option<(tempfile::TempDir, serde_json::Value)> {
    if !util::python_with("ezdxf", "ezdxf") {
        return None;
    }
    let dir = tempfile::tempdir().unwrap();
    let out = std::process::Command::new("python3")
        .arg(util::root().join("tests/clients/dxf_drawings.py"))
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let manifest = serde_json::from_slice(&out.stdout).unwrap();
    Some((dir, manifest))
}

#[test]
fn ezdxf_drawings_of_every_entity_kind_plan_as_the_same_geometry() {
    let Some((dir, manifest)) = drawings() else {
        return;
    };
    let dir = dir.path();
    let machine = MachineProfile::load(&util::root().join("machine-profiles/sim.toml")).unwrap();
    let points = load(
        dir,
        "points.toml",
        &eccentric_job("points = \"eccentric.csv\""),
    )
    .unwrap();
    let standard = load(
        dir,
        "standard.toml",
        &trapezoid_job("standard = \"trapezoidal\"\nmajor_diameter = 40.0\nroot_radius = 0.5"),
    )
    .unwrap();
    let good = manifest["good"].as_array().unwrap();
    let mut kinds = std::collections::BTreeSet::new();
    for case in good {
        let file = case["file"].as_str().unwrap();
        // R12 has no $INSUNITS: the job says the units.
        let units = if case["version"] == "R12" {
            "\nunits = \"mm\""
        } else {
            ""
        };
        let spec = format!("dxf = \"{file}\"\nlayer = \"GROOVE\"{units}");
        let (job, reference) = if case["groove"] == "eccentric" {
            (eccentric_job(&spec), &points)
        } else {
            (
                trapezoid_job(&format!("section = \"axial\"\n{spec}")),
                &standard,
            )
        };
        let drawn = load(dir, "drawn.toml", &job).unwrap_or_else(|e| panic!("{file}: {e}"));
        same_program(&drawn, reference, &machine, file);
        kinds.insert(case["kind"].as_str().unwrap().to_owned());
    }
    let all = ["ARC", "CIRCLE", "LINE", "LWPOLYLINE", "POLYLINE", "SPLINE"];
    assert_eq!(kinds.into_iter().collect::<Vec<_>>(), all);
}

#[test]
fn an_ezdxf_drawing_of_a_nut_plans_as_its_standard_form() {
    // The closed half-section of the Tr 40x7 nut, three pitches along the bore out to the
    // nut's outer radius: its groove is the part above the bore, and it is the same groove
    // as the example's, which names the form by the standard.
    let Some((dir, manifest)) = drawings() else {
        return;
    };
    let dir = dir.path();
    let machine = MachineProfile::load(&util::root().join("machine-profiles/sim.toml")).unwrap();
    let reference = Job::load(&util::example("trapezoidal-nut")).unwrap();
    let nuts = manifest["nut"].as_array().unwrap();
    assert_eq!(nuts.len(), 2);
    for case in nuts {
        let file = case["file"].as_str().unwrap();
        let spec = format!("section = \"axial\"\ndxf = \"{file}\"\nlayer = \"GROOVE\"");
        let drawn = load(dir, "nut.toml", &example_job("trapezoidal-nut", &spec))
            .unwrap_or_else(|e| panic!("{file}: {e}"));
        same_program(&drawn, &reference, &machine, file);
    }
}

#[test]
fn malformed_ezdxf_drawings_are_refused_naming_the_entities() {
    let Some((dir, manifest)) = drawings() else {
        return;
    };
    let dir = dir.path();
    for case in manifest["bad"].as_array().unwrap() {
        let file = case["file"].as_str().unwrap();
        let job = eccentric_job(&format!("dxf = \"{file}\"\nlayer = \"GROOVE\""))
            .replace("starts = 1", "starts = 2");
        let err = load(dir, "bad.toml", &job).expect_err(file);
        let expect = case["expect"].as_str().unwrap();
        assert!(err.contains(expect), "{file}: {err} (expected {expect})");
        assert!(err.contains(file), "{file}: the file is named: {err}");
        for handle in case["handles"].as_array().unwrap() {
            let handle = format!("#{}", handle.as_str().unwrap());
            assert!(err.contains(&handle), "{file}: {err} names {handle}");
        }
    }
}
