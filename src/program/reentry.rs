//! Re-entering a program part way along the groove, after a stop.
//!
//! A whirling program cuts one continuous helical pass: a lead-in (X clear, C and Z to the
//! start, spindle on, a plunge in X), the linked moves, a lead-out (X clear, spindle off).
//! After a stop the ring stands somewhere along the path, not necessarily where the line to
//! resume at begins: the controller may have gone on a few lines past the last one it
//! reported, or a reset may have stopped it mid-line. Streaming that line as it is would move
//! the ring in a straight line from where it stands to where the line ends, across the
//! groove. So a resume inside the cut goes the way the program itself came in, to the
//! resume line's start:
//!
//! 1. X to the program's clear position (its first rapid in X), straight out of the groove;
//! 2. C and Z, in rapid, to where the moves before the resume line leave them: the ring
//!    is clear of the work, so any path is safe;
//! 3. the spindle back on at the program's speed, if the program had it on there;
//! 4. X in at the program's plunge feed (its first feed in X alone) to the line's start:
//!    the same radial plunge as the lead-in, at a point of the helix.
//!
//! From there the resume line and the rest of the program follow. A line the controller had
//! finished is cut again along the same path, which removes nothing more. A resume in the
//! lead-in clears X the same way (the ring may have cut on past a line not known to have
//! run) and leaves the rest of the lead-in to the program; after the cut the lead-out
//! begins by clearing X, so nothing is added there.

use thiserror::Error;

use super::{Move, Position, Program};

/// Why a program cannot be re-entered at a move.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ReentryError {
    /// The index is past the program's end.
    #[error("cannot resume at move {from}: the program has {len} moves")]
    BeyondEnd {
        /// The move asked for.
        from: usize,
        /// Moves in the program.
        len: usize,
    },
    /// No rapid in X before the cut: nowhere known to be clear of the work.
    #[error("the program has no rapid move in X before its cut, so no position known to be clear of the work to re-enter from")]
    NoClearX,
    /// No feed in X alone before the cut: no plunge feed the program uses.
    #[error("the program has no plunge (a feed in X alone) before its cut, so no feed to plunge back in with")]
    NoPlunge,
    /// An axis never positioned before the resume move.
    #[error(
        "the program never positions {axis} before move {from}, so where to re-enter is unknown"
    )]
    Unpositioned {
        /// The axis.
        axis: char,
        /// The resume move.
        from: usize,
    },
}

/// The moves that bring the ring from wherever it stopped to the start of
/// `program.moves[from]` along the way the program came in (see the module docs); empty
/// where the program's own next move is that way: at or before its first move out to the
/// clear X, and after its cut (the lead-out begins with that move).
///
/// In the lead-in the ring may stand anywhere all the same (a resume point is the first
/// line *not known* to have run, and the controller may have cut on well past it), so it
/// clears X there too and positions the axes the program had positioned; the rest of the
/// lead-in follows as written.
pub fn approach(program: &Program, from: usize) -> Result<Vec<Move>, ReentryError> {
    let moves = &program.moves;
    if from > moves.len() {
        return Err(ReentryError::BeyondEnd {
            from,
            len: moves.len(),
        });
    }
    let cutting = |m: &Move| matches!(m, Move::Feed { .. } | Move::Linked { .. });
    let (Some(first_cut), Some(last_cut)) = (
        moves.iter().position(cutting),
        moves.iter().rposition(cutting),
    ) else {
        return Ok(Vec::new());
    };
    if from == 0 || from > last_cut {
        return Ok(Vec::new());
    }
    let (clear_at, clear) = moves[..first_cut]
        .iter()
        .enumerate()
        .find_map(|(i, m)| match m {
            Move::Rapid { x: Some(x), .. } => Some((i, *x)),
            _ => None,
        })
        .ok_or(ReentryError::NoClearX)?;
    if from <= clear_at {
        return Ok(Vec::new());
    }
    let before = Program {
        moves: moves[..from].to_vec(),
    };
    let mut at = Position::UNKNOWN;
    let mut spindle = None;
    for step in before.steps(Position::UNKNOWN) {
        at = step.to;
        match step.action {
            Move::SpindleOn { rpm } => spindle = Some(*rpm),
            Move::SpindleOff => spindle = None,
            _ => {}
        }
    }
    // Inside the cut every axis must be known; in the lead-in the program positions the
    // rest itself.
    if from > first_cut {
        for (value, axis) in [(at.x, 'X'), (at.z, 'Z'), (at.c, 'C')] {
            if value.is_none() {
                return Err(ReentryError::Unpositioned { axis, from });
            }
        }
    }
    let mut approach = vec![Move::Rapid {
        x: Some(clear),
        z: None,
        c: None,
    }];
    if at.z.is_some() || at.c.is_some() {
        approach.push(Move::Rapid {
            x: None,
            z: at.z,
            c: at.c,
        });
    }
    approach.extend(spindle.map(|rpm| Move::SpindleOn { rpm }));
    if let Some(x) = at.x.filter(|&x| x != clear) {
        let plunge = moves
            .iter()
            .find_map(|m| match m {
                Move::Feed {
                    x: Some(_),
                    z: None,
                    c: None,
                    feed,
                } => Some(*feed),
                _ => None,
            })
            .ok_or(ReentryError::NoPlunge)?;
        approach.push(Move::Feed {
            x: Some(x),
            z: None,
            c: None,
            feed: plunge,
        });
    }
    Ok(approach)
}

/// `program` resumed at move `from`: the [`approach`], then the moves from `from` on.
pub fn resumed(program: &Program, from: usize) -> Result<Program, ReentryError> {
    let mut moves = approach(program, from)?;
    moves.extend_from_slice(&program.moves[from..]);
    Ok(Program { moves })
}

#[cfg(test)]
mod tests;
