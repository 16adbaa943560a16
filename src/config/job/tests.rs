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
            "designation = \"Tr 40x7-7H\"",
            "names an internal thread (a nut",
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
            "designation = \"Tr 40x7\"\npoints = \"p.csv\"",
            "points does not go with designation",
        ),
        (
            "designation = \"Tr 40x7\"\nroot_radius = 3.0",
            "root radius 3 mm is too large",
        ),
    ];
    for (lines, said) in cases {
        let e = profile(lines).unwrap_err().to_string();
        assert!(e.contains(said), "{lines}: {e}");
    }
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
