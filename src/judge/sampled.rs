//! A path sampled every servo period (LinuxCNC's HAL `sampler` in a dry run), measured
//! against Δ and logged as the moves it is made of.
//!
//! Each sample is the commanded X, Z, C of one servo period and the program line motion
//! was executing. Consecutive samples make a straight step; steps alike are merged into
//! straight stretches ([`Merger`], the same merging the simulated CAN drives' cycles get: at
//! constant speed every step is the same, so a stretch is the samples' path to within the
//! samples' own rounding), a stretch ends where the line's kind changes (a rapid is
//! positioning; the Δ guard judges feed moves), and each stretch goes to the Δ guard
//! ([`DeltaGuard`]) and to the executed-path log. A lost sample (the sampler's FIFO ran
//! over) makes the path unknown there: it is counted, and the run cannot be judged within Δ.

use crate::judge::cycles::{Merger, Stretch};
use crate::judge::guard::DeltaGuard;
use crate::log::{self, ExecLog, LogError};
use whirl_sim::{Breach, ExecutedBlock, Guard, Measured, MoveKind, Position};

/// What the samples add up to.
#[derive(Debug, Clone, PartialEq)]
pub struct SampledRun {
    /// What the guard measured.
    pub measured: Measured,
    /// The first point beyond Δ (or a motion that cannot be measured).
    pub breach: Option<String>,
    /// Samples read.
    pub samples: u64,
    /// Samples lost (gaps in the sampler's numbering).
    pub lost: u64,
    /// From the first sample that moved to the last one that did, s.
    pub machine_time_s: f64,
    /// The furthest program line motion reached.
    pub furthest_line: u64,
}

/// The measuring of a sampled path; see the module docs.
pub struct SampledPath {
    guard: DeltaGuard,
    merger: Merger,
    /// Whether the stretch being merged is a rapid.
    open_rapid: Option<bool>,
    /// Whether each program line (1-based index) is a rapid.
    rapid_lines: Vec<bool>,
    period_s: f64,
    last: Option<(u64, [f64; 3])>,
    run: SampledRun,
    /// Time of the first moving sample, s.
    first_motion: Option<f64>,
    log: ExecLog,
    started: std::time::Instant,
    log_error: Option<LogError>,
}

/// The samples' resolution: `halsampler` prints six decimals (mm, degrees), so two samples'
/// step differs from the true one by up to 10⁻⁶; steps this close are alike.
const COUNTS_PER_UNIT: f64 = 5e5;

impl SampledPath {
    /// Measures with `guard` (built for radius X: the sampler records LinuxCNC's axis
    /// positions, whose X is the radius in every X mode), samples `period_s` apart, the
    /// program's rapids by line; logs to `log`.
    pub fn new(guard: DeltaGuard, rapid_lines: Vec<bool>, period_s: f64, log: &ExecLog) -> Self {
        SampledPath {
            guard,
            merger: Merger::new([COUNTS_PER_UNIT; 3]),
            open_rapid: None,
            rapid_lines,
            period_s,
            last: None,
            run: SampledRun {
                measured: Measured::default(),
                breach: None,
                samples: 0,
                lost: 0,
                machine_time_s: 0.0,
                furthest_line: 0,
            },
            first_motion: None,
            log: log.clone(),
            started: std::time::Instant::now(),
            log_error: None,
        }
    }

    /// The first breach, once there is one: the caller stops the machine.
    pub fn breach(&self) -> Option<&str> {
        self.run.breach.as_deref()
    }

    /// Sample number `index` (the sampler's count), at `position` (X, Z, C), motion on
    /// program line `line`.
    pub fn push(&mut self, index: u64, position: [f64; 3], line: u64) {
        self.run.samples += 1;
        self.run.furthest_line = self.run.furthest_line.max(line);
        let Some((last_index, from)) = self.last.replace((index, position)) else {
            return;
        };
        let steps = index.saturating_sub(last_index);
        self.run.lost += steps.saturating_sub(1);
        if steps == 0 {
            return;
        }
        let t1 = index as f64 * self.period_s;
        let t0 = last_index as f64 * self.period_s;
        if from != position {
            self.first_motion.get_or_insert(t0);
            self.run.machine_time_s = t1 - self.first_motion.unwrap_or(t0);
        }
        let rapid = self
            .rapid_lines
            .get(line as usize)
            .copied()
            .unwrap_or(false);
        if let Some(open) = self.open_rapid.replace(rapid).filter(|&open| open != rapid) {
            if let Some(stretch) = self.merger.finish() {
                self.judge(stretch, open);
            }
        }
        let block = ExecutedBlock {
            line,
            n: None,
            kind: MoveKind::Feed,
            from: Position::from_array(from),
            target: Position::from_array(position),
            to: Position::from_array(position),
            start_time: t0,
            end_time: t1,
            completed: true,
            phases: Vec::new(),
        };
        if let Some(stretch) = self.merger.push(&block) {
            self.judge(stretch, rapid);
        }
    }

    /// A finished stretch (a `rapid` one or not): logged, and judged unless it is a rapid
    /// or stands still.
    fn judge(&mut self, stretch: Stretch, rapid: bool) {
        if stretch.from == stretch.to {
            return;
        }
        let event = log::Event::Executed {
            line: Some(stretch.line as usize),
            times: stretch.times,
            from: stretch.from,
            to: stretch.to,
            rapid,
        };
        if let Err(error) = self.log.write(self.started.elapsed().as_secs_f64(), event) {
            self.log_error.get_or_insert(error);
        }
        if rapid || self.run.breach.is_some() {
            return;
        }
        if let Err(Breach { message }) = self.guard.executed(&stretch.block()) {
            self.run.breach = Some(message);
        }
    }

    /// The samples are over: the last stretch is measured, and if the program `ran` to its
    /// end, the points still open (a program stopped part way leaves them uncut, which is
    /// no error of its path).
    pub fn finish(mut self, ran: bool) -> Result<SampledRun, LogError> {
        if let (Some(stretch), Some(rapid)) = (self.merger.finish(), self.open_rapid) {
            self.judge(stretch, rapid);
        }
        if ran && self.run.breach.is_none() {
            if let Err(Breach { message }) = self.guard.program_end() {
                self.run.breach = Some(message);
            }
        }
        if let Some(error) = self.log_error {
            return Err(error);
        }
        self.run.measured = self.guard.measured();
        Ok(self.run)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::job::Job;
    use crate::config::machine::{MachineProfile, XMode};

    fn job() -> Job {
        Job::from_toml(
            include_str!("../../examples/trapezoidal/job.toml"),
            std::path::Path::new("examples/trapezoidal/job.toml"),
        )
        .unwrap()
    }

    fn path(rapid_lines: Vec<bool>) -> SampledPath {
        let mut machine = MachineProfile::from_toml(
            include_str!("../../machine-profiles/linuxcnc-lathe.toml"),
            "l",
        )
        .unwrap();
        machine.x_mode = XMode::Radius;
        let job = job();
        let (ring, _) = crate::plan::angles::ring(&job).unwrap();
        let guard = DeltaGuard::new(&job, ring, &machine).unwrap();
        SampledPath::new(guard, rapid_lines, 0.001, &ExecLog::discard())
    }

    #[test]
    fn lost_samples_are_counted_and_time_runs_from_the_first_move() {
        let mut p = path(vec![false; 4]);
        p.push(0, [10.0, 0.0, 0.0], 1);
        p.push(1, [10.0, 0.0, 0.0], 1);
        p.push(2, [10.0, 0.0, 1.0], 2);
        p.push(5, [10.0, 0.0, 4.0], 2);
        p.push(6, [10.0, 0.0, 5.0], 3);
        assert_eq!(p.run.lost, 2, "samples 3 and 4 are missing");
        assert_eq!(p.run.samples, 5);
        assert_eq!(p.run.furthest_line, 3);
        // The first move is the step from sample 1 to 2; the last ends at sample 6.
        assert!((p.run.machine_time_s - 0.005).abs() < 1e-12);
    }

    #[test]
    fn a_program_that_never_turns_c_is_a_breach_at_its_end() {
        let mut p = path(vec![false; 4]);
        for k in 0..10 {
            p.push(k, [10.0 + k as f64 * 0.01, 0.0, 0.0], 1);
        }
        let run = p.finish(true).unwrap();
        let breach = run.breach.expect("nothing was cut");
        assert!(breach.contains("without turning C"), "{breach}");
        assert_eq!(run.measured.points, 0);
    }

    #[test]
    fn rapids_are_logged_but_not_judged() {
        // A rapid that turns C backwards would be a breach if it were judged as a feed.
        let mut p = path(vec![false, true]);
        for k in 0..10 {
            p.push(k, [30.0, 0.0, -(k as f64)], 1);
        }
        assert_eq!(p.breach(), None);
    }
}
