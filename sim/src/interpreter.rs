//! The G-code interpreter: one line → the parser's modal state updated and the steps the
//! line asks of the machine, refused with grbl's error numbers.
//!
//! It follows grbl's `gc_execute_line` (gnea/grbl `gcode.c`, kept by grblHAL): words are
//! read and classified first (errors 1, 2, 4, 20, 21, 23, 24, 25), then the block is
//! checked as a whole in the NIST order of execution (22, 26, 27, 28, 31, 33, 36), and only
//! a block that passes every check changes the modal state. whirl's own parser
//! (`whirl::gcode::parse`) is not reused: it reports errors by column, refuses things grbl
//! accepts (axis words before any G0/G1, `/`, text after M2) and accepts things grbl refuses
//! (G64), so a sender would see different answers than from the real controller.
//!
//! Positions are machine coordinates (`MPos`): X the ring-centre offset as a radius (mm), Z
//! (mm), C (degrees). Like grbl, the parser keeps its position as the controller's number
//! type: with 32-bit floats every target is `f32(word) + f32(offset)`, so rebasing C with
//! G92 does not make the machine target small again.

use crate::machine::Number as NumberType;

use crate::error::GrblError;

/// Millimetres per inch (G20).
const MM_PER_INCH: f64 = 25.4;
/// grbl's `MAX_LINE_NUMBER`.
const MAX_LINE_NUMBER: f64 = 10_000_000.0;
/// Significant digits grblHAL's `read_float` keeps (`MAX_INT_DIGITS` in its `nuts_bolts.h`;
/// grbl 1.1 keeps 8 and counts leading zeros); later digits are dropped.
const MAX_INT_DIGITS: u32 = 9;

/// Rounds values to the controller's number type, as its parser does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Numbers(pub NumberType);

impl Numbers {
    /// `value` as the controller holds it.
    pub fn hold(self, value: f64) -> f64 {
        match self.0 {
            NumberType::F32 => f64::from(value as f32),
            NumberType::F64 => value,
        }
    }

    /// `a + b` computed in the controller's number type.
    pub fn add(self, a: f64, b: f64) -> f64 {
        match self.0 {
            NumberType::F32 => f64::from(a as f32 + b as f32),
            NumberType::F64 => a + b,
        }
    }

    /// `a − b` computed in the controller's number type.
    pub fn sub(self, a: f64, b: f64) -> f64 {
        match self.0 {
            NumberType::F32 => f64::from(a as f32 - b as f32),
            NumberType::F64 => a - b,
        }
    }
}

/// The motion mode (modal group 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MotionMode {
    /// G0.
    Rapid,
    /// G1.
    Linear,
    /// G80: motion cancelled; axis words are then an error.
    Cancelled,
}

/// The whirling ring's spindle as the program set it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spindle {
    /// M3 or M4 in force.
    pub on: bool,
    /// M4 (counter-clockwise) rather than M3.
    pub ccw: bool,
    /// The programmed speed S, rpm.
    pub rpm: f64,
}

/// The parser's modal state (what `$G` reports) and its view of the position, which runs
/// ahead of the machine by the blocks still queued.
#[derive(Debug, Clone, PartialEq)]
pub struct ParserState {
    /// Motion mode.
    pub motion: MotionMode,
    /// Plane: 17, 18 or 19.
    pub plane: u8,
    /// G20 in force.
    pub inches: bool,
    /// G91 in force.
    pub incremental: bool,
    /// G93 in force.
    pub inverse_time: bool,
    /// G7 (X words are diameters) in force.
    pub diameter: bool,
    /// Work coordinate system, 54..=59 (all with zero offset: G10 is not supported).
    pub coord_system: u8,
    /// G99 (canned cycles retract to R) rather than G98; no canned cycle uses it here.
    pub retract_r: bool,
    /// The N of the last line executed, 0 without one (grblHAL's `gc_state.line_number`,
    /// which the status report's `Ln:` shows while no block is queued).
    pub line_number: u32,
    /// Feed rate: mm/min in G94 (as converted from the units in force), 1/min in G93.
    pub feed: f64,
    /// Spindle.
    pub spindle: Spindle,
    /// Flood coolant (M8).
    pub coolant: bool,
    /// Position at the end of the last parsed block: X, Z, C in machine coordinates.
    pub position: [f64; 3],
    /// G92 offsets of X, Z, C: machine position minus work position.
    pub g92: [f64; 3],
}

impl ParserState {
    /// The power-up (and soft-reset) state: G0 G54 G17 G21 G90 G94 G8 M5 M9 F0 S0, at
    /// `position`, with the G92 offsets given (grblHAL keeps them across a reset).
    pub fn new(position: [f64; 3], g92: [f64; 3]) -> ParserState {
        ParserState {
            motion: MotionMode::Rapid,
            plane: 17,
            inches: false,
            incremental: false,
            inverse_time: false,
            diameter: false,
            coord_system: 54,
            retract_r: false,
            line_number: 0,
            feed: 0.0,
            spindle: Spindle {
                on: false,
                ccw: false,
                rpm: 0.0,
            },
            coolant: false,
            position,
            g92,
        }
    }
}

/// How a motion block's speed is given.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MotionKind {
    /// G0: at the axes' max rates.
    Rapid,
    /// G1 in G94: along the block's length (mm and degrees counted alike) at this many
    /// units per minute.
    Feed {
        /// Units per minute.
        per_minute: f64,
    },
    /// G1 in G93: the block takes `1 / inverse_minutes` minutes.
    InverseTime {
        /// The F word, 1/min.
        inverse_minutes: f64,
    },
    /// A jog (`$J=`): like a G1 in G94, but the feed override does not apply
    /// (`mc_jog_execute` sets `no_feed_override`).
    Jog {
        /// Units per minute.
        per_minute: f64,
    },
}

/// A motion the line asks for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionRequest {
    /// Target X, Z, C in machine coordinates.
    pub target: [f64; 3],
    /// How fast.
    pub kind: MotionKind,
}

/// Something that waits for all queued motion to finish before it happens (grbl's
/// `protocol_buffer_synchronize`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SyncAction {
    /// Nothing but the wait (coordinate-offset changes).
    Wait,
    /// Flood coolant on (M8) or off (M9).
    Coolant(bool),
    /// The spindle changes to this.
    Spindle(Spindle),
    /// M0: pause (feed hold) until cycle start.
    Pause,
    /// M2/M30: program end (`[MSG:Pgm End]`, spindle off).
    ProgramEnd,
}

/// One thing a line makes the machine do, in execution order.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Step {
    /// Wait for the queue to empty and the machine to stop, then act.
    Sync(SyncAction),
    /// G4: wait for the queue, then dwell this many seconds.
    Dwell(f64),
    /// Queue a motion.
    Motion(MotionRequest),
}

/// What a G-code line comes to.
#[derive(Debug, Clone, PartialEq)]
pub struct Block {
    /// The N word.
    pub n: Option<u32>,
    /// The steps, in execution order.
    pub steps: Vec<Step>,
}

/// Settings that shape how lines are read.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dialect {
    /// The controller's number type.
    pub numbers: Numbers,
    /// Wait for the queue before a G92 or G54–G59 change (`$10` bit 8, on by default).
    pub sync_on_offset_change: bool,
    /// Lathe mode (`$32=2`): G7 and G8 are accepted (grblHAL's `gcode.c` refuses them,
    /// `error:20`, in any other mode).
    pub lathe: bool,
    /// C is rotary (`$376`): never scaled by G20.
    pub c_rotary: bool,
}

/// A word: letter and value.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Word {
    letter: u8,
    value: f64,
}

/// Removes spaces, comments (`( … )` up to the first `)`, and `;` to the end) and block
/// delete `/`, and upper-cases, as grbl does before parsing.
fn normalize(text: &str) -> Vec<u8> {
    let mut out = Vec::with_capacity(text.len());
    let mut in_paren = false;
    for byte in text.bytes() {
        if in_paren {
            in_paren = byte != b')';
            continue;
        }
        match byte {
            b'(' => in_paren = true,
            b';' => break,
            b' ' | b'/' => {}
            other => out.push(other.to_ascii_uppercase()),
        }
    }
    out
}

/// grblHAL's `read_float`: optional sign, digits with at most one point, at least one
/// digit. Digits past the ninth significant one are dropped (the value keeps its
/// magnitude); leading zeros are not significant.
pub(crate) fn read_float(bytes: &[u8], at: &mut usize) -> Option<f64> {
    let mut i = *at;
    let negative = match bytes.get(i) {
        Some(b'-') => {
            i += 1;
            true
        }
        Some(b'+') => {
            i += 1;
            false
        }
        _ => false,
    };
    let (mut int_val, mut exp, mut digits, mut point) = (0u64, 0i32, 0u32, false);
    let mut any = false;
    while let Some(&byte) = bytes.get(i) {
        match byte {
            b'0'..=b'9' => {
                any = true;
                if byte != b'0' || int_val != 0 {
                    digits += 1;
                }
                if digits <= MAX_INT_DIGITS {
                    if point {
                        exp -= 1;
                    }
                    int_val = int_val * 10 + u64::from(byte - b'0');
                } else if !point {
                    exp += 1;
                }
            }
            b'.' if !point => point = true,
            _ => break,
        }
        i += 1;
    }
    if !any {
        return None;
    }
    *at = i;
    // int_val has at most 9 digits, exactly representable; powi keeps the magnitude.
    let value = int_val as f64 * 10f64.powi(exp);
    Some(if negative { -value } else { value })
}

/// Splits a normalized line into words (errors 1 and 2).
fn words(bytes: &[u8]) -> Result<Vec<Word>, GrblError> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        let letter = bytes[i];
        if !letter.is_ascii_uppercase() {
            return Err(GrblError::ExpectedCommandLetter);
        }
        i += 1;
        let value = read_float(bytes, &mut i).ok_or(GrblError::BadNumberFormat)?;
        out.push(Word { letter, value });
    }
    Ok(out)
}

/// The N word of a line, if it can be read; for logging lines the controller refuses
/// without parsing (sticky errors, alarm lock).
pub fn line_number(text: &str) -> Option<u32> {
    let bytes = normalize(text);
    let words = words(&bytes).ok()?;
    let value = words.iter().find(|w| w.letter == b'N')?.value;
    (0.0..=MAX_LINE_NUMBER)
        .contains(&value)
        .then_some(value.trunc() as u32)
}

/// The modal groups grbl checks for duplicates (error 21).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Group {
    NonModal,
    Motion,
    Plane,
    Distance,
    ArcDistance,
    FeedMode,
    Units,
    CutterComp,
    ToolLength,
    CoordSystem,
    PathControl,
    LatheMode,
    Retract,
    MacroCall,
    Stop,
    Spindle,
    Coolant,
}

/// The commands of a block, one slot per modal group.
#[derive(Debug, Default)]
struct Commands {
    groups: Vec<Group>,
    dwell: bool,
    set_offset: bool,
    clear_offset: bool,
    /// G53: this block's targets are machine coordinates.
    absolute_override: bool,
    motion: Option<MotionMode>,
    plane: Option<u8>,
    incremental: Option<bool>,
    inverse_time: Option<bool>,
    inches: Option<bool>,
    coord_system: Option<u8>,
    diameter: Option<bool>,
    retract_r: Option<bool>,
    /// G65 or G66: a macro call (P names the macro); G67 ends a modal one.
    macro_call: Option<u8>,
    stop: Option<u8>,
    spindle: Option<(bool, bool)>,
    coolant: Option<bool>,
}

impl Commands {
    fn claim(&mut self, group: Group) -> Result<(), GrblError> {
        if self.groups.contains(&group) {
            return Err(GrblError::ModalGroupViolation);
        }
        self.groups.push(group);
        Ok(())
    }
}

/// Which command takes the axis words.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum AxisCommand {
    NonModal,
    Motion,
}

/// Value words of a block.
#[derive(Debug, Default)]
struct Values {
    seen: Vec<u8>,
    n: Option<f64>,
    f: Option<f64>,
    p: Option<f64>,
    s: Option<f64>,
    /// X, Z, C as written.
    axes: [Option<f64>; 3],
}

/// Interprets one G-code line (neither empty nor a `$` command) against `state`, which it
/// updates only if the whole line is accepted.
pub fn interpret(
    text: &str,
    state: &mut ParserState,
    dialect: Dialect,
) -> Result<Block, GrblError> {
    let bytes = normalize(text);
    if bytes == b"%" {
        // grblHAL's program demarcation: a line holding only `%` is accepted and does nothing.
        return Ok(Block {
            n: None,
            steps: Vec::new(),
        });
    }
    let (cmd, axis_command, values) = parse(&bytes, dialect)?;
    check_and_run(cmd, axis_command, values, state, dialect)
}

/// A block's words read and classified (grbl's step 2: errors 1, 2, 4, 20, 21, 23, 24,
/// 25).
fn parse(
    bytes: &[u8],
    dialect: Dialect,
) -> Result<(Commands, Option<AxisCommand>, Values), GrblError> {
    let mut cmd = Commands::default();
    let mut axis_command = None;
    let mut values = Values::default();
    for word in words(bytes)? {
        match word.letter {
            b'G' => g_word(word.value, &mut cmd, &mut axis_command, dialect)?,
            b'M' => m_word(word.value, &mut cmd)?,
            letter @ (b'F' | b'N' | b'P' | b'S' | b'X' | b'Z' | b'C') => {
                if values.seen.contains(&letter) {
                    return Err(GrblError::WordRepeated);
                }
                values.seen.push(letter);
                if matches!(letter, b'F' | b'N' | b'P' | b'S') && word.value < 0.0 {
                    return Err(GrblError::NegativeValue);
                }
                let slot = match letter {
                    b'F' => &mut values.f,
                    b'N' => &mut values.n,
                    b'P' => &mut values.p,
                    b'S' => &mut values.s,
                    b'X' => &mut values.axes[0],
                    b'Z' => &mut values.axes[1],
                    _ => &mut values.axes[2],
                };
                *slot = Some(word.value);
            }
            // Y (the machine has no Y drive), T, arcs' I J K R, A, B and the rest.
            _ => return Err(GrblError::UnsupportedCommand),
        }
    }
    Ok((cmd, axis_command, values))
}

/// Splits a code into its whole part and hundredths of a fraction, as grbl does.
fn split_code(value: f64) -> (i64, i64) {
    let whole = value.trunc();
    // Codes beyond i64 are no code at all; the saturating cast makes them unsupported.
    (whole as i64, ((value - whole) * 100.0).round() as i64)
}

fn g_word(
    value: f64,
    cmd: &mut Commands,
    axis_command: &mut Option<AxisCommand>,
    dialect: Dialect,
) -> Result<(), GrblError> {
    let (code, mut mantissa) = split_code(value);
    let group = match code {
        4 => {
            cmd.dwell = true;
            Group::NonModal
        }
        53 => {
            cmd.absolute_override = true;
            Group::NonModal
        }
        92 => {
            match mantissa {
                0 => {
                    if axis_command.is_some() {
                        return Err(GrblError::AxisCommandConflict);
                    }
                    *axis_command = Some(AxisCommand::NonModal);
                    cmd.set_offset = true;
                }
                10 => cmd.clear_offset = true,
                _ => return Err(GrblError::UnsupportedCommand),
            }
            mantissa = 0;
            Group::NonModal
        }
        0 | 1 => {
            if axis_command.is_some() {
                return Err(GrblError::AxisCommandConflict);
            }
            *axis_command = Some(AxisCommand::Motion);
            cmd.motion = Some(if code == 0 {
                MotionMode::Rapid
            } else {
                MotionMode::Linear
            });
            Group::Motion
        }
        80 => {
            cmd.motion = Some(MotionMode::Cancelled);
            Group::Motion
        }
        7 | 8 if dialect.lathe => {
            cmd.diameter = Some(code == 7);
            Group::LatheMode
        }
        17..=19 => {
            cmd.plane = Some(code as u8);
            Group::Plane
        }
        20 | 21 => {
            cmd.inches = Some(code == 20);
            Group::Units
        }
        40 => Group::CutterComp,
        49 => Group::ToolLength,
        54..=59 => {
            cmd.coord_system = Some(code as u8);
            Group::CoordSystem
        }
        61 => {
            if mantissa != 0 {
                return Err(GrblError::UnsupportedCommand);
            }
            Group::PathControl
        }
        90 | 91 => {
            if mantissa == 0 {
                cmd.incremental = Some(code == 91);
                Group::Distance
            } else if code == 91 && mantissa == 10 {
                // G91.1: arc centres incremental, grbl's only arc mode; nothing to do.
                mantissa = 0;
                Group::ArcDistance
            } else {
                return Err(GrblError::UnsupportedCommand);
            }
        }
        93 | 94 => {
            cmd.inverse_time = Some(code == 93);
            Group::FeedMode
        }
        // Macro calls: grblHAL's core always has them (ngc_params.c hooks
        // `on_macro_execute`), the simulator has no macro to call.
        65..=67 => {
            cmd.macro_call = Some(code as u8);
            Group::MacroCall
        }
        // Canned-cycle retract mode (modal group 10): grblHAL keeps it with or without
        // canned cycles, so a post's G98/G99 preamble is accepted.
        98 | 99 => {
            cmd.retract_r = Some(code == 99);
            Group::Retract
        }
        _ => return Err(GrblError::UnsupportedCommand),
    };
    if mantissa != 0 {
        return Err(GrblError::CommandValueNotInteger);
    }
    cmd.claim(group)
}

fn m_word(value: f64, cmd: &mut Commands) -> Result<(), GrblError> {
    let (code, mantissa) = split_code(value);
    if mantissa != 0 {
        return Err(GrblError::CommandValueNotInteger);
    }
    let group = match code {
        0 | 1 | 2 | 30 => {
            cmd.stop = Some(code as u8);
            Group::Stop
        }
        3..=5 => {
            cmd.spindle = Some((code != 5, code == 4));
            Group::Spindle
        }
        8 | 9 => {
            cmd.coolant = Some(code == 8);
            Group::Coolant
        }
        _ => return Err(GrblError::UnsupportedCommand),
    };
    cmd.claim(group)
}

/// Axis words in millimetres (X, Z; C too unless rotary) and X as a radius.
fn axis_values(
    axes: [Option<f64>; 3],
    inches: bool,
    diameter: bool,
    dialect: Dialect,
) -> [Option<f64>; 3] {
    let mut axes = axes;
    for (i, axis) in axes.iter_mut().enumerate() {
        if let Some(v) = axis.as_mut() {
            if inches && (i < 2 || !dialect.c_rotary) {
                *v *= MM_PER_INCH;
            }
            if i == 0 && diameter {
                *v /= 2.0;
            }
        }
    }
    axes
}

/// A jog the controller may run (`$J=`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Jog {
    /// The N word, if any.
    pub n: Option<u32>,
    /// The motion: target in machine coordinates, [`MotionKind::Jog`].
    pub request: MotionRequest,
}

/// Interprets the G-code of a `$J=` line (the text after the `=`) against `state`, as
/// grblHAL's `gc_execute_block` does with its jog flag (`gcode.c`): G1 and G94 are
/// enforced, F is required (`error:22`), S (and P without G4) are unused words (`error:36`), and only
/// G20/G21, G90/G91 and G53 may be given (`error:16` for any other G or M code, checked
/// after those). The parser's modes are left alone; only its position is to move to the
/// target, once the controller has taken the jog, so that the next one starts from there. Soft
/// limits are the controller's to check.
pub fn jog(text: &str, state: &ParserState, dialect: Dialect) -> Result<Jog, GrblError> {
    let (cmd, _, values) = parse(&normalize(text), dialect)?;
    let n = match values.n {
        Some(n) if n > MAX_LINE_NUMBER => return Err(GrblError::InvalidLineNumber),
        n => n.map(|n| n.trunc() as u32),
    };
    let inches = cmd.inches.unwrap_or(state.inches);
    let Some(feed) = values.f else {
        return Err(GrblError::UndefinedFeedRate);
    };
    // The G1 check of a motion without a feed rate.
    if feed == 0.0 && values.axes.iter().any(Option::is_some) {
        return Err(GrblError::UndefinedFeedRate);
    }
    if values.s.is_some() || (values.p.is_some() && !cmd.dwell) {
        return Err(GrblError::UnusedWords);
    }
    let allowed = [Group::Units, Group::Distance, Group::NonModal];
    if cmd.groups.iter().any(|g| !allowed.contains(g))
        || cmd.dwell
        || cmd.set_offset
        || cmd.clear_offset
    {
        return Err(GrblError::InvalidJogCommand);
    }
    let num = dialect.numbers;
    let incremental = cmd.incremental.unwrap_or(state.incremental);
    let axes = axis_values(values.axes, inches, state.diameter, dialect);
    let mut target = state.position;
    for (i, axis) in axes.iter().enumerate() {
        if let Some(v) = axis {
            target[i] = if cmd.absolute_override {
                num.hold(*v)
            } else if incremental {
                num.add(state.position[i], *v)
            } else {
                num.add(*v, state.g92[i])
            };
        }
    }
    if !target.iter().all(|v| v.is_finite()) {
        return Err(GrblError::InvalidTarget);
    }
    let per_minute = if inches { feed * MM_PER_INCH } else { feed };
    Ok(Jog {
        n,
        request: MotionRequest {
            target,
            kind: MotionKind::Jog { per_minute },
        },
    })
}

/// grbl's error checks of a whole block, then its execution on a copy of the state that
/// replaces `state` only on success.
fn check_and_run(
    cmd: Commands,
    mut axis_command: Option<AxisCommand>,
    values: Values,
    state: &mut ParserState,
    dialect: Dialect,
) -> Result<Block, GrblError> {
    let num = dialect.numbers;
    let has_axes = values.axes.iter().any(Option::is_some);
    if has_axes && axis_command.is_none() {
        axis_command = Some(AxisCommand::Motion);
    }
    let motion = cmd.motion.unwrap_or(state.motion);
    let n = match values.n {
        Some(n) if n > MAX_LINE_NUMBER => return Err(GrblError::InvalidLineNumber),
        Some(n) => Some(n.trunc() as u32),
        None => None,
    };
    let inches = cmd.inches.unwrap_or(state.inches);
    let to_mm = |v: f64| if inches { v * MM_PER_INCH } else { v };

    // Feed rate mode, then feed rate: in G93 F belongs to its block, in G94 it is modal,
    // and a change of mode forgets it.
    let inverse_time = cmd.inverse_time.unwrap_or(state.inverse_time);
    let feed = if inverse_time {
        if axis_command == Some(AxisCommand::Motion)
            && motion == MotionMode::Linear
            && values.f.is_none()
        {
            return Err(GrblError::UndefinedFeedRate);
        }
        values.f.unwrap_or(0.0)
    } else {
        match (values.f, state.inverse_time) {
            (Some(f), _) => to_mm(f),
            (None, false) => state.feed,
            (None, true) => 0.0,
        }
    };
    if cmd.dwell && values.p.is_none() {
        return Err(GrblError::ValueWordMissing);
    }
    if let Some(65 | 66) = cmd.macro_call {
        // A macro call needs P (gcode.c); none exists here, as a P no macro has is
        // answered in grblHAL (ngc_params.c: out of range).
        return Err(if values.p.is_none() {
            GrblError::ValueWordMissing
        } else {
            GrblError::ValueOutOfRange
        });
    }

    // Axis words: X and Z in mm (C is rotary and stays in degrees), X a radius.
    let diameter = cmd.diameter.unwrap_or(state.diameter);
    let axes = axis_values(values.axes, inches, diameter, dialect);
    if cmd.set_offset && !has_axes {
        return Err(GrblError::NoAxisWords);
    }
    // The non-modal checks come before the motion's (gcode.c, steps 19 and 20).
    if cmd.absolute_override && !matches!(motion, MotionMode::Rapid | MotionMode::Linear) {
        return Err(GrblError::G53InvalidMotionMode);
    }
    let moves = axis_command == Some(AxisCommand::Motion) && has_axes;
    if moves && motion == MotionMode::Cancelled {
        return Err(GrblError::AxisWordsExist);
    }
    if moves && motion == MotionMode::Linear && feed == 0.0 {
        return Err(GrblError::UndefinedFeedRate);
    }
    if values.p.is_some() && !cmd.dwell {
        return Err(GrblError::UnusedWords);
    }

    // Execution, in RS274/NGC order, on a copy.
    let mut next = state.clone();
    let mut steps = Vec::new();
    next.inverse_time = inverse_time;
    next.feed = feed;
    let mut spindle = next.spindle;
    if let Some(s) = values.s {
        spindle.rpm = s;
    }
    if let Some((on, ccw)) = cmd.spindle {
        spindle.on = on;
        spindle.ccw = on && ccw;
    }
    let spindle_changed = spindle.on != next.spindle.on
        || spindle.ccw != next.spindle.ccw
        || (spindle.on && spindle.rpm != next.spindle.rpm);
    next.spindle = spindle;
    if spindle_changed {
        steps.push(Step::Sync(SyncAction::Spindle(spindle)));
    }
    if let Some(coolant) = cmd.coolant {
        if coolant != next.coolant {
            next.coolant = coolant;
            steps.push(Step::Sync(SyncAction::Coolant(coolant)));
        }
    }
    if cmd.dwell {
        steps.push(Step::Dwell(values.p.unwrap_or(0.0)));
    }
    if let Some(plane) = cmd.plane {
        next.plane = plane;
    }
    next.inches = inches;
    next.diameter = diameter;
    if let Some(cs) = cmd.coord_system {
        if cs != next.coord_system && dialect.sync_on_offset_change {
            steps.push(Step::Sync(SyncAction::Wait));
        }
        next.coord_system = cs;
    }
    if let Some(incremental) = cmd.incremental {
        next.incremental = incremental;
    }
    if let Some(retract_r) = cmd.retract_r {
        next.retract_r = retract_r;
    }
    if cmd.clear_offset {
        next.g92 = [0.0; 3];
    }
    if cmd.set_offset {
        for (i, axis) in axes.iter().enumerate() {
            if let Some(v) = axis {
                next.g92[i] = num.sub(next.position[i], *v);
            }
        }
        if !next.g92.iter().all(|v| v.is_finite()) {
            return Err(GrblError::InvalidTarget);
        }
    }
    // grbl waits on every G92 and G92.1, changed or not (`system_flag_wco_change`).
    if (cmd.set_offset || cmd.clear_offset) && dialect.sync_on_offset_change {
        steps.push(Step::Sync(SyncAction::Wait));
    }
    if let Some(mode) = cmd.motion {
        next.motion = mode;
    }
    if moves {
        let mut target = next.position;
        for (i, axis) in axes.iter().enumerate() {
            if let Some(v) = axis {
                target[i] = if cmd.absolute_override {
                    // G53: machine coordinates, whatever the distance mode.
                    num.hold(*v)
                } else if next.incremental {
                    num.add(next.position[i], *v)
                } else {
                    num.add(*v, next.g92[i])
                };
            }
        }
        if !target.iter().all(|v| v.is_finite()) {
            return Err(GrblError::InvalidTarget);
        }
        let kind = match (motion, inverse_time) {
            (MotionMode::Linear, true) => MotionKind::InverseTime {
                inverse_minutes: feed,
            },
            (MotionMode::Linear, false) => MotionKind::Feed { per_minute: feed },
            _ => MotionKind::Rapid,
        };
        steps.push(Step::Motion(MotionRequest { target, kind }));
        next.position = target;
    }
    if next.inverse_time {
        // grbl: in G93 the feed rate is always undefined after the block.
        next.feed = 0.0;
    }
    next.line_number = n.unwrap_or(0);
    match cmd.stop {
        Some(0) => steps.push(Step::Sync(SyncAction::Pause)),
        Some(2 | 30) => {
            // grbl's program end: G1 G17 G90 G94 G54 M5 M9; units, G92 and F stay.
            next.motion = MotionMode::Linear;
            next.plane = 17;
            next.incremental = false;
            next.inverse_time = false;
            next.coord_system = 54;
            next.spindle.on = false;
            next.spindle.ccw = false;
            next.coolant = false;
            steps.push(Step::Sync(SyncAction::ProgramEnd));
        }
        _ => {}
    }
    *state = next;
    Ok(Block { n, steps })
}

#[cfg(test)]
mod tests;
