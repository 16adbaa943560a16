//! The fastest feed's limits and its search: when a controller waits for blocks or lines,
//! the chip an insert takes, what refuses a feed, and the bracket and bisection.

use super::*;
use crate::config::testing::{example, machine, machine_text};
use crate::plan::segment::{Choice, Estimated, NodeError, Problem};
use crate::program::Move;
use std::f64::consts::{PI, TAU};

/// The linked moves' durations of a plan as posted, s.
fn runs(plan: &Plan, machine: &MachineProfile) -> Vec<f64> {
    crate::post::gcode::read_program(&plan.text, machine.x_diameter())
        .unwrap()
        .moves
        .iter()
        .filter_map(|m| match m {
            Move::Linked { minutes, .. } => Some(minutes * 60.0),
            _ => None,
        })
        .collect()
}

#[test]
fn a_controller_that_keeps_up_never_waits() {
    assert_eq!(first_wait(&[0.02; 500], |_| 0.01, 9), None);
    assert_eq!(first_wait(&[0.02; 500], |_| 0.01, 1), None);
}

#[test]
fn moves_faster_than_their_making_run_out_the_buffer_where_the_sums_say() {
    // Moves of d = 5 ms made one every m = 10 ms, nine ready at the start. Move 9 is ready at
    // m once move 0 has left the buffer (at 0), move 9 + k at (k + 1)·m; move i starts at
    // i·d unless it waits. So the first wait is the first i with (i − 8)·m > i·d: i > 16.
    assert_eq!(first_wait(&[0.005; 100], |_| 0.010, 9), Some(17));
}

#[test]
fn one_short_move_among_long_ones_is_covered_by_the_blocks_ahead() {
    let mut runs = vec![0.02; 200];
    runs[50] = 0.002;
    assert_eq!(first_wait(&runs, |_| 0.01, 9), None);
    // With one block ahead, the move after the short one is made while the short one runs,
    // in 10 ms of its 2 ms.
    assert_eq!(first_wait(&runs, |_| 0.01, 1), Some(51));
}

#[test]
fn a_round_nose_enters_the_stock_at_the_angle_its_depth_gives() {
    assert_eq!(sin_entry(0.0), 0.0);
    assert!((sin_entry(0.5) - 3f64.sqrt() / 2.0).abs() < 1e-15);
    assert_eq!(sin_entry(1.0), 1.0);
    assert_eq!(sin_entry(3.0), 1.0);
}

#[test]
fn the_stock_a_pass_meets_is_deepest_at_the_root_as_its_formula_says() {
    // Double-start: ρ from 26 to 34 mm, R = 60 mm internal. ρ·√(2(ρ_max − ρ)(1/ρ − 1/R)) falls
    // from 15.3 at the root to 0 at the crest, so the stock is the root's, a pass spacing τ
    // apart: τ·ρ_min·√(2(ρ_max − ρ_min)(1/ρ_min − 1/R)).
    let job = example("double-start");
    let (lo, hi) = job.profile.radius_range();
    for feed in [0.05, 0.1, 0.4] {
        let p = 60.0 / TAU;
        let tau = TAU * feed / (TAU * p + feed);
        let expected = tau * lo * (2.0 * (hi - lo) * (1.0 / lo - 1.0 / 60.0)).sqrt();
        let got = stock(&job, feed);
        assert!(
            (got / expected - 1.0).abs() < 1e-12,
            "{feed}: {got} {expected}"
        );
    }
    // An external ring's curvature adds to the groove's: more stock.
    let mut external = job.clone();
    external.tool.whirling = Whirling::External;
    assert!(stock(&external, 0.1) > stock(&job, 0.1));
}

#[test]
fn the_chip_is_the_step_between_hits_thinned_by_the_noses_entry() {
    // One linked move: X 0.3 mm, Z 0.01 mm and C 1° in 0.1 s. Between two hits (4 inserts at
    // 1500 rpm: 10 ms apart) every point of the ring moves a tenth of (ΔX, p·ΔC + ΔZ) in the
    // axial section.
    let job = example("double-start");
    let p = 60.0 / TAU;
    let program = Program {
        moves: vec![
            Move::Rapid {
                x: Some(30.0),
                z: Some(-10.0),
                c: Some(5.0),
            },
            Move::Linked {
                x: 30.3,
                z: -9.99,
                c: 6.0,
                minutes: 0.1 / 60.0,
            },
        ],
    };
    let step = 0.3f64.hypot(p * PI / 180.0 + 0.01) / 0.1 * 0.01;
    let feed = 0.2;
    let expected = step * sin_entry(stock(&job, feed) / 1.2);
    let got = chip_thickness(&job, &program, feed);
    assert!((got / expected - 1.0).abs() < 1e-12, "{got} {expected}");
    // A higher feed: more stock, a thicker chip from the same moves.
    assert!(chip_thickness(&job, &program, 2.0 * feed) > got);
}

#[test]
fn a_programs_feed_is_read_back_from_its_linked_moves() {
    let job = example("trapezoidal");
    let sim = machine("sim");
    let plan = crate::plan::plan(&job, &sim).unwrap();
    let posted = crate::post::gcode::read_program(&plan.text, false).unwrap();
    let feed = program_feed(&posted).unwrap();
    // Z and C are written to 4 and 4 decimals over some 860 turns.
    assert!((feed / job.cut.axial_feed - 1.0).abs() < 1e-6, "{feed}");
    assert_eq!(program_feed(&Program { moves: vec![] }), None);
}

#[test]
fn a_feed_of_the_pitch_is_refused_without_planning() {
    let job = example("trapezoidal");
    // Lead 14 mm, 2 starts: a pitch of 7 mm.
    let Outcome::TooFast(bound) =
        evaluate(&job, &machine("sim"), 7.0, &Estimated, &Resolved::default()).unwrap()
    else {
        panic!("a feed of a whole pitch passes");
    };
    assert_eq!(bound.limit, Limit::Pitch);
    assert_eq!(bound.refused_feed_mm, 7.0);
    assert!(bound.why.contains("7 mm"), "{}", bound.why);
}

#[test]
fn a_feed_whose_scallop_eats_the_budget_is_refused_as_too_fast() {
    // Double-start: its scallop passes 80 % of Δ below 0.6 mm a revolution.
    let job = example("double-start");
    let Outcome::TooFast(bound) =
        evaluate(&job, &machine("sim"), 0.6, &Estimated, &Resolved::default()).unwrap()
    else {
        panic!("0.6 mm a revolution plans");
    };
    assert_eq!(bound.limit, Limit::Budget);
    assert!(bound.why.contains("feed scallop"), "{}", bound.why);
}

#[test]
fn a_move_shorter_than_a_block_breaks_the_block_rate_on_a_plc() {
    // On the Modbus PLC every move must last one block, and the planner refuses a program
    // with a shorter one: on a controller a little slower than one block for the program's
    // shortest move, the feed is too fast for the block rate, naming the move's line; a little
    // faster takes it.
    let job = example("left-external");
    let mut plc = machine("modbus-plc");
    let plan = crate::plan::plan(&job, &plc).unwrap();
    let shortest = runs(&plan, &plc).into_iter().fold(f64::INFINITY, f64::min);
    plc.max_block_rate = Some(0.999 / shortest);
    let feed = job.cut.axial_feed;
    let Outcome::TooFast(bound) =
        evaluate(&job, &plc, feed, &Estimated, &Resolved::default()).unwrap()
    else {
        panic!("a move shorter than a block passes");
    };
    assert_eq!(bound.limit, Limit::BlockRate);
    assert!(
        bound.why.contains("line ") && bound.why.contains("which every move must last"),
        "{}",
        bound.why
    );
    plc.max_block_rate = Some(1.001 / shortest);
    assert!(matches!(
        evaluate(&job, &plc, feed, &Estimated, &Resolved::default()).unwrap(),
        Outcome::Passes(_)
    ));
}

#[test]
fn a_slow_serial_line_starves_grbl_and_a_fast_one_does_not() {
    // Lines of some 45 characters take 1.5 s at 300 baud, against moves of tens of ms.
    let job = example("double-start");
    let serial = |baud: u32| {
        let text = format!(
            "{}\n[connection]\ntransport = \"serial\"\nport = \"/dev/ttyACM0\"\nbaud = {baud}\n",
            machine_text("sim")
        );
        MachineProfile::from_toml(&text, "sim").unwrap()
    };
    let slow = serial(300);
    let plan = crate::plan::plan(&job, &slow).unwrap();
    let (limit, why) = sustained(&job, &slow, &plan, job.cut.axial_feed)
        .unwrap()
        .unwrap();
    assert_eq!(limit, Limit::Link);
    assert!(why.contains("300 baud") && why.contains("line"), "{why}");
    assert_eq!(
        sustained(&job, &serial(115_200), &plan, job.cut.axial_feed).unwrap(),
        None
    );
}

#[test]
fn a_chip_thicker_than_the_insert_takes_is_refused() {
    let mut job = example("double-start");
    let sim = machine("sim");
    let plan = crate::plan::plan(&job, &sim).unwrap();
    let posted = crate::post::gcode::read_program(&plan.text, false).unwrap();
    let chip = chip_thickness(&job, &posted, job.cut.axial_feed);
    job.tool.max_chip_thickness = Some(chip * 0.99);
    let (limit, why) = sustained(&job, &sim, &plan, job.cut.axial_feed)
        .unwrap()
        .unwrap();
    assert_eq!(limit, Limit::Chip);
    assert!(why.contains("tool.max_chip_thickness"), "{why}");
    job.tool.max_chip_thickness = Some(chip * 1.01);
    assert_eq!(
        sustained(&job, &sim, &plan, job.cut.axial_feed).unwrap(),
        None
    );
}

/// A search over a made-up limit: feeds for which `passes` holds pass, the others are too
/// fast (the budget's, for the sake of a name); the feeds tried, in order.
fn made_up(start: f64, passes: impl Fn(f64) -> bool) -> (Result<Found<f64>, PlanError>, Vec<f64>) {
    let mut tried = Vec::new();
    let found = search(start, None, |feed| {
        tried.push(feed);
        Ok::<_, PlanError>(if passes(feed) {
            Outcome::Passes(feed)
        } else {
            Outcome::TooFast(FeedBound {
                limit: Limit::Budget,
                refused_feed_mm: feed,
                why: String::new(),
            })
        })
    });
    (found, tried)
}

#[test]
fn the_search_finds_a_threshold_to_half_a_percent_and_five_percent_more_is_refused() {
    // From below, at it, and from above within the sixteenth the search halves down to.
    for start in [0.001, 0.3, 4.0] {
        let (found, _) = made_up(start, |f| f <= 0.3);
        let found = found.unwrap();
        assert!(
            found.feed <= 0.3 && found.feed >= 0.3 / RESOLUTION,
            "{start}: {found:?}"
        );
        assert_eq!(found.passed, found.feed);
        assert_eq!(found.bound.refused_feed_mm, found.feed * MARGIN);
        assert!(found.nearest_refused.refused_feed_mm <= found.feed * RESOLUTION);
    }
}

#[test]
fn a_feed_five_percent_up_that_passes_sends_the_search_on() {
    // Feeds pass up to 0.2 and again in a sliver about 0.21, which the bisection between 0.2
    // and 0.4 never lands in: 5 % above 0.2 does, and the search goes on from there.
    let (found, tried) = made_up(0.1, |f| f <= 0.2 || (0.2095..=0.2105).contains(&f));
    let found = found.unwrap();
    assert!(found.feed >= 0.2095, "{found:?}, tried {tried:?}");
    assert!(found.feed * MARGIN > 0.2105);
}

#[test]
fn a_limit_that_refuses_every_feed_is_named() {
    let (found, tried) = made_up(0.1, |_| false);
    let Err(PlanError::Feed(FeedError::TooFast { bound })) = found else {
        panic!("{found:?}");
    };
    // Halved down to a sixteenth of the start.
    assert_eq!(tried, [0.1, 0.05, 0.025, 0.0125, 0.00625]);
    assert_eq!(bound.refused_feed_mm, 0.00625);
}

#[test]
fn too_slow_feeds_are_left_upwards_and_a_gap_between_is_refused() {
    let slow = || PlanError::CPrecision {
        c_max: 1e6,
        resolution_deg: 0.06,
        error_mm: 0.01,
        delta: 0.005,
    };
    // Too slow below 0.05, too fast above 0.3.
    let verdict = |feed: f64, low: f64| {
        Ok::<_, PlanError>(if feed < low {
            Outcome::TooSlow(slow())
        } else if feed > 0.3 {
            Outcome::TooFast(FeedBound {
                limit: Limit::Budget,
                refused_feed_mm: feed,
                why: String::new(),
            })
        } else {
            Outcome::Passes(())
        })
    };
    let found = search(0.01, None, |f| verdict(f, 0.05)).unwrap();
    assert!(found.feed <= 0.3 && found.feed >= 0.3 / RESOLUTION);
    // Too slow below 0.5 and too fast above 0.3: nothing plans.
    let gap = search(0.01, None, |f| verdict(f, 0.5)).unwrap_err();
    assert!(
        matches!(gap, PlanError::Feed(FeedError::Between { .. })),
        "{gap}"
    );
    assert!(gap.to_string().contains("no feed plans this job"), "{gap}");
}

#[test]
fn an_auto_job_plans_at_the_feed_its_report_names() {
    let mut job = example("trapezoidal");
    let sim = machine("sim");
    job.cut.auto_feed = true;
    let plan = crate::plan::plan(&job, &sim).unwrap();
    let bound = plan.report.feed_bound.clone().expect("a bound");
    let feed = plan.report.axial_feed_mm;
    assert_eq!(bound.refused_feed_mm, feed * MARGIN);
    // The same program as the job at that feed, which plans no faster than that.
    let given = crate::plan::plan(&at(&job, feed), &sim).unwrap();
    assert_eq!(given.text, plan.text);
    assert_eq!(given.report.feed_bound, None);
    assert_eq!(given.report.axial_feed_mm, feed);
    assert!(plan
        .report
        .fastest_summary()
        .unwrap()
        .contains("machine time"));
    assert_eq!(given.report.fastest_summary(), None);
}

/// A node choice that finds no nodes within Δ above `most` mm a revolution, and the budget's
/// below: a measured choice whose engine refuses the faster feeds.
struct RefusesAbove {
    most: f64,
}

impl NodeChoice for RefusesAbove {
    fn choose(&self, problem: &Problem) -> Result<Choice, NodeError> {
        if problem.spec.feed > self.most {
            return Err(NodeError(format!("beyond Δ at {}", problem.spec.feed)));
        }
        Estimated.choose(problem)
    }
}

#[test]
fn a_feed_at_which_the_choice_finds_no_nodes_within_delta_is_refused_by_delta() {
    // The double-start groove's budget plans up to some 0.43 mm a revolution; a choice that
    // finds no nodes above 0.2 mm is what stops the feed there, and its words are the why.
    // (4 mm of the groove: the limit is the same along it.)
    let mut job = example("double-start");
    job.groove.length = 4.0;
    let sim = machine("sim");
    let choice = RefusesAbove { most: 0.2 };
    let Outcome::TooFast(bound) =
        evaluate(&job, &sim, 0.25, &choice, &Resolved::default()).unwrap()
    else {
        panic!("0.25 mm a revolution plans");
    };
    assert_eq!(bound.limit, Limit::Delta);
    assert_eq!(bound.why, "beyond Δ at 0.25");
    assert!(matches!(
        evaluate(&job, &sim, 0.15, &choice, &Resolved::default()).unwrap(),
        Outcome::Passes(_)
    ));
    let mut auto = job.clone();
    auto.cut.auto_feed = true;
    let found = fastest(&auto, &sim, &choice).unwrap();
    let feed = found.job.cut.axial_feed;
    assert!(feed <= 0.2 && feed * MARGIN > 0.2, "{feed}");
    assert_eq!(found.plan.report.feed_bound.unwrap().limit, Limit::Delta);
    // The program is the one the choice plans for the job at that feed.
    let given = crate::plan::plan_with(&at(&job, feed), &sim, &choice).unwrap();
    assert_eq!(given.text, found.plan.text);
}

#[test]
fn a_delta_no_feed_can_meet_is_refused_as_it_is_and_one_a_faster_feed_lifts_is_searched() {
    let sim = machine("sim");
    // Finer than the post can write (6 decimals on the LinuxCNC profile): the same at any
    // feed, so the search refuses it at once with the planner's own words.
    let mut fine = example("double-start");
    fine.cut.delta = 1e-6;
    fine.cut.auto_feed = true;
    let e = fastest(&fine, &machine("linuxcnc-lathe"), &Estimated).unwrap_err();
    assert!(
        matches!(
            e,
            PlanError::Delta {
                higher_feed_lifts: false,
                ..
            }
        ),
        "{e}"
    );
    // Beyond the groove's depth: likewise.
    let mut coarse = example("double-start");
    coarse.cut.delta = 9.0;
    coarse.cut.auto_feed = true;
    let e = fastest(&coarse, &sim, &Estimated).unwrap_err();
    assert!(
        matches!(
            e,
            PlanError::Delta {
                higher_feed_lifts: false,
                ..
            }
        ),
        "{e}"
    );
    // Below what the simulator's 32-bit C holds after 88 200° at 0.1 mm a turn: a faster
    // feed turns C less far, so the job's feed is too slow, not its Δ impossible.
    let mut slow = example("double-start");
    slow.cut.delta = 1e-4;
    let Outcome::TooSlow(e) = evaluate(&slow, &sim, 0.1, &Estimated, &Resolved::default()).unwrap()
    else {
        panic!("0.1 mm a turn at Δ = 0.1 µm is refused for C's precision");
    };
    assert!(
        matches!(
            e,
            PlanError::Delta {
                higher_feed_lifts: true,
                ..
            }
        ),
        "{e}"
    );
}
