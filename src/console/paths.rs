//! The job files the console may read: only under its `--jobs` folder.
//!
//! A job is named by its path relative to the folder, as the page lists it. Anything that
//! could lead elsewhere is refused before a file is opened: an absolute path, a `..` or
//! `.` component, a name that is not a `.toml` file, and a symbolic link (of the file or
//! of a folder on the way) that resolves outside the folder.

use std::path::{Component, Path, PathBuf};

/// The console's jobs folder.
#[derive(Debug, Clone)]
pub struct JobDir {
    /// Canonical: symbolic links resolved, so containment is a prefix test.
    root: PathBuf,
}

/// Why a job path was refused.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PathError {
    /// Nothing given.
    #[error("no job given")]
    Empty,
    /// An absolute path.
    #[error("job \"{0}\" is an absolute path: name it relative to the jobs folder")]
    Absolute(String),
    /// A `..` or `.` component.
    #[error("job \"{0}\" steps out of the jobs folder (a \"..\" or \".\" in the path)")]
    Traversal(String),
    /// Not a job file.
    #[error("job \"{0}\" is not a job file (.toml)")]
    NotToml(String),
    /// A symbolic link out of the folder.
    #[error("job \"{0}\" leads out of the jobs folder (a link to {1})")]
    Outside(String, String),
    /// No such file, or the folder cannot be read.
    #[error("job \"{0}\": {1}")]
    Missing(String, String),
}

impl JobDir {
    /// The folder `dir`, which must exist.
    pub fn open(dir: &Path) -> Result<JobDir, std::io::Error> {
        let root = dir.canonicalize()?;
        if !root.is_dir() {
            return Err(std::io::Error::other(format!(
                "{} is not a folder",
                dir.display()
            )));
        }
        Ok(JobDir { root })
    }

    /// The file the job `name` (relative to the folder) is, if it is one the console may
    /// read.
    pub fn resolve(&self, name: &str) -> Result<PathBuf, PathError> {
        if name.is_empty() {
            return Err(PathError::Empty);
        }
        let path = Path::new(name);
        for component in path.components() {
            match component {
                Component::Normal(_) => {}
                Component::RootDir | Component::Prefix(_) => {
                    return Err(PathError::Absolute(name.to_owned()))
                }
                Component::ParentDir | Component::CurDir => {
                    return Err(PathError::Traversal(name.to_owned()))
                }
            }
        }
        if path.extension().is_none_or(|e| e != "toml") {
            return Err(PathError::NotToml(name.to_owned()));
        }
        let real = self
            .root
            .join(path)
            .canonicalize()
            .map_err(|e| PathError::Missing(name.to_owned(), e.to_string()))?;
        if !real.starts_with(&self.root) {
            return Err(PathError::Outside(
                name.to_owned(),
                real.display().to_string(),
            ));
        }
        Ok(real)
    }

    /// The job files in the folder and its subfolders, as [`JobDir::resolve`] takes them,
    /// sorted; those that resolve outside the folder are left out.
    pub fn list(&self) -> Vec<String> {
        let mut found = Vec::new();
        self.walk(Path::new(""), 0, &mut found);
        found.sort();
        found
    }

    /// Collects the `.toml` files under `relative`, at most a few folders deep (a link
    /// loop inside the folder ends there).
    fn walk(&self, relative: &Path, depth: usize, found: &mut Vec<String>) {
        const DEPTH: usize = 8;
        let Ok(entries) = std::fs::read_dir(self.root.join(relative)) else {
            return;
        };
        for entry in entries.flatten() {
            let relative = relative.join(entry.file_name());
            let Some(name) = relative.to_str() else {
                continue;
            };
            let full = self.root.join(&relative);
            if full.is_dir() {
                if depth < DEPTH && full.canonicalize().is_ok_and(|r| r.starts_with(&self.root)) {
                    self.walk(&relative, depth + 1, found);
                }
            } else if self.resolve(name).is_ok() {
                found.push(name.to_owned());
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn folder() -> (tempfile::TempDir, JobDir) {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir_all(dir.path().join("jobs/screw")).unwrap();
        std::fs::write(dir.path().join("jobs/screw/job.toml"), "").unwrap();
        std::fs::write(dir.path().join("jobs/notes.txt"), "").unwrap();
        std::fs::write(dir.path().join("secret.toml"), "").unwrap();
        let jobs = JobDir::open(&dir.path().join("jobs")).unwrap();
        (dir, jobs)
    }

    #[test]
    fn jobs_inside_the_folder_resolve_and_list() {
        let (dir, jobs) = folder();
        let path = jobs.resolve("screw/job.toml").unwrap();
        assert_eq!(
            path,
            dir.path()
                .join("jobs/screw/job.toml")
                .canonicalize()
                .unwrap()
        );
        assert_eq!(jobs.list(), vec!["screw/job.toml".to_owned()]);
    }

    #[test]
    fn paths_out_of_the_folder_are_refused() {
        let (dir, jobs) = folder();
        assert_eq!(
            jobs.resolve("../secret.toml"),
            Err(PathError::Traversal("../secret.toml".into()))
        );
        assert_eq!(
            jobs.resolve("screw/../../secret.toml"),
            Err(PathError::Traversal("screw/../../secret.toml".into()))
        );
        assert_eq!(
            jobs.resolve("./screw/job.toml"),
            Err(PathError::Traversal("./screw/job.toml".into()))
        );
        let absolute = dir.path().join("secret.toml").display().to_string();
        assert_eq!(
            jobs.resolve(&absolute),
            Err(PathError::Absolute(absolute.clone()))
        );
        assert_eq!(jobs.resolve(""), Err(PathError::Empty));
        assert_eq!(
            jobs.resolve("notes.txt"),
            Err(PathError::NotToml("notes.txt".into()))
        );
        assert!(matches!(
            jobs.resolve("missing.toml"),
            Err(PathError::Missing(..))
        ));
    }

    #[test]
    fn a_link_out_of_the_folder_is_refused_and_not_listed() {
        let (dir, jobs) = folder();
        std::os::unix::fs::symlink(
            dir.path().join("secret.toml"),
            dir.path().join("jobs/link.toml"),
        )
        .unwrap();
        std::os::unix::fs::symlink(dir.path(), dir.path().join("jobs/up")).unwrap();
        assert!(matches!(
            jobs.resolve("link.toml"),
            Err(PathError::Outside(..))
        ));
        assert!(matches!(
            jobs.resolve("up/secret.toml"),
            Err(PathError::Outside(..))
        ));
        assert_eq!(jobs.list(), vec!["screw/job.toml".to_owned()]);
    }
}
