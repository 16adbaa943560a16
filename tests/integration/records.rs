//! Run records (docs/records.md): the store through the library, against SQLite and a real
//! PostgreSQL server (`postgres.rs`); every recording command through the real binaries;
//! `whirl runs list|show`; a bridge killed mid-run, closed as interrupted on the next start
//! with its log untouched; a database that cannot be written.
//!
//! Every whirl started here is given its database (`WHIRL_DB`, or `--db`) and a home
//! folder of its own, so no test touches the real user's records.

use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::sync::Arc;
use std::time::{Duration, Instant};

use serde_json::Value;
use whirl::records::process::Process;
use whirl::records::store::POSTGRES_TIMEOUT;
use whirl::records::{
    Ending, FileSnapshot, Filter, Kept, Kind, LogPlace, Measured, NewRun, Note, NoteKind, Outcome,
    Place, ProgramId, Store, Timestamp,
};

use crate::postgres::{dead_postgres_url, postgres, private_postgres};
use crate::util::{self, Sim};

// ---------------------------------------------------------------------------------------
// The store, through the library, against either database.

fn block_on<F: std::future::Future>(future: F) -> F::Output {
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap()
        .block_on(future)
}

fn snapshot(path: &str, text: &str) -> FileSnapshot {
    FileSnapshot::of(path, text.as_bytes())
}

/// A new run of `kind` for the job `job`, on the machine `machine`, of `program`.
fn new_run(kind: Kind, job: &str, machine: &str, program: Option<&ProgramId>) -> NewRun {
    let mut run = NewRun::new(kind);
    run.job = Some(snapshot(job, &format!("# {job}\n")));
    run.machine = Some(snapshot(&format!("{machine}.toml"), "name = 1\n"));
    run.machine_name = Some(machine.to_owned());
    run.program = program.cloned();
    run
}

/// What the store must do, on whichever database `place` is.
async fn store_suite(place: Place) {
    let store = Store::open(&place).await.unwrap();
    // Opening again finds the schema in place.
    let store_again = Store::open(&place).await.unwrap();
    assert!(store_again
        .list(&Filter::default())
        .await
        .unwrap()
        .is_empty());
    store_again.close_connections().await;

    // A plan: its inputs kept whole, the program and report known at its end.
    let mut plan = new_run(Kind::Plan, "jobs/Double-Start.toml", "sim", None);
    plan.plan_report = None;
    let plan_run = store.begin(&plan).await.unwrap();
    let plan_id = plan_run.id;
    assert_eq!(plan_run.kept, Kept::Database);
    let program = ProgramId::of("double-start.nc", "G21 G90\nG1 X1 F100\nM2\n");
    let mut done = Ending::new(Outcome::Completed);
    done.program = Some(program.clone());
    done.plan_report = Some(r#"{"segments":3,"delta_mm":0.005}"#.into());
    assert!(store.finish(&plan_run, &done).await.unwrap().closed);
    // A record is closed once: a second ending changes nothing.
    assert!(
        !store
            .finish(&plan_run, &Ending::new(Outcome::Failed))
            .await
            .unwrap()
            .closed
    );
    let shown = store.show(plan_id).await.unwrap().unwrap();
    assert_eq!(shown.summary.kind, Kind::Plan);
    assert_eq!(shown.summary.outcome, Outcome::Completed);
    assert_eq!(shown.job_file, plan.job);
    assert_eq!(shown.machine_file, plan.machine);
    assert_eq!(shown.program_id, Some(program.clone()));
    assert_eq!(shown.plan_report.as_ref().unwrap()["segments"], 3);
    assert_eq!(shown.summary.host, plan.process.host);
    assert_eq!(shown.uid.as_ref(), Some(&plan_run.uid));
    assert_eq!(shown.pid, std::process::id());
    let (started, ended) = (
        Timestamp::parse(&shown.summary.started_at).unwrap(),
        Timestamp::parse(shown.summary.ended_at.as_deref().unwrap()).unwrap(),
    );
    assert!(started <= ended && ended <= Timestamp::now());

    // A stream of that program, stopped by an alarm, held and resumed on the way.
    let mut stream = new_run(
        Kind::Stream,
        "jobs/double-start.toml",
        "plc-modbus",
        Some(&program),
    );
    stream.transport = Some("modbus-tcp".into());
    stream.port = Some("127.0.0.1:1502".into());
    stream.log = Some(LogPlace {
        path: PathBuf::from("/var/log/whirl/exec.jsonl"),
        offset: 4096,
    });
    let stream_run = store.begin(&stream).await.unwrap();
    let stream_id = stream_run.id;
    assert!(stream_id > plan_id);
    store
        .note(
            &stream_run,
            &Note {
                line: Some(80),
                ..Note::new(NoteKind::Hold, "Hold pressed")
            },
        )
        .await
        .unwrap();
    store
        .note(&stream_run, &Note::new(NoteKind::Resume, "Resume pressed"))
        .await
        .unwrap();
    let mut stopped = Ending::new(Outcome::Stopped);
    stopped.reason = Some("the controller stopped the stream: ALARM:64".into());
    stopped.resume_at = Some(120);
    stopped.possibly_run_to = Some(130);
    stopped.last_line = Some(119);
    stopped.notes = vec![
        Note {
            code: Some(64),
            ..Note::new(NoteKind::Alarm, "profile error beyond Δ")
        },
        Note {
            line: Some(120),
            ..Note::new(NoteKind::Stop, "ALARM:64")
        },
    ];
    assert!(store.finish(&stream_run, &stopped).await.unwrap().closed);
    let shown = store.show(stream_id).await.unwrap().unwrap();
    assert_eq!(shown.summary.outcome, Outcome::Stopped);
    assert_eq!(
        (
            shown.summary.resume_at,
            shown.possibly_run_to,
            shown.last_line
        ),
        (Some(120), Some(130), Some(119))
    );
    assert_eq!(shown.summary.transport.as_deref(), Some("modbus-tcp"));
    assert_eq!(shown.port.as_deref(), Some("127.0.0.1:1502"));
    assert_eq!(shown.log, stream.log);
    let notes: Vec<(NoteKind, Option<usize>, Option<u32>)> = shown
        .notes
        .iter()
        .map(|n| (n.kind, n.line, n.code))
        .collect();
    assert_eq!(
        notes,
        [
            (NoteKind::Hold, Some(80), None),
            (NoteKind::Resume, None, None),
            (NoteKind::Alarm, None, Some(64)),
            (NoteKind::Stop, Some(120), None),
        ]
    );
    assert!(shown.notes.iter().all(|n| n.at.is_some()));

    // A resume of the same program at the offered line continues that run; a run of
    // another program that starts at a line continues nothing.
    let mut resumed = new_run(
        Kind::Stream,
        "jobs/double-start.toml",
        "plc-modbus",
        Some(&program),
    );
    resumed.resume_from = Some(120);
    let resumed_id = store.begin(&resumed).await.unwrap().id;
    assert_eq!(
        store.show(resumed_id).await.unwrap().unwrap().resumes,
        Some(stream_id)
    );
    let other = ProgramId::of("other.nc", "G0 X2\n");
    let mut unrelated = new_run(Kind::Stream, "jobs/other.toml", "sim", Some(&other));
    unrelated.resume_from = Some(120);
    let unrelated_run = store.begin(&unrelated).await.unwrap();
    let unrelated_id = unrelated_run.id;
    assert_eq!(
        store.show(unrelated_id).await.unwrap().unwrap().resumes,
        None
    );
    assert!(store.show(unrelated_id + 1000).await.unwrap().is_none());
    let mut measured = Ending::new(Outcome::Completed);
    measured.measured = Some(Measured {
        max_overcut_mm: 0.0036,
        max_undercut_mm: 0.0038,
        delta_mm: 0.005,
        within_delta: true,
    });
    store.finish(&unrelated_run, &measured).await.unwrap();
    assert_eq!(
        store.show(unrelated_id).await.unwrap().unwrap().measured,
        measured.measured
    );

    // The list: newest first, each filter on its own.
    let all = store.list(&Filter::default()).await.unwrap();
    let ids: Vec<i64> = all.iter().map(|r| r.id).collect();
    assert_eq!(ids, [unrelated_id, resumed_id, stream_id, plan_id]);
    let ids_of =
        |runs: Vec<whirl::records::RunSummary>| -> Vec<i64> { runs.iter().map(|r| r.id).collect() };
    let by = |filter: Filter| {
        let store = store.clone();
        async move { ids_of(store.list(&filter).await.unwrap()) }
    };
    // Any case, any part of the job file's path or the program's name.
    assert_eq!(
        by(Filter {
            job: Some("DOUBLE-start".into()),
            ..Filter::default()
        })
        .await,
        [resumed_id, stream_id, plan_id]
    );
    assert_eq!(
        by(Filter {
            job: Some("other.nc".into()),
            ..Filter::default()
        })
        .await,
        [unrelated_id]
    );
    // A LIKE wildcard in the word is a character to find, not a wildcard.
    assert!(by(Filter {
        job: Some("double_start".into()),
        ..Filter::default()
    })
    .await
    .is_empty());
    assert_eq!(
        by(Filter {
            machine: Some("modbus".into()),
            ..Filter::default()
        })
        .await,
        [resumed_id, stream_id]
    );
    assert_eq!(
        by(Filter {
            outcome: Some(Outcome::Running),
            ..Filter::default()
        })
        .await,
        [resumed_id]
    );
    assert_eq!(
        by(Filter {
            outcome: Some(Outcome::Stopped),
            ..Filter::default()
        })
        .await,
        [stream_id]
    );
    let tomorrow = Timestamp(Timestamp::now().0 + 86_400_000);
    let yesterday = Timestamp(Timestamp::now().0 - 86_400_000);
    assert!(by(Filter {
        since: Some(tomorrow),
        ..Filter::default()
    })
    .await
    .is_empty());
    assert_eq!(
        by(Filter {
            since: Some(yesterday),
            until: Some(tomorrow),
            ..Filter::default()
        })
        .await
        .len(),
        4
    );
    assert!(by(Filter {
        until: Some(yesterday),
        ..Filter::default()
    })
    .await
    .is_empty());
    assert_eq!(
        by(Filter {
            limit: Some(2),
            ..Filter::default()
        })
        .await,
        [unrelated_id, resumed_id]
    );

    // Writers at once each get a record of their own.
    let mut writers = tokio::task::JoinSet::new();
    for k in 0..8 {
        let store = store.clone();
        writers.spawn(async move {
            store
                .begin(&new_run(
                    Kind::DryRun,
                    &format!("jobs/{k}.toml"),
                    "sim",
                    None,
                ))
                .await
                .unwrap()
                .id
        });
    }
    let mut ids = writers.join_all().await;
    ids.sort_unstable();
    ids.dedup();
    assert_eq!(ids.len(), 8);

    orphans(&store).await;
    store.close_connections().await;
}

/// Records left running: this process's stays, another host's stays, a process that is
/// gone has its record closed from its log.
async fn orphans(store: &Store) {
    let dir = tempfile::tempdir().unwrap();
    let here = Process::current();
    let mut child = Command::new("true").spawn().unwrap();
    let gone_pid = child.id();
    child.wait().unwrap();
    // The gone run's log: another run before it, then its own events, cut off mid-run.
    let log = dir.path().join("exec.jsonl");
    let mut exec = whirl::log::ExecLog::append(&log).unwrap();
    let start = || whirl::log::Event::Start {
        program: "p.nc".into(),
        lines: 100,
        transport: "serial".into(),
    };
    exec.write(0.0, start()).unwrap();
    exec.write(
        0.1,
        whirl::log::Event::End {
            completed: true,
            reason: None,
        },
    )
    .unwrap();
    let offset = std::fs::metadata(&log).unwrap().len();
    exec.write(0.0, start()).unwrap();
    for line in 1..=30 {
        exec.write(
            0.01 * line as f64,
            whirl::log::Event::Sent {
                line,
                text: format!("N{line} G1 X1"),
            },
        )
        .unwrap();
    }
    exec.write(
        0.5,
        whirl::log::Event::Status {
            state: "Run".into(),
            pos: [0.0; 3],
            blocks_free: None,
            rx_free: None,
            line: Some(21),
        },
    )
    .unwrap();
    let before = std::fs::read(&log).unwrap();

    let mut gone = new_run(Kind::Stream, "jobs/gone.toml", "sim", None);
    gone.process = Process {
        pid: gone_pid,
        ..here.clone()
    };
    gone.log = Some(LogPlace {
        path: log.clone(),
        offset,
    });
    let gone_id = store.begin(&gone).await.unwrap().id;
    let mut elsewhere = new_run(Kind::Stream, "jobs/elsewhere.toml", "sim", None);
    elsewhere.process = Process {
        host: format!("{}-elsewhere", here.host),
        pid: gone_pid,
        ..here.clone()
    };
    let elsewhere_id = store.begin(&elsewhere).await.unwrap().id;
    let mine_id = store
        .begin(&new_run(Kind::Stream, "jobs/mine.toml", "sim", None))
        .await
        .unwrap()
        .id;

    let closed = store.close_orphans(&here).await.unwrap();
    assert!(
        closed.contains(&(gone_id, Outcome::Interrupted)),
        "{closed:?}"
    );
    assert!(!closed
        .iter()
        .any(|(id, _)| *id == elsewhere_id || *id == mine_id));
    let run = store.show(gone_id).await.unwrap().unwrap();
    assert_eq!(run.summary.outcome, Outcome::Interrupted);
    // Line 21 was executing: 1 to 20 are done; the controller may have run all it had.
    assert_eq!(
        (run.summary.resume_at, run.last_line, run.possibly_run_to),
        (Some(21), Some(20), Some(30))
    );
    assert!(run
        .summary
        .reason
        .as_deref()
        .unwrap()
        .contains(&gone_pid.to_string()));
    assert_eq!(
        run.notes.last().map(|n| (n.kind, n.line)),
        Some((NoteKind::Stop, Some(21)))
    );
    // It ended at its log's last event (0.5 s after it started), not now.
    let (started, ended) = (
        Timestamp::parse(&run.summary.started_at).unwrap(),
        Timestamp::parse(run.summary.ended_at.as_deref().unwrap()).unwrap(),
    );
    assert_eq!(ended.0 - started.0, 500);
    for id in [elsewhere_id, mine_id] {
        let run = store.show(id).await.unwrap().unwrap();
        assert_eq!(run.summary.outcome, Outcome::Running);
    }
    // The log was only read.
    assert_eq!(std::fs::read(&log).unwrap(), before);
    // Once closed, it is not closed again.
    let again = store.close_orphans(&here).await.unwrap();
    assert!(!again.iter().any(|(id, _)| *id == gone_id));
}

#[test]
fn the_store_keeps_and_finds_runs_in_sqlite() {
    let dir = tempfile::tempdir().unwrap();
    // A folder that does not exist yet: made on first use.
    let file = dir.path().join("records").join("runs.sqlite");
    block_on(store_suite(
        Place::parse(&file.display().to_string()).unwrap(),
    ));
    assert!(file.is_file());
}

#[test]
fn the_store_keeps_and_finds_runs_in_postgresql() {
    let Some(server) = postgres() else { return };
    block_on(store_suite(Place::parse(&server.database()).unwrap()));
}

#[test]
fn a_database_that_cannot_be_opened_is_said_naming_it() {
    let dead = dead_postgres_url();
    let error = block_on(Store::open(&Place::parse(&dead).unwrap()))
        .unwrap_err()
        .to_string();
    assert!(error.contains(&dead), "{error}");
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("runs.sqlite");
    let url = format!("sqlite://{}?mode=rw", missing.display());
    let error = block_on(Store::open(&Place::parse(&url).unwrap()))
        .unwrap_err()
        .to_string();
    assert!(error.contains(&missing.display().to_string()), "{error}");
    assert!(
        !missing.exists(),
        "a database is not made where the URL says not to"
    );
    // A file that is not a database is left as it was.
    let not_db = util::write(dir.path(), "notes.txt", "shopping list\n");
    let error = block_on(Store::open(
        &Place::parse(&not_db.display().to_string()).unwrap(),
    ))
    .unwrap_err()
    .to_string();
    assert!(error.contains("notes.txt"), "{error}");
    assert_eq!(std::fs::read_to_string(&not_db).unwrap(), "shopping list\n");
}

#[test]
fn a_sqlite_file_damaged_in_its_middle_is_refused_when_opened_and_kept_as_it_was() {
    let dir = tempfile::tempdir().unwrap();
    let home = dir.path();
    let file = dir.path().join("runs.sqlite");
    let db = file.display().to_string();
    // Records enough to fill pages beyond the first (each plan keeps its job and machine
    // texts and its report).
    for example in util::examples() {
        let program = dir.path().join("p.nc");
        let o = whirl_in(
            &db,
            home,
            &[
                OsStr::new("plan"),
                example.as_os_str(),
                OsStr::new("-o"),
                program.as_os_str(),
            ],
        );
        assert!(o.status.success(), "{}", stderr(&o));
    }
    // The middle pages overwritten, the first (the header and the schema) left whole: the
    // file opens as a database, and its damage shows only where a query reads.
    let mut bytes = std::fs::read(&file).unwrap();
    let page = 4096;
    let pages = bytes.len() / page;
    assert!(pages >= 4, "{pages} pages");
    for byte in &mut bytes[page * (pages / 3)..page * (2 * pages / 3)] {
        *byte = 0xA5;
    }
    std::fs::write(&file, &bytes).unwrap();
    let program = dir.path().join("q.nc");
    let job = util::example("trapezoidal");
    for args in [
        vec![OsStr::new("runs"), OsStr::new("list")],
        vec![
            OsStr::new("plan"),
            job.as_os_str(),
            OsStr::new("-o"),
            program.as_os_str(),
        ],
    ] {
        let o = whirl_in(&db, home, &args);
        let error = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {error}");
        assert!(
            error.contains(&format!("the run records at {db} are damaged"))
                && error.contains(&format!("mv {db} {db}.damaged"))
                && error.contains(".recover"),
            "{args:?}: {error}"
        );
        assert!(!program.exists(), "{args:?}: a program was written");
    }
    // Nothing recorded was lost: the file is as the damage left it.
    assert_eq!(std::fs::read(&file).unwrap(), bytes);
}

// ---------------------------------------------------------------------------------------
// One database for a whole shop: many bridges at once, and the spool.

/// The pid of a process that has ended: a bridge killed outright.
fn gone_pid() -> u32 {
    let mut child = Command::new("true").spawn().unwrap();
    let pid = child.id();
    child.wait().unwrap();
    pid
}

/// Every run in `store`, whole, oldest first.
async fn every_run(store: &Store) -> Vec<whirl::records::Run> {
    let mut runs = Vec::new();
    for summary in store.list(&Filter::default()).await.unwrap().iter().rev() {
        runs.push(store.show(summary.id).await.unwrap().unwrap());
    }
    runs
}

#[test]
fn twenty_bridges_at_once_on_one_postgresql_record_every_run_once_with_its_notes() {
    let Some(server) = postgres() else { return };
    let place = Place::parse(&server.database()).unwrap();
    // The schema made first, as a shop's database has it before its bridges start.
    block_on(async { Store::open(&place).await.unwrap().close_connections().await });
    const BRIDGES: usize = 20;
    const RUNS: usize = 3;
    const NOTES: usize = 4;
    // Each bridge its own process's worth of connections (a store of its own, on a thread
    // of its own), all let go at once.
    let start = Arc::new(std::sync::Barrier::new(BRIDGES));
    let began = Instant::now();
    let bridges: Vec<_> = (0..BRIDGES)
        .map(|b| {
            let (place, start) = (place.clone(), Arc::clone(&start));
            std::thread::spawn(move || {
                block_on(async move {
                    let store = Store::open(&place).await.unwrap();
                    start.wait();
                    let mut recorded = Vec::new();
                    for r in 0..RUNS {
                        let name = format!("bridge {b} run {r}");
                        let job = format!("jobs/{b}-{r}.toml");
                        let machine = format!("lathe-{b}");
                        let run = store
                            .begin(&new_run(Kind::Stream, &job, &machine, None))
                            .await
                            .unwrap();
                        assert_eq!(run.kept, Kept::Database);
                        for n in 0..NOTES {
                            let note = Note {
                                line: Some(n + 1),
                                ..Note::new(NoteKind::Hold, format!("{name} hold {n}"))
                            };
                            assert_eq!(store.note(&run, &note).await.unwrap(), Kept::Database);
                        }
                        let mut stopped = Ending::new(Outcome::Stopped);
                        stopped.reason = Some(format!("{name} stopped"));
                        stopped.resume_at = Some(NOTES + 1);
                        let finished = store.finish(&run, &stopped).await.unwrap();
                        assert!(finished.closed && finished.kept == Kept::Database);
                        recorded.push((run.id, run.uid, name));
                    }
                    store.close_connections().await;
                    recorded
                })
            })
        })
        .collect();
    let recorded: Vec<_> = bridges
        .into_iter()
        .flat_map(|b| b.join().unwrap())
        .collect();
    eprintln!(
        "{BRIDGES} bridges at once, {RUNS} runs each, each noted {NOTES} times and closed: {:?}",
        began.elapsed()
    );
    // Numbers 1 to 60, each run its own; keys all different.
    let mut ids: Vec<i64> = recorded.iter().map(|(id, _, _)| *id).collect();
    ids.sort_unstable();
    assert_eq!(ids, (1..=(BRIDGES * RUNS) as i64).collect::<Vec<_>>());
    let keys: std::collections::HashSet<_> = recorded.iter().map(|(_, uid, _)| uid).collect();
    assert_eq!(keys.len(), BRIDGES * RUNS);
    // The database holds those runs and no others, each whole: its notes in the order
    // they were written, then its stop.
    block_on(async {
        let store = Store::open(&place).await.unwrap();
        let runs = every_run(&store).await;
        let mut listed: Vec<i64> = runs.iter().map(|r| r.summary.id).collect();
        listed.sort_unstable();
        assert_eq!(listed, ids);
        for (id, uid, name) in &recorded {
            let run = runs.iter().find(|r| r.summary.id == *id).unwrap();
            assert_eq!(run.uid.as_ref(), Some(uid));
            assert_eq!(run.summary.outcome, Outcome::Stopped);
            let mut expected: Vec<(NoteKind, String)> = (0..NOTES)
                .map(|n| (NoteKind::Hold, format!("{name} hold {n}")))
                .collect();
            expected.push((NoteKind::Stop, format!("{name} stopped")));
            let notes: Vec<(NoteKind, String)> =
                run.notes.iter().map(|n| (n.kind, n.text.clone())).collect();
            assert_eq!(notes, expected);
        }
        store.close_connections().await;
    });
}

/// The files of the SQLite file `file` (with its write-ahead log, if it has one), to put
/// back as they were.
fn sqlite_files(file: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    ["", "-wal", "-shm"]
        .iter()
        .filter_map(|suffix| {
            let path = PathBuf::from(format!("{}{suffix}", file.display()));
            std::fs::read(&path).ok().map(|bytes| (path, bytes))
        })
        .collect()
}

fn put_back(file: &Path, files: &[(PathBuf, Vec<u8>)]) {
    for suffix in ["", "-wal", "-shm"] {
        let _ = std::fs::remove_file(format!("{}{suffix}", file.display()));
    }
    for (path, bytes) in files {
        std::fs::write(path, bytes).unwrap();
    }
}

fn in_spool(kept: &Kept, spool: &Path) -> bool {
    matches!(kept, Kept::Spool { file, .. } if file == spool)
}

#[test]
fn a_postgresql_stopped_mid_run_keeps_the_runs_in_the_spool_and_the_next_opening_uploads_each_once()
{
    let Some(server) = private_postgres() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let place = Place::parse(&server.database())
        .unwrap()
        .with_spool_in(dir.path());
    let spool = place.spool().unwrap().to_owned();
    let here = Process::current();
    // One runtime for the whole test: a store's connections live on the runtime that
    // opened them.
    block_on(async {
        let first = Store::open(&place).await.unwrap();
        assert!(first.down().is_none() && first.uploaded().is_none());
        // A stream and a dry run begin in the database; the stream's hold is noted there.
        let a = first
            .begin(&new_run(Kind::Stream, "jobs/a.toml", "lathe-a", None))
            .await
            .unwrap();
        let b = first
            .begin(&new_run(Kind::DryRun, "jobs/b.toml", "lathe-b", None))
            .await
            .unwrap();
        assert_eq!((&a.kept, &b.kept), (&Kept::Database, &Kept::Database));
        let hold = Note {
            line: Some(40),
            ..Note::new(NoteKind::Hold, "held")
        };
        assert_eq!(first.note(&a, &hold).await.unwrap(), Kept::Database);
        assert!(!spool.exists(), "a spool is made only when it is needed");

        server.stop();
        // The stream's resume and the dry run's end cannot reach it: each kept in the spool,
        // after a copy of its run's beginning.
        let resumed = first
            .note(&a, &Note::new(NoteKind::Resume, "resumed"))
            .await
            .unwrap();
        assert!(in_spool(&resumed, &spool), "{resumed:?}");
        let b_end = first
            .finish(&b, &Ending::new(Outcome::Completed))
            .await
            .unwrap();
        assert!(b_end.closed && in_spool(&b_end.kept, &spool), "{b_end:?}");
        // A bridge that starts while it is down opens its records all the same, its runs in
        // the spool from their beginning: a plan, a stream still running when the database
        // is back, and a stream whose bridge is killed.
        let second = Store::open(&place).await.unwrap();
        let why = second.down().expect("the database is down").to_owned();
        assert!(why.contains(second.place()), "{why}");
        let c = second
            .begin(&new_run(Kind::Plan, "jobs/c.toml", "lathe-c", None))
            .await
            .unwrap();
        assert!(in_spool(&c.kept, &spool), "{c:?}");
        let alarm = Note {
            code: Some(9),
            ..Note::new(NoteKind::Alarm, "homing fail")
        };
        assert!(in_spool(&second.note(&c, &alarm).await.unwrap(), &spool));
        assert!(
            second
                .finish(&c, &Ending::new(Outcome::Completed))
                .await
                .unwrap()
                .closed
        );
        let d = second
            .begin(&new_run(Kind::Stream, "jobs/d.toml", "lathe-d", None))
            .await
            .unwrap();
        let mut killed = new_run(Kind::Stream, "jobs/e.toml", "lathe-e", None);
        killed.process = Process {
            pid: gone_pid(),
            ..here.clone()
        };
        let e = second.begin(&killed).await.unwrap();
        assert!(in_spool(&e.kept, &spool));
        // While it is down, the history cannot be read, and says which database.
        let error = second
            .list(&Filter::default())
            .await
            .unwrap_err()
            .to_string();
        assert!(error.contains(second.place()), "{error}");

        server.start_again();
        // The stream's end goes after its resume, to the spool, though the database is
        // back: a run's writes stay in their order.
        let mut stopped = Ending::new(Outcome::Stopped);
        stopped.reason = Some("ALARM:3".into());
        stopped.resume_at = Some(120);
        stopped.notes = vec![Note {
            code: Some(3),
            ..Note::new(NoteKind::Alarm, "reset while in motion")
        }];
        let a_end = first.finish(&a, &stopped).await.unwrap();
        assert!(a_end.closed && in_spool(&a_end.kept, &spool), "{a_end:?}");
        first.close_connections().await;
        second.close_connections().await;
        let before_upload = sqlite_files(&spool);

        // The next opening uploads every run whose process is done with it: the killed
        // bridge's closed first, as interrupted; the running stream waits.
        let third = Store::open(&place).await.unwrap();
        let uploaded = third.uploaded().unwrap().as_ref().unwrap().clone();
        assert_eq!(uploaded.runs.len(), 4, "{uploaded:?}");
        assert_eq!(uploaded.waiting, 1, "{uploaded:?}");
        let runs = every_run(&third).await;
        let by_key = |uid: &whirl::records::Uid| {
            let found: Vec<_> = runs
                .iter()
                .filter(|r| r.uid.as_ref() == Some(uid))
                .collect();
            assert_eq!(found.len(), 1, "{uid}: {runs:?}");
            found[0].clone()
        };
        assert_eq!(runs.len(), 4, "{runs:?}");
        // Begun in the database: the same numbers, completed from the spool.
        let a_run = by_key(&a.uid);
        assert_eq!(a_run.summary.id, a.id);
        assert_eq!(a_run.summary.outcome, Outcome::Stopped);
        assert_eq!(a_run.summary.resume_at, Some(120));
        let notes: Vec<(NoteKind, &str)> = a_run
            .notes
            .iter()
            .map(|n| (n.kind, n.text.as_str()))
            .collect();
        assert_eq!(
            notes,
            [
                (NoteKind::Hold, "held"),
                (NoteKind::Resume, "resumed"),
                (NoteKind::Alarm, "reset while in motion"),
                (NoteKind::Stop, "ALARM:3"),
            ]
        );
        let b_run = by_key(&b.uid);
        assert_eq!(
            (b_run.summary.id, b_run.summary.outcome),
            (b.id, Outcome::Completed)
        );
        assert!(b_run.notes.is_empty());
        // Begun in the spool: whole, numbered by the database.
        let c_run = by_key(&c.uid);
        assert!(![a.id, b.id].contains(&c_run.summary.id));
        assert_eq!(c_run.summary.outcome, Outcome::Completed);
        assert_eq!(c_run.summary.machine.as_deref(), Some("lathe-c"));
        assert_eq!(
            c_run.job_file,
            new_run(Kind::Plan, "jobs/c.toml", "x", None).job
        );
        assert_eq!(
            c_run.notes.iter().map(|n| n.code).collect::<Vec<_>>(),
            [Some(9)]
        );
        let e_run = by_key(&e.uid);
        assert_eq!(e_run.summary.outcome, Outcome::Interrupted);
        assert_eq!(e_run.summary.host, here.host);
        // The running stream, closed, goes with the next upload.
        let d_end = third
            .finish(&d, &Ending::new(Outcome::Completed))
            .await
            .unwrap();
        assert!(d_end.closed && in_spool(&d_end.kept, &spool));
        let later = third.upload().await.unwrap();
        assert_eq!((later.runs.len(), later.waiting), (1, 0), "{later:?}");
        assert_eq!(
            third.show(later.runs[0].1).await.unwrap().unwrap().uid,
            Some(d.uid.clone())
        );
        assert_eq!(third.upload().await.unwrap(), Default::default());
        let after = every_run(&third).await;
        assert_eq!(after.len(), 5);
        third.close_connections().await;

        // An upload cut short between the database's commit and the spool's removal: the
        // spool as it was before, uploaded again, finds every run by its key and adds
        // nothing.
        put_back(&spool, &before_upload);
        let fourth = Store::open(&place).await.unwrap();
        let again = fourth.uploaded().unwrap().as_ref().unwrap();
        assert_eq!(again.runs, uploaded.runs);
        assert_eq!(every_run(&fourth).await, after);
        fourth.close_connections().await;
    });
}

#[test]
fn a_postgresql_that_stops_answering_never_holds_a_run_up() {
    let Some(server) = private_postgres() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let place = Place::parse(&server.database())
        .unwrap()
        .with_spool_in(dir.path());
    // A call that waited on a server that does not answer would wait as long as TCP does
    // (minutes to hours); each waits the bound, and a minute is room enough for a loaded
    // host to notice the bound has passed.
    let held_up = Duration::from_secs(60);
    block_on(async {
        let store = Store::open(&place).await.unwrap();
        let run = store
            .begin(&new_run(Kind::Stream, "jobs/a.toml", "lathe-a", None))
            .await
            .unwrap();
        assert_eq!(run.kept, Kept::Database);
        server.signal_all("STOP");
        let asked = Instant::now();
        let finished = store
            .finish(&run, &Ending::new(Outcome::Completed))
            .await
            .unwrap();
        let waited = asked.elapsed();
        assert!(waited >= POSTGRES_TIMEOUT && waited < held_up, "{waited:?}");
        let Kept::Spool { why, .. } = &finished.kept else {
            panic!("{finished:?}");
        };
        assert!(why.contains("no answer within"), "{why}");
        // A bridge that starts meanwhile opens its records within the bound, and its run
        // begins in the spool straight away.
        let asked = Instant::now();
        let other = Store::open(&place).await.unwrap();
        assert!(
            other
                .down()
                .is_some_and(|why| why.contains("no answer within")),
            "{:?}",
            other.down()
        );
        let begun = other
            .begin(&new_run(Kind::Plan, "jobs/b.toml", "lathe-b", None))
            .await
            .unwrap();
        assert!(matches!(begun.kept, Kept::Spool { .. }));
        assert!(
            other
                .finish(&begun, &Ending::new(Outcome::Completed))
                .await
                .unwrap()
                .closed
        );
        assert!(asked.elapsed() < held_up, "{:?}", asked.elapsed());
        server.signal_all("CONT");
        store.close_connections().await;
        other.close_connections().await;
        let after = Store::open(&place).await.unwrap();
        let uploaded = after.uploaded().unwrap().as_ref().unwrap();
        assert_eq!(uploaded.runs.len(), 2, "{uploaded:?}");
        for key in [&run.uid, &begun.uid] {
            let runs = every_run(&after).await;
            let run = runs.iter().find(|r| r.uid.as_ref() == Some(key)).unwrap();
            assert_eq!(run.summary.outcome, Outcome::Completed);
        }
        after.close_connections().await;
    });
}

#[test]
fn a_postgresql_that_cannot_be_reached_nor_its_run_kept_in_the_spool_is_said_naming_both() {
    let dead = dead_postgres_url();
    let dir = tempfile::tempdir().unwrap();
    // The data folder is a file: no spool can be made in it.
    let data = util::write(dir.path(), "data", "not a folder\n");
    let place = Place::parse(&dead).unwrap().with_spool_in(&data);
    let spool = place.spool().unwrap().display().to_string();
    let error = block_on(Store::open(&place)).unwrap_err().to_string();
    assert!(error.contains(&dead) && error.contains(&spool), "{error}");
}

#[test]
fn a_spool_that_cannot_be_read_is_said_left_as_it_is_and_runs_are_recorded_all_the_same() {
    let Some(server) = postgres() else { return };
    let dir = tempfile::tempdir().unwrap();
    let place = Place::parse(&server.database())
        .unwrap()
        .with_spool_in(dir.path());
    let spool = place.spool().unwrap().to_owned();
    std::fs::create_dir_all(spool.parent().unwrap()).unwrap();
    std::fs::write(&spool, "shopping list\n").unwrap();
    block_on(async {
        let store = Store::open(&place).await.unwrap();
        let error = store.uploaded().unwrap().as_ref().unwrap_err().to_string();
        assert!(error.contains(&spool.display().to_string()), "{error}");
        let run = store
            .begin(&new_run(Kind::Plan, "jobs/a.toml", "lathe-a", None))
            .await
            .unwrap();
        assert_eq!(run.kept, Kept::Database);
        assert!(
            store
                .finish(&run, &Ending::new(Outcome::Completed))
                .await
                .unwrap()
                .closed
        );
        store.close_connections().await;
    });
    assert_eq!(std::fs::read_to_string(&spool).unwrap(), "shopping list\n");
}

// ---------------------------------------------------------------------------------------
// The command line.

/// `whirl` with `args`, its records in `db`, its home a folder of the test's.
fn whirl_in(db: &str, home: &Path, args: &[&OsStr]) -> Output {
    whirl_command(db, home)
        .args(args)
        .output()
        .expect("the whirl binary runs")
}

fn whirl_command(db: &str, home: &Path) -> Command {
    let mut command = Command::new(env!("CARGO_BIN_EXE_whirl"));
    command
        .env("WHIRL_DB", db)
        .env("HOME", home)
        .env_remove("XDG_DATA_HOME");
    command
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// `whirl runs list --json [filters…]`.
fn list(db: &str, home: &Path, filters: &[&str]) -> Vec<Value> {
    let mut args = vec![OsStr::new("runs"), OsStr::new("list"), OsStr::new("--json")];
    args.extend(filters.iter().map(OsStr::new));
    let o = whirl_in(db, home, &args);
    assert!(o.status.success(), "{}", stderr(&o));
    serde_json::from_slice::<Value>(&o.stdout)
        .unwrap()
        .as_array()
        .unwrap()
        .clone()
}

/// `whirl runs show ID --json`.
fn show(db: &str, home: &Path, id: &Value) -> Value {
    let id = id.to_string();
    let o = whirl_in(
        db,
        home,
        &[
            OsStr::new("runs"),
            OsStr::new("show"),
            OsStr::new(&id),
            OsStr::new("--json"),
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    serde_json::from_slice(&o.stdout).unwrap()
}

/// A short program of the planned program `planned` (its lead-in and 60 linked moves, then
/// the retract), written to `dir/short.nc`.
fn short_of(planned: &Path, dir: &Path) -> PathBuf {
    let text = std::fs::read_to_string(planned).unwrap();
    // Its provenance header kept: the job and the machine are those it was planned from.
    let header = text
        .lines()
        .take_while(|l| l.contains("whirl provenance"))
        .count();
    let mut lines: Vec<&str> = text.lines().take(header + 66).collect();
    lines.extend(["G94", "G0 X0", "M5", "M2"]);
    util::write(dir, "short.nc", &(lines.join("\n") + "\n"))
}

/// The double-start example planned to `dir/planned.nc`, recorded in a database of its
/// own.
fn planned(dir: &Path) -> PathBuf {
    let planned = dir.join("planned.nc");
    let o = util::whirl(&[
        OsStr::new("plan"),
        util::example("double-start").as_os_str(),
        OsStr::new("-o"),
        planned.as_os_str(),
        OsStr::new("--db"),
        dir.join("plans.sqlite").as_os_str(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    planned
}

#[test]
fn every_command_records_its_run_and_runs_list_and_show_find_them() {
    let dir = tempfile::tempdir().unwrap();
    let home = dir.path().join("home");
    std::fs::create_dir(&home).unwrap();
    let db = dir.path().join("runs.sqlite").display().to_string();
    let job = util::example("double-start");
    let job_text = std::fs::read(&job).unwrap();

    // plan: the program it wrote, by hash, and its report.
    let program = dir.path().join("p.nc");
    let report = dir.path().join("plan.json");
    let o = whirl_in(
        &db,
        &home,
        &[
            OsStr::new("plan"),
            job.as_os_str(),
            OsStr::new("-o"),
            program.as_os_str(),
            OsStr::new("--report"),
            report.as_os_str(),
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    // dry-run of a short program of the job, with a log.
    let short = short_of(&program, dir.path());
    let log = dir.path().join("dry.jsonl");
    let dry_report = dir.path().join("dry.json");
    let o = whirl_in(
        &db,
        &home,
        &[
            OsStr::new("dry-run"),
            job.as_os_str(),
            OsStr::new("--program"),
            short.as_os_str(),
            OsStr::new("--log"),
            log.as_os_str(),
            OsStr::new("--report"),
            dry_report.as_os_str(),
        ],
    );
    // Whatever the simulator measured of this cut-short program, its exit code and its
    // record say the same.
    let dry_json: Value =
        serde_json::from_str(&std::fs::read_to_string(&dry_report).unwrap()).unwrap();
    let dry_outcome = if dry_json["completed"] == true {
        "completed"
    } else {
        "stopped"
    };
    assert_eq!(
        o.status.code() == Some(0),
        dry_json["within_delta"] == true,
        "{}",
        stderr(&o)
    );
    // stream of the short program to the simulator.
    let link = dir.path().join("grbl");
    let sim = Sim::serving(
        OsStr::new("--pty"),
        &link,
        &[OsStr::new("--time-scale"), OsStr::new("0")],
    );
    let stream_log = dir.path().join("stream.jsonl");
    let o = whirl_in(
        &db,
        &home,
        &[
            OsStr::new("stream"),
            short.as_os_str(),
            OsStr::new("--port"),
            link.as_os_str(),
            OsStr::new("--log"),
            stream_log.as_os_str(),
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    drop(sim);
    // A command that is not a run records nothing.
    let o = whirl_in(
        &db,
        &home,
        &[OsStr::new("log"), OsStr::new("summary"), log.as_os_str()],
    );
    assert!(o.status.success(), "{}", stderr(&o));

    let runs = list(&db, &home, &[]);
    let kinds: Vec<&str> = runs.iter().map(|r| r["kind"].as_str().unwrap()).collect();
    assert_eq!(kinds, ["stream", "dry-run", "plan"], "newest first");
    let outcomes: Vec<&str> = runs
        .iter()
        .map(|r| r["outcome"].as_str().unwrap())
        .collect();
    assert_eq!(outcomes, ["completed", dry_outcome, "completed"]);
    // The database was the one named: nothing in the home folder.
    assert!(!home.join(".local").exists());

    let plan = show(&db, &home, &runs[2]["id"]);
    assert_eq!(
        plan["job_file"]["sha256"],
        whirl::records::sha256_hex(&job_text)
    );
    assert_eq!(
        plan["job_file"]["text"],
        String::from_utf8_lossy(&job_text).as_ref()
    );
    assert_eq!(
        plan["machine_file"]["path"],
        "machine-profiles/sim.toml (built in)"
    );
    let written = std::fs::read_to_string(&program).unwrap();
    assert_eq!(
        plan["program_id"]["sha256"],
        ProgramId::of("", &written).sha256.as_str()
    );
    assert_eq!(plan["program_id"]["lines"], written.lines().count());
    let plan_report: Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(plan["plan_report"], plan_report);

    let dry = show(&db, &home, &runs[1]["id"]);
    assert_eq!(
        dry["measured"]["max_overcut_mm"],
        dry_json["max_overcut_mm"]
    );
    assert_eq!(
        dry["measured"]["max_undercut_mm"],
        dry_json["max_undercut_mm"]
    );
    assert_eq!(dry["measured"]["delta_mm"], dry_json["delta_mm"]);
    assert_eq!(dry["measured"]["within_delta"], dry_json["within_delta"]);
    // Its alarms, in order, then its stop if it stopped.
    let alarms: Vec<&Value> = dry_json["alarms"]
        .as_array()
        .unwrap()
        .iter()
        .map(|a| &a["code"])
        .collect();
    let notes = dry["notes"].as_array().unwrap();
    let noted: Vec<&Value> = notes
        .iter()
        .filter(|n| n["kind"] == "alarm")
        .map(|n| &n["code"])
        .collect();
    assert_eq!(noted, alarms);
    assert_eq!(
        notes.iter().any(|n| n["kind"] == "stop"),
        dry_outcome == "stopped"
    );
    assert_eq!(
        dry["plan_report"],
        Value::Null,
        "a given program is not planned"
    );
    assert_eq!(dry["transport"], "serial");
    assert_eq!(
        dry["log"]["path"],
        std::path::absolute(&log).unwrap().display().to_string()
    );
    assert_eq!(dry["log"]["offset"], 0);
    assert_eq!(
        dry["program_id"]["sha256"],
        ProgramId::of("", &std::fs::read_to_string(&short).unwrap())
            .sha256
            .as_str()
    );

    let stream = show(&db, &home, &runs[0]["id"]);
    assert_eq!(stream["transport"], "serial");
    assert!(stream["port"]
        .as_str()
        .unwrap()
        .contains(&link.display().to_string()));
    // The bridge's process on this host, not the test's.
    assert_eq!(stream["host"], Process::current().host);
    assert!(stream["pid"]
        .as_u64()
        .is_some_and(|pid| pid != u64::from(std::process::id())));
    assert_eq!(
        stream["job_file"],
        Value::Null,
        "a program, not a job, was streamed"
    );
    assert_eq!(stream["program"], short.display().to_string());

    // The filters.
    let ids =
        |runs: Vec<Value>| -> Vec<i64> { runs.iter().map(|r| r["id"].as_i64().unwrap()).collect() };
    let id = |k: usize| runs[k]["id"].as_i64().unwrap();
    // The dry run ran short.nc for the job: found by either.
    assert_eq!(
        ids(list(&db, &home, &["--job", "SHORT.nc"])),
        [id(0), id(1)]
    );
    assert_eq!(
        ids(list(&db, &home, &["--job", "double-start/job.toml"])),
        [id(1), id(2)]
    );
    assert_eq!(
        ids(list(&db, &home, &["--machine", "no such machine"])),
        Vec::<i64>::new()
    );
    let completed: Vec<i64> = (0..3)
        .filter(|&k| runs[k]["outcome"] == "completed")
        .map(id)
        .collect();
    assert_eq!(
        ids(list(&db, &home, &["--outcome", "completed"])),
        completed
    );
    assert_eq!(
        ids(list(
            &db,
            &home,
            &["--outcome", "completed", "--limit", "1"]
        )),
        [id(0)]
    );
    assert!(list(&db, &home, &["--outcome", "interrupted"]).is_empty());
    assert!(list(&db, &home, &["--since", "2999-01-01"]).is_empty());
    assert_eq!(
        list(
            &db,
            &home,
            &["--since", "2000-01-01", "--until", "2999-01-01T00:00"]
        )
        .len(),
        3
    );

    // The table and the text.
    let o = whirl_in(&db, &home, &[OsStr::new("runs"), OsStr::new("list")]);
    let table = String::from_utf8_lossy(&o.stdout);
    assert_eq!(table.lines().count(), 4, "{table}");
    assert!(table.lines().nth(1).unwrap().contains("stream"), "{table}");
    let o = whirl_in(
        &db,
        &home,
        &[
            OsStr::new("runs"),
            OsStr::new("show"),
            OsStr::new(&id(1).to_string()),
        ],
    );
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.starts_with(&format!("run {}: dry-run, {dry_outcome}", id(1))),
        "{text}"
    );
    assert!(
        text.contains(&whirl::records::sha256_hex(&job_text)),
        "{text}"
    );

    // --db comes before WHIRL_DB: another database, with nothing in it.
    let other = dir.path().join("other.sqlite");
    let o = whirl_in(
        &db,
        &home,
        &[
            OsStr::new("runs"),
            OsStr::new("list"),
            OsStr::new("--json"),
            OsStr::new("--db"),
            other.as_os_str(),
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        serde_json::from_slice::<Value>(&o.stdout).unwrap(),
        Value::Array(vec![])
    );
}

#[test]
fn runs_refuses_what_it_cannot_read_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("runs.sqlite").display().to_string();
    let home = dir.path();
    for (args, named) in [
        (vec!["runs", "list", "--since", "yesterday"], "--since"),
        (vec!["runs", "list", "--since", "2025-02-29"], "--since"),
        (vec!["runs", "list", "--outcome", "done"], "--outcome"),
        (vec!["runs", "list", "--limit", "0"], "--limit"),
        (vec!["runs", "show", "x"], "ID"),
    ] {
        let args: Vec<&OsStr> = args.iter().map(OsStr::new).collect();
        let o = whirl_in(&db, home, &args);
        assert_eq!(o.status.code(), Some(2), "{args:?}");
        assert!(stderr(&o).contains(named), "{args:?}: {}", stderr(&o));
    }
    let o = whirl_in(
        &db,
        home,
        &[OsStr::new("runs"), OsStr::new("show"), OsStr::new("7")],
    );
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("no run 7") && stderr(&o).contains(&db),
        "{}",
        stderr(&o)
    );
    let o = whirl_in(
        "mysql://db/shop",
        home,
        &[OsStr::new("runs"), OsStr::new("list")],
    );
    assert!(
        !o.status.success() && stderr(&o).contains("mysql://"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn the_default_database_is_made_in_the_users_data_folder_on_first_use() {
    let dir = tempfile::tempdir().unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_whirl"))
        .args(["runs", "list"])
        .env_remove("WHIRL_DB")
        .env_remove("XDG_DATA_HOME")
        .env("HOME", dir.path())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(dir.path().join(".local/share/whirl/runs.sqlite").is_file());
    let xdg = dir.path().join("xdg");
    let o = Command::new(env!("CARGO_BIN_EXE_whirl"))
        .args(["runs", "list"])
        .env_remove("WHIRL_DB")
        .env("XDG_DATA_HOME", &xdg)
        .env("HOME", dir.path())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(xdg.join("whirl/runs.sqlite").is_file());
}

#[test]
fn a_database_that_cannot_be_written_nor_a_spool_keep_the_run_refuses_it_unless_told_to_go_on_unrecorded(
) {
    let dir = tempfile::tempdir().unwrap();
    let short = short_of(&planned(dir.path()), dir.path());
    let link = dir.path().join("grbl");
    let _sim = Sim::serving(
        OsStr::new("--pty"),
        &link,
        &[OsStr::new("--time-scale"), OsStr::new("0")],
    );
    let log = dir.path().join("exec.jsonl");
    let stream = |db: &str, extra: &[&OsStr]| {
        let mut args = vec![
            OsStr::new("stream"),
            short.as_os_str(),
            OsStr::new("--port"),
            link.as_os_str(),
            OsStr::new("--log"),
            log.as_os_str(),
        ];
        args.extend_from_slice(extra);
        let mut command = whirl_command(db, dir.path());
        // A PostgreSQL's spool is in the user's data folder: without a home there is none,
        // and a run it cannot take is not kept anywhere.
        if db.starts_with("postgres://") {
            command.env_remove("HOME");
        }
        command.args(&args).output().expect("the whirl binary runs")
    };
    // A database that exists but is opened read-only (root writes any file, so the URL
    // says it), and a PostgreSQL that is down with no spool to keep the run.
    let file = dir.path().join("runs.sqlite");
    let o = whirl_in(
        &file.display().to_string(),
        dir.path(),
        &[OsStr::new("runs"), OsStr::new("list")],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let read_only = format!("sqlite://{}?mode=ro", file.display());
    for db in [read_only, dead_postgres_url()] {
        let shown = Place::parse(&db).unwrap().name();
        let o = stream(&db, &[]);
        assert_eq!(o.status.code(), Some(1), "{db}: {}", stderr(&o));
        let error = stderr(&o);
        assert!(
            error.contains(&shown) && error.contains("--allow-unrecorded"),
            "{error}"
        );
        assert!(error.contains("not started"), "{error}");
        // Nothing was run: no log.
        assert!(!log.exists(), "{db}");

        let o = stream(&db, &[OsStr::new("--allow-unrecorded")]);
        assert!(o.status.success(), "{db}: {}", stderr(&o));
        assert!(stderr(&o).contains("not recorded"), "{}", stderr(&o));
        assert!(
            stderr(&o).contains(&log.display().to_string()),
            "{}",
            stderr(&o)
        );
        // The run is whole in its log.
        let summary = whirl::log::Summary::of(&whirl::log::read(&log).unwrap());
        assert_eq!((summary.runs, summary.completed), (1, Some(true)));
        std::fs::remove_file(&log).unwrap();
    }
    assert!(list(&file.display().to_string(), dir.path(), &[]).is_empty());
}

/// The names and contents of the files in `dir`, in order.
fn contents(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut files: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_file())
        .map(|p| {
            let name = p.file_name().unwrap().to_string_lossy().into_owned();
            (name, std::fs::read(&p).unwrap())
        })
        .collect();
    files.sort();
    files
}

#[test]
fn a_database_that_is_one_of_the_runs_files_or_no_file_is_refused_before_anything_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let job = util::write(
        d,
        "job.toml",
        &std::fs::read_to_string(util::example("double-start")).unwrap(),
    );
    let machine = util::write(
        d,
        "machine.toml",
        &std::fs::read_to_string(util::root().join("machine-profiles/sim.toml")).unwrap(),
    );
    let program = util::write(d, "program.nc", "G0 X1\nM2\n");
    let log = util::write(
        d,
        "exec.jsonl",
        "{\"t\":0.0,\"event\":\"message\",\"text\":\"earlier\"}\n",
    );
    let report = util::write(d, "report.json", "{}\n");
    let output = util::write(d, "out.nc", "an earlier program\n");
    let link = d.join("job-link.toml");
    std::os::unix::fs::symlink(&job, &link).unwrap();
    let fifo = d.join("fifo");
    assert!(Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap()
        .success());
    let folder = d.join("folder");
    std::fs::create_dir(&folder).unwrap();
    let p = |path: &Path| path.display().to_string();
    let plan = |extra: &[&str]| {
        let mut args = vec!["plan".to_owned(), p(&job), "-o".into(), p(&output)];
        args.extend(extra.iter().map(|s| s.to_string()));
        args
    };
    let dry_run = vec![
        "dry-run".to_owned(),
        p(&job),
        "--log".into(),
        p(&log),
        "--report".into(),
        p(&report),
        "--machine".into(),
        p(&machine),
    ];
    let stream = vec![
        "stream".to_owned(),
        p(&program),
        "--port".into(),
        p(&d.join("no-such-port")),
        "--log".into(),
        p(&log),
    ];
    // (arguments, the database, what names it, why it is refused)
    let cases: Vec<(Vec<String>, PathBuf, &str, &str)> = vec![
        (
            plan(&[]),
            job.clone(),
            "--db",
            "it is the job file this run reads",
        ),
        (
            plan(&[]),
            link.clone(),
            "--db",
            "it is the job file this run reads",
        ),
        (
            plan(&[]),
            output.clone(),
            "--db",
            "it is the output -o of this run",
        ),
        (
            plan(&["--report", &p(&report)]),
            report.clone(),
            "--db",
            "it is the output --report of this run",
        ),
        (
            plan(&["--machine", &p(&machine)]),
            machine.clone(),
            "--db",
            "it is the machine profile (--machine) this run reads",
        ),
        (plan(&[]), folder.clone(), "--db", "it is a directory"),
        (plan(&[]), fifo.clone(), "--db", "it is a named pipe"),
        (
            plan(&[]),
            "/dev/null".into(),
            "--db",
            "it is a character device",
        ),
        (
            dry_run.clone(),
            log.clone(),
            "WHIRL_DB",
            "it is the log (--log) this run appends to",
        ),
        (
            dry_run.clone(),
            report.clone(),
            "WHIRL_DB",
            "it is the output --report of this run",
        ),
        (
            stream.clone(),
            program.clone(),
            "--db",
            "it is the program this run reads",
        ),
        (
            stream.clone(),
            log.clone(),
            "WHIRL_DB",
            "it is the log (--log) this run appends to",
        ),
    ];
    let before = contents(d);
    for (args, db, named, why) in cases {
        let mut command = whirl_command(&p(&d.join("unused.sqlite")), d);
        command.args(&args);
        if named == "--db" {
            command.arg("--db").arg(&db);
        } else {
            command.env("WHIRL_DB", &db);
        }
        let o = command.output().unwrap();
        let error = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{args:?} {db:?}: {error}");
        assert!(
            error.contains(&format!(
                "refusing to keep the run records in {} ({named}): {why}",
                db.display()
            )),
            "{args:?} {db:?}: {error}"
        );
        // Nothing written: every file as it was, no database, no program, no report.
        assert_eq!(contents(d), before, "{args:?} {db:?}");
    }
}

#[test]
fn a_run_whose_postgresql_is_down_is_kept_in_the_spool_and_uploaded_by_the_next_whirl() {
    let Some(server) = private_postgres() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let home = dir.path();
    let db = server.database();
    let shown = Place::parse(&db).unwrap().name();
    // The schema made while it is up, as a shop's is.
    assert!(list(&db, home, &[]).is_empty());
    server.stop();
    let program = dir.path().join("p.nc");
    let job = util::example("double-start");
    let o = whirl_in(
        &db,
        home,
        &[
            OsStr::new("plan"),
            job.as_os_str(),
            OsStr::new("-o"),
            program.as_os_str(),
        ],
    );
    // The run is not refused: it is recorded in the spool, and says so.
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(program.is_file());
    let spool = home
        .join(".local/share/whirl")
        .join(whirl::records::spool::file_name(&db));
    assert!(spool.is_file(), "{}", spool.display());
    let said = stderr(&o);
    assert!(
        said.contains(&shown) && said.contains(&spool.display().to_string()),
        "{said}"
    );
    // While it is down, the history cannot be read, and says which database.
    let o = whirl_in(&db, home, &[OsStr::new("runs"), OsStr::new("list")]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains(&shown), "{}", stderr(&o));

    server.start_again();
    let o = whirl_in(
        &db,
        home,
        &[OsStr::new("runs"), OsStr::new("list"), OsStr::new("--json")],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("uploaded") && stderr(&o).contains(&spool.display().to_string()),
        "{}",
        stderr(&o)
    );
    let runs: Vec<Value> = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(runs.len(), 1, "{runs:?}");
    assert_eq!(
        (&runs[0]["kind"], &runs[0]["outcome"]),
        (&Value::from("plan"), &Value::from("completed"))
    );
    assert_eq!(runs[0]["host"], Process::current().host.as_str());
    let run = show(&db, home, &runs[0]["id"]);
    assert_eq!(
        run["job_file"]["sha256"],
        whirl::records::sha256_hex(&std::fs::read(&job).unwrap())
    );
    // Once: the next whirl finds nothing more to upload.
    let o = whirl_in(
        &db,
        home,
        &[OsStr::new("runs"), OsStr::new("list"), OsStr::new("--json")],
    );
    assert!(!stderr(&o).contains("uploaded"), "{}", stderr(&o));
    assert_eq!(
        serde_json::from_slice::<Vec<Value>>(&o.stdout)
            .unwrap()
            .len(),
        1
    );
}

#[test]
fn runs_list_finds_a_machines_runs_across_the_hosts_of_a_shared_postgresql() {
    let Some(server) = postgres() else { return };
    let dir = tempfile::tempdir().unwrap();
    let home = dir.path();
    let db = server.database();
    let since = Timestamp::now().to_text()[..19].to_owned();
    // This host plans for two machines: the built-in simulator and the grblHAL lathe.
    let job = util::example("double-start");
    let grblhal = util::root().join("machine-profiles/grblhal-lathe.toml");
    for (machine, out) in [(None, "sim.nc"), (Some(&grblhal), "grblhal.nc")] {
        let out = dir.path().join(out);
        let mut args = vec![
            OsStr::new("plan"),
            job.as_os_str(),
            OsStr::new("-o"),
            out.as_os_str(),
        ];
        if let Some(machine) = machine {
            args.extend([OsStr::new("--machine"), machine.as_os_str()]);
        }
        let o = whirl_in(&db, home, &args);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    // Another host's bridge streams on a grblHAL lathe of its own into the same database.
    let here = Process::current();
    let other = format!("{}-lathe-2", here.host);
    let grblhal_name = "grblHAL XZC whirling lathe (lathe 2)";
    block_on(async {
        let store = Store::open(&Place::parse(&db).unwrap()).await.unwrap();
        let mut run = new_run(Kind::Stream, "jobs/bolt.toml", grblhal_name, None);
        run.process = Process {
            host: other.clone(),
            ..here.clone()
        };
        let recorded = store.begin(&run).await.unwrap();
        store
            .finish(&recorded, &Ending::new(Outcome::Completed))
            .await
            .unwrap();
        store.close_connections().await;
    });
    // Both hosts' grblHAL runs, newest first, each with its host; not the simulator's.
    let runs = list(&db, home, &["--machine", "GRBLHAL", "--since", &since]);
    let found: Vec<(&str, &str)> = runs
        .iter()
        .map(|r| (r["host"].as_str().unwrap(), r["kind"].as_str().unwrap()))
        .collect();
    assert_eq!(
        found,
        [(other.as_str(), "stream"), (here.host.as_str(), "plan")],
        "{runs:?}"
    );
    assert_eq!(list(&db, home, &["--since", &since]).len(), 3);
    assert_eq!(
        list(&db, home, &["--machine", "grblhal", "--host", "LATHE-2"]).len(),
        1
    );
    let tomorrow = Timestamp(Timestamp::now().0 + 86_400_000).to_text()[..10].to_owned();
    assert!(list(&db, home, &["--machine", "grblhal", "--since", &tomorrow]).is_empty());
    // The table names each run's host.
    let o = whirl_in(
        &db,
        home,
        &[
            OsStr::new("runs"),
            OsStr::new("list"),
            OsStr::new("--machine"),
            OsStr::new("grblhal"),
            OsStr::new("--since"),
            OsStr::new(&since),
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let table = String::from_utf8_lossy(&o.stdout);
    let lines: Vec<&str> = table.lines().collect();
    assert!(lines[0].contains("HOST"), "{table}");
    assert!(
        lines[1].contains(&other) && lines[1].contains(grblhal_name),
        "{table}"
    );
    assert!(lines[2].contains(&format!(" {} ", here.host)), "{table}");
    assert_eq!(lines.len(), 3, "{table}");
}

// ---------------------------------------------------------------------------------------
// A bridge killed mid-run; a database lost mid-run.

/// The double-start program streamed by `whirl stream` to a whirl-sim on a pseudo-terminal
/// as fast as the host allows, with the records in `db`.
struct Cut {
    dir: tempfile::TempDir,
    program: PathBuf,
    link: PathBuf,
    sim_log: PathBuf,
    log: PathBuf,
    _sim: Sim,
    db: String,
}

impl Cut {
    fn new(db: impl FnOnce(&Path) -> String) -> Cut {
        let dir = tempfile::tempdir().unwrap();
        let program = planned(dir.path());
        let link = dir.path().join("grbl");
        let sim_log = dir.path().join("sim.jsonl");
        let sim = Sim::serving(
            OsStr::new("--pty"),
            &link,
            &[
                OsStr::new("--time-scale"),
                OsStr::new("0"),
                OsStr::new("--log"),
                sim_log.as_os_str(),
            ],
        );
        let db = db(dir.path());
        Cut {
            log: dir.path().join("exec.jsonl"),
            dir,
            program,
            link,
            sim_log,
            _sim: sim,
            db,
        }
    }

    fn home(&self) -> &Path {
        self.dir.path()
    }

    fn stream(&self, args: &[&OsStr]) -> Child {
        whirl_command(&self.db, self.home())
            .args([OsStr::new("stream"), self.program.as_os_str()])
            .args([OsStr::new("--port"), self.link.as_os_str()])
            .args([OsStr::new("--log"), self.log.as_os_str()])
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("whirl starts")
    }

    /// Waits until the bridge has logged a status report naming the line executing.
    fn wait_reported(&self) {
        let deadline = Instant::now() + Duration::from_secs(60);
        while !std::fs::read_to_string(&self.log)
            .unwrap_or_default()
            .lines()
            .any(|l| l.contains("\"status\"") && l.contains("\"line\""))
        {
            assert!(Instant::now() < deadline, "no status report named a line");
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Waits until the simulator stands: a controller whose sender died goes on with every
    /// line it had received, and an operator resumes once the machine has stopped. The
    /// simulator's log has taken no move for two seconds (it executes as fast as the host
    /// allows: a loaded host makes it slow, not stop).
    fn wait_standing(&self) {
        let deadline = Instant::now() + Duration::from_secs(120);
        let mut last = (
            std::fs::metadata(&self.sim_log).map_or(0, |m| m.len()),
            Instant::now(),
        );
        loop {
            std::thread::sleep(Duration::from_millis(100));
            let len = std::fs::metadata(&self.sim_log).map_or(0, |m| m.len());
            if len != last.0 {
                last = (len, Instant::now());
            } else if last.1.elapsed() >= Duration::from_secs(2) {
                return;
            }
            assert!(
                Instant::now() < deadline,
                "the simulator did not come to a stand"
            );
        }
    }

    /// Waits until the simulator has executed `blocks` moves: the cut is on.
    fn wait_cutting(&self, blocks: usize) {
        let deadline = Instant::now() + Duration::from_secs(60);
        loop {
            let executed = std::fs::read_to_string(&self.sim_log)
                .unwrap_or_default()
                .lines()
                .filter(|l| l.contains("\"executed\""))
                .count();
            if executed >= blocks {
                return;
            }
            assert!(Instant::now() < deadline, "the simulator executed nothing");
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

fn finish(mut child: Child) -> Output {
    let deadline = Instant::now() + Duration::from_secs(120);
    while child.try_wait().unwrap().is_none() {
        if Instant::now() > deadline {
            let _ = child.kill();
            panic!("whirl did not exit");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    child.wait_with_output().unwrap()
}

/// The run's log: the controller's last `Ln:` (the first line not known done) and the last
/// line sent.
fn last_reported_and_sent(log: &Path) -> (usize, usize) {
    let read = whirl::log::read(log).unwrap();
    let mut reported = None;
    let mut sent = 0;
    for r in &read.records {
        match &r.event {
            whirl::log::Event::Status { line: Some(l), .. } => reported = Some(*l as usize),
            whirl::log::Event::Sent { line, .. } => sent = sent.max(*line),
            _ => {}
        }
    }
    (
        reported.expect("the controller reported the line it executed"),
        sent,
    )
}

fn a_bridge_killed_mid_run_is_closed_as_interrupted_on_the_next_start(cut: Cut) {
    let child = cut.stream(&[]);
    cut.wait_cutting(1500);
    cut.wait_reported();
    // The record is open while the run goes.
    let running = list(&cut.db, cut.home(), &["--outcome", "running"]);
    assert_eq!(running.len(), 1, "{running:?}");
    let id = running[0]["id"].clone();
    // SIGKILL: nothing of the bridge's runs after it.
    let mut child = child;
    child.kill().unwrap();
    child.wait().unwrap();
    let log_before = std::fs::read(&cut.log).unwrap();

    let o = whirl_in(
        &cut.db,
        cut.home(),
        &[OsStr::new("runs"), OsStr::new("list"), OsStr::new("--json")],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains(&format!("run {id}")) && stderr(&o).contains("interrupted"),
        "{}",
        stderr(&o)
    );
    let runs: Vec<Value> = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(runs[0]["id"], id);
    assert_eq!(runs[0]["outcome"], "interrupted");
    // The resume point is what the log says: the block the controller last reported
    // executing; it may have gone on with every line it had been sent.
    let (reported, sent) = last_reported_and_sent(&cut.log);
    assert_eq!(runs[0]["resume_at"], reported);
    let run = show(&cut.db, cut.home(), &id);
    assert_eq!(run["possibly_run_to"], sent);
    assert_eq!(run["last_line"], reported - 1);
    assert!(run["ended_at"].is_string());
    let stop = run["notes"].as_array().unwrap().last().unwrap().clone();
    assert_eq!(
        (stop["kind"].as_str(), stop["line"].as_u64()),
        (Some("stop"), Some(reported as u64))
    );
    // The log is intact: not a byte changed by closing the record.
    assert_eq!(std::fs::read(&cut.log).unwrap(), log_before);
    let summary = whirl::log::Summary::of(&whirl::log::read(&cut.log).unwrap());
    assert_eq!(summary.per_run[0].ended, whirl::log::Ended::Interrupted);
    // The next command finds it closed already.
    let o = whirl_in(
        &cut.db,
        cut.home(),
        &[OsStr::new("runs"), OsStr::new("list")],
    );
    assert!(!stderr(&o).contains("interrupted"), "{}", stderr(&o));
    // Resuming at the recorded line, once the machine stands, finishes the job, and its
    // record continues the interrupted one.
    cut.wait_standing();
    let line = reported.to_string();
    let o = finish(cut.stream(&[OsStr::new("--resume-at"), OsStr::new(&line)]));
    assert!(o.status.success(), "{}", stderr(&o));
    let resumed = show(
        &cut.db,
        cut.home(),
        &list(&cut.db, cut.home(), &[])[0]["id"],
    );
    assert_eq!(resumed["outcome"], "completed");
    assert_eq!(
        (resumed["resume_from"].as_u64(), &resumed["resumes"]),
        (Some(reported as u64), &id)
    );
}

#[test]
fn a_bridge_killed_mid_run_is_closed_as_interrupted_in_sqlite() {
    let cut = Cut::new(|dir| dir.join("runs.sqlite").display().to_string());
    a_bridge_killed_mid_run_is_closed_as_interrupted_on_the_next_start(cut);
}

#[test]
fn a_bridge_killed_mid_run_is_closed_as_interrupted_in_postgresql() {
    let Some(server) = postgres() else { return };
    let cut = Cut::new(|_| server.database());
    a_bridge_killed_mid_run_is_closed_as_interrupted_on_the_next_start(cut);
}

#[test]
fn a_database_lost_mid_run_lets_the_run_finish_and_its_record_is_closed_from_the_log() {
    let cut = Cut::new(|dir| dir.join("runs.sqlite").display().to_string());
    let child = cut.stream(&[]);
    cut.wait_cutting(500);
    // Another process takes the database and holds it past the run's end (whirl waits 5 s
    // for a lock, then gives up).
    let url = format!("sqlite://{}", cut.db);
    let mut lock = block_on(async {
        use sqlx::Connection;
        let mut conn = sqlx::SqliteConnection::connect(&url).await.unwrap();
        sqlx::raw_sql("BEGIN EXCLUSIVE")
            .execute(&mut conn)
            .await
            .unwrap();
        conn
    });
    let o = finish(child);
    assert!(o.status.success(), "the run completes: {}", stderr(&o));
    assert!(
        stderr(&o).contains("warning") && stderr(&o).contains(&cut.log.display().to_string()),
        "{}",
        stderr(&o)
    );
    block_on(async {
        use sqlx::Connection;
        sqlx::raw_sql("ROLLBACK").execute(&mut lock).await.unwrap();
        lock.close().await.unwrap();
    });
    let summary = whirl::log::Summary::of(&whirl::log::read(&cut.log).unwrap());
    assert_eq!(summary.completed, Some(true));
    // The next whirl closes the record from the log: completed.
    let runs = list(&cut.db, cut.home(), &[]);
    assert_eq!(runs[0]["outcome"], "completed", "{runs:?}");
}

#[test]
fn a_database_a_newer_whirl_has_migrated_further_is_refused_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("runs.sqlite");
    let db = file.display().to_string();
    assert!(list(&db, dir.path(), &[]).is_empty());
    // A schema version this whirl does not have.
    block_on(async {
        use sqlx::Connection;
        let mut conn = sqlx::SqliteConnection::connect(&format!("sqlite://{db}"))
            .await
            .unwrap();
        sqlx::raw_sql(
            "INSERT INTO _sqlx_migrations (version, description, success, checksum, \
             execution_time) VALUES (99, 'from a newer whirl', TRUE, x'00', 0)",
        )
        .execute(&mut conn)
        .await
        .unwrap();
        conn.close().await.unwrap();
    });
    let before = std::fs::read(&file).unwrap();
    let o = whirl_in(&db, dir.path(), &[OsStr::new("runs"), OsStr::new("list")]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains(&db) && stderr(&o).contains("migration 99"),
        "{}",
        stderr(&o)
    );
    assert_eq!(std::fs::read(&file).unwrap(), before, "nothing written");
}
