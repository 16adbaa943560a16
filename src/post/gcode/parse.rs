//! Reading G-code: the subset both writers emit and grbl senders commonly send.
//!
//! Two stages, so a caller can stop after the first:
//!
//! 1. [`parse`] / [`parse_line`]: text → [`ParsedLine`]s, each with its 1-based line
//!    number, typed [`Word`]s and comments. This stage checks what a controller checks
//!    within one line: known letters and codes, numbers present, no word given twice,
//!    no two codes of one modal group.
//! 2. [`to_program`]: lines → [`Program`], interpreting the modal state the way the
//!    RS274/NGC order of execution does (feed mode, F, S, spindle, plane, units,
//!    distance mode, G92, motion, program end), so that `parse(write(p)) ≈ p`: G91
//!    increments become absolute targets, G20 inches become mm (C stays in degrees),
//!    diameter X becomes the ring-centre radius, G93 `F` becomes the move's minutes.
//!
//! Every error names the line, the column (1-based, in characters) and what is wrong.
//!
//! Accepted: `N` (first word only), comments `( )` (not nested) and `;` (to the end of
//! the line), lines holding only `%`, G0 G1 G7 G8 G17 G18 G20 G21 G61 G64 (with P, Q)
//! G90 G91 G92 G92.1 G93 G94, M2 M3 M5 M30, S, F and the axis words X Y Z C; letters in
//! either case, spaces and tabs between words and between a letter and its number. A Y
//! word parses, but a program that moves Y is refused by [`to_program`]: the whirling
//! machine has no Y. Lines after M2/M30 are ignored, as LinuxCNC ignores them.
//!
//! G92.1 takes no axis words: as in LinuxCNC and grbl, axis words on its line are a
//! move in the current motion mode, made after the offset is cancelled.
//!
//! # G92, undone
//!
//! A [`Program`] has one continuous frame, so the reader undoes G92's renaming of C as it
//! goes: every C it gives is in the controller's frame at the program's start (taken to
//! have no offset active then), counting whole turns across any G92. A G92 that renames a
//! C no line has positioned yet anchors the frame there (C takes the new name's value);
//! turns and speeds stay right. A G92.1 after such a renaming is refused: the controller
//! then reads a C whose relation to the program's frame nobody knows.

use std::fmt;

use thiserror::Error;

use crate::config::machine::Axis;
use crate::program::{Move, Program};

/// Millimetres per inch, for G20 programs.
const MM_PER_INCH: f64 = 25.4;

/// A G-code this reader knows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum GCode {
    /// G0: rapid motion.
    Rapid,
    /// G1: linear motion at feed.
    Linear,
    /// G7: lathe diameter mode (X words are diameters).
    DiameterMode,
    /// G8: lathe radius mode (X words are radii).
    RadiusMode,
    /// G17: XY plane.
    PlaneXy,
    /// G18: XZ plane.
    PlaneXz,
    /// G20: inches.
    Inch,
    /// G21: millimetres.
    Millimetre,
    /// G61: exact path.
    ExactPath,
    /// G64: path blending (P tolerance, Q naive-CAM tolerance).
    Blending,
    /// G90: absolute distances.
    Absolute,
    /// G91: incremental distances.
    Incremental,
    /// G92: rename the current position.
    SetPosition,
    /// G92.1: cancel the G92 offsets (the controller's unrebased positions again).
    ClearOffset,
    /// G93: inverse-time feed.
    InverseTime,
    /// G94: units-per-minute feed.
    UnitsPerMinute,
}

/// Groups of codes of which a line may hold at most one (RS274/NGC modal groups, with
/// G92 and G92.1 in the non-modal group; of the two, only G92 claims the axis words).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Group {
    Motion,
    LatheMode,
    Plane,
    Units,
    PathControl,
    Distance,
    NonModal,
    FeedMode,
    Spindle,
    Stop,
}

impl GCode {
    const ALL: [GCode; 16] = [
        GCode::Rapid,
        GCode::Linear,
        GCode::DiameterMode,
        GCode::RadiusMode,
        GCode::PlaneXy,
        GCode::PlaneXz,
        GCode::Inch,
        GCode::Millimetre,
        GCode::ExactPath,
        GCode::Blending,
        GCode::Absolute,
        GCode::Incremental,
        GCode::SetPosition,
        GCode::ClearOffset,
        GCode::InverseTime,
        GCode::UnitsPerMinute,
    ];

    /// The code's number in tenths, so that G92.1 has one too (G1 → 10, G92.1 → 921).
    pub fn tenths(self) -> u32 {
        match self {
            GCode::Rapid => 0,
            GCode::Linear => 10,
            GCode::DiameterMode => 70,
            GCode::RadiusMode => 80,
            GCode::PlaneXy => 170,
            GCode::PlaneXz => 180,
            GCode::Inch => 200,
            GCode::Millimetre => 210,
            GCode::ExactPath => 610,
            GCode::Blending => 640,
            GCode::Absolute => 900,
            GCode::Incremental => 910,
            GCode::SetPosition => 920,
            GCode::ClearOffset => 921,
            GCode::InverseTime => 930,
            GCode::UnitsPerMinute => 940,
        }
    }

    fn group(self) -> Group {
        match self {
            GCode::Rapid | GCode::Linear => Group::Motion,
            GCode::DiameterMode | GCode::RadiusMode => Group::LatheMode,
            GCode::PlaneXy | GCode::PlaneXz => Group::Plane,
            GCode::Inch | GCode::Millimetre => Group::Units,
            GCode::ExactPath | GCode::Blending => Group::PathControl,
            GCode::Absolute | GCode::Incremental => Group::Distance,
            GCode::SetPosition | GCode::ClearOffset => Group::NonModal,
            GCode::InverseTime | GCode::UnitsPerMinute => Group::FeedMode,
        }
    }
}

impl fmt::Display for GCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let tenths = self.tenths();
        match tenths % 10 {
            0 => write!(f, "G{}", tenths / 10),
            decimal => write!(f, "G{}.{decimal}", tenths / 10),
        }
    }
}

/// An M-code this reader knows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MCode {
    /// M2: program end.
    End,
    /// M3: spindle (the whirling ring) on, clockwise.
    SpindleOn,
    /// M5: spindle off.
    SpindleOff,
    /// M30: program end and rewind.
    EndRewind,
}

impl MCode {
    const ALL: [MCode; 4] = [
        MCode::End,
        MCode::SpindleOn,
        MCode::SpindleOff,
        MCode::EndRewind,
    ];

    /// The code's number (M3 → 3).
    pub fn number(self) -> u32 {
        match self {
            MCode::End => 2,
            MCode::SpindleOn => 3,
            MCode::SpindleOff => 5,
            MCode::EndRewind => 30,
        }
    }

    fn group(self) -> Group {
        match self {
            MCode::End | MCode::EndRewind => Group::Stop,
            MCode::SpindleOn | MCode::SpindleOff => Group::Spindle,
        }
    }
}

impl fmt::Display for MCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "M{}", self.number())
    }
}

/// What a word says.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum WordKind {
    /// `N`: line number.
    LineNumber(u32),
    /// A G-code.
    G(GCode),
    /// An M-code.
    M(MCode),
    /// `X`, as written (diameter or radius, mm or inch, absolute or incremental).
    X(f64),
    /// `Y`, as written.
    Y(f64),
    /// `Z`, as written.
    Z(f64),
    /// `C`, degrees, as written.
    C(f64),
    /// `F`: feed (units per minute in G94, 1/minutes in G93).
    F(f64),
    /// `S`: spindle speed, rpm.
    S(f64),
    /// `P`: G64 path tolerance.
    P(f64),
    /// `Q`: G64 naive-CAM tolerance.
    Q(f64),
}

impl WordKind {
    fn letter(&self) -> char {
        match self {
            WordKind::LineNumber(_) => 'N',
            WordKind::G(_) => 'G',
            WordKind::M(_) => 'M',
            WordKind::X(_) => 'X',
            WordKind::Y(_) => 'Y',
            WordKind::Z(_) => 'Z',
            WordKind::C(_) => 'C',
            WordKind::F(_) => 'F',
            WordKind::S(_) => 'S',
            WordKind::P(_) => 'P',
            WordKind::Q(_) => 'Q',
        }
    }
}

/// A word of a line and where it starts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Word {
    /// 1-based column (in characters) of the word's letter.
    pub column: usize,
    /// What the word says.
    pub kind: WordKind,
}

/// One source line.
#[derive(Debug, Clone, PartialEq)]
pub struct ParsedLine {
    /// 1-based line number in the source text.
    pub number: usize,
    /// The line is a `%` program delimiter (LinuxCNC); it then has no words.
    pub percent: bool,
    /// The words, in source order.
    pub words: Vec<Word>,
    /// The comments' texts: a `( )` comment exactly as written between the parentheses,
    /// a `;` comment trimmed.
    pub comments: Vec<String>,
}

/// Where a text could not be read, and why.
#[derive(Debug, Clone, PartialEq, Error)]
#[error("line {line}, column {column}: {kind}")]
pub struct ParseError {
    /// 1-based line number.
    pub line: usize,
    /// 1-based column, in characters, of the offending character or word.
    pub column: usize,
    /// What is wrong.
    pub kind: ParseErrorKind,
}

/// What is wrong with a line.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ParseErrorKind {
    /// A character that starts no word or comment.
    #[error("unexpected character {0:?}")]
    UnexpectedCharacter(char),
    /// A word letter outside the subset.
    #[error("unknown word {0} (this reader takes N G M X Y Z C F S P Q)")]
    UnknownWord(char),
    /// A letter with no number after it.
    #[error("number missing after {0}")]
    MissingNumber(char),
    /// `(` without `)`.
    #[error("comment is not closed")]
    UnclosedComment,
    /// `(` inside a comment.
    #[error("comment inside a comment")]
    NestedComment,
    /// `%` on a line with something else.
    #[error("'%' must stand alone on its line")]
    PercentNotAlone,
    /// A G- or M-code outside the subset, as written.
    #[error("unsupported code {0}")]
    UnsupportedCode(String),
    /// An `N` word that is not a whole number in 0..=4294967295, as written.
    #[error("{0} is not a line number (a whole number from 0 to 4294967295)")]
    BadLineNumber(String),
    /// An `N` word after another word.
    #[error("the line number must be the first word")]
    LineNumberNotFirst,
    /// A letter given twice.
    #[error("{0} word given twice")]
    RepeatedWord(char),
    /// Two motion codes in one block.
    #[error("two motion codes in one block: {0} and {1}")]
    TwoMotionCodes(GCode, GCode),
    /// Two codes of one modal group.
    #[error("{0} and {1} are in the same modal group")]
    ModalConflict(String, String),
    /// G92 and a motion code both want the axis words.
    #[error("G92 and {0} in one block both use the axis words")]
    AxisWordConflict(GCode),
    /// `P` or `Q` with no G64.
    #[error("{0} word without G64 to use it")]
    UnusedWord(char),
    /// A negative F or S.
    #[error("{0} must not be negative")]
    Negative(char),
    /// Axis words with no motion mode set yet.
    #[error("axis words but no motion mode (no G0 or G1 so far)")]
    NoMotionMode,
    /// G92 without axis words.
    #[error("G92 without an axis word")]
    G92WithoutAxis,
    /// G92 on a linear axis.
    #[error("G92 {0}: only C can be renamed in a whirling program")]
    G92OnLinearAxis(char),
    /// G92.1 after G92 renamed a C that no line had positioned.
    #[error(
        "G92.1 after G92 renamed C before any line positioned it: where C stands afterwards \
         is unknown, so the program has no continuous C (position C before renaming it)"
    )]
    LostC,
    /// A Y word on a motion.
    #[error("Y word: a whirling machine has no Y axis")]
    YAxis,
    /// G1 in G93 without F on its line.
    #[error("G1 in inverse-time mode (G93) without F on its line")]
    InverseTimeWithoutFeed,
    /// G1 in G94 with no feed rate set.
    #[error("G1 in units-per-minute mode (G94) with no F since the program start or the last feed-mode change")]
    FeedUndefined,
    /// A zero feed on a G1.
    #[error("G1 with a zero feed rate")]
    ZeroFeed,
    /// A move that needs a position the program never set.
    #[error("{0} position unknown: the program has not positioned {0} yet (needed for G91 or a G93 move)")]
    UnknownPosition(Axis),
    /// M3 with no speed, or speed zero.
    #[error("M3 without a spindle speed S above zero")]
    SpindleSpeedMissing,
}

/// Parses a whole text into lines; see [`parse_line`]. Lines end at `\n` or `\r\n`.
pub fn parse(text: &str) -> Result<Vec<ParsedLine>, ParseError> {
    text.lines()
        .enumerate()
        .map(|(i, line)| parse_line(line, i + 1))
        .collect()
}

/// Parses the text and builds the program; see [`to_program`].
pub fn read_program(text: &str, x_diameter: bool) -> Result<Program, ParseError> {
    read_program_with_lines(text, x_diameter).map(|(program, _)| program)
}

/// [`read_program`], with the 1-based text line of every block, so that what is said about
/// a block (a limit it breaks) can name the line.
pub fn read_program_with_lines(
    text: &str,
    x_diameter: bool,
) -> Result<(Program, Vec<usize>), ParseError> {
    to_program_with_lines(&parse(text)?, x_diameter)
}

/// Parses one line (without its line end); `number` is its 1-based line number, used
/// in errors and kept in the result.
pub fn parse_line(text: &str, number: usize) -> Result<ParsedLine, ParseError> {
    let error = |column: usize, kind: ParseErrorKind| ParseError {
        line: number,
        column,
        kind,
    };
    let mut line = ParsedLine {
        number,
        percent: false,
        words: Vec::new(),
        comments: Vec::new(),
    };
    if text.trim() == "%" {
        line.percent = true;
        return Ok(line);
    }
    let chars: Vec<char> = text.chars().collect();
    let mut i = 0;
    while i < chars.len() {
        let column = i + 1;
        match chars[i] {
            ' ' | '\t' => i += 1,
            '(' => {
                let mut end = i + 1;
                loop {
                    match chars.get(end) {
                        None => return Err(error(column, ParseErrorKind::UnclosedComment)),
                        Some(')') => break,
                        Some('(') => return Err(error(end + 1, ParseErrorKind::NestedComment)),
                        Some(_) => end += 1,
                    }
                }
                line.comments.push(chars[i + 1..end].iter().collect());
                i = end + 1;
            }
            ';' => {
                let rest: String = chars[i + 1..].iter().collect();
                line.comments.push(rest.trim().to_owned());
                break;
            }
            '%' => return Err(error(column, ParseErrorKind::PercentNotAlone)),
            ch if ch.is_ascii_alphabetic() => {
                let letter = ch.to_ascii_uppercase();
                if !"NGMXYZCFSPQ".contains(letter) {
                    return Err(error(column, ParseErrorKind::UnknownWord(letter)));
                }
                let (raw, next) = read_number(&chars, i + 1)
                    .ok_or_else(|| error(column, ParseErrorKind::MissingNumber(letter)))?;
                let kind = word_kind(letter, &raw).map_err(|kind| error(column, kind))?;
                line.words.push(Word { column, kind });
                i = next;
            }
            other => return Err(error(column, ParseErrorKind::UnexpectedCharacter(other))),
        }
    }
    check_line(&line).map_err(|(column, kind)| error(column, kind))?;
    Ok(line)
}

/// Reads the number starting at `start` (after optional blanks): sign, digits, one
/// optional point; returns its text and the index after it, `None` without a digit.
fn read_number(chars: &[char], start: usize) -> Option<(String, usize)> {
    let mut i = start;
    while matches!(chars.get(i), Some(' ' | '\t')) {
        i += 1;
    }
    let mut text = String::new();
    if let Some(&sign @ ('+' | '-')) = chars.get(i) {
        text.push(sign);
        i += 1;
    }
    let mut digits = 0;
    let mut point = false;
    while let Some(&ch) = chars.get(i) {
        match ch {
            '0'..='9' => digits += 1,
            '.' if !point => point = true,
            _ => break,
        }
        text.push(ch);
        i += 1;
    }
    (digits > 0).then_some((text, i))
}

fn word_kind(letter: char, raw: &str) -> Result<WordKind, ParseErrorKind> {
    // `raw` is sign, digits and at most one point: always a valid Rust float.
    let value: f64 = raw
        .parse()
        .map_err(|_| ParseErrorKind::MissingNumber(letter))?;
    let code = || -> Option<u64> {
        // Codes are whole or have one decimal (G92.1); compare in tenths. The cast
        // saturates, and no supported code or line number is anywhere near u64::MAX.
        let tenths = value * 10.0;
        (value >= 0.0 && !raw.starts_with(['+', '-']) && (tenths - tenths.round()).abs() < 1e-6)
            .then_some(tenths.round() as u64)
    };
    let unsupported = || ParseErrorKind::UnsupportedCode(format!("{letter}{raw}"));
    Ok(match letter {
        'N' => {
            let n = code()
                .filter(|tenths| tenths % 10 == 0)
                .and_then(|tenths| u32::try_from(tenths / 10).ok())
                .ok_or_else(|| ParseErrorKind::BadLineNumber(format!("N{raw}")))?;
            WordKind::LineNumber(n)
        }
        'G' => WordKind::G(
            code()
                .and_then(|t| GCode::ALL.into_iter().find(|g| u64::from(g.tenths()) == t))
                .ok_or_else(unsupported)?,
        ),
        'M' => WordKind::M(
            code()
                .and_then(|t| {
                    MCode::ALL
                        .into_iter()
                        .find(|m| u64::from(m.number()) * 10 == t)
                })
                .ok_or_else(unsupported)?,
        ),
        'X' => WordKind::X(value),
        'Y' => WordKind::Y(value),
        'Z' => WordKind::Z(value),
        'C' => WordKind::C(value),
        'F' | 'S' if value < 0.0 => return Err(ParseErrorKind::Negative(letter)),
        'F' => WordKind::F(value),
        'S' => WordKind::S(value),
        'P' => WordKind::P(value),
        _ => WordKind::Q(value),
    })
}

/// The checks a controller makes within one line; errors carry the word's column.
fn check_line(line: &ParsedLine) -> Result<(), (usize, ParseErrorKind)> {
    let mut groups: Vec<(Group, String, usize, Option<GCode>)> = Vec::new();
    let mut letters: Vec<char> = Vec::new();
    for (index, word) in line.words.iter().enumerate() {
        let (group, text, gcode) = match word.kind {
            WordKind::LineNumber(_) if index > 0 => {
                return Err((word.column, ParseErrorKind::LineNumberNotFirst))
            }
            WordKind::G(g) => (g.group(), g.to_string(), Some(g)),
            WordKind::M(m) => (m.group(), m.to_string(), None),
            ref other => {
                let letter = other.letter();
                if letters.contains(&letter) {
                    return Err((word.column, ParseErrorKind::RepeatedWord(letter)));
                }
                letters.push(letter);
                continue;
            }
        };
        if let Some((_, earlier, _, earlier_g)) = groups.iter().find(|(g, ..)| *g == group) {
            let kind = match (earlier_g, gcode) {
                (Some(a), Some(b)) if group == Group::Motion => {
                    ParseErrorKind::TwoMotionCodes(*a, b)
                }
                _ => ParseErrorKind::ModalConflict(earlier.clone(), text),
            };
            return Err((word.column, kind));
        }
        groups.push((group, text, word.column, gcode));
    }
    let has = |g: GCode| groups.iter().any(|(_, _, _, code)| *code == Some(g));
    if has(GCode::SetPosition) {
        if let Some((_, _, column, Some(motion))) =
            groups.iter().find(|(g, ..)| *g == Group::Motion)
        {
            return Err((*column, ParseErrorKind::AxisWordConflict(*motion)));
        }
    }
    if !has(GCode::Blending) {
        for word in &line.words {
            if let WordKind::P(_) | WordKind::Q(_) = word.kind {
                return Err((word.column, ParseErrorKind::UnusedWord(word.kind.letter())));
            }
        }
    }
    Ok(())
}

/// The modal state of [`to_program`].
struct State {
    inch: bool,
    incremental: bool,
    inverse_time: bool,
    diameter: bool,
    motion: Option<GCode>,
    /// Last F in G94, as written (units per minute of the units in force at the move).
    feed: Option<f64>,
    rpm: Option<f64>,
    spindle_on: bool,
    /// Controller position: X radius mm, Z mm, C degrees (in the G92-renamed frame).
    position: [Option<f64>; 3],
    /// The program's continuous C minus the controller's (G92-renamed) C: zero at the
    /// start (no offset is taken to be active then).
    c_offset: f64,
    /// A G92 renamed a C whose position was unknown, anchoring the continuous frame there.
    c_anchored: bool,
}

/// Builds the program a controller would run from `lines`, starting in the modes the
/// writers' preamble sets and grbl starts in (G21 G90 G94, no motion mode) and with X
/// read as a diameter when `x_diameter` (until G7/G8 says otherwise). Positions are
/// absolute mm (X a radius) and degrees, C in one continuous frame (G92 undone); see the
/// module docs.
pub fn to_program(lines: &[ParsedLine], x_diameter: bool) -> Result<Program, ParseError> {
    to_program_with_lines(lines, x_diameter).map(|(program, _)| program)
}

/// [`to_program`], with the line number of every block.
fn to_program_with_lines(
    lines: &[ParsedLine],
    x_diameter: bool,
) -> Result<(Program, Vec<usize>), ParseError> {
    let mut state = State {
        inch: false,
        incremental: false,
        inverse_time: false,
        diameter: x_diameter,
        motion: None,
        feed: None,
        rpm: None,
        spindle_on: false,
        position: [None; 3],
        c_offset: 0.0,
        c_anchored: false,
    };
    let mut program = Program::default();
    let mut block_lines = Vec::new();
    for line in lines {
        let ended = run_line(line, &mut state, &mut program.moves).map_err(|(column, kind)| {
            ParseError {
                line: line.number,
                column,
                kind,
            }
        })?;
        block_lines.resize(program.moves.len(), line.number);
        if ended {
            break;
        }
    }
    Ok((program, block_lines))
}

/// Runs one line in RS274/NGC order of execution; `Ok(true)` at program end.
fn run_line(
    line: &ParsedLine,
    state: &mut State,
    blocks: &mut Vec<Move>,
) -> Result<bool, (usize, ParseErrorKind)> {
    let has_g = |g: GCode| line.words.iter().find(|w| w.kind == WordKind::G(g));
    let has_m = |m: MCode| line.words.iter().find(|w| w.kind == WordKind::M(m));
    let value = |letter: char| {
        line.words.iter().find_map(|w| match w.kind {
            WordKind::X(v)
            | WordKind::Y(v)
            | WordKind::Z(v)
            | WordKind::C(v)
            | WordKind::F(v)
            | WordKind::S(v)
                if w.kind.letter() == letter =>
            {
                Some((v, w.column))
            }
            _ => None,
        })
    };

    blocks.extend(line.comments.iter().cloned().map(Move::Comment));

    // Feed mode, then F: a feed-mode change forgets the units-per-minute feed, as grbl does.
    let mode_change = if has_g(GCode::InverseTime).is_some() {
        Some(true)
    } else if has_g(GCode::UnitsPerMinute).is_some() {
        Some(false)
    } else {
        None
    };
    if let Some(inverse_time) = mode_change {
        if inverse_time != state.inverse_time {
            state.feed = None;
        }
        state.inverse_time = inverse_time;
    }
    let f = value('F');
    if let (Some((f, _)), false) = (f, state.inverse_time) {
        state.feed = Some(f);
    }

    // Spindle speed, then spindle on/off.
    if let Some((s, _)) = value('S') {
        state.rpm = Some(s);
    }
    if let Some(word) = has_m(MCode::SpindleOn) {
        let rpm = state
            .rpm
            .filter(|&rpm| rpm > 0.0)
            .ok_or((word.column, ParseErrorKind::SpindleSpeedMissing))?;
        state.spindle_on = true;
        blocks.push(Move::SpindleOn { rpm });
    } else if has_m(MCode::SpindleOff).is_some() {
        state.spindle_on = false;
        blocks.push(Move::SpindleOff);
    } else if let (Some((rpm, column)), true) = (value('S'), state.spindle_on) {
        if rpm <= 0.0 {
            return Err((column, ParseErrorKind::SpindleSpeedMissing));
        }
        blocks.push(Move::SpindleOn { rpm });
    }

    // Lathe mode, units, distance mode (plane and path control change nothing here).
    if has_g(GCode::DiameterMode).is_some() {
        state.diameter = true;
    }
    if has_g(GCode::RadiusMode).is_some() {
        state.diameter = false;
    }
    if has_g(GCode::Inch).is_some() {
        state.inch = true;
    }
    if has_g(GCode::Millimetre).is_some() {
        state.inch = false;
    }
    if has_g(GCode::Incremental).is_some() {
        state.incremental = true;
    }
    if has_g(GCode::Absolute).is_some() {
        state.incremental = false;
    }

    let axis_words: Vec<&Word> = line
        .words
        .iter()
        .filter(|w| {
            matches!(
                w.kind,
                WordKind::X(_) | WordKind::Y(_) | WordKind::Z(_) | WordKind::C(_)
            )
        })
        .collect();

    // G92.1 (never on a line with G92, its modal group): cancel the offset, so the
    // controller's C is the unrebased one; axis words on the line are a move after it.
    if let Some(g92_1) = has_g(GCode::ClearOffset) {
        if state.c_anchored {
            return Err((g92_1.column, ParseErrorKind::LostC));
        }
        state.position[2] = state.position[2].map(|c| c + state.c_offset);
        state.c_offset = 0.0;
    }

    // G92: rename the current position; C only, and never incremental.
    if let Some(g92) = has_g(GCode::SetPosition) {
        if axis_words.is_empty() {
            return Err((g92.column, ParseErrorKind::G92WithoutAxis));
        }
        for word in &axis_words {
            match word.kind {
                WordKind::C(c) => {
                    match state.position[2] {
                        Some(old) => state.c_offset += old - c,
                        None => {
                            state.c_offset = 0.0;
                            state.c_anchored = true;
                        }
                    }
                    state.position[2] = Some(c);
                }
                other => {
                    return Err((word.column, ParseErrorKind::G92OnLinearAxis(other.letter())))
                }
            }
        }
    } else {
        let motion_word = line
            .words
            .iter()
            .find(|w| matches!(w.kind, WordKind::G(GCode::Rapid | GCode::Linear)));
        if let Some(&Word {
            kind: WordKind::G(g),
            ..
        }) = motion_word
        {
            state.motion = Some(g);
        }
        if let Some(first) = axis_words.first() {
            let motion = state
                .motion
                .ok_or((first.column, ParseErrorKind::NoMotionMode))?;
            let column = motion_word.map_or(first.column, |w| w.column);
            let block = motion_block(state, motion, &axis_words, f, column)?;
            blocks.push(block);
        }
    }

    Ok(has_m(MCode::End).is_some() || has_m(MCode::EndRewind).is_some())
}

/// The block of a motion line, updating the controller position.
fn motion_block(
    state: &mut State,
    motion: GCode,
    axis_words: &[&Word],
    f: Option<(f64, usize)>,
    column: usize,
) -> Result<Move, (usize, ParseErrorKind)> {
    let unit = if state.inch { MM_PER_INCH } else { 1.0 };
    let mut targets: [Option<f64>; 3] = [None; 3];
    for word in axis_words {
        let (slot, axis, written) = match word.kind {
            WordKind::X(v) => (
                0,
                Axis::X,
                v * unit / if state.diameter { 2.0 } else { 1.0 },
            ),
            WordKind::Z(v) => (1, Axis::Z, v * unit),
            WordKind::C(v) => (2, Axis::C, v),
            _ => return Err((word.column, ParseErrorKind::YAxis)),
        };
        targets[slot] = Some(if state.incremental {
            let from =
                state.position[slot].ok_or((word.column, ParseErrorKind::UnknownPosition(axis)))?;
            from + written
        } else {
            written
        });
    }
    let continuous = |c: f64| c + state.c_offset;
    let block = match motion {
        GCode::Rapid => Move::Rapid {
            x: targets[0],
            z: targets[1],
            c: targets[2].map(continuous),
        },
        _ if state.inverse_time => {
            let (per_minute, f_column) =
                f.ok_or((column, ParseErrorKind::InverseTimeWithoutFeed))?;
            if per_minute <= 0.0 {
                return Err((f_column, ParseErrorKind::ZeroFeed));
            }
            let mut full = [0.0; 3];
            for (slot, axis) in Axis::ALL.into_iter().enumerate() {
                full[slot] = targets[slot]
                    .or(state.position[slot])
                    .ok_or((column, ParseErrorKind::UnknownPosition(axis)))?;
            }
            Move::Linked {
                x: full[0],
                z: full[1],
                c: continuous(full[2]),
                minutes: 1.0 / per_minute,
            }
        }
        _ => {
            let feed = state.feed.ok_or((column, ParseErrorKind::FeedUndefined))?;
            if feed <= 0.0 {
                return Err((f.map_or(column, |(_, c)| c), ParseErrorKind::ZeroFeed));
            }
            Move::Feed {
                x: targets[0],
                z: targets[1],
                c: targets[2].map(continuous),
                feed: feed * unit,
            }
        }
    };
    for (slot, target) in targets.into_iter().enumerate() {
        if target.is_some() {
            state.position[slot] = target;
        }
    }
    Ok(block)
}

#[cfg(test)]
mod tests;
