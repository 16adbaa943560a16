//! What the benches share: the repository's example jobs.

use std::path::Path;
use whirl::config::job::Job;

/// `examples/NAME/job.toml`, loaded.
pub fn example(name: &str) -> Job {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("examples")
        .join(name)
        .join("job.toml");
    Job::load(&path).expect("the example loads")
}
