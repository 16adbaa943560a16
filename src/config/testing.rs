//! The unit tests' way to the repository's own files: the example jobs and the machine
//! profiles, loaded as a user's clone has them.

use std::path::{Path, PathBuf};

use crate::config::job::Job;
use crate::config::machine::MachineProfile;

/// `examples/NAME/job.toml`, loaded.
pub fn example(name: &str) -> Job {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("examples")
        .join(name)
        .join("job.toml");
    Job::load(&path).expect("the example loads")
}

/// `machine-profiles/NAME.toml`'s path.
pub fn machine_path(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("machine-profiles")
        .join(format!("{name}.toml"))
}

/// `machine-profiles/NAME.toml`'s text.
pub fn machine_text(name: &str) -> String {
    std::fs::read_to_string(machine_path(name)).expect("the machine profile reads")
}

/// `machine-profiles/NAME.toml`, loaded.
pub fn machine(name: &str) -> MachineProfile {
    MachineProfile::load(&machine_path(name)).expect("the machine profile loads")
}
