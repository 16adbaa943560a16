//! The console's runs in the run records ([`crate::records`]), as the command line records
//! its own: a record opened `running` before anything is sent, holds and resumes noted as
//! they are pressed, the record closed with the outcome, where to resume, the alarms and
//! the measured error.
//!
//! A console run's kind is [`Kind::Serve`]; a dry run has no port (the simulator is the
//! console's own), a stream names where it went. Each run opens the records on its own
//! thread's runtime (the database's connections live where they are used); the server
//! keeps one opening for the history page and the buttons' notes.

use super::registry::{Measured, ResumePoint};
use crate::log::Record;
use crate::records::from_log::LogFacts;
use crate::records::{
    Ending, FileSnapshot, Kind, NewRun, Note, NoteKind, Outcome, Place, ProgramId, RecordError,
    Recorded, RunProvenance, Store, Timestamp,
};
use crate::transport::Posted;

/// Where a console records its runs.
#[derive(Debug, Clone)]
pub struct Records {
    /// The database, for each run's own opening.
    pub place: Place,
    /// The server's opening: the history, the buttons' notes.
    pub store: Store,
}

/// What a console run's record holds from its start.
pub struct Start<'a> {
    /// The job file as read.
    pub job: Option<FileSnapshot>,
    /// The machine profile file as read.
    pub machine: Option<FileSnapshot>,
    /// The machine profile's name.
    pub machine_name: &'a str,
    /// The program.
    pub posted: &'a Posted,
    /// The plan report (JSON).
    pub plan_report: Option<String>,
    /// What the program was planned from.
    pub provenance: Option<RunProvenance>,
    /// How it goes (`serial`, `modbus-tcp`, …).
    pub transport: &'a str,
    /// Where it goes, for a stream to a machine; `None` for a dry run.
    pub port: Option<String>,
    /// The line (1-based) it resumes at.
    pub resume_from: Option<usize>,
}

/// The record a console run opens.
pub fn new_run(start: Start<'_>) -> NewRun {
    let mut run = NewRun::new(Kind::Serve);
    run.job = start.job;
    run.machine = start.machine;
    run.machine_name = Some(start.machine_name.to_owned());
    run.program = Some(ProgramId::of(
        start.posted.name.clone(),
        &start.posted.lines.join("\n"),
    ));
    run.plan_report = start.plan_report;
    run.provenance = start.provenance;
    run.transport = Some(start.transport.to_owned());
    run.port = start.port;
    run.resume_from = start.resume_from;
    run
}

/// Opens the records at `place` on the caller's runtime (which uploads what their spool
/// keeps, if the shop's database answers) and the run's record in them.
pub async fn begin(place: &Place, run: &NewRun) -> Result<(Store, Recorded), RecordError> {
    let store = Store::open(place).await?;
    if let Some(Err(e)) = store.uploaded() {
        tracing::warn!(error = %e, "the runs kept in the spool stay there until the next upload");
    }
    let recorded = store.begin(run).await?;
    Ok((store, recorded))
}

/// A hold or a resume pressed at `line` by `client` (its address and session, as
/// [`crate::console::http`] tells them), as its record notes it: an operator's hold and
/// anyone else's are told apart.
pub fn pressed(kind: NoteKind, line: Option<usize>, client: &str) -> Note {
    let what = match kind {
        NoteKind::Hold => "held",
        _ => "resumed",
    };
    Note {
        line,
        ..Note::new(kind, format!("{what} from the console by {client}"))
    }
}

/// Adds to `ending` what a console knows beside the run's own result: the controller's
/// alarms in its log (when the result noted none), the feed overrides it ran at (each at
/// the wall time `when` gives its log time), the resume point it offers, and the error
/// measured of the cut.
pub fn complete(
    ending: &mut Ending,
    log: &[Record],
    resume: Option<&ResumePoint>,
    measured: Option<Measured>,
    when: impl Fn(f64) -> Option<Timestamp>,
) {
    // What the log says beside where to resume, which the run's view knows; each feed
    // override noted when it happened (`when`: the wall time of a log time).
    ending.add_log_timed(&LogFacts::of(log.to_vec(), 1), when);
    if ending.outcome != Outcome::Completed {
        if let Some(point) = resume {
            ending.resume_at = Some(point.line);
            ending.possibly_run_to = point.possibly_run_to;
        }
    }
    if let Some(m) = measured {
        ending.measured = Some(crate::records::Measured {
            max_overcut_mm: m.max_overcut_mm,
            max_undercut_mm: m.max_undercut_mm,
            delta_mm: m.delta_mm,
            within_delta: m.within_delta && ending.outcome == Outcome::Completed,
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::machine::MachineProfile;
    use crate::log::Event;

    fn posted() -> Posted {
        let machine = MachineProfile::builtin_sim().unwrap();
        Posted::read("p.nc", "G0 X1\nG1 Z-1 F100\n", &machine).unwrap()
    }

    #[test]
    fn a_console_run_is_recorded_as_a_serve_of_its_program() {
        let posted = posted();
        let run = new_run(Start {
            job: Some(FileSnapshot::of("jobs/t.toml", b"x")),
            machine: None,
            machine_name: "lathe",
            posted: &posted,
            plan_report: None,
            provenance: None,
            transport: "modbus-tcp",
            port: None,
            resume_from: Some(2),
        });
        assert_eq!(run.kind, Kind::Serve);
        assert_eq!(run.machine_name.as_deref(), Some("lathe"));
        assert_eq!(run.transport.as_deref(), Some("modbus-tcp"));
        assert_eq!(run.resume_from, Some(2));
        // The program by the hash of its lines, each ended by a newline.
        assert_eq!(
            run.program.unwrap().sha256,
            crate::records::sha256_hex(b"G0 X1\nG1 Z-1 F100\n")
        );
    }

    #[test]
    fn a_stopped_run_resumes_at_the_offered_line_with_its_alarms_and_never_within_delta() {
        let alarm = Record {
            t: 1.0,
            event: Event::Alarm {
                code: 3,
                message: "reset while in motion".into(),
            },
        };
        let point = ResumePoint {
            line: 40,
            possibly_run_to: Some(44),
        };
        let measured = Measured {
            max_overcut_mm: 0.001,
            max_undercut_mm: 0.5,
            delta_mm: 0.01,
            within_delta: true,
        };
        let mut stopped = Ending::new(Outcome::Stopped);
        complete(&mut stopped, &[alarm], Some(&point), Some(measured), |_| {
            None
        });
        assert_eq!(
            (stopped.resume_at, stopped.possibly_run_to),
            (Some(40), Some(44))
        );
        assert_eq!(stopped.notes[0].code, Some(3));
        // Half a groove is not a part within Δ.
        assert!(!stopped.measured.unwrap().within_delta);
        let mut done = Ending::new(Outcome::Completed);
        complete(&mut done, &[], Some(&point), Some(measured), |_| None);
        assert_eq!(done.resume_at, None);
        assert!(done.measured.unwrap().within_delta);
        assert!(done.notes.is_empty());
    }

    #[test]
    fn each_feed_override_is_noted_when_the_controller_ran_at_it_not_at_the_end() {
        let feed = |t, percent| Record {
            t,
            event: Event::FeedOverride {
                percent,
                state: crate::log::FeedOverrideState::Running,
            },
        };
        let log = [feed(1.0, 100), feed(2.0, 90), feed(7.5, 120)];
        let mut ending = Ending::new(Outcome::Stopped);
        // The wall clock of a run that started at 10:00:00.
        let start = Timestamp::parse("2026-05-01T10:00:00").unwrap();
        complete(&mut ending, &log, None, None, |t| {
            Some(Timestamp(start.0 + (t * 1000.0) as i64))
        });
        let noted: Vec<(Option<u32>, Option<&str>)> = ending
            .notes
            .iter()
            .map(|n| (n.code, n.at.as_deref()))
            .collect();
        assert_eq!(
            noted,
            [
                (Some(90), Some("2026-05-01T10:00:02.000Z")),
                (Some(120), Some("2026-05-01T10:00:07.500Z"))
            ]
        );
    }
}
