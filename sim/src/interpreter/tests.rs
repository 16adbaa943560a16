//! Tests of the G-code interpreter, kept apart from it for length: grbl's error numbers,
//! number parsing, modes, targets, feed kinds, syncs and program end.

use super::*;

const F64: Dialect = Dialect {
    numbers: Numbers(NumberType::F64),
    sync_on_offset_change: true,
    lathe: true,
    c_rotary: true,
};

fn run(lines: &[&str]) -> Result<(ParserState, Vec<Block>), GrblError> {
    let mut state = ParserState::new([0.0; 3], [0.0; 3]);
    let mut blocks = Vec::new();
    for line in lines {
        blocks.push(interpret(line, &mut state, F64)?);
    }
    Ok((state, blocks))
}

fn err(lines: &[&str]) -> u8 {
    run(lines).expect_err("line must be refused").code()
}

fn motion(block: &Block) -> MotionRequest {
    block
        .steps
        .iter()
        .find_map(|s| match s {
            Step::Motion(m) => Some(*m),
            _ => None,
        })
        .expect("a motion step")
}

#[test]
fn every_error_path_has_its_number() {
    assert_eq!(err(&["G0 #1"]), 1);
    assert_eq!(err(&["G0 X"]), 2);
    assert_eq!(err(&["G0 X-"]), 2);
    assert_eq!(err(&["G0 X."]), 2);
    assert_eq!(err(&["G1 X1 F-5"]), 4);
    assert_eq!(err(&["N-1 G0 X1"]), 4);
    assert_eq!(err(&["G2 X1"]), 20);
    assert_eq!(err(&["G0 Y1"]), 20);
    assert_eq!(err(&["T1"]), 20);
    assert_eq!(err(&["M6"]), 20);
    assert_eq!(err(&["G92.2"]), 20);
    assert_eq!(err(&["G90.1"]), 20);
    assert_eq!(err(&["G61.1"]), 20);
    assert_eq!(err(&["G90 G91"]), 21);
    assert_eq!(err(&["M3 M5"]), 21);
    assert_eq!(err(&["G1.5 X2"]), 23);
    assert_eq!(err(&["M3.1"]), 23);
    // grbl checks the axis-word claim before the group: G0 G1 is 24, like G92 G1.
    assert_eq!(err(&["G0 G1 X1"]), 24);
    assert_eq!(err(&["G92 G1 X1 F1"]), 24);
    assert_eq!(err(&["G1 X1 X2 F1"]), 25);
    assert_eq!(err(&["G92"]), 26);
    assert_eq!(err(&["N10000001 G0 X1"]), 27);
    assert_eq!(err(&["G4"]), 28);
    assert_eq!(err(&["G80 X1"]), 31);
    // 320 digits: 1e320 is not a finite f64.
    assert_eq!(err(&[&format!("G0 X{}", "9".repeat(320))]), 33);
    assert_eq!(err(&["G0 P1"]), 36);
    assert_eq!(err(&["G1 X1"]), 22);
    assert_eq!(err(&["G93 G1 X1"]), 22);
    assert_eq!(err(&["G93 G1 X1 F0"]), 22);
    // Leaving G93 forgets the feed.
    assert_eq!(err(&["G1 X1 F100", "G93 G1 X2 F5", "G94 G1 X3"]), 22);
}

#[test]
fn numbers_as_grbl_reads_them() {
    let (state, _) = run(&["g0 x1.5 z-.5 c+2"]).unwrap();
    assert_eq!(state.position, [1.5, -0.5, 2.0]);
    // Nine significant digits are kept, later ones dropped (magnitude kept); leading
    // zeros are not significant (grblHAL's nuts_bolts.c).
    let (state, _) = run(&["G0 X1.2345678912 Z1234567891 C0.000123456789"]).unwrap();
    assert!((state.position[0] - 1.23456789).abs() < 1e-15);
    assert_eq!(state.position[1], 1234567890.0);
    assert!((state.position[2] - 0.000123456789).abs() < 1e-18);
    // Comments, block delete and `;` are not words.
    let (state, _) = run(&["/G0 (move) X3 ; Z9"]).unwrap();
    assert_eq!(state.position, [3.0, 0.0, 0.0]);
    assert_eq!(line_number("n120 g1 x3"), Some(120));
    assert_eq!(line_number("G1 X3"), None);
}

#[test]
fn modes_and_targets() {
    // Axis words alone use the modal motion, G0 at power-up (grbl), incremental
    // moves add, G92 renames, G92.1 clears, G20 converts X and Z but not C.
    let (state, blocks) = run(&[
        "X10 Z5 C90",
        "G91 X1 C10",
        "G90 G92 C0",
        "C30",
        "G92.1",
        "G20 G0 X1 C1",
        "G21 G7 X20",
    ])
    .unwrap();
    assert_eq!(motion(&blocks[0]).target, [10.0, 5.0, 90.0]);
    assert_eq!(motion(&blocks[1]).target, [11.0, 5.0, 100.0]);
    assert_eq!(state.g92, [0.0, 0.0, 0.0]);
    assert_eq!(motion(&blocks[3]).target, [11.0, 5.0, 130.0]);
    assert_eq!(motion(&blocks[5]).target, [25.4, 5.0, 1.0]);
    assert_eq!(motion(&blocks[6]).target[0], 10.0);
    assert!(state.diameter);
}

#[test]
fn feed_kinds() {
    let (_, blocks) = run(&["G1 X1 F100", "X2", "G93 G1 X3 F4", "G20 G94 G1 X0 F10"]).unwrap();
    assert_eq!(
        motion(&blocks[1]).kind,
        MotionKind::Feed { per_minute: 100.0 }
    );
    assert_eq!(
        motion(&blocks[2]).kind,
        MotionKind::InverseTime {
            inverse_minutes: 4.0
        }
    );
    assert_eq!(
        motion(&blocks[3]).kind,
        MotionKind::Feed { per_minute: 254.0 }
    );
}

#[test]
fn syncs_and_program_end() {
    let (state, blocks) = run(&[
        "M3 S1000",
        "S1000",
        "S2000",
        "G4 P0.5",
        "G92 C0",
        "G1 X1 F1 M2",
    ])
    .unwrap();
    assert!(matches!(
        blocks[0].steps[..],
        [Step::Sync(SyncAction::Spindle(Spindle { on: true, .. }))]
    ));
    assert!(blocks[1].steps.is_empty());
    assert_eq!(blocks[2].steps.len(), 1);
    assert_eq!(blocks[3].steps, [Step::Dwell(0.5)]);
    assert_eq!(blocks[4].steps, [Step::Sync(SyncAction::Wait)]);
    assert!(matches!(
        blocks[5].steps[..],
        [Step::Motion(_), Step::Sync(SyncAction::ProgramEnd)]
    ));
    assert!(!state.spindle.on);
    assert_eq!(state.motion, MotionMode::Linear);
    // A refused line changes nothing.
    let mut state = ParserState::new([0.0; 3], [0.0; 3]);
    assert!(interpret("G91 G1 X1", &mut state, F64).is_err());
    assert!(!state.incremental);
}

#[test]
fn f32_targets_keep_their_magnitude() {
    // C at 180 000° renamed to 0: the machine target of C10 is still 180 010 in f32,
    // whose spacing there is 1/64°.
    let dialect = Dialect {
        numbers: Numbers(NumberType::F32),
        ..F64
    };
    let mut state = ParserState::new([0.0, 0.0, 180_000.0], [0.0; 3]);
    interpret("G92 C0", &mut state, dialect).unwrap();
    let block = interpret("G0 C10.003", &mut state, dialect).unwrap();
    let c = motion(&block).target[2];
    assert_eq!(c, f64::from(180_010.003_f32));
    assert!((c - 180_010.003).abs() > 1e-3);
}
