//! Helpers shared by the integration tests: paths, the CLI runner, temp dirs.

use std::path::{Path, PathBuf};
use std::process::Output;

/// The repository root.
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// An example job file.
pub fn example(name: &str) -> PathBuf {
    root().join("examples").join(name).join("job.toml")
}

/// Every example job.
pub fn examples() -> Vec<PathBuf> {
    let mut jobs: Vec<PathBuf> = std::fs::read_dir(root().join("examples"))
        .expect("examples/")
        .filter_map(|e| e.ok())
        .map(|e| e.path().join("job.toml"))
        .filter(|p| p.exists())
        .collect();
    jobs.sort();
    jobs
}

/// Run the `whirl` binary with `args`.
pub fn whirl(args: &[&std::ffi::OsStr]) -> Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_whirl"))
        .args(args)
        .output()
        .expect("the whirl binary runs")
}

/// Write `text` to `dir/name` and return the path.
pub fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).expect("write a test file");
    path
}

/// A program line without its N word (grblHAL programs number every line).
pub fn block(line: &str) -> &str {
    match line.strip_prefix('N') {
        Some(rest) => {
            let digits = rest.len() - rest.trim_start_matches(|c: char| c.is_ascii_digit()).len();
            rest[digits..].trim_start()
        }
        None => line,
    }
}
