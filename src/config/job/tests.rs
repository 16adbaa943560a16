//! The job file's check of Δ against the groove it is for.

use super::*;

/// The trapezoidal example (Tr 40×14, radii 16 to 20 mm) with `delta` as Δ.
fn trapezoidal(delta: &str) -> Result<Job, JobError> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/trapezoidal/job.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let text = text.replace("delta = 0.01", &format!("delta = {delta}"));
    Job::from_toml(&text, &path)
}

#[test]
fn a_delta_beyond_the_groove_depth_is_refused_naming_it() {
    for delta in ["1e308", "4.5"] {
        let e = trapezoidal(delta).unwrap_err();
        let JobError::Invalid { key, value, .. } = &e else {
            panic!("Δ = {delta}: expected cut.delta refused, got {e}");
        };
        assert_eq!((*key, value.as_str()), ("cut.delta", delta));
        let text = e.to_string();
        assert!(
            text.contains("depth, 4.0000 mm") && text.contains("16.0000 to 20.0000"),
            "{text}"
        );
        assert!(text.len() < 300, "no number spelt out in full: {text}");
    }
    // Within the depth it is the planner's to judge.
    assert_eq!(trapezoidal("3.9").unwrap().cut.delta, 3.9);
}

/// The nut example (Tr 40x7 internal, bore D1 = 33 mm) with `edit` applied to its text.
fn nut(edit: impl Fn(String) -> String) -> Result<Job, JobError> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/trapezoidal-nut/job.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    Job::from_toml(&edit(text), &path)
}

#[test]
fn a_nut_has_its_material_outside_between_the_bore_and_d4() {
    // ISO 2904 Tr 40x7: D1 = d − P = 33, D4 = d + 2·a_c = 41 (a_c = 0.5 for P 6 to 12).
    let job = nut(|t| t).unwrap();
    assert_eq!(job.profile.material(), Material::Outside);
    let (lo, hi) = job.profile.radius_range();
    assert!(
        (lo - 16.5).abs() < 1e-9 && (hi - 20.5).abs() < 1e-9,
        "{lo} {hi}"
    );
    // The normal points from the wall into the groove: towards the axis on the root flat.
    let root = (0..400)
        .map(|k| {
            job.profile
                .point(job.profile.length() * f64::from(k) / 400.0)
        })
        .max_by(|a, b| a.pos.length().total_cmp(&b.pos.length()))
        .unwrap();
    let n = job.profile.normal(&root, job.p());
    assert!(n.truncate().dot(root.pos.normalize()) < -0.99, "{n}");
}

#[test]
fn a_head_that_does_not_fit_the_bore_is_refused_naming_the_sizes() {
    // R + r = 16.1 + 0.4 = 16.5 mm reaches the 16.5 mm bore radius.
    let e = nut(|t| t.replace("ring_radius = 12.0", "ring_radius = 16.1")).unwrap_err();
    let JobError::Invalid { key, value, why } = &e else {
        panic!("{e}")
    };
    assert_eq!((*key, value.as_str()), ("tool.ring_radius", "16.1"));
    assert!(
        why.contains("16.5 mm") && why.contains("16.5000 mm"),
        "{why}"
    );
    assert!(why.contains("bore diameter 33.0000 mm"), "{why}");
    // Just inside the bore it is the planner's to judge.
    nut(|t| t.replace("ring_radius = 12.0", "ring_radius = 16.0")).unwrap();
}

#[test]
fn a_screw_tool_on_a_nut_and_a_bore_head_on_a_screw_are_refused_naming_both_keys() {
    for whirling in ["internal", "external"] {
        let e = nut(|t| t.replace("\"bore\"", &format!("\"{whirling}\""))).unwrap_err();
        let text = e.to_string();
        assert!(
            text.contains("tool.whirling") && text.contains("internal = true"),
            "{text}"
        );
    }
    let e = nut(|t| t.replace("internal = true", "internal = false")).unwrap_err();
    let text = e.to_string();
    assert!(
        text.contains("tool.whirling = \"bore\"") && text.contains("internal = true"),
        "{text}"
    );
}

#[test]
fn a_nut_of_a_standard_without_a_nut_form_is_refused() {
    let e = nut(|t| t.replace("standard = \"trapezoidal\"", "standard = \"acme\"")).unwrap_err();
    assert!(e.to_string().contains("no nut form"), "{e}");
}
