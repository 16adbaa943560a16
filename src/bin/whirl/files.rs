//! A command's files: what it may write, checked before anything is computed, and writing it
//! whole.
//!
//! An output is written to a new temporary file beside it and renamed into place, so a
//! reader never sees half of it. A rename replaces whatever the name pointed to: a device
//! node, a symbolic link (not the file it leads to), or one of the run's own inputs. So
//! [`Files::check`] refuses, naming the path and why, an output that is
//!
//! - anything but a regular file or nothing: a directory, a device, a named pipe, a socket,
//!   a symbolic link;
//! - in a folder that does not exist (or is no folder), or a name the file system cannot
//!   hold;
//! - a file the same run reads or appends to: the job, its profile points, the program, the
//!   machine profile, a log;
//! - the same file as another output of the run.
//!
//! The run records' SQLite file ([`Files::database`]) is written in place, not renamed, but
//! it may be none of those files either, nor anything but a regular file: SQLite would
//! write its pages over the job, the log or the report, or into a device.
//!
//! [`write_all`] then writes them all or none: each is staged in a temporary sibling, then
//! they are renamed into place one after the other, and if one rename fails the ones before
//! it are put back as they were. No temporary file outlives the call, whichever way it ends
//! (a kill mid-write aside: the temporary file is then left hidden beside its output).

use anyhow::{Context, Result};
use std::ffi::{OsStr, OsString};
use std::fs;
use std::io::Write;
use std::os::unix::ffi::OsStrExt;
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};
use whirl::log::special_kind;

/// The files of one command: the outputs it replaces and the files it reads (or appends
/// to), each with the words that name it in a refusal.
#[derive(Default)]
pub(crate) struct Files {
    /// Option (`--report`) and path of each output.
    outputs: Vec<(&'static str, PathBuf)>,
    /// The files it reads or appends to.
    inputs: Vec<Input>,
    /// The run records' SQLite file, and what names it (`--db`, `WHIRL_DB`, the default).
    database: Option<(&'static str, PathBuf)>,
}

/// A file a command reads, or a log it appends to.
struct Input {
    /// What it is, for a refusal: "the job file".
    what: &'static str,
    path: PathBuf,
    /// A log the run appends to, rather than a file it reads.
    appended: bool,
}

impl Input {
    /// "reads" or "appends to".
    fn verb(&self) -> &'static str {
        if self.appended {
            "appends to"
        } else {
            "reads"
        }
    }
}

impl Files {
    /// A command's files, none named yet.
    pub(crate) fn new() -> Files {
        Files::default()
    }

    /// An output the command replaces, given with `option`; `None`: not asked for.
    pub(crate) fn output(mut self, option: &'static str, path: Option<&Path>) -> Files {
        if let Some(path) = path {
            self.outputs.push((option, path.to_owned()));
        }
        self
    }

    /// A file the command reads, `what` saying which ("the program"); `None`: not given.
    pub(crate) fn input(self, what: &'static str, path: Option<&Path>) -> Files {
        self.add(what, path, false)
    }

    /// A log the command appends to, `what` saying which ("the log (--log)"); `None`: none.
    /// It may be no input of the run either.
    pub(crate) fn log(self, what: &'static str, path: Option<&Path>) -> Files {
        self.add(what, path, true)
    }

    /// Adds `path`, if given, to the files the command reads or appends to.
    fn add(mut self, what: &'static str, path: Option<&Path>, appended: bool) -> Files {
        if let Some(path) = path {
            self.inputs.push(Input {
                what,
                path: path.to_owned(),
                appended,
            });
        }
        self
    }

    /// The SQLite file the run is recorded in, and what names it (`--db`); `None`: none
    /// (not recorded, or not in a file).
    pub(crate) fn database(mut self, database: Option<(&'static str, PathBuf)>) -> Files {
        self.database = database;
        self
    }

    /// A job file and the profile points file it names (if it names one and can be read:
    /// a job that cannot is refused by its loading, with the reason).
    pub(crate) fn job(self, path: &Path) -> Files {
        let points = points_file(path);
        self.input("the job file", Some(path))
            .input("the job's profile points", points.as_deref())
    }

    /// Refuses an output that is not a regular file (or nothing yet), lies in no folder, is
    /// one of the inputs, or is named twice; a log that is one of the inputs; and a records
    /// database that is not a regular file (or nothing yet) or is one of the run's files.
    pub(crate) fn check(&self) -> Result<()> {
        self.check_outputs()?;
        self.check_database()
    }

    fn check_outputs(&self) -> Result<()> {
        for (i, (option, path)) in self.outputs.iter().enumerate() {
            let refuse = |why: String| {
                anyhow::anyhow!("refusing to write {} ({option}): {why}", path.display())
            };
            if let Err(why) = writable(path) {
                return Err(refuse(why));
            }
            for (other, earlier) in &self.outputs[..i] {
                if same_file(path, earlier) {
                    return Err(refuse(format!("{other} names the same file")));
                }
            }
            for input in &self.inputs {
                if same_file(path, &input.path) {
                    return Err(refuse(format!(
                        "it is {} this run {}",
                        input.what,
                        input.verb()
                    )));
                }
            }
        }
        // A log grows by every event: it may be none of the files the run reads, and it is
        // a regular file (a device or a pipe keeps nothing, and may never end when read).
        for log in self.inputs.iter().filter(|i| i.appended) {
            if let Ok(meta) = fs::metadata(&log.path) {
                if !meta.is_file() {
                    anyhow::bail!(
                        "refusing to append to {} ({}): it is {}, not a regular file; a log \
                         keeps every run's events in a file: name one",
                        log.path.display(),
                        log.what,
                        special_kind(&meta.file_type())
                    );
                }
            }
            for input in &self.inputs {
                if !std::ptr::eq(log, input) && same_file(&log.path, &input.path) {
                    anyhow::bail!(
                        "refusing to append to {} ({}): it is {} this run {}",
                        log.path.display(),
                        log.what,
                        input.what,
                        input.verb()
                    );
                }
            }
        }
        Ok(())
    }

    /// The records database: a regular file or nothing yet (SQLite makes it), and none of
    /// the files the run reads, appends to or writes.
    fn check_database(&self) -> Result<()> {
        let Some((what, path)) = &self.database else {
            return Ok(());
        };
        let refuse = |why: String| {
            anyhow::anyhow!(
                "refusing to keep the run records in {} ({what}): {why}; name another \
                 database with --db",
                path.display()
            )
        };
        // Links followed: SQLite writes through a link to the file it leads to.
        match fs::metadata(path) {
            Ok(meta) if meta.is_dir() => return Err(refuse("it is a directory".into())),
            Ok(meta) if !meta.is_file() => {
                let it = special_kind(&meta.file_type());
                return Err(refuse(format!("it is {it}, not a database file")));
            }
            _ => {}
        }
        for (option, output) in &self.outputs {
            if same_file(path, output) {
                return Err(refuse(format!("it is the output {option} of this run")));
            }
        }
        for input in &self.inputs {
            if same_file(path, &input.path) {
                return Err(refuse(format!(
                    "it is {} this run {}",
                    input.what,
                    input.verb()
                )));
            }
        }
        Ok(())
    }
}

/// The points file a job file names, relative to the job's folder as the job's loading
/// reads it; `None` if the job names none or cannot be read as TOML.
pub(crate) fn points_file(job: &Path) -> Option<PathBuf> {
    // Only a regular file is read twice: a pipe (`whirl plan <(…)`) read here would be
    // empty for the job's loading.
    if !fs::metadata(job).ok()?.is_file() {
        return None;
    }
    let text = fs::read_to_string(job).ok()?;
    let points = whirl::config::provenance::points_named(&text)?;
    Some(job.parent().unwrap_or(Path::new("")).join(points))
}

/// Whether `path` can take an output: nothing there yet, or a regular file, in a folder
/// that exists. `Err` says why not.
fn writable(path: &Path) -> Result<(), String> {
    if path.as_os_str().as_bytes().ends_with(b"/") || path.file_name().is_none() {
        return Err("it names a directory, not a file".into());
    }
    let error = match fs::symlink_metadata(path) {
        Ok(meta) => return kind_refusal(path, &meta.file_type()).map_or(Ok(()), Err),
        Err(error) => error,
    };
    let folder = folder(path);
    match fs::metadata(folder) {
        Ok(meta) if !meta.is_dir() => Err(format!(
            "its folder {} is not a directory",
            folder.display()
        )),
        Ok(_) if error.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Ok(_) => Err(format!("cannot look at it: {error}")),
        Err(_) => Err(format!("its folder {} does not exist", folder.display())),
    }
}

/// Why a file of type `kind` at `path` may not be replaced by an output; `None` for a
/// regular file.
fn kind_refusal(path: &Path, kind: &fs::FileType) -> Option<String> {
    let what = if kind.is_file() {
        return None;
    } else if kind.is_dir() {
        return Some("it is a directory".into());
    } else if kind.is_symlink() {
        let target = fs::read_link(path).map_or_else(|_| "?".into(), |t| t.display().to_string());
        return Some(format!(
            "it is a symbolic link (to {target}): the output would replace the link, not \
             the file it leads to; name that file itself"
        ));
    } else {
        special_kind(kind)
    };
    Some(format!(
        "it is {what}, and an output is a regular file renamed into place, which would \
         replace it"
    ))
}

/// The folder `path` is in ("." for a bare name).
fn folder(path: &Path) -> &Path {
    match path.parent() {
        Some(parent) if !parent.as_os_str().is_empty() => parent,
        _ => Path::new("."),
    }
}

/// Where `path` leads: the file with every link followed if it exists, else its folder's
/// real path joined with its name.
fn real(path: &Path) -> Option<PathBuf> {
    if let Ok(real) = fs::canonicalize(path) {
        return Some(real);
    }
    Some(fs::canonicalize(folder(path)).ok()?.join(path.file_name()?))
}

/// Whether `a` and `b` are one file: one real path, or (both existing) one inode.
fn same_file(a: &Path, b: &Path) -> bool {
    if let (Ok(a), Ok(b)) = (fs::metadata(a), fs::metadata(b)) {
        if (a.dev(), a.ino()) == (b.dev(), b.ino()) {
            return true;
        }
    }
    matches!((real(a), real(b)), (Some(a), Some(b)) if a == b)
}

/// One output on its way: its text in a temporary sibling, and, once it has been renamed
/// into place, the old file kept to put back.
struct Staged {
    /// The output.
    path: PathBuf,
    /// The temporary file holding its text; `None` once renamed into place.
    tmp: Option<PathBuf>,
    /// The file the output replaced, kept aside (a hard link or a copy) while later
    /// outputs are renamed, to put back if one fails; `None` if there was none.
    old: Option<PathBuf>,
}

/// Outputs staged or renamed into place; dropped, it removes every temporary file left,
/// whatever way the write ends.
#[derive(Default)]
struct Batch(Vec<Staged>);

impl Drop for Batch {
    fn drop(&mut self) {
        for staged in &self.0 {
            for tmp in staged.tmp.iter().chain(&staged.old) {
                let _ = fs::remove_file(tmp);
            }
        }
    }
}

/// A name for a temporary sibling of `path` that nothing has: `.NAME.whirl-PID-N.SUFFIX`,
/// created empty (never over an existing file) and returned open. NAME is cut to its first
/// 128 bytes, so that an output with a long name still has room for its sibling's.
fn sibling(path: &Path, suffix: &str) -> Result<(PathBuf, fs::File)> {
    let name = path.file_name().map_or(&b"output"[..], OsStr::as_bytes);
    let name = OsStr::from_bytes(&name[..name.len().min(128)]);
    let mut last = None;
    for n in 0..100 {
        let mut tmp = OsString::from(".");
        tmp.push(name);
        tmp.push(format!(".whirl-{}-{n}.{suffix}", std::process::id()));
        let tmp = folder(path).join(tmp);
        match fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&tmp)
        {
            Ok(file) => return Ok((tmp, file)),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => last = Some(e),
            Err(e) => return Err(e.into()),
        }
    }
    Err(last.map_or_else(|| anyhow::anyhow!("no free name"), Into::into))
}

/// Write each file with its text (a `None` path is skipped): all of them or none. Each is
/// staged in a temporary sibling (with the permissions of the file it replaces); then they
/// are renamed into place, and if a rename fails the files already renamed are put back as
/// they were. An output that is not a regular file (or nothing yet) is refused before
/// anything is written.
pub(crate) fn write_all(files: &[(Option<&Path>, &String)]) -> Result<()> {
    let files: Vec<(&Path, &String)> = files
        .iter()
        .filter_map(|(path, text)| path.map(|p| (p, *text)))
        .collect();
    for (path, _) in &files {
        if let Ok(meta) = fs::symlink_metadata(path) {
            if let Some(why) = kind_refusal(path, &meta.file_type()) {
                anyhow::bail!("refusing to write {}: {why}", path.display());
            }
        }
    }
    let mut batch = Batch::default();
    for (path, text) in &files {
        stage(&mut batch, path, text)
            .with_context(|| format!("cannot write {}", path.display()))?;
    }
    commit(&mut batch)
}

/// Writes `text` to a temporary sibling of `path`, added to `batch`.
fn stage(batch: &mut Batch, path: &Path, text: &str) -> Result<()> {
    let (tmp, mut file) = sibling(path, "tmp")?;
    batch.0.push(Staged {
        path: path.to_owned(),
        tmp: Some(tmp),
        old: None,
    });
    file.write_all(text.as_bytes())?;
    if let Ok(meta) = fs::metadata(path) {
        file.set_permissions(meta.permissions())?;
    }
    file.sync_all()?;
    Ok(())
}

/// Renames every staged file of `batch` into place, keeping each replaced file aside until
/// the last is in, and putting them back if a rename fails.
fn commit(batch: &mut Batch) -> Result<()> {
    let last = batch.0.len().saturating_sub(1);
    for i in 0..batch.0.len() {
        let result = (|| -> Result<()> {
            let staged = &mut batch.0[i];
            // The last rename failing leaves its own file as it was: only earlier ones
            // need theirs kept.
            if i < last && fs::symlink_metadata(&staged.path).is_ok() {
                let (old, _) = sibling(&staged.path, "old")?;
                staged.old = Some(old.clone());
                if fs::remove_file(&old)
                    .and_then(|()| fs::hard_link(&staged.path, &old))
                    .is_err()
                {
                    fs::copy(&staged.path, &old)?;
                }
            }
            let tmp = staged.tmp.as_ref().expect("staged, not yet renamed");
            fs::rename(tmp, &staged.path)?;
            staged.tmp = None;
            Ok(())
        })();
        if let Err(e) = result {
            let path = batch.0[i].path.clone();
            put_back(&mut batch.0[..i]);
            return Err(e.context(format!("cannot write {}", path.display())));
        }
    }
    Ok(())
}

/// Puts back what the outputs of `renamed` replaced: the old file, or nothing.
fn put_back(renamed: &mut [Staged]) {
    for staged in renamed.iter_mut().rev() {
        let restored = match staged.old.take() {
            Some(old) => fs::rename(&old, &staged.path),
            None => fs::remove_file(&staged.path),
        };
        if let Err(e) = restored {
            tracing::error!(path = %staged.path.display(), %e, "cannot put the old file back");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn listing(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn a_failed_second_rename_puts_the_first_file_back() {
        let dir = tempfile::tempdir().unwrap();
        let (program, report) = (dir.path().join("p.nc"), dir.path().join("r.json"));
        fs::write(&program, "old program").unwrap();
        let mut batch = Batch::default();
        stage(&mut batch, &program, "new program").unwrap();
        stage(&mut batch, &report, "new report").unwrap();
        // Something takes the report's name between the checks and the renames.
        fs::create_dir(&report).unwrap();
        fs::write(report.join("inside"), "").unwrap();
        let error = commit(&mut batch).unwrap_err();
        drop(batch);
        assert!(format!("{error:#}").contains("r.json"), "{error:#}");
        assert_eq!(fs::read_to_string(&program).unwrap(), "old program");
        assert_eq!(
            listing(dir.path()),
            ["p.nc", "r.json"],
            "no temporary file left"
        );
    }

    #[test]
    fn a_first_output_that_was_new_is_removed_again() {
        let dir = tempfile::tempdir().unwrap();
        let (program, report) = (dir.path().join("p.nc"), dir.path().join("r.json"));
        let mut batch = Batch::default();
        stage(&mut batch, &program, "new program").unwrap();
        stage(&mut batch, &report, "new report").unwrap();
        fs::create_dir(&report).unwrap();
        fs::write(report.join("inside"), "").unwrap();
        assert!(commit(&mut batch).is_err());
        drop(batch);
        assert_eq!(listing(dir.path()), ["r.json"]);
    }

    #[test]
    fn an_output_that_became_a_socket_after_the_checks_is_refused_unwritten() {
        let dir = tempfile::tempdir().unwrap();
        let (program, report) = (dir.path().join("p.nc"), dir.path().join("r.json"));
        fs::write(&program, "old program").unwrap();
        // Something takes the report's name between the checks and the write.
        let _socket = std::os::unix::net::UnixListener::bind(&report).unwrap();
        let text = String::from("text");
        let error = write_all(&[(Some(&program), &text), (Some(&report), &text)]).unwrap_err();
        assert!(format!("{error:#}").contains("it is a socket"), "{error:#}");
        assert_eq!(fs::read_to_string(&program).unwrap(), "old program");
        assert_eq!(listing(dir.path()), ["p.nc", "r.json"]);
    }

    #[test]
    fn both_outputs_are_replaced_with_the_permissions_they_had() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let (program, report) = (dir.path().join("p.nc"), dir.path().join("r.json"));
        fs::write(&program, "old").unwrap();
        fs::set_permissions(&program, fs::Permissions::from_mode(0o600)).unwrap();
        let (p, r) = (String::from("program"), String::from("report"));
        write_all(&[(Some(&program), &p), (Some(&report), &r)]).unwrap();
        assert_eq!(fs::read_to_string(&program).unwrap(), "program");
        assert_eq!(fs::read_to_string(&report).unwrap(), "report");
        let mode = fs::metadata(&program).unwrap().permissions().mode();
        assert_eq!(mode & 0o777, 0o600);
        assert_eq!(listing(dir.path()), ["p.nc", "r.json"]);
    }
}
