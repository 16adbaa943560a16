//! A program's provenance on the command line (docs/streaming.md#provenance): `whirl plan`
//! writes it at the top of the program, `whirl stream` refuses a program whose job or
//! machine profile has changed since, that was planned for another machine, or that carries
//! none, before anything is opened; `dry-run --program`, `verify` and `measure --program`
//! say so and go on.
//!
//! The header's job and machine-profile paths are relative to the program's folder, so a
//! program finds its job from any working directory, and a folder of jobs and programs
//! moved as a whole keeps them.

use std::path::{Component, Path, PathBuf};

use anyhow::{bail, Context, Result};
use whirl::config::machine::MachineProfile;
use whirl::config::provenance::{Provenance, Source, BUILT_IN};
use whirl::plan::Plan;
use whirl::records::{ProvenanceCheck, RunProvenance};

use crate::measure::relative;

/// The flag that streams a program whatever its provenance says.
pub(crate) const OVERRIDE: &str = "--no-provenance-check";

/// A machine profile as a run read it: where (`built-in:…` for the built-in one) and its
/// bytes.
pub(crate) struct MachineFile {
    /// The path as given (`None`: the built-in profile).
    pub(crate) given: Option<PathBuf>,
    /// Its bytes.
    pub(crate) bytes: Vec<u8>,
    /// The built-in profile's repository path, when it is that one.
    builtin: &'static str,
}

impl MachineFile {
    /// The profile `path` names, or the built-in `builtin` (its path and text).
    pub(crate) fn read(path: Option<&Path>, builtin: (&'static str, &'static str)) -> Result<Self> {
        let bytes = match path {
            Some(path) => std::fs::read(path)
                .with_context(|| format!("cannot read machine profile {}", path.display()))?,
            None => builtin.1.as_bytes().to_vec(),
        };
        let repository = builtin.0.trim_end_matches(" (built in)");
        Ok(MachineFile {
            given: path.map(Path::to_owned),
            bytes,
            builtin: repository,
        })
    }

    /// How a refusal names it: its path, or the built-in profile.
    fn shown(&self) -> String {
        match &self.given {
            Some(path) => path.display().to_string(),
            None => format!("the built-in {}", self.builtin),
        }
    }
}

/// The provenance of `plan`, planned from the job at `job` for `machine` (read from
/// `file`); paths relative to `folder` (a real path): the program's folder, or for a
/// program planned and run at once, the working directory.
pub(crate) fn of_plan(
    job: &Path,
    machine: &MachineProfile,
    file: &MachineFile,
    folder: &Path,
    plan: &Plan,
    fastest: bool,
) -> Result<Provenance> {
    let job_bytes = std::fs::read(job).with_context(|| format!("cannot read {}", job.display()))?;
    let points = match crate::files::points_file(job) {
        Some(points) => Some(Source::of(
            recorded(folder, &points)?,
            &std::fs::read(&points).with_context(|| format!("cannot read {}", points.display()))?,
        )),
        None => None,
    };
    let machine_path = match &file.given {
        Some(path) => recorded(folder, path)?,
        None => format!("{BUILT_IN}{}", file.builtin),
    };
    Ok(Provenance {
        version: env!("CARGO_PKG_VERSION").into(),
        job: Source::of(recorded(folder, job)?, &job_bytes),
        points,
        machine_name: machine.name.clone(),
        machine: Source::of(machine_path, &file.bytes),
        delta_mm: plan.report.delta_mm,
        installation_angle_deg: plan.report.installation_angle_deg,
        axial_feed_mm: plan.report.axial_feed_mm,
        fastest,
    })
}

/// `plan`'s text with `provenance`'s header at its top (its report's line count with it).
pub(crate) fn stamp(
    plan: &mut Plan,
    machine: &MachineProfile,
    provenance: &Provenance,
) -> Result<()> {
    plan.text = whirl::post::gcode::header::stamp(
        &plan.text,
        machine.dialect,
        machine.max_line_length,
        provenance,
    )
    .context("cannot write the program's provenance header")?;
    plan.report.lines = plan.text.lines().count();
    Ok(())
}

/// The working directory, its real path.
pub(crate) fn here() -> Result<PathBuf> {
    std::env::current_dir()
        .and_then(|d| d.canonicalize())
        .context("cannot find the working directory")
}

/// The real folder `file` is (or will be) in.
pub(crate) fn real_folder(file: &Path) -> Result<PathBuf> {
    let folder = match file.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    folder
        .canonicalize()
        .with_context(|| format!("cannot find the folder of {}", file.display()))
}

/// How the header names `file`: its path from `folder` (a real path).
fn recorded(folder: &Path, file: &Path) -> Result<String> {
    let real = file
        .canonicalize()
        .with_context(|| format!("cannot find {}", file.display()))?;
    let path = relative(folder, &real);
    path.to_str().map(str::to_owned).with_context(|| {
        format!(
            "{} is no UTF-8 path, which the program's provenance header cannot hold",
            file.display()
        )
    })
}

/// Where a path of the header of `program` leads, as the working directory reaches it.
fn resolve(program: &Path, recorded: &str) -> PathBuf {
    let recorded = Path::new(recorded);
    if recorded.is_absolute() {
        return recorded.to_owned();
    }
    let Ok(folder) = real_folder(program) else {
        return program.parent().unwrap_or(Path::new("")).join(recorded);
    };
    // The folder is real (no links) and the recorded path climbs first, so its ".." may
    // be taken off the folder's end.
    let mut path = folder;
    for part in recorded.components() {
        match part {
            Component::ParentDir => {
                path.pop();
            }
            Component::CurDir => {}
            other => path.push(other),
        }
    }
    match std::env::current_dir().and_then(|d| d.canonicalize()) {
        Ok(here) => relative(&here, &path),
        Err(_) => path,
    }
}

/// What the check of a program's provenance found: nothing (it matches), or why it would
/// be refused.
pub(crate) struct Checked {
    /// The program's header, if it has one that reads.
    pub(crate) header: Option<Provenance>,
    /// Why the program does not match, in words; empty if it does.
    pub(crate) findings: Vec<String>,
    /// The command that plans it again.
    pub(crate) plan_again: String,
    /// The program has no provenance header at all (written by hand, or by another tool).
    bare: bool,
}

impl Checked {
    /// The run record's provenance: matched, or `otherwise` with the findings.
    pub(crate) fn record(&self, otherwise: ProvenanceCheck) -> RunProvenance {
        let matched = self.findings.is_empty();
        RunProvenance {
            header: self.header.clone(),
            check: if matched {
                ProvenanceCheck::Matched
            } else {
                otherwise
            },
            finding: (!matched).then(|| self.findings.join("; ")),
        }
    }
}

/// Checks the provenance of `program` (its text `text`) against the job it names (or
/// `given_job`, the job a dry run or a verification is given) and the machine profile
/// `machine` (read from `file`) the run is given.
pub(crate) fn check(
    program: &Path,
    text: &str,
    given_job: Option<&Path>,
    machine: &MachineProfile,
    file: &MachineFile,
) -> Checked {
    let name = program.display();
    let machine_flag = file
        .given
        .as_ref()
        .map_or(String::new(), |m| format!(" --machine {}", m.display()));
    let header = match whirl::post::gcode::header::read(text) {
        Ok(Some(header)) => header,
        Ok(None) => {
            return Checked {
                header: None,
                findings: vec![format!(
                    "{name} carries no provenance (no `(whirl provenance: …)` header at its \
                     top): whirl cannot tell which job and machine profile it was planned \
                     from, nor whether they changed since"
                )],
                plan_again: format!("whirl plan JOB.toml{machine_flag} -o {name}"),
                bare: true,
            }
        }
        Err(error) => {
            return Checked {
                header: None,
                findings: vec![format!(
                    "{name}: its provenance header is damaged ({error}): whirl cannot tell \
                     which job and machine profile it was planned from"
                )],
                plan_again: format!("whirl plan JOB.toml{machine_flag} -o {name}"),
                bare: false,
            }
        }
    };
    let job = given_job.map_or_else(|| resolve(program, &header.job.path), Path::to_owned);
    let fastest = if header.fastest { " --fastest" } else { "" };
    let plan_again = format!(
        "whirl plan {}{machine_flag}{fastest} -o {name}",
        job.display()
    );
    let mut findings = Vec::new();
    let given = file.shown();
    let now = whirl::config::provenance::sha256_hex(&file.bytes);
    if header.machine_name != machine.name {
        findings.push(format!(
            "{name} was planned for the machine \"{}\" ({}), and this run is given \"{}\" \
             ({given})",
            header.machine_name,
            shown_machine(program, &header.machine.path),
            machine.name
        ));
    } else if header.machine.sha256 != now {
        findings.push(format!(
            "the machine profile \"{}\" has changed since {name} was planned: {given} has \
             sha256 {}, the program was planned with {} ({})",
            machine.name,
            short(&now),
            short(&header.machine.sha256),
            shown_machine(program, &header.machine.path)
        ));
    }
    match std::fs::read(&job) {
        Err(error) => findings.push(format!(
            "the job {} that {name} was planned from cannot be read ({error}): whirl \
             cannot tell whether it changed",
            job.display()
        )),
        Ok(bytes) => {
            let now = whirl::config::provenance::sha256_hex(&bytes);
            if now != header.job.sha256 && given_job.is_some() {
                findings.push(format!(
                    "{name} was not planned from the job {} as it is now: its header names \
                     {} (sha256 {}), and this job's sha256 is {}",
                    job.display(),
                    resolve(program, &header.job.path).display(),
                    short(&header.job.sha256),
                    short(&now)
                ));
            } else if now != header.job.sha256 {
                findings.push(format!(
                    "the job {} has changed since {name} was planned from it (sha256 {} \
                     now, {} then)",
                    job.display(),
                    short(&now),
                    short(&header.job.sha256)
                ));
            } else if let Some(finding) = points_changed(&job, header.points.as_ref(), &name) {
                findings.push(finding);
            }
        }
    }
    Checked {
        header: Some(header),
        findings,
        plan_again,
        bare: false,
    }
}

/// Whether the profile points the job `job` names now are those the header recorded; a
/// sentence saying how not.
fn points_changed(
    job: &Path,
    recorded: Option<&Source>,
    program: &impl std::fmt::Display,
) -> Option<String> {
    let now = crate::files::points_file(job);
    match (now, recorded) {
        (None, None) => None,
        (Some(points), Some(then)) => match std::fs::read(&points) {
            Err(error) => Some(format!(
                "the profile points {} of the job {} cannot be read ({error})",
                points.display(),
                job.display()
            )),
            Ok(bytes) => {
                let now = whirl::config::provenance::sha256_hex(&bytes);
                (now != then.sha256).then(|| {
                    format!(
                        "the profile points {} of the job {} have changed since {program} was \
                         planned (sha256 {} now, {} then)",
                        points.display(),
                        job.display(),
                        short(&now),
                        short(&then.sha256)
                    )
                })
            }
        },
        // The job's bytes are those planned from, so it names the points it named then;
        // a header that says otherwise was written by hand.
        _ => Some(format!(
            "the provenance header of {program} and the job {} disagree on whether the job \
             names a profile points file",
            job.display()
        )),
    }
}

/// The machine-profile path of a header, as a person reads it.
fn shown_machine(program: &Path, recorded: &str) -> String {
    match recorded.strip_prefix(BUILT_IN) {
        Some(builtin) => format!("the built-in {builtin}"),
        None => resolve(program, recorded).display().to_string(),
    }
}

/// A hash's first 12 digits, enough to tell two apart in a sentence.
fn short(sha256: &str) -> &str {
    &sha256[..sha256.len().min(12)]
}

/// `whirl stream`'s refusal of `program`, unless `unchecked` (then a warning on stderr).
pub(crate) fn refuse_or_warn(checked: &Checked, program: &Path, unchecked: bool) -> Result<()> {
    if checked.findings.is_empty() {
        return Ok(());
    }
    let findings = checked.findings.join("; ");
    if unchecked {
        crate::terminal::warn(&format!(
            "{findings}; streaming {} all the same ({OVERRIDE}; the run's record says so)",
            program.display()
        ));
        return Ok(());
    }
    bail!(
        "refusing to stream {}: {findings}. Nothing was sent. Plan it again with `{}`, or, \
         knowing what it cuts, stream it as it is with {OVERRIDE}",
        program.display(),
        checked.plan_again
    )
}

/// `dry-run --program`'s, `verify`'s and `measure --program`'s word on a program whose
/// header does not match the job and machine they are given: they measure it against that
/// job whatever it was planned from. A program without a header (written by hand, the
/// usual reason to measure a given program) is measured without a word.
pub(crate) fn report(checked: &Checked) {
    if checked.findings.is_empty() || checked.bare {
        return;
    }
    crate::terminal::warn(&format!(
        "{}; it is measured against the job given here all the same (`{}` plans it again)",
        checked.findings.join("; "),
        checked.plan_again
    ));
}
