//! Tests of the cusp, kept apart from it for length: the engine against the ball and corner-radius
//! closed forms, its polyline and quadrature accuracies, bad input, and the paper's equations
//! as printed and corrected.

use super::paper::{BallSymbols, CornerSymbols};
use super::*;
use crate::papers::tool::{FlatEnd, Paraboloid, Torus};
use proptest::prelude::*;
use std::f64::consts::PI;

const ACCURACY: f64 = 1e-7;

/// |a − b| ≤ rel·|b|, or both within `floor` of each other (for true zeros).
fn close(a: f64, b: f64, rel: f64, floor: f64) -> bool {
    (a - b).abs() <= rel * b.abs() || (a - b).abs() <= floor
}

/// Stepovers as fractions of the ball's diameter: from vanishing to the full width.
/// (Below 10⁻³ the tool's own rounding of r − √(r² − ρ²), about ε·r, is more than 10⁻⁹
/// of the area: see the vanishing-stepover test.)
const FRACTIONS: [f64; 12] = [
    0.0, 1e-3, 3e-3, 0.01, 0.05, 0.1, 0.25, 0.5, 0.75, 0.9, 0.999, 1.0,
];

#[test]
fn gauss_kronrod_weights_integrate_polynomials_to_their_degrees() {
    // K15 is exact to degree 22, G7 to degree 13: on [0, 1] ∫ x^n = 1/(n + 1).
    for n in 0..=22 {
        let f = |x: f64| Ok(x.powi(n));
        let piece = gk15(&f, 0.0, 1.0, 1.0).unwrap();
        let (k, diff) = (piece.value, piece.error);
        assert!(
            (k - 1.0 / (n + 1) as f64).abs() < 1e-15,
            "K15 at degree {n}"
        );
        if n <= 13 {
            assert!(diff < 1e-15, "G7 at degree {n}: |K − G| {diff}");
        }
    }
    assert!(gk15(&|x: f64| Ok(x.powi(14)), 0.0, 1.0, 1.0).unwrap().error > 1e-10);
    // A rise hidden between the last node and the end of the interval is not missed.
    let step = |x: f64| Ok(if x > 0.999 { x - 0.999 } else { 0.0 });
    let piece = gk15(&step, 0.0, 1.0, 1.0).unwrap();
    assert_eq!(piece.value, 0.0);
    assert!(piece.error >= 1e-3);
    let (area, _) = integrate(&step, 0.0, 1.0, 1.0).unwrap();
    assert!((area - 0.5e-6).abs() <= 1e-12 * 0.5e-6);
}

#[test]
fn ball_cusp_height_is_the_arc_at_half_the_stepover() {
    for r in [0.5, 3.0, 12.7] {
        let tool = BallEnd { radius: r };
        for q in FRACTIONS {
            let s = 2.0 * r * q;
            let section = section(&tool, s, ACCURACY).unwrap();
            let expected = r - (r * r - s * s / 4.0).sqrt();
            assert!(
                (section.cusp.height - expected).abs() <= 1e-14 * r,
                "r {r} s {s}: {} against {expected}",
                section.cusp.height
            );
            if s > 0.0 {
                assert_eq!(section.peak.x, s / 2.0, "the peak is midway");
            }
        }
    }
}

#[test]
fn corner_radius_cusp_height_is_the_corner_arc_beyond_the_flat() {
    let tool = CornerRadius {
        flat: 2.0,
        corner: 1.0,
    };
    for s in [0.0, 1.0, 3.9, 4.0, 4.001, 4.5, 5.0, 5.5, 5.999, 6.0] {
        let section = section(&tool, s, ACCURACY).unwrap();
        let d: f64 = s / 2.0 - 2.0;
        let expected = if d <= 0.0 {
            0.0
        } else {
            1.0 - (1.0 - d * d).sqrt()
        };
        assert!(
            (section.cusp.height - expected).abs() <= 1e-14,
            "s {s}: {} against {expected}",
            section.cusp.height
        );
    }
}

#[test]
fn ball_cusp_area_agrees_with_the_closed_forms_over_stepovers() {
    for r in [0.5, 3.0, 12.7] {
        let tool = BallEnd { radius: r };
        for q in FRACTIONS {
            let s = 2.0 * r * q;
            let engine = section(&tool, s, ACCURACY).unwrap();
            let closed = ball_cusp(&tool, s).unwrap();
            assert!(
                close(engine.cusp.area, closed.area, 1e-9, 0.0),
                "r {r} s {s}: engine {} closed {} (rel {:e})",
                engine.cusp.area,
                closed.area,
                (engine.cusp.area / closed.area - 1.0).abs()
            );
            assert!(close(engine.cusp.half_area, closed.half_area, 1e-9, 0.0));
            assert!(
                engine.area_error <= 1e-12 * engine.cusp.area.max(f64::MIN_POSITIVE)
                    || engine.area_error <= 16.0 * f64::EPSILON * 2.0 * r * s
            );
        }
    }
}

#[test]
fn corner_radius_cusp_area_agrees_with_the_closed_forms_and_vanishes_while_flats_overlap() {
    // Dyadic radii: the tool puts its edge exactly at flat + corner only when
    // (flat + corner) − flat rounds back to the corner, and the sweep ends there.
    for (flat, corner) in [(2.0, 1.0), (0.25, 2.5), (5.0, 0.25)] {
        let tool = CornerRadius { flat, corner };
        let width = 2.0 * (flat + corner);
        for q in [0.0, 0.1, 0.5, 0.999, 1.0] {
            // Flats overlapping: s ≤ 2·r1, nothing left.
            let s = 2.0 * flat * q;
            let engine = section(&tool, s, ACCURACY).unwrap();
            assert_eq!(engine.cusp.area, 0.0, "flats overlap at s {s}");
            assert_eq!(engine.cusp.height, 0.0);
            assert_eq!(corner_radius_cusp(&tool, s).unwrap().area, 0.0);
        }
        for q in [1e-2, 0.05, 0.1, 0.3, 0.5, 0.7, 0.9, 0.999, 1.0] {
            let s = 2.0 * flat + q * (width - 2.0 * flat);
            let engine = section(&tool, s, ACCURACY).unwrap();
            let closed = corner_radius_cusp(&tool, s).unwrap();
            assert!(
                close(engine.cusp.area, closed.area, 1e-9, 0.0),
                "r1 {flat} r2 {corner} s {s}: engine {} closed {}",
                engine.cusp.area,
                closed.area
            );
            // The cusp is a ball's of radius r2 at stepover s − 2·r1.
            let ball = ball_cusp(&BallEnd { radius: corner }, s - 2.0 * flat).unwrap();
            assert!(close(closed.area, ball.area, 1e-12, 0.0));
            assert!(close(closed.height, ball.height, 1e-12, 0.0));
        }
    }
}

#[test]
fn vanishing_stepovers_leave_the_parabola_s_cube_over_24_r_within_the_tools_rounding() {
    // Near its tip a ball of radius r is the parabola z = x²/(2r): the cusp area tends to
    // 2∫₀^{s/2} x²/(2r) dx = s³/(24r). The engine reads the tool's heights as
    // r − √(r² − ρ²), good to about ε·r, so its area is good to about ε·r·s.
    let r = 3.0;
    let tool = BallEnd { radius: r };
    for s in [1e-2, 1e-3, 1e-4, 1e-5, 1e-6] {
        let closed = ball_cusp(&tool, s).unwrap();
        let parabola = s * s * s / (24.0 * r);
        // The next term, 2∫₀^{s/2} x⁴/(8r³) dx, is 0.0375·(s/r)² of the first.
        assert!(close(
            closed.area,
            parabola,
            0.04 * (s / r).powi(2) + 1e-13,
            0.0
        ));
        let engine = section(&tool, s, ACCURACY).unwrap();
        assert!(
            (engine.cusp.area - closed.area).abs() <= 4.0 * f64::EPSILON * r * s,
            "s {s}: engine {} closed {}",
            engine.cusp.area,
            closed.area
        );
    }
    assert_eq!(
        section(&tool, 0.0, ACCURACY).unwrap().cusp,
        ball_cusp(&tool, 0.0).unwrap()
    );
}

#[test]
fn closed_forms_meet_the_geometry_at_the_full_width() {
    // At s = 2r the half-cusp is the square r × r less the quarter disc.
    let r = 3.0;
    let full = ball_cusp(&BallEnd { radius: r }, 2.0 * r).unwrap();
    assert!(close(full.height, r, 1e-15, 0.0));
    assert!(close(full.half_area, r * r * (1.0 - PI / 4.0), 1e-14, 0.0));
    // And every half-cusp lies in the rectangle half-stepover × height, and within the
    // triangle under the chord from the pass centre to the peak (the arc is convex, so it
    // runs below that chord).
    for q in [1e-3, 0.1, 0.5, 0.9, 1.0] {
        let s = 2.0 * r * q;
        let c = ball_cusp(&BallEnd { radius: r }, s).unwrap();
        assert!(c.half_area <= s / 2.0 * c.height);
        assert!(c.half_area >= 0.0);
        assert!(c.half_area <= 0.5 * s / 2.0 * c.height);
    }
}

#[test]
fn the_polyline_is_within_its_accuracy_across_accuracies() {
    let tools: [(&dyn Revolved, f64); 4] = [
        (&BallEnd { radius: 3.0 }, 6.0),
        (&BallEnd { radius: 3.0 }, 2.5),
        (
            &CornerRadius {
                flat: 2.0,
                corner: 1.0,
            },
            5.3,
        ),
        (
            &CornerRadius {
                flat: 2.0,
                corner: 1.0,
            },
            6.0,
        ),
    ];
    let truth = |tool: &dyn Revolved, s: f64, x: f64| {
        let u = x.min(s - x).max(0.0);
        tool.span_at(u).unwrap().0
    };
    for (tool, s) in tools {
        for accuracy in [1e-2, 1e-4, 1e-6, 1e-8, 1e-10] {
            let section = section(tool, s, accuracy).unwrap();
            let points = &section.points;
            assert_eq!(points[0].x, 0.0);
            assert_eq!(points[points.len() - 1].x, s);
            assert!(points.windows(2).all(|w| w[1].x > w[0].x));
            // Every sampled point of the envelope is within the accuracy of the polyline:
            // of the chord over it, or of a neighbour (an upper bound on the distance).
            for k in 0..=4000 {
                let x = s * k as f64 / 4000.0;
                let p = DVec2::new(x, truth(tool, s, x));
                let i = points
                    .partition_point(|q| q.x <= x)
                    .clamp(1, points.len() - 1);
                let distance = (i.saturating_sub(2)..(i + 1).min(points.len() - 1))
                    .map(|j| {
                        let (a, b) = (points[j], points[j + 1]);
                        let d = b - a;
                        let t = ((p - a).dot(d) / d.length_squared()).clamp(0.0, 1.0);
                        (a + t * d - p).length()
                    })
                    .fold(f64::INFINITY, f64::min);
                assert!(
                    distance <= accuracy * (1.0 + 1e-6) + 1e-14,
                    "s {s} accuracy {accuracy}: {distance} at x {x}"
                );
            }
            // The polyline's own area is within its bound of the envelope's.
            let exact = section.cusp.area;
            assert!(
                (section.polyline_area() - exact).abs() <= section.polyline_area_bound(),
                "accuracy {accuracy}: {} vs {exact}",
                section.polyline_area()
            );
        }
    }
}

#[test]
fn the_volume_per_pass_is_the_area_times_the_length() {
    let tool = BallEnd { radius: 3.0 };
    let engine = section(&tool, 2.2, ACCURACY).unwrap();
    let closed = ball_cusp(&tool, 2.2).unwrap();
    for length in [0.0, 1.0, 37.5, 1000.0] {
        let v = engine.volume(length).unwrap();
        assert!(close(v, closed.area * length, 1e-9, 0.0));
        assert!(close(
            engine.volume(2.0 * length).unwrap(),
            2.0 * v,
            1e-15,
            0.0
        ));
    }
    let corner = CornerRadius {
        flat: 2.0,
        corner: 1.0,
    };
    let engine = section(&corner, 5.0, ACCURACY).unwrap();
    let closed = corner_radius_cusp(&corner, 5.0).unwrap();
    assert!(close(
        engine.volume(12.0).unwrap(),
        12.0 * closed.area,
        1e-9,
        0.0
    ));
    assert!(matches!(
        engine.volume(-1.0),
        Err(CuspError::Negative { .. })
    ));
    assert!(matches!(
        engine.volume(f64::NAN),
        Err(CuspError::Negative { .. })
    ));
}

proptest! {
    /// Why the section is the meridian outline and the same all along a straight pass: a
    /// tool point at horizontal offset (dx, dy) from the axis is at radius √(dx² + dy²)
    /// ≥ |dx|, and the tip never sits lower further out, so the deepest cut at offset dx
    /// across the pass is the one in the axis plane (dy = 0), wherever along the pass.
    #[test]
    fn no_tool_point_off_the_axis_plane_cuts_deeper(
        dx in 0.0..3.0f64, dy in -3.0..3.0f64, flat in 0.0..2.0f64, corner in 0.1..2.0f64,
    ) {
        let tools: [&dyn Revolved; 3] = [
            &BallEnd { radius: 3.0 },
            &CornerRadius { flat, corner },
            &FlatEnd { radius: 3.0 },
        ];
        for tool in tools {
            let rho = dx.hypot(dy);
            if let (Some(on), Some(off)) = (tool.span_at(dx), tool.span_at(rho)) {
                prop_assert!(off.0 >= on.0 - 1e-12);
            }
        }
    }

    /// The envelope is symmetric and the two halves hold the same area.
    #[test]
    fn sections_are_symmetric_and_bounded(r in 0.1..10.0f64, q in 0.0..1.0f64) {
        let tool = BallEnd { radius: r };
        let s = 2.0 * r * q;
        let section = section(&tool, s, 1e-6).unwrap();
        let c = section.cusp;
        prop_assert!(c.half_area >= 0.0);
        prop_assert!(c.half_area <= s / 2.0 * c.height * (1.0 + 1e-12));
        let points = &section.points;
        let n = points.len();
        for (a, b) in points.iter().zip(points.iter().rev()).take(n / 2) {
            prop_assert!((a.x - (s - b.x)).abs() <= 1e-12 * r);
            prop_assert!((a.y - b.y).abs() <= 1e-12 * r);
        }
    }
}

#[test]
fn the_engine_takes_any_tool_through_the_trait() {
    // A flat end mill and the paraboloid (flat below, on h = 0) leave no cusp.
    let flat: &dyn Revolved = &FlatEnd { radius: 3.0 };
    let paraboloid: &dyn Revolved = &Paraboloid { a: -0.05, b: 7.2 };
    for (tool, width) in [(flat, 6.0), (paraboloid, 24.0)] {
        // (Not at the full width: the tools' own rounding may put their edge a hair short.)
        for s in [0.5, width / 2.0, 0.999 * width] {
            let section = section(tool, s, ACCURACY).unwrap();
            assert_eq!(section.cusp.area, 0.0);
            assert_eq!(section.cusp.height, 0.0);
        }
    }
    // A ring torus has no material on its axis; a spindle torus's tip surface falls
    // outward (lowest at ρ = R), so its pass section is not its meridian outline.
    let ring = Torus {
        ring: 3.0,
        nose: 1.0,
    };
    assert_eq!(section(&ring, 1.0, ACCURACY), Err(CuspError::MissesAxis));
    let spindle = Torus {
        ring: 0.5,
        nose: 1.0,
    };
    assert!(matches!(
        section(&spindle, 2.0, ACCURACY),
        Err(CuspError::NotRisingOutward { .. })
    ));
}

#[test]
fn bad_input_is_refused() {
    let ball = BallEnd { radius: 3.0 };
    for s in [-1.0, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            section(&ball, s, ACCURACY),
            Err(CuspError::Negative { .. })
        ));
        assert!(matches!(
            ball_cusp(&ball, s),
            Err(CuspError::Negative { .. })
        ));
    }
    for accuracy in [0.0, -1.0, f64::NAN] {
        assert!(matches!(
            section(&ball, 1.0, accuracy),
            Err(CuspError::NotPositive { .. })
        ));
    }
    assert!(matches!(
        section(&ball, 6.01, ACCURACY),
        Err(CuspError::TooWide { .. })
    ));
    assert!(matches!(
        section(&BallEnd { radius: 25.0 }, 50.0, 1e-15),
        Err(CuspError::TooManyPoints { .. })
    ));
    assert!(matches!(
        ball_cusp(&ball, 6.01),
        Err(CuspError::TooWide { .. })
    ));
    for radius in [0.0, -3.0, f64::NAN] {
        let bad = BallEnd { radius };
        assert!(matches!(
            ball_cusp(&bad, 1.0),
            Err(CuspError::NotPositive { .. })
        ));
        assert!(section(&bad, 1.0, ACCURACY).is_err());
    }
    let bad = CornerRadius {
        flat: -1.0,
        corner: 1.0,
    };
    assert!(matches!(
        corner_radius_cusp(&bad, 1.0),
        Err(CuspError::Negative { .. })
    ));
    let bad = CornerRadius {
        flat: 1.0,
        corner: 0.0,
    };
    assert!(matches!(
        corner_radius_cusp(&bad, 1.0),
        Err(CuspError::NotPositive { .. })
    ));
    let tool = CornerRadius {
        flat: 2.0,
        corner: 1.0,
    };
    assert!(matches!(
        corner_radius_cusp(&tool, 6.5),
        Err(CuspError::TooWide { .. })
    ));
    assert!(BallSymbols::from_r_h(3.0, 3.5).is_err());
    assert!(BallSymbols::from_r_h(-3.0, 1.0).is_err());
}

// The paper: ball end mill, Eqs. 11 and 24–28.

/// Stepovers, as fractions of the diameter, where the printed forms keep their digits.
const PAPER_FRACTIONS: [f64; 8] = [0.05, 0.1, 0.25, 0.5, 0.75, 0.9, 0.999, 1.0];

#[test]
fn eq_11_makes_r_c_the_half_stepover_when_h_is_the_cusp_height() {
    for q in PAPER_FRACTIONS {
        let (r, s) = (3.0, 6.0 * q);
        let symbols = BallSymbols::for_tool(&BallEnd { radius: r }, s).unwrap();
        let by_eq_11 = BallSymbols::from_r_h(r, symbols.h).unwrap();
        assert!(close(by_eq_11.r_c, s / 2.0, 1e-12, 0.0), "s {s}");
    }
}

#[test]
fn eq_27_corrected_agrees_with_the_engine_and_printed_is_off_by_pi_rc2_less_r_rc() {
    for r in [0.5, 3.0, 12.7] {
        let tool = BallEnd { radius: r };
        for q in PAPER_FRACTIONS {
            let s = 2.0 * r * q;
            let engine = section(&tool, s, ACCURACY).unwrap().cusp;
            let symbols = BallSymbols::for_tool(&tool, s).unwrap();
            let corrected = symbols.eq27_corrected().unwrap();
            assert!(
                close(corrected, engine.half_area, 1e-9, 0.0),
                "r {r} s {s}: corrected Eq. 27 {corrected} engine {}",
                engine.half_area
            );
            // Printed less true is exactly the wrong first term's excess.
            let rc = symbols.r_c;
            let excess = 0.5 * (PI * rc * rc - r * rc);
            let printed = symbols.eq27().unwrap();
            assert!(
                (printed - engine.half_area - excess).abs() <= 1e-9 * (r * rc),
                "r {r} s {s}: printed {printed} engine {} excess {excess}",
                engine.half_area
            );
            // Eq. 28 is both halves over L, of Eq. 27 printed or corrected.
            let length = 40.0;
            assert!(close(
                symbols.eq28(length).unwrap(),
                2.0 * length * printed,
                1e-12,
                0.0
            ));
            assert!(close(
                symbols.eq28_corrected(length).unwrap(),
                section(&tool, s, ACCURACY).unwrap().volume(length).unwrap(),
                1e-9,
                0.0
            ));
        }
    }
}

#[test]
fn eq_27_as_printed_gives_impossible_areas() {
    let r = 3.0;
    let tool = BallEnd { radius: r };
    // Over the whole range: below zero, or above the rectangle r_c × h that contains the
    // half-cusp, except in a narrow band around r_c = r/π.
    for k in 1..=100 {
        let rc = r * k as f64 / 100.0;
        let symbols = BallSymbols::for_tool(&tool, 2.0 * rc).unwrap();
        let printed = symbols.eq27().unwrap();
        if rc < 0.308 * r {
            assert!(printed < 0.0, "r_c {rc}: {printed}");
        } else if rc > 0.345 * r {
            assert!(printed > rc * symbols.h, "r_c {rc}: {printed}");
        }
    }
    // Small stepover: an area cannot be negative.
    let small = BallSymbols::for_tool(&tool, 0.2 * r).unwrap();
    let printed = small.eq27().unwrap();
    assert!(printed < 0.0, "Eq. 27 at s = 0.2r: {printed}");
    // Full width: the half-cusp lies inside the rectangle r_c × h, here the square r × r.
    let full = BallSymbols::for_tool(&tool, 2.0 * r).unwrap();
    let printed = full.eq27().unwrap();
    let rectangle = full.r_c * full.h;
    assert!(
        printed > rectangle,
        "Eq. 27 at s = 2r: {printed} > {rectangle}"
    );
    // Only where π·r_c² = r·r_c, r_c = r/π, does the printed form happen to be right.
    let lucky = BallSymbols::for_tool(&tool, 2.0 * r / PI).unwrap();
    let engine = section(&tool, 2.0 * r / PI, ACCURACY).unwrap().cusp;
    assert!(close(lucky.eq27().unwrap(), engine.half_area, 1e-9, 0.0));
}

// The paper: corner-radius end mill, Eqs. 21–23.

#[test]
fn eq_22_corrected_agrees_with_the_engine_and_printed_is_its_mirror_about_a_times_width() {
    for (flat, corner) in [(2.0, 1.0), (0.25, 2.5), (5.0, 0.25)] {
        let tool = CornerRadius { flat, corner };
        for q in PAPER_FRACTIONS {
            let s = 2.0 * flat + 2.0 * corner * q;
            let engine = section(&tool, s, ACCURACY).unwrap();
            let symbols = CornerSymbols::for_tool(&tool, s).unwrap();
            assert_eq!(symbols.a, corner);
            // a − h is the half-cusp's width: from where the corner leaves the flat to
            // the midpoint.
            assert!((symbols.a - symbols.h - (s / 2.0 - flat)).abs() < 1e-12);
            let corrected = symbols.eq22_corrected().unwrap();
            assert!(
                close(corrected, engine.cusp.half_area, 1e-9, 0.0),
                "r1 {flat} r2 {corner} s {s}: corrected Eq. 22 {corrected} engine {}",
                engine.cusp.half_area
            );
            // Upper and lower halves of the corner circle, over the same width a − h, sum
            // to the rectangle of height 2a.
            let width = symbols.a - symbols.h;
            let printed = symbols.eq22().unwrap();
            assert!(
                close(
                    printed + engine.cusp.half_area,
                    2.0 * symbols.a * width,
                    1e-9,
                    0.0
                ),
                "printed {printed} engine {}",
                engine.cusp.half_area
            );
            let length = 25.0;
            assert!(close(
                symbols.eq23(length).unwrap(),
                2.0 * length * printed,
                1e-12,
                0.0
            ));
            assert!(close(
                symbols.eq23_corrected(length).unwrap(),
                engine.volume(length).unwrap(),
                1e-9,
                0.0
            ));
        }
    }
}

#[test]
fn eq_22_as_printed_exceeds_the_rectangle_holding_the_half_cusp() {
    // The half-cusp lies in the rectangle (half-width a − h) × (cusp height); Eq. 22 is
    // at least a·(a − h), and the cusp is never higher than the corner radius a.
    let tool = CornerRadius {
        flat: 2.0,
        corner: 1.0,
    };
    for s in [4.01, 4.5, 5.0, 5.5, 6.0] {
        let symbols = CornerSymbols::for_tool(&tool, s).unwrap();
        let height = section(&tool, s, ACCURACY).unwrap().cusp.height;
        let rectangle = (symbols.a - symbols.h) * height;
        let printed = symbols.eq22().unwrap();
        assert!(printed > rectangle, "s {s}: Eq. 22 {printed} > {rectangle}");
        assert!(printed > symbols.a * (symbols.a - symbols.h));
    }
    // At the full width the printed form gives the square plus a quarter disc, a²(1 + π/4),
    // for the square less one, a²(1 − π/4).
    let full = CornerSymbols::for_tool(&tool, 6.0).unwrap();
    assert!(close(full.eq22().unwrap(), 1.0 + PI / 4.0, 1e-14, 0.0));
    assert!(close(
        full.eq22_corrected().unwrap(),
        1.0 - PI / 4.0,
        1e-14,
        0.0
    ));
}

#[test]
fn eq_21_is_outside_its_range_when_the_flats_overlap() {
    let tool = CornerRadius {
        flat: 2.0,
        corner: 1.0,
    };
    let symbols = CornerSymbols::for_tool(&tool, 3.0).unwrap();
    assert!(symbols.h > symbols.a);
    assert!(matches!(
        symbols.eq22(),
        Err(CuspError::OutsideEquation { equation: 22, .. })
    ));
    assert!(matches!(
        symbols.eq23(1.0),
        Err(CuspError::OutsideEquation { equation: 23, .. })
    ));
    assert_eq!(symbols.eq22_corrected().unwrap(), 0.0);
    // At s = 2·r1 exactly, h = a: the integral from a to a is empty, in both forms.
    let edge = CornerSymbols::for_tool(&tool, 4.0).unwrap();
    assert_eq!(edge.eq22().unwrap(), 0.0);
    assert_eq!(edge.eq22_corrected().unwrap(), 0.0);
}

#[test]
fn reading_eq_21_s_h_as_the_cusp_height_fails_even_with_the_sign_fixed() {
    // With h the cusp height, the sign-fixed Eq. 22 measures the half-cusp's mirror image
    // across the corner's diagonal: right only at a half-width of a/√2.
    let tool = CornerRadius {
        flat: 2.0,
        corner: 1.0,
    };
    for s in [4.5, 5.0, 5.9] {
        let engine = section(&tool, s, ACCURACY).unwrap().cusp;
        let as_height = CornerSymbols {
            a: 1.0,
            h: engine.height,
        };
        let value = as_height.eq22_corrected().unwrap();
        assert!(
            (value - engine.half_area).abs() > 0.05 * engine.half_area,
            "s {s}: {value} vs {}",
            engine.half_area
        );
    }
    let s = 4.0 + 2.0 / 2f64.sqrt();
    let engine = section(&tool, s, ACCURACY).unwrap().cusp;
    let as_height = CornerSymbols {
        a: 1.0,
        h: engine.height,
    };
    assert!(close(
        as_height.eq22_corrected().unwrap(),
        engine.half_area,
        1e-9,
        0.0
    ));
}
