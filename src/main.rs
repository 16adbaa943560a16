//! The `whirl` command line: thin glue over the library.

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use whirl::job::Job;
use whirl::machine::MachineProfile;

#[derive(Parser)]
#[command(
    name = "whirl",
    version,
    about = "Plan and post thread-whirling programs"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Plan a job: write the machine program and, optionally, a JSON report.
    Plan {
        /// The job file (TOML).
        job: PathBuf,
        /// Machine profile (TOML); default: the built-in simulator's, machine-profiles/sim.toml.
        #[arg(long)]
        machine: Option<PathBuf>,
        /// Where to write the program.
        #[arg(short, long)]
        output: PathBuf,
        /// Where to write the report (JSON).
        #[arg(long)]
        report: Option<PathBuf>,
    },
}

fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "warn".into()),
        )
        .with_writer(std::io::stderr)
        .init();
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Plan {
            job,
            machine,
            output,
            report,
        } => {
            let machine = load_machine(machine.as_deref())?;
            let job = Job::load(&job)?;
            let plan = whirl::plan::plan(&job, &machine)
                .with_context(|| format!("cannot plan {}", job_name(&job)))?;
            let json = serde_json::to_string_pretty(&plan.report)?;
            // Everything is computed; only now is anything written.
            write_all(&[(Some(&output), &plan.text), (report.as_deref(), &json)])?;
            let r = &plan.report;
            println!(
                "{}: {} segments ({} per period), max error {:.4} mm of Δ {:.4} mm \
                 (interpolation {:.4}, scallop {:.4}, cusp {:.4}), cycle {:.1} s",
                output.display(),
                r.segments,
                r.nodes_per_period,
                r.max_error_mm,
                r.delta_mm,
                r.interp_error_mm,
                r.scallop_mm,
                r.cusp_mm,
                r.cycle_time_s
            );
            Ok(())
        }
    }
}

fn job_name(job: &Job) -> String {
    format!(
        "the {}-start groove of lead {} mm",
        job.groove.starts, job.groove.lead
    )
}

fn load_machine(path: Option<&Path>) -> Result<MachineProfile> {
    match path {
        Some(p) => Ok(MachineProfile::load(p)?),
        None => Ok(MachineProfile::builtin_sim()?),
    }
}

/// Write each file through a temporary sibling and rename, so that a failure part-way leaves
/// no half-written program behind.
fn write_all(files: &[(Option<&Path>, &String)]) -> Result<()> {
    let mut staged = Vec::new();
    for (path, text) in files {
        let Some(path) = path else { continue };
        let mut tmp = path.as_os_str().to_owned();
        tmp.push(".whirl-tmp");
        let tmp = PathBuf::from(tmp);
        if let Err(e) = std::fs::write(&tmp, text) {
            let _ = std::fs::remove_file(&tmp);
            for (t, _) in &staged {
                let _ = std::fs::remove_file(t);
            }
            return Err(e).with_context(|| format!("cannot write {}", path.display()));
        }
        staged.push((tmp, path.to_path_buf()));
    }
    for (tmp, path) in staged {
        std::fs::rename(&tmp, &path).with_context(|| format!("cannot write {}", path.display()))?;
    }
    Ok(())
}
