//! `axial_feed = "auto"` and `whirl plan --fastest` on the command line: the fastest feed,
//! planned and measured ([`whirl::judge::fastest`]), for the commands that plan or measure a
//! job. Whatever measures a job measures it at the feed its program was planned at.

use anyhow::{Context, Result};
use std::path::Path;
use whirl::config::job::Job;
use whirl::config::machine::MachineProfile;
use whirl::plan::Plan;

/// `job` planned as `whirl plan` plans it: an auto job at its fastest feed (`job` resolved to
/// it), the report naming the limit that bound it; any other at its own feed.
pub(crate) fn planned(job: &mut Job, machine: &MachineProfile) -> Result<Plan> {
    if !job.cut.auto_feed {
        return whirl::judge::refine::plan(job, machine)
            .with_context(|| format!("cannot plan {}", crate::job_name(job)));
    }
    let found = whirl::judge::fastest::fastest(job, machine)
        .with_context(|| format!("cannot find the fastest feed for {}", crate::job_name(job)))?;
    *job = found.job;
    Ok(found.plan)
}

/// `job` at the feed it is cut at: an auto job's fastest (as `whirl plan` finds it), or, when
/// a program planned for it is given, the feed that program cuts at.
pub(crate) fn resolve(job: Job, machine: &MachineProfile, program: Option<&Path>) -> Result<Job> {
    if !job.cut.auto_feed {
        return Ok(job);
    }
    match program {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("cannot read {}", path.display()))?;
            let posted = whirl::post::gcode::read_program(&text, machine.x_diameter())
                .with_context(|| format!("{}", path.display()))?;
            let feed = whirl::plan::feed::program_feed(&posted).with_context(|| {
                format!(
                    "{}: the job's axial_feed is \"auto\", and the program has no linked \
                     moves to read the feed it was planned at from",
                    path.display()
                )
            })?;
            Ok(whirl::plan::feed::at(&job, feed))
        }
        None => {
            let name = crate::job_name(&job);
            Ok(whirl::judge::fastest::fastest(&job, machine)
                .with_context(|| format!("cannot find the fastest feed for {name}"))?
                .job)
        }
    }
}
