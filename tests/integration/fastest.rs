//! The fastest feed (`axial_feed = "auto"`, `whirl plan --fastest`): on every example it names
//! a feed, a machine time and the limit that binds, and a feed 5 % higher breaks that limit,
//! as this file computes it from the limit's definition (docs/planner.md, "The fastest
//! feed"), or measures beyond Δ by the engine. Bad input is refused naming file and key.

use crate::util;
use std::f64::consts::TAU;
use std::ffi::OsStr;
use std::path::Path;
use whirl::config::job::Job;
use whirl::config::machine::MachineProfile;
use whirl::judge::fastest::{fastest, fastest_within, Fastest};
use whirl::plan::feed::{FeedBound, Limit, MARGIN};
use whirl::plan::PlanError;

fn job(name: &str) -> Job {
    Job::load(&util::example(name)).unwrap()
}

fn machine(name: &str) -> MachineProfile {
    MachineProfile::load(&util::root().join(format!("machine-profiles/{name}.toml"))).unwrap()
}

fn auto(mut job: Job) -> Job {
    job.cut.auto_feed = true;
    job
}

/// `job` at `feed`, to plan as given.
fn at(job: &Job, feed: f64) -> Job {
    let mut job = job.clone();
    job.cut.axial_feed = feed;
    job.cut.auto_feed = false;
    job
}

/// The linked moves of a posted program, read from its text here: (characters of the line,
/// seconds, X mm, Z mm, C degrees at the move's end), after the first position all three
/// axes are known at. Inverse-time F is moves a minute (G93).
struct Linked {
    chars: usize,
    seconds: f64,
    to: [f64; 3],
    from: [f64; 3],
}

fn linked_moves(text: &str, x_diameter: bool) -> Vec<Linked> {
    let mut at = [f64::NAN; 3];
    let mut inverse = false;
    let mut moves = Vec::new();
    for line in text.lines() {
        let block = util::block(line);
        let mut to = at;
        let mut feed = None;
        for word in block.split_whitespace() {
            let (letter, value) = word.split_at(1);
            let value: f64 = match value.parse() {
                Ok(v) => v,
                Err(_) => continue,
            };
            match letter {
                "G" if value == 93.0 => inverse = true,
                "G" if value == 94.0 => inverse = false,
                "X" => to[0] = if x_diameter { value / 2.0 } else { value },
                "Z" => to[1] = value,
                "C" => to[2] = value,
                "F" => feed = Some(value),
                _ => {}
            }
        }
        if let (true, Some(per_minute), true) = (inverse, feed, at.iter().all(|v| v.is_finite())) {
            moves.push(Linked {
                chars: line.len(),
                seconds: 60.0 / per_minute,
                from: at,
                to,
            });
        }
        at = to;
    }
    moves
}

/// Whether a controller that makes one move ready every `making(i)` seconds, holding `ahead`
/// ready behind the one running (all of them at the start), ever waits: the queue as
/// docs/planner.md states it, simulated here on its own.
fn waits(moves: &[Linked], making: impl Fn(&Linked) -> f64, ahead: usize) -> bool {
    let mut starts = Vec::with_capacity(moves.len());
    let (mut ready, mut clock) = (0.0f64, 0.0f64);
    for (i, m) in moves.iter().enumerate() {
        if i >= ahead {
            ready = ready.max(starts[i - ahead]) + making(m);
        }
        if ready > clock * (1.0 + 1e-12) {
            return true;
        }
        starts.push(clock);
        clock += m.seconds;
    }
    false
}

/// The insert's largest chip, as docs/planner.md derives it, computed here from the program's
/// text: the largest step of the ring in the axial section between two hits, thinned by the
/// round nose's entry into the deepest stock a pass meets (sampled finely).
fn chip(job: &Job, moves: &[Linked], feed: f64) -> f64 {
    let p = job.p();
    let hit = 60.0 / (f64::from(job.tool.inserts) * job.cut.ring_rpm);
    let step = moves
        .iter()
        .map(|m| {
            let axial = p * (m.to[2] - m.from[2]).to_radians() + (m.to[1] - m.from[1]);
            (m.to[0] - m.from[0]).hypot(axial) / m.seconds * hit
        })
        .fold(0.0, f64::max);
    let tau = (TAU * feed / (TAU * p + feed)).abs();
    let (lo, hi) = job.profile.radius_range();
    let big_r = job.tool.ring_radius;
    use whirl::geometry::linkage::Whirling;
    let stock = (0..=1000)
        .map(|k| {
            let rho = lo + (hi - lo) * f64::from(k) / 1000.0;
            // The stock's depth at ρ, and the relative curvature of work and ring there: a
            // bore head cuts outward from the bore, its tip circle inside the nut's surface.
            let (depth, curvature) = match job.tool.whirling {
                Whirling::Internal => (hi - rho, 1.0 / rho - 1.0 / big_r),
                Whirling::External => (hi - rho, 1.0 / rho + 1.0 / big_r),
                Whirling::Bore => (rho - lo, 1.0 / big_r - 1.0 / rho),
            };
            rho * tau * (2.0 * depth * curvature.max(0.0)).sqrt()
        })
        .fold(0.0, f64::max);
    let cos = 1.0 - (stock / job.tool.nose_radius).min(1.0);
    step * (1.0 - cos * cos).sqrt()
}

/// That `bound`, found for `job` on `machine`, is broken at its feed, by its own definition.
fn breaks(job: &Job, machine: &MachineProfile, bound: &FeedBound, tolerance: f64) {
    let feed = bound.refused_feed_mm;
    let pitch = job.groove.lead / f64::from(job.groove.starts);
    if bound.limit == Limit::Pitch {
        assert!(feed >= pitch, "{feed} is below the pitch {pitch}");
        return;
    }
    // The program the search planned there: `whirl plan`'s, its nodes measured.
    let planned = whirl::judge::refine::plan(&at(job, feed), machine);
    match bound.limit {
        Limit::Budget => {
            // The error budget: Δ less the other shares leaves interpolation below its least.
            let Err(PlanError::Budget(e)) = planned else {
                panic!("{feed} mm is not refused by the budget: {planned:?}");
            };
            let left = e.delta - e.scallop - e.cusp - e.blend - e.rounding - e.concave;
            assert!(
                left < whirl::plan::budget::MIN_INTERPOLATION_SHARE * e.delta,
                "{e}"
            );
        }
        Limit::Axes => assert!(
            matches!(planned, Err(PlanError::Limits { .. })),
            "{planned:?}"
        ),
        Limit::Delta => match whirl::judge::refine::plan(&at(job, feed), machine) {
            // The engine measured every choice of nodes the planner tried beyond Δ: no
            // program is written at that feed.
            Err(PlanError::Nodes(e)) => {
                assert_eq!(tolerance, job.cut.delta, "{feed} mm: {e}");
                assert!(e.to_string().contains("measured within Δ"), "{e}");
            }
            planned => {
                let plan = planned.unwrap();
                let v = whirl::judge::verify::verify(
                    &at(job, feed),
                    plan.ring,
                    machine,
                    &plan.text,
                    false,
                )
                .unwrap();
                assert!(
                    v.max_overcut_mm.max(v.max_undercut_mm) > tolerance,
                    "{feed} mm measures {} / {} mm, within {tolerance}",
                    v.max_overcut_mm,
                    v.max_undercut_mm
                );
            }
        },
        // Where the rate bounds every move, the planner refuses a program with a move shorter
        // than a block.
        Limit::BlockRate if machine.block_rate().ahead.is_none() => {
            let Err(PlanError::BlockTime(e)) = planned else {
                panic!("{feed} mm is not refused for a move shorter than a block: {planned:?}");
            };
            assert!(e.seconds * e.per_second < 1.0, "{e}");
        }
        Limit::BlockRate | Limit::Link | Limit::Chip => {
            let plan = planned.unwrap();
            let moves = linked_moves(&plan.text, machine.x_diameter());
            match bound.limit {
                Limit::BlockRate => {
                    let rate = machine.block_rate();
                    let ahead = rate.ahead.expect("a rate sustained over blocks ahead");
                    let broken = waits(&moves, |_| 1.0 / rate.per_second, ahead);
                    assert!(broken, "{feed} mm keeps to {} blocks/s", rate.per_second);
                }
                Limit::Link => {
                    // grbl on a serial line, 8N1, a planner of 35 blocks.
                    let baud = match &machine.connection {
                        Some(whirl::config::connection::Connection::Serial(s)) => s.baud,
                        _ => 115_200,
                    };
                    let line = |m: &Linked| (m.chars + 1) as f64 * 10.0 / f64::from(baud);
                    assert!(waits(&moves, line, 34), "{feed} mm keeps the link ahead");
                }
                _ => {
                    let most = job.tool.max_chip_thickness.unwrap();
                    let h = chip(job, &moves, feed);
                    assert!(h > most, "{feed} mm: a chip of {h} mm, within {most}");
                }
            }
        }
        Limit::Pitch => unreachable!("checked above"),
    }
}

/// The fastest feed for an example's job on `machine`, its facts checked: a feed, a machine
/// time, what bounds it, the engine's measure within Δ, and the bound broken 5 % higher.
fn check(name: &str, machine: &MachineProfile) -> Fastest {
    let given = job(name);
    let found = fastest(&auto(given.clone()), machine).unwrap();
    let report = &found.plan.report;
    let bound = report.feed_bound.clone().expect("the bound");
    assert!(report.axial_feed_mm > 0.0 && report.axial_feed_mm == found.job.cut.axial_feed);
    // The machine time: at least the linked moves' own, as the program's F words give them.
    let cutting: f64 = linked_moves(&found.plan.text, machine.x_diameter())
        .iter()
        .map(|m| m.seconds)
        .sum();
    assert!(report.cycle_time_s >= cutting, "{name}");
    assert!(found.verification.within_delta, "{name}");
    assert_eq!(bound.refused_feed_mm, report.axial_feed_mm * MARGIN);
    breaks(&given, machine, &bound, given.cut.delta);
    let line = report.fastest_summary().unwrap();
    assert!(
        line.contains("machine time") && line.contains(bound.limit.name()),
        "{line}"
    );
    found
}

#[test]
fn every_example_gets_a_feed_a_machine_time_and_the_limit_five_percent_more_breaks() {
    let sim = machine("sim");
    for name in ["ball-screw", "double-start", "left-external", "trapezoidal"] {
        let found = check(name, &sim);
        // Each example's own feed leaves most of Δ to spare on this machine: faster is found.
        let own = whirl::judge::refine::plan(&job(name), &sim)
            .unwrap()
            .report
            .cycle_time_s;
        assert!(found.plan.report.cycle_time_s < own, "{name}");
    }
}

#[test]
fn on_every_profile_each_example_it_plans_names_its_bound_and_five_percent_more_breaks_it() {
    // Every example on every machine profile that plans it at its own feed, as `whirl stream`
    // plans an auto job: a feed, a machine time no shorter than its linked moves, the bound,
    // and the bound broken 5 % higher by its own definition. Every limit that binds is shown.
    let mut bound_by = std::collections::BTreeSet::new();
    for profile in [
        "grblhal-lathe",
        "linuxcnc-lathe",
        "modbus-plc",
        "canopen-drives",
    ] {
        let m = machine(profile);
        for name in ["ball-screw", "double-start", "left-external", "trapezoidal"] {
            let given = job(name);
            if whirl::judge::refine::plan(&given, &m).is_err() {
                continue;
            }
            let plan = whirl::judge::refine::plan(&auto(given.clone()), &m)
                .unwrap_or_else(|e| panic!("{name} on {profile}: {e}"));
            let report = &plan.report;
            let bound = report.feed_bound.clone().expect("the bound");
            assert_eq!(bound.refused_feed_mm, report.axial_feed_mm * MARGIN);
            let cutting: f64 = linked_moves(&plan.text, m.x_diameter())
                .iter()
                .map(|l| l.seconds)
                .sum();
            assert!(report.cycle_time_s >= cutting, "{name} on {profile}");
            breaks(&given, &m, &bound, given.cut.delta);
            eprintln!(
                "{name} on {profile}: {} mm, {:.1} s, {:?}",
                report.axial_feed_mm, report.cycle_time_s, bound.limit
            );
            bound_by.insert(format!("{:?}", bound.limit));
        }
    }
    assert!(!bound_by.is_empty());
}

#[test]
fn the_fastest_feeds_program_is_the_one_whirl_plan_writes_for_the_job_at_that_feed() {
    // One program: what the search returns is what the planning path every command uses
    // writes for the auto job, and for the job given that feed.
    let sim = machine("sim");
    let given = job("left-external");
    let found = fastest(&auto(given.clone()), &sim).unwrap();
    let feed = found.job.cut.axial_feed;
    let at_feed = whirl::judge::refine::plan(&at(&given, feed), &sim).unwrap();
    assert_eq!(at_feed.text, found.plan.text);
    let auto_plan = whirl::judge::refine::plan(&auto(given), &sim).unwrap();
    assert_eq!(auto_plan.text, found.plan.text);
    assert_eq!(auto_plan.report.feed_bound, found.plan.report.feed_bound);
}

#[test]
fn on_a_plc_every_move_keeps_to_its_segment_rate() {
    // A PLC that just takes the segments of each example's own program: its rate one over
    // that program's shortest move (and a millionth, for the rounding of the inverse). The
    // fastest feed keeps every linked move at least one segment of it long, and 5 % more
    // breaks what it names.
    for name in ["left-external", "trapezoidal"] {
        let given = job(name);
        let mut plc = machine("modbus-plc");
        let own = whirl::judge::refine::plan(&given, &plc).unwrap();
        let shortest = linked_moves(&own.text, false)
            .iter()
            .map(|m| m.seconds)
            .fold(f64::INFINITY, f64::min);
        let rate = 1.000_001 / shortest;
        plc.max_block_rate = Some(rate);
        let found = check(name, &plc);
        let moves = linked_moves(&found.plan.text, false);
        assert!(moves.iter().all(|m| m.seconds * rate >= 1.0), "{name}");
    }
}

#[test]
fn an_inserts_chip_limit_binds_where_the_chip_reaches_it() {
    // The chip at the example's own feed, as the insert's limit: the feed cannot go 5 % past
    // it, and the chip limit is what stops it (the budget allows four times the feed).
    let sim = machine("sim");
    let mut given = job("double-start");
    let plan = whirl::judge::refine::plan(&given, &sim).unwrap();
    let h = chip(
        &given,
        &linked_moves(&plan.text, false),
        given.cut.axial_feed,
    );
    given.tool.max_chip_thickness = Some(h);
    let found = fastest(&auto(given.clone()), &sim).unwrap();
    let bound = found.plan.report.feed_bound.clone().unwrap();
    assert_eq!(bound.limit, Limit::Chip, "{}", bound.why);
    breaks(&given, &sim, &bound, given.cut.delta);
}

#[test]
fn measured_to_a_tolerance_below_delta_the_engine_binds() {
    // A 6 mm stretch of the double-start groove. Held to 95 % of what the engine measures of
    // the program at the planner's fastest feed, that feed is refused by the engine, and the
    // search goes on below it with every program measured: the engine, not the planner,
    // stops the feed, and 5 % more measures beyond.
    let sim = machine("sim");
    let mut given = job("double-start");
    given.groove.length = 6.0;
    let planner = fastest(&auto(given.clone()), &sim).unwrap().verification;
    let tolerance = 0.95 * planner.max_overcut_mm.max(planner.max_undercut_mm);
    let found = fastest_within(&auto(given.clone()), &sim, tolerance).unwrap();
    let v = &found.verification;
    assert!(v.max_overcut_mm <= tolerance && v.max_undercut_mm <= tolerance);
    let bound = found.plan.report.feed_bound.clone().unwrap();
    assert_eq!(bound.limit, Limit::Delta, "{}", bound.why);
    breaks(&given, &sim, &bound, tolerance);
}

/// `whirl plan` of `job` with `args`: (success, stdout, stderr).
fn plan_cli(job: &Path, dir: &Path, args: &[&str]) -> (bool, String, String) {
    let (out, report) = (dir.join("p.nc"), dir.join("r.json"));
    let mut all: Vec<&OsStr> = vec![
        OsStr::new("plan"),
        job.as_os_str(),
        OsStr::new("-o"),
        out.as_os_str(),
        OsStr::new("--report"),
        report.as_os_str(),
    ];
    all.extend(args.iter().map(OsStr::new));
    let o = util::whirl(&all);
    (
        o.status.success(),
        String::from_utf8_lossy(&o.stdout).into(),
        String::from_utf8_lossy(&o.stderr).into(),
    )
}

#[test]
fn whirl_plan_fastest_says_feed_time_and_limit_in_one_line_and_reports_them() {
    let dir = tempfile::tempdir().unwrap();
    let (ok, out, err) = plan_cli(&util::example("trapezoidal"), dir.path(), &["--fastest"]);
    assert!(ok, "{err}");
    let line: Vec<&str> = out
        .lines()
        .filter(|l| l.starts_with("fastest feed"))
        .collect();
    assert_eq!(line.len(), 1, "{out}");
    assert!(
        line[0].contains("machine time") && line[0].contains("bound by"),
        "{out}"
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("r.json")).unwrap()).unwrap();
    let feed = report["axial_feed_mm"].as_f64().unwrap();
    assert!(report["feed_bound"]["limit"].is_string(), "{report}");
    // (JSON's decimals read back to within a unit in the last place.)
    let refused = report["feed_bound"]["refused_feed_mm"].as_f64().unwrap();
    assert!(
        (refused / (feed * MARGIN) - 1.0).abs() < 1e-12,
        "{refused} {feed}"
    );
    // The program cuts at that feed: Z's advance over C's turn across the linked moves.
    let moves = linked_moves(
        &std::fs::read_to_string(dir.path().join("p.nc")).unwrap(),
        false,
    );
    let (first, last) = (moves.first().unwrap(), moves.last().unwrap());
    let cut = 360.0 * (last.to[1] - first.from[1]) / (last.to[2] - first.from[2]);
    assert!((cut / feed - 1.0).abs() < 1e-5, "{cut} {feed}");
    // The job's own feed: no line, no bound.
    let (ok, out, _) = plan_cli(&util::example("trapezoidal"), dir.path(), &[]);
    assert!(ok && !out.contains("fastest feed"), "{out}");
}

#[test]
fn an_auto_job_plans_and_its_program_verifies_against_it() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(util::example("trapezoidal"))
        .unwrap()
        .replace("axial_feed = 0.05", "axial_feed = \"auto\"");
    let job = util::write(dir.path(), "job.toml", &text);
    let (ok, out, err) = plan_cli(&job, dir.path(), &[]);
    assert!(ok && out.contains("fastest feed"), "{out}{err}");
    let program = dir.path().join("p.nc");
    let report = dir.path().join("v.json");
    let o = util::whirl(&[
        OsStr::new("verify"),
        program.as_os_str(),
        OsStr::new("--job"),
        job.as_os_str(),
        OsStr::new("--report"),
        report.as_os_str(),
    ]);
    let said = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success() && said.contains("within"), "{said}");
}

/// `whirl plan` must refuse, write nothing, and say `what` of `file`.
fn refused(job: &Path, dir: &Path, args: &[&str], what: &[&str]) {
    let (ok, out, err) = plan_cli(job, dir, args);
    assert!(!ok, "{out}");
    assert!(!dir.join("p.nc").exists() && !dir.join("r.json").exists());
    assert!(
        err.starts_with("error: ") && !err.contains("panicked"),
        "{err}"
    );
    for w in what {
        assert!(err.contains(w), "{w:?} not in: {err}");
    }
}

#[test]
fn a_feed_that_is_neither_a_number_nor_auto_is_refused_naming_file_line_and_key() {
    for (feed, why) in [
        ("\"fast\"", "\"fast\""),
        ("-0.1", "positive"),
        ("0", "positive"),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let text = std::fs::read_to_string(util::example("trapezoidal"))
            .unwrap()
            .replace("axial_feed = 0.05", &format!("axial_feed = {feed}"));
        let job = util::write(dir.path(), "job.toml", &text);
        // The example's axial_feed is on its line 26.
        refused(
            &job,
            dir.path(),
            &[],
            &["job.toml", "line 26", "cut.axial_feed", why],
        );
    }
}

#[test]
fn a_chip_limit_below_zero_is_refused_naming_its_key() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(util::example("trapezoidal"))
        .unwrap()
        .replace("inserts = 4", "inserts = 4\nmax_chip_thickness = -0.1");
    let job = util::write(dir.path(), "job.toml", &text);
    refused(
        &job,
        dir.path(),
        &[],
        &["tool.max_chip_thickness", "positive"],
    );
}

#[test]
fn a_block_rate_of_zero_in_a_profile_is_refused_naming_file_and_key() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(util::root().join("machine-profiles/sim.toml")).unwrap();
    let profile = util::write(
        dir.path(),
        "plc.toml",
        &format!("max_block_rate = 0\n{text}"),
    );
    let profile = profile.to_str().unwrap().to_owned();
    refused(
        &util::example("trapezoidal"),
        dir.path(),
        &["--fastest", "--machine", &profile],
        &["plc.toml", "max_block_rate", "above zero"],
    );
}

/// The trapezoidal example, 4 mm of it, its feed `feed`, written to `dir`.
fn short_trapezoidal(dir: &Path, feed: &str) -> std::path::PathBuf {
    let text = std::fs::read_to_string(util::example("trapezoidal"))
        .unwrap()
        .replace("axial_feed = 0.05", &format!("axial_feed = {feed}"))
        .replace("length = 40.0", "length = 4.0");
    util::write(dir, "job.toml", &text)
}

#[test]
fn a_dry_run_of_an_auto_job_sends_the_program_whirl_plan_writes_for_it() {
    let dir = tempfile::tempdir().unwrap();
    let job = short_trapezoidal(dir.path(), "\"auto\"");
    let (ok, out, err) = plan_cli(&job, dir.path(), &[]);
    assert!(ok && out.contains("fastest feed"), "{out}{err}");
    let program = std::fs::read_to_string(dir.path().join("p.nc")).unwrap();
    let (code, r, log) = util::dry_run(&job, dir.path(), &[]);
    assert_eq!(code, Some(0), "{r:#}");
    let sent: Vec<String> = log
        .records
        .iter()
        .filter_map(|r| match &r.event {
            whirl::log::Event::Sent { text, .. } => Some(text.clone()),
            _ => None,
        })
        .collect();
    // The blocks whirl plan writes, its provenance header aside (the file's alone: a job
    // run at once keeps its provenance in its record), each numbered from its own line.
    let blocks = |lines: Vec<&str>| -> Vec<String> {
        lines
            .into_iter()
            .filter(|l| !l.contains("(whirl provenance: "))
            .map(|l| util::block(l).to_owned())
            .collect()
    };
    let written: Vec<&str> = program.lines().collect();
    assert_eq!(
        blocks(sent.iter().map(String::as_str).collect()),
        blocks(written)
    );
}

#[test]
fn an_auto_job_given_a_program_without_linked_moves_is_refused_before_anything_is_written() {
    // `whirl verify` and `whirl dry-run --program` measure an auto job at the feed its program
    // cuts at, read from its linked moves: a program with none gives no feed.
    let dir = tempfile::tempdir().unwrap();
    let job = short_trapezoidal(dir.path(), "\"auto\"");
    let program = util::write(dir.path(), "rapid.nc", "G21\nG90\nG0 X10 Z5\nM2\n");
    let report = dir.path().join("v.json");
    let log = dir.path().join("exec.jsonl");
    for args in [
        vec![
            OsStr::new("verify"),
            program.as_os_str(),
            OsStr::new("--job"),
            job.as_os_str(),
            OsStr::new("--report"),
            report.as_os_str(),
        ],
        vec![
            OsStr::new("dry-run"),
            job.as_os_str(),
            OsStr::new("--program"),
            program.as_os_str(),
            OsStr::new("--report"),
            report.as_os_str(),
            OsStr::new("--log"),
            log.as_os_str(),
        ],
    ] {
        let o = util::whirl(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?}");
        assert!(
            err.contains("rapid.nc")
                && err.contains("axial_feed is \"auto\"")
                && err.contains("no linked moves"),
            "{err}"
        );
        assert!(!report.exists() && !log.exists(), "{args:?}");
    }
}
