//! How a run ended, in a record's terms, from what the library's runs hand back: a
//! stream's outcome (or its error), a dry run's report, and the run's log. The command line
//! and a console close their records from the same facts.

use super::from_log::LogFacts;
use super::time::Timestamp;
use super::{Ending, Measured, Note, NoteKind, Outcome};
use crate::judge::dry_run::DryRunReport;
use crate::transport::{self, StreamError};

impl Ending {
    /// A stream's ending: completed; stopped (an alarm, the operator, a stall: the run
    /// ended in an outcome that says where to resume); or failed (the link, the log, a
    /// resume that cannot re-enter), with the resume point the transport gives.
    pub fn of_stream(result: &Result<transport::Outcome, StreamError>) -> Ending {
        let (outcome, reason, resume) = match result {
            Ok(run) if run.completed() => (Outcome::Completed, None, None),
            Ok(run) => (Outcome::Stopped, run.stop(), run.resume()),
            Err(error) => (Outcome::Failed, Some(error.to_string()), error.resume()),
        };
        let mut ending = Ending::new(outcome);
        ending.reason = reason;
        if let Some(resume) = resume {
            // The transport counts lines from 0, a record (and the command line) from 1.
            ending.resume_at = Some(resume.line + 1);
            ending.possibly_run_to =
                (!resume.possibly_executed.is_empty()).then_some(resume.possibly_executed.end);
        }
        ending
    }

    /// A dry run's ending: completed or stopped, the measured error, the simulator's alarms,
    /// and where a stopped one resumes (the console resumes a dry run on its simulator).
    pub fn of_dry_run(report: &DryRunReport) -> Ending {
        let mut ending = Ending::new(if report.completed {
            Outcome::Completed
        } else {
            Outcome::Stopped
        });
        ending.resume_at = report.resume_at;
        if !report.completed {
            ending.reason = report.stop.clone().or_else(|| {
                report
                    .alarms
                    .first()
                    .map(|a| format!("ALARM:{} {}", a.code, a.message))
            });
        }
        ending.measured = Some(Measured {
            max_overcut_mm: report.max_overcut_mm,
            max_undercut_mm: report.max_undercut_mm,
            delta_mm: report.delta_mm,
            within_delta: report.within_delta,
        });
        ending.notes = report
            .alarms
            .iter()
            .map(|a| Note {
                code: Some(u32::from(a.code)),
                ..Note::new(
                    NoteKind::Alarm,
                    match &a.detail {
                        Some(detail) => format!("{}: {detail}", a.message),
                        None => a.message.clone(),
                    },
                )
            })
            .collect();
        ending
    }

    /// Adds what the run's log says: the last line known done, the controller's alarms if
    /// none are noted yet (a dry run's report has them with the guard's words), and every
    /// feed override the controller ran at, each at the time the controller first reported
    /// it: the run's start (`started`, its log's time 0) plus its log time. Without a
    /// start, see [`Ending::add_log_timed`].
    pub fn add_log(&mut self, facts: &LogFacts, started: Option<Timestamp>) {
        self.add_log_timed(facts, |t| {
            let start = started?;
            (t.is_finite() && t >= 0.0)
                .then(|| Timestamp(start.0.saturating_add((t * 1000.0) as i64)))
        });
    }

    /// [`Ending::add_log`] with the wall time of a log time given by `when`: a log whose
    /// clock is not the wall's (a CAN session's, scaled) is timed by when it was read. A
    /// note `when` cannot time is noted at the run's end.
    pub fn add_log_timed(&mut self, facts: &LogFacts, when: impl Fn(f64) -> Option<Timestamp>) {
        self.last_line = facts.last_line;
        self.notes
            .extend(facts.feed_overrides.iter().map(|change| Note {
                code: Some(u32::from(change.percent)),
                at: when(change.t).map(Timestamp::to_text),
                ..Note::new(
                    NoteKind::FeedOverride,
                    format!(
                        "the controller ran at a feed override of {} %",
                        change.percent
                    ),
                )
            }));
        if !self.notes.iter().any(|n| n.kind == NoteKind::Alarm) {
            let alarms = facts.alarms.iter().map(|(code, message)| Note {
                code: Some(*code),
                ..Note::new(NoteKind::Alarm, message.clone())
            });
            self.notes.splice(0..0, alarms);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::judge::dry_run::Alarm;

    fn report(completed: bool, alarms: Vec<Alarm>) -> DryRunReport {
        DryRunReport {
            job: "job.toml".into(),
            within_delta: completed && alarms.is_empty(),
            completed,
            lines: 100,
            lines_acked: 100,
            stop: None,
            resume_at: (!completed).then_some(42),
            machine_time_s: 10.0,
            wall_time_s: 1.0,
            baud: 115_200,
            link_utilization: 0.1,
            max_error_mm: 0.004,
            max_overcut_mm: 0.004,
            max_undercut_mm: 0.003,
            delta_mm: 0.005,
            points_measured: 10,
            points: 10,
            alarms,
        }
    }

    #[test]
    fn a_dry_run_stopped_by_the_guard_is_stopped_with_its_alarm_and_measure() {
        let alarm = Alarm {
            code: 64,
            message: "profile error beyond Δ".into(),
            detail: Some("0.0123 mm overcut at Z-12".into()),
        };
        let ending = Ending::of_dry_run(&report(false, vec![alarm]));
        assert_eq!(ending.outcome, Outcome::Stopped);
        assert_eq!(
            ending.reason.as_deref(),
            Some("ALARM:64 profile error beyond Δ")
        );
        assert_eq!(ending.notes[0].code, Some(64));
        assert!(ending.notes[0].text.ends_with("0.0123 mm overcut at Z-12"));
        assert_eq!(ending.measured.unwrap().max_overcut_mm, 0.004);
        // Where the dry run said to resume, as its report gives it (1-based).
        assert_eq!(ending.resume_at, Some(42));
        let done = Ending::of_dry_run(&report(true, vec![]));
        assert_eq!((done.outcome, done.reason), (Outcome::Completed, None));
        assert!(done.measured.unwrap().within_delta);
    }

    #[test]
    fn a_failed_stream_resumes_where_its_transport_says_counted_from_one() {
        let error = StreamError::ResumeOnLinuxcnc(41);
        let ending = Ending::of_stream(&Err(error));
        assert_eq!(ending.outcome, Outcome::Failed);
        assert!(ending.reason.unwrap().contains("line 42"));
        // LinuxCNC resumes at its own console: no line of whirl's.
        assert_eq!(ending.resume_at, None);
    }

    #[test]
    fn every_feed_override_the_controller_ran_at_is_noted_with_its_percent_and_time() {
        use super::super::from_log::FeedChange;
        let facts = LogFacts {
            feed_overrides: vec![
                FeedChange {
                    percent: 120,
                    t: 2.5,
                },
                FeedChange {
                    percent: 90,
                    t: 61.0,
                },
            ],
            ..LogFacts::default()
        };
        let mut ending = Ending::new(Outcome::Completed);
        let started = Timestamp::parse("2026-05-01T10:00:00").unwrap();
        ending.add_log(&facts, Some(started));
        // When the controller ran at each: the run's start plus the log's time, not the
        // run's end.
        let at: Vec<Option<&str>> = ending.notes.iter().map(|n| n.at.as_deref()).collect();
        assert_eq!(
            at,
            [
                Some("2026-05-01T10:00:02.500Z"),
                Some("2026-05-01T10:01:01.000Z")
            ]
        );
        // Without a start, the store notes them when it writes them.
        let mut untimed = Ending::new(Outcome::Completed);
        untimed.add_log(&facts, None);
        assert!(untimed.notes.iter().all(|n| n.at.is_none()));
        let noted: Vec<(NoteKind, Option<u32>)> =
            ending.notes.iter().map(|n| (n.kind, n.code)).collect();
        assert_eq!(
            noted,
            [
                (NoteKind::FeedOverride, Some(120)),
                (NoteKind::FeedOverride, Some(90))
            ]
        );
    }

    #[test]
    fn the_log_gives_the_last_line_and_the_alarms_not_yet_noted() {
        let facts = LogFacts {
            last_line: Some(30),
            alarms: vec![(3, "reset while in motion".into())],
            ..LogFacts::default()
        };
        let mut stream = Ending::new(Outcome::Stopped);
        stream.add_log(&facts, None);
        assert_eq!(stream.last_line, Some(30));
        assert_eq!(stream.notes.len(), 1);
        assert_eq!(stream.notes[0].code, Some(3));
        // A dry run's own alarms stand.
        let mut dry = Ending::of_dry_run(&report(
            false,
            vec![Alarm {
                code: 64,
                message: "beyond Δ".into(),
                detail: None,
            }],
        ));
        dry.add_log(&facts, None);
        let codes: Vec<Option<u32>> = dry.notes.iter().map(|n| n.code).collect();
        assert_eq!(codes, [Some(64)]);
    }
}
