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

/// The trapezoidal example's text with its `[groove]` and `[groove.profile]` replaced by
/// `groove` (the rest: tool and cut, as there).
fn with_groove(groove: &str) -> Result<Job, JobError> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/trapezoidal/job.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let tool = text.find("[tool]").unwrap();
    Job::from_toml(&format!("{groove}\n{}", &text[tool..]), &path)
}

const GROOVE: &str = "[groove]\nz_start = 0.0\nlength = 40.0\n";

#[test]
fn a_designation_gives_the_form_lead_starts_and_hand_of_the_standard_example() {
    // The example names Tr 40x14 (P7) by its dimensions; the designation names the same thread.
    let example = trapezoidal("0.01").unwrap();
    let designated = with_groove(&format!(
        "{GROOVE}[groove.profile]\ndesignation = \"Tr 40x14 P7\"\nroot_radius = 0.5\n"
    ))
    .unwrap();
    assert_eq!(designated.groove.lead, 14.0);
    assert_eq!(designated.groove.starts, 2);
    assert_eq!(designated.groove.hand, Hand::Right);
    assert_eq!(
        format!("{:?}", designated.profile),
        format!("{:?}", example.profile)
    );
    // LH sets the hand; a job may repeat what the designation says.
    let left = with_groove(
        "[groove]\nlead = 14.0\nstarts = 2\nhand = \"left\"\nz_start = 0.0\nlength = 40.0\n\
         [groove.profile]\ndesignation = \"Tr 40x14 P7 LH\"\n",
    )
    .unwrap();
    assert_eq!(left.groove.hand, Hand::Left);
}

#[test]
fn a_job_that_disagrees_with_its_designation_is_refused_naming_both_values() {
    let cases = [
        (
            "lead = 7.0",
            "groove.lead = 7 disagrees with designation = \"Tr 40x14 P7\", which gives 14",
        ),
        (
            "starts = 1",
            "groove.starts = 1 disagrees with designation = \"Tr 40x14 P7\", which gives 2",
        ),
        (
            "hand = \"left\"",
            "groove.hand = left disagrees with designation = \"Tr 40x14 P7\", which gives right",
        ),
    ];
    for (line, said) in cases {
        let e = with_groove(&format!(
            "{GROOVE}{line}\n[groove.profile]\ndesignation = \"Tr 40x14 P7\"\n"
        ))
        .unwrap_err();
        assert!(
            matches!(e, JobError::DisagreesWithDesignation { .. }),
            "{e}"
        );
        assert_eq!(e.to_string(), said);
    }
}

#[test]
fn every_designation_refusal_of_a_job_names_what() {
    let profile = |lines: &str| with_groove(&format!("{GROOVE}[groove.profile]\n{lines}\n"));
    let cases = [
        (
            "designation = \"Tr 40x5\"",
            "[groove.profile] designation = `Tr 40x5`: ISO 2902 has no pitch 5 mm",
        ),
        (
            "designation = \"Q 40x7\"",
            "`Q 40x7` is not a designation whirl reads",
        ),
        (
            // A nut's class (7H) makes the groove internal: the example's ring cannot cut it.
            "designation = \"Tr 40x7-7H\"",
            "is a nut's groove, cut from inside its bore",
        ),
        (
            "designation = \"Tr 40x7\"\nmajor_diameter = 40.0",
            "major_diameter does not go with designation",
        ),
        (
            "designation = \"Tr 40x7\"\nstandard = \"trapezoidal\"",
            "standard does not go with designation",
        ),
        (
            "designation = \"Tr 40x7\"\nmodule = 2.0",
            "module does not go with designation",
        ),
        (
            "designation = \"Tr 40x7\"\npoints = \"p.csv\"",
            "points does not go with designation",
        ),
        (
            "designation = \"Tr 40x7\"\nroot_radius = 3.0",
            "root radius 3 mm is too large",
        ),
        (
            "designation = \"Tr 40x7\"\nload_flank = \"-z\"",
            "load_flank belongs to a buttress thread",
        ),
        (
            "designation = \"S 48x8\"\nload_flank = \"left\"",
            "unknown variant `left`, expected `+z` or `-z`",
        ),
    ];
    for (lines, said) in cases {
        let e = profile(lines).unwrap_err().to_string();
        assert!(e.contains(said), "{lines}: {e}");
    }
    // A standard form given by its dimensions has no load flank to place.
    let e = with_groove(&format!(
        "{GROOVE}lead = 7.0\nstarts = 1\nhand = \"right\"\n[groove.profile]\n\
         standard = \"trapezoidal\"\nmajor_diameter = 40.0\nload_flank = \"-z\"\n"
    ))
    .unwrap_err()
    .to_string();
    assert!(e.contains("load_flank"), "{e}");
    // Without a designation, lead, starts and hand are the job's to give.
    let e = with_groove(&format!(
        "{GROOVE}starts = 1\nhand = \"right\"\n[groove.profile]\nstandard = \"trapezoidal\"\n\
         major_diameter = 40.0\n"
    ))
    .unwrap_err();
    assert!(
        matches!(
            e,
            JobError::Missing {
                key: "groove.lead",
                ..
            }
        ),
        "{e}"
    );
    let e = with_groove(&format!(
        "{GROOVE}lead = 7.0\nhand = \"right\"\n[groove.profile]\nstandard = \"trapezoidal\"\n\
         major_diameter = 40.0\n"
    ))
    .unwrap_err();
    assert!(
        matches!(
            e,
            JobError::Missing {
                key: "groove.starts",
                ..
            }
        ),
        "{e}"
    );
    let e = with_groove(&format!(
        "{GROOVE}lead = 7.0\nstarts = 1\n[groove.profile]\nstandard = \"trapezoidal\"\n\
         major_diameter = 40.0\n"
    ))
    .unwrap_err();
    assert!(
        matches!(
            e,
            JobError::Missing {
                key: "groove.hand",
                ..
            }
        ),
        "{e}"
    );
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
fn a_nut_of_a_form_without_a_nut_is_refused() {
    // A ball screw's raceway is a screw's groove: its nut is another part, not its mirror.
    let e = nut(|t| {
        t.replace(
            "standard = \"trapezoidal\"\nmajor_diameter = 40.0\nroot_radius = 0.5",
            "standard = \"ball-arc\"\nball_diameter = 3.5\ngroove_radius = 1.85\n\
             pitch_diameter = 40.0\nouter_diameter = 39.5",
        )
    })
    .unwrap_err();
    assert!(e.to_string().contains("no internal (nut) form"), "{e}");
}

#[test]
fn a_capital_class_designation_makes_the_groove_a_nut_and_a_job_saying_otherwise_is_refused() {
    // ISO 2903: the internal thread's tolerance class is written in capitals (7H).
    let designated = |internal: &str| {
        nut(|t| {
            t.replace(
                "standard = \"trapezoidal\"\nmajor_diameter = 40.0",
                "designation = \"Tr 40x7-7H\"",
            )
            .replace("internal = true", internal)
        })
    };
    let job = designated("").unwrap();
    assert_eq!(job.groove.material(), Material::Outside);
    // The nut's bore is D1 = d − P = 33 mm (ISO 2904), its groove reaching D4 = 41 mm.
    let (rho_min, rho_max) = job.profile.radius_range();
    assert!((rho_min - 16.5).abs() < 1e-9 && (rho_max - 20.5).abs() < 1e-9);
    let e = designated("internal = false").unwrap_err();
    assert!(e.to_string().contains("groove.internal"), "{e}");
}

#[test]
fn a_buttress_designation_puts_its_load_flank_where_the_job_says() {
    // S 48x8 (DIN 513): crest at 24 mm, d3 = d − 1.73554·P = 34.11568 mm. Where the 3° flank
    // lies decides which side of the groove the nearly radial wall is on: the point of the
    // groove's floor is nearer the load flank (the flanks are P − e = 5.889 mm apart at the
    // crest; the 3° one leans 0.364 mm over the 6.94 mm depth, the 30° one 4.01 mm).
    let deepest_z = |side: &str| {
        let job = with_groove(&format!(
            "{GROOVE}[groove.profile]\ndesignation = \"S 48x8\"\n{side}"
        ))
        .unwrap();
        let (rho_min, rho_max) = job.profile.radius_range();
        assert!((rho_max - 24.0).abs() < 1e-9 && (2.0 * rho_min - 34.11568).abs() < 2e-4);
        let form = designation::parse("S 48x8").unwrap().form;
        let StandardProfile::Buttress(b) = form else {
            panic!("{form:?}")
        };
        let b = match side {
            "" => b,
            _ => b.with_load_flank(LoadFlank::MinusZ),
        };
        let pieces = b.pieces(8.0).unwrap();
        pieces
            .iter()
            .flat_map(|p| (0..=200).map(move |k| p.eval(p.length() * k as f64 / 200.0).0))
            .min_by(|a, b| a.x.total_cmp(&b.x))
            .unwrap()
            .y
    };
    let (plus, minus) = (deepest_z(""), deepest_z("load_flank = \"-z\""));
    assert!(plus > 1.0, "the floor lies towards +z: {plus}");
    assert!((plus + minus).abs() < 1e-9, "mirrored: {plus} {minus}");
}
