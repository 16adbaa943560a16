//! `whirl angles`: the installation angles at which a job plans without interference, the
//! error and segments `plan` gets across them, and the angle with the largest margin, as a
//! table and a plot (`docs/planner.md`, "The installation-angle window"). Every file is
//! checked before anything is computed, and everything is computed before the plot is
//! written.

use crate::files::{self, Files};
use crate::terminal::say;
use anyhow::{Context, Result};
use clap::Args;
use std::path::PathBuf;
use std::process::ExitCode;
use whirl::config::job::Job;
use whirl::judge::svg::{self, Plot, Series};
use whirl::plan::angles::{
    self, show_deg, Row, Windows, EDGE_TOLERANCE_DEG, RANGE_DEG, SCAN_STEP_DEG,
};

/// Angles planned across each window, its edges included.
const PER_WINDOW: usize = 11;

/// `whirl angles`'s words.
#[derive(Args)]
pub(crate) struct AnglesArgs {
    /// The job file (TOML); its own installation angle, if it gives one, is left aside.
    job: PathBuf,
    /// Machine profile to plan for; default: the built-in simulator's.
    #[arg(long)]
    machine: Option<PathBuf>,
    /// Where to draw the max error and the segments across the window, with its edges and
    /// the angle of largest margin (SVG).
    #[arg(long)]
    svg: Option<PathBuf>,
}

/// Find the windows, plan across them, print the table, draw the plot.
pub(crate) fn run(args: AnglesArgs) -> Result<ExitCode> {
    Files::new()
        .output("--svg", args.svg.as_deref())
        .job(&args.job)
        .input("the machine profile (--machine)", args.machine.as_deref())
        .check()?;
    let machine = crate::load_machine(args.machine.as_deref())?;
    let job = Job::load(&args.job)?;
    let name = args.job.display();
    let found = angles::windows(&job).with_context(|| format!("{name}"))?;
    let (window, best) = found.best();
    // Each angle planned as `whirl plan` plans it, its nodes measured by the engine.
    let rows = angles::survey(&job, &found, PER_WINDOW, |at| {
        whirl::judge::refine::plan(at, &machine)
    });
    let plot = args
        .svg
        .as_ref()
        .map(|_| plots(&found, &rows, job.cut.delta));
    files::write_all(&[(args.svg.as_deref(), &plot.unwrap_or_default())])?;
    say!(
        "{name}: installation angles that plan without interference: {} (every {}° from 0° \
         to {}° scanned, edges bisected to {}°)",
        found.list(),
        SCAN_STEP_DEG,
        RANGE_DEG,
        EDGE_TOLERANCE_DEG
    )?;
    for w in &found.windows {
        for (side, edge) in [("below", &w.low), ("above", &w.high)] {
            if let Some((_, why)) = &edge.beyond {
                say!("{side} {}°: {why}", show_deg(edge.deg))?;
            }
        }
    }
    say!(
        "  {:>9}  {:>8}  {:>12}  {:>8}",
        "angle",
        "margin",
        "max error",
        "segments"
    )?;
    for row in &rows {
        let mark = if row.chosen { '*' } else { ' ' };
        let angle = format!("{}°", show_deg(row.deg));
        let margin = format!("{:.3}°", row.margin_deg);
        match &row.planned {
            Ok((error, segments)) => say!(
                "{mark} {angle:>9}  {margin:>8}  {:>9.4} mm  {segments:>8}",
                error
            )?,
            Err(why) => say!(
                "{mark} {angle:>9}  {margin:>8}  refused: {}",
                why.lines().next().unwrap_or_default()
            )?,
        }
    }
    say!(
        "* largest margin: {}°, {:.3}° from the nearer edge (Δ {} mm); a job that gives no \
         installation_angle_deg plans with it",
        show_deg(best),
        window.margin(best),
        job.cut.delta
    )?;
    if let Some(given) = job.tool.installation_angle_deg {
        say!("{}", own_angle(&found, given))?;
    }
    Ok(ExitCode::SUCCESS)
}

/// Where the job's own angle lies: in a window, with its margin, or outside every one, where
/// `plan` refuses it.
fn own_angle(found: &Windows, given: f64) -> String {
    let deg = show_deg(given);
    match found.holding(given) {
        Some(w) => format!(
            "the job's installation_angle_deg = {deg}° lies in {}°–{}°, {:.3}° from the \
             nearer edge",
            show_deg(w.low.deg),
            show_deg(w.high.deg),
            w.margin(given)
        ),
        None => format!(
            "the job's installation_angle_deg = {deg}° lies outside every window: `whirl \
             plan` refuses it; give an angle inside one, or none"
        ),
    }
}

/// The max error and the segments across the windows, one plot each, with each window's
/// edges and the chosen angle drawn upright.
fn plots(found: &Windows, rows: &[Row], delta: f64) -> String {
    let (_, best) = found.best();
    // Angle, max error, segments, where the job planned.
    let planned: Vec<(f64, f64, f64)> = rows
        .iter()
        .filter_map(|r| r.planned.as_ref().ok().map(|(e, s)| (r.deg, *e, *s as f64)))
        .collect();
    let plot = |title: &str, y_label: &str, pick: fn(&(f64, f64, f64)) -> f64, also: &[f64]| {
        let values: Vec<f64> = planned
            .iter()
            .map(pick)
            .chain(also.iter().copied())
            .collect();
        let (lo, hi) = match values.iter().copied().reduce(f64::min) {
            Some(lo) => (lo, values.iter().copied().fold(lo, f64::max)),
            None => (0.0, 1.0),
        };
        let mut series = Vec::new();
        for w in &found.windows {
            series.push(Series {
                label: format!("{y_label} planned"),
                colour: "steelblue",
                points: planned
                    .iter()
                    .filter(|p| (w.low.deg..=w.high.deg).contains(&p.0))
                    .map(|p| (p.0, pick(p)))
                    .collect(),
            });
            // The window's edges, joined across its top, with a foot outside each: the
            // angles beyond are refused.
            let foot = ((w.high.deg - w.low.deg) / 10.0).max(0.05);
            series.push(Series {
                label: format!("window {}°–{}°", show_deg(w.low.deg), show_deg(w.high.deg)),
                colour: "seagreen",
                points: vec![
                    (w.low.deg - foot, lo),
                    (w.low.deg, lo),
                    (w.low.deg, hi),
                    (w.high.deg, hi),
                    (w.high.deg, lo),
                    (w.high.deg + foot, lo),
                ],
            });
        }
        series.push(Series {
            label: format!("largest margin, {}°", show_deg(best)),
            colour: "crimson",
            points: vec![(best, lo), (best, hi)],
        });
        Plot {
            title: title.into(),
            x_label: "installation angle, degrees".into(),
            y_label: y_label.into(),
            series,
            equal_scale: false,
        }
    };
    let mut error = plot(
        "The plan's max error across the installation-angle window",
        "max error, mm",
        |p| p.1,
        &[delta],
    );
    let (first, last) = (&found.windows[0], &found.windows[found.windows.len() - 1]);
    error.series.push(Series {
        label: format!("Δ {delta} mm"),
        colour: "darkorange",
        points: vec![(first.low.deg, delta), (last.high.deg, delta)],
    });
    let segments = plot(
        "Linked segments across the installation-angle window",
        "segments",
        |p| p.2,
        &[],
    );
    svg::stack(&[error, segments])
}
