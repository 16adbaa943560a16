//! The installation-angle window on the trapezoidal example, whose 0.4 mm nose follows the
//! 0.5 mm root fillet only near the lead angle at the root; on variants of it whose ring fits
//! nowhere; and the ball screw, which gives no angle.

use super::*;
use crate::config::machine::MachineProfile;
use crate::config::testing::example;
use crate::plan::plan;

fn sim() -> MachineProfile {
    MachineProfile::builtin_sim().expect("the built-in machine profile")
}

/// The trapezoidal example (radii 16 to 20 mm) with a ring of radius `ring_radius`.
fn trapezoidal_with_ring(ring_radius: f64) -> Job {
    let mut job = example("trapezoidal");
    job.tool.ring_radius = ring_radius;
    job
}

/// Whether `deg` is an angle of the grid: what it prints as, read back, is itself.
fn on_grid(deg: f64) -> bool {
    show_deg(deg).parse::<f64>() == Ok(deg)
}

/// The edges' facts: each edge is a grid angle, the ring fits there and its margin is zero;
/// at the grid angle one step beyond (the bisection's tolerance) the margin is negative and
/// the ring does not fit, for the reason recorded; at angles between the edges the margin is
/// positive and the ring fits.
fn assert_edges_hold(job: &Job, found: &Windows) {
    for w in &found.windows {
        for (edge, outward) in [(&w.low, -1.0), (&w.high, 1.0)] {
            assert!(on_grid(edge.deg), "{edge:?}");
            assert_eq!(w.margin(edge.deg), 0.0);
            assert!(fit(job, &tilted(job, edge.deg)).is_ok(), "fits at {edge:?}");
            let (beyond, why) = edge.beyond.as_ref().expect("an edge inside the range");
            assert!(on_grid(*beyond), "{edge:?}");
            let step = (beyond - edge.deg) * outward;
            assert!(
                (step - EDGE_TOLERANCE_DEG).abs() < 1e-9,
                "one grid step outside: {edge:?}"
            );
            assert!(w.margin(*beyond) < 0.0);
            assert_eq!(fit(job, &tilted(job, *beyond)).err().as_ref(), Some(why));
        }
        for i in 1..8 {
            let deg = w.low.deg + (w.high.deg - w.low.deg) * f64::from(i) / 8.0;
            assert!(w.margin(deg) > 0.0);
            assert!(
                fit(job, &tilted(job, deg)).is_ok(),
                "fits at {deg}° inside {w:?}"
            );
        }
    }
}

#[test]
fn the_trapezoidal_window_holds_the_examples_angle_and_not_the_mean_radius_lead_angle() {
    let job = example("trapezoidal");
    // Radii 16 to 20 mm, lead 14 mm: atan(14/2π / 18) = 7.0566° at the mean radius, the angle
    // a job without one got before, which the example's comment says is refused.
    let mean_lead = lead_angles(&job)[1];
    assert!((mean_lead - 7.0566).abs() < 1e-3, "{mean_lead}");
    let found = windows(&job).unwrap();
    assert_eq!(found.windows.len(), 1, "{}", found.list());
    let w = &found.windows[0];
    assert!(w.margin(7.8) > 0.0, "the example's 7.8° plans: {w:?}");
    assert!(w.margin(mean_lead) < 0.0, "7.06° is refused: {w:?}");
    // The refusal before this window listed the whole degrees from 0° to 45° that pass: "8°".
    let whole: Vec<u32> = (0..=45)
        .filter(|d| w.margin(f64::from(*d)) >= 0.0)
        .collect();
    assert_eq!(whole, [8]);
    assert_edges_hold(&job, &found);
}

#[test]
fn the_refusal_of_an_angle_lists_the_window_and_its_best_angle() {
    let found = windows(&example("trapezoidal")).unwrap();
    let best = show_deg(found.best().1);
    for deg in [7.06, 12.0] {
        let mut job = example("trapezoidal");
        job.tool.installation_angle_deg = Some(deg);
        let e = plan(&job, &sim()).unwrap_err();
        assert!(
            matches!(e, PlanError::Table { .. } | PlanError::Interference { .. }),
            "{e}"
        );
        let text = e.to_string();
        assert!(
            text.contains(&format!(
                "installation angles that work with this ring: {} ",
                found.list()
            )) && text.contains(&format!("largest margin is at {best}°")),
            "{text}"
        );
    }
}

#[test]
fn an_edge_where_the_ring_cuts_a_flank_is_bisected_on_the_whole_check() {
    // A 20.8 mm ring round the 20 mm work: tilted less, its far side dips into the groove
    // beyond the Δ/10 the interference check allows, although every point has its pose.
    let job = trapezoidal_with_ring(20.8);
    let found = windows(&job).unwrap();
    let low = &found.windows[0].low;
    let Some((_, Misfit::Interference(cut))) = &low.beyond else {
        panic!("the lower edge is the interference check's: {low:?}");
    };
    assert!(cut.depth > job.cut.delta / 10.0, "{cut}");
    assert!(
        Search::new(&job)
            .check(steps(low.beyond.as_ref().unwrap().0), false)
            .is_none(),
        "the table alone passes beyond it"
    );
    assert_edges_hold(&job, &found);
}

#[test]
fn the_chosen_angle_is_the_middle_of_the_widest_window() {
    let found = windows(&example("trapezoidal")).unwrap();
    let (w, best) = found.best();
    assert!(on_grid(best) && w.margin(best) > 0.0, "{best}");
    // Within half a grid step of the middle, and no grid angle of the window has more margin.
    let half = (w.high.deg - w.low.deg) / 2.0;
    assert!(half - w.margin(best) <= EDGE_TOLERANCE_DEG / 2.0 + 1e-12);
    let grid = ((w.high.deg - w.low.deg) / EDGE_TOLERANCE_DEG).round() as u32;
    for i in 0..=grid {
        let deg = w.low.deg + f64::from(i) * EDGE_TOLERANCE_DEG;
        assert!(w.margin(deg) <= w.margin(best) + 1e-12, "{deg}");
    }
    assert!(
        w.margin(best) > w.margin(7.8),
        "more than the example's own angle"
    );
    // Of several windows the widest holds it, the lowest of equally wide ones.
    let window = |low: f64, high: f64| Window {
        low: Edge {
            deg: low,
            beyond: None,
        },
        high: Edge {
            deg: high,
            beyond: None,
        },
    };
    let several = Windows {
        windows: vec![window(2.0, 3.0), window(5.0, 9.0), window(20.0, 24.0)],
    };
    assert_eq!(several.best().1, 7.0);
    assert_eq!(several.list(), "2°–3°, 5°–9°, 20°–24°");
}

#[test]
fn a_job_without_an_angle_plans_at_the_chosen_angle_and_says_so() {
    let mut job = example("trapezoidal");
    job.tool.installation_angle_deg = None;
    let found = windows(&job).unwrap();
    let (w, best) = found.best();
    let chosen = plan(&job, &sim()).unwrap();
    // (In degrees as it was chosen; planned in radians.)
    assert!((chosen.report.installation_angle_deg - best).abs() < 1e-12);
    assert_eq!(
        chosen.report.installation_angle_origin,
        AngleOrigin::Window {
            window_deg: [w.low.deg, w.high.deg],
            margin_deg: w.margin(best),
        }
    );
    // Given that angle as printed, the job plans the same program, and says the angle was
    // given.
    job.tool.installation_angle_deg = Some(show_deg(best).parse().unwrap());
    let given = plan(&job, &sim()).unwrap();
    assert_eq!(given.text, chosen.text);
    assert_eq!(given.report.installation_angle_origin, AngleOrigin::Given);
}

#[test]
fn the_ball_screw_which_gives_no_angle_plans_at_the_middle_of_its_window() {
    // `plan` (and the engine, measuring what it planned) take the ring from `ring`.
    let job = example("ball-screw");
    let (ring, origin) = ring(&job).unwrap();
    let found = windows(&job).unwrap();
    assert_eq!(ring.installation, found.best().1.to_radians());
    assert!(matches!(origin, AngleOrigin::Window { margin_deg, .. } if margin_deg > 0.0));
    assert_edges_hold(&job, &found);
}

#[test]
fn a_ring_that_cannot_enclose_the_work_fits_nowhere_and_came_nearest_untilted() {
    // R − r = 20.3 − 0.4 = 19.9 mm < 20 mm, the work's outer radius: tilted by δ the ring
    // reaches R·cos δ − r from its centre, least short at δ = 0.
    let mut job = trapezoidal_with_ring(20.3);
    let none = windows(&job).unwrap_err();
    let Misfit::Clearance { reach, rho_max } = none.why else {
        panic!("{none}");
    };
    assert_eq!(none.deg, 0.0);
    assert!(
        (reach - 19.9).abs() < 1e-9 && (rho_max - 20.0).abs() < 1e-3,
        "{none}"
    );
    job.tool.installation_angle_deg = None;
    let e = plan(&job, &sim()).unwrap_err();
    assert!(matches!(e, PlanError::NoAngle(_)), "{e}");
    let text = e.to_string();
    assert!(
        text.starts_with("tool.installation_angle_deg is not given, and no installation angle")
            && text.contains("it came nearest at 0°, where the ring is too small"),
        "{text}"
    );
}

#[test]
fn a_ring_that_meets_the_groove_on_another_branch_everywhere_fits_nowhere() {
    // A 20.6 mm ring round the 20 mm work meets the flanks on another branch at every angle
    // (as `a_branch_switch_is_refused_as_x_jumping` finds for one): no angle has a table, so
    // none came nearer than another, and the refusal names the lead angle at the mean radius.
    let job = trapezoidal_with_ring(20.6);
    let none = windows(&job).unwrap_err();
    assert!(matches!(none.why, Misfit::Table(_)), "{none}");
    assert!(
        (none.deg - lead_angles(&job)[1]).abs() <= EDGE_TOLERANCE_DEG / 2.0,
        "{none}"
    );
    // The example's own angle is refused with the same news.
    let e = plan(&job, &sim()).unwrap_err();
    let text = e.to_string();
    assert!(
        text.contains("\nno installation angle from 0° to 90° plans this groove")
            && text.contains("the nearest to the lead angle at the mean radius"),
        "{text}"
    );
}

#[test]
fn the_survey_plans_across_the_window_its_edges_included() {
    let job = example("trapezoidal");
    let found = windows(&job).unwrap();
    let (w, best) = found.best();
    // Four angles a third of the window apart, and the middle, the chosen one.
    let rows = survey(&job, &found, 4, |at| plan(at, &sim()));
    assert_eq!(rows.len(), 5);
    assert_eq!((rows[0].deg, rows[4].deg), (w.low.deg, w.high.deg));
    assert!(rows.windows(2).all(|r| r[0].deg < r[1].deg));
    let chosen: Vec<f64> = rows.iter().filter(|r| r.chosen).map(|r| r.deg).collect();
    assert_eq!(chosen, [best]);
    for row in &rows {
        assert!(on_grid(row.deg), "planned at the angle printed: {row:?}");
        assert_eq!(row.margin_deg, w.margin(row.deg));
        let (error, segments) = row.planned.clone().unwrap();
        assert!(error <= job.cut.delta && segments > 0, "{row:?}");
    }
}

#[test]
fn the_search_finds_what_fit_finds_at_every_scan_angle() {
    // The search builds the finer table alone, stops it where ψ first turns back, and runs
    // the interference check on it: its verdict is `fit`'s, and so is its refusal once
    // `reason` has given a refused table `fit`'s own words.
    for job in [example("ball-screw"), trapezoidal_with_ring(20.8)] {
        let search = Search::new(&job);
        let (mut fits, mut refused) = (0, 0);
        for at in scan_angles(&job) {
            let expected = fit(&job, &tilted(&job, degrees(at))).err();
            let found = search.check(at, true);
            assert_eq!(found.is_none(), expected.is_none(), "{at}: {expected:?}");
            if let Some(why) = found {
                refused += 1;
                assert_eq!(Some(search.reason(at, why)), expected, "{at}");
            } else {
                fits += 1;
            }
        }
        assert!(fits > 0 && refused > 0, "{fits} {refused}");
    }
}
