//! One database of run records, SQLite or PostgreSQL, through sqlx's `Any` driver, so both
//! run the same code and the same SQL: its schema brought up to date (the migrations
//! embedded in the binary, `src/records/migrations/`), a record opened, noted and closed,
//! the runs of a process that is gone closed from their logs, the runs listed and shown.
//! [`super::Store`] is what a run uses: the database named, and for PostgreSQL a spool
//! ([`super::spool`]) that keeps what the database cannot take.
//!
//! Every call to a PostgreSQL server is bounded by [`POSTGRES_TIMEOUT`], so that a server
//! that hangs (a network gone quiet, a server stopped mid-answer) never holds up a run; a
//! SQLite call is bounded by its lock's wait ([`SQLITE_BUSY_TIMEOUT`]).

use std::borrow::Cow;
use std::future::Future;
use std::path::{Path, PathBuf};
use std::str::FromStr;
use std::sync::Arc;
use std::time::Duration;

use sqlx::any::{AnyConnectOptions, AnyPoolOptions, AnyRow};
use sqlx::migrate::{Migration, MigrationType, Migrator};
use sqlx::sqlite::SqliteConnectOptions;
use sqlx::{
    AnyConnection, AnyPool, ConnectOptions, Connection as _, Executor as _, Row, SqlSafeStr,
};
use tokio::sync::OnceCell;

use super::from_log::{read_run, LogFacts};
use super::process::{Liveness, Process};
use super::store::RecordError;
use super::time::Timestamp;
use super::uid::Uid;
use super::{
    Ending, FileSnapshot, Filter, Kind, LogPlace, Measured, NewRun, Note, NoteKind, Outcome,
    ProgramId, Run, RunId, RunMode, RunProvenance, RunSummary,
};
use crate::log::Ended;

/// The records' schema, version by version.
fn migrator() -> Migrator {
    let migration = |version, name, sql: &'static str| {
        Migration::new(
            version,
            Cow::Borrowed(name),
            MigrationType::Simple,
            sql.into_sql_str(),
            false,
        )
    };
    Migrator::with_migrations(vec![
        migration(1, "runs", include_str!("migrations/0001_runs.sql")),
        migration(
            2,
            "provenance",
            include_str!("migrations/0002_provenance.sql"),
        ),
        migration(3, "shop", include_str!("migrations/0003_shop.sql")),
    ])
}

/// How many times a note's number is tried when another writer took the one chosen.
pub(super) const ID_TRIES: usize = 20;

/// How long a SQLite connection waits for another writer (another whirl on the host, a
/// console) to let go of the file before its write fails: a run must not be refused, nor
/// its record left open, because another run was writing its own a moment earlier.
pub const SQLITE_BUSY_TIMEOUT: Duration = Duration::from_secs(30);

/// The longest any one call to a PostgreSQL server may take, its connection included:
/// past it the call has failed, and what it was writing goes to the spool. A shop's
/// server answers these small writes in milliseconds; this is for one that does not
/// answer at all (a network gone quiet, a server stopped), which would otherwise hold a
/// run up for as long as TCP waits.
pub const POSTGRES_TIMEOUT: Duration = Duration::from_secs(5);

/// Which database a connection speaks to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Backend {
    Sqlite,
    Postgres,
}

/// One database of run records.
#[derive(Debug, Clone)]
pub(super) struct Database {
    pool: AnyPool,
    /// How messages name it.
    place: String,
    backend: Backend,
    /// How to reach a PostgreSQL server, to tell that it is down before a run waits on it.
    probe: Option<AnyConnectOptions>,
    /// Its schema brought up to date, once an opening has reached it (a PostgreSQL
    /// database is reached when first used, which may be after it was opened).
    ready: Arc<OnceCell<()>>,
}

impl Database {
    /// The SQLite file `options` names (its folder made first if `create`), checked whole
    /// and brought up to date.
    pub(super) async fn sqlite(
        options: &SqliteConnectOptions,
        create: bool,
        place: String,
    ) -> Result<Database, RecordError> {
        let parent = options.get_filename().parent();
        if let Some(folder) = parent.filter(|p| !p.as_os_str().is_empty()) {
            if create && !folder.exists() {
                std::fs::create_dir_all(folder).map_err(|error| RecordError::Folder {
                    path: folder.to_owned(),
                    error,
                })?;
            }
        }
        let url = options.to_url_lossy().to_string();
        let open = |error| RecordError::Open {
            place: place.clone(),
            error,
        };
        let pool = pool_options()
            .connect_with(connect_options(&url).map_err(open)?)
            .await
            .map_err(open)?;
        quick_check(&pool, &place, options.get_filename()).await?;
        let database = Database {
            pool,
            place,
            backend: Backend::Sqlite,
            probe: None,
            ready: Arc::new(OnceCell::new()),
        };
        database.ready().await?;
        Ok(database)
    }

    /// The PostgreSQL database at `url`, not yet reached: [`Database::ready`] reaches it.
    pub(super) fn postgres(url: &str, place: String) -> Result<Database, RecordError> {
        let options = connect_options(url).map_err(|error| RecordError::Open {
            place: place.clone(),
            error,
        })?;
        Ok(Database {
            pool: pool_options().connect_lazy_with(options.clone()),
            place,
            backend: Backend::Postgres,
            probe: Some(options),
            ready: Arc::new(OnceCell::new()),
        })
    }

    /// The database, as messages name it.
    pub(super) fn place(&self) -> &str {
        &self.place
    }

    /// Reaches the database and brings its schema up to date, once: a database a newer
    /// whirl has migrated further is refused, not written in a form this whirl does not
    /// know.
    pub(super) async fn ready(&self) -> Result<(), RecordError> {
        self.ready
            .get_or_try_init(|| async {
                if let Some(options) = &self.probe {
                    // A connection of its own, not the pool's: the pool tries a refused
                    // connection again until its wait is over, as for a server starting
                    // up; a server that is down is known at once.
                    let probe = self
                        .bounded_raw(AnyConnection::connect_with(options))
                        .await
                        .map_err(|error| match error {
                            Bounded::TimedOut => self.timed_out("reach the database"),
                            Bounded::Failed(error) => RecordError::Open {
                                place: self.place.clone(),
                                error,
                            },
                        })?;
                    let _ = probe.close().await;
                }
                // Whirls opening a new SQLite file at once may each try the same migration
                // (SQLite has no lock for the migrator to take): the one that loses finds
                // it done when it looks again, and may lose the next one's race too, so it
                // looks once more for every migration there is. PostgreSQL's migrations
                // wait for each other on a lock of the server's.
                let migrator = migrator();
                let mut tries = migrator.iter().count() + 1;
                loop {
                    tries -= 1;
                    match self.bounded_raw(migrator.run(&self.pool)).await {
                        Ok(()) => break,
                        Err(Bounded::Failed(_)) if tries > 0 => {}
                        Err(Bounded::Failed(error)) => {
                            return Err(RecordError::Migrate {
                                place: self.place.clone(),
                                error,
                            })
                        }
                        Err(Bounded::TimedOut) => {
                            return Err(self.timed_out("bring the schema up to date"))
                        }
                    }
                }
                Ok(())
            })
            .await
            .map(|_| ())
    }

    /// `call` within [`POSTGRES_TIMEOUT`] on PostgreSQL; on SQLite as it is (its lock's
    /// wait bounds it).
    async fn bounded_raw<T, E>(
        &self,
        call: impl Future<Output = Result<T, E>>,
    ) -> Result<T, Bounded<E>> {
        let result = match self.backend {
            Backend::Sqlite => call.await,
            Backend::Postgres => tokio::time::timeout(POSTGRES_TIMEOUT, call)
                .await
                .map_err(|_| Bounded::TimedOut)?,
        };
        result.map_err(Bounded::Failed)
    }

    /// `call`, the store doing `what`, on a database made ready, bounded as
    /// [`Database::bounded_raw`] says, its error named.
    pub(super) async fn bounded<T>(
        &self,
        what: &'static str,
        call: impl Future<Output = Result<T, Failure>>,
    ) -> Result<T, RecordError> {
        self.ready().await?;
        match self.bounded_raw(call).await {
            Ok(value) => Ok(value),
            Err(Bounded::TimedOut) => Err(self.timed_out(what)),
            Err(Bounded::Failed(Failure::Sql(error))) => Err(RecordError::Query {
                place: self.place.clone(),
                what,
                error,
            }),
            Err(Bounded::Failed(Failure::Contended)) => Err(RecordError::Contended {
                place: self.place.clone(),
                what,
            }),
        }
    }

    fn timed_out(&self, what: &'static str) -> RecordError {
        RecordError::TimedOut {
            place: self.place.clone(),
            what,
            after: POSTGRES_TIMEOUT,
        }
    }

    /// The connections, for the spool's upload, which runs its own transactions.
    pub(super) fn pool(&self) -> &AnyPool {
        &self.pool
    }

    /// Opens a record, `running`, keyed `uid`, started at `started`; a run that resumes an
    /// earlier one ([`NewRun::resume_from`]) is linked to it. Its number is the counter's
    /// next.
    pub(super) async fn begin(
        &self,
        run: &NewRun,
        uid: &Uid,
        started: &str,
    ) -> Result<RunId, RecordError> {
        self.bounded("open a record", async {
            let resumes = match (&run.program, run.resume_from) {
                (Some(program), Some(line)) => {
                    resumed_run(&self.pool, &program.sha256, line, None).await?
                }
                _ => None,
            };
            let file = |f: &Option<FileSnapshot>, part: fn(&FileSnapshot) -> &String| {
                f.as_ref().map(|f| part(f).clone())
            };
            let mut tx = self.pool.begin().await?;
            let id = next_id(&mut tx).await?;
            sqlx::query(
                "INSERT INTO runs (id, uid, kind, outcome, started_at, host, pid, \
                 process_started, boot_id, job_path, job_sha256, job_text, machine_name, \
                 machine_path, machine_sha256, machine_text, program_name, program_sha256, \
                 program_lines, transport, port, plan_report, resume_from, resumes, log_path, \
                 log_offset, provenance) \
                 VALUES ($1, $2, $3, 'running', $4, $5, $6, $7, $8, $9, $10, $11, $12, $13, \
                 $14, $15, $16, $17, $18, $19, $20, $21, $22, $23, $24, $25, $26)",
            )
            .bind(id)
            .bind(uid.as_str())
            .bind(run.kind.as_str())
            .bind(started)
            .bind(&run.process.host)
            .bind(i64::from(run.process.pid))
            .bind(run.process.started.map(saturating))
            .bind(run.process.boot.clone())
            .bind(file(&run.job, |f| &f.path))
            .bind(file(&run.job, |f| &f.sha256))
            .bind(file(&run.job, |f| &f.text))
            .bind(run.machine_name.clone())
            .bind(file(&run.machine, |f| &f.path))
            .bind(file(&run.machine, |f| &f.sha256))
            .bind(file(&run.machine, |f| &f.text))
            .bind(run.program.as_ref().map(|p| p.name.clone()))
            .bind(run.program.as_ref().map(|p| p.sha256.clone()))
            .bind(run.program.as_ref().map(|p| line(p.lines)))
            .bind(run.transport.clone())
            .bind(run.port.clone())
            .bind(run.plan_report.clone())
            .bind(run.resume_from.map(line))
            .bind(resumes)
            .bind(
                run.log
                    .as_ref()
                    .map(|l| l.path.to_string_lossy().into_owned()),
            )
            .bind(run.log.as_ref().map(|l| saturating(l.offset)))
            .bind(run.provenance.as_ref().map(RunProvenance::to_json))
            .execute(&mut *tx)
            .await?;
            tx.commit().await?;
            Ok(id)
        })
        .await
    }

    /// The number of the run keyed `uid`, if this database holds it.
    pub(super) async fn find(&self, uid: &Uid) -> Result<Option<RunId>, RecordError> {
        self.bounded("find a run by its key", async {
            Ok(sqlx::query("SELECT id FROM runs WHERE uid = $1")
                .bind(uid.as_str())
                .fetch_optional(&self.pool)
                .await?
                .map(|row| row.try_get("id"))
                .transpose()?)
        })
        .await
    }

    /// Adds a note keyed `uid` to run `id` as it goes (an alarm, a hold, a resume); a note
    /// of that key written already is not written again.
    pub(super) async fn note(&self, id: RunId, uid: &Uid, note: &Note) -> Result<(), RecordError> {
        self.bounded("add a note to a run", async {
            let at = Timestamp::now().to_text();
            for _ in 0..ID_TRIES {
                match add_note(&self.pool, id, Some(uid.as_str()), note, &at).await {
                    Err(e) if taken(&e) => continue,
                    written => return Ok(written.map(|_| ())?),
                }
            }
            Err(Failure::Contended)
        })
        .await
    }

    /// Closes a running record with how its run ended (at `ended`); the ending's notes
    /// keyed by the run's key `uid` ([`Uid::ending_note`]). `false` if it was not running
    /// (it was closed already, by its process or as interrupted).
    pub(super) async fn close(
        &self,
        id: RunId,
        uid: Option<&Uid>,
        ending: &Ending,
        ended: &str,
    ) -> Result<bool, RecordError> {
        // Its notes are numbered after the last one written: a note written at the same
        // moment (a hold pressed on the console) takes the number, and the close tries
        // again.
        self.bounded("close a record", async {
            for _ in 0..ID_TRIES {
                match self.close_once(id, uid, ending, ended).await {
                    Err(e) if taken(&e) => continue,
                    closed => return Ok(closed?),
                }
            }
            Err(Failure::Contended)
        })
        .await
    }

    async fn close_once(
        &self,
        id: RunId,
        uid: Option<&Uid>,
        ending: &Ending,
        ended: &str,
    ) -> sqlx::Result<bool> {
        let mut tx = self.pool.begin().await?;
        let updated = sqlx::query(
            "UPDATE runs SET outcome = $2, reason = $3, ended_at = $4, \
             program_name = COALESCE($5, program_name), \
             program_sha256 = COALESCE($6, program_sha256), \
             program_lines = COALESCE($7, program_lines), \
             plan_report = COALESCE($8, plan_report), \
             resume_at = $9, possibly_run_to = $10, last_line = $11, \
             provenance = COALESCE($12, provenance) \
             WHERE id = $1 AND outcome = 'running'",
        )
        .bind(id)
        .bind(ending.outcome.as_str())
        .bind(ending.reason.clone())
        .bind(ended)
        .bind(ending.program.as_ref().map(|p| p.name.clone()))
        .bind(ending.program.as_ref().map(|p| p.sha256.clone()))
        .bind(ending.program.as_ref().map(|p| line(p.lines)))
        .bind(ending.plan_report.clone())
        .bind(ending.resume_at.map(line))
        .bind(ending.possibly_run_to.map(line))
        .bind(ending.last_line.map(line))
        .bind(ending.provenance.as_ref().map(RunProvenance::to_json))
        .execute(&mut *tx)
        .await?;
        if updated.rows_affected() == 0 {
            return Ok(false);
        }
        // Set only when measured: sqlx's Any driver hands PostgreSQL an absent f64 as a
        // 4-byte float, which the server refuses for a DOUBLE PRECISION parameter.
        if let Some(m) = ending.measured {
            sqlx::query(
                "UPDATE runs SET max_overcut_mm = $2, max_undercut_mm = $3, delta_mm = $4, \
                 within_delta = $5 WHERE id = $1",
            )
            .bind(id)
            .bind(m.max_overcut_mm)
            .bind(m.max_undercut_mm)
            .bind(m.delta_mm)
            .bind(i64::from(m.within_delta))
            .execute(&mut *tx)
            .await?;
        }
        // A run that did not complete stops once, at its resume line.
        let stop = (ending.outcome != Outcome::Completed
            && !ending.notes.iter().any(|n| n.kind == NoteKind::Stop))
        .then(|| Note {
            line: ending.resume_at,
            ..Note::new(NoteKind::Stop, ending.reason.clone().unwrap_or_default())
        });
        for (k, note) in ending.notes.iter().chain(&stop).enumerate() {
            let key = uid.map(|uid| uid.ending_note(k));
            add_note(&mut *tx, id, key.as_ref().map(Uid::as_str), note, ended).await?;
        }
        tx.commit().await?;
        Ok(true)
    }

    /// Closes the records of this host whose process is gone without closing them (see
    /// [`Process::liveness`]), each from what its log says ([`read_run`]): the outcome its
    /// log's end gives, or `interrupted` if the log has none, with the resume point, the
    /// last line known done and the alarms. The logs are only read; the records of other
    /// hosts are left to them. Returns the runs closed, and the outcome each was given.
    pub(super) async fn close_orphans(
        &self,
        here: &Process,
    ) -> Result<Vec<(RunId, Outcome)>, RecordError> {
        let what = "look for runs whose process is gone";
        let rows = self
            .bounded(what, async {
                Ok(sqlx::query(
                    "SELECT id, uid, pid, process_started, boot_id, started_at, log_path, \
                     log_offset, resume_from FROM runs WHERE outcome = 'running' AND host = $1 \
                     ORDER BY id",
                )
                .bind(&here.host)
                .fetch_all(&self.pool)
                .await?)
            })
            .await?;
        let mut closed = Vec::new();
        for row in rows {
            let get = |error| RecordError::Query {
                place: self.place.clone(),
                what,
                error,
            };
            let id: RunId = row.try_get("id").map_err(get)?;
            let uid = row
                .try_get::<Option<String>, _>("uid")
                .map_err(get)?
                .map(Uid::from_text);
            let pid: i64 = row.try_get("pid").map_err(get)?;
            let owner = Process {
                host: here.host.clone(),
                pid: u32::try_from(pid).unwrap_or(u32::MAX),
                started: row
                    .try_get::<Option<i64>, _>("process_started")
                    .map_err(get)?
                    .map(|s| s.max(0) as u64),
                boot: row.try_get("boot_id").map_err(get)?,
            };
            if owner.liveness(here) != Liveness::Gone {
                continue;
            }
            let started: String = row.try_get("started_at").map_err(get)?;
            let log_path: Option<String> = row.try_get("log_path").map_err(get)?;
            let log_offset: Option<i64> = row.try_get("log_offset").map_err(get)?;
            let from_line = usize_of(row.try_get("resume_from").map_err(get)?).unwrap_or(1);
            let log = log_path.map(|path| {
                let facts = read_run(
                    Path::new(&path),
                    log_offset.map_or(0, |o| o.max(0) as u64),
                    from_line,
                );
                (path, facts)
            });
            let (ending, ended) = orphan_ending(owner.pid, &started, log);
            if self.close(id, uid.as_ref(), &ending, &ended).await? {
                closed.push((id, ending.outcome));
            }
        }
        Ok(closed)
    }

    /// The runs `filter` lets through, newest first (by their start: a run uploaded from a
    /// spool is numbered when it arrives, after runs that started later).
    pub(super) async fn list(&self, filter: &Filter) -> Result<Vec<RunSummary>, RecordError> {
        self.bounded("list the runs", async {
            let rows = sqlx::query(
                "SELECT id, kind, outcome, started_at, ended_at, host, job_path, program_name, \
                 machine_name, transport, port, resume_at, reason FROM runs \
                 WHERE ($1 IS NULL OR LOWER(job_path) LIKE $1 ESCAPE '\\' \
                        OR LOWER(program_name) LIKE $1 ESCAPE '\\') \
                 AND ($2 IS NULL OR LOWER(machine_name) LIKE $2 ESCAPE '\\' \
                      OR LOWER(machine_path) LIKE $2 ESCAPE '\\') \
                 AND ($3 IS NULL OR started_at >= $3) \
                 AND ($4 IS NULL OR started_at < $4) \
                 AND ($5 IS NULL OR outcome = $5) \
                 AND ($6 IS NULL OR LOWER(host) LIKE $6 ESCAPE '\\') \
                 ORDER BY started_at DESC, id DESC LIMIT $7",
            )
            .bind(filter.job.as_deref().map(contains))
            .bind(filter.machine.as_deref().map(contains))
            .bind(filter.since.map(Timestamp::to_text))
            .bind(filter.until.map(Timestamp::to_text))
            .bind(filter.outcome.map(Outcome::as_str))
            .bind(filter.host.as_deref().map(contains))
            .bind(filter.limit.map_or(i64::MAX, i64::from))
            .fetch_all(&self.pool)
            .await?;
            Ok(rows.iter().map(summary).collect::<Result<_, _>>()?)
        })
        .await
    }

    /// The whole record of run `id`, with its notes; `None` if there is none.
    pub(super) async fn show(&self, id: RunId) -> Result<Option<Run>, RecordError> {
        self.bounded("read the run", async {
            let Some(row) = sqlx::query(
                "SELECT id, uid, kind, outcome, started_at, ended_at, job_path, program_name, \
                 machine_name, transport, resume_at, reason, host, pid, job_sha256, job_text, \
                 machine_path, machine_sha256, machine_text, program_sha256, program_lines, \
                 port, plan_report, max_overcut_mm, max_undercut_mm, delta_mm, within_delta, \
                 resume_from, resumes, possibly_run_to, last_line, log_path, log_offset, \
                 provenance FROM runs WHERE id = $1",
            )
            .bind(id)
            .fetch_optional(&self.pool)
            .await?
            else {
                return Ok(None);
            };
            let notes = sqlx::query(
                "SELECT at, kind, line, code, text FROM run_notes WHERE run_id = $1 \
                 ORDER BY seq",
            )
            .bind(id)
            .fetch_all(&self.pool)
            .await?;
            let notes = notes.iter().map(note).collect::<Result<Vec<_>, _>>()?;
            Ok(Some(run(&row, notes)?))
        })
        .await
    }

    /// Closes the connections.
    pub(super) async fn close_connections(self) {
        self.pool.close().await;
    }
}

/// Why a bounded call failed: the database said no, or it found every number taken.
pub(super) enum Failure {
    Sql(sqlx::Error),
    Contended,
}

impl From<sqlx::Error> for Failure {
    fn from(error: sqlx::Error) -> Failure {
        Failure::Sql(error)
    }
}

/// A call bounded in time: it failed, or it took too long.
enum Bounded<E> {
    Failed(E),
    TimedOut,
}

/// The connections a database is used through: two, so that a history read and a run's
/// write need not wait for each other, and no more, so that a shop's server with many
/// bridges keeps connections to spare. A connection is handed out within 10 s (a
/// PostgreSQL call's own bound, [`POSTGRES_TIMEOUT`], is the shorter, and says so), and a
/// SQLite connection waits [`SQLITE_BUSY_TIMEOUT`] for a lock.
fn pool_options() -> AnyPoolOptions {
    AnyPoolOptions::new()
        .max_connections(2)
        .acquire_timeout(Duration::from_secs(10))
        // The Any driver's options carry only what a URL says, and a SQLite URL cannot
        // say how long to wait for a lock: each connection is told here.
        .after_connect(|connection, _| {
            Box::pin(async move {
                if connection.backend_name() == "SQLite" {
                    let pragma =
                        format!("PRAGMA busy_timeout = {}", SQLITE_BUSY_TIMEOUT.as_millis());
                    connection.execute(sqlx::AssertSqlSafe(pragma)).await?;
                }
                Ok(())
            })
        })
}

fn connect_options(url: &str) -> sqlx::Result<AnyConnectOptions> {
    Ok(AnyConnectOptions::from_str(url)?.disable_statement_logging())
}

/// The next run number, from the counter row: a writer that takes it holds the row until
/// its transaction ends, and the next writer waits for it, on either database.
pub(super) async fn next_id(tx: &mut sqlx::Transaction<'_, sqlx::Any>) -> sqlx::Result<RunId> {
    sqlx::query("UPDATE counters SET last = last + 1 WHERE name = 'runs' RETURNING last")
        .fetch_one(&mut **tx)
        .await?
        .try_get("last")
}

/// Adds `note` to run `id`, numbered after its last, keyed `uid` (nothing if a note of
/// that key is there already); `at`: when, if the note does not say.
pub(super) async fn add_note<'c, E>(
    executor: E,
    id: RunId,
    uid: Option<&str>,
    note: &Note,
    at: &str,
) -> sqlx::Result<u64>
where
    E: sqlx::Executor<'c, Database = sqlx::Any>,
{
    // The SELECT's WHERE also keeps SQLite from reading ON CONFLICT as a join's.
    Ok(sqlx::query(
        "INSERT INTO run_notes (run_id, seq, uid, at, kind, line, code, text) \
         SELECT $1, COALESCE(MAX(seq), 0) + 1, $2, $3, $4, $5, $6, $7 \
         FROM run_notes WHERE run_id = $1 ON CONFLICT (uid) DO NOTHING",
    )
    .bind(id)
    .bind(uid)
    .bind(note.at.clone().unwrap_or_else(|| at.to_owned()))
    .bind(note.kind.as_str())
    .bind(note.line.map(line))
    .bind(note.code.map(i64::from))
    .bind(&note.text)
    .execute(executor)
    .await?
    .rows_affected())
}

/// The run a run of the program `sha256` starting at `line` resumes: the latest that
/// did not complete (started `before`, if given), the one whose resume point is `line` if
/// any is.
pub(super) async fn resumed_run<'c, E>(
    executor: E,
    sha256: &str,
    line: usize,
    before: Option<&str>,
) -> sqlx::Result<Option<RunId>>
where
    E: sqlx::Executor<'c, Database = sqlx::Any>,
{
    sqlx::query(
        "SELECT id FROM runs WHERE program_sha256 = $1 \
         AND outcome IN ('stopped', 'failed', 'interrupted') \
         AND ($3 IS NULL OR started_at < $3) \
         ORDER BY CASE WHEN resume_at = $2 THEN 0 ELSE 1 END, started_at DESC, id DESC \
         LIMIT 1",
    )
    .bind(sha256)
    .bind(self::line(line))
    .bind(before)
    .fetch_optional(executor)
    .await?
    .map(|row| row.try_get("id"))
    .transpose()
}

/// Another writer took the note's number (or the key) chosen.
pub(super) fn taken(error: &sqlx::Error) -> bool {
    matches!(error, sqlx::Error::Database(e) if e.is_unique_violation())
}

/// SQLite's `PRAGMA quick_check`: the file's pages and their b-trees are whole (the
/// indexes' agreement with their tables, which only the full integrity check compares, is
/// left out: it costs a sort of every index). A page damaged in the middle of the file
/// opens without complaint and fails only when a query reaches it: checked here, at open,
/// before the run it would record starts.
async fn quick_check(pool: &AnyPool, place: &str, path: &Path) -> Result<(), RecordError> {
    let damaged = |problem: String| RecordError::Damaged {
        place: place.to_owned(),
        path: path.to_owned(),
        problem,
    };
    let rows = match sqlx::query("PRAGMA quick_check").fetch_all(pool).await {
        Ok(rows) => rows,
        // SQLite's own word for a file that is not a database at all is left to the opening
        // error it has always been; anything the check itself trips over is damage.
        Err(sqlx::Error::Database(error)) if error.message().contains("not a database") => {
            return Err(RecordError::Open {
                place: place.to_owned(),
                error: sqlx::Error::Database(error),
            })
        }
        Err(error) => return Err(damaged(error.to_string())),
    };
    let found: Vec<String> = rows
        .iter()
        .filter_map(|row| row.try_get::<String, _>(0).ok())
        .collect();
    match found.first() {
        Some(first) if first == "ok" => Ok(()),
        Some(first) => Err(damaged(first.clone())),
        None => Err(damaged("no answer".into())),
    }
}

/// A count or a line as the database holds it.
fn line(n: usize) -> i64 {
    i64::try_from(n).unwrap_or(i64::MAX)
}

fn saturating(n: u64) -> i64 {
    i64::try_from(n).unwrap_or(i64::MAX)
}

fn usize_of(n: Option<i64>) -> Option<usize> {
    n.and_then(|n| usize::try_from(n).ok())
}

/// The `LIKE` pattern of "contains `text`, in any case", `\` escaping the pattern's own
/// characters.
fn contains(text: &str) -> String {
    let mut pattern = String::from("%");
    for c in text.to_lowercase().chars() {
        if matches!(c, '%' | '_' | '\\') {
            pattern.push('\\');
        }
        pattern.push(c);
    }
    pattern.push('%');
    pattern
}

/// How an orphaned run is closed: from what its log says, if it has a log, and when it
/// ended (the record's start plus the log's last event, or now).
fn orphan_ending(
    pid: u32,
    started: &str,
    log: Option<(String, std::io::Result<LogFacts>)>,
) -> (Ending, String) {
    let gone = format!("its process ({pid}) ended without closing the record");
    let (ending, last_t) = match log {
        None => {
            let mut ending = Ending::new(Outcome::Interrupted);
            ending.reason = Some(format!("{gone}; it kept no log"));
            (ending, None)
        }
        Some((path, Err(error))) => {
            let mut ending = Ending::new(Outcome::Interrupted);
            ending.reason = Some(format!("{gone}; its log {path} cannot be read: {error}"));
            (ending, None)
        }
        Some((path, Ok(facts))) => {
            let outcome = match facts.ended {
                Some(Ended::Completed) => Outcome::Completed,
                Some(Ended::Stopped) => Outcome::Stopped,
                Some(Ended::Interrupted) | None => Outcome::Interrupted,
            };
            let mut ending = Ending::new(outcome);
            ending.reason = Some(match (outcome, &facts.reason) {
                (Outcome::Interrupted, _) => {
                    format!("{gone}; its log {path} ends without the run's end")
                }
                (_, Some(reason)) => format!("{reason} ({gone}; closed from its log)"),
                (_, None) => format!("{gone}; closed from its log {path}"),
            });
            ending.resume_at = facts.resume_at;
            ending.possibly_run_to = facts.possibly_run_to;
            ending.add_log(&facts, Timestamp::parse(started).ok());
            (ending, facts.last_t)
        }
    };
    let ended = match (Timestamp::parse(started), last_t) {
        (Ok(start), Some(t)) if t.is_finite() && t >= 0.0 => {
            Timestamp(start.0.saturating_add((t * 1000.0) as i64)).to_text()
        }
        _ => Timestamp::now().to_text(),
    };
    (ending, ended)
}

fn summary(row: &AnyRow) -> Result<RunSummary, sqlx::Error> {
    let word = |column: &str| -> Result<String, sqlx::Error> { row.try_get(column) };
    let kind = word("kind")?;
    let outcome = word("outcome")?;
    let unknown = |column: &str, value: &str| sqlx::Error::ColumnDecode {
        index: column.to_owned(),
        source: format!("\"{value}\" is not a word this whirl knows").into(),
    };
    let kind = Kind::from_word(&kind).ok_or_else(|| unknown("kind", &kind))?;
    let port: Option<String> = row.try_get("port")?;
    let started_at: String = row.try_get("started_at")?;
    let ended_at: Option<String> = row.try_get("ended_at")?;
    Ok(RunSummary {
        id: row.try_get("id")?,
        kind,
        outcome: Outcome::from_word(&outcome).ok_or_else(|| unknown("outcome", &outcome))?,
        duration_s: super::duration_s(&started_at, ended_at.as_deref(), Timestamp::now()),
        started_at,
        ended_at,
        host: row.try_get("host")?,
        job: row.try_get("job_path")?,
        program: row.try_get("program_name")?,
        machine: row.try_get("machine_name")?,
        transport: row.try_get("transport")?,
        mode: RunMode::of(kind, port.as_deref()),
        resume_at: usize_of(row.try_get("resume_at")?),
        reason: row.try_get("reason")?,
    })
}

fn note(row: &AnyRow) -> Result<Note, sqlx::Error> {
    let kind: String = row.try_get("kind")?;
    Ok(Note {
        kind: NoteKind::from_word(&kind).ok_or_else(|| sqlx::Error::ColumnDecode {
            index: "kind".into(),
            source: format!("\"{kind}\" is not a note this whirl knows").into(),
        })?,
        at: row.try_get("at")?,
        line: usize_of(row.try_get("line")?),
        code: row
            .try_get::<Option<i64>, _>("code")?
            .and_then(|c| u32::try_from(c).ok()),
        text: row.try_get("text")?,
    })
}

fn run(row: &AnyRow, notes: Vec<Note>) -> Result<Run, sqlx::Error> {
    let snapshot =
        |path: &str, sha: &str, text: &str| -> Result<Option<FileSnapshot>, sqlx::Error> {
            let (path, sha256, text): (Option<String>, Option<String>, Option<String>) =
                (row.try_get(path)?, row.try_get(sha)?, row.try_get(text)?);
            Ok(match (path, sha256, text) {
                (Some(path), Some(sha256), Some(text)) => Some(FileSnapshot { path, sha256, text }),
                _ => None,
            })
        };
    let summary = summary(row)?;
    let program_id = match (
        summary.program.clone(),
        row.try_get::<Option<String>, _>("program_sha256")?,
        usize_of(row.try_get("program_lines")?),
    ) {
        (Some(name), Some(sha256), Some(lines)) => Some(ProgramId {
            name,
            sha256,
            lines,
        }),
        _ => None,
    };
    let measured = match (
        row.try_get::<Option<f64>, _>("max_overcut_mm")?,
        row.try_get::<Option<f64>, _>("max_undercut_mm")?,
        row.try_get::<Option<f64>, _>("delta_mm")?,
        row.try_get::<Option<i64>, _>("within_delta")?,
    ) {
        (Some(max_overcut_mm), Some(max_undercut_mm), Some(delta_mm), Some(within)) => {
            Some(Measured {
                max_overcut_mm,
                max_undercut_mm,
                delta_mm,
                within_delta: within != 0,
            })
        }
        _ => None,
    };
    let plan_report = row
        .try_get::<Option<String>, _>("plan_report")?
        .map(|text| serde_json::from_str(&text).unwrap_or(serde_json::Value::String(text)));
    let provenance = row
        .try_get::<Option<String>, _>("provenance")?
        .map(|text| serde_json::from_str(&text).unwrap_or(serde_json::Value::String(text)));
    let log = row
        .try_get::<Option<String>, _>("log_path")?
        .map(|path| -> Result<LogPlace, sqlx::Error> {
            Ok(LogPlace {
                path: PathBuf::from(path),
                offset: row
                    .try_get::<Option<i64>, _>("log_offset")?
                    .map_or(0, |o| o.max(0) as u64),
            })
        })
        .transpose()?;
    Ok(Run {
        uid: row.try_get::<Option<String>, _>("uid")?.map(Uid::from_text),
        pid: u32::try_from(row.try_get::<i64, _>("pid")?).unwrap_or(u32::MAX),
        job_file: snapshot("job_path", "job_sha256", "job_text")?,
        machine_file: snapshot("machine_path", "machine_sha256", "machine_text")?,
        program_id,
        port: row.try_get("port")?,
        plan_report,
        provenance,
        measured,
        resume_from: usize_of(row.try_get("resume_from")?),
        resumes: row.try_get("resumes")?,
        possibly_run_to: usize_of(row.try_get("possibly_run_to")?),
        last_line: usize_of(row.try_get("last_line")?),
        log,
        notes,
        summary,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::records::block_on;

    #[test]
    fn every_sqlite_connection_waits_for_another_writer() {
        let dir = tempfile::tempdir().unwrap();
        let options = SqliteConnectOptions::new()
            .filename(dir.path().join("runs.sqlite"))
            .create_if_missing(true);
        let waits: i64 = block_on(async {
            sqlx::any::install_default_drivers();
            let database = Database::sqlite(&options, true, "runs.sqlite".into())
                .await
                .unwrap();
            sqlx::query("PRAGMA busy_timeout")
                .fetch_one(&database.pool)
                .await
                .unwrap()
                .try_get(0)
                .unwrap()
        });
        assert_eq!(waits, SQLITE_BUSY_TIMEOUT.as_millis() as i64);
    }

    #[test]
    fn a_search_word_is_matched_as_it_is_written() {
        assert_eq!(contains("Double"), "%double%");
        assert_eq!(contains("50%_a\\b"), "%50\\%\\_a\\\\b%");
    }

    #[test]
    fn an_orphan_without_a_readable_log_is_interrupted_and_says_why() {
        let (ending, _) = orphan_ending(42, "2026-05-01T00:00:00.000Z", None);
        assert_eq!(ending.outcome, Outcome::Interrupted);
        assert!(ending.reason.as_deref().unwrap().contains("(42)"));
        let missing = std::io::Error::from(std::io::ErrorKind::NotFound);
        let (ending, _) = orphan_ending(
            42,
            "2026-05-01T00:00:00.000Z",
            Some(("/gone/exec.jsonl".into(), Err(missing))),
        );
        assert_eq!(ending.outcome, Outcome::Interrupted);
        assert!(ending
            .reason
            .as_deref()
            .unwrap()
            .contains("/gone/exec.jsonl"));
    }

    #[test]
    fn an_orphan_whose_log_ended_the_run_is_closed_as_the_log_says_at_its_last_event() {
        let facts = LogFacts {
            ended: Some(Ended::Completed),
            last_t: Some(90.5),
            ..LogFacts::default()
        };
        let (ending, ended) = orphan_ending(
            42,
            "2026-05-01T00:00:00.000Z",
            Some(("exec.jsonl".into(), Ok(facts))),
        );
        assert_eq!(ending.outcome, Outcome::Completed);
        assert_eq!(ended, "2026-05-01T00:01:30.500Z");
        assert!(ending.notes.is_empty());
    }
}
