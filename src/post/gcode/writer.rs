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
use crate::program::{Move, Pose, Program};

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
    fn axis_words(&mut self, index: usize, target: Pose) -> Result<Vec<String>, PostError> {
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
                let words = self.axis_words(index, Pose { x, z, c })?;
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
                let words = self.axis_words(index, Pose { x, z, c })?;
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
                let words = self.axis_words(index, Pose::known(x, z, c))?;
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
mod tests {
    use super::*;
    use crate::post::gcode::parse::{parse, read_program, GCode, WordKind};
    use proptest::prelude::*;

    fn grbl() -> PostSettings {
        PostSettings {
            dialect: Dialect::GrblHal,
            linear_decimals: 3,
            angular_decimals: 4,
            x_diameter: false,
            blend_tolerance_mm: None,
            max_line_length: 256,
        }
    }

    fn linuxcnc() -> PostSettings {
        PostSettings {
            dialect: Dialect::LinuxCnc,
            linear_decimals: 3,
            angular_decimals: 4,
            x_diameter: true,
            blend_tolerance_mm: Some(0.001),
            max_line_length: 255,
        }
    }

    fn sample() -> Program {
        Program {
            moves: vec![
                Move::Comment("whirl test".into()),
                Move::SpindleOn { rpm: 3000.0 },
                Move::Rapid {
                    x: Some(12.0),
                    z: Some(-1.0),
                    c: Some(0.0),
                },
                Move::Feed {
                    x: Some(10.5),
                    z: None,
                    c: None,
                    feed: 200.0,
                },
                Move::Linked {
                    x: 10.5,
                    z: -0.5,
                    c: 90.0,
                    minutes: 0.01,
                },
                Move::Linked {
                    x: 10.25,
                    z: 0.0,
                    c: 180.0,
                    minutes: 0.02,
                },
                Move::Linked {
                    x: 10.25,
                    z: 0.5,
                    c: 270.0,
                    minutes: 0.01,
                },
                Move::Feed {
                    x: Some(15.0),
                    z: None,
                    c: None,
                    feed: 500.0,
                },
                Move::Rapid {
                    x: None,
                    z: Some(10.0),
                    c: None,
                },
                Move::SpindleOff,
            ],
        }
    }

    /// `text` without the line numbers grblHAL programs carry (lines without one kept).
    fn unnumbered(text: &str) -> String {
        text.lines()
            .map(|l| {
                let rest = l.strip_prefix('N').and_then(|r| {
                    let digits = r.len() - r.trim_start_matches(|c: char| c.is_ascii_digit()).len();
                    (digits > 0)
                        .then(|| r[digits..].strip_prefix(' '))
                        .flatten()
                });
                format!("{}\n", rest.unwrap_or(l))
            })
            .collect()
    }

    #[test]
    fn grblhal_lines_carry_their_file_line_numbers_and_linuxcnc_lines_none() {
        let text = write(&sample(), &grbl()).unwrap();
        for (i, line) in text.lines().enumerate() {
            assert!(line.starts_with(&format!("N{} ", i + 1)), "{line}");
        }
        let text = write(&sample(), &linuxcnc()).unwrap();
        assert!(text.lines().all(|l| !l.starts_with('N')), "{text}");
    }

    #[test]
    fn a_line_that_fits_only_without_its_number_is_refused() {
        // `G0 X1234.568 Z-1234.568 C123456.789` is 35 characters; with "N3 " in front
        // (after the preamble and the comment) it is 38, over a 37-character limit.
        let program = one(Move::Rapid {
            x: Some(1234.5678),
            z: Some(-1234.5678),
            c: Some(123_456.789),
        });
        let settings = PostSettings {
            max_line_length: 37,
            ..grbl()
        };
        let error = write(&program, &settings).unwrap_err();
        assert!(
            matches!(
                error,
                PostError::LineTooLong {
                    length: 38,
                    max: 37,
                    ..
                }
            ),
            "{error}"
        );
    }

    #[test]
    fn grblhal_format() {
        // Unchanged words are left out (X on the first linked move and on the third),
        // G93/G94 appear only at mode changes, F is on every G1 (1/0.01 min = 100).
        let expected = "\
N1 G21 G90 G94
N2 (whirl test)
N3 M3 S3000
N4 G0 X12 Z-1 C0
N5 G1 X10.5 F200
N6 G93 G1 Z-0.5 C90 F100
N7 G1 X10.25 Z0 C180 F50
N8 G1 Z0.5 C270 F100
N9 G94 G1 X15 F500
N10 G0 Z10
N11 M5
N12 M2
";
        assert_eq!(write(&sample(), &grbl()).unwrap(), expected);
    }

    #[test]
    fn linuxcnc_format() {
        // Diameter mode doubles X; blending with the given tolerance and Q0; % around.
        let expected = "\
%
G21 G90 G94 G7
G64 P0.001 Q0
(whirl test)
M3 S3000
G0 X24 Z-1 C0
G1 X21 F200
G93 G1 Z-0.5 C90 F100
G1 X20.5 Z0 C180 F50
G1 Z0.5 C270 F100
G94 G1 X30 F500
G0 Z10
M5
M2
%
";
        assert_eq!(write(&sample(), &linuxcnc()).unwrap(), expected);
    }

    #[test]
    fn c_is_written_as_it_is_however_many_turns() {
        // Three turns and a quarter: C1170, no G92 anywhere.
        let program = Program {
            moves: vec![
                Move::Rapid {
                    x: Some(12.0),
                    z: Some(0.0),
                    c: Some(0.0),
                },
                Move::Linked {
                    x: 12.0,
                    z: 6.5,
                    c: 1170.0,
                    minutes: 0.1,
                },
            ],
        };
        for settings in [grbl(), linuxcnc()] {
            let text = write(&program, &settings).unwrap();
            assert!(text.contains(" C1170 "), "{text}");
            assert!(!text.contains("G92"), "{text}");
        }
    }

    #[test]
    fn linuxcnc_without_blending_uses_exact_path_and_radius_mode() {
        let settings = PostSettings {
            blend_tolerance_mm: None,
            x_diameter: false,
            ..linuxcnc()
        };
        let text = write(&Program::default(), &settings).unwrap();
        assert_eq!(text, "%\nG21 G90 G94 G8\nG61\nM2\n%\n");
    }

    #[test]
    fn spindle_left_on_is_stopped_and_inverse_time_is_left() {
        let program = Program {
            moves: vec![
                Move::SpindleOn { rpm: 2500.5 },
                Move::Linked {
                    x: 1.0,
                    z: 2.0,
                    c: 3.0,
                    minutes: 0.5,
                },
            ],
        };
        let text = unnumbered(&write(&program, &grbl()).unwrap());
        assert_eq!(
            text,
            "G21 G90 G94\nM3 S2500.5\nG93 G1 X1 Z2 C3 F2\nM5\nG94\nM2\n"
        );
    }

    #[test]
    fn blend_tolerance_is_never_written_larger() {
        for tolerance in [0.0015, 0.002_000_9, 1e-6, 0.123_456_789] {
            let settings = PostSettings {
                blend_tolerance_mm: Some(tolerance),
                ..linuxcnc()
            };
            let text = write(&Program::default(), &settings).unwrap();
            let line = text.lines().find(|l| l.starts_with("G64")).unwrap();
            let p: f64 = line["G64 P".len()..line.len() - " Q0".len()]
                .parse()
                .unwrap();
            assert!(p <= tolerance && tolerance - p < 1e-6, "{line}");
        }
    }

    #[test]
    fn settings_are_checked() {
        let program = Program::default();
        let cases = [
            (
                PostSettings {
                    blend_tolerance_mm: Some(0.01),
                    ..grbl()
                },
                PostError::BlendingUnsupported,
            ),
            (
                PostSettings {
                    blend_tolerance_mm: Some(0.0),
                    ..linuxcnc()
                },
                PostError::BadBlendTolerance(0.0),
            ),
            (
                PostSettings {
                    blend_tolerance_mm: Some(5.0),
                    ..linuxcnc()
                },
                PostError::BadBlendTolerance(5.0),
            ),
            (
                PostSettings {
                    max_line_length: 31,
                    ..grbl()
                },
                PostError::LineLengthTooSmall(31),
            ),
            (
                PostSettings {
                    linear_decimals: 7,
                    ..grbl()
                },
                PostError::TooManyDecimals {
                    which: "linear_decimals",
                    decimals: 7,
                },
            ),
            (
                PostSettings {
                    angular_decimals: 9,
                    ..grbl()
                },
                PostError::TooManyDecimals {
                    which: "angular_decimals",
                    decimals: 9,
                },
            ),
        ];
        for (settings, error) in cases {
            assert_eq!(write(&program, &settings), Err(error));
        }
        let nan = PostSettings {
            blend_tolerance_mm: Some(f64::NAN),
            ..linuxcnc()
        };
        assert!(matches!(
            write(&program, &nan),
            Err(PostError::BadBlendTolerance(_))
        ));
    }

    fn one(block: Move) -> Program {
        Program {
            moves: vec![Move::Comment("first".into()), block],
        }
    }

    #[test]
    fn unwritable_moves_are_errors_naming_the_move() {
        let bad = [
            Move::Linked {
                x: 1.0,
                z: 1.0,
                c: 1.0,
                minutes: 0.0,
            },
            Move::Linked {
                x: 1.0,
                z: 1.0,
                c: 1.0,
                minutes: -1.0,
            },
            // 1/minutes overflows to infinity.
            Move::Linked {
                x: 1.0,
                z: 1.0,
                c: 1.0,
                minutes: 1e-310,
            },
            Move::Linked {
                x: 1.0,
                z: 1.0,
                c: 1.0,
                minutes: f64::INFINITY,
            },
            Move::Linked {
                x: f64::NAN,
                z: 1.0,
                c: 1.0,
                minutes: 1.0,
            },
            Move::Feed {
                x: Some(1.0),
                z: None,
                c: None,
                feed: 0.0,
            },
            Move::Feed {
                x: Some(1.0),
                z: None,
                c: None,
                feed: f64::NAN,
            },
            Move::Rapid {
                x: None,
                z: Some(f64::INFINITY),
                c: None,
            },
            Move::SpindleOn { rpm: 0.0 },
            Move::SpindleOn { rpm: -5.0 },
        ];
        for case in bad {
            let error = write(&one(case.clone()), &grbl()).unwrap_err();
            assert!(
                matches!(error, PostError::InvalidMove { index: 1, .. }),
                "{case:?}: {error}"
            );
            assert!(error.to_string().starts_with("move 1 (not a file line): "));
        }
    }

    #[test]
    fn a_motion_line_that_cannot_fit_is_an_error_naming_the_move() {
        let settings = PostSettings {
            dialect: Dialect::LinuxCnc,
            max_line_length: 32,
            linear_decimals: 6,
            angular_decimals: 6,
            ..linuxcnc()
        };
        let block = Move::Linked {
            x: 123.456789,
            z: -234.567891,
            c: 3456.789123,
            minutes: 0.012345,
        };
        let error = write(&one(block), &settings).unwrap_err();
        assert!(
            matches!(
                error,
                PostError::LineTooLong {
                    index: 1,
                    max: 32,
                    ..
                }
            ),
            "{error}"
        );
    }

    #[test]
    fn grblhal_rejects_numbers_it_would_truncate() {
        let settings = PostSettings {
            linear_decimals: 6,
            ..grbl()
        };
        let block = Move::Rapid {
            x: None,
            z: Some(-1234.567891),
            c: None,
        };
        let error = write(&one(block.clone()), &settings).unwrap_err();
        assert_eq!(
            error,
            PostError::TooManyDigits {
                index: 1,
                word: "Z-1234.567891".into(),
                digits: 10,
                max: 9,
            }
        );
        // LinuxCNC reads doubles: the same number is fine there.
        let linuxcnc_settings = PostSettings {
            linear_decimals: 6,
            ..linuxcnc()
        };
        assert!(write(&one(block), &linuxcnc_settings).is_ok());
    }

    #[test]
    fn comments_are_sanitized_for_grbl() {
        let program = one(Move::Comment("a (nested) ?!~ ünï\tcode\u{18}".into()));
        let text = unnumbered(&write(&program, &grbl()).unwrap());
        let line = text.lines().nth(2).unwrap();
        assert_eq!(line, "(a [nested] ___ _n_ code )");
    }

    #[test]
    fn linuxcnc_active_comments_are_disarmed() {
        for active in ["MSG, hello", " debug,#<x>", "PY,print(1)", "print ,x"] {
            let text = write(&one(Move::Comment(active.into())), &linuxcnc()).unwrap();
            let line = text.lines().nth(4).unwrap();
            assert!(line.starts_with("(note: "), "{line}");
        }
        // Question marks are fine for LinuxCNC, and plain comments stay as they are.
        let text = write(&one(Move::Comment("pass 2, finish?".into())), &linuxcnc()).unwrap();
        assert_eq!(text.lines().nth(4), Some("(pass 2, finish?)"));
    }

    #[test]
    fn long_comments_are_split_and_keep_their_text() {
        let long: String = (0..700)
            .map(|i| char::from(b'a' + (i % 26) as u8))
            .collect();
        let numbered = write(&one(Move::Comment(long.clone())), &grbl()).unwrap();
        assert!(numbered.lines().all(|l| l.len() <= 256));
        let text = unnumbered(&numbered);
        let comments: Vec<&str> = text
            .lines()
            .filter(|l| l.starts_with('('))
            .skip(1)
            .collect();
        assert_eq!(comments.len(), 3);
        let joined: String = comments.iter().map(|l| &l[1..l.len() - 1]).collect();
        assert_eq!(joined, long);
    }

    /// What a G-code program does, read line by line: the feed mode each G1 runs in and
    /// whether it carries F, and the X written.
    struct Modal {
        g1_lines: Vec<(bool, bool)>,
        x_words: Vec<f64>,
    }

    fn modal_facts(text: &str) -> Modal {
        let mut inverse_time = false;
        let mut facts = Modal {
            g1_lines: Vec::new(),
            x_words: Vec::new(),
        };
        for line in parse(text).unwrap() {
            let mut g1 = false;
            let mut f = false;
            for word in &line.words {
                match word.kind {
                    WordKind::G(GCode::InverseTime) => inverse_time = true,
                    WordKind::G(GCode::UnitsPerMinute) => inverse_time = false,
                    WordKind::G(GCode::Linear) => g1 = true,
                    WordKind::F(_) => f = true,
                    WordKind::X(x) => facts.x_words.push(x),
                    _ => {}
                }
            }
            if g1 {
                facts.g1_lines.push((inverse_time, f));
            }
        }
        facts
    }

    #[test]
    fn every_linked_line_is_in_g93_and_carries_f() {
        let mut moves = vec![Move::Rapid {
            x: Some(5.0),
            z: Some(0.0),
            c: Some(0.0),
        }];
        for i in 1..=20 {
            moves.push(Move::Linked {
                x: 5.0 + (i % 3) as f64 * 0.01,
                z: i as f64 * 0.1,
                c: i as f64 * 18.0,
                minutes: 0.001 * i as f64,
            });
            if i % 7 == 0 {
                moves.push(Move::Feed {
                    x: Some(8.0),
                    z: None,
                    c: None,
                    feed: 300.0,
                });
            }
        }
        let program = Program { moves };
        for settings in [grbl(), linuxcnc()] {
            let facts = modal_facts(&write(&program, &settings).unwrap());
            let linked: Vec<_> = facts.g1_lines.iter().filter(|(inv, _)| *inv).collect();
            assert_eq!(linked.len(), 20);
            assert!(facts.g1_lines.iter().all(|(_, f)| *f));
            assert_eq!(facts.g1_lines.len(), 22);
        }
    }

    #[test]
    fn x_doubles_in_diameter_mode() {
        let program = Program {
            moves: vec![
                Move::Rapid {
                    x: Some(7.25),
                    z: Some(0.0),
                    c: None,
                },
                Move::Feed {
                    x: Some(3.125),
                    z: None,
                    c: None,
                    feed: 100.0,
                },
            ],
        };
        for (dialect, factor) in [(Dialect::GrblHal, 2.0), (Dialect::LinuxCnc, 2.0)] {
            let settings = PostSettings {
                dialect,
                x_diameter: true,
                blend_tolerance_mm: None,
                ..grbl()
            };
            let facts = modal_facts(&write(&program, &settings).unwrap());
            assert_eq!(facts.x_words, vec![7.25 * factor, 3.125 * factor]);
        }
        let facts = modal_facts(&write(&program, &grbl()).unwrap());
        assert_eq!(facts.x_words, vec![7.25, 3.125]);
    }

    #[test]
    fn inverse_time_feed_gives_the_move_time_to_1e4() {
        for i in 1..3000 {
            let minutes = 1e-4 * 1.0037f64.powi(i);
            let program = one(Move::Linked {
                x: 1.0,
                z: 1.0,
                c: 1.0,
                minutes,
            });
            let text = write(&program, &linuxcnc()).unwrap();
            let line = text.lines().find(|l| l.contains("G1")).unwrap();
            let f: f64 = line.rsplit_once('F').unwrap().1.parse().unwrap();
            let read_minutes = 1.0 / f;
            // Never faster than planned, and right to 1e-4 relative.
            assert!(
                read_minutes >= minutes * (1.0 - 1e-15),
                "{minutes} → {line}"
            );
            assert!(
                (read_minutes - minutes) / minutes < 1e-4,
                "{minutes} → {line}"
            );
        }
    }

    fn arb_move() -> impl Strategy<Value = Move> {
        let coord = || -300.0..300.0f64;
        let maybe = || proptest::option::of(-300.0..300.0f64);
        prop_oneof![
            "[ -~]{0,400}".prop_map(Move::Comment),
            (maybe(), maybe(), maybe()).prop_map(|(x, z, c)| Move::Rapid { x, z, c }),
            (maybe(), maybe(), maybe(), 1.0..5000.0f64).prop_map(|(x, z, c, feed)| Move::Feed {
                x,
                z,
                c,
                feed
            }),
            (coord(), coord(), -5000.0..5000.0f64, 1e-4..10.0f64)
                .prop_map(|(x, z, c, minutes)| Move::Linked { x, z, c, minutes }),
            (100.0..9000.0f64).prop_map(|rpm| Move::SpindleOn { rpm }),
            Just(Move::SpindleOff),
        ]
    }

    fn arb_settings() -> impl Strategy<Value = PostSettings> {
        (
            any::<bool>(),
            0..=4u32,
            0..=4u32,
            any::<bool>(),
            32..300usize,
        )
            .prop_map(
                |(linuxcnc, linear_decimals, angular_decimals, x_diameter, max_line_length)| {
                    PostSettings {
                        dialect: if linuxcnc {
                            Dialect::LinuxCnc
                        } else {
                            Dialect::GrblHal
                        },
                        linear_decimals,
                        angular_decimals,
                        x_diameter,
                        blend_tolerance_mm: linuxcnc.then_some(0.002),
                        max_line_length,
                    }
                },
            )
    }

    proptest! {
        #[test]
        fn lines_never_exceed_the_limit(
            moves in proptest::collection::vec(arb_move(), 0..40),
            settings in arb_settings(),
        ) {
            let program = Program { moves };
            // Either the text fits, or the writer refused a line that could not fit.
            match write(&program, &settings) {
                Ok(text) => {
                    for line in text.lines() {
                        prop_assert!(line.chars().count() <= settings.max_line_length, "{line}");
                        prop_assert!(line.is_ascii());
                    }
                    prop_assert!(!text.contains('\r'));
                }
                Err(error) => {
                    let is_line_too_long = matches!(error, PostError::LineTooLong { .. });
                    prop_assert!(is_line_too_long, "{}", error);
                }
            }
        }

        #[test]
        fn values_round_trip_through_the_parser(
            moves in proptest::collection::vec(arb_move(), 0..40),
            settings in arb_settings(),
        ) {
            let settings = PostSettings { max_line_length: 256, ..settings };
            let program = Program { moves };
            let text = write(&program, &settings).unwrap();
            let read = read_program(&text, settings.x_diameter).unwrap();

            // What the controller should hold after each move: every axis rounded to
            // its written decimals (X through the diameter when the controller's X is
            // one).
            let round = |axis: Axis, v: f64| -> f64 {
                match axis {
                    Axis::X if settings.x_diameter => {
                        format_number(2.0 * v, settings.linear_decimals).parse::<f64>().unwrap() / 2.0
                    }
                    Axis::X | Axis::Z => format_number(v, settings.linear_decimals).parse().unwrap(),
                    Axis::C => format_number(v, settings.angular_decimals).parse().unwrap(),
                }
            };
            let half = |axis: Axis| -> f64 {
                let d = if axis == Axis::C { settings.angular_decimals } else { settings.linear_decimals };
                let unit = 0.5 * 10f64.powi(-(d as i32));
                if axis == Axis::X && settings.x_diameter { unit / 2.0 } else { unit }
            };
            let mut expected: Vec<[Option<f64>; 3]> = Vec::new();
            let mut expected_times: Vec<f64> = Vec::new();
            let mut rounded = [None; 3];
            for action in &program.moves {
                let Some(t) = action.target() else { continue };
                let targets = [t.x, t.z, t.c];
                for (slot, axis) in Axis::ALL.into_iter().enumerate() {
                    if let Some(v) = targets[slot] {
                        rounded[slot] = Some(round(axis, v));
                        prop_assert!((round(axis, v) - v).abs() <= half(axis) * (1.0 + 1e-9));
                    }
                }
                if expected.last().unwrap_or(&[None; 3]) != &rounded {
                    expected.push(rounded);
                    if let Move::Linked { minutes, .. } = action {
                        expected_times.push(*minutes);
                    }
                }
            }
            let mut actual: Vec<[Option<f64>; 3]> = Vec::new();
            let mut actual_times: Vec<f64> = Vec::new();
            let mut position = [None; 3];
            for action in &read.moves {
                let Some(t) = action.target() else { continue };
                let targets = [t.x, t.z, t.c];
                for slot in 0..3 {
                    if targets[slot].is_some() {
                        position[slot] = targets[slot];
                    }
                }
                if actual.last().unwrap_or(&[None; 3]) != &position {
                    actual.push(position);
                    if let Move::Linked { minutes, .. } = action {
                        actual_times.push(*minutes);
                    }
                }
            }
            prop_assert_eq!(&actual, &expected);
            prop_assert_eq!(actual_times.len(), expected_times.len());
            for (read_minutes, planned) in actual_times.iter().zip(&expected_times) {
                prop_assert!(*read_minutes >= *planned * (1.0 - 1e-12));
                prop_assert!((read_minutes - planned) / planned < 1e-4);
            }
            // Comments and spindle blocks survive in order.
            let others = |p: &Program| -> Vec<Move> {
                p.moves.iter().filter(|b| matches!(b, Move::SpindleOn { .. } | Move::SpindleOff)).cloned().collect()
            };
            let spindle_read = others(&read);
            let mut spindle_planned = others(&program);
            // The writer stops a ring left running at the end.
            if let Some(Move::SpindleOn { .. }) = spindle_planned.last() {
                spindle_planned.push(Move::SpindleOff);
            }
            prop_assert_eq!(spindle_read.len(), spindle_planned.len());
            for (r, p) in spindle_read.iter().zip(&spindle_planned) {
                match (r, p) {
                    (Move::SpindleOn { rpm: a }, Move::SpindleOn { rpm: b }) => prop_assert!((a - b).abs() <= 0.05 + 1e-9),
                    (Move::SpindleOff, Move::SpindleOff) => {}
                    _ => prop_assert!(false, "{r:?} vs {p:?}"),
                }
            }
        }
    }
}
