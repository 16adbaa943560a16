//! `whirl profile`: what whirl understood of a job's groove, to see before cutting
//! (`docs/profiles.md`, "Seeing the profile"): the standard form's dimensions and source, or
//! what the curve through the points is; lead, starts, hand and axial pitch; with `-o` the
//! axial section as a points file whirl reads back as the same groove, with `--svg` its plot.
//! Every file is checked before the job is read, and everything is computed before anything
//! is written.

use crate::files::{self, Files};
use crate::terminal::say;
use anyhow::{Context, Result};
use clap::Args;
use std::path::PathBuf;
use std::process::ExitCode;
use whirl::config::job::Job;
use whirl::judge::profile_view::{self, CSV_DECIMALS};

/// `whirl profile`'s words.
#[derive(Args)]
pub(crate) struct ProfileArgs {
    /// The job file (TOML).
    job: PathBuf,
    /// Where to write the groove's axial section at polar angle 0 over one axial pitch, as
    /// an axial points file (`rho,z`, mm): `section = "axial"` with it is the same groove.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Where to draw the axial section with its dimensions (SVG).
    #[arg(long)]
    svg: Option<PathBuf>,
}

/// Read the job, print what whirl understood, write the section and the plot.
pub(crate) fn run(args: ProfileArgs) -> Result<ExitCode> {
    Files::new()
        .output("-o", args.output.as_deref())
        .output("--svg", args.svg.as_deref())
        .job(&args.job)
        .check()?;
    let job = Job::load(&args.job)?;
    let name = args.job.display();
    let view = profile_view::view(&job).with_context(|| format!("{name}"))?;
    let csv = args.output.as_ref().map(|_| view.csv());
    let svg = args.svg.as_ref().map(|_| {
        view.svg(&format!(
            "{name}: axial section at polar angle 0, one pitch"
        ))
    });
    files::write_all(&[
        (args.output.as_deref(), &csv.unwrap_or_default()),
        (args.svg.as_deref(), &svg.unwrap_or_default()),
    ])?;
    say!("{name}:")?;
    let width = view.facts.iter().map(|f| f.name.chars().count()).max();
    for f in &view.facts {
        say!("  {:<w$}  {}", f.name, f.value, w = width.unwrap_or(0))?;
    }
    if let Some(path) = &args.output {
        say!(
            "{}: the axial section, {} points (rho,z, mm, {CSV_DECIMALS} decimals) over one \
             axial pitch",
            path.display(),
            view.section.points.len()
        )?;
    }
    if let Some(path) = &args.svg {
        say!("{}: the axial section drawn", path.display())?;
    }
    Ok(ExitCode::SUCCESS)
}
