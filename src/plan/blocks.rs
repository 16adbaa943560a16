//! The machine's block time: a controller whose block rate bounds every move (a Modbus PLC
//! taking one segment a scan, LinuxCNC's trajectory planner, CANopen drives taking one
//! set-point a cycle; [`MachineProfile::block_rate`]) runs a linked move shorter than one
//! block slower than planned, so `plan` refuses such a program rather than write it.
//!
//! grbl and grblHAL prepare their blocks ahead, and a short move there only eats into the lead
//! the buffer keeps: that rate is sustained, not per move, and the fastest feed holds the
//! program to it (`crate::plan::feed::sustained`).

use crate::config::machine::MachineProfile;
use crate::post::gcode::parse::read_program_with_lines;
use crate::program::{Move, Program};

/// A linked move shorter than the block every move must last.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error(
    "linked move {index} of the planned path{} lasts {:.2} ms, less than one block of the \
     controller's {per_second} blocks a second ({origin}), which every move must last: it would \
     run slower than planned. Every move lasts a block at cut.workpiece_rpm = {rpm:.3} or below \
     (moves last longer in proportion as the work turns slower), or give the controller's own \
     rate as max_block_rate in the machine profile",
    line.map_or(String::new(), |l| format!(" (line {l} of the program)")),
    seconds * 1e3
)]
pub struct TooShort {
    /// The move's index in the planned path, as the machine limits name moves.
    pub index: usize,
    /// Its line in the program text, where it reads back.
    pub line: Option<usize>,
    /// How long it lasts, s.
    pub seconds: f64,
    /// The block rate, blocks a second.
    pub per_second: f64,
    /// Where the rate comes from.
    pub origin: String,
    /// The workpiece speed at which the move would last one block, rpm.
    pub rpm: f64,
}

/// Refuses the shortest linked move of `program` (written as `text`) if it lasts less than a
/// block on `machine`, where the block rate bounds every move; `rpm` is the job's workpiece
/// speed.
///
/// The durations checked are the planned ones: what the Modbus segments and CANopen
/// set-points carry, and no longer than what LinuxCNC's inverse-time words, rounded down, ask
/// for.
pub fn check(
    program: &Program,
    text: &str,
    machine: &MachineProfile,
    rpm: f64,
) -> Result<(), TooShort> {
    let rate = machine.block_rate();
    if rate.ahead.is_some() {
        return Ok(());
    }
    let block = 1.0 / rate.per_second;
    let shortest = program
        .moves
        .iter()
        .enumerate()
        .filter_map(|(index, m)| match *m {
            Move::Linked { minutes, .. } => Some((index, minutes * 60.0)),
            _ => None,
        })
        .min_by(|a, b| a.1.total_cmp(&b.1));
    let Some((index, seconds)) = shortest.filter(|&(_, seconds)| seconds < block) else {
        return Ok(());
    };
    // The move's line: the posted program has the planned one's linked moves, in order.
    let nth = program.moves[..index]
        .iter()
        .filter(|m| matches!(m, Move::Linked { .. }))
        .count();
    let line = read_program_with_lines(text, machine.x_diameter())
        .ok()
        .and_then(|(posted, lines)| {
            posted
                .moves
                .iter()
                .zip(lines)
                .filter(|(m, _)| matches!(m, Move::Linked { .. }))
                .nth(nth)
                .map(|(_, line)| line)
        });
    Err(TooShort {
        index,
        line,
        seconds,
        per_second: rate.per_second,
        origin: rate.source,
        rpm: rpm * seconds / block,
    })
}

#[cfg(test)]
mod tests {
    use crate::config::job::Job;
    use crate::config::machine::MachineProfile;
    use crate::plan::{plan, PlanError};
    use crate::program::Move;
    use std::path::Path;

    fn load(path: &str) -> (Job, MachineProfile) {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let job = Job::load(&root.join("examples/left-external/job.toml")).unwrap();
        let machine = MachineProfile::load(&root.join(path)).unwrap();
        (job, machine)
    }

    /// The shortest linked move of a plan and its index, s.
    fn shortest(program: &crate::program::Program) -> (usize, f64) {
        program
            .moves
            .iter()
            .enumerate()
            .filter_map(|(i, m)| match *m {
                Move::Linked { minutes, .. } => Some((i, minutes * 60.0)),
                _ => None,
            })
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap()
    }

    #[test]
    fn a_move_shorter_than_a_block_is_refused_naming_the_move_and_the_rate() {
        // The PLC takes one segment a block: given a rate a little too slow for the program's
        // shortest move, the plan is refused, naming that move, its line (a linked move of that
        // duration, in inverse time) and the rate; a little faster, it plans.
        let (job, mut plc) = load("machine-profiles/modbus-plc.toml");
        let planned = plan(&job, &plc).unwrap();
        let (index, seconds) = shortest(&planned.program);
        plc.max_block_rate = Some(0.999 / seconds);
        let Err(PlanError::BlockTime(e)) = plan(&job, &plc) else {
            panic!("a move shorter than a block plans");
        };
        assert_eq!((e.index, e.seconds), (index, seconds));
        assert_eq!(e.per_second, 0.999 / seconds);
        let line = planned.text.lines().nth(e.line.unwrap() - 1).unwrap();
        let f: f64 = line.split(" F").nth(1).unwrap().parse().unwrap();
        // (F written to 2 decimals: 0.005 in some 2000.)
        assert!((60.0 / f - seconds).abs() < 1e-5 * seconds, "{line}");
        let text = e.to_string();
        assert!(
            text.contains(&format!("linked move {index} of the planned path (line "))
                && text.contains("blocks a second (the machine profile's max_block_rate)")
                && text.contains("cut.workpiece_rpm"),
            "{text}"
        );
        // The speed named lengthens that move to one block: the job's, in the ratio.
        assert!(
            (e.rpm - job.cut.workpiece_rpm * 0.999).abs() < 1e-9,
            "{}",
            e.rpm
        );
        plc.max_block_rate = Some(1.001 / seconds);
        plan(&job, &plc).unwrap();
    }

    #[test]
    fn grbl_takes_a_short_move_from_the_blocks_it_prepares_ahead() {
        // The same rate on grblHAL bounds the moves only over the step segments it holds
        // ready: the planner writes the program, and the fastest feed holds it to the rate.
        let (job, mut grbl) = load("machine-profiles/grblhal-lathe.toml");
        let planned = plan(&job, &grbl).unwrap();
        let (_, seconds) = shortest(&planned.program);
        grbl.max_block_rate = Some(0.999 / seconds);
        plan(&job, &grbl).unwrap();
    }
}
