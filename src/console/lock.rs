//! One run per machine, across processes: a lock file per machine or port, held with an
//! advisory `flock` for as long as a run drives it.
//!
//! `whirl stream` and the console take the same lock before they open anything, so a
//! second run is refused with the name of whoever holds it (its process id and command
//! line, written into the file), whichever program the first one was. The operating system
//! releases the lock when the holding process ends, however it ends: a bridge that crashed
//! leaves no stale lock behind, only a file naming a holder that is gone, which the next
//! run overwrites.

use rustix::fs::{flock, FlockOperation};
use std::fs::{File, OpenOptions};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

/// The environment variable that names the folder of the lock files; without it, a
/// `whirl-locks` folder in the system's temporary folder, which every process of one host
/// sees.
pub const LOCK_DIR_VAR: &str = "WHIRL_LOCK_DIR";

/// The folder the lock files are in (see [`LOCK_DIR_VAR`]).
pub fn lock_dir() -> PathBuf {
    std::env::var_os(LOCK_DIR_VAR)
        .map(PathBuf::from)
        .unwrap_or_else(|| std::env::temp_dir().join("whirl-locks"))
}

/// This process, as a lock names its holder: its id and command line, the access token
/// left out (the lock file is readable by every user of the host, and the console shows
/// its holder on its page).
pub fn this_process() -> String {
    let command = without_secrets(std::env::args());
    format!("process {} ({})", std::process::id(), command.join(" "))
}

/// A command line with the value of `--token` replaced by `***`.
fn without_secrets(args: impl IntoIterator<Item = String>) -> Vec<String> {
    let mut hide = false;
    args.into_iter()
        .map(|arg| {
            let hidden = if hide {
                "***".to_owned()
            } else if arg.starts_with("--token=") {
                "--token=***".to_owned()
            } else {
                arg.clone()
            };
            hide = arg == "--token";
            hidden
        })
        .collect()
}

/// Who holds a lock, as its file names them, and since when.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct Holder {
    /// The holder as it wrote itself into the lock file.
    pub holder: String,
    /// When it took the lock (the file's last change), UTC.
    pub since: Option<String>,
}

/// Who holds the lock on `what` in `dir` now, if anyone: looked at with a shared lock
/// tried and let go at once (a held lock refuses it), so a lock a `whirl stream` of
/// another terminal holds is seen as well as this console's own. A run starting in that
/// instant is refused as busy, which errs on the safe side.
pub fn holder(dir: &Path, what: &str) -> Option<Holder> {
    let path = dir.join(file_name(what));
    let mut file = File::open(&path).ok()?;
    match flock(&file, FlockOperation::NonBlockingLockShared) {
        Ok(()) => {
            // Free: let go at once.
            let _ = flock(&file, FlockOperation::Unlock);
            None
        }
        Err(_) => {
            let mut holder = String::new();
            let _ = file.read_to_string(&mut holder);
            let since = file
                .metadata()
                .and_then(|m| m.modified())
                .ok()
                .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
                .and_then(|d| i64::try_from(d.as_millis()).ok())
                .map(|ms| crate::records::Timestamp(ms).to_text());
            Some(Holder {
                holder: match holder.trim() {
                    "" => "another process (not yet named in the lock file)".to_owned(),
                    named => named.to_owned(),
                },
                since,
            })
        }
    }
}

/// A held lock; dropping it (or the process ending) releases it.
#[derive(Debug)]
pub struct MachineLock {
    /// Holds the `flock`: closing the file releases it.
    _file: File,
}

/// Why a lock was not taken.
#[derive(Debug, thiserror::Error)]
pub enum LockError {
    /// Someone else runs it.
    #[error("{what} is busy: {holder} runs it (lock file {})", path.display())]
    Held {
        /// The machine or port.
        what: String,
        /// Who holds the lock, as it wrote itself into the file.
        holder: String,
        /// The lock file.
        path: PathBuf,
    },
    /// The lock file cannot be made or written.
    #[error("cannot lock {what}: lock file {}: {error}", path.display())]
    Io {
        /// The machine or port.
        what: String,
        /// The lock file.
        path: PathBuf,
        /// Why.
        error: std::io::Error,
    },
}

impl MachineLock {
    /// Takes the lock on `what` (a machine or port, in words: see [`crate::console::link_key`])
    /// in `dir`, writing `holder` into the file; refused, naming the holder, if another
    /// open lock holds it (another process, or another run of this one).
    pub fn acquire(dir: &Path, what: &str, holder: &str) -> Result<MachineLock, LockError> {
        let path = dir.join(file_name(what));
        let io = |error| LockError::Io {
            what: what.to_owned(),
            path: path.clone(),
            error,
        };
        std::fs::create_dir_all(dir).map_err(io)?;
        let mut file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&path)
            .map_err(io)?;
        match flock(&file, FlockOperation::NonBlockingLockExclusive) {
            Ok(()) => {}
            Err(rustix::io::Errno::WOULDBLOCK) => {
                let mut holder = String::new();
                // Best effort: the holder may not have written itself in yet.
                let _ = file.read_to_string(&mut holder);
                let holder = holder.trim();
                return Err(LockError::Held {
                    what: what.to_owned(),
                    holder: if holder.is_empty() {
                        "another process (not yet named in the lock file)".to_owned()
                    } else {
                        holder.to_owned()
                    },
                    path,
                });
            }
            Err(error) => return Err(io(error.into())),
        }
        file.set_len(0).map_err(io)?;
        file.write_all(format!("{holder}\n").as_bytes())
            .and_then(|()| file.flush())
            .map_err(io)?;
        Ok(MachineLock { _file: file })
    }
}

/// The lock file's name for `what`: its letters and digits kept, anything else (a path's
/// slashes) an underscore. Two names that differ only there share a lock, which errs on
/// the side of refusing.
fn file_name(what: &str) -> String {
    let name: String = what
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '.' {
                c
            } else {
                '_'
            }
        })
        .collect();
    format!("{name}.lock")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_second_lock_is_refused_naming_the_holder_until_the_first_is_dropped() {
        let dir = tempfile::tempdir().unwrap();
        let what = "serial port /dev/ttyUSB0";
        let first = MachineLock::acquire(dir.path(), what, "process 1 (whirl serve)").unwrap();
        let error = MachineLock::acquire(dir.path(), what, "process 2").unwrap_err();
        let text = error.to_string();
        assert!(text.contains("serial port /dev/ttyUSB0 is busy"), "{text}");
        assert!(text.contains("process 1 (whirl serve)"), "{text}");
        // Another machine is free.
        let other = MachineLock::acquire(dir.path(), "serial port /dev/ttyUSB1", "p").unwrap();
        drop(first);
        let again = MachineLock::acquire(dir.path(), what, "process 3").unwrap();
        // The file names the new holder only.
        let written = std::fs::read_to_string(dir.path().join(file_name(what))).unwrap();
        assert_eq!(written, "process 3\n");
        drop((again, other));
    }

    #[test]
    fn a_lock_folder_that_cannot_be_made_is_an_error_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let blocker = dir.path().join("file");
        std::fs::write(&blocker, "").unwrap();
        let error = MachineLock::acquire(&blocker, "machine m", "p").unwrap_err();
        assert!(matches!(error, LockError::Io { .. }), "{error}");
        assert!(
            error.to_string().contains("cannot lock machine m"),
            "{error}"
        );
    }

    #[test]
    fn the_holder_of_a_lock_is_seen_until_it_is_dropped_and_the_token_never() {
        let dir = tempfile::tempdir().unwrap();
        let what = "machine lathe";
        assert_eq!(holder(dir.path(), what), None);
        let lock = MachineLock::acquire(dir.path(), what, "process 7 (whirl stream)").unwrap();
        let held = holder(dir.path(), what).expect("held");
        assert_eq!(held.holder, "process 7 (whirl stream)");
        assert!(held.since.unwrap().ends_with('Z'));
        // Looking did not take it: the holder still holds it, and a second is refused.
        assert!(MachineLock::acquire(dir.path(), what, "p").is_err());
        drop(lock);
        assert_eq!(holder(dir.path(), what), None);
        let args = [
            "whirl",
            "serve",
            "--token",
            "s3cret-s3cret-s3cret",
            "--token=abc",
            "-x",
        ];
        assert_eq!(
            without_secrets(args.map(str::to_owned)),
            ["whirl", "serve", "--token", "***", "--token=***", "-x"]
        );
    }

    #[test]
    fn file_names_keep_no_path_separators() {
        assert_eq!(
            file_name("serial port /dev/tty0"),
            "serial_port__dev_tty0.lock"
        );
        assert_eq!(file_name("../x"), ".._x.lock");
    }
}
