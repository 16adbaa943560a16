//! The re-entry rule on a program shaped as whirl's posts write them: lead-in, linked moves,
//! lead-out.

use super::*;

/// Lead-in (clear X 0, C, Z, spindle, plunge to X 18 at 50 mm/min), three linked moves along
/// a helix of lead 10 mm (Z = 10·C/360), lead-out.
fn program() -> Program {
    let linked = |x: f64, c: f64| Move::Linked {
        x,
        z: 10.0 * c / 360.0,
        c,
        minutes: 0.01,
    };
    Program {
        moves: vec![
            Move::Comment("whirl".into()),
            Move::Rapid {
                x: Some(0.0),
                z: None,
                c: None,
            },
            Move::Rapid {
                x: None,
                z: None,
                c: Some(0.0),
            },
            Move::Rapid {
                x: None,
                z: Some(0.0),
                c: None,
            },
            Move::SpindleOn { rpm: 2500.0 },
            Move::Feed {
                x: Some(18.0),
                z: None,
                c: None,
                feed: 50.0,
            },
            linked(18.1, 90.0),
            linked(18.2, 180.0),
            linked(18.3, 270.0),
            Move::Rapid {
                x: Some(0.0),
                z: None,
                c: None,
            },
            Move::SpindleOff,
        ],
    }
}

/// Where the moves before `index` leave the ring.
fn start_of(program: &Program, index: usize) -> Position {
    program
        .steps(Position::UNKNOWN)
        .nth(index)
        .map(|step| step.from)
        .unwrap()
}

#[test]
fn inside_the_cut_the_ring_clears_positions_on_the_helix_and_plunges_radially() {
    let program = program();
    let approach = approach(&program, 7).unwrap();
    assert_eq!(
        approach,
        vec![
            Move::Rapid {
                x: Some(0.0),
                z: None,
                c: None
            },
            // The end of move 6: C 90°, a quarter of the 10 mm lead.
            Move::Rapid {
                x: None,
                z: Some(2.5),
                c: Some(90.0)
            },
            Move::SpindleOn { rpm: 2500.0 },
            Move::Feed {
                x: Some(18.1),
                z: None,
                c: None,
                feed: 50.0
            },
        ]
    );
}

#[test]
fn the_resumed_program_reaches_each_remaining_move_where_the_original_does() {
    let program = program();
    for from in 0..=program.moves.len() {
        let resumed = resumed(&program, from).unwrap();
        let added = resumed.moves.len() - (program.moves.len() - from);
        assert_eq!(resumed.moves[added..], program.moves[from..]);
        // Wherever the ring stood, after the approach it is where move `from` starts,
        // in every axis the original had positioned by then.
        let anywhere = Position::known(7.0, -3.0, 1234.0);
        let mut reached = anywhere;
        for step in resumed.steps(anywhere).take(added) {
            reached = step.to;
        }
        // Axes the program has not positioned yet by then are left to its lead-in.
        if added > 0 {
            let start = start_of(&program, from);
            for (got, want) in [
                (reached.x, start.x),
                (reached.z, start.z),
                (reached.c, start.c),
            ] {
                if want.is_some() {
                    assert_eq!(got, want, "from {from}");
                }
            }
        }
    }
}

#[test]
fn every_approach_move_off_the_clear_x_is_radial() {
    let program = program();
    for from in 6..=8 {
        let resumed = resumed(&program, from).unwrap();
        let anywhere = Position::known(18.2, 5.0, 180.0);
        for step in resumed.steps(anywhere).take(4) {
            // Moving in C or Z happens only at the clear X; off it, only X moves.
            if step.from.z != step.to.z || step.from.c != step.to.c {
                assert_eq!(step.from.x, Some(0.0), "from {from}: {step:?}");
            }
        }
    }
}

#[test]
fn before_the_clear_and_after_the_cut_the_programs_own_moves_are_the_way() {
    let program = program();
    // Up to the move out to the clear X: the program starts with it.
    for from in 0..=1 {
        assert_eq!(approach(&program, from).unwrap(), vec![], "from {from}");
    }
    // The lead-out (X clear first) and the end.
    for from in 9..=program.moves.len() {
        assert_eq!(approach(&program, from).unwrap(), vec![], "from {from}");
    }
}

#[test]
fn in_the_lead_in_the_ring_clears_and_the_program_positions_the_rest() {
    let program = program();
    let clear = Move::Rapid {
        x: Some(0.0),
        z: None,
        c: None,
    };
    // Resuming at the C rapid: wherever the ring is (it may have cut on past the lines not
    // known to have run), it goes out to the clear X first; nothing else is known yet.
    assert_eq!(approach(&program, 2).unwrap(), vec![clear.clone()]);
    // At the plunge: out, to where the lead-in had put C and Z, the spindle on; the plunge
    // itself follows as written (X is at the clear position there, so no plunge of its own).
    assert_eq!(
        approach(&program, 5).unwrap(),
        vec![
            clear,
            Move::Rapid {
                x: None,
                z: Some(0.0),
                c: Some(0.0)
            },
            Move::SpindleOn { rpm: 2500.0 },
        ]
    );
}

#[test]
fn the_spindle_comes_back_only_if_the_program_had_it_on() {
    let mut program = program();
    program.moves.remove(4);
    let approach = approach(&program, 6).unwrap();
    assert!(!approach.iter().any(|m| matches!(m, Move::SpindleOn { .. })));
}

#[test]
fn a_program_that_cannot_be_reentered_says_why() {
    let program = program();
    assert_eq!(
        approach(&program, 12),
        Err(ReentryError::BeyondEnd { from: 12, len: 11 })
    );
    let mut no_clear = program.clone();
    no_clear.moves[1] = Move::Comment("no clear".into());
    assert_eq!(approach(&no_clear, 7), Err(ReentryError::NoClearX));
    let mut no_plunge = program.clone();
    no_plunge.moves[5] = Move::Feed {
        x: Some(18.0),
        z: Some(0.0),
        c: None,
        feed: 50.0,
    };
    assert_eq!(approach(&no_plunge, 7), Err(ReentryError::NoPlunge));
    let mut no_c = program.clone();
    no_c.moves[2] = Move::Comment("C never set".into());
    no_c.moves[6] = Move::Feed {
        x: Some(18.1),
        z: Some(2.5),
        c: None,
        feed: 50.0,
    };
    assert_eq!(
        approach(&no_c, 7),
        Err(ReentryError::Unpositioned { axis: 'C', from: 7 })
    );
    // The messages name what is missing.
    assert!(ReentryError::NoClearX.to_string().contains("clear"));
    assert!(ReentryError::NoPlunge.to_string().contains("plunge"));
}
