//! `whirl verify`'s engine on the 100 mm ball-screw groove: every start, the whole formed
//! length, 64 profile positions per period.

use divan::{black_box, Bencher};
use std::path::Path;
use whirl::config::job::Job;
use whirl::config::machine::MachineProfile;

fn main() {
    divan::main();
}

/// Plan the example, then measure the program text the machine would get.
#[divan::bench(sample_count = 3)]
fn verify_100mm_ball_screw(bencher: Bencher) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/ball-screw/job.toml");
    let job = Job::load(&path).unwrap();
    let machine = MachineProfile::builtin_sim().unwrap();
    let plan = whirl::plan::plan(&job, &machine).unwrap();
    bencher.bench(|| {
        let v = whirl::judge::verify::verify(&job, plan.ring, &machine, &plan.text, false).unwrap();
        black_box(v.max_undercut_mm)
    });
}
