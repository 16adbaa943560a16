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
