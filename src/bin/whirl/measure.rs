//! `whirl measure`: a measured section of a cut part against its job's groove; with `--fit`
//! the tool it was really cut with, with `--correct` the job that cuts the target with that
//! tool. Every file is checked before anything is computed, and everything is computed (the
//! corrected job read back and planned) before anything is written (`docs/measure.md`).

use crate::files::{self, Files};
use crate::terminal::say;
use anyhow::{Context, Result};
use clap::Args;
use serde::Serialize;
use std::path::{Component, Path, PathBuf};
use std::process::ExitCode;
use whirl::config::job::Job;
use whirl::judge::fit::{self, Fit};
use whirl::judge::section::{self, Deviations, Frame, Plane, SectionTarget};

/// `whirl measure`'s words.
#[derive(Args)]
pub(crate) struct MeasureArgs {
    /// The job the part was cut by (TOML).
    job: PathBuf,
    /// The measured section: CSV points under a header that states their frame
    /// (docs/measure.md).
    section: PathBuf,
    /// States a key of the frame as the file's header would (section, angle_deg, z, units,
    /// columns, origin); repeatable; where the header states the key too, both must agree.
    #[arg(long = "frame", value_name = "KEY=VALUE")]
    frame: Vec<String>,
    /// Machine profile the part's program was planned for; default: the built-in simulator's.
    #[arg(long)]
    machine: Option<PathBuf>,
    /// The program that cut the part; default: the job planned for the machine.
    #[arg(long)]
    program: Option<PathBuf>,
    /// Where to draw the section: target, the Δ band, measured points and, with --fit, the
    /// fitted tool's section, deviations magnified (SVG).
    #[arg(long)]
    svg: Option<PathBuf>,
    /// Where to write the report (JSON): every point's deviation, the fit, the correction.
    #[arg(long)]
    report: Option<PathBuf>,
    /// Fit the ring radius, nose radius and installation angle the part was really cut
    /// with, with their standard errors.
    #[arg(long)]
    fit: bool,
    /// Write the job that cuts the target with the fitted tool to -o (implies --fit).
    #[arg(long, requires = "output")]
    correct: bool,
    /// Where --correct writes the corrected job.
    #[arg(short, long, requires = "correct")]
    output: Option<PathBuf>,
}

/// What `whirl measure --report` writes.
#[derive(Serialize)]
struct Report<'a> {
    section: String,
    frame: &'a Frame,
    delta_mm: f64,
    within_delta: bool,
    #[serde(flatten)]
    deviations: &'a Deviations,
    fit: Option<&'a Fit>,
    correction: Option<CorrectionReport>,
}

/// The corrected job, as the report states it.
#[derive(Serialize)]
struct CorrectionReport {
    job: String,
    segments: usize,
    max_error_mm: f64,
    cycle_time_s: f64,
}

pub(crate) fn run(args: MeasureArgs) -> Result<ExitCode> {
    Files::new()
        .output("-o", args.output.as_deref())
        .output("--svg", args.svg.as_deref())
        .output("--report", args.report.as_deref())
        .job(&args.job)
        .input("the measured section", Some(&args.section))
        .input("the machine profile (--machine)", args.machine.as_deref())
        .input("the program (--program)", args.program.as_deref())
        .check()?;
    let machine = crate::load_machine(args.machine.as_deref())?;
    if let Some(program) = &args.program {
        // Measured against the job given whatever it was planned from: said if that differs.
        let file = crate::provenance::MachineFile::read(
            args.machine.as_deref(),
            crate::runs::BUILTIN_SIM,
        )?;
        let text = std::fs::read_to_string(program)
            .with_context(|| format!("cannot read {}", program.display()))?;
        crate::provenance::report(&crate::provenance::check(
            program,
            &text,
            Some(&args.job),
            &machine,
            &file,
        ));
    }
    // An auto job measured at the feed it was cut at: its program's, or the fastest as
    // `whirl plan` finds it.
    let job = crate::fastest::resolve(Job::load(&args.job)?, &machine, args.program.as_deref())?;
    let name = args.section.display().to_string();
    let text =
        std::fs::read_to_string(&args.section).with_context(|| format!("cannot read {name}"))?;
    let measured = section::read(&text, &args.frame).with_context(|| name.clone())?;
    let delta = job.cut.delta;
    let target = SectionTarget::new(&job, measured.frame.plane);
    let deviations = target.deviations(&measured).with_context(|| name.clone())?;
    let fitted = if args.fit || args.correct {
        let program = match &args.program {
            Some(path) => Some(
                std::fs::read_to_string(path)
                    .with_context(|| format!("cannot read {}", path.display()))?,
            ),
            None => None,
        };
        let cut = fit::motion(&job, &machine, program.as_deref())?;
        Some(
            fit::fit(&job, &cut, &deviations.points)
                .with_context(|| format!("{name}: cannot fit the tool"))?,
        )
    } else {
        None
    };
    let correction = match (&fitted, &args.output) {
        (Some(fit), Some(output)) if args.correct => {
            let job_text = std::fs::read_to_string(&args.job)
                .with_context(|| format!("cannot read {}", args.job.display()))?;
            let points = moved_points(&args.job, &job_text, output)?;
            let note = note(&args.job, &name, fit);
            let c = fit::correct(
                &job,
                &job_text,
                fit,
                points.as_deref(),
                &note,
                output,
                &machine,
            )
            .with_context(|| format!("{name}: no corrected job written"))?;
            Some((output, c))
        }
        _ => None,
    };
    let within = deviations.max_overcut_mm <= delta && deviations.max_undercut_mm <= delta;
    let svg = args.svg.as_ref().map(|_| {
        target
            .plot(
                &deviations,
                fitted.as_ref().map(|f| f.predicted_mm.as_slice()),
                delta,
            )
            .to_svg()
    });
    let json = match &args.report {
        Some(_) => serde_json::to_string_pretty(&Report {
            section: name.clone(),
            frame: &measured.frame,
            delta_mm: delta,
            within_delta: within,
            deviations: &deviations,
            fit: fitted.as_ref(),
            correction: correction.as_ref().map(|(path, c)| CorrectionReport {
                job: path.display().to_string(),
                segments: c.report.segments,
                max_error_mm: c.report.max_error_mm,
                cycle_time_s: c.report.cycle_time_s,
            }),
        })?,
        None => String::new(),
    };
    let (svg, none) = (svg.unwrap_or_default(), String::new());
    files::write_all(&[
        (args.svg.as_deref(), &svg),
        (args.report.as_deref(), &json),
        (
            correction.as_ref().map(|(path, _)| path.as_path()),
            correction.as_ref().map_or(&none, |(_, c)| &c.text),
        ),
    ])?;
    print(&name, measured.frame.plane, &deviations, delta, within)?;
    if let Some(fit) = &fitted {
        print_fit(fit, delta)?;
    }
    if let Some((path, c)) = &correction {
        say!(
            "{}: the job with the fitted tool: {} segments, max error {:.4} mm of Δ {} mm \
             (`whirl plan {} --verify` measures its program)",
            path.display(),
            c.report.segments,
            c.report.max_error_mm,
            delta,
            path.display()
        )?;
    }
    Ok(if within {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(crate::BEYOND_DELTA)
    })
}

/// Every point's deviation, then the largest over- and undercut against Δ.
fn print(name: &str, plane: Plane, d: &Deviations, delta: f64, within: bool) -> Result<()> {
    let [a, b] = plane.axes();
    say!("{name}: {} points of {plane}", d.points.len())?;
    say!(
        "{:>6} {:>10} {:>10} {:>11} {:>11}",
        "line",
        a,
        b,
        "deviation",
        "in section"
    )?;
    for p in &d.points {
        say!(
            "{:>6} {:>10.4} {:>10.4} {:>+11.5} {:>+11.5}",
            p.line,
            p.at[0],
            p.at[1],
            p.deviation_mm,
            p.in_section_mm
        )?;
    }
    say!(
        "{name}: max overcut {:.5} mm (line {}), max undercut {:.5} mm (line {}) over {} points \
         (mm along the surface's normal; + undercut, − overcut); Δ {} mm: {}",
        d.max_overcut_mm,
        d.max_overcut_line,
        d.max_undercut_mm,
        d.max_undercut_line,
        d.points.len(),
        delta,
        if within { "within" } else { "BEYOND" }
    )?;
    Ok(())
}

/// The fitted tool, its uncertainty, and whether it is known well enough to plan with.
fn print_fit(fit: &Fit, delta: f64) -> Result<()> {
    say!(
        "fit over {} points: rms residual {:.5} mm, {} steps",
        fit.points,
        fit.rms_residual_mm,
        fit.steps
    )?;
    let rows = [
        ("ring radius", &fit.ring_radius_mm, " mm"),
        ("nose radius", &fit.nose_radius_mm, " mm"),
        ("installation angle", &fit.installation_angle_deg, "°"),
    ];
    for (what, e, unit) in rows {
        say!(
            "  {what:<19} {:>10.5}{unit} ± {:.5} (standard error; job {})",
            e.fitted,
            e.standard_error,
            short(e.job)
        )?;
    }
    if fit.determined(delta) {
        say!(
            "the fitted tool's effect on the groove is known to ±{:.5} mm (3σ), within Δ/{:.0}",
            fit.groove_uncertainty_mm,
            1.0 / fit::UNCERTAINTY_SHARE
        )?;
    } else {
        say!(
            "NOT DETERMINED: the fitted tool's effect on the groove is known only to ±{:.5} mm \
             (3σ), more than Δ/{:.0}; the points see least that {}",
            fit.groove_uncertainty_mm,
            1.0 / fit::UNCERTAINTY_SHARE,
            fit.weakest
        )?;
    }
    Ok(())
}

/// The comment that heads a corrected job: where it came from and what changed.
fn note(job: &Path, section: &str, fit: &Fit) -> String {
    let row = |key: &str, e: &fit::Estimate, unit: &str| {
        format!(
            "{key} {} -> {:.4}{unit} (standard error {:.5})",
            short(e.job),
            e.fitted,
            e.standard_error
        )
    };
    [
        format!(
            "Corrected by `whirl measure --correct` from {} and the section measured in {section}:",
            job.display()
        ),
        format!(
            "the tool the part was really cut with, fitted over {} points, is this job's tool.",
            fit.points
        ),
        row("ring_radius", &fit.ring_radius_mm, " mm"),
        row("nose_radius", &fit.nose_radius_mm, " mm"),
        row("installation_angle_deg", &fit.installation_angle_deg, "°"),
    ]
    .join("\n")
}

/// A job's value to five decimals, without trailing zeros (`60`, `17.65679`).
fn short(v: f64) -> String {
    let s = format!("{v:.5}");
    s.trim_end_matches('0').trim_end_matches('.').to_owned()
}

/// The profile points path a job written to `output` must name for the points `job` names
/// (`None`: the job names none, or both are in one folder, so the path stands).
fn moved_points(job: &Path, job_text: &str, output: &Path) -> Result<Option<String>> {
    let table: toml::Table =
        toml::from_str(job_text).with_context(|| format!("cannot read {}", job.display()))?;
    let Some(points) = table
        .get("groove")
        .and_then(|g| g.get("profile"))
        .and_then(|p| p.get("points"))
        .and_then(|p| p.as_str())
    else {
        return Ok(None);
    };
    let folder = |p: &Path| -> Result<PathBuf> {
        let dir = p
            .parent()
            .filter(|d| !d.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        dir.canonicalize()
            .with_context(|| format!("cannot find the folder of {}", p.display()))
    };
    let (from, to) = (folder(job)?, folder(output)?);
    if from == to {
        return Ok(None);
    }
    let file = from.join(points).canonicalize().with_context(|| {
        format!(
            "cannot find {points}, the profile points {} names",
            job.display()
        )
    })?;
    let relative = relative(&to, &file);
    relative
        .to_str()
        .map(|s| Some(s.to_owned()))
        .with_context(|| {
            format!(
                "{} is no UTF-8 path, which TOML cannot hold",
                relative.display()
            )
        })
}

/// The path from folder `from` to `to`, both absolute.
pub(crate) fn relative(from: &Path, to: &Path) -> PathBuf {
    let (a, b): (Vec<Component>, Vec<Component>) =
        (from.components().collect(), to.components().collect());
    let common = a.iter().zip(&b).take_while(|(x, y)| x == y).count();
    let mut path: PathBuf = a[common..].iter().map(|_| "..").collect();
    path.extend(&b[common..]);
    path
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_relative_path_climbs_to_the_common_folder_and_down() {
        assert_eq!(
            relative(Path::new("/a/b/c"), Path::new("/a/d/p.csv")),
            PathBuf::from("../../d/p.csv")
        );
        assert_eq!(
            relative(Path::new("/a"), Path::new("/a/d/p.csv")),
            PathBuf::from("d/p.csv")
        );
    }
}
