//! The example jobs on the machines that are not reached by G-code: a PLC through the
//! Modbus register map and CiA 402 drives on CAN.

use whirl::config::connection::Connection;
use whirl::config::job::Job;
use whirl::config::machine::{Axis, MachineProfile};
use whirl::program::limits::check_limits;
use whirl::program::{Move, Position};

use crate::util;

/// Every example job plans on the two machines that are not reached by G-code, and
/// what is planned fits their links: the register map's segments (whose 0.1 µm and
/// 10⁻⁴° are no coarser than the decimals the planner counted), and the drives' 32-bit
/// linear counts.
#[test]
fn the_examples_plan_on_the_modbus_and_can_machines() {
    let root = util::root();
    let jobs = util::examples();
    // The folder was read: the first example is among what was found.
    assert!(
        jobs.iter()
            .any(|p| p.ends_with("examples/trapezoidal/job.toml")),
        "{jobs:?}"
    );
    let plc = MachineProfile::load(&root.join("machine-profiles/modbus-plc.toml")).unwrap();
    let can = MachineProfile::load(&root.join("machine-profiles/canopen-drives.toml")).unwrap();
    let drives = can
        .connection
        .as_ref()
        .and_then(Connection::drives)
        .unwrap();
    for path in &jobs {
        let job = Job::load(path).unwrap();
        for machine in [&plc, &can] {
            let plan = whirl::plan::plan(&job, machine)
                .unwrap_or_else(|e| panic!("{} on {}: {e}", path.display(), machine.name));
            let [linear, angular] = plan.report.decimals;
            assert!(linear <= 4 && angular <= 4, "{path:?}: {linear}, {angular}");
            check_limits(&plan.program, machine).unwrap();
            // Modbus: every block fits a segment, and the shortest linked move is within
            // a controller that takes 44 segments a second (the profile's comment).
            let segments = whirl::post::modbus::segments(&plan.program)
                .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            whirl::post::modbus::check_rate(&segments, 44)
                .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            // CAN: X and Z stay in INTEGER32 counts, and every linked move spans at
            // least four cycles.
            for step in plan.program.steps(Position::UNKNOWN) {
                for (slot, axis) in [Axis::X, Axis::Z].into_iter().enumerate() {
                    if let Some(value) = step.to.get(axis) {
                        let counts = value * drives.counts_per_mm[slot];
                        assert!(counts.abs() < f64::from(i32::MAX), "{counts}");
                    }
                }
                if let Move::Linked { minutes, .. } = *step.action {
                    assert!(minutes * 60.0 >= 4.0 * drives.period().as_secs_f64());
                }
            }
        }
    }
}
