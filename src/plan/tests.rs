//! The planner's refusals of an absurd Δ and of concave stretches, and planning a dense
//! profile.

use super::*;
use crate::config::testing::{example, machine};
use crate::geometry::profile::points::{self, Row, Section};
use std::f64::consts::PI;

/// The double-start example (radii 26 to 34 mm, lead 60 mm) with Δ = `delta`, bypassing the
/// job file's checks as a program building its own job could.
fn double_start(delta: f64) -> Job {
    let mut job = example("double-start");
    job.cut.delta = delta;
    job
}

#[test]
fn a_delta_finer_than_the_post_can_write_is_refused_at_once_naming_the_bound() {
    // The post writes at most 6 decimals and keeps each axis's rounding below Δ/60, so on a
    // controller with 64-bit positions nothing finer than 60 × 0.5·10⁻⁶ = 0.00003 mm can be
    // planned. (Δ = 10⁻¹² used to be refused by the number format after the whole table: half
    // a minute and 1.27 GB.)
    let linuxcnc = machine("linuxcnc-lathe");
    for delta in [1e-12, 1e-6, 2.9e-5] {
        let e = plan(&double_start(delta), &linuxcnc).unwrap_err();
        let PlanError::Delta { value, bound, .. } = &e else {
            panic!("Δ = {delta}: expected the Δ refusal, got {e}");
        };
        assert_eq!(*value, delta);
        assert!((bound - 3e-5).abs() < 1e-12, "{e}");
        let text = e.to_string();
        assert!(
            text.contains("cut.delta") && text.contains("0.00003 mm"),
            "{text}"
        );
    }
    assert!(
        plan(&double_start(1e-12), &linuxcnc)
            .unwrap_err()
            .to_string()
            .contains("cut.delta = 1e-12 mm"),
        "the value as written"
    );
    // Just above it the post can write the numbers: whatever refuses it, it is not Δ's size.
    let e = plan(&double_start(3.1e-5), &linuxcnc).unwrap_err();
    assert!(!matches!(e, PlanError::Delta { .. }), "{e}");
    // And a sane Δ plans, within it.
    let planned = plan(&double_start(0.005), &linuxcnc).unwrap();
    assert!(planned.report.max_error_mm <= 0.005);
}

#[test]
fn a_delta_finer_than_a_32_bit_controller_holds_is_refused_at_once() {
    // The simulator holds positions as 32-bit floats: over this 24 mm groove at 0.1 mm a turn
    // C reaches at least 88 200°, held to ±0.0039° (0.00065 mm at 9.5 mm a radian), which
    // alone leaves interpolation less than 20 % of Δ = 0.0001 mm.
    let sim = MachineProfile::builtin_sim().unwrap();
    let e = plan(&double_start(1e-4), &sim).unwrap_err();
    let PlanError::Delta { bound, .. } = &e else {
        panic!("expected the Δ refusal, got {e}");
    };
    assert!(*bound > 1e-4 && *bound < 1e-3, "{e}");
    let text = e.to_string();
    assert!(
        text.contains("cut.delta = 0.0001 mm") && text.contains("88200°"),
        "{text}"
    );
    // The same Δ on a controller with 64-bit positions is not refused for its size.
    let e = plan(&double_start(1e-4), &machine("linuxcnc-lathe"));
    assert!(!matches!(e, Err(PlanError::Delta { .. })), "{e:?}");
}

#[test]
fn a_delta_beyond_the_groove_depth_is_refused_at_once() {
    // Radii from 26 to 34 mm: an allowable error above 8 mm bounds nothing. Δ = 10³⁰⁸ used to
    // plan, reporting "max error 5e306 mm" on a title line no controller could receive.
    let sim = MachineProfile::builtin_sim().unwrap();
    for delta in [1e308, 8.5] {
        let e = plan(&double_start(delta), &sim).unwrap_err();
        let PlanError::Delta { bound, .. } = &e else {
            panic!("Δ = {delta}: expected the Δ refusal, got {e}");
        };
        assert!((bound - 8.0).abs() < 1e-3, "{e}");
        let text = e.to_string();
        assert!(
            text.contains("cut.delta") && text.contains("depth"),
            "{text}"
        );
        assert!(text.len() < 300, "{text}");
    }
    let planned = plan(&double_start(7.9), &sim).unwrap();
    assert!(planned.report.max_error_mm <= 7.9);
}

#[test]
fn a_million_point_profile_plans_within_its_bound() {
    // ρ = 30 − 4·cos 2φ over one period of the double-start groove, a million points 0.1 µm
    // apart, exact and written to 10 decimals (the outlier check used to take hours over
    // these: it rebuilt a spline through all points for every zig-zag).
    let n = 1_000_000;
    for decimals in [None, Some(10)] {
        let rows: Vec<Row> = (0..n)
            .map(|k| {
                let phi = PI * k as f64 / n as f64;
                let rho = 30.0 - 4.0 * (2.0 * phi).cos();
                let written = |v: f64| match decimals {
                    Some(d) => format!("{v:.d$}").parse::<f64>().unwrap(),
                    None => v,
                };
                Row {
                    line: k + 2,
                    a: written(rho * phi.cos()),
                    b: written(rho * phi.sin()),
                }
            })
            .collect();
        let mut job = example("double-start");
        job.profile = points::profile(&rows, Section::Transverse, false, job.p(), 2)
            .unwrap_or_else(|e| panic!("{decimals:?}: {e}"));
        let planned = plan(&job, &MachineProfile::builtin_sim().unwrap())
            .unwrap_or_else(|e| panic!("{decimals:?}: {e}"));
        let report = &planned.report;
        assert!(report.segments > 0);
        assert!(
            report.max_error_mm <= job.cut.delta,
            "{decimals:?}: bound {} beyond Δ",
            report.max_error_mm
        );
    }
}

/// `n` points over half a period of the double-start groove, ρ = 30 − 4·cos 2φ for
/// 0 ≤ φ ≤ 90°, written to `decimals`.
fn half_period(n: usize, decimals: usize) -> Vec<Row> {
    (0..n)
        .map(|k| {
            let phi = PI / 2.0 * k as f64 / (n - 1) as f64;
            let rho = 30.0 - 4.0 * (2.0 * phi).cos();
            let written = |v: f64| format!("{v:.decimals$}").parse::<f64>().unwrap();
            Row {
                line: k + 2,
                a: written(rho * phi.cos()),
                b: written(rho * phi.sin()),
            }
        })
        .collect()
}

#[test]
fn points_written_to_four_decimals_plan_as_the_exact_curve_does() {
    // 20 000 points 2.5 µm apart at 4 decimals: rounding moves them by up to 0.07 µm, and a
    // spline through them would bend with the rounding far tighter than the groove (or the
    // nose). Fitted within the rounding, they plan as the same points at 12 decimals do: the
    // same installation angle (the issue's ±0.05°), segments within 5 %, the fit's distance
    // from the points counted in the budget.
    let sim = MachineProfile::builtin_sim().unwrap();
    let mut job = example("double-start");
    job.tool.installation_angle_deg = None;
    let planned = |decimals: usize| {
        let mut job = job.clone();
        job.profile = points::profile(
            &half_period(20_000, decimals),
            Section::Transverse,
            true,
            job.p(),
            2,
        )
        .unwrap();
        let fit = job.profile.fit();
        (
            plan(&job, &sim).unwrap_or_else(|e| panic!("{decimals}: {e}")),
            fit,
        )
    };
    let (exact, _) = planned(12);
    let (rounded, fit) = planned(4);
    let angle = |p: &Plan| p.report.installation_angle_deg;
    assert!((angle(&rounded) - angle(&exact)).abs() <= 0.05);
    let segments = |p: &Plan| p.report.segments as f64;
    assert!((segments(&rounded) / segments(&exact) - 1.0).abs() <= 0.05);
    // Half the 4th decimal in x and y, and for mirrored points up to twice the turn that puts
    // on the mirror line through the crest point: about three times as much at most.
    let fit = fit.expect("rounded points are fitted");
    let half_unit = 0.00005f64.hypot(0.00005);
    assert!(
        fit.band >= half_unit && fit.band <= 3.01 * half_unit,
        "{fit:?}"
    );
    assert!(fit.deviation > 0.0 && fit.deviation <= fit.band);
    assert_eq!(rounded.report.fit_mm, fit.deviation);
    assert!(rounded.report.max_error_mm <= rounded.report.delta_mm);
}

#[test]
fn kinks_too_shallow_to_matter_are_counted_not_refused() {
    // A nose a hair wider than the trapezoid's root fillet is across the groove (its radius
    // on the helical surface) cannot follow the fillet, but what it leaves is far below
    // Δ/100: the job plans, and what the stretches leave is part of the bound.
    let sim = MachineProfile::builtin_sim().unwrap();
    let mut job = example("trapezoidal");
    let fillet = job
        .profile
        .concave_stretches(job.p(), 2.0 * job.groove.profile.root_radius.unwrap())
        .iter()
        .map(|c| c.min_radius)
        .fold(f64::INFINITY, f64::min);
    job.tool.nose_radius = fillet * (1.0 + 1e-4);
    let stretches = job.profile.concave_stretches(job.p(), job.tool.nose_radius);
    assert!(!stretches.is_empty(), "stretches tighter than the nose");
    let deepest = stretches.iter().map(|c| c.depth_left).fold(0.0, f64::max);
    assert!(
        deepest > 0.0 && deepest <= CONCAVE_SHARE * job.cut.delta,
        "{deepest}"
    );
    // The rooms interpolation gets, as the node choice sees them, with the scallop and cusp
    // at each sample.
    type Seen = (segment::Rooms, Vec<f64>);
    struct Rooms(std::cell::RefCell<Option<Seen>>);
    impl segment::NodeChoice for Rooms {
        fn choose(
            &self,
            problem: &segment::Problem,
        ) -> Result<segment::Choice, segment::NodeError> {
            let cusps = problem.cusps();
            let left = (0..cusps.len())
                .map(|i| problem.scallops.near(i) + cusps[i])
                .collect();
            *self.0.borrow_mut() = Some((problem.rooms(), left));
            segment::Estimated.choose(problem)
        }
    }
    let rooms = Rooms(Default::default());
    let report = plan_with(&job, &sim, &rooms).unwrap().report;
    assert_eq!(report.concave_mm, deepest);
    assert!(report.max_error_mm <= report.delta_mm);
    // The material is left wherever the stretches are, so every profile point's undercut room
    // leaves it out, besides the scallop and cusp there, of what the overcut room allows.
    let (rooms, left) = rooms.0.into_inner().unwrap();
    for ((over, under), left) in rooms.overcut.iter().zip(&rooms.undercut).zip(&left) {
        let out = over - under - left;
        assert!((out - deepest).abs() <= 1e-15, "{over} − {under} − {left}");
    }
    // A nose that fits has none to count.
    assert_eq!(
        plan(&example("trapezoidal"), &sim)
            .unwrap()
            .report
            .concave_mm,
        0.0
    );
}

#[test]
fn a_groove_tighter_than_the_nose_is_refused_with_the_tool_to_change() {
    // The ball groove's radius is 3.429 mm; its exact profile has no rounding to blame.
    let mut job = example("ball-screw");
    job.tool.nose_radius = 4.0;
    let e = plan(&job, &MachineProfile::builtin_sim().unwrap()).unwrap_err();
    assert!(
        matches!(&e, PlanError::Concave { points: false, .. }),
        "{e}"
    );
    assert!(e.to_string().contains("use a smaller nose radius"), "{e}");
    assert!(!e.to_string().contains("fit_tolerance"), "{e}");
}

/// LinuxCNC's parabolic blends at the corners of a program's linked moves, worked out here
/// from the program alone as `docs/planner.md` ("LinuxCNC's blends") states the model: for
/// each corner between two linked moves with no other motion between them, the predicted
/// corner cut (mm), how far the blend reaches into each move (degrees of C), half the
/// shorter move's turn (degrees), and the text line of the move out of the corner.
fn blend_corners(
    program: &Program,
    lines: &[usize],
    machine: &MachineProfile,
) -> Vec<(f64, f64, f64, usize)> {
    use crate::config::machine::Axis;
    use crate::program::{Move, Position};
    let (ax, az, ac) = (
        machine.accel(Axis::X),
        machine.accel(Axis::Z),
        machine.accel(Axis::C),
    );
    // (ΔX, ΔZ, ΔC, seconds) of each linked move; `None` for any other motion.
    let mut moves: Vec<(Option<[f64; 4]>, usize)> = Vec::new();
    for step in program.steps(Position::UNKNOWN) {
        match *step.action {
            Move::Linked { minutes, .. } => {
                let (from, to) = (step.from, step.to);
                let d = |a: Option<f64>, b: Option<f64>| b.unwrap() - a.unwrap();
                moves.push((
                    Some([
                        d(from.x, to.x),
                        d(from.z, to.z),
                        d(from.c, to.c),
                        minutes * 60.0,
                    ]),
                    lines[step.index],
                ));
            }
            Move::Rapid { .. } | Move::Feed { .. } => moves.push((None, lines[step.index])),
            _ => {}
        }
    }
    let accel = |[dx, dz, dc, _]: [f64; 4]| {
        let mut a = ac;
        if dx != 0.0 {
            a = a.min(ax * dc.abs() / dx.abs());
        }
        if dz != 0.0 {
            a = a.min(az * dc.abs() / dz.abs());
        }
        a / 2.0
    };
    moves
        .windows(2)
        .filter_map(|w| {
            let (Some(m1), Some(m2)) = (w[0].0, w[1].0) else {
                return None;
            };
            // Each move blends at its own rate: the faster sets the corner.
            let rate = (m1[2].abs() / m1[3]).max(m2[2].abs() / m2[3]);
            let (a1, a2) = (accel(m1), accel(m2));
            let a = a1.min(a2);
            // How far into C the blend is where C passes the corner: (a/2)·(T/2)² with both
            // moves at the smaller acceleration, or, the second accelerating faster than the
            // first decelerates, where the parabolas (a₁/2)(T − t)² and (a₂/2)t² meet.
            let depth = (rate * rate / (8.0 * a))
                .max(rate * rate * a2 / (2.0 * a1 * (a1.sqrt() + a2.sqrt()).powi(2)));
            let kink = (m2[0] / m2[2] - m1[0] / m1[2]).hypot(m2[1] / m2[2] - m1[1] / m1[2]);
            let half = m1[2].abs().min(m2[2].abs()) / 2.0;
            Some((depth * kink, rate * rate / (2.0 * a), half, w[1].1))
        })
        .collect()
}

#[test]
fn a_linuxcnc_plan_slows_its_linked_moves_until_every_blend_is_within_the_share() {
    use crate::post::gcode::parse::read_program_with_lines;
    use crate::program::timing::cycle_time_s;
    use crate::program::Move;
    let linuxcnc = machine("linuxcnc-lathe");
    let job = example("double-start");
    let planned = plan(&job, &linuxcnc).unwrap();
    let report = &planned.report;
    let share = report.blend_mm;
    assert_eq!(share, 0.001, "blend_tolerance_mm, under Δ/5");
    // The corners of the program as posted (X written as diameters, F rounded down), read back.
    let (posted, lines) = read_program_with_lines(&planned.text, linuxcnc.x_diameter()).unwrap();
    let capped = blend_corners(&posted, &lines, &linuxcnc);
    assert_eq!(capped.len(), report.segments - 1);
    for &(deviation, reach, half, line) in &capped {
        assert!(deviation <= share, "line {line}: {deviation} mm");
        assert!(reach <= half, "line {line}: reaches {reach}° of {half}°");
    }
    // The cap works on the corners as posted; F is written rounded down, up to 10⁻⁵ slower.
    let largest = capped.iter().map(|c| c.0).fold(0.0, f64::max);
    assert!(
        largest <= report.blend_predicted_mm && largest > (1.0 - 1e-4) * report.blend_predicted_mm,
        "{largest} mm, reported {} mm",
        report.blend_predicted_mm
    );
    // At the job's own pace, C at 360°·workpiece_rpm a minute throughout.
    let deg_per_min = 360.0 * job.cut.workpiece_rpm;
    let paced = |posted: &Program| {
        let mut paced = posted.clone();
        let mut c = None;
        for m in &mut paced.moves {
            if let Some(target) = m.target() {
                if let (Move::Linked { minutes, .. }, Some(from), Some(to)) = (&mut *m, c, target.c)
                {
                    *minutes = (to - from) / deg_per_min;
                }
                c = target.c.or(c);
            }
        }
        paced
    };
    // So paced, the program the lead ran on a simulated LinuxCNC 2.9, planned as the planner
    // planned it then (the lead angle at the mean radius, nodes on the table), has the corners
    // the lead predicted over its first 1500 lines: at most 3.12 µm (3.19 µm measured), three
    // times the share.
    let mut then = job.clone();
    let (rho_min, rho_max) = job.profile.radius_range();
    let mean_lead = (job.p().abs() / ((rho_min + rho_max) / 2.0)).atan();
    then.tool.installation_angle_deg = Some(mean_lead.to_degrees());
    let then = plan_with(&then, &linuxcnc, &segment::Interpolating).unwrap();
    let (then_posted, then_lines) =
        read_program_with_lines(&then.text, linuxcnc.x_diameter()).unwrap();
    let first_lines = blend_corners(&paced(&then_posted), &then_lines, &linuxcnc)
        .iter()
        .filter(|c| c.3 <= 1500)
        .map(|c| c.0)
        .fold(0.0, f64::max);
    assert!((first_lines - 0.00312).abs() < 0.00002, "{first_lines} mm");
    let paced = paced(&posted);
    // The slowing is what the cycle time gained.
    assert!(report.blend_slowed_moves > 0 && report.blend_slowed_moves <= report.segments);
    let before = cycle_time_s(&paced, &linuxcnc);
    assert!(report.blend_time_added_s > 0.0);
    assert!(
        (report.cycle_time_s - report.blend_time_added_s - before).abs() < 1e-4 * before,
        "{} s − {} s against {before} s",
        report.cycle_time_s,
        report.blend_time_added_s
    );
    let summary = report.blending_summary().unwrap();
    assert!(
        summary.contains("0.001 mm") && summary.contains("capping the blend speed"),
        "{summary}"
    );
    // grblHAL follows the polyline: nothing is slowed, nothing said.
    let sim = plan(&job, &MachineProfile::builtin_sim().unwrap()).unwrap();
    assert_eq!(sim.report.blend_slowed_moves, 0);
    assert_eq!(sim.report.blend_predicted_mm, 0.0);
    assert_eq!(sim.report.blend_time_added_s, 0.0);
    assert_eq!(sim.report.blending_summary(), None);
}

#[test]
fn the_budgets_nodes_need_fewer_spans_than_interpolating_ones_within_their_bound() {
    // A best approximation splits a span's error over both sides of X(ψ) and each side's room
    // is Δ less only what adds to it where it is; nodes on the table kept a span's error on
    // one side, within Δ less every share at its largest. Engine-free, `plan::plan`'s choice.
    let sim = MachineProfile::builtin_sim().unwrap();
    for name in ["ball-screw", "double-start", "left-external", "trapezoidal"] {
        let job = example(name);
        let counted = segment::AgainstInterpolation {
            choice: segment::Estimated,
            interpolating: Default::default(),
        };
        let report = plan_with(&job, &sim, &counted).unwrap().report;
        let before = counted.interpolating.get();
        assert!(
            report.nodes_per_period < before,
            "{name}: {report:?}, {before} before"
        );
        assert!(report.max_error_mm <= report.delta_mm, "{name}: {report:?}");
        assert_eq!(report.measured, None);
    }
}

#[test]
fn a_points_profile_tighter_than_the_nose_names_the_fit_tolerance_too() {
    // The double-start's root is a concave arc of about 26 mm radius across the groove; a
    // nose of 40 mm cannot follow it, whatever the points' decimals.
    let mut job = example("double-start");
    job.tool.nose_radius = 40.0;
    let e = plan(&job, &MachineProfile::builtin_sim().unwrap()).unwrap_err();
    assert!(matches!(&e, PlanError::Concave { points: true, .. }), "{e}");
    let text = e.to_string();
    assert!(text.contains("use a smaller nose radius"), "{text}");
    assert!(text.contains("[groove.profile] fit_tolerance"), "{text}");
}
