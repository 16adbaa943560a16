//! Thread forms named only by their designation, as a drawing names them, planned and
//! measured within Δ: a DIN 513 buttress screw, whose 3° load flank runs nearly radial, an
//! ASME B1.1 unified screw, and a DIN 3975-1 ZK worm, whose flank is its wheel's envelope.

use whirl::config::job::Job;
use whirl::config::machine::MachineProfile;
use whirl::judge::measure::Motion;
use whirl::judge::verify;
use whirl::post::gcode::parse::read_program;

/// A job cutting `designation` over `length` mm with the trapezoidal example's ring, its
/// inserts' nose `nose` mm, the workpiece turning at `rpm` (a steep flank moves X fast).
fn job(designation: &str, length: f64, rpm: f64, nose: f64) -> Job {
    let text = format!(
        "[groove]\nz_start = 0.0\nlength = {length}\n\n\
         [groove.profile]\ndesignation = \"{designation}\"\n\n\
         [tool]\nwhirling = \"internal\"\nring_radius = 32.0\nnose_radius = {nose}\ninserts = 4\n\n\
         [cut]\ndelta = 0.01\naxial_feed = 0.05\nworkpiece_rpm = {rpm}\nring_rpm = 3000.0\n"
    );
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("job.toml");
    std::fs::write(&path, text).unwrap();
    Job::load(&path).unwrap()
}

/// Plans `job` for the simulator and measures the program as a controller reads it.
fn measured_within_delta(job: &Job) {
    let machine = MachineProfile::builtin_sim().unwrap();
    let plan = whirl::plan::plan(job, &machine).unwrap();
    let program = read_program(&plan.text, machine.x_diameter()).unwrap();
    let target = verify::target(job, plan.ring).unwrap();
    let m = target.measure(&Motion::new(&program).unwrap()).unwrap();
    let delta = job.cut.delta;
    assert!(
        m.max_overcut_mm <= delta && m.max_undercut_mm <= delta,
        "{m:?}"
    );
}

#[test]
fn a_buttress_screw_by_its_designation_is_cut_within_delta() {
    // S 48x8: lead 8 mm, one start, from the designation.
    let job = job("S 48x8", 16.0, 3.0, 0.4);
    assert_eq!((job.groove.lead, job.groove.starts), (8.0, 1));
    measured_within_delta(&job);
}

#[test]
fn a_unified_screw_by_its_designation_is_cut_within_delta() {
    // 1-8 UNC-2A: 1 in, 8 threads per inch, a lead of 3.175 mm.
    let job = job("1-8 UNC-2A", 12.0, 12.0, 0.4);
    assert!((job.groove.lead - 3.175).abs() < 1e-12);
    measured_within_delta(&job);
}

#[test]
fn a_zk_worm_by_its_designation_is_cut_within_delta() {
    // ZK m2 z1 q10 D250: lead π·m·z1 = 2π mm, one start. Its 0.4 mm root fillets (0.2·m)
    // want a smaller nose than 0.4 mm.
    let job = job("ZK m2 z1 q10 D250", 12.0, 10.0, 0.35);
    assert!((job.groove.lead - 2.0 * std::f64::consts::PI).abs() < 1e-12);
    assert_eq!(job.groove.starts, 1);
    measured_within_delta(&job);
}
