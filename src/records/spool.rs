//! The spool: a SQLite file of the host's that keeps the run records a shop's PostgreSQL
//! cannot take (down, not answering, gone away mid-run), and the upload that sends them
//! there once it answers. Records never delay or stop a cut, and none is lost or written
//! twice:
//!
//! - a run whose database cannot be reached when it begins is opened in the spool, and
//!   noted and closed there;
//! - a run opened in the database whose note or ending the database cannot take is
//!   continued in the spool: a copy of its beginning (the same key, the same start), then
//!   that write and every later one of the run;
//! - an upload sends each run its process is done with (closed, or closed here first from
//!   its log if its process is gone) in one transaction of the database's, keyed by the
//!   run's key ([`Uid`]): a run the database does not hold is inserted whole, numbered by
//!   the database; one it holds (a continuation, or an upload tried again after a crash
//!   between the database's commit and the spool's removal) is given the spool's ending
//!   if the database's is still running, and the notes it lacks (by their keys). Then
//!   the run is removed from the spool.
//!
//! The spool has the records' own schema (the same migrations), so that its runs are
//! opened, noted, closed and closed from their logs by the same code as the database's.
//! One spool a database ([`file_name`]), so that a run goes only to the database it was
//! meant for.

use std::path::{Path, PathBuf};
use std::str::FromStr;
use std::sync::Arc;

use sqlx::postgres::PgConnectOptions;
use sqlx::sqlite::SqliteConnectOptions;
use sqlx::{AnyPool, Row};
use tokio::sync::OnceCell;

use super::database::{add_note, next_id, resumed_run, taken, Database, Failure, ID_TRIES};
use super::process::Process;
use super::store::{Kept, RecordError, Recorded};
use super::uid::Uid;
use super::{NewRun, Note, NoteKind, RunId};

/// The spool's file name for the PostgreSQL database at `url`: its host, port and
/// database, each character that is no letter, digit, `.` or `_` made `_`
/// (`spool-db.shop.lan-5432-whirl.sqlite`).
pub fn file_name(url: &str) -> String {
    let named = match PgConnectOptions::from_str(url) {
        Ok(options) => format!(
            "{}-{}-{}",
            options.get_host(),
            options.get_port(),
            options.get_database().unwrap_or(options.get_username())
        ),
        Err(_) => url.to_owned(),
    };
    let safe: String = named
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '-') {
                c
            } else {
                '_'
            }
        })
        .collect();
    format!("spool-{safe}.sqlite")
}

/// A database's spool.
#[derive(Debug, Clone)]
pub(super) struct Spool {
    file: PathBuf,
    /// Opened (and made, with its folder) when first written or read.
    database: Arc<OnceCell<Database>>,
}

impl Spool {
    pub(super) fn new(file: PathBuf) -> Spool {
        Spool {
            file,
            database: Arc::new(OnceCell::new()),
        }
    }

    pub(super) fn file(&self) -> &Path {
        &self.file
    }

    /// Whether the spool was ever made (one never made keeps nothing).
    pub(super) fn exists(&self) -> bool {
        self.file.exists()
    }

    /// Where a write kept here went, and why.
    pub(super) fn kept(&self, why: String) -> Kept {
        Kept::Spool {
            file: self.file.clone(),
            why,
        }
    }

    /// The spool's database, opened (made on first use) and brought up to date.
    pub(super) async fn database(&self) -> Result<&Database, RecordError> {
        self.database
            .get_or_try_init(|| async {
                let options = SqliteConnectOptions::new()
                    .filename(&self.file)
                    .create_if_missing(true);
                Database::sqlite(&options, true, self.file.display().to_string()).await
            })
            .await
    }

    /// The spool's number of the run keyed `uid`, if it keeps it.
    pub(super) async fn find(&self, uid: &Uid) -> Result<Option<RunId>, RecordError> {
        if !self.exists() && self.database.get().is_none() {
            return Ok(None);
        }
        self.database().await?.find(uid).await
    }

    /// Opens run `run`'s record here, keyed `uid`, started at `started`.
    pub(super) async fn begin(
        &self,
        run: &NewRun,
        uid: &Uid,
        started: &str,
    ) -> Result<RunId, RecordError> {
        self.database().await?.begin(run, uid, started).await
    }

    /// The spool's number of the continuation of `run`, a run opened in the database: a
    /// copy of its beginning, made on the first write the database could not take.
    pub(super) async fn continuation(&self, run: &Recorded) -> Result<RunId, RecordError> {
        if let Some(id) = self.find(&run.uid).await? {
            return Ok(id);
        }
        match self
            .begin(&run.begun.run, &run.uid, &run.begun.started)
            .await
        {
            Ok(id) => Ok(id),
            // Another writer of the run (a console's hold beside its run's end) made it
            // a moment before: its key is taken.
            Err(error) => self.find(&run.uid).await?.ok_or(error),
        }
    }

    /// Uploads what the spool keeps to `database` ([the module's docs](self)); `here`: this
    /// process, which judges whether a run's process is gone.
    pub(super) async fn upload(
        &self,
        database: &Database,
        here: &Process,
    ) -> Result<Uploaded, RecordError> {
        let mut uploaded = Uploaded::default();
        if !self.exists() {
            return Ok(uploaded);
        }
        let spool = self.database().await?;
        database.ready().await?;
        spool.close_orphans(here).await?;
        let what = "read the runs it keeps";
        let (runs, waiting) = spool.bounded(what, spooled_runs(spool.pool())).await?;
        uploaded.waiting = waiting;
        for run in runs {
            let id = database
                .bounded("upload a run from the spool", upload(database.pool(), &run))
                .await?;
            spool
                .bounded("remove an uploaded run", remove(spool.pool(), run.id))
                .await?;
            uploaded.runs.push((run.id, id));
        }
        Ok(uploaded)
    }

    /// Closes the connections, if the spool was opened.
    pub(super) async fn close_connections(self) {
        if let Some(database) = Arc::into_inner(self.database).and_then(OnceCell::into_inner) {
            database.close_connections().await;
        }
    }
}

/// What an upload did.
#[derive(Debug, Default, Clone, PartialEq, Eq)]
pub struct Uploaded {
    /// Each run uploaded: its number in the spool, and in the database.
    pub runs: Vec<(RunId, RunId)>,
    /// The runs the spool keeps still, their processes still at them.
    pub waiting: usize,
}

/// How a column of `runs` holds its values.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Type {
    Int,
    Real,
    Text,
}

/// Every column of `runs` an upload carries (the run's number and the run it resumes are
/// the database's own, given on upload), and whether a run's ending sets it.
const COLUMNS: [(&str, Type, bool); 34] = [
    ("uid", Type::Text, false),
    ("kind", Type::Text, false),
    ("outcome", Type::Text, true),
    ("reason", Type::Text, true),
    ("started_at", Type::Text, false),
    ("ended_at", Type::Text, true),
    ("host", Type::Text, false),
    ("pid", Type::Int, false),
    ("process_started", Type::Int, false),
    ("boot_id", Type::Text, false),
    ("job_path", Type::Text, false),
    ("job_sha256", Type::Text, false),
    ("job_text", Type::Text, false),
    ("machine_name", Type::Text, false),
    ("machine_path", Type::Text, false),
    ("machine_sha256", Type::Text, false),
    ("machine_text", Type::Text, false),
    ("program_name", Type::Text, true),
    ("program_sha256", Type::Text, true),
    ("program_lines", Type::Int, true),
    ("transport", Type::Text, false),
    ("port", Type::Text, false),
    ("plan_report", Type::Text, true),
    ("max_overcut_mm", Type::Real, true),
    ("max_undercut_mm", Type::Real, true),
    ("delta_mm", Type::Real, true),
    ("within_delta", Type::Int, true),
    ("resume_from", Type::Int, false),
    ("resume_at", Type::Int, true),
    ("possibly_run_to", Type::Int, true),
    ("last_line", Type::Int, true),
    ("log_path", Type::Text, false),
    ("log_offset", Type::Int, false),
    ("provenance", Type::Text, true),
];

/// A value of a column.
#[derive(Debug, Clone, PartialEq)]
enum Value {
    Int(i64),
    Real(f64),
    Text(String),
}

/// A run the spool keeps, closed, as its columns hold it.
#[derive(Debug)]
struct Spooled {
    /// The spool's number.
    id: RunId,
    uid: Uid,
    /// The columns that hold a value (an absent one is left to the database's default,
    /// NULL: sqlx's Any driver hands PostgreSQL an absent f64 as a 4-byte float, which
    /// the server refuses for a DOUBLE PRECISION parameter).
    values: Vec<(&'static str, Value)>,
    /// The key of the run it resumes, if that is a run the spool kept.
    resumes: Option<Uid>,
    /// Its notes in order, each with its key.
    notes: Vec<(String, Note)>,
}

impl Spooled {
    fn text(&self, column: &str) -> Option<&str> {
        self.values.iter().find_map(|(c, v)| match v {
            Value::Text(text) if *c == column => Some(text.as_str()),
            _ => None,
        })
    }

    fn int(&self, column: &str) -> Option<i64> {
        self.values.iter().find_map(|(c, v)| match v {
            Value::Int(n) if *c == column => Some(*n),
            _ => None,
        })
    }
}

/// The runs the spool keeps that their processes are done with, in the order they began,
/// and how many it keeps still running.
async fn spooled_runs(pool: &AnyPool) -> Result<(Vec<Spooled>, usize), Failure> {
    let columns: Vec<String> = COLUMNS.iter().map(|(c, _, _)| format!("r.{c}")).collect();
    let rows = sqlx::query(built(format!(
        "SELECT r.id, p.uid AS resumes_uid, {} FROM runs r LEFT JOIN runs p ON p.id = r.resumes \
         WHERE r.outcome <> 'running' ORDER BY r.id",
        columns.join(", ")
    )))
    .fetch_all(pool)
    .await?;
    let mut runs = Vec::new();
    for row in rows {
        let mut values = Vec::new();
        for (column, kind, _) in COLUMNS {
            let value = match kind {
                Type::Int => row.try_get::<Option<i64>, _>(column)?.map(Value::Int),
                Type::Real => row.try_get::<Option<f64>, _>(column)?.map(Value::Real),
                Type::Text => row.try_get::<Option<String>, _>(column)?.map(Value::Text),
            };
            values.extend(value.map(|v| (column, v)));
        }
        let id: RunId = row.try_get("id")?;
        let uid = match values.iter().find(|(c, _)| *c == "uid") {
            Some((_, Value::Text(uid))) => Uid::from_text(uid.clone()),
            _ => {
                return Err(Failure::Sql(sqlx::Error::ColumnDecode {
                    index: "uid".into(),
                    source: format!("run {id} of the spool has no key").into(),
                }))
            }
        };
        let notes = sqlx::query(
            "SELECT uid, at, kind, line, code, text FROM run_notes WHERE run_id = $1 \
             ORDER BY seq",
        )
        .bind(id)
        .fetch_all(pool)
        .await?
        .iter()
        .map(|row| {
            let kind: String = row.try_get("kind")?;
            let note = Note {
                kind: NoteKind::from_word(&kind).unwrap_or(NoteKind::Stop),
                at: row.try_get("at")?,
                line: row
                    .try_get::<Option<i64>, _>("line")?
                    .and_then(|l| usize::try_from(l).ok()),
                code: row
                    .try_get::<Option<i64>, _>("code")?
                    .and_then(|c| u32::try_from(c).ok()),
                text: row.try_get("text")?,
            };
            Ok((row.try_get::<String, _>("uid")?, note))
        })
        .collect::<sqlx::Result<Vec<_>>>()?;
        runs.push(Spooled {
            id,
            uid,
            values,
            resumes: row
                .try_get::<Option<String>, _>("resumes_uid")?
                .map(Uid::from_text),
            notes,
        });
    }
    let waiting: i64 = sqlx::query("SELECT COUNT(*) AS n FROM runs WHERE outcome = 'running'")
        .fetch_one(pool)
        .await?
        .try_get("n")?;
    Ok((runs, usize::try_from(waiting).unwrap_or(0)))
}

/// Sends `run` to the database; its number there. Its notes are numbered after the run's
/// last there: a note written there at the same moment takes a number, and the upload
/// tries again.
async fn upload(pool: &AnyPool, run: &Spooled) -> Result<RunId, Failure> {
    for _ in 0..ID_TRIES {
        match upload_once(pool, run).await {
            Ok(Some(id)) => return Ok(id),
            // Another upload of the same spool inserted it a moment before: found now.
            Ok(None) => continue,
            Err(e) if taken(&e) => continue,
            Err(e) => return Err(e.into()),
        }
    }
    Err(Failure::Contended)
}

async fn upload_once(pool: &AnyPool, run: &Spooled) -> sqlx::Result<Option<RunId>> {
    let mut tx = pool.begin().await?;
    let held: Option<RunId> = sqlx::query("SELECT id FROM runs WHERE uid = $1")
        .bind(run.uid.as_str())
        .fetch_optional(&mut *tx)
        .await?
        .map(|row| row.try_get("id"))
        .transpose()?;
    let (id, ended_here) = match held {
        Some(id) => (id, end(&mut tx, id, run).await?),
        None => {
            let id = next_id(&mut tx).await?;
            let resumes = match &run.resumes {
                Some(uid) => sqlx::query("SELECT id FROM runs WHERE uid = $1")
                    .bind(uid.as_str())
                    .fetch_optional(&mut *tx)
                    .await?
                    .map(|row| row.try_get::<RunId, _>("id"))
                    .transpose()?,
                None => None,
            };
            let resumes = match (resumes, run.text("program_sha256"), run.int("resume_from")) {
                (Some(id), _, _) => Some(id),
                (None, Some(sha256), Some(line)) => {
                    let line = usize::try_from(line).unwrap_or(0);
                    resumed_run(&mut *tx, sha256, line, run.text("started_at")).await?
                }
                _ => None,
            };
            if !insert(&mut tx, id, resumes, run).await? {
                tx.rollback().await?;
                return Ok(None);
            }
            (id, true)
        }
    };
    for (key, note) in &run.notes {
        // An ending the database's record had already (a closing whose answer was lost)
        // brought its own notes.
        if !ended_here && run.uid.is_ending_note(key) {
            continue;
        }
        add_note(&mut *tx, id, Some(key), note, "").await?;
    }
    tx.commit().await?;
    Ok(Some(id))
}

/// Inserts `run` as number `id`; `false` if a run of its key is there already.
async fn insert(
    tx: &mut sqlx::Transaction<'_, sqlx::Any>,
    id: RunId,
    resumes: Option<RunId>,
    run: &Spooled,
) -> sqlx::Result<bool> {
    let mut columns = vec!["id"];
    columns.extend(resumes.map(|_| "resumes"));
    columns.extend(run.values.iter().map(|(c, _)| *c));
    let places: Vec<String> = (1..=columns.len()).map(|n| format!("${n}")).collect();
    let sql = format!(
        "INSERT INTO runs ({}) VALUES ({}) ON CONFLICT (uid) DO NOTHING",
        columns.join(", "),
        places.join(", ")
    );
    let mut query = sqlx::query(built(sql)).bind(id);
    if let Some(resumes) = resumes {
        query = query.bind(resumes);
    }
    for (_, value) in &run.values {
        query = bind(query, value);
    }
    Ok(query.execute(&mut **tx).await?.rows_affected() == 1)
}

/// Gives run `id` the ending `run` holds, if its record is still running; whether it did.
async fn end(
    tx: &mut sqlx::Transaction<'_, sqlx::Any>,
    id: RunId,
    run: &Spooled,
) -> sqlx::Result<bool> {
    let ending: Vec<&(&str, Value)> = run
        .values
        .iter()
        .filter(|(c, _)| COLUMNS.iter().any(|(name, _, ends)| name == c && *ends))
        .collect();
    let sets: Vec<String> = ending
        .iter()
        .enumerate()
        .map(|(n, (c, _))| format!("{c} = ${}", n + 2))
        .collect();
    let sql = format!(
        "UPDATE runs SET {} WHERE id = $1 AND outcome = 'running'",
        sets.join(", ")
    );
    let mut query = sqlx::query(built(sql)).bind(id);
    for (_, value) in ending {
        query = bind(query, value);
    }
    Ok(query.execute(&mut **tx).await?.rows_affected() == 1)
}

fn bind<'q>(
    query: sqlx::query::Query<'q, sqlx::Any, sqlx::any::AnyArguments>,
    value: &Value,
) -> sqlx::query::Query<'q, sqlx::Any, sqlx::any::AnyArguments> {
    match value {
        Value::Int(n) => query.bind(*n),
        Value::Real(x) => query.bind(*x),
        Value::Text(text) => query.bind(text.clone()),
    }
}

/// Removes an uploaded run from the spool, and the links of the runs that resume it (an
/// upload of those, tried after this one, finds what they resume in the database).
async fn remove(pool: &AnyPool, id: RunId) -> Result<(), Failure> {
    let mut tx = pool.begin().await?;
    sqlx::query("UPDATE runs SET resumes = NULL WHERE resumes = $1")
        .bind(id)
        .execute(&mut *tx)
        .await?;
    sqlx::query("DELETE FROM run_notes WHERE run_id = $1")
        .bind(id)
        .execute(&mut *tx)
        .await?;
    sqlx::query("DELETE FROM runs WHERE id = $1")
        .bind(id)
        .execute(&mut *tx)
        .await?;
    tx.commit().await?;
    Ok(())
}

/// A SQL text this module builds from its own column names (never from a value).
fn built(sql: String) -> sqlx::AssertSqlSafe<String> {
    sqlx::AssertSqlSafe(sql)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_spool_is_named_by_its_databases_host_port_and_name() {
        assert_eq!(
            file_name("postgres://whirl:pw@db.shop.lan:5433/shop"),
            "spool-db.shop.lan-5433-shop.sqlite"
        );
        // No password, no user in the name: the same database whoever writes it.
        assert_eq!(
            file_name("postgres://other@db.shop.lan:5433/shop"),
            file_name("postgres://whirl:pw@db.shop.lan:5433/shop")
        );
        let odd = file_name("postgres://whirl@[::1]:5432/shop/../x");
        assert!(
            odd.starts_with("spool-") && !odd[6..].contains(['/', ':']),
            "{odd}"
        );
    }

    #[test]
    fn an_upload_carries_every_column_of_a_run_but_its_number_and_link() {
        let dir = tempfile::tempdir().unwrap();
        let spool = Spool::new(dir.path().join("spool.sqlite"));
        let columns: Vec<String> = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap()
            .block_on(async {
                sqlx::any::install_default_drivers();
                let database = spool.database().await.unwrap();
                sqlx::query("SELECT name FROM pragma_table_info('runs') ORDER BY cid")
                    .fetch_all(database.pool())
                    .await
                    .unwrap()
                    .iter()
                    .map(|row| row.try_get::<String, _>("name").unwrap())
                    .collect()
            });
        let carried: Vec<&str> = COLUMNS.iter().map(|(c, _, _)| *c).collect();
        let mut expected: Vec<&str> = columns
            .iter()
            .map(String::as_str)
            .filter(|c| !matches!(*c, "id" | "resumes"))
            .collect();
        expected.sort_unstable();
        let mut sorted = carried.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, expected);
    }
}
