//! The ball-screw and worm keys of `[groove.profile]`: what each form needs, what it refuses.

use super::*;

/// The example `name`'s job text with `from` replaced by `to`, read.
fn example(name: &str, from: &str, to: &str) -> Result<Job, JobError> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("examples/{name}/job.toml"));
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.contains(from), "{name} has no `{from}`");
    Job::from_toml(&text.replacen(from, to, 1), &path)
}

fn refusal(e: JobError) -> String {
    e.to_string()
}

#[test]
fn a_gothic_arch_job_builds_its_raceway_from_the_ball() {
    let job = example("ball-screw-gothic", "", "").unwrap();
    // The relief's bottom is the deepest point, above the ball's lowest point
    // d_0/2 − D_w/2 = 12.825 mm less the flank centres' offset; the crest is d/2.
    let (lo, hi) = job.profile.radius_range();
    assert!((hi - 15.75).abs() < 1e-9);
    assert!(lo < 16.0 - 3.175 && lo > 12.5, "{lo}");
}

#[test]
fn a_ball_screw_without_its_raceway_or_dimensions_is_refused_naming_the_key() {
    let e = refusal(example("ball-screw-gothic", "raceway = \"gothic-arch\"\n", "").unwrap_err());
    assert!(e.contains("needs raceway"), "{e}");
    let e = refusal(example("ball-screw-gothic", "conformity = 0.55\n", "").unwrap_err());
    assert!(e.contains("needs conformity"), "{e}");
    let e = refusal(
        example(
            "ball-screw-gothic",
            "raceway = \"gothic-arch\"",
            "raceway = \"circular-arc\"",
        )
        .unwrap_err(),
    );
    assert!(e.contains("belongs to the gothic arch"), "{e}");
    let e = refusal(
        example(
            "ball-screw-gothic",
            "conformity = 0.55",
            "groove_radius = 3.5",
        )
        .unwrap_err(),
    );
    assert!(e.contains("groove_radius is not a dimension"), "{e}");
    let e = refusal(
        example(
            "ball-screw-gothic",
            "relief_radius = 2.0",
            "relief_radius = 3.2",
        )
        .unwrap_err(),
    );
    assert!(
        e.contains("relief radius 3.2 mm reaches the contact points"),
        "{e}"
    );
}

#[test]
fn a_worm_job_takes_its_starts_from_the_groove_and_refuses_a_lead_not_pi_m_z1() {
    let job = example("worm-zi", "", "").unwrap();
    let (lo, hi) = job.profile.radius_range();
    // Root and tip diameters 15.2 and 24 mm (DIN 3975-1: d1 − 2.4m, d1 + 2m).
    assert!(
        (lo - 7.6).abs() < 1e-6 && (hi - 12.0).abs() < 1e-9,
        "{lo} {hi}"
    );
    let e = refusal(example("worm-zi", "lead = 6.283185307179586", "lead = 6.0").unwrap_err());
    assert!(e.contains("is not the module's"), "{e}");
    // Two starts need twice the lead.
    let e = refusal(example("worm-zi", "starts = 1", "starts = 2").unwrap_err());
    assert!(e.contains("is not the module's"), "{e}");
    let e = refusal(example("worm-zi", "flank = \"ZI\"\n", "").unwrap_err());
    assert!(e.contains("needs flank"), "{e}");
    let e = refusal(example("worm-zi", "module = 2.0\n", "").unwrap_err());
    assert!(e.contains("needs module"), "{e}");
    // ZK's flank is its wheel's envelope: the wheel's diameter is needed, and only there.
    let e = refusal(example("worm-zi", "flank = \"ZI\"", "flank = \"ZK\"").unwrap_err());
    assert!(e.contains("needs wheel_diameter"), "{e}");
    let zk = example(
        "worm-zi",
        "flank = \"ZI\"",
        "flank = \"ZK\"\nwheel_diameter = 250.0",
    )
    .unwrap();
    let (lo, hi) = zk.profile.radius_range();
    assert!(
        (lo - 7.6).abs() < 1e-6 && (hi - 12.0).abs() < 1e-9,
        "{lo} {hi}"
    );
    let e = refusal(
        example(
            "worm-zi",
            "flank = \"ZI\"",
            "flank = \"ZI\"\nwheel_diameter = 250.0",
        )
        .unwrap_err(),
    );
    assert!(e.contains("wheel_diameter belongs to a ZK worm"), "{e}");
}

#[test]
fn the_new_keys_are_refused_where_they_do_not_belong() {
    let e = refusal(example("trapezoidal", "root_radius = 0.5", "module = 2.0").unwrap_err());
    assert!(e.contains("module is not a dimension"), "{e}");
    let e = refusal(
        example(
            "ball-screw",
            "groove_radius = 3.429",
            "groove_radius = 3.429\nconformity = 0.54",
        )
        .unwrap_err(),
    );
    assert!(e.contains("conformity is not a dimension"), "{e}");
    let e = refusal(
        example(
            "worm-zi",
            "diameter_quotient = 10.0",
            "diameter_quotient = 10.0\nball_diameter = 3.0",
        )
        .unwrap_err(),
    );
    assert!(e.contains("ball_diameter is not a dimension"), "{e}");
    let e = refusal(
        example(
            "double-start",
            "[groove.profile]",
            "[groove.profile]\nraceway = \"gothic-arch\"",
        )
        .unwrap_err(),
    );
    assert!(e.contains("raceway belongs to a standard profile"), "{e}");
}
