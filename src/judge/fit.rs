//! The tool a part was really cut with, from its measured section, and the job that cuts
//! the target with that tool (`whirl measure --fit`, `--correct`; `docs/measure.md`).
//!
//! **The model.** The part was cut by a known program (the job's, planned for the machine
//! by [`crate::judge::refine::plan`], the planning every command uses)
//! with a ring whose radius R, nose radius r and installation angle δ may differ from the
//! job's. For any such tool the swept-volume engine gives the error at the foot of every
//! measured point ([`Target::error_at_u`], the program's interpolation and feed scallop
//! included), so the fit is nonlinear least squares of the measured deviations against the
//! engine's, over (R, r, δ): Levenberg–Marquardt on a central-difference Jacobian. Three
//! parameters and a few hundred points make a 3 × 3 system, small enough to write here
//! rather than take a crate for.
//!
//! **Uncertainty.** At the solution the covariance is `s²·(JᵀJ)⁻¹`, with `s²` the residual
//! variance `Σres²/(n − 3)`; the standard errors are the square roots of its diagonal.
//! They assume the residuals are independent measurement noise of one size.
//!
//! **Identifiability.** r moves the surface along its normal everywhere (∂e/∂r = −1); R
//! moves the nose along the ring's radial direction, which shows along the normal in
//! proportion to how nearly the two align (1 at a root or crest, about 0.25 on a 15° flank);
//! δ tilts the ring about its radial line through the contact, which moves nothing where the
//! contact lies on that line (the root and crest of a symmetric groove) and most on the
//! flanks. So an axial section separates R from r only if it holds points whose normals
//! differ in direction (a root and a flank), and sees δ only through its flank points. A
//! fit whose Jacobian is singular is refused, naming the combination of parameters the
//! points cannot see; one that is merely loose is reported with its standard errors, and
//! [`correct`] refuses to act on it (see [`Fit::groove_uncertainty_mm`]).

use crate::config::job::{Job, JobError};
use crate::config::machine::MachineProfile;
use crate::geometry::linkage::{Linkage, Ring};
use crate::judge::measure::{Motion, Target, VerifyError};
use crate::judge::section::Deviation;
use crate::judge::verify::CheckError;
use crate::plan::{PlanError, Report};
use crate::post::gcode::parse::read_program;
use glam::{DMat3, DVec3};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::Path;

/// Parameters fitted: ring radius, nose radius, installation angle.
pub const PARAMETERS: usize = 3;
/// Their names, in order.
const NAMES: [&str; PARAMETERS] = ["ring radius", "nose radius", "installation angle"];
/// Central-difference steps: mm, mm, radians.
const STEPS: [f64; PARAMETERS] = [1e-4, 1e-4, 1e-5];
/// The units a combination of parameters is shown in: 1 µm, 1 µm, 0.001°.
const SHOWN: [f64; PARAMETERS] = [1e-3, 1e-3, 1e-3 * std::f64::consts::PI / 180.0];
/// A correlation matrix whose smallest eigenvalue is below this share of its largest is
/// singular for the fit: some combination of the parameters changes no deviation.
const SINGULAR: f64 = 1e-12;
/// The most Levenberg–Marquardt steps taken.
const MAX_STEPS: usize = 100;
/// Profile positions at which the fitted tool's effect on the groove is judged.
const PROFILE_POSITIONS: usize = 64;
/// The share of Δ the fitted tool's uncertainty may take for a correction: the planner's
/// programs measure up to about 0.9 Δ, so 3σ of the tool's effect must stay within the rest.
pub const UNCERTAINTY_SHARE: f64 = 0.1;

/// A tool as the fit sees it: R, r in mm, δ in radians.
type Params = [f64; PARAMETERS];

/// One fitted value, in the job's units (mm, or degrees for the angle).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Estimate {
    /// The job's value: for the angle of a job that gives none, the one it was planned with.
    pub job: f64,
    /// The fitted value.
    pub fitted: f64,
    /// Its standard error.
    pub standard_error: f64,
}

/// The fit of the tool a part was cut with.
#[derive(Debug, Clone, Serialize)]
pub struct Fit {
    /// Ring radius R, mm.
    pub ring_radius_mm: Estimate,
    /// Nose radius r, mm.
    pub nose_radius_mm: Estimate,
    /// Installation angle δ, degrees.
    pub installation_angle_deg: Estimate,
    /// Correlations of the three estimates (R, r, δ).
    pub correlation: [[f64; PARAMETERS]; PARAMETERS],
    /// Root mean square of the residuals (measured minus fitted deviation), mm.
    pub rms_residual_mm: f64,
    /// Points fitted.
    pub points: usize,
    /// Levenberg–Marquardt steps taken.
    pub steps: usize,
    /// 3σ of the fitted tool's effect on the groove's error, the largest over the profile,
    /// mm: how far the error a program planned for the fitted tool makes can be from what it
    /// was planned to make, given the fit's uncertainty.
    pub groove_uncertainty_mm: f64,
    /// The combination of parameter changes the points see least, as words.
    pub weakest: String,
    /// The deviation the fitted tool gives at each point, mm, in the points' order.
    pub predicted_mm: Vec<f64>,
}

impl Fit {
    /// The fitted tool: R, r in mm, δ in radians.
    fn params(&self) -> Params {
        [
            self.ring_radius_mm.fitted,
            self.nose_radius_mm.fitted,
            self.installation_angle_deg.fitted.to_radians(),
        ]
    }

    /// Whether the tool is known well enough to plan with: its effect on the groove within
    /// [`UNCERTAINTY_SHARE`] of Δ at 3σ.
    pub fn determined(&self, delta: f64) -> bool {
        self.groove_uncertainty_mm <= UNCERTAINTY_SHARE * delta
    }
}

/// Why no fit.
#[derive(Debug, thiserror::Error)]
pub enum FitError {
    /// The job that cut the part does not plan.
    #[error("cannot plan the job the part was cut by: {0}")]
    Plan(Box<PlanError>),
    /// The program that cut the part cannot be measured.
    #[error("the program the part was cut by: {0}")]
    Program(CheckError),
    /// Fewer points than the fit needs.
    #[error(
        "{found} measured points (lines {first_line} to {last_line}): fitting the ring radius, \
         the nose radius and the installation angle, with their uncertainty, needs at least \
         {needed}"
    )]
    TooFew {
        /// Points given.
        found: usize,
        /// Points needed.
        needed: usize,
        /// The first point's line.
        first_line: usize,
        /// The last point's line.
        last_line: usize,
    },
    /// The points cannot tell some parameters apart.
    #[error(
        "the measured points cannot tell the tool's parameters apart: {combination}; measure \
         points on the flanks as well as the root and crest"
    )]
    Degenerate {
        /// The combination that changes no deviation, as words.
        combination: String,
    },
    /// The engine cannot place the ring for the job's own tool.
    #[error("the ring's poses cannot be found for the job's tool: {0}")]
    Engine(VerifyError),
}

/// What cut the part: the motion, and the ring it was planned with, whose radius, nose and
/// angle the fit starts from.
#[derive(Debug, Clone)]
pub struct Cut {
    /// The motion of the program that cut the part.
    pub motion: Motion,
    /// The ring the program was planned with: the job's, tilted by its installation angle or,
    /// where it gives none, by the angle `whirl plan` chose ([`crate::plan::angles::ring`]).
    pub ring: Ring,
}

/// What cut the part: `program` (text for `machine`), or the job planned for the machine as
/// `whirl plan` plans it ([`crate::judge::refine::plan`]), and the ring either was planned
/// with.
pub fn motion(job: &Job, machine: &MachineProfile, program: Option<&str>) -> Result<Cut, FitError> {
    let planned;
    let (text, ring) = match program {
        Some(text) => {
            let (ring, _) = crate::plan::angles::ring(job)
                .map_err(|e| FitError::Plan(Box::new(PlanError::NoAngle(e))))?;
            (text, ring)
        }
        None => {
            planned = crate::judge::refine::plan(job, machine)
                .map_err(|e| FitError::Plan(Box::new(e)))?;
            (planned.text.as_str(), planned.ring)
        }
    };
    let program = read_program(text, machine.x_diameter())
        .map_err(|e| FitError::Program(CheckError::Parse(e)))?;
    let motion = Motion::new(&program).map_err(|e| FitError::Program(CheckError::Verify(e)))?;
    Ok(Cut { motion, ring })
}

/// The engine's errors of a tool at fixed points of the groove.
struct Engine<'a> {
    job: &'a Job,
    cut: &'a Cut,
    /// (profile parameter, start, z) of each point.
    points: Vec<(f64, u32, f64)>,
}

impl Engine<'_> {
    fn ring(&self, params: &Params) -> Ring {
        Ring {
            radius: params[0],
            nose: params[1],
            installation: params[2],
            ..self.cut.ring
        }
    }

    /// The error the tool `params` makes at each point, mm.
    fn errors(&self, params: &Params) -> Result<Vec<f64>, VerifyError> {
        let linkage = Linkage {
            p: self.job.p(),
            ring: self.ring(params),
        };
        let z_range = (
            self.job.groove.z_start,
            self.job.groove.z_start + self.job.groove.length,
        );
        let target = Target::new(
            self.job.profile.clone(),
            linkage,
            self.job.groove.starts,
            z_range,
            self.job.cut.axial_feed,
        )?;
        Ok(self
            .points
            .iter()
            .map(|&(u, start, z)| target.error_at_u(&self.cut.motion, u, start, z))
            .collect())
    }
}

/// A tool the ring can be: a positive nose, smaller than the ring, and an angle from 0 to
/// below 90°.
fn valid(params: &Params) -> bool {
    params[1] > 0.0
        && params[0] > params[1]
        && (0.0..std::f64::consts::FRAC_PI_2).contains(&params[2])
}

/// Fit the tool `job`'s part was cut with, by `cut`, from the deviations measured on it,
/// starting from the ring the cut was planned with.
pub fn fit(job: &Job, cut: &Cut, deviations: &[Deviation]) -> Result<Fit, FitError> {
    if deviations.len() <= PARAMETERS {
        return Err(FitError::TooFew {
            found: deviations.len(),
            needed: PARAMETERS + 1,
            first_line: deviations.first().map_or(0, |d| d.line),
            last_line: deviations.last().map_or(0, |d| d.line),
        });
    }
    let ring = cut.ring;
    let start: Params = [ring.radius, ring.nose, ring.installation];
    let engine = Engine {
        job,
        cut,
        points: deviations
            .iter()
            .map(|d| (d.profile_u, d.start, d.z_mm))
            .collect(),
    };
    let observed: Vec<f64> = deviations.iter().map(|d| d.deviation_mm).collect();
    let solution = least_squares(|t| engine.errors(t), &observed, start, STEPS, valid).map_err(
        |e| match e {
            Failure::Model(e) => FitError::Engine(e),
            Failure::Singular(combination) => FitError::Degenerate { combination },
        },
    )?;
    // The fitted tool's effect over the whole profile, for the uncertainty of a correction.
    let middle = job.groove.z_start + job.groove.length / 2.0;
    let profile = Engine {
        job,
        cut,
        points: (0..PROFILE_POSITIONS)
            .map(|k| {
                let u = job.profile.length() * (k as f64 + 0.5) / PROFILE_POSITIONS as f64;
                (u, 0, middle)
            })
            .collect(),
    };
    let sensitivity =
        jacobian(&mut |t| profile.errors(t), &solution.params, STEPS).map_err(FitError::Engine)?;
    let groove_sigma = sensitivity
        .iter()
        .map(|row| {
            let j = DVec3::from(*row);
            j.dot(solution.covariance * j).max(0.0).sqrt()
        })
        .fold(0.0, f64::max);
    let se = |k: usize| solution.covariance.col(k)[k].max(0.0).sqrt();
    let estimate = |k: usize, scale: f64| Estimate {
        job: start[k] * scale,
        fitted: solution.params[k] * scale,
        standard_error: se(k) * scale,
    };
    let mut correlation = [[0.0; PARAMETERS]; PARAMETERS];
    for (i, row) in correlation.iter_mut().enumerate() {
        for (k, c) in row.iter_mut().enumerate() {
            *c = solution.covariance.col(k)[i] / (se(i) * se(k));
        }
    }
    let n = observed.len();
    Ok(Fit {
        ring_radius_mm: estimate(0, 1.0),
        nose_radius_mm: estimate(1, 1.0),
        installation_angle_deg: estimate(2, 180.0 / std::f64::consts::PI),
        correlation,
        rms_residual_mm: (solution.cost / n as f64).sqrt(),
        points: n,
        steps: solution.steps,
        groove_uncertainty_mm: 3.0 * groove_sigma,
        weakest: solution.weakest,
        predicted_mm: solution.predicted,
    })
}

/// A least-squares solution.
#[derive(Debug, Clone)]
struct Solution {
    params: Params,
    /// The model at `params`.
    predicted: Vec<f64>,
    /// Sum of squared residuals.
    cost: f64,
    /// `s²·(JᵀJ)⁻¹`.
    covariance: DMat3,
    steps: usize,
    /// The combination the data see least, in words.
    weakest: String,
}

/// Why least squares stopped.
#[derive(Debug)]
enum Failure<E> {
    /// The model failed where it must not (at the start, or for the Jacobian).
    Model(E),
    /// The Jacobian is singular: the combination that changes nothing, in words.
    Singular(String),
}

/// The model's Jacobian at `params` by central differences.
fn jacobian<E>(
    model: &mut impl FnMut(&Params) -> Result<Vec<f64>, E>,
    params: &Params,
    steps: Params,
) -> Result<Vec<Params>, E> {
    let mut columns = Vec::with_capacity(PARAMETERS);
    for k in 0..PARAMETERS {
        let (mut up, mut down) = (*params, *params);
        up[k] += steps[k];
        down[k] -= steps[k];
        let (a, b) = (model(&up)?, model(&down)?);
        columns.push(
            a.iter()
                .zip(&b)
                .map(|(a, b)| (a - b) / (2.0 * steps[k]))
                .collect::<Vec<f64>>(),
        );
    }
    Ok((0..columns[0].len())
        .map(|i| std::array::from_fn(|k| columns[k][i]))
        .collect())
}

/// JᵀJ and Jᵀr.
fn normal_equations(jac: &[Params], residuals: &[f64]) -> (DMat3, DVec3) {
    let mut a = DMat3::ZERO;
    let mut g = DVec3::ZERO;
    for (row, r) in jac.iter().zip(residuals) {
        let j = DVec3::from(*row);
        a += DMat3::from_cols(j * j.x, j * j.y, j * j.z);
        g += j * *r;
    }
    (a, g)
}

/// Levenberg–Marquardt: the parameters whose `model` best matches `observed`, from `start`,
/// with central-difference `steps`; candidates outside `valid` (or where the model fails,
/// there or a step beside it) are rejected like a step that does not lower the cost. Refuses a singular Jacobian,
/// naming the combination of parameters that changes nothing.
fn least_squares<E>(
    mut model: impl FnMut(&Params) -> Result<Vec<f64>, E>,
    observed: &[f64],
    start: Params,
    steps: Params,
    valid: impl Fn(&Params) -> bool,
) -> Result<Solution, Failure<E>> {
    let cost_of = |predicted: &[f64]| -> f64 {
        observed
            .iter()
            .zip(predicted)
            .map(|(o, p)| (o - p).powi(2))
            .sum()
    };
    let residuals = |predicted: &[f64]| -> Vec<f64> {
        observed.iter().zip(predicted).map(|(o, p)| o - p).collect()
    };
    let mut params = start;
    let mut predicted = model(&params).map_err(Failure::Model)?;
    let mut cost = cost_of(&predicted);
    let mut lambda = 1e-3;
    let mut taken = 0;
    let mut jac = jacobian(&mut model, &params, steps).map_err(Failure::Model)?;
    for _ in 0..MAX_STEPS {
        let (a, g) = normal_equations(&jac, &residuals(&predicted));
        singular(&jac, &a)?;
        let mut accepted = None;
        while lambda < 1e12 {
            let damped =
                a + DMat3::from_diagonal(DVec3::new(a.x_axis.x, a.y_axis.y, a.z_axis.z) * lambda);
            let step = damped.inverse() * g;
            let candidate: Params = std::array::from_fn(|k| params[k] + step[k]);
            // A candidate is taken where it lowers the cost and the model holds round it
            // (for the next Jacobian).
            let tried = valid(&candidate)
                .then(|| model(&candidate).ok())
                .flatten()
                .map(|p| (cost_of(&p), p))
                .filter(|(c, _)| *c < cost)
                .and_then(|(c, p)| Some((c, p, jacobian(&mut model, &candidate, steps).ok()?)));
            match tried {
                Some((c, p, j)) => {
                    accepted = Some((candidate, p, c, j, step));
                    lambda = (lambda / 10.0).max(1e-12);
                    break;
                }
                None => lambda *= 10.0,
            }
        }
        // No step lowers the cost: this is the minimum, as far as the model resolves it.
        let Some((candidate, p, c, j, step)) = accepted else {
            break;
        };
        let change = cost - c;
        (params, predicted, cost, jac) = (candidate, p, c, j);
        taken += 1;
        let tiny = step
            .to_array()
            .iter()
            .zip(&steps)
            .all(|(s, h)| s.abs() < h * 1e-4);
        if tiny || change <= cost * 1e-12 {
            break;
        }
    }
    let (a, _) = normal_equations(&jac, &residuals(&predicted));
    singular(&jac, &a)?;
    let dof = observed.len().saturating_sub(PARAMETERS).max(1);
    let covariance = a.inverse() * (cost / dof as f64);
    Ok(Solution {
        params,
        predicted,
        cost,
        covariance,
        steps: taken,
        weakest: weakest(&jac, &a).1,
    })
}

/// Refuses a singular JᵀJ (`a`), naming the combination of parameters that changes nothing.
fn singular<E>(jac: &[Params], a: &DMat3) -> Result<(), Failure<E>> {
    let (ratio, words) = weakest(jac, a);
    if ratio < SINGULAR {
        Err(Failure::Singular(words))
    } else {
        Ok(())
    }
}

/// The combination of parameter changes the data see least: the smallest eigenvalue of the
/// correlation form of JᵀJ over its largest (0 when a parameter changes nothing at all), and
/// the combination in words with what it changes.
fn weakest(jac: &[Params], a: &DMat3) -> (f64, String) {
    let diag = [a.x_axis.x, a.y_axis.y, a.z_axis.z];
    if let Some(k) = (0..PARAMETERS).find(|&k| diag[k] <= 0.0) {
        return (
            0.0,
            format!("the {} changes no measured deviation", NAMES[k]),
        );
    }
    let d = diag.map(f64::sqrt);
    let c: [[f64; PARAMETERS]; PARAMETERS] =
        std::array::from_fn(|i| std::array::from_fn(|k| a.col(k)[i] / (d[i] * d[k])));
    let (values, vectors) = symmetric_eigen(c);
    let (small, large) = (0..PARAMETERS).fold((0, 0), |(s, l), k| {
        (
            if values[k] < values[s] { k } else { s },
            if values[k] > values[l] { k } else { l },
        )
    });
    // The direction in parameter units, scaled so that its largest part is one shown unit.
    let direction: Params = std::array::from_fn(|k| vectors[k][small] / d[k]);
    let largest = (0..PARAMETERS)
        .map(|k| (direction[k] / SHOWN[k]).abs())
        .fold(0.0, f64::max);
    let direction = direction.map(|v| v / largest);
    let effect = jac
        .iter()
        .map(|row| {
            (0..PARAMETERS)
                .map(|k| row[k] * direction[k])
                .sum::<f64>()
                .powi(2)
        })
        .sum::<f64>()
        / jac.len().max(1) as f64;
    let parts: Vec<String> = (0..PARAMETERS)
        .filter(|&k| (direction[k] / SHOWN[k]).abs() >= 0.05)
        .map(|k| match k {
            2 => format!("the {} by {:+.5}°", NAMES[k], direction[k].to_degrees()),
            _ => format!("the {} by {:+.2} µm", NAMES[k], direction[k] * 1e3),
        })
        .collect();
    let together = match &parts[..] {
        [one] => one.clone(),
        [first @ .., last] => format!("{} and {last} together", first.join(", ")),
        [] => "nothing".to_owned(),
    };
    let words = format!(
        "changing {together} changes the measured deviations by {:.2e} mm (root mean square)",
        effect.sqrt()
    );
    (values[small].max(0.0) / values[large], words)
}

/// Eigenvalues and eigenvectors (columns) of a symmetric 3 × 3 matrix, by Jacobi rotations.
fn symmetric_eigen(
    mut a: [[f64; PARAMETERS]; PARAMETERS],
) -> ([f64; PARAMETERS], [[f64; PARAMETERS]; PARAMETERS]) {
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _ in 0..64 {
        let off = a[0][1].powi(2) + a[0][2].powi(2) + a[1][2].powi(2);
        let scale = (0..PARAMETERS).map(|k| a[k][k].powi(2)).sum::<f64>();
        if off <= 1e-32 * scale.max(f64::MIN_POSITIVE) {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q] == 0.0 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = if theta >= 0.0 { 1.0 } else { -1.0 }
                / (theta.abs() + (theta * theta + 1.0).sqrt());
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            for row in a.iter_mut() {
                let (kp, kq) = (row[p], row[q]);
                row[p] = c * kp - s * kq;
                row[q] = s * kp + c * kq;
            }
            let (upper, lower) = a.split_at_mut(q);
            for (pk, qk) in upper[p].iter_mut().zip(lower[0].iter_mut()) {
                (*pk, *qk) = (c * *pk - s * *qk, s * *pk + c * *qk);
            }
            for row in v.iter_mut() {
                let (kp, kq) = (row[p], row[q]);
                row[p] = c * kp - s * kq;
                row[q] = s * kp + c * kq;
            }
        }
    }
    ([a[0][0], a[1][1], a[2][2]], v)
}

/// Why no correction.
#[derive(Debug, thiserror::Error)]
pub enum CorrectionError {
    /// The fit is too loose to plan with.
    #[error(
        "the fit does not determine the tool well enough to correct the job: its effect on the \
         groove is known only to ±{uncertainty:.4} mm (3σ), more than {share} of Δ = {delta} mm; \
         the points see least that {weakest}. Measure more points, on the flanks as well as the \
         root and crest, or with less noise"
    )]
    Undetermined {
        /// The fit's [`Fit::groove_uncertainty_mm`].
        uncertainty: f64,
        /// Δ, mm.
        delta: f64,
        /// [`UNCERTAINTY_SHARE`].
        share: f64,
        /// [`Fit::weakest`].
        weakest: String,
    },
    /// The job's text cannot be edited as TOML.
    #[error("the job's text: {0}")]
    Text(String),
    /// The corrected job does not read back.
    #[error("the corrected job: {0}")]
    Job(JobError),
    /// The corrected job does not plan.
    #[error("the corrected job cannot be planned: {0}")]
    Plan(Box<PlanError>),
}

/// A corrected job: its text, and the plan it makes.
#[derive(Debug, Clone)]
pub struct Correction {
    /// The job file's text.
    pub text: String,
    /// The plan's report for it.
    pub report: Report,
}

/// The job that cuts the target with the fitted tool: `job_text` (the job file that cut the
/// part) with the fitted ring radius, nose radius and installation angle as its tool, its
/// comments and layout kept. `points`, given, replaces the profile's points path (for a job
/// written to another folder); `note` heads the file as comment lines. The text is read back
/// as a job (relative to `path`, where it will be written) and planned for `machine`; a fit
/// too loose for Δ is refused before any of this.
pub fn correct(
    job: &Job,
    job_text: &str,
    fit: &Fit,
    points: Option<&str>,
    note: &str,
    path: &Path,
    machine: &MachineProfile,
) -> Result<Correction, CorrectionError> {
    if !fit.determined(job.cut.delta) {
        return Err(CorrectionError::Undetermined {
            uncertainty: fit.groove_uncertainty_mm,
            delta: job.cut.delta,
            share: UNCERTAINTY_SHARE,
            weakest: fit.weakest.clone(),
        });
    }
    let text = corrected_text(job_text, &fit.params(), points, note)?;
    let corrected = Job::from_toml(&text, path).map_err(CorrectionError::Job)?;
    let plan = crate::judge::refine::plan(&corrected, machine)
        .map_err(|e| CorrectionError::Plan(Box::new(e)))?;
    Ok(Correction {
        text,
        report: plan.report,
    })
}

/// `job_text` with `params` as its tool (R, r to 0.1 µm, δ to 0.0001°), `points` as its
/// profile's points path if given, headed by `note`.
fn corrected_text(
    job_text: &str,
    params: &Params,
    points: Option<&str>,
    note: &str,
) -> Result<String, CorrectionError> {
    let mut doc: toml_edit::DocumentMut = job_text
        .parse()
        .map_err(|e: toml_edit::TomlError| CorrectionError::Text(e.to_string()))?;
    let rounded =
        |v: f64, decimals: usize| -> f64 { format!("{v:.decimals$}").parse().unwrap_or(v) };
    let tool = doc
        .get_mut("tool")
        .and_then(toml_edit::Item::as_table_like_mut)
        .ok_or_else(|| CorrectionError::Text("no [tool] table".into()))?;
    set(tool, "ring_radius", rounded(params[0], 4).into());
    set(tool, "nose_radius", rounded(params[1], 4).into());
    set(
        tool,
        "installation_angle_deg",
        rounded(params[2].to_degrees(), 4).into(),
    );
    if let Some(points) = points {
        let profile = doc
            .get_mut("groove")
            .and_then(|g| g.get_mut("profile"))
            .and_then(toml_edit::Item::as_table_like_mut)
            .ok_or_else(|| CorrectionError::Text("no [groove.profile] table".into()))?;
        set(profile, "points", points.into());
    }
    let mut text = String::new();
    for line in note.lines() {
        let _ = writeln!(text, "# {line}");
    }
    if !text.is_empty() {
        text.push('\n');
    }
    text.push_str(&doc.to_string());
    Ok(text)
}

/// Sets `key` of `table` to `value`, keeping the comments and spacing around the old one
/// (the key's lines above it, the value's comment after it).
fn set(table: &mut dyn toml_edit::TableLike, key: &str, mut value: toml_edit::Value) {
    match table.get_mut(key) {
        Some(item) => {
            if let Some(old) = item.as_value() {
                *value.decor_mut() = old.decor().clone();
            }
            *item = toml_edit::Item::Value(value);
        }
        None => {
            table.insert(key, toml_edit::Item::Value(value));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::judge::section::Deviation;

    fn example(name: &str) -> (Job, String, std::path::PathBuf) {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("examples/{name}/job.toml"));
        let text = std::fs::read_to_string(&path).unwrap();
        (Job::from_toml(&text, &path).unwrap(), text, path)
    }

    #[test]
    fn jacobi_finds_the_eigenvalues_and_vectors_of_a_symmetric_matrix() {
        // [[2, 1, 0], [1, 2, 0], [0, 0, 5]]: eigenvalues 1 and 3 (in the first two axes'
        // plane, along (1, −1) and (1, 1)) and 5.
        let a = [[2.0, 1.0, 0.0], [1.0, 2.0, 0.0], [0.0, 0.0, 5.0]];
        let (values, vectors) = symmetric_eigen(a);
        let mut sorted = values;
        sorted.sort_by(f64::total_cmp);
        for (v, want) in sorted.iter().zip([1.0, 3.0, 5.0]) {
            assert!((v - want).abs() < 1e-12, "{values:?}");
        }
        for k in 0..3 {
            let v: [f64; 3] = std::array::from_fn(|i| vectors[i][k]);
            for i in 0..3 {
                let av: f64 = (0..3).map(|j| a[i][j] * v[j]).sum();
                assert!((av - values[k] * v[i]).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn least_squares_recovers_the_parameters_of_exact_data() {
        let xs: Vec<f64> = (0..30).map(|k| k as f64 / 10.0).collect();
        let model = |t: &Params| -> Result<Vec<f64>, ()> {
            Ok(xs
                .iter()
                .map(|x| t[0] * (t[1] * x).exp() + t[2] * x)
                .collect())
        };
        let truth = [1.5, -0.7, 0.25];
        let observed = model(&truth).unwrap();
        let s = least_squares(model, &observed, [1.0, -0.5, 0.0], [1e-6; 3], |_| true).unwrap();
        for (got, want) in s.params.iter().zip(truth) {
            assert!((got - want).abs() < 1e-8, "{:?}", s.params);
        }
    }

    #[test]
    fn standard_errors_are_the_textbook_ones_for_an_orthogonal_design() {
        // y = a + b·x + c·(x² − 2/3) at x = −1, 0, 1 repeated: orthogonal columns, so
        // se(a) = s/√n, se(b) = s/√Σx², se(c) = s/√Σ(x² − 2/3)², s² = RSS/(n − 3).
        let xs: Vec<f64> = (0..12).map(|k| f64::from(k % 3) - 1.0).collect();
        let noise = [
            0.3, -0.1, 0.2, -0.4, 0.1, 0.0, 0.25, -0.2, -0.15, 0.05, 0.1, -0.35,
        ];
        let model = |t: &Params| -> Result<Vec<f64>, ()> {
            Ok(xs
                .iter()
                .map(|x| t[0] + t[1] * x + t[2] * (x * x - 2.0 / 3.0))
                .collect())
        };
        let observed: Vec<f64> = model(&[2.0, 0.5, -1.0])
            .unwrap()
            .iter()
            .zip(noise)
            .map(|(y, e)| y + e)
            .collect();
        let s = least_squares(model, &observed, [0.0; 3], [1e-3; 3], |_| true).unwrap();
        let n = xs.len() as f64;
        let s2 = s.cost / (n - 3.0);
        let sums = [
            n,
            xs.iter().map(|x| x * x).sum::<f64>(),
            xs.iter().map(|x| (x * x - 2.0 / 3.0).powi(2)).sum::<f64>(),
        ];
        for (k, sum) in sums.iter().enumerate() {
            let se = s.covariance.col(k)[k].sqrt();
            assert!((se - (s2 / sum).sqrt()).abs() < 1e-9, "{k}: {se}");
        }
    }

    #[test]
    fn parameters_the_data_cannot_tell_apart_are_refused_by_name() {
        let xs: Vec<f64> = (0..10).map(f64::from).collect();
        // The first two enter only as their sum.
        let summed = |t: &Params| -> Result<Vec<f64>, ()> {
            Ok(xs.iter().map(|x| (t[0] + t[1]) * x + t[2]).collect())
        };
        let observed = summed(&[1.0, 1.0, 0.5]).unwrap();
        let Err(Failure::Singular(words)) =
            least_squares(summed, &observed, [0.9, 0.9, 0.0], [1e-6; 3], |_| true)
        else {
            panic!("a sum of two parameters fitted");
        };
        assert!(
            words.contains("ring radius") && words.contains("nose radius"),
            "{words}"
        );
        assert!(!words.contains("installation angle"), "{words}");
        // The third changes nothing.
        let blind = |t: &Params| -> Result<Vec<f64>, ()> {
            Ok(xs.iter().map(|x| t[0] * x + t[1]).collect())
        };
        let observed = blind(&[1.0, 1.0, 0.0]).unwrap();
        let Err(Failure::Singular(words)) =
            least_squares(blind, &observed, [0.5, 0.5, 0.0], [1e-6; 3], |_| true)
        else {
            panic!("a parameter without effect fitted");
        };
        assert_eq!(
            words,
            "the installation angle changes no measured deviation"
        );
    }

    #[test]
    fn a_fit_needs_more_points_than_parameters() {
        let (job, _, _) = example("trapezoidal");
        let point = |line: usize| Deviation {
            line,
            at: [16.0, 1.0],
            nearest: [16.0, 1.0],
            deviation_mm: 0.0,
            in_section_mm: 0.0,
            profile_u: 0.0,
            start: 0,
            z_mm: 1.0,
            normal: [1.0, 0.0],
            share: 1.0,
            chain: 0.0,
        };
        let three: Vec<Deviation> = [9, 10, 12].map(point).to_vec();
        let cut = Cut {
            motion: Motion::empty(),
            ring: ring(&job),
        };
        let e = fit(&job, &cut, &three).unwrap_err();
        assert_eq!(
            e.to_string(),
            "3 measured points (lines 9 to 12): fitting the ring radius, the nose radius and the \
             installation angle, with their uncertainty, needs at least 4"
        );
    }

    #[test]
    fn a_job_that_does_not_plan_or_a_program_that_does_not_read_cuts_nothing_to_fit() {
        let (mut job, _, _) = example("trapezoidal");
        let machine = MachineProfile::builtin_sim().unwrap();
        let e = motion(&job, &machine, Some("G1 X1 Q\n")).unwrap_err();
        assert!(matches!(e, FitError::Program(_)), "{e}");
        let program = crate::judge::refine::plan(&job, &machine).unwrap().text;
        // 3°: the ring does not follow the root fillet (the example's comment).
        job.tool.installation_angle_deg = Some(3.0);
        let e = motion(&job, &machine, None).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("cannot plan the job the part was cut by"),
            "{e}"
        );
        // The part cut by the 7.8° program, fitted from a 3° job: no table to search from.
        let cut = motion(&job, &machine, Some(&program)).unwrap();
        let points: Vec<Deviation> = (0..4)
            .map(|k| Deviation {
                line: k,
                at: [16.0, 14.0],
                nearest: [16.0, 14.0],
                deviation_mm: 0.0,
                in_section_mm: 0.0,
                profile_u: job.profile.length() * (k as f64 + 0.5) / 4.0,
                start: 0,
                z_mm: 14.0,
                normal: [1.0, 0.0],
                share: 1.0,
                chain: 0.0,
            })
            .collect();
        let e = fit(&job, &cut, &points).unwrap_err();
        assert!(matches!(e, FitError::Engine(_)), "{e}");
    }

    /// The ring `plan` plans `job` with.
    fn ring(job: &Job) -> Ring {
        crate::plan::angles::ring(job).unwrap().0
    }

    /// A fit of `job`'s tool moved to `params`, its uncertainty `uncertainty`.
    fn fitted(job: &Job, params: Params, uncertainty: f64) -> Fit {
        let ring = ring(job);
        let estimate = |job: f64, fitted: f64| Estimate {
            job,
            fitted,
            standard_error: 1e-5,
        };
        Fit {
            ring_radius_mm: estimate(ring.radius, params[0]),
            nose_radius_mm: estimate(ring.nose, params[1]),
            installation_angle_deg: estimate(
                ring.installation.to_degrees(),
                params[2].to_degrees(),
            ),
            correlation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            rms_residual_mm: 1e-4,
            points: 100,
            steps: 3,
            groove_uncertainty_mm: uncertainty,
            weakest: "changing the installation angle by +0.00100° changes …".into(),
            predicted_mm: Vec::new(),
        }
    }

    #[test]
    fn the_corrected_job_keeps_the_file_and_takes_the_fitted_tool() {
        let (job, text, path) = example("double-start");
        let params = [60.0213, 1.19987, 21.03456f64.to_radians()];
        let out = corrected_text(&text, &params, None, "first line\nsecond").unwrap();
        assert!(
            out.starts_with("# first line\n# second\n\n# A double-start"),
            "{out}"
        );
        // Comments and layout stay; the values change; the angle the job left out is added.
        assert!(out.contains("ring_radius = 60.0213     # R, mm"), "{out}");
        assert!(out.contains("nose_radius = 1.1999      # r, mm"), "{out}");
        assert!(out.contains("installation_angle_deg = 21.0346"), "{out}");
        assert!(out.contains(
            "# installation_angle_deg omitted: the angle with the largest margin in its window"
        ));
        let corrected = Job::from_toml(&out, &path).unwrap();
        assert_eq!(corrected.tool.ring_radius, 60.0213);
        assert_eq!(corrected.tool.nose_radius, 1.1999);
        assert_eq!(corrected.tool.installation_angle_deg, Some(21.0346));
        assert_eq!(corrected.groove.lead, job.groove.lead);
        // Written to another folder, the points are named from there.
        let elsewhere =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/trapezoidal/job2.toml");
        let out = corrected_text(&text, &params, Some("../double-start/profile.csv"), "").unwrap();
        assert!(
            out.contains("points = \"../double-start/profile.csv\""),
            "{out}"
        );
        Job::from_toml(&out, &elsewhere).unwrap();
        // The comment lines above a key that changes stay above it.
        let (_, text, _) = example("trapezoidal");
        let out = corrected_text(&text, &params, None, "").unwrap();
        let above = "# only within about half a degree of it (the lead angle at the mean radius, \
                     7.06°, is refused).\ninstallation_angle_deg = 21.0346\n";
        assert!(out.contains(above), "{out}");
    }

    #[test]
    fn a_correction_is_refused_when_the_fit_is_loose_the_job_invalid_or_unplannable() {
        let (job, text, path) = example("trapezoidal");
        let machine = MachineProfile::builtin_sim().unwrap();
        let ring = ring(&job);
        let good = [
            ring.radius + 0.02,
            ring.nose,
            ring.installation + 0.3f64.to_radians(),
        ];
        // 3σ of the tool's effect above Δ/10.
        let loose = fitted(&job, good, 0.0011);
        let e = correct(&job, &text, &loose, None, "", &path, &machine).unwrap_err();
        assert!(
            e.to_string().starts_with(
                "the fit does not determine the tool well enough to correct the job: its effect \
                 on the groove is known only to ±0.0011 mm (3σ), more than 0.1 of Δ = 0.01 mm"
            ),
            "{e}"
        );
        let e = correct(
            &job,
            "[tool",
            &fitted(&job, good, 0.0),
            None,
            "",
            &path,
            &machine,
        )
        .unwrap_err();
        assert!(matches!(e, CorrectionError::Text(_)), "{e}");
        // A nose as large as the ring is no tool.
        let e = correct(
            &job,
            &text,
            &fitted(&job, [0.4, 0.4, ring.installation], 0.0),
            None,
            "",
            &path,
            &machine,
        )
        .unwrap_err();
        assert!(
            e.to_string()
                .contains("tool.nose_radius = 0.4: must be smaller than ring_radius"),
            "{e}"
        );
        // 3°: the ring does not follow the root fillet.
        let e = correct(
            &job,
            &text,
            &fitted(&job, [ring.radius, ring.nose, 3f64.to_radians()], 0.0),
            None,
            "",
            &path,
            &machine,
        )
        .unwrap_err();
        assert!(
            e.to_string()
                .starts_with("the corrected job cannot be planned"),
            "{e}"
        );
        let c = correct(
            &job,
            &text,
            &fitted(&job, good, 0.0),
            None,
            "",
            &path,
            &machine,
        )
        .unwrap();
        assert!(c.report.max_error_mm <= job.cut.delta);
        assert!((c.report.installation_angle_deg - 8.1).abs() < 1e-9);
    }
}
