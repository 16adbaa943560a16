//! Writers: a [`Program`] → G-code text for one controller dialect. The program is in one
//! continuous frame, and so is the text: C is written as it is, never renamed with G92.
//!
//! Both dialects get the same shape of program, chosen so that what the controller
//! executes is what the program model says:
//!
//! - a preamble that sets every mode the program relies on (`G21 G90 G94`, the X mode,
//!   and on LinuxCNC the path-control mode) instead of trusting the controller's state;
//! - `G93`/`G94` written only when the feed mode changes, and `F` on every `G1` line:
//!   in inverse time F belongs to its block, and after a G93→G94 change some controllers
//!   (grbl) forget the units-per-minute feed;
//! - axis words left out when their *written text* did not change, so the position the
//!   controller holds is exactly what was last written; a move whose words all equal
//!   the written position produces no line (the controller would not move either).
//! - `G0`/`G1` on every motion line (no reliance on the modal motion code);
//! - feed rates rounded down, so rounding never makes a move faster than planned.
//!
//! grblHAL: every line numbered with an N word (its line in the file, so `Ln:` in status
//! reports names the file line), `\n` line endings, no line longer than the controller's line buffer,
//! comments in parentheses with only the characters grbl ignores there (its serial
//! driver acts on `?`, `!`, `~` and bytes above 0x7F wherever they appear), and at most
//! nine digits per number (grblHAL's number reader drops the rest). LinuxCNC: `%` first
//! and last, and comments that cannot be mistaken for its active comments (`(MSG,`,
//! `(DEBUG,`, `(PY,` …).

use thiserror::Error;

use super::format::{format_number, format_number_down, format_significant_down, MAX_DECIMALS};
use crate::config::machine::{Axis, Dialect, MachineProfile, MIN_LINE_LENGTH};
use crate::program::{Move, Position, Program};

/// Significant digits of every F word, rounded down: the written feed is below the
/// planned one by less than 10⁻⁵ relative, so an inverse-time move lasts its planned
/// time to better than 1e-4 and never runs faster.
pub const FEED_DIGITS: u32 = 6;

/// Decimals of the S word (ring speed, rpm).
const RPM_DECIMALS: u32 = 1;

/// Prefix that disarms a LinuxCNC comment which would otherwise be read as an active
/// comment (`(MSG,…)`, `(DEBUG,…)`, `(PY,…)`, …).
const DISARM_PREFIX: &str = "note: ";

/// How a program is written for one controller; [`crate::config::machine::MachineProfile`]
/// gives the machine's part of it.
#[derive(Debug, Clone, PartialEq)]
pub struct PostSettings {
    /// Controller language.
    pub dialect: Dialect,
    /// Decimals of X and Z words (see [`super::format::decimals_for`]); at most
    /// [`MAX_DECIMALS`].
    pub linear_decimals: u32,
    /// Decimals of C words, degrees; at most [`MAX_DECIMALS`].
    pub angular_decimals: u32,
    /// The controller's X is a diameter: X words are written as 2·X (and the preamble
    /// selects G7). X words still get `linear_decimals`, so the radius is rounded to half
    /// the written unit.
    pub x_diameter: bool,
    /// LinuxCNC path blending tolerance, mm: written as `G64 P<tol> Q0` (rounded down);
    /// `None` writes `G61` (exact path). Must be `None` for grblHAL, which does not blend.
    pub blend_tolerance_mm: Option<f64>,
    /// Longest line the controller accepts, in characters, not counting the line end
    /// (grblHAL: 256); at least [`MIN_LINE_LENGTH`].
    pub max_line_length: usize,
}

impl PostSettings {
    /// The post settings of `machine`, with decimals the planner chose from its error
    /// budget (see [`super::format::decimals_for`]).
    pub fn for_machine(
        machine: &MachineProfile,
        linear_decimals: u32,
        angular_decimals: u32,
    ) -> PostSettings {
        PostSettings {
            dialect: machine.dialect,
            linear_decimals,
            angular_decimals,
            x_diameter: machine.x_diameter(),
            blend_tolerance_mm: machine.blend_tolerance_mm,
            max_line_length: machine.max_line_length,
        }
    }
}

/// Why a program could not be written.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum PostError {
    /// A decimals setting above [`MAX_DECIMALS`].
    #[error("{which} = {decimals} is above the maximum of {MAX_DECIMALS} decimals")]
    TooManyDecimals {
        /// `"linear_decimals"` or `"angular_decimals"`.
        which: &'static str,
        /// The setting.
        decimals: u32,
    },
    /// `max_line_length` below [`MIN_LINE_LENGTH`].
    #[error("max_line_length {0} is below the minimum of {MIN_LINE_LENGTH} characters")]
    LineLengthTooSmall(usize),
    /// A blend tolerance outside 0.000001..=1 mm (or not a number).
    #[error("blend tolerance {0} mm is outside 0.000001..=1 mm")]
    BadBlendTolerance(f64),
    /// A blend tolerance for a controller that does not blend.
    #[error(
        "grblHAL follows the polyline exactly and has no G64: blend_tolerance_mm must be absent"
    )]
    BlendingUnsupported,
    /// A move whose values cannot be written (not finite, a zero or negative time,
    /// feed or speed).
    #[error("move {index} (not a file line): {problem}")]
    InvalidMove {
        /// Index of the move in [`Program::moves`].
        index: usize,
        /// What is wrong.
        problem: String,
    },
    /// A motion line longer than the controller accepts.
    #[error(
        "move {index} (not a file line): its line is {length} characters, \
         over the controller's limit of {max}: {line}"
    )]
    LineTooLong {
        /// Index of the move in [`Program::moves`].
        index: usize,
        /// The line.
        line: String,
        /// Its length in characters.
        length: usize,
        /// The limit.
        max: usize,
    },
    /// A line longer than the controller accepts once the provenance header is written
    /// (a provenance comment with a long path, or a line whose number grew by a digit).
    #[error(
        "with the provenance header, the line \"{line}\" is {length} characters, over the \
         controller's limit of {max} (a shorter path to the job or the machine profile \
         shortens it)"
    )]
    HeaderTooLong {
        /// The line.
        line: String,
        /// Its length in characters.
        length: usize,
        /// The limit.
        max: usize,
    },
    /// A number with more digits than the controller reads.
    #[error(
        "move {index} (not a file line): {word} has {digits} digits, but \
         the controller reads only the first {max} digits of a number"
    )]
    TooManyDigits {
        /// Index of the move in [`Program::moves`].
        index: usize,
        /// The word, e.g. `X123456.7891`.
        word: String,
        /// Its digit count.
        digits: usize,
        /// The controller's limit.
        max: usize,
    },
}

/// Writes `program` as G-code text for `settings.dialect`; see the module docs for what
/// the text guarantees.
pub fn write(program: &Program, settings: &PostSettings) -> Result<String, PostError> {
    check_settings(settings)?;
    let mut writer = Writer {
        settings,
        out: String::new(),
        written: [None, None, None],
        inverse_time: false,
        spindle_on: false,
        lines: 0,
    };
    writer.preamble();
    for (index, action) in program.moves.iter().enumerate() {
        writer.write_move(index, action)?;
    }
    writer.epilogue();
    Ok(writer.out)
}

fn check_settings(settings: &PostSettings) -> Result<(), PostError> {
    for (which, decimals) in [
        ("linear_decimals", settings.linear_decimals),
        ("angular_decimals", settings.angular_decimals),
    ] {
        if decimals > MAX_DECIMALS {
            return Err(PostError::TooManyDecimals { which, decimals });
        }
    }
    if settings.max_line_length < MIN_LINE_LENGTH {
        return Err(PostError::LineLengthTooSmall(settings.max_line_length));
    }
    if let Some(tolerance) = settings.blend_tolerance_mm {
        if settings.dialect == Dialect::GrblHal {
            return Err(PostError::BlendingUnsupported);
        }
        // 1 mm is far above any whirling budget; the cap keeps the G64 line short.
        if !(tolerance.is_finite() && (1e-6..=1.0).contains(&tolerance)) {
            return Err(PostError::BadBlendTolerance(tolerance));
        }
    }
    Ok(())
}

/// Replaces what a controller would not take inside a parenthesized comment: nested
/// parentheses become brackets; control characters spaces; anything outside printable
/// ASCII, and for grblHAL its real-time command characters, `_`.
fn sanitize_comment(text: &str, dialect: Dialect) -> String {
    text.chars()
        .map(|ch| match ch {
            '(' => '[',
            ')' => ']',
            '?' | '!' | '~' if dialect == Dialect::GrblHal => '_',
            ch if ch.is_ascii_control() => ' ',
            ch if ch.is_ascii() => ch,
            _ => '_',
        })
        .collect()
}

/// LinuxCNC treats a comment starting with a word and a comma (`MSG,`, `DEBUG,`,
/// `PRINT,`, `LOG,`, `PY,`, …) as a command; such comments get [`DISARM_PREFIX`].
fn is_active_linuxcnc_comment(text: &str) -> bool {
    match text.trim_start().split_once(',') {
        Some((head, _)) => {
            let head = head.trim_end();
            !head.is_empty()
                && head
                    .chars()
                    .all(|ch| ch.is_ascii_alphanumeric() || ch == '_')
        }
        None => false,
    }
}

struct Writer<'a> {
    settings: &'a PostSettings,
    out: String,
    /// Text last written for X, Z, C (as the controller holds it).
    written: [Option<String>; 3],
    inverse_time: bool,
    spindle_on: bool,
    /// Lines written so far.
    lines: usize,
}

/// The longest line-number prefix, `N9999999 `: grbl reads N up to 9 999 999.
const MAX_NUMBER_PREFIX: usize = 9;

impl Writer<'_> {
    /// Whether every line carries its line number as an N word. grblHAL reports the N word
    /// of the block executing (`Ln:` in status reports): with the file's line numbers
    /// there, a sender knows exactly which line runs, so a stopped job resumes at the
    /// right line and the executed-path log names file lines.
    fn numbered(&self) -> bool {
        self.settings.dialect == Dialect::GrblHal
    }

    /// The length of the next line's number prefix (`N12 `).
    fn prefix_length(&self) -> usize {
        if self.numbered() {
            (self.lines + 1).to_string().len() + 2
        } else {
            0
        }
    }

    fn line(&mut self, line: &str) {
        self.lines += 1;
        if self.numbered() {
            self.out.push_str(&format!("N{} ", self.lines));
        }
        self.out.push_str(line);
        self.out.push('\n');
    }

    /// Writes the line of move `index`, checking it fits the controller's line buffer.
    fn move_line(&mut self, index: usize, line: String) -> Result<(), PostError> {
        let length = line.chars().count() + self.prefix_length();
        let max = self.settings.max_line_length;
        if length > max {
            return Err(PostError::LineTooLong {
                index,
                line,
                length,
                max,
            });
        }
        self.line(&line);
        Ok(())
    }

    /// `letter` + `number`, checked against the controller's digit limit.
    fn word(&self, index: usize, letter: char, number: &str) -> Result<String, PostError> {
        let word = format!("{letter}{number}");
        let digits = number.chars().filter(char::is_ascii_digit).count();
        match self.settings.dialect.max_number_digits() {
            Some(max) if digits > max => Err(PostError::TooManyDigits {
                index,
                word,
                digits,
                max,
            }),
            _ => Ok(word),
        }
    }

    fn preamble(&mut self) {
        let dialect = self.settings.dialect;
        if dialect == Dialect::LinuxCnc {
            self.line("%");
        }
        // G7/G8 select how X words are read (diameter/radius). LinuxCNC always knows them;
        // grblHAL only in lathe mode, which a diameter-mode grblHAL machine is in, while a
        // radius-mode one may not be (and then reads X as a radius anyway).
        let x_mode = match (self.settings.x_diameter, dialect) {
            (true, _) => " G7",
            (false, Dialect::LinuxCnc) => " G8",
            (false, Dialect::GrblHal) => "",
        };
        self.line(&format!("G21 G90 G94{x_mode}"));
        if dialect == Dialect::LinuxCnc {
            match self.settings.blend_tolerance_mm {
                Some(tolerance) => {
                    // At least 1e-6 (checked), so P is never written as 0.
                    let p = format_number_down(tolerance, MAX_DECIMALS);
                    // Q0: LinuxCNC's naive-CAM segment merger would only merge the X/Z
                    // part of linked moves; turn it off.
                    self.line(&format!("G64 P{p} Q0"));
                }
                None => self.line("G61"),
            }
        }
    }

    fn epilogue(&mut self) {
        if self.spindle_on {
            self.line("M5");
        }
        if self.inverse_time {
            self.line("G94");
        }
        self.line("M2");
        if self.settings.dialect == Dialect::LinuxCnc {
            self.line("%");
        }
    }

    fn comment(&mut self, text: &str) {
        let dialect = self.settings.dialect;
        let clean = sanitize_comment(text, dialect);
        let reserve = if dialect == Dialect::LinuxCnc {
            DISARM_PREFIX.len()
        } else {
            MAX_NUMBER_PREFIX
        };
        let chunk_length = self.settings.max_line_length - 2 - reserve;
        let chars: Vec<char> = clean.chars().collect();
        let chunks: Vec<String> = if chars.is_empty() {
            vec![String::new()]
        } else {
            chars
                .chunks(chunk_length)
                .map(|c| c.iter().collect())
                .collect()
        };
        for chunk in chunks {
            let prefix = if dialect == Dialect::LinuxCnc && is_active_linuxcnc_comment(&chunk) {
                DISARM_PREFIX
            } else {
                ""
            };
            self.line(&format!("({prefix}{chunk})"));
        }
    }

    /// The axis words of a move to `target`, leaving out axes the move does not move
    /// and those whose text equals what was last written; updates the written position.
    fn axis_words(&mut self, index: usize, target: Position) -> Result<Vec<String>, PostError> {
        let mut words = Vec::new();
        for (slot, axis) in Axis::ALL.into_iter().enumerate() {
            let Some(value) = target.get(axis) else {
                continue;
            };
            if !value.is_finite() {
                return Err(invalid(
                    index,
                    format!("{axis} target {value} is not finite"),
                ));
            }
            let (written, decimals) = match axis {
                Axis::X if self.settings.x_diameter => (2.0 * value, self.settings.linear_decimals),
                Axis::X | Axis::Z => (value, self.settings.linear_decimals),
                Axis::C => (value, self.settings.angular_decimals),
            };
            let text = format_number(written, decimals);
            if self.written[slot].as_deref() != Some(text.as_str()) {
                words.push(self.word(index, axis.letter(), &text)?);
                self.written[slot] = Some(text);
            }
        }
        Ok(words)
    }

    fn write_move(&mut self, index: usize, action: &Move) -> Result<(), PostError> {
        match *action {
            Move::Comment(ref text) => self.comment(text),
            Move::Rapid { x, z, c } => {
                let words = self.axis_words(index, Position { x, z, c })?;
                if !words.is_empty() {
                    self.move_line(index, format!("G0 {}", words.join(" ")))?;
                }
            }
            Move::Feed { x, z, c, feed } => {
                if !(feed.is_finite() && feed > 0.0) {
                    return Err(invalid(
                        index,
                        format!("feed {feed} mm/min is not above zero"),
                    ));
                }
                let f = self.word(index, 'F', &format_significant_down(feed, FEED_DIGITS))?;
                let words = self.axis_words(index, Position { x, z, c })?;
                if !words.is_empty() {
                    let mode = if self.inverse_time { "G94 " } else { "" };
                    self.inverse_time = false;
                    self.move_line(index, format!("{mode}G1 {} {f}", words.join(" ")))?;
                }
            }
            Move::Linked { x, z, c, minutes } => {
                let per_minute = 1.0 / minutes;
                if !(minutes > 0.0 && per_minute.is_finite() && per_minute > 0.0) {
                    return Err(invalid(
                        index,
                        format!("move time {minutes} min gives no finite inverse-time F"),
                    ));
                }
                let f = self.word(
                    index,
                    'F',
                    &format_significant_down(per_minute, FEED_DIGITS),
                )?;
                let words = self.axis_words(index, Position::known(x, z, c))?;
                if !words.is_empty() {
                    let mode = if self.inverse_time { "" } else { "G93 " };
                    self.inverse_time = true;
                    self.move_line(index, format!("{mode}G1 {} {f}", words.join(" ")))?;
                }
            }
            Move::SpindleOn { rpm } => {
                if !(rpm.is_finite() && rpm > 0.0) {
                    return Err(invalid(
                        index,
                        format!("spindle speed {rpm} rpm is not above zero"),
                    ));
                }
                let s = self.word(index, 'S', &format_number(rpm, RPM_DECIMALS))?;
                self.spindle_on = true;
                self.move_line(index, format!("M3 {s}"))?;
            }
            Move::SpindleOff => {
                self.spindle_on = false;
                self.line("M5");
            }
        }
        Ok(())
    }
}

fn invalid(index: usize, problem: String) -> PostError {
    PostError::InvalidMove { index, problem }
}

#[cfg(test)]
mod tests;
