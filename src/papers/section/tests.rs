//! Tests of the observer-plane section, kept apart from it for length: seed 000's ends and
//! Eqs. 10 and 12, the torus against brute force, accuracies, refusals and the paraboloid run.

use super::seed000::{Case, TABLE_1};
use super::*;
use crate::papers::tool::{BallEnd, Torus};
use proptest::prelude::*;

fn table_1_tool() -> Paraboloid {
    Paraboloid {
        a: TABLE_1.a,
        b: TABLE_1.b,
    }
}

/// The polyline's y at x (x within its span).
fn interpolate(points: &[DVec2], x: f64) -> f64 {
    let i = points
        .partition_point(|p| p.x <= x)
        .clamp(1, points.len() - 1);
    let (p, q) = (points[i - 1], points[i]);
    p.y + (q.y - p.y) * (x - p.x) / (q.x - p.x)
}

/// The largest vertical gap between the polyline and `truth`: at its vertices, at seven
/// points inside every segment and on a uniform grid of `n` x.
fn worst_gap(points: &[DVec2], truth: impl Fn(f64) -> f64, n: usize) -> f64 {
    let mut worst: f64 = 0.0;
    for w in points.windows(2) {
        for k in 0..8 {
            let x = w[0].x + (w[1].x - w[0].x) * k as f64 / 8.0;
            let y = w[0].y + (w[1].y - w[0].y) * k as f64 / 8.0;
            worst = worst.max((y - truth(x)).abs());
        }
    }
    let (x0, x1) = (points[0].x, points[points.len() - 1].x);
    for k in 0..=n {
        let x = x0 + (x1 - x0) * k as f64 / n as f64;
        worst = worst.max((interpolate(points, x) - truth(x)).abs());
    }
    worst
}

#[test]
fn the_closed_form_switches_from_eq_12_to_eq_10_and_back_where_the_two_touch() {
    let c = TABLE_1;
    let (far, near) = c.switches();
    // Eq. 12 governs next to both ends of the groove, not only one: at x = −32 Eq. 10 is
    // positive while the section must close on the axis.
    assert!(-32.0 < far && far < -c.r && -c.r < near && near < -8.0);
    assert!(c.eq10(-32.0) > 0.05, "Eq. 10 alone misses the end at −32");
    assert!(c.eq12(-32.0).abs() < 1e-7 && c.eq12(-8.0).abs() < 1e-7);
    for x in [far, near] {
        assert!((c.eq10(x) - c.eq12(x)).abs() < 1e-9, "they meet at {x}");
    }
    // Everywhere else the rim's path is below Eq. 10's unconstrained maximum.
    for k in 1..1000 {
        let x = -32.0 + 24.0 * k as f64 / 1000.0;
        assert!(c.eq12(x) <= c.eq10(x) + 1e-12, "{x}");
    }
}

#[test]
fn slopes_match_the_change_of_the_top_on_both_pieces() {
    let helix = Helix::one_turn(20.0, 20.0);
    let tool = table_1_tool();
    // Eq. 12 (edge) next to both ends, Eq. 10 (interior) between, at p > 0 and p = 0.
    for (h, x) in [
        (helix, -31.99),
        (helix, -25.0),
        (helix, -12.0),
        (helix, -8.1),
        (Helix::one_turn(20.0, 0.0), -30.0),
    ] {
        let top = top_at(&tool, &h, x).unwrap();
        let s = slope_at(&tool, &h, x, &top).unwrap();
        let d = 1e-6;
        let fd =
            (top_at(&tool, &h, x + d).unwrap().y - top_at(&tool, &h, x - d).unwrap().y) / (2.0 * d);
        assert!(
            (s - fd).abs() < 1e-5 * (1.0 + fd.abs()),
            "at {x}: {s} vs {fd}"
        );
    }
}

#[test]
fn seed_000_ends_are_exactly_minus_32_and_minus_8() {
    let (from, to) = section_ends(&table_1_tool(), &Helix::one_turn(20.0, 20.0)).unwrap();
    // a (x + R)² = −b.
    assert!((from + 32.0).abs() < 1e-12 && (to + 8.0).abs() < 1e-12);
    let ends = |x: f64| TABLE_1.a * (x + TABLE_1.r).powi(2) + TABLE_1.b;
    assert!(ends(from).abs() < 1e-12 && ends(to).abs() < 1e-12);
}

#[test]
fn seed_000_section_matches_eqs_10_and_12_within_a_tenth_of_a_micron() {
    let c = TABLE_1;
    let helix = Helix::one_turn(c.r, c.p);
    let pts = upper_boundary(&table_1_tool(), &helix, (-40.0, 0.0), 1e-4).unwrap();
    assert!(pts.windows(2).all(|w| w[0].x < w[1].x), "ordered by x");
    let (first, last) = (pts[0], pts[pts.len() - 1]);
    assert!((first.x + 32.0).abs() < 1e-9 && first.y.abs() < 1e-9);
    assert!((last.x + 8.0).abs() < 1e-9 && last.y.abs() < 1e-9);
    // The vertices are on the curve (to Eq. 12's own rounding near the ends: acos near −1).
    for p in &pts {
        assert!((p.y - c.section(p.x)).abs() < 1e-7, "vertex {p}");
    }
    let gap = worst_gap(&pts, |x| c.section(x), 200_000);
    assert!(gap <= 1e-4, "worst gap {gap}");
    // Both of the paper's pieces are there: the rim sets the top next to both ends, an
    // interior instant in between.
    let (far, near) = c.switches();
    for (x, kind) in [
        ((far - 32.0) / 2.0, Attained::ReachEdge),
        (-20.0, Attained::Interior),
        ((near - 8.0) / 2.0, Attained::ReachEdge),
    ] {
        let top = top_at(&table_1_tool(), &helix, x).unwrap();
        assert_eq!(top.attained, kind, "at {x}");
        assert!((top.y - c.section(x)).abs() < 1e-9);
    }
    // Eq. 9's φ is the maximiser on the Eq. 10 part.
    let top = top_at(&table_1_tool(), &helix, -25.0).unwrap();
    assert!((top.phi - c.phi_star(-25.0)).abs() < 1e-6);
}

#[test]
fn with_no_pitch_it_is_the_circular_path_case() {
    let c = Case { p: 0.0, ..TABLE_1 };
    let helix = Helix::one_turn(c.r, 0.0);
    let pts = upper_boundary(&table_1_tool(), &helix, (-32.0, -8.0), 1e-4).unwrap();
    // Eq. 10 with p = 0: y = a (x + R)² + b, the tool's own section at φ = π.
    let truth = |x: f64| c.a * (x + c.r).powi(2) + c.b;
    for x in [-31.0, -25.0, -20.0, -12.5, -8.5] {
        assert!((c.eq10(x) - truth(x)).abs() < 1e-12);
    }
    assert!((pts[0].x + 32.0).abs() < 1e-9 && (pts[pts.len() - 1].x + 8.0).abs() < 1e-9);
    let gap = worst_gap(&pts, truth, 100_000);
    assert!(gap <= 1e-4, "worst gap {gap}");
}

#[test]
fn finer_accuracies_are_honoured_too() {
    let c = TABLE_1;
    let helix = Helix::one_turn(c.r, c.p);
    for acc in [1e-2, 1e-6] {
        let pts = upper_boundary(&table_1_tool(), &helix, (-32.0, -8.0), acc).unwrap();
        let gap = worst_gap(&pts, |x| c.section(x), 50_000);
        // Eq. 12 as printed carries ~5e-8 of its own rounding next to the ends.
        assert!(gap <= acc + 1e-7, "accuracy {acc}: gap {gap}");
    }
}

#[test]
fn a_range_inside_the_groove_keeps_its_own_ends() {
    let helix = Helix::one_turn(20.0, 20.0);
    let pts = upper_boundary(&table_1_tool(), &helix, (-25.0, -15.0), 1e-4).unwrap();
    assert_eq!(pts[0].x, -25.0);
    assert_eq!(pts[pts.len() - 1].x, -15.0);
}

/// The largest chord top on a fine grid of φ: a brute-force lower bound on Y.
fn brute(tool: &dyn Revolved, helix: &Helix, x: f64) -> Option<f64> {
    let n = 40_000;
    (0..=n)
        .filter_map(|i| {
            let phi = helix.phi_start + (helix.phi_end - helix.phi_start) * i as f64 / n as f64;
            chord_top(tool, helix, x, phi)
        })
        .reduce(f64::max)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Nothing on a fine grid of φ beats `top_at`, and it is attained by a real instant.
    #[test]
    fn top_at_is_the_maximum_over_phi(
        r in 12.0f64..40.0,
        a in -0.5f64..-0.01,
        depth in 0.5f64..10.0,
        p in 0.0f64..40.0,
        u in 0.0f64..1.0,
    ) {
        let b = depth;
        let tool = Paraboloid { a, b };
        prop_assume!(tool.base_radius() < 0.9 * r);
        let helix = Helix::one_turn(r, p);
        let (from, to) = section_ends(&tool, &helix).unwrap();
        let x = from + (to - from) * (0.001 + 0.998 * u);
        let top = top_at(&tool, &helix, x).unwrap();
        let lower = brute(&tool, &helix, x).unwrap();
        prop_assert!(lower <= top.y + 1e-9, "grid {lower} above {}", top.y);
        prop_assert_eq!(chord_top(&tool, &helix, x, top.phi), Some(top.y));
    }

    /// The same for a torus, whose reach in φ has a hole (its inner radius).
    #[test]
    fn top_at_handles_a_torus(
        ring in 1.0f64..5.0,
        nose in 0.2f64..1.0,
        p in 0.0f64..20.0,
        u in 0.0f64..1.0,
    ) {
        let tool = Torus { ring, nose };
        let helix = Helix::one_turn(20.0, p);
        let (from, to) = section_ends(&tool, &helix).unwrap();
        let x = from + (to - from) * (0.001 + 0.998 * u);
        let top = top_at(&tool, &helix, x).unwrap();
        let lower = brute(&tool, &helix, x).unwrap();
        prop_assert!(lower <= top.y + 1e-9, "grid {lower} above {}", top.y);
        prop_assert_eq!(chord_top(&tool, &helix, x, top.phi), Some(top.y));
    }
}

#[test]
fn a_torus_section_is_within_its_accuracy_of_the_brute_force_maximum() {
    let tool = Torus {
        ring: 3.0,
        nose: 1.0,
    };
    let helix = Helix::one_turn(20.0, 6.0);
    let pts = upper_boundary(&tool, &helix, (-30.0, -10.0), 1e-4).unwrap();
    assert!(pts.windows(2).all(|w| w[0].x < w[1].x));
    assert!((pts[0].x + 24.0).abs() < 1e-12 && (pts[pts.len() - 1].x + 16.0).abs() < 1e-12);
    for k in 1..400 {
        let x = -24.0 + 8.0 * k as f64 / 400.0;
        let top = top_at(&tool, &helix, x).unwrap().y;
        assert!((interpolate(&pts, x) - top).abs() <= 1e-4, "at {x}");
        assert!(brute(&tool, &helix, x).unwrap() <= top + 1e-9);
    }
}

#[test]
fn refuses_what_it_cannot_section() {
    let helix = Helix::one_turn(20.0, 20.0);
    let tool = table_1_tool();
    assert_eq!(
        upper_boundary(&tool, &helix, (-8.0, -32.0), 1e-4),
        Err(SectionError::XRange(-8.0, -32.0))
    );
    assert!(matches!(
        upper_boundary(&tool, &helix, (f64::NAN, 0.0), 1e-4),
        Err(SectionError::XRange(..))
    ));
    assert!(matches!(
        upper_boundary(&tool, &helix, (0.0, 10.0), 1e-4),
        Err(SectionError::Misses { .. })
    ));
    assert_eq!(
        upper_boundary(&tool, &helix, (-32.0, -8.0), 1e-12),
        Err(SectionError::Accuracy(1e-12))
    );
    assert_eq!(
        upper_boundary(&BallEnd { radius: 3.0 }, &helix, (-32.0, -8.0), 1e-4),
        Err(SectionError::Unbounded)
    );
    assert!(matches!(
        section_ends(&Paraboloid { a: -0.01, b: 7.2 }, &helix),
        Err(SectionError::ReachesAxis { .. })
    ));
    // A φ range that never brings the tool to the x < 0 side.
    let near_side = Helix {
        phi_start: -0.5,
        phi_end: 0.5,
        ..helix
    };
    assert_eq!(
        section_ends(&tool, &near_side),
        Err(SectionError::NoSection)
    );
}

fn parse(csv: &str) -> Vec<DVec2> {
    csv.lines()
        .skip(1)
        .map(|l| {
            let (x, y) = l.split_once(',').unwrap();
            DVec2::new(x.parse().unwrap(), y.parse().unwrap())
        })
        .collect()
}

#[test]
fn run_paraboloid_writes_the_groove_end_to_end() {
    let csv = run_paraboloid(-0.05, 7.2, 20.0, 20.0, 1e-4).unwrap();
    assert!(csv.starts_with("x,y\n"));
    let pts = parse(&csv);
    assert_eq!(pts[0], DVec2::new(-32.0, 0.0));
    assert_eq!(pts[pts.len() - 1], DVec2::new(-8.0, 0.0));
    assert!(pts.windows(2).all(|w| w[0].x < w[1].x));
    assert_eq!(csv.lines().nth(1), Some("-32,0"));
    // The file reads back to exactly what upper_boundary gives.
    let direct = upper_boundary(
        &table_1_tool(),
        &Helix::one_turn(20.0, 20.0),
        (-32.0, -8.0),
        1e-4,
    )
    .unwrap();
    assert_eq!(pts.len(), direct.len());
    assert!(pts
        .iter()
        .zip(&direct)
        .all(|(p, q)| p.x == q.x && (p.y - q.y).abs() < 1e-12));
    let gap = worst_gap(&pts, |x| TABLE_1.section(x), 20_000);
    assert!(gap <= 1e-4, "{gap}");
}

#[test]
fn run_paraboloid_refuses_each_bad_input() {
    let ok = (-0.05, 7.2, 20.0, 20.0, 1e-4);
    let run = |a, b, r, p, acc| run_paraboloid(a, b, r, p, acc);
    assert!(run(ok.0, ok.1, ok.2, ok.3, ok.4).is_ok());
    assert_eq!(
        run(0.0, 7.2, 20.0, 20.0, 1e-4),
        Err(SectionError::ParaboloidA(0.0))
    );
    assert_eq!(
        run(0.05, 7.2, 20.0, 20.0, 1e-4),
        Err(SectionError::ParaboloidA(0.05))
    );
    assert!(matches!(
        run(f64::NAN, 7.2, 20.0, 20.0, 1e-4),
        Err(SectionError::ParaboloidA(_))
    ));
    assert_eq!(
        run(-0.05, 0.0, 20.0, 20.0, 1e-4),
        Err(SectionError::ParaboloidB(0.0))
    );
    assert_eq!(
        run(-0.05, f64::INFINITY, 20.0, 20.0, 1e-4),
        Err(SectionError::ParaboloidB(f64::INFINITY))
    );
    assert_eq!(
        run(-0.05, 7.2, 0.0, 20.0, 1e-4),
        Err(SectionError::Helix(HelixError::Radius(0.0)))
    );
    assert_eq!(
        run(-0.05, 7.2, -20.0, 20.0, 1e-4),
        Err(SectionError::Helix(HelixError::Radius(-20.0)))
    );
    assert_eq!(
        run(-0.05, 7.2, 20.0, -1.0, 1e-4),
        Err(SectionError::Helix(HelixError::Pitch(-1.0)))
    );
    assert!(matches!(
        run(-0.05, 7.2, 20.0, f64::NAN, 1e-4),
        Err(SectionError::Helix(HelixError::Pitch(_)))
    ));
    assert_eq!(
        run(-0.05, 7.2, 20.0, 20.0, 0.0),
        Err(SectionError::Accuracy(0.0))
    );
    assert_eq!(
        run(-0.05, 7.2, 20.0, 20.0, -1.0),
        Err(SectionError::Accuracy(-1.0))
    );
    assert_eq!(
        run(-0.05, 7.2, 20.0, 20.0, 1e-10),
        Err(SectionError::Accuracy(1e-10))
    );
    assert!(matches!(
        run(-0.05, 7.2, 20.0, 20.0, f64::INFINITY),
        Err(SectionError::Accuracy(_))
    ));
    // A tool as wide as the helix radius would cut across the screw axis.
    assert!(matches!(
        run(-0.05, 7.2, 12.0, 20.0, 1e-4),
        Err(SectionError::ReachesAxis { .. })
    ));
    // Every error reads as a sentence naming the value.
    let msg = run(-0.05, 7.2, 20.0, 20.0, 1e-10).unwrap_err().to_string();
    assert!(msg.contains("accuracy") && msg.contains("1e-10"), "{msg}");
}

#[test]
fn the_finest_accuracy_works_at_seed_000() {
    let helix = Helix::one_turn(20.0, 20.0);
    let pts = upper_boundary(&table_1_tool(), &helix, (-32.0, -8.0), MIN_ACCURACY).unwrap();
    assert!(pts.windows(2).all(|w| w[0].x < w[1].x));
    assert!(pts.len() < 1_000_000, "{}", pts.len());
}
