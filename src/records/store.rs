//! The run records a run uses: the database named (SQLite, one file, no server, created on
//! first use; or PostgreSQL, a shop's server, given as a `postgres://` URL), and for
//! PostgreSQL the spool ([`super::spool`]), a SQLite file of the host's that keeps what the
//! server cannot take. Records never delay or stop a cut: a run whose PostgreSQL cannot be
//! reached when it begins, or that goes away mid-run, is kept in the spool, and the next
//! opening of the records that reaches the server uploads it, once.
//!
//! Many bridges write to one PostgreSQL at once: run numbers come from a counter row each
//! takes in turn ([`super::database`]), and every run has a key of its own ([`Uid`]) that
//! an upload is keyed by.

use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::str::FromStr;
use std::sync::Arc;
use std::time::Duration;

use sqlx::migrate::MigrateError;
use sqlx::sqlite::SqliteConnectOptions;

use super::database::{Database, ID_TRIES};
pub use super::database::{POSTGRES_TIMEOUT, SQLITE_BUSY_TIMEOUT};
use super::process::Process;
use super::spool::{self, Spool, Uploaded};
use super::time::Timestamp;
use super::uid::Uid;
use super::{Ending, Filter, NewRun, Note, Outcome, Run, RunId, RunSummary};

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
    /// A PostgreSQL database.
    Postgres {
        /// Its URL.
        url: String,
        /// The SQLite file that keeps runs while the database cannot be reached; `None`:
        /// none, and a run whose database cannot be reached is not recorded.
        spool: Option<PathBuf>,
    },
}

/// The environment variable that names the database when `--db` does not.
pub const ENV: &str = "WHIRL_DB";

impl Place {
    /// A database as the user names it: a `postgres://` (or `postgresql://`) URL, a
    /// `sqlite:` URL (`sqlite://runs.sqlite?mode=ro`), or a plain path to a SQLite file.
    /// A SQLite file is created if missing, unless the URL gives its `mode`. A PostgreSQL
    /// database has no spool until [`Place::with_spool_in`] gives it one.
    pub fn parse(text: &str) -> Result<Place, RecordError> {
        if text.starts_with("postgres://") || text.starts_with("postgresql://") {
            return Ok(Place::Postgres {
                url: text.to_owned(),
                spool: None,
            });
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
    /// variable, else [`Place::default_in`] the user's data folder. A PostgreSQL database
    /// is given its spool in the user's data folder, if there is one.
    pub fn resolve(given: Option<&str>) -> Result<Place, RecordError> {
        let (xdg, home) = (std::env::var_os("XDG_DATA_HOME"), std::env::var_os("HOME"));
        let place = match given {
            Some(given) => Place::parse(given)?,
            None => match std::env::var_os(ENV) {
                Some(value) if !value.is_empty() => Place::parse(&value.to_string_lossy())?,
                _ => return Place::default_in(xdg.as_deref(), home.as_deref()),
            },
        };
        Ok(match data_folder(xdg.as_deref(), home.as_deref()) {
            Ok(data) => place.with_spool_in(&data),
            Err(_) => place,
        })
    }

    /// The default: `runs.sqlite` in the user's data folder, `$XDG_DATA_HOME/whirl/` (an
    /// absolute one) or `$HOME/.local/share/whirl/`. One index of every run the user
    /// makes, whichever folder its job and its log are in; a plan has no log to sit beside.
    pub fn default_in(
        xdg_data_home: Option<&OsStr>,
        home: Option<&OsStr>,
    ) -> Result<Place, RecordError> {
        let data = data_folder(xdg_data_home, home)?;
        Ok(Place::sqlite_file(&data.join("whirl").join("runs.sqlite")))
    }

    /// The same place; a PostgreSQL database with its spool in `whirl/` of the data
    /// folder `data`, beside the default SQLite file: one spool a database
    /// ([`spool::file_name`]), so that a run is uploaded only to the database it was
    /// meant for.
    pub fn with_spool_in(self, data: &Path) -> Place {
        match self {
            Place::Postgres { url, .. } => Place::Postgres {
                spool: Some(data.join("whirl").join(spool::file_name(&url))),
                url,
            },
            sqlite => sqlite,
        }
    }

    /// The spool of a PostgreSQL database, if it has one.
    pub fn spool(&self) -> Option<&Path> {
        match self {
            Place::Postgres { spool, .. } => spool.as_deref(),
            Place::Sqlite { .. } => None,
        }
    }

    /// The SQLite file the records are kept in; `None` for PostgreSQL, which is no file of
    /// the host's. A command checks it against its own files before anything is written
    /// (it may be none of them).
    pub fn file(&self) -> Option<&Path> {
        match self {
            Place::Sqlite { options, .. } => Some(options.get_filename()),
            Place::Postgres { .. } => None,
        }
    }

    /// How the place is named in messages: the SQLite file, or the PostgreSQL URL without
    /// its password.
    pub fn name(&self) -> String {
        match self {
            Place::Sqlite { options, .. } => options.get_filename().display().to_string(),
            Place::Postgres { url, .. } => without_password(url),
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

/// The user's data folder: `$XDG_DATA_HOME` (an absolute one; a relative one is to be
/// ignored, by the XDG base directory rules), else `$HOME/.local/share`.
fn data_folder(
    xdg_data_home: Option<&OsStr>,
    home: Option<&OsStr>,
) -> Result<PathBuf, RecordError> {
    match (xdg_data_home.map(Path::new), home.map(Path::new)) {
        (Some(xdg), _) if xdg.is_absolute() => Ok(xdg.to_owned()),
        (_, Some(home)) if home.is_absolute() => Ok(home.join(".local/share")),
        _ => Err(RecordError::Place(format!(
            "no home folder (HOME) to keep the run records in: name a database with --db or \
             {ENV}"
        ))),
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
    /// Other writers took every number tried for a run's new note (PostgreSQL; SQLite
    /// writes one at a time).
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
    /// A PostgreSQL server did not answer in time ([`POSTGRES_TIMEOUT`]).
    #[error(
        "the run records at {place}: cannot {what}: no answer within {} s (the server down, or \
         not answering)",
        .after.as_secs()
    )]
    TimedOut {
        /// The database.
        place: String,
        /// What the store was doing.
        what: &'static str,
        /// How long it waited.
        after: Duration,
    },
    /// The shop's database could not be reached, nor the spool that keeps runs meanwhile
    /// be opened.
    #[error("{why}; nor can the spool {} keep the run meanwhile: {error}", .spool.display())]
    NoSpool {
        /// Why the database could not be reached.
        why: Box<RecordError>,
        /// The spool.
        spool: PathBuf,
        /// Why the spool could not be opened.
        error: Box<RecordError>,
    },
    /// The operating system gave no random bits for a run's key.
    #[error("cannot make a key for the run's record: {0}")]
    Key(getrandom::Error),
}

impl RecordError {
    /// Whether the database could not be reached (down, or not answering), as opposed to
    /// refusing what it was asked: a run whose records cannot be reached is kept in the
    /// spool.
    fn unreachable(&self) -> bool {
        matches!(
            self,
            RecordError::Open { .. } | RecordError::TimedOut { .. }
        )
    }
}

/// Where a write to a run's record went.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Kept {
    /// Into the database named.
    Database,
    /// Into the spool `file`, since the database named could not take it (`why`); the
    /// next opening of the records that reaches the database uploads it.
    Spool {
        /// The spool.
        file: PathBuf,
        /// Why the database could not take it.
        why: String,
    },
}

/// A run's record, as the process that runs it holds it from [`Store::begin`] to
/// [`Store::finish`]. Cheap to clone.
#[derive(Debug, Clone, PartialEq)]
pub struct Recorded {
    /// Its number where it was opened: the database's, or the spool's (an upload gives it
    /// the database's next).
    pub id: RunId,
    /// Its key in every database.
    pub uid: Uid,
    /// Where it was opened.
    pub kept: Kept,
    /// The run as it began, to continue its record in the spool if the database goes away
    /// mid-run.
    pub(super) begun: Arc<Begun>,
}

/// What a run's record began with.
#[derive(Debug, PartialEq)]
pub(super) struct Begun {
    pub(super) run: NewRun,
    pub(super) started: String,
}

/// How a record's closing went.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Finished {
    /// `false` if the record was not running (closed already, by its process or as
    /// interrupted).
    pub closed: bool,
    /// Where the ending went.
    pub kept: Kept,
}

/// A write to a run's record, in whichever database it goes to.
enum Write<'a> {
    /// A note, with its key.
    Note(&'a Uid, &'a Note),
    /// The ending, at its time.
    Close(&'a Ending, &'a str),
}

impl Write<'_> {
    async fn to(&self, database: &Database, id: RunId, uid: &Uid) -> Result<bool, RecordError> {
        match self {
            Write::Note(key, note) => database.note(id, key, note).await.map(|()| true),
            Write::Close(ending, ended) => database.close(id, Some(uid), ending, ended).await,
        }
    }
}

/// The run records, opened.
#[derive(Debug, Clone)]
pub struct Store {
    /// The database named.
    database: Database,
    /// A PostgreSQL database's spool.
    spool: Option<Spool>,
    /// Why the database could not be reached when the records were opened: the runs begun
    /// through this opening go to the spool straight away, rather than wait on it again.
    down: Option<String>,
    /// What the opening's upload of the spool did, if it found runs to upload.
    uploaded: Option<Arc<Result<Uploaded, RecordError>>>,
}

impl Store {
    /// Opens the records at `place`, creating a SQLite file (and its folder) on first use,
    /// and brings the schema up to date. A PostgreSQL database that cannot be reached is
    /// no error where it has a spool: the runs begun meanwhile are kept there. One that
    /// can be reached is sent what its spool keeps ([`Store::uploaded`] says how that
    /// went; it never fails the opening).
    pub async fn open(place: &Place) -> Result<Store, RecordError> {
        sqlx::any::install_default_drivers();
        let (url, spool) = match place {
            Place::Sqlite { options, create } => {
                return Ok(Store {
                    database: Database::sqlite(options, *create, place.name()).await?,
                    spool: None,
                    down: None,
                    uploaded: None,
                })
            }
            Place::Postgres { url, spool } => (url, spool.clone().map(Spool::new)),
        };
        let database = Database::postgres(url, place.name())?;
        let down = match (database.ready().await, &spool) {
            (Ok(()), _) => None,
            (Err(error), Some(spool)) if error.unreachable() => {
                if let Err(spool_error) = spool.database().await {
                    return Err(RecordError::NoSpool {
                        why: Box::new(error),
                        spool: spool.file().to_owned(),
                        error: Box::new(spool_error),
                    });
                }
                Some(error.to_string())
            }
            (Err(error), _) => return Err(error),
        };
        let mut store = Store {
            database,
            spool,
            down,
            uploaded: None,
        };
        if store.down.is_none() && store.spool.as_ref().is_some_and(Spool::exists) {
            store.uploaded = Some(Arc::new(store.upload().await));
        }
        Ok(store)
    }

    /// The database, as messages name it.
    pub fn place(&self) -> &str {
        self.database.place()
    }

    /// The spool, for a PostgreSQL database that has one.
    pub fn spool(&self) -> Option<&Path> {
        self.spool.as_ref().map(Spool::file)
    }

    /// Why the database could not be reached when the records were opened, if it could
    /// not (the runs begun through this opening are kept in the spool).
    pub fn down(&self) -> Option<&str> {
        self.down.as_deref()
    }

    /// What the opening's upload of the spool did: `None` if there was nothing to upload
    /// or the database could not be reached.
    pub fn uploaded(&self) -> Option<&Result<Uploaded, RecordError>> {
        self.uploaded.as_deref()
    }

    /// Opens a record, `running`, for a run about to start; a run that resumes an earlier
    /// one ([`NewRun::resume_from`]) is linked to it. In the spool if the database cannot
    /// take it and there is a spool ([`Recorded::kept`] says which).
    pub async fn begin(&self, run: &NewRun) -> Result<Recorded, RecordError> {
        let uid = Uid::random().map_err(RecordError::Key)?;
        let started = Timestamp::now().to_text();
        let begun = Arc::new(Begun {
            run: run.clone(),
            started,
        });
        let (spool, why) = match (&self.down, &self.spool) {
            (Some(why), Some(spool)) => (spool, why.clone()),
            (_, spool) => match (self.database.begin(run, &uid, &begun.started).await, spool) {
                (Ok(id), _) => {
                    return Ok(Recorded {
                        id,
                        uid,
                        kept: Kept::Database,
                        begun,
                    })
                }
                (Err(error), Some(spool)) => (spool, error.to_string()),
                (Err(error), None) => return Err(error),
            },
        };
        let id = spool.begin(run, &uid, &begun.started).await?;
        Ok(Recorded {
            id,
            uid,
            kept: spool.kept(why),
            begun,
        })
    }

    /// Adds a note to a run as it goes (an alarm, a hold, a resume). Returns where it went.
    pub async fn note(&self, run: &Recorded, note: &Note) -> Result<Kept, RecordError> {
        let key = Uid::random().map_err(RecordError::Key)?;
        self.write(run, Write::Note(&key, note))
            .await
            .map(|(_, kept)| kept)
    }

    /// Closes a running record with how its run ended.
    pub async fn finish(&self, run: &Recorded, ending: &Ending) -> Result<Finished, RecordError> {
        let ended = Timestamp::now().to_text();
        let (closed, kept) = self.write(run, Write::Close(ending, &ended)).await?;
        Ok(Finished { closed, kept })
    }

    /// Writes to `run`'s record where it is: a run opened in the spool stays there until
    /// uploaded; one opened in the database goes on there, unless part of it went to the
    /// spool already (what follows goes after it) or the database cannot take this write,
    /// which then goes to the spool, after a copy of the run's beginning.
    async fn write(&self, run: &Recorded, write: Write<'_>) -> Result<(bool, Kept), RecordError> {
        if let Kept::Spool { file, .. } = &run.kept {
            let spool = match &self.spool {
                Some(spool) if spool.file() == file => spool.clone(),
                _ => Spool::new(file.clone()),
            };
            let written = write.to(spool.database().await?, run.id, &run.uid).await?;
            return Ok((written, run.kept.clone()));
        }
        let Some(spool) = &self.spool else {
            let written = write.to(&self.database, run.id, &run.uid).await?;
            return Ok((written, Kept::Database));
        };
        // A spool that cannot be read (said when the records were opened) holds no part of
        // this run for this write to go after.
        if let Some(id) = spool.find(&run.uid).await.ok().flatten() {
            let written = write.to(spool.database().await?, id, &run.uid).await?;
            let why = format!(
                "an earlier write of run {} went to the spool, and what follows it goes there too",
                run.id
            );
            return Ok((written, spool.kept(why)));
        }
        let why = match write.to(&self.database, run.id, &run.uid).await {
            Ok(written) => return Ok((written, Kept::Database)),
            Err(error) => error.to_string(),
        };
        let id = spool.continuation(run).await?;
        let written = write.to(spool.database().await?, id, &run.uid).await?;
        Ok((written, spool.kept(why)))
    }

    /// Closes the records of this host whose process is gone without closing them, each
    /// from what its log says: the outcome its log's end gives, or `interrupted` if the
    /// log has none, with the resume point, the last line known done and the alarms. The
    /// logs are only read; other hosts' records are left to them. Returns the runs closed,
    /// and the outcome each was given. Nothing, if the database could not be reached when
    /// opened (the next opening that reaches it closes them).
    pub async fn close_orphans(
        &self,
        here: &Process,
    ) -> Result<Vec<(RunId, Outcome)>, RecordError> {
        if self.down.is_some() {
            return Ok(Vec::new());
        }
        self.database.close_orphans(here).await
    }

    /// Uploads what the spool keeps to the database: each run its process is done with
    /// (closed, or closed here first from its log if its process is gone), with its notes,
    /// keyed by its key, then removed from the spool. An upload cut short and tried again
    /// adds nothing twice. Nothing to do for a database without a spool.
    pub async fn upload(&self) -> Result<Uploaded, RecordError> {
        match &self.spool {
            Some(spool) => spool.upload(&self.database, &Process::current()).await,
            None => Ok(Uploaded::default()),
        }
    }

    /// The runs `filter` lets through, newest first, from every machine and host that
    /// records into the database.
    pub async fn list(&self, filter: &Filter) -> Result<Vec<RunSummary>, RecordError> {
        self.database.list(filter).await
    }

    /// The whole record of run `id`, with its notes; `None` if there is none.
    pub async fn show(&self, id: RunId) -> Result<Option<Run>, RecordError> {
        self.database.show(id).await
    }

    /// Closes the connections.
    pub async fn close_connections(self) {
        if let Some(spool) = self.spool {
            spool.close_connections().await;
        }
        self.database.close_connections().await;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::records::block_on;
    use crate::records::Kind;

    #[test]
    fn a_database_is_named_by_a_url_or_a_path() {
        assert!(matches!(
            Place::parse("postgres://whirl@127.0.0.1:5432/shop").unwrap(),
            Place::Postgres { spool: None, .. }
        ));
        assert!(matches!(
            Place::parse("postgresql://127.0.0.1/shop").unwrap(),
            Place::Postgres { .. }
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
                            let run = store.begin(&NewRun::new(Kind::Plan)).await.unwrap();
                            store
                                .finish(&run, &Ending::new(Outcome::Completed))
                                .await
                                .unwrap();
                            ids.push(run.id);
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
    fn a_postgresql_database_has_its_own_spool_beside_the_default_file() {
        let url = "postgres://whirl:s3cret@db.shop.lan:5433/shop";
        let place = Place::parse(url).unwrap();
        assert_eq!(place.spool(), None, "none until a data folder is given");
        let place = place.with_spool_in(Path::new("/data"));
        assert_eq!(
            place.spool().unwrap(),
            Path::new("/data/whirl/spool-db.shop.lan-5433-shop.sqlite")
        );
        let other = Place::parse("postgres://whirl@db.shop.lan:5433/tools")
            .unwrap()
            .with_spool_in(Path::new("/data"));
        assert_ne!(other.spool(), place.spool(), "one spool a database");
        let sqlite = Place::parse("runs.sqlite")
            .unwrap()
            .with_spool_in(Path::new("/data"));
        assert_eq!(sqlite.spool(), None, "a SQLite file needs none");
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
}
