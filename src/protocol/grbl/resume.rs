//! Resuming a program at a line: the controller modes that line depends on, replayed from
//! the program text ([`ModalState::replay`]), and the preamble that restores them
//! ([`resume_preamble`]).
//!
//! A G-code line means something only together with the modes the lines before it left
//! behind: units, distance mode, feed mode and the modal feed, the motion mode, lathe
//! and plane modes, the spindle, and the G92 offset of C that a whirling program uses to
//! rebase its ever-growing C. After a stop those may be gone (a reset restores the
//! controller's defaults and clears G92, grbl's interface document says so) or intact
//! (an `error:N` stop changes no mode), so the preamble sets every one the program set,
//! whatever the controller holds: the same preamble is right in both cases.
//!
//! # The G92 offset of C
//!
//! G92 has no absolute form: `G92 C v` declares "the position C is at *now* is v". The
//! offset it leaves can therefore be restored only at a known position. The preamble
//! writes `G92 C v` with v the program's C (in the renamed frame) at the end of line
//! `line_index − 1`, which is right when the machine stands where that line left it:
//!
//! - after an `error:N` stop, once the controller is idle: it executes every line before
//!   the failed one (grbl refuses only the failed line, and with grblHAL's sticky error
//!   the lines after it), so it stands at the end of line `line_index − 1`, and if the
//!   offset survived, re-declaring the same value changes nothing;
//! - after an alarm or a reset, only if the machine is put back there (a reset during
//!   motion loses position; ALARM:2 keeps it but stops mid-line). When the machine stopped
//!   inside a line, the value to declare is instead the C the program frame gives the
//!   machine's present position, `MPos_C − WCO_C` with the `WCO` reported before the
//!   stop; replace the `G92` line of the preamble with that value (the preamble is plain
//!   lines for exactly this reason).
//!
//! Only C is restored: the parser this module uses (the crate's own,
//! [`crate::post::gcode::parse`](mod@crate::post::gcode::parse)) reads the subset our posts write and
//! common senders send, and a whirling program renames only C. A program that renames X
//! or Z, or holds a line the parser cannot read before the resume line, is refused rather
//! than resumed with modes guessed.

use thiserror::Error;

use crate::post::gcode::format::format_number;
use crate::post::gcode::parse::{parse_line, GCode, MCode, ParseError, ParsedLine, WordKind};
use crate::program::Move;

/// Millimetres per inch (grbl converts G20 feeds and lengths with it at parse time).
const MM_PER_INCH: f64 = 25.4;

/// Digits of a number that grbl-family controllers read (grblHAL drops the rest).
const MAX_NUMBER_DIGITS: usize = 9;

/// Most decimals a restored number is written with.
const MAX_DECIMALS: u32 = 6;

/// Length units (G20/G21).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Units {
    /// G21.
    Millimetres,
    /// G20.
    Inches,
}

/// Distance mode (G90/G91).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Distance {
    /// G90.
    Absolute,
    /// G91.
    Incremental,
}

/// Feed mode (G93/G94).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FeedMode {
    /// G94: F in units per minute, modal.
    UnitsPerMinute,
    /// G93: F is 1/minutes of its own block and required on every G1.
    InverseTime,
}

/// Motion mode (G0/G1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Motion {
    /// G0.
    Rapid,
    /// G1.
    Linear,
}

/// Lathe X mode (G7/G8), set only by programs that select it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LatheMode {
    /// G7: X words are diameters.
    Diameter,
    /// G8: X words are radii.
    Radius,
}

/// Plane (G17/G18), set only by programs that select it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Plane {
    /// G17.
    Xy,
    /// G18.
    Xz,
}

/// What the program did with the G92 offset of C.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum COffset {
    /// Neither G92 nor G92.1 so far: the program runs in whatever frame the controller had,
    /// and the preamble leaves it alone.
    Untouched,
    /// The last was G92.1: no offset.
    Cleared,
    /// A G92 C offset is active; `c` is the program's C, degrees, in the renamed frame, at
    /// this point of the program.
    Renamed {
        /// The C position in the renamed frame.
        c: f64,
    },
}

/// The controller modes the program has set by some line, as the controller's parser
/// holds them (grbl's order of execution within a line: feed mode, F, S, spindle,
/// units/distance/plane, G92.1/G92, motion).
#[derive(Debug, Clone, PartialEq)]
pub struct ModalState {
    /// G20/G21 (grbl starts in G21).
    pub units: Units,
    /// G90/G91 (grbl starts in G90).
    pub distance: Distance,
    /// G93/G94 (grbl starts in G94).
    pub feed_mode: FeedMode,
    /// The modal G94 feed in mm/min, as grbl keeps it (a G20 feed is converted when read);
    /// `None` in G93 and after a feed-mode change, where grbl forgets it.
    pub feed_mm_per_min: Option<f64>,
    /// G0/G1, once set.
    pub motion: Option<Motion>,
    /// G7/G8, if the program set it.
    pub lathe: Option<LatheMode>,
    /// G17/G18, if the program set it.
    pub plane: Option<Plane>,
    /// The last S, rpm.
    pub spindle_rpm: Option<f64>,
    /// M3 in force (M5 not since).
    pub spindle_on: bool,
    /// The G92 offset of C.
    pub c_offset: COffset,
    /// C, degrees, in the controller's current frame, if the program has made it known
    /// (taking no offset to be active at the start, as [`crate::program::Program::steps`]
    /// does).
    pub c: Option<f64>,
    /// Unrebased C minus the frame's C; `None` once unknown.
    c_shift: Option<f64>,
}

impl Default for ModalState {
    /// grbl's state after power-up or reset, with nothing set by a program.
    fn default() -> ModalState {
        ModalState {
            units: Units::Millimetres,
            distance: Distance::Absolute,
            feed_mode: FeedMode::UnitsPerMinute,
            feed_mm_per_min: None,
            motion: None,
            lathe: None,
            plane: None,
            spindle_rpm: None,
            spindle_on: false,
            c_offset: COffset::Untouched,
            c: None,
            c_shift: Some(0.0),
        }
    }
}

/// Why a program cannot be resumed at a line.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ResumeError {
    /// The resume line is past the program.
    #[error("cannot resume at line index {line_index}: the program has {len} lines")]
    BeyondEnd {
        /// The requested 0-based line index.
        line_index: usize,
        /// The program's line count.
        len: usize,
    },
    /// A line before the resume line cannot be read, so the modes it sets are unknown.
    #[error("cannot replay the modal state: {error}")]
    Unreadable {
        /// 0-based index of the line.
        index: usize,
        /// Why (its line number is `index + 1`).
        error: ParseError,
    },
    /// G92 on an axis other than C.
    #[error("program line {}: G92 on {axis}: only a G92 offset of C is restored on resume", .index + 1)]
    G92OnLinearAxis {
        /// 0-based index of the line.
        index: usize,
        /// The axis letter.
        axis: char,
    },
    /// M2/M30 before the resume line: the program had ended.
    #[error("program line {}: the program ends (M2/M30) before the resume line", .index + 1)]
    AfterProgramEnd {
        /// 0-based index of the line.
        index: usize,
    },
    /// The resumed lines move without a motion code, and the motion mode they rely on
    /// cannot be set by a line that does not move.
    #[error(
        "program line {}: axis words without G0/G1 rely on the modal motion mode, which \
         cannot be restored here ({why})", .index + 1
    )]
    MotionModeNotRestorable {
        /// 0-based index of the first line relying on it.
        index: usize,
        /// Why not.
        why: &'static str,
    },
    /// A move that has no place in an approach (a linked move, a comment).
    #[error(
        "the approach to the resume line holds {what}, which is no rapid, feed or spindle move"
    )]
    ApproachMove {
        /// The move.
        what: String,
    },
    /// A value the preamble must write needs more digits than the controller reads.
    #[error("{word} needs more than {MAX_NUMBER_DIGITS} digits, which grbl-family controllers do not read")]
    TooManyDigits {
        /// The word as it would be written.
        word: String,
    },
}

impl ModalState {
    /// Replays lines `0..upto` of `lines` from grbl's power-up state.
    pub fn replay<S: AsRef<str>>(lines: &[S], upto: usize) -> Result<ModalState, ResumeError> {
        let before = lines.get(..upto).ok_or(ResumeError::BeyondEnd {
            line_index: upto,
            len: lines.len(),
        })?;
        let mut state = ModalState::default();
        for (index, text) in before.iter().enumerate() {
            let line = parse_line(text.as_ref(), index + 1)
                .map_err(|error| ResumeError::Unreadable { index, error })?;
            state.apply(&line, index)?;
        }
        Ok(state)
    }

    /// Applies one line in grbl's order of execution.
    fn apply(&mut self, line: &ParsedLine, index: usize) -> Result<(), ResumeError> {
        let has_g = |code: GCode| line.words.iter().any(|w| w.kind == WordKind::G(code));
        let has_m = |code: MCode| line.words.iter().any(|w| w.kind == WordKind::M(code));
        if has_m(MCode::End) || has_m(MCode::EndRewind) {
            return Err(ResumeError::AfterProgramEnd { index });
        }
        // Units first: grbl converts the F and the lengths of a block in its own units.
        if has_g(GCode::Inch) {
            self.units = Units::Inches;
        }
        if has_g(GCode::Millimetre) {
            self.units = Units::Millimetres;
        }
        // Feed mode, then F; any feed-mode change leaves the G94 feed undefined, as in grbl.
        for (code, mode) in [
            (GCode::InverseTime, FeedMode::InverseTime),
            (GCode::UnitsPerMinute, FeedMode::UnitsPerMinute),
        ] {
            if has_g(code) {
                if self.feed_mode != mode {
                    self.feed_mm_per_min = None;
                }
                self.feed_mode = mode;
            }
        }
        let mut c_word = None;
        for word in &line.words {
            match word.kind {
                WordKind::F(f) if self.feed_mode == FeedMode::UnitsPerMinute => {
                    self.feed_mm_per_min = Some(f * self.unit_mm());
                }
                WordKind::S(s) => self.spindle_rpm = Some(s),
                WordKind::C(c) => c_word = Some(c),
                WordKind::X(_) | WordKind::Y(_) | WordKind::Z(_) if has_g(GCode::SetPosition) => {
                    let axis = match word.kind {
                        WordKind::X(_) => 'X',
                        WordKind::Y(_) => 'Y',
                        _ => 'Z',
                    };
                    return Err(ResumeError::G92OnLinearAxis { index, axis });
                }
                _ => {}
            }
        }
        if has_m(MCode::SpindleOn) {
            self.spindle_on = true;
        }
        if has_m(MCode::SpindleOff) {
            self.spindle_on = false;
        }
        if has_g(GCode::DiameterMode) {
            self.lathe = Some(LatheMode::Diameter);
        }
        if has_g(GCode::RadiusMode) {
            self.lathe = Some(LatheMode::Radius);
        }
        if has_g(GCode::PlaneXy) {
            self.plane = Some(Plane::Xy);
        }
        if has_g(GCode::PlaneXz) {
            self.plane = Some(Plane::Xz);
        }
        if has_g(GCode::Absolute) {
            self.distance = Distance::Absolute;
        }
        if has_g(GCode::Incremental) {
            self.distance = Distance::Incremental;
        }
        if has_g(GCode::Rapid) {
            self.motion = Some(Motion::Rapid);
        }
        if has_g(GCode::Linear) {
            self.motion = Some(Motion::Linear);
        }
        if has_g(GCode::ClearOffset) {
            // The frame becomes the unrebased one; axis words on the line are a move after it.
            self.c = self.c.zip(self.c_shift).map(|(c, shift)| c + shift);
            self.c_shift = Some(0.0);
            self.c_offset = COffset::Cleared;
        }
        if has_g(GCode::SetPosition) {
            // G92 values are absolute whatever G90/G91 says; C is in degrees whatever the units.
            if let Some(v) = c_word {
                self.c_shift = self.c.zip(self.c_shift).map(|(c, shift)| c + shift - v);
                self.c = Some(v);
                self.c_offset = COffset::Renamed { c: v };
            }
        } else if let Some(v) = c_word {
            let moved = |from: f64| match self.distance {
                Distance::Absolute => v,
                Distance::Incremental => from + v,
            };
            self.c = match self.distance {
                Distance::Absolute => Some(v),
                Distance::Incremental => self.c.map(moved),
            };
            if let COffset::Renamed { c } = self.c_offset {
                self.c_offset = COffset::Renamed { c: moved(c) };
            }
        }
        Ok(())
    }

    /// Millimetres per program length unit.
    fn unit_mm(&self) -> f64 {
        match self.units {
            Units::Millimetres => 1.0,
            Units::Inches => MM_PER_INCH,
        }
    }
}

/// The lines that put a controller into the modes the program is in at line `line_index`
/// (0-based), to be sent before that line; see the module docs for the G92 rule.
///
/// In order:
/// 1. `G92.1`, or `G21 G92 C…` (in G21 and before any G91, so the value is read as
///    written) if the program cleared or set the C offset; nothing if it never did;
/// 2. one modal line `G20|G21 G90|G91 G93|G94`, with `G7|G8` and `G17|G18` if the program
///    set them, `G0|G1` if the resumed lines move without a motion code of their own, and
///    `F…` (in the line's units) if a G94 feed is in force;
/// 3. `M3 S…` if the spindle (the whirling ring) is on, and `G4 P…` if `spin_up_dwell_s`
///    is above zero, so that no cut resumes with the ring still spinning up. Without the
///    dwell the controller's own spindle settings decide, as they did at the program's
///    first M3.
///
/// None of these lines moves the machine.
pub fn resume_preamble<S: AsRef<str>>(
    lines: &[S],
    line_index: usize,
    spin_up_dwell_s: f64,
) -> Result<Vec<String>, ResumeError> {
    let state = ModalState::replay(lines, line_index)?;
    let mut preamble = offset_lines(&state)?;
    preamble.push(modal_line(&state, lines, line_index)?);
    preamble.extend(spindle_lines(&state, spin_up_dwell_s)?);
    Ok(preamble)
}

/// The preamble of a resume inside the cut, which re-enters along the groove
/// ([`crate::program::reentry`]): as [`resume_preamble`], with the `approach` moves written
/// between the C offset and the modal line, in millimetres, absolute, units per minute,
/// and in the program's frame at `line_index` (X as a diameter where the program, or with
/// `x_diameter` the machine, reads it so; C renamed as the program's G92 renamed it). The
/// modal line after them puts back every mode the program is in there.
pub fn reentry_preamble<S: AsRef<str>>(
    lines: &[S],
    line_index: usize,
    approach: &[Move],
    x_diameter: bool,
    spin_up_dwell_s: f64,
) -> Result<Vec<String>, ResumeError> {
    let state = ModalState::replay(lines, line_index)?;
    let mut preamble = offset_lines(&state)?;
    let x_scale = match state.lathe {
        Some(LatheMode::Diameter) => 2.0,
        Some(LatheMode::Radius) => 1.0,
        None if x_diameter => 2.0,
        None => 1.0,
    };
    let c_shift = state.c_shift.unwrap_or(0.0);
    let axes = |x: Option<f64>, z: Option<f64>, c: Option<f64>| -> Result<String, ResumeError> {
        let words = [
            x.map(|x| word('X', x * x_scale)).transpose()?,
            z.map(|z| word('Z', z)).transpose()?,
            c.map(|c| word('C', c - c_shift)).transpose()?,
        ];
        Ok(words.into_iter().flatten().collect::<Vec<_>>().join(" "))
    };
    let mut moves = Vec::new();
    for m in approach {
        match *m {
            Move::Rapid { x, z, c } => moves.push(format!("G0 {}", axes(x, z, c)?)),
            Move::Feed { x, z, c, feed } => {
                moves.push(format!("G1 {} {}", axes(x, z, c)?, word('F', feed)?));
            }
            Move::SpindleOn { rpm } => moves.extend(spin_up(Some(rpm), spin_up_dwell_s)?),
            Move::SpindleOff => moves.push("M5".to_owned()),
            Move::Linked { .. } | Move::Comment(_) => {
                return Err(ResumeError::ApproachMove {
                    what: format!("{m:?}"),
                })
            }
        }
    }
    // The approach is written in millimetres, absolute, units per minute, whatever the
    // program is in; the modal line after it puts the program's modes back.
    if let Some(first) = moves.first_mut() {
        first.insert_str(0, "G21 G90 G94 ");
    }
    preamble.extend(moves);
    preamble.push(modal_line(&state, lines, line_index)?);
    // The approach turned the spindle on where the program has it on.
    if !approach.iter().any(|m| matches!(m, Move::SpindleOn { .. })) {
        preamble.extend(spindle_lines(&state, spin_up_dwell_s)?);
    }
    Ok(preamble)
}

/// `G92.1`, or `G21 G92 C…`, if the program cleared or set the C offset before the line.
fn offset_lines(state: &ModalState) -> Result<Vec<String>, ResumeError> {
    Ok(match state.c_offset {
        COffset::Untouched => Vec::new(),
        COffset::Cleared => vec!["G92.1".to_owned()],
        COffset::Renamed { c } => vec![format!("G21 G92 {}", word('C', c)?)],
    })
}

/// The one line of the program's modes at `line_index`; see [`resume_preamble`].
fn modal_line<S: AsRef<str>>(
    state: &ModalState,
    lines: &[S],
    line_index: usize,
) -> Result<String, ResumeError> {
    let mut modal = vec![
        match state.units {
            Units::Millimetres => "G21",
            Units::Inches => "G20",
        },
        match state.distance {
            Distance::Absolute => "G90",
            Distance::Incremental => "G91",
        },
        match state.feed_mode {
            FeedMode::UnitsPerMinute => "G94",
            FeedMode::InverseTime => "G93",
        },
    ];
    modal.extend(state.lathe.map(|mode| match mode {
        LatheMode::Diameter => "G7",
        LatheMode::Radius => "G8",
    }));
    modal.extend(state.plane.map(|plane| match plane {
        Plane::Xy => "G17",
        Plane::Xz => "G18",
    }));
    if let Some(index) = first_relying_on_motion_mode(lines, line_index) {
        // grbl accepts G0, and G1 with a defined feed, without axis words: the mode is set
        // and nothing moves. A G1 in G93 would need an F of its own block.
        let code = match (state.motion, state.feed_mode, state.feed_mm_per_min) {
            (Some(Motion::Rapid), ..) => "G0",
            (Some(Motion::Linear), FeedMode::UnitsPerMinute, Some(_)) => "G1",
            (Some(Motion::Linear), FeedMode::InverseTime, _) => {
                return Err(ResumeError::MotionModeNotRestorable {
                    index,
                    why: "G1 in inverse time (G93) needs F on a moving line",
                })
            }
            (Some(Motion::Linear), ..) => {
                return Err(ResumeError::MotionModeNotRestorable {
                    index,
                    why: "G1 with no feed rate defined",
                })
            }
            (None, ..) => {
                return Err(ResumeError::MotionModeNotRestorable {
                    index,
                    why: "the program never set G0 or G1 before it",
                })
            }
        };
        modal.push(code);
    }
    let mut modal = modal.join(" ");
    if let (FeedMode::UnitsPerMinute, Some(feed)) = (state.feed_mode, state.feed_mm_per_min) {
        modal.push(' ');
        modal.push_str(&word('F', feed / state.unit_mm())?);
    }
    Ok(modal)
}

/// `M3 S…` and the spin-up dwell, if the spindle is on; see [`resume_preamble`].
fn spindle_lines(state: &ModalState, spin_up_dwell_s: f64) -> Result<Vec<String>, ResumeError> {
    if state.spindle_on {
        spin_up(state.spindle_rpm, spin_up_dwell_s)
    } else {
        Ok(Vec::new())
    }
}

/// `M3` (at `rpm`, if known) and the spin-up dwell, if there is one.
fn spin_up(rpm: Option<f64>, spin_up_dwell_s: f64) -> Result<Vec<String>, ResumeError> {
    let mut lines = vec![match rpm {
        Some(rpm) => format!("M3 {}", word('S', rpm)?),
        None => "M3".to_owned(),
    }];
    if spin_up_dwell_s > 0.0 && spin_up_dwell_s.is_finite() {
        lines.push(format!("G4 {}", word('P', spin_up_dwell_s)?));
    }
    Ok(lines)
}

/// The first line from `from` on that has axis words but no G0/G1 (and no G92 to claim
/// them), before any line that sets the motion mode itself; `None` if there is none or a
/// line on the way cannot be read (the controller will refuse that line anyway).
fn first_relying_on_motion_mode<S: AsRef<str>>(lines: &[S], from: usize) -> Option<usize> {
    for (index, text) in lines.iter().enumerate().skip(from) {
        let line = parse_line(text.as_ref(), index + 1).ok()?;
        let mut axis_words = false;
        for word in &line.words {
            match word.kind {
                WordKind::G(GCode::Rapid | GCode::Linear)
                | WordKind::M(MCode::End | MCode::EndRewind) => return None,
                WordKind::X(_) | WordKind::Y(_) | WordKind::Z(_) | WordKind::C(_) => {
                    axis_words = true;
                }
                _ => {}
            }
        }
        let g92 = line
            .words
            .iter()
            .any(|w| w.kind == WordKind::G(GCode::SetPosition));
        if axis_words && !g92 {
            return Some(index);
        }
    }
    None
}

/// `letter` and `value` with the fewest decimals (at most six) that give the value back
/// within 10⁻¹¹ relative: a replayed value is a written one, or a sum or unit conversion
/// of written ones, whose floating-point noise is far below that, so this recovers the
/// program's own spelling.
fn word(letter: char, value: f64) -> Result<String, ResumeError> {
    let scale = value.abs().max(1.0);
    let text = (0..=MAX_DECIMALS)
        .map(|decimals| format_number(value, decimals))
        .find(|text| {
            text.parse::<f64>()
                .is_ok_and(|read| (read - value).abs() <= 1e-11 * scale)
        })
        .unwrap_or_else(|| format_number(value, MAX_DECIMALS));
    let word = format!("{letter}{text}");
    if text.chars().filter(char::is_ascii_digit).count() > MAX_NUMBER_DIGITS {
        return Err(ResumeError::TooManyDigits { word });
    }
    Ok(word)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lines(text: &str) -> Vec<String> {
        text.lines().map(str::to_owned).collect()
    }

    /// The shape our grblHAL post writes: preamble, spindle, linked moves in G93, G92 C
    /// rebasing between revolutions.
    const POSTED: &str = "\
G21 G90 G94
M3 S3000
G0 X20 Z5 C0
G93 G1 Z-0.5 C90 F100
G1 Z-1 C180 F100
G92 C0
G1 Z-1.5 C90 F100
G1 Z-2 C180 F100
G92.1
G94
G0 X30
M5
M2";

    #[test]
    fn a_reentry_approaches_in_the_programs_frame_then_restores_its_modes() {
        let program = lines(POSTED);
        // The neutral program's frame is continuous: line index 6 ends at C 270 (C90 after
        // `G92 C0` at 180), Z -1.5.
        let approach = [
            Move::Rapid {
                x: Some(20.0),
                z: None,
                c: None,
            },
            Move::Rapid {
                x: None,
                z: Some(-1.5),
                c: Some(270.0),
            },
            Move::SpindleOn { rpm: 3000.0 },
            Move::Feed {
                x: Some(10.0),
                z: None,
                c: None,
                feed: 50.0,
            },
        ];
        assert_eq!(
            reentry_preamble(&program, 7, &approach, false, 0.0).unwrap(),
            vec![
                "G21 G92 C90",
                "G21 G90 G94 G0 X20",
                "G0 Z-1.5 C90",
                "M3 S3000",
                "G1 X10 F50",
                "G21 G90 G93",
            ]
        );
        // A machine that reads X as a diameter gets twice the radius; a dwell follows M3.
        let preamble = reentry_preamble(&program, 7, &approach, true, 2.0).unwrap();
        assert_eq!(preamble[1], "G21 G90 G94 G0 X40");
        assert_eq!(preamble[3..6], ["M3 S3000", "G4 P2", "G1 X20 F50"]);
        // Only rapids, feeds and the spindle make an approach.
        let linked = [Move::Linked {
            x: 1.0,
            z: 1.0,
            c: 1.0,
            minutes: 1.0,
        }];
        assert!(matches!(
            reentry_preamble(&program, 7, &linked, false, 0.0),
            Err(ResumeError::ApproachMove { .. })
        ));
    }

    #[test]
    fn before_any_line_the_preamble_is_grbls_defaults() {
        let program = lines(POSTED);
        assert_eq!(
            resume_preamble(&program, 0, 0.0).unwrap(),
            vec!["G21 G90 G94"]
        );
    }

    #[test]
    fn the_g92_offset_of_c_is_redeclared_at_the_programs_c() {
        let program = lines(POSTED);
        // Line index 6 follows `G92 C0`: C is 0 in the renamed frame.
        assert_eq!(
            resume_preamble(&program, 6, 0.0).unwrap(),
            vec!["G21 G92 C0", "G21 G90 G93", "M3 S3000"]
        );
        // Index 7 follows `G1 … C90`: the machine stands at C90 of the renamed frame.
        assert_eq!(
            resume_preamble(&program, 7, 0.0).unwrap(),
            vec!["G21 G92 C90", "G21 G90 G93", "M3 S3000"]
        );
        let state = ModalState::replay(&program, 8).unwrap();
        assert_eq!(state.c_offset, COffset::Renamed { c: 180.0 });
        // The unrebased C: 180 before G92 C0, then 180 more.
        let cleared = ModalState::replay(&program, 9).unwrap();
        assert_eq!(cleared.c_offset, COffset::Cleared);
        assert_eq!(cleared.c, Some(360.0));
        // After G92.1 the preamble clears the offset, in case the controller kept one.
        assert_eq!(
            resume_preamble(&program, 10, 0.0).unwrap(),
            vec!["G92.1", "G21 G90 G94", "M3 S3000"]
        );
        // Before any G92 the preamble leaves the controller's frame alone.
        assert_eq!(
            resume_preamble(&program, 4, 0.0).unwrap(),
            vec!["G21 G90 G93", "M3 S3000"]
        );
    }

    #[test]
    fn inches_incremental_inverse_time_and_the_spindle_are_restored() {
        let program = lines(
            "G20 G91 G94 F10\nM3 S2500\nG92 C10\nG1 X0.1 C-2.5\nG93 G1 Z-0.05 C30 F2\nG1 Z-0.05 C30 F2",
        );
        let state = ModalState::replay(&program, 5).unwrap();
        assert_eq!(state.units, Units::Inches);
        assert_eq!(state.distance, Distance::Incremental);
        assert_eq!(state.feed_mode, FeedMode::InverseTime);
        assert_eq!(state.feed_mm_per_min, None);
        // G91 C moves add up in the renamed frame: 10 − 2.5 + 30.
        assert_eq!(state.c_offset, COffset::Renamed { c: 37.5 });
        assert_eq!(
            resume_preamble(&program, 5, 1.5).unwrap(),
            vec!["G21 G92 C37.5", "G20 G91 G93", "M3 S2500", "G4 P1.5"]
        );
        // In G94 the modal feed comes back in the units in force: F10 in/min.
        assert_eq!(
            resume_preamble(&program, 4, 0.0).unwrap(),
            vec!["G21 G92 C7.5", "G20 G91 G94 F10", "M3 S2500"]
        );
    }

    #[test]
    fn a_feed_set_in_inches_is_restored_in_millimetres_after_g21() {
        // grbl keeps the feed in mm/min: F10 in G20 is 254 mm/min, still in force after G21.
        let program = lines("G20 G94 F10\nG21\nG1 X1");
        assert_eq!(
            resume_preamble(&program, 2, 0.0).unwrap(),
            vec!["G21 G90 G94 F254"]
        );
        // A feed-mode change forgets the feed, as grbl does.
        let program = lines("G94 F500\nG93\nG94\nG1 X1 F300");
        assert_eq!(
            ModalState::replay(&program, 3).unwrap().feed_mm_per_min,
            None
        );
    }

    #[test]
    fn the_motion_mode_is_restored_only_when_the_resumed_lines_rely_on_it() {
        let program = lines("G21 G90 G94\nG1 X1 F200\nX2\nX3\nG0 X4\nX5");
        // Line index 2 is `X2`, a modal G1 move.
        assert_eq!(
            resume_preamble(&program, 2, 0.0).unwrap(),
            vec!["G21 G90 G94 G1 F200"]
        );
        // Index 4 has its own G0.
        assert_eq!(
            resume_preamble(&program, 4, 0.0).unwrap(),
            vec!["G21 G90 G94 F200"]
        );
        assert_eq!(
            resume_preamble(&program, 5, 0.0).unwrap(),
            vec!["G21 G90 G94 G0 F200"]
        );
        // A modal G1 in inverse time cannot be set without moving.
        let program = lines("G93 G1 X1 F2\nX2 F2");
        assert!(matches!(
            resume_preamble(&program, 1, 0.0),
            Err(ResumeError::MotionModeNotRestorable { index: 1, .. })
        ));
        let program = lines("G21\nX2");
        assert!(matches!(
            resume_preamble(&program, 1, 0.0),
            Err(ResumeError::MotionModeNotRestorable { index: 1, .. })
        ));
    }

    #[test]
    fn lathe_and_plane_modes_are_restored_when_the_program_set_them() {
        let program = lines("G21 G90 G94 G7 G18\nG0 X40");
        assert_eq!(
            resume_preamble(&program, 1, 0.0).unwrap(),
            vec!["G21 G90 G94 G7 G18"]
        );
    }

    #[test]
    fn programs_that_cannot_be_replayed_are_refused() {
        let program = lines("G21\nG54\nG0 X1");
        let error = resume_preamble(&program, 2, 0.0).unwrap_err();
        assert!(matches!(error, ResumeError::Unreadable { index: 1, .. }));
        assert!(error.to_string().contains("line 2"), "{error}");
        let program = lines("G92 X0\nG0 X1");
        assert_eq!(
            resume_preamble(&program, 1, 0.0),
            Err(ResumeError::G92OnLinearAxis {
                index: 0,
                axis: 'X'
            })
        );
        let program = lines("G0 X1\nM30\nG0 X2");
        assert_eq!(
            resume_preamble(&program, 2, 0.0),
            Err(ResumeError::AfterProgramEnd { index: 1 })
        );
        assert_eq!(
            resume_preamble(&program, 4, 0.0),
            Err(ResumeError::BeyondEnd {
                line_index: 4,
                len: 3
            })
        );
        // Lines after the resume line are not replayed, readable or not.
        let program = lines("G0 X1\nG54");
        assert_eq!(
            resume_preamble(&program, 1, 0.0).unwrap(),
            vec!["G21 G90 G94"]
        );
    }

    #[test]
    fn restored_numbers_keep_the_programs_spelling_and_the_digit_limit() {
        assert_eq!(word('C', 720.0).unwrap(), "C720");
        assert_eq!(word('C', -0.0).unwrap(), "C0");
        assert_eq!(word('C', 0.1 + 0.2).unwrap(), "C0.3");
        assert_eq!(word('F', 254.0 / 25.4).unwrap(), "F10");
        assert_eq!(word('C', 123.456789).unwrap(), "C123.456789");
        assert_eq!(word('C', 1234.56789).unwrap(), "C1234.56789");
        // Ten digits: grblHAL would drop the last.
        assert!(matches!(
            word('C', 1234.567891),
            Err(ResumeError::TooManyDigits { .. })
        ));
    }
}
