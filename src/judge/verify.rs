//! `whirl verify`: a program, as text, measured against its job's groove by the swept-volume
//! engine ([`crate::judge::measure`]), independently of how it was planned.

use crate::config::job::Job;
use crate::config::machine::MachineProfile;
use crate::geometry::linkage::{Linkage, Ring};
use crate::judge::measure::{Measurement, Motion, PointError, Target, VerifyError};
use crate::plan::Report;
use crate::post::gcode::parse::{read_program, ParseError};
use serde::Serialize;

/// What `whirl verify --report` writes.
#[derive(Debug, Clone, Serialize)]
pub struct Verification {
    /// Largest overcut, mm (≥ 0).
    pub max_overcut_mm: f64,
    /// Largest undercut, mm (≥ 0).
    pub max_undercut_mm: f64,
    /// Δ, mm.
    pub delta_mm: f64,
    /// Both within Δ.
    pub within_delta: bool,
    /// Where the largest overcut is.
    pub worst_overcut: PointError,
    /// Where the largest undercut is.
    pub worst_undercut: PointError,
    /// Target points measured.
    pub points: usize,
    /// The section picture (SVG), when asked for.
    #[serde(skip)]
    pub svg: Option<String>,
}

/// A plan's report with the engine's measurement of its program beside it, as
/// `whirl plan --verify --report` writes it: the report's keys, then `verify`.
#[derive(Debug, Clone, Serialize)]
pub struct VerifiedReport<'a> {
    /// The plan's figures.
    #[serde(flatten)]
    pub report: &'a Report,
    /// What the engine measured of the planned program.
    pub verify: &'a Verification,
}

/// Why a program could not be measured.
#[derive(Debug, thiserror::Error)]
pub enum CheckError {
    /// The program text.
    #[error("program: {0}")]
    Parse(ParseError),
    /// The motion or the target.
    #[error(transparent)]
    Verify(#[from] VerifyError),
}

/// Measure `program` (G-code text for `machine`) against `job`'s groove over its formed
/// length, swept by `ring`, the ring it was planned with (see [`target`]); with `picture`,
/// also draw the axial section around the worst point.
pub fn verify(
    job: &Job,
    ring: Ring,
    machine: &MachineProfile,
    program: &str,
    picture: bool,
) -> Result<Verification, CheckError> {
    let target = target(job, ring)?;
    let program = read_program(program, machine.x_diameter()).map_err(CheckError::Parse)?;
    let motion = Motion::new(&program)?;
    let m: Measurement = target.measure(&motion)?;
    let delta = job.cut.delta;
    let svg = picture.then(|| {
        let worst = if m.max_overcut_mm > m.max_undercut_mm {
            m.worst_overcut
        } else {
            m.worst_undercut
        };
        let pitch = job.groove.lead / f64::from(job.groove.starts);
        target
            .section_plot(
                &motion,
                worst.at[2],
                magnification(m.max_overcut_mm.max(m.max_undercut_mm), pitch),
            )
            .to_svg()
    });
    Ok(Verification {
        max_overcut_mm: m.max_overcut_mm,
        max_undercut_mm: m.max_undercut_mm,
        delta_mm: delta,
        within_delta: m.max_overcut_mm <= delta && m.max_undercut_mm <= delta,
        worst_overcut: m.worst_overcut,
        worst_undercut: m.worst_undercut,
        points: m.points,
        svg,
    })
}

/// `job`'s groove over its formed length, as the engine measures a program planned with
/// `ring`: the plan's own ([`crate::plan::Plan::ring`]), or for a program planned before, the
/// ring `plan` plans the job with ([`crate::plan::angles::ring`]). The engine finds each
/// point's nearest poses from the linkage of that ring, so another ring (another installation
/// angle) measures the program against poses it was not planned at.
pub fn target(job: &Job, ring: Ring) -> Result<Target, CheckError> {
    let linkage = Linkage { p: job.p(), ring };
    let z_range = (job.groove.z_start, job.groove.z_start + job.groove.length);
    Ok(Target::new(
        job.profile.clone(),
        linkage,
        job.groove.starts,
        z_range,
        job.cut.axial_feed,
    )?)
}

/// A round magnification (1, 2 or 5 × 10ⁿ) that draws the largest error as about a
/// twentieth of the pitch.
pub(crate) fn magnification(error: f64, pitch: f64) -> f64 {
    if error <= 0.0 {
        return 1.0;
    }
    let raw = (pitch / 20.0) / error;
    let mag = 10f64.powf(raw.log10().floor());
    [5.0, 2.0, 1.0]
        .iter()
        .map(|m| m * mag)
        .find(|m| *m <= raw)
        .unwrap_or(mag)
        .max(1.0)
}
