//! The database of run records: SQLite (one file, no server, created on first use) or
//! PostgreSQL (a shop's server, given as a `postgres://` URL), through sqlx's `Any` driver,
//! so both run the same code and the same SQL. The schema is versioned migrations
//! embedded in the binary (`src/records/migrations/`), brought up to date each time the
//! database is opened: a database a newer whirl has migrated further is refused, not
//! written in a form it does not know.

use std::borrow::Cow;
use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::str::FromStr;
use std::time::Duration;

use sqlx::any::{AnyConnectOptions, AnyPoolOptions, AnyRow};
use sqlx::migrate::{MigrateError, Migration, MigrationType, Migrator};
use sqlx::sqlite::SqliteConnectOptions;
use sqlx::{AnyPool, ConnectOptions, Executor as _, Row, SqlSafeStr};

use super::from_log::{read_run, LogFacts};
use super::process::{Liveness, Process};
use super::time::Timestamp;
use super::{
    Ending, FileSnapshot, Filter, Kind, LogPlace, Measured, NewRun, Note, NoteKind, Outcome,
    ProgramId, Run, RunId, RunMode, RunProvenance, RunSummary,
};
use crate::log::Ended;

/// Where the records are kept.
#[derive(Debug, Clone)]
pub enum Place {
    /// A SQLite file; `create`: made, with its folder, if missing.
    Sqlite {
        /// How to open it.
        options: Box<SqliteConnectOptions>,
        /// Whether to create it.
        create: bool,
    },
    /// A PostgreSQL database, by its URL.
    Postgres(String),
}

/// The environment variable that names the database when `--db` does not.
pub const ENV: &str = "WHIRL_DB";

impl Place {
    /// A database as the user names it: a `postgres://` (or `postgresql://`) URL, a
    /// `sqlite:` URL (`sqlite://runs.sqlite?mode=ro`), or a plain path to a SQLite file.
    /// A SQLite file is created if missing, unless the URL gives its `mode`.
    pub fn parse(text: &str) -> Result<Place, RecordError> {
        if text.starts_with("postgres://") || text.starts_with("postgresql://") {
            return Ok(Place::Postgres(text.to_owned()));
        }
        if text.starts_with("sqlite:") {
            if text.starts_with("sqlite::memory:") || text.contains("mode=memory") {
                return Err(RecordError::Place(format!(
                    "{text}: a database in memory keeps no record past the run: give a \
                     SQLite file or a postgres:// URL"
                )));
            }
            let options = SqliteConnectOptions::from_str(text)
                .map_err(|e| RecordError::Place(format!("{text}: {e}")))?;
            let file = absolute(options.get_filename());
            let create = !text.contains("mode=");
            return Ok(Place::Sqlite {
                options: Box::new(options.filename(file).create_if_missing(create)),
                create,
            });
        }
        if let Some((scheme, _)) = text.split_once("://") {
            return Err(RecordError::Place(format!(
                "{text}: a {scheme}:// database is not one whirl keeps records in: give a \
                 SQLite file or a postgres:// URL"
            )));
        }
        if text.is_empty() {
            return Err(RecordError::Place(
                "an empty name is no database: give a SQLite file or a postgres:// URL".into(),
            ));
        }
        Ok(Place::sqlite_file(Path::new(text)))
    }

    /// The SQLite file at `path`, created if missing.
    fn sqlite_file(path: &Path) -> Place {
        Place::Sqlite {
            options: Box::new(
                SqliteConnectOptions::new()
                    .filename(absolute(path))
                    .create_if_missing(true),
            ),
            create: true,
        }
    }

    /// The database to use: `given` (`--db`) if any, else the `WHIRL_DB` environment
    /// variable, else [`Place::default_in`] the user's data folder.
    pub fn resolve(given: Option<&str>) -> Result<Place, RecordError> {
        if let Some(given) = given {
            return Place::parse(given);
        }
        match std::env::var_os(ENV) {
            Some(value) if !value.is_empty() => Place::parse(&value.to_string_lossy()),
            _ => Place::default_in(
                std::env::var_os("XDG_DATA_HOME").as_deref(),
                std::env::var_os("HOME").as_deref(),
            ),
        }
    }

    /// The default: `runs.sqlite` in the user's data folder, `$XDG_DATA_HOME/whirl/` (an
    /// absolute one) or `$HOME/.local/share/whirl/`. One index of every run the user
    /// makes, whichever folder its job and its log are in; a plan has no log to sit beside.
    pub fn default_in(
        xdg_data_home: Option<&OsStr>,
        home: Option<&OsStr>,
    ) -> Result<Place, RecordError> {
        let data = match (xdg_data_home.map(Path::new), home.map(Path::new)) {
            (Some(xdg), _) if xdg.is_absolute() => xdg.to_owned(),
            (_, Some(home)) if home.is_absolute() => home.join(".local/share"),
            _ => {
                return Err(RecordError::Place(format!(
                    "no home folder (HOME) to keep the run records in: name a database with \
                     --db or {ENV}"
                )))
            }
        };
        Ok(Place::sqlite_file(&data.join("whirl").join("runs.sqlite")))
    }

    /// The SQLite file the records are kept in; `None` for PostgreSQL, which is no file of
    /// the host's. A command checks it against its own files before anything is written
    /// (it may be none of them).
    pub fn file(&self) -> Option<&Path> {
        match self {
            Place::Sqlite { options, .. } => Some(options.get_filename()),
            Place::Postgres(_) => None,
        }
    }

    /// How the place is named in messages: the SQLite file, or the PostgreSQL URL without
    /// its password.
    pub fn name(&self) -> String {
        match self {
            Place::Sqlite { options, .. } => options.get_filename().display().to_string(),
            Place::Postgres(url) => without_password(url),
        }
    }
}

/// `path` from the root: the store hands sqlx its file as a URL, `sqlite:///…`, in which a
/// relative name would be read as a host (and one with a colon as a host and a port). A
/// path that cannot be made absolute (no working folder) is left as it is, and its opening
/// says why.
fn absolute(path: &Path) -> PathBuf {
    std::path::absolute(path).unwrap_or_else(|_| path.to_owned())
}

/// `postgres://user:secret@host/db` → `postgres://user:***@host/db`.
fn without_password(url: &str) -> String {
    let Some((scheme, rest)) = url.split_once("://") else {
        return url.to_owned();
    };
    let authority_end = rest.find('/').unwrap_or(rest.len());
    match rest[..authority_end].rfind('@') {
        Some(at) => match rest[..at].split_once(':') {
            Some((user, _)) => format!("{scheme}://{user}:***{}", &rest[at..]),
            None => url.to_owned(),
        },
        None => url.to_owned(),
    }
}

/// Why the records could not be opened, read or written.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    /// The database named is not one.
    #[error("{0}")]
    Place(String),
    /// The folder of a new SQLite file could not be made.
    #[error("cannot make the folder {} for the run records: {error}", .path.display())]
    Folder {
        /// The folder.
        path: PathBuf,
        /// Why.
        error: std::io::Error,
    },
    /// The database could not be reached or opened.
    #[error("cannot open the run records at {place}: {error}")]
    Open {
        /// The database, as [`Place::name`] says it.
        place: String,
        /// Why.
        error: sqlx::Error,
    },
    /// The schema could not be brought up to date.
    #[error("cannot bring the run records at {place} up to this whirl's schema: {error}")]
    Migrate {
        /// The database.
        place: String,
        /// Why.
        error: MigrateError,
    },
    /// Other writers took every number tried for a new row (PostgreSQL; SQLite writes one
    /// at a time).
    #[error("the run records at {place}: cannot {what}: other writers took each of the {ID_TRIES} numbers tried")]
    Contended {
        /// The database.
        place: String,
        /// What the store was doing.
        what: &'static str,
    },
    /// SQLite's quick check found the file damaged (a disk fault, a copy taken mid-write):
    /// refused before anything is read from or written to it, so that nothing recorded in
    /// it is lost to a write over a broken page.
    #[error(
        "the run records at {place} are damaged (SQLite's quick check: {problem}); nothing \
         was read from or written to them. Keep the file: move it aside (mv {file} \
         {file}.damaged) and whirl starts a new one there; sqlite3's .recover reads what the \
         old one still holds (sqlite3 {file}.damaged .recover | sqlite3 {file}.recovered)",
        file = .path.display()
    )]
    Damaged {
        /// The database.
        place: String,
        /// Its file.
        path: PathBuf,
        /// What the check found first.
        problem: String,
    },
    /// A query failed.
    #[error("the run records at {place}: cannot {what}: {error}")]
    Query {
        /// The database.
        place: String,
        /// What the store was doing.
        what: &'static str,
        /// Why.
        error: sqlx::Error,
    },
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

/// The records' schema, version by version.
fn migrator() -> Migrator {
    Migrator::with_migrations(vec![
        Migration::new(
            1,
            Cow::Borrowed("runs"),
            MigrationType::Simple,
            include_str!("migrations/0001_runs.sql").into_sql_str(),
            false,
        ),
        Migration::new(
            2,
            Cow::Borrowed("provenance"),
            MigrationType::Simple,
            include_str!("migrations/0002_provenance.sql").into_sql_str(),
            false,
        ),
    ])
}

/// How many times a new id is tried when another writer took the one chosen.
const ID_TRIES: usize = 20;

/// How long a SQLite connection waits for another writer (another whirl on the host, a
/// console) to let go of the file before its write fails: a run must not be refused, nor
/// its record left open, because another run was writing its own a moment earlier.
/// PostgreSQL writers wait for each other's row locks without one.
pub const SQLITE_BUSY_TIMEOUT: Duration = Duration::from_secs(30);

/// An open database of run records.
#[derive(Debug, Clone)]
pub struct Store {
    pool: AnyPool,
    place: String,
}

impl Store {
    /// Opens the records at `place`, creating a SQLite file (and its folder) on first use,
    /// and brings the schema up to date.
    pub async fn open(place: &Place) -> Result<Store, RecordError> {
        sqlx::any::install_default_drivers();
        let name = place.name();
        let url = match place {
            Place::Sqlite { options, create } => {
                let parent = options.get_filename().parent();
                if let Some(folder) = parent.filter(|p| !p.as_os_str().is_empty()) {
                    if *create && !folder.exists() {
                        std::fs::create_dir_all(folder).map_err(|error| RecordError::Folder {
                            path: folder.to_owned(),
                            error,
                        })?;
                    }
                }
                options.to_url_lossy().to_string()
            }
            Place::Postgres(url) => url.clone(),
        };
        let open = |error| RecordError::Open {
            place: name.clone(),
            error,
        };
        let options = AnyConnectOptions::from_str(&url)
            .map_err(open)?
            .disable_statement_logging();
        let pool = AnyPoolOptions::new()
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
            .connect_with(options)
            .await
            .map_err(open)?;
        if let Place::Sqlite { options, .. } = place {
            quick_check(&pool, &name, options.get_filename()).await?;
        }
        // Two whirls opening a new SQLite file at once may both try the first migration
        // (SQLite has no lock for the migrator to take); the one that loses finds it done
        // when it looks again.
        let migrator = migrator();
        if migrator.run(&pool).await.is_err() {
            migrator
                .run(&pool)
                .await
                .map_err(|error| RecordError::Migrate {
                    place: name.clone(),
                    error,
                })?;
        }
        Ok(Store { pool, place: name })
    }

    /// The database, as messages name it.
    pub fn place(&self) -> &str {
        &self.place
    }

    fn error(&self, what: &'static str) -> impl Fn(sqlx::Error) -> RecordError + '_ {
        move |error| RecordError::Query {
            place: self.place.clone(),
            what,
            error,
        }
    }

    fn contended(&self, what: &'static str) -> RecordError {
        RecordError::Contended {
            place: self.place.clone(),
            what,
        }
    }

    /// Opens a record, `running`, for a run about to start; a run that resumes an earlier
    /// one ([`NewRun::resume_from`]) is linked to it.
    pub async fn begin(&self, run: &NewRun) -> Result<RunId, RecordError> {
        let resumes = match (&run.program, run.resume_from) {
            (Some(program), Some(line)) => self.resumed_run(&program.sha256, line).await?,
            _ => None,
        };
        let started = Timestamp::now().to_text();
        let file = |f: &Option<FileSnapshot>, part: fn(&FileSnapshot) -> &String| {
            f.as_ref().map(|f| part(f).clone())
        };
        for _ in 0..ID_TRIES {
            let inserted = sqlx::query(
                "INSERT INTO runs (id, kind, outcome, started_at, host, pid, process_started, \
                 boot_id, job_path, job_sha256, job_text, machine_name, machine_path, \
                 machine_sha256, machine_text, program_name, program_sha256, program_lines, \
                 transport, port, plan_report, resume_from, resumes, log_path, log_offset, \
                 provenance) \
                 SELECT COALESCE(MAX(id), 0) + 1, $1, 'running', $2, $3, $4, $5, $6, $7, $8, \
                 $9, $10, $11, $12, $13, $14, $15, $16, $17, $18, $19, $20, $21, $22, $23, \
                 $24 FROM runs RETURNING id",
            )
            .bind(run.kind.as_str())
            .bind(&started)
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
            .fetch_one(&self.pool)
            .await;
            match inserted {
                Ok(row) => return row.try_get("id").map_err(self.error("open a record")),
                Err(e) if taken(&e) => continue,
                Err(e) => return Err(self.error("open a record")(e)),
            }
        }
        Err(self.contended("open a record"))
    }

    /// The run a run of the program `sha256` starting at `line` resumes: the latest that
    /// did not complete, the one whose resume point is `line` if any is.
    async fn resumed_run(&self, sha256: &str, line: usize) -> Result<Option<RunId>, RecordError> {
        sqlx::query(
            "SELECT id FROM runs WHERE program_sha256 = $1 \
             AND outcome IN ('stopped', 'failed', 'interrupted') \
             ORDER BY CASE WHEN resume_at = $2 THEN 0 ELSE 1 END, id DESC LIMIT 1",
        )
        .bind(sha256)
        .bind(self::line(line))
        .fetch_optional(&self.pool)
        .await
        .map_err(self.error("find the run this one resumes"))?
        .map(|row| row.try_get("id"))
        .transpose()
        .map_err(self.error("find the run this one resumes"))
    }

    /// Adds a note to a run as it goes (an alarm, a hold, a resume).
    pub async fn note(&self, id: RunId, note: &Note) -> Result<(), RecordError> {
        for _ in 0..ID_TRIES {
            let at = Timestamp::now().to_text();
            let written = sqlx::query(
                "INSERT INTO run_notes (run_id, seq, at, kind, line, code, text) \
                 SELECT $1, COALESCE(MAX(seq), 0) + 1, $2, $3, $4, $5, $6 \
                 FROM run_notes WHERE run_id = $1",
            )
            .bind(id)
            .bind(note.at.clone().unwrap_or(at))
            .bind(note.kind.as_str())
            .bind(note.line.map(line))
            .bind(note.code.map(i64::from))
            .bind(&note.text)
            .execute(&self.pool)
            .await;
            match written {
                Ok(_) => return Ok(()),
                Err(e) if taken(&e) => continue,
                Err(e) => return Err(self.error("add a note to a run")(e)),
            }
        }
        Err(self.contended("add a note to a run"))
    }

    /// Closes a running record with how its run ended. `false` if it was not running (it
    /// was closed already, by its process or as interrupted).
    pub async fn finish(&self, id: RunId, ending: &Ending) -> Result<bool, RecordError> {
        let ended = Timestamp::now().to_text();
        self.close(id, ending, &ended).await
    }

    async fn close(&self, id: RunId, ending: &Ending, ended: &str) -> Result<bool, RecordError> {
        let what = "close a record";
        // Its notes are numbered after the last one written: a note written at the same
        // moment (a hold pressed on the console) takes the number, and the close tries again.
        for _ in 0..ID_TRIES {
            match self.close_once(id, ending, ended).await {
                Err(e) if taken(&e) => continue,
                closed => return closed.map_err(self.error(what)),
            }
        }
        Err(self.contended(what))
    }

    async fn close_once(&self, id: RunId, ending: &Ending, ended: &str) -> sqlx::Result<bool> {
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
        let last: i64 =
            sqlx::query("SELECT COALESCE(MAX(seq), 0) AS seq FROM run_notes WHERE run_id = $1")
                .bind(id)
                .fetch_one(&mut *tx)
                .await
                .and_then(|row| row.try_get("seq"))?;
        for (seq, note) in (last + 1..).zip(ending.notes.iter().chain(&stop)) {
            sqlx::query(
                "INSERT INTO run_notes (run_id, seq, at, kind, line, code, text) \
                 VALUES ($1, $2, $3, $4, $5, $6, $7)",
            )
            .bind(id)
            .bind(seq)
            .bind(note.at.clone().unwrap_or_else(|| ended.to_owned()))
            .bind(note.kind.as_str())
            .bind(note.line.map(line))
            .bind(note.code.map(i64::from))
            .bind(&note.text)
            .execute(&mut *tx)
            .await?;
        }
        tx.commit().await?;
        Ok(true)
    }

    /// Closes the records of this host whose process is gone without closing them (see
    /// [`Process::liveness`]), each from what its log says ([`read_run`]): the outcome its
    /// log's end gives, or `interrupted` if the log has none, with the resume point, the
    /// last line known done and the alarms. The logs are only read. Returns the runs
    /// closed, and the outcome each was given.
    pub async fn close_orphans(
        &self,
        here: &Process,
    ) -> Result<Vec<(RunId, Outcome)>, RecordError> {
        let what = "look for runs whose process is gone";
        let rows = sqlx::query(
            "SELECT id, pid, process_started, boot_id, started_at, log_path, log_offset, \
             resume_from FROM runs WHERE outcome = 'running' AND host = $1 ORDER BY id",
        )
        .bind(&here.host)
        .fetch_all(&self.pool)
        .await
        .map_err(self.error(what))?;
        let mut closed = Vec::new();
        for row in rows {
            let get = |e| self.error(what)(e);
            let id: RunId = row.try_get("id").map_err(get)?;
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
            if self.close(id, &ending, &ended).await? {
                closed.push((id, ending.outcome));
            }
        }
        Ok(closed)
    }

    /// The runs `filter` lets through, newest first.
    pub async fn list(&self, filter: &Filter) -> Result<Vec<RunSummary>, RecordError> {
        let what = "list the runs";
        let rows = sqlx::query(
            "SELECT id, kind, outcome, started_at, ended_at, job_path, program_name, \
             machine_name, transport, port, resume_at, reason FROM runs \
             WHERE ($1 IS NULL OR LOWER(job_path) LIKE $1 ESCAPE '\\' \
                    OR LOWER(program_name) LIKE $1 ESCAPE '\\') \
             AND ($2 IS NULL OR LOWER(machine_name) LIKE $2 ESCAPE '\\' \
                  OR LOWER(machine_path) LIKE $2 ESCAPE '\\') \
             AND ($3 IS NULL OR started_at >= $3) \
             AND ($4 IS NULL OR started_at < $4) \
             AND ($5 IS NULL OR outcome = $5) \
             ORDER BY id DESC LIMIT $6",
        )
        .bind(filter.job.as_deref().map(contains))
        .bind(filter.machine.as_deref().map(contains))
        .bind(filter.since.map(Timestamp::to_text))
        .bind(filter.until.map(Timestamp::to_text))
        .bind(filter.outcome.map(Outcome::as_str))
        .bind(filter.limit.map_or(i64::MAX, i64::from))
        .fetch_all(&self.pool)
        .await
        .map_err(self.error(what))?;
        rows.iter()
            .map(summary)
            .collect::<Result<_, _>>()
            .map_err(self.error(what))
    }

    /// The whole record of run `id`, with its notes; `None` if there is none.
    pub async fn show(&self, id: RunId) -> Result<Option<Run>, RecordError> {
        let what = "read the run";
        let Some(row) = sqlx::query(
            "SELECT id, kind, outcome, started_at, ended_at, job_path, program_name, \
             machine_name, transport, resume_at, reason, host, pid, job_sha256, job_text, \
             machine_path, machine_sha256, machine_text, program_sha256, program_lines, port, \
             plan_report, max_overcut_mm, max_undercut_mm, delta_mm, within_delta, \
             resume_from, resumes, possibly_run_to, last_line, log_path, log_offset, \
             provenance FROM runs WHERE id = $1",
        )
        .bind(id)
        .fetch_optional(&self.pool)
        .await
        .map_err(self.error(what))?
        else {
            return Ok(None);
        };
        let notes = sqlx::query(
            "SELECT at, kind, line, code, text FROM run_notes WHERE run_id = $1 ORDER BY seq",
        )
        .bind(id)
        .fetch_all(&self.pool)
        .await
        .map_err(self.error(what))?;
        let notes = notes
            .iter()
            .map(note)
            .collect::<Result<Vec<_>, _>>()
            .map_err(self.error(what))?;
        run(&row, notes).map(Some).map_err(self.error(what))
    }

    /// Closes the connections.
    pub async fn close_connections(self) {
        self.pool.close().await;
    }
}

/// Another writer took the id (or the note's number) chosen.
fn taken(error: &sqlx::Error) -> bool {
    matches!(error, sqlx::Error::Database(e) if e.is_unique_violation())
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
        host: row.try_get("host")?,
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

    #[test]
    fn a_database_is_named_by_a_url_or_a_path() {
        assert!(matches!(
            Place::parse("postgres://whirl@127.0.0.1:5432/shop").unwrap(),
            Place::Postgres(_)
        ));
        assert!(matches!(
            Place::parse("postgresql://127.0.0.1/shop").unwrap(),
            Place::Postgres(_)
        ));
        let Place::Sqlite { options, create } = Place::parse("records/runs.sqlite").unwrap() else {
            panic!("a path is a SQLite file");
        };
        let here = std::env::current_dir().unwrap();
        assert_eq!(options.get_filename(), here.join("records/runs.sqlite"));
        assert!(create);
        let Place::Sqlite { create, .. } = Place::parse("sqlite://runs.sqlite?mode=ro").unwrap()
        else {
            panic!("a sqlite: URL is a SQLite file");
        };
        assert!(!create, "the URL gives its mode");
        let error = Place::parse("mysql://db/shop").unwrap_err().to_string();
        assert!(
            error.contains("mysql://") && error.contains("postgres://"),
            "{error}"
        );
        assert!(Place::parse("").is_err());
        assert!(Place::parse("sqlite://x?mode=sideways").is_err());
        for memory in ["sqlite::memory:", "sqlite://x?mode=memory"] {
            let error = Place::parse(memory).unwrap_err().to_string();
            assert!(error.contains("in memory"), "{error}");
        }
    }

    #[test]
    fn a_sqlite_place_is_a_file_and_the_others_are_none() {
        let file = |text: &str| Place::parse(text).unwrap().file().map(Path::to_owned);
        let here = std::env::current_dir().unwrap();
        assert_eq!(
            file("records/runs.sqlite").unwrap(),
            here.join("records/runs.sqlite")
        );
        assert_eq!(
            file("sqlite://shop.sqlite?mode=rw").unwrap(),
            here.join("shop.sqlite")
        );
        assert_eq!(file("postgres://whirl@127.0.0.1/shop"), None);
    }

    fn block_on<F: std::future::Future>(future: F) -> F::Output {
        tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap()
            .block_on(future)
    }

    #[test]
    fn every_sqlite_connection_waits_for_another_writer() {
        let dir = tempfile::tempdir().unwrap();
        let place = Place::parse(dir.path().join("runs.sqlite").to_str().unwrap()).unwrap();
        let waits: i64 = block_on(async {
            let store = Store::open(&place).await.unwrap();
            sqlx::query("PRAGMA busy_timeout")
                .fetch_one(&store.pool)
                .await
                .unwrap()
                .try_get(0)
                .unwrap()
        });
        assert_eq!(waits, SQLITE_BUSY_TIMEOUT.as_millis() as i64);
    }

    #[test]
    fn writers_at_once_on_one_sqlite_file_each_get_their_run_recorded() {
        // Eight processes' worth of stores (each its own connections) opening a new file
        // and recording five runs each, all at once: every run gets a record, and each a
        // number of its own.
        let dir = tempfile::tempdir().unwrap();
        let place = Place::parse(dir.path().join("runs.sqlite").to_str().unwrap()).unwrap();
        let writers: Vec<_> = (0..8)
            .map(|_| {
                let place = place.clone();
                std::thread::spawn(move || {
                    block_on(async {
                        let store = Store::open(&place).await.unwrap();
                        let mut ids = Vec::new();
                        for _ in 0..5 {
                            let id = store.begin(&NewRun::new(Kind::Plan)).await.unwrap();
                            store
                                .finish(id, &Ending::new(Outcome::Completed))
                                .await
                                .unwrap();
                            ids.push(id);
                        }
                        ids
                    })
                })
            })
            .collect();
        let mut ids: Vec<RunId> = writers
            .into_iter()
            .flat_map(|w| w.join().unwrap())
            .collect();
        ids.sort();
        assert_eq!(ids, (1..=40).collect::<Vec<RunId>>());
    }

    #[test]
    fn the_default_is_in_the_users_data_folder() {
        let name = |xdg: Option<&str>, home: Option<&str>| {
            Place::default_in(xdg.map(OsStr::new), home.map(OsStr::new)).map(|p| p.name())
        };
        assert_eq!(
            name(Some("/data"), Some("/home/op")).unwrap(),
            "/data/whirl/runs.sqlite"
        );
        // A relative XDG_DATA_HOME is to be ignored (the XDG base directory rules).
        assert_eq!(
            name(Some("data"), Some("/home/op")).unwrap(),
            "/home/op/.local/share/whirl/runs.sqlite"
        );
        let error = name(None, None).unwrap_err().to_string();
        assert!(error.contains("--db") && error.contains(ENV), "{error}");
    }

    #[test]
    fn a_password_is_never_said() {
        assert_eq!(
            without_password("postgres://whirl:s3cret@10.0.0.5:5432/shop"),
            "postgres://whirl:***@10.0.0.5:5432/shop"
        );
        assert_eq!(
            without_password("postgres://whirl@host/shop"),
            "postgres://whirl@host/shop"
        );
        assert_eq!(
            Place::parse("postgres://a:b@h/d").unwrap().name(),
            "postgres://a:***@h/d"
        );
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
