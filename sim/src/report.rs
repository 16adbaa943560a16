//! Everything the controller prints: banner, responses, status reports, `$` listings.
//!
//! Formats are grbl 1.1's (`doc/markdown/interface.md` of gnea/grbl) as grblHAL prints them
//! (`report.c` of grblHAL/core): lines end in `\r\n`, positions have 3 decimals (4 in
//! inches), rates none, and axes are listed X, Y, Z, C, with Y present and always 0 as in an
//! XYZC build.

use std::fmt::{self, Write};

use crate::error::{Alarm, GrblError, ALARM_CODES, ERROR_CODES};
use crate::settings::report_bits;

/// Version in the banner and `[VER:]` (grblHAL's `GRBL_VERSION`, `grbl.h`).
pub const VERSION: &str = "1.1f";
/// The build grblHAL prints after the version (`GRBL_BUILD` of the core whose behaviour
/// the simulator follows).
pub const BUILD: &str = "20260817";
/// grbl's line end.
pub const EOL: &str = "\r\n";
/// Millimetres per inch.
const MM_PER_INCH: f64 = 25.4;

/// The controller's state, as the status report names it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum MachineState {
    /// Nothing to do.
    Idle,
    /// Executing queued motion.
    Run,
    /// Executing a jog (`$J=`).
    Jog,
    /// Feed hold: `complete` once the machine has stopped (`Hold:0`), else slowing
    /// (`Hold:1`).
    Hold {
        /// The machine has stopped.
        complete: bool,
    },
    /// Locked by an alarm.
    Alarm,
    /// Check mode (`$C`): lines are checked, nothing moves.
    Check,
}

impl MachineState {
    /// Whether grblHAL counts the state as busy for its report refresh counters
    /// (`STATE_HOMING|STATE_CYCLE|STATE_HOLD|STATE_JOG|STATE_SAFETY_DOOR`).
    fn busy(self) -> bool {
        matches!(
            self,
            MachineState::Run | MachineState::Jog | MachineState::Hold { .. }
        )
    }
}

impl fmt::Display for MachineState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            MachineState::Idle => "Idle",
            MachineState::Run => "Run",
            MachineState::Jog => "Jog",
            MachineState::Hold { complete: true } => "Hold:0",
            MachineState::Hold { complete: false } => "Hold:1",
            MachineState::Alarm => "Alarm",
            MachineState::Check => "Check",
        })
    }
}

/// A number with `decimals` decimals, never `-0`.
pub fn number(value: f64, decimals: usize) -> String {
    let text = format!("{value:.decimals$}");
    if text.starts_with('-') && text[1..].chars().all(|c| c == '0' || c == '.') {
        text[1..].to_owned()
    } else {
        text
    }
}

/// How positions and rates are printed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Units {
    /// G7 in force: X is a diameter (grblHAL doubles it, `get_axis_values`).
    pub diameter: bool,
    /// `$13=1`: millimetres as inches with 4 decimals.
    pub inches: bool,
    /// `$376` bit 0: C is rotary, never converted to inches.
    pub c_rotary: bool,
}

impl Units {
    /// X, Y, Z, C (grblHAL's `get_axis_values_mm` / `_inches`).
    fn axes(self, xzc: [f64; 3]) -> String {
        let x = if self.diameter { xzc[0] * 2.0 } else { xzc[0] };
        let linear = |v: f64| {
            if self.inches {
                number(v / MM_PER_INCH, 4)
            } else {
                number(v, 3)
            }
        };
        let c = if self.c_rotary {
            number(xzc[2], 3)
        } else {
            linear(xzc[2])
        };
        format!("{},{},{},{c}", linear(x), linear(0.0), linear(xzc[1]))
    }

    /// A rate, truncated to whole units per minute (grblHAL's `get_rate_value`).
    fn rate(self, mm_per_min: f64) -> String {
        let value = if self.inches {
            mm_per_min / MM_PER_INCH
        } else {
            mm_per_min
        };
        format!("{}", value.max(0.0).trunc() as u64)
    }
}

/// The start-up message, printed at power-up and after every soft reset
/// (`report_init_message`, `COMPATIBILITY_LEVEL` 0).
pub fn banner() -> String {
    format!("{EOL}GrblHAL {VERSION} ['$' or '$HELP' for help]{EOL}")
}

/// `ok` or `error:N`.
pub fn response(result: Result<(), GrblError>) -> String {
    match result {
        Ok(()) => format!("ok{EOL}"),
        Err(e) => format!("error:{}{EOL}", e.code()),
    }
}

/// `ALARM:N`.
pub fn alarm(alarm: Alarm) -> String {
    format!("ALARM:{}{EOL}", alarm.code())
}

/// `[MSG:text]`.
pub fn message(text: &str) -> String {
    format!("[MSG:{text}]{EOL}")
}

/// The optional fields a status report may carry, as grblHAL tracks them per stream
/// (`report_tracking_flags_t`, `stream.h`): set by what changed, cleared by the report.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Flags {
    /// `WCO:` (a work offset changed).
    pub wco: bool,
    /// `WCS:` (the coordinate system changed).
    pub coord_system: bool,
    /// `Ov:` (an override changed).
    pub overrides: bool,
    /// `A:` (the spindle changed).
    pub spindle: bool,
    /// `A:` (the coolant changed).
    pub coolant: bool,
    /// `D:` (G7/G8).
    pub diameter_mode: bool,
    /// `H:` (`$G` asks for it).
    pub homed: bool,
    /// `TLR:` (the tool length reference, reported after a reset).
    pub tool_reference: bool,
    /// The complete report (0x87): every field, and `Sc:`, `MPG:`, `T:`, `FW:`.
    pub all: bool,
}

impl Flags {
    /// What grblHAL's reset sets: the overrides (`grbllib.c`), spindle and coolant
    /// (`gc_init` switching them off) and the tool length reference.
    pub fn after_reset() -> Flags {
        Flags {
            overrides: true,
            spindle: true,
            coolant: true,
            tool_reference: true,
            ..Flags::default()
        }
    }

    /// 0x87's (`report_get_rt_flags_all`: `Report_All`).
    pub fn everything() -> Flags {
        Flags {
            wco: true,
            coord_system: true,
            overrides: true,
            spindle: true,
            coolant: true,
            diameter_mode: true,
            homed: true,
            tool_reference: true,
            all: true,
        }
    }

    /// Both sets.
    pub fn union(self, other: Flags) -> Flags {
        Flags {
            wco: self.wco || other.wco,
            coord_system: self.coord_system || other.coord_system,
            overrides: self.overrides || other.overrides,
            spindle: self.spindle || other.spindle,
            coolant: self.coolant || other.coolant,
            diameter_mode: self.diameter_mode || other.diameter_mode,
            homed: self.homed || other.homed,
            tool_reference: self.tool_reference || other.tool_reference,
            all: self.all || other.all,
        }
    }

    fn any(self) -> bool {
        self != Flags::default()
    }
}

/// grblHAL's refresh of `Ov:` and `WCO:` (`report_realtime_status`): each is shown when its
/// counter runs out (every 10 reports idle, 20 (`Ov`) or 30 (`WCO`) busy,
/// `REPORT_*_REFRESH_*_COUNT` in `config.h`) or when something set its flag; a `WCO:` due
/// in the same report as `Ov:` waits for the next one. The counters start at 0 with every
/// banner (`report_init_message`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Tracker {
    flags: Flags,
    wco_counter: u8,
    ov_counter: u8,
}

impl Tracker {
    /// As after the banner of a reset.
    pub fn after_reset() -> Tracker {
        Tracker {
            flags: Flags::after_reset(),
            wco_counter: 0,
            ov_counter: 0,
        }
    }

    /// Something changed that the next report shows.
    pub fn add(&mut self, flags: Flags) {
        self.flags = self.flags.union(flags);
    }

    /// The fields of the next report in `state`, with `$10` = `mask`, the spindle and
    /// coolant on or off; the flags are cleared for the one after.
    fn next(
        &mut self,
        state: MachineState,
        mask: u32,
        spindle_on: bool,
        coolant_on: bool,
    ) -> Flags {
        let busy = state.busy();
        let idle = state == MachineState::Idle;
        let mut f = self.flags;
        if mask & report_bits::OVERRIDES != 0 {
            if self.ov_counter == 0 || f.overrides {
                f.overrides = true;
                self.ov_counter = if busy { 19 } else { 9 };
                if !f.all {
                    f.spindle |= spindle_on;
                    f.coolant |= coolant_on;
                }
            } else {
                self.ov_counter -= 1;
            }
            if idle {
                self.ov_counter = self.ov_counter.min(9);
            }
        } else {
            f.overrides = false;
        }
        let mut delayed_wco = false;
        if mask & report_bits::WORK_COORD_OFFSET != 0 {
            if self.wco_counter == 0 || f.wco || f.coord_system || f.all {
                self.wco_counter = if busy { 29 } else { 9 };
                f.wco = !f.overrides || f.all || f.coord_system;
                delayed_wco = !f.wco;
            } else {
                self.wco_counter -= 1;
            }
            if idle {
                self.wco_counter = self.wco_counter.min(9);
            }
        } else {
            f.wco = false;
        }
        self.flags = Flags {
            wco: delayed_wco,
            ..Flags::default()
        };
        f
    }
}

/// What a status report shows.
#[derive(Debug, Clone, PartialEq)]
pub struct StatusSnapshot {
    /// State.
    pub state: MachineState,
    /// The alarm, if any (shown as `Alarm:N` with `$10` bit 10 or in the complete report).
    pub alarm: Option<Alarm>,
    /// Machine position X, Z, C.
    pub position: [f64; 3],
    /// The work offset X, Z, C (machine minus work position).
    pub offset: [f64; 3],
    /// The coordinate system, 54..=59.
    pub coord_system: u8,
    /// How numbers are printed.
    pub units: Units,
    /// `$10`.
    pub mask: u32,
    /// Lathe mode (`$32=2`): `D:` is shown.
    pub lathe: bool,
    /// The homing cycle names axes (`$44`–`$47`): `H:` is shown.
    pub homing_axes: bool,
    /// Planner blocks free.
    pub blocks_free: usize,
    /// RX bytes free.
    pub rx_free: usize,
    /// N of the block executing, or of the last line parsed, if above 0.
    pub line: Option<u32>,
    /// Path speed, mm (or degrees) per minute.
    pub feed: f64,
    /// Spindle: on, counter-clockwise, speed in rpm.
    pub spindle: (bool, bool, f64),
    /// Flood coolant on.
    pub coolant: bool,
    /// Feed, rapid and spindle overrides in percent.
    pub overrides: [u8; 3],
}

/// `<State|MPos:…|Bf:…|Ln:…|FS:…|WCO:…|WCS:…|Ov:…|A:…|Sc:|MPG:0|H:0|D:0|T:0|TLR:0|FW:grblHAL>`
/// in grblHAL's field order (`report_realtime_status`), the optional fields as `tracker`
/// says.
pub fn status(s: &StatusSnapshot, tracker: &mut Tracker) -> String {
    let (spindle_on, ccw, rpm) = s.spindle;
    let f = tracker.next(s.state, s.mask, spindle_on, s.coolant);
    let mut out = format!("<{}", s.state);
    if let Some(alarm) = s.alarm {
        if f.all || s.mask & report_bits::ALARM_SUBSTATE != 0 {
            let _ = write!(out, ":{}", alarm.code());
        }
    }
    let machine = s.mask & report_bits::MACHINE_POSITION != 0;
    let shown = if machine {
        s.position
    } else {
        [0, 1, 2].map(|i| s.position[i] - s.offset[i])
    };
    let _ = write!(
        out,
        "|{}:{}",
        if machine { "MPos" } else { "WPos" },
        s.units.axes(shown)
    );
    if s.mask & report_bits::BUFFER_STATE != 0 {
        let _ = write!(out, "|Bf:{},{}", s.blocks_free, s.rx_free);
    }
    if let Some(n) = s.line.filter(|_| s.mask & report_bits::LINE_NUMBERS != 0) {
        let _ = write!(out, "|Ln:{n}");
    }
    if s.mask & report_bits::FEED_SPEED != 0 {
        let speed = if spindle_on { rpm.round() } else { 0.0 };
        let _ = write!(out, "|FS:{},{}", s.units.rate(s.feed), number(speed, 0));
    }
    if f.any() {
        if f.wco {
            let _ = write!(out, "|WCO:{}", s.units.axes(s.offset));
        }
        if f.coord_system {
            let _ = write!(out, "|WCS:G{}", s.coord_system);
        }
        if f.overrides {
            let [feed, rapid, spindle] = s.overrides;
            let _ = write!(out, "|Ov:{feed},{rapid},{spindle}");
        }
        if f.spindle || f.coolant {
            out.push_str("|A:");
            if spindle_on {
                out.push(if ccw { 'C' } else { 'S' });
            }
            if s.coolant {
                out.push('F');
            }
        }
        if f.all {
            out.push_str("|Sc:|MPG:0");
        }
        if f.homed && s.homing_axes {
            // No axis is ever homed (no switches).
            out.push_str("|H:0");
        }
        if f.diameter_mode && s.lathe {
            let _ = write!(out, "|D:{}", u8::from(s.units.diameter));
        }
        if f.all {
            out.push_str("|T:0");
        }
        if f.tool_reference {
            out.push_str("|TLR:0");
        }
        if f.all {
            out.push_str("|FW:grblHAL");
        }
    }
    out.push('>');
    out.push_str(EOL);
    out
}

/// The `$` help line (`report_help_message`: grblHAL prints it whatever the build has).
pub fn help() -> String {
    format!("[HLP:$$ $# $G $I $N $x=val $Nx=line $J=line $SLP $C $X $H $B ~ ! ? ctrl-x]{EOL}")
}

/// `$$`: `$n=value` lines of `settings`, ascending (`report_grbl_settings`).
pub fn settings(settings: &crate::settings::Settings) -> String {
    settings
        .list()
        .into_iter()
        .map(|(n, v)| format!("${n}={v}{EOL}"))
        .collect()
}

/// What `$I` shows beyond the fixed lines.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BuildInfo<'a> {
    /// The build string (`$I=` sets it).
    pub build: &'a str,
    /// Planner blocks.
    pub blocks: usize,
    /// RX buffer size.
    pub rx_size: usize,
    /// `$10` bit 8: sync the queue on work offset changes (`W` in `[OPT:]` when off).
    pub sync_on_offset_change: bool,
    /// `$39`: `RT+` (legacy real-time characters), else `RT-`.
    pub legacy_realtime: bool,
    /// `$22` bit 0: `HOME`.
    pub homing: bool,
    /// `$32=2`: `LATHE`.
    pub lathe: bool,
}

/// `$I` (`report_build_info`, extended as `COMPATIBILITY_LEVEL` 0 always is): version,
/// options with planner blocks, RX buffer size, axes and tools, the axes, the new options,
/// firmware, control signals (none) and the driver.
pub fn build_info(info: &BuildInfo) -> String {
    // V variable spindle, N line numbers, L homing does not lock at power-up; W: no buffer
    // sync when a work offset changes (shown when disabled).
    let w = if info.sync_on_offset_change { "" } else { "W" };
    let rt = if info.legacy_realtime { '+' } else { '-' };
    let home = if info.homing { "HOME," } else { "" };
    let lathe = if info.lathe { "LATHE," } else { "" };
    format!(
        "[VER:{VERSION}.{BUILD}:{}]{EOL}[OPT:VNL{w},{},{},4,0]{EOL}[AXS:4:XYZC]{EOL}\
         [NEWOPT:ENUMS,RT{rt},{home}NOPROBE,{lathe}SED]{EOL}[FIRMWARE:grblHAL]{EOL}\
         [SIGNALS:]{EOL}[DRIVER:whirl-sim]{EOL}",
        info.build, info.blocks, info.rx_size
    )
}

/// `$#` (`report_ngc_parameters`): the coordinate systems (all zero), G28/G30 (zero), G92,
/// the tool length offset, the probe.
pub fn parameters(g92: [f64; 3], units: Units) -> String {
    let zero = units.axes([0.0; 3]);
    let mut out = String::new();
    for name in [
        "G54", "G55", "G56", "G57", "G58", "G59", "G59.1", "G59.2", "G59.3", "G28", "G30",
    ] {
        let _ = write!(out, "[{name}:{zero}]{EOL}");
    }
    let _ = write!(
        out,
        "[G92:{}]{EOL}[TLO:{zero}]{EOL}[PRB:{zero}:0]{EOL}",
        units.axes(g92)
    );
    out
}

/// The parser state `[GC:…]` (`$G`, 0x83).
#[derive(Debug, Clone, PartialEq)]
pub struct GcSnapshot {
    /// G0, G1 or G80.
    pub motion: u8,
    /// 54..=59.
    pub coord_system: u8,
    /// A G92 offset is in force.
    pub g92: bool,
    /// Lathe mode: G7/G8 shown.
    pub lathe: bool,
    /// G7 in force.
    pub diameter: bool,
    /// 17, 18, 19.
    pub plane: u8,
    /// G20 in force.
    pub inches: bool,
    /// G91 in force.
    pub incremental: bool,
    /// G93 in force.
    pub inverse_time: bool,
    /// G99 in force (else G98).
    pub retract_r: bool,
    /// M3, M4 or M5.
    pub spindle: u8,
    /// M8 in force.
    pub coolant: bool,
    /// F as the parser holds it, mm/min.
    pub feed: f64,
    /// S.
    pub rpm: f64,
    /// How rates are printed.
    pub units: Units,
}

/// `[GC:G0 G54 G8 G17 G21 G90 G94 G97 G40 G49 G98 G50 M5 M9 T0 F0 S0.]` in grblHAL's order
/// (`report_gcode_modes`); S has grblHAL's `ftoa` with no decimals, a bare point.
pub fn gc_state(g: &GcSnapshot) -> String {
    let mut out = format!("[GC:G{} G{}", g.motion, g.coord_system);
    if g.g92 {
        out.push_str(" G92");
    }
    if g.lathe {
        out.push_str(if g.diameter { " G7" } else { " G8" });
    }
    let _ = write!(
        out,
        " G{} G{} G{} G{}",
        g.plane,
        if g.inches { 20 } else { 21 },
        if g.incremental { 91 } else { 90 },
        if g.inverse_time { 93 } else { 94 }
    );
    if g.lathe {
        out.push_str(" G97");
    }
    let _ = write!(
        out,
        " G40 G49 G{} G50 M{} M{} T0 F{} S{}.]{EOL}",
        if g.retract_r { 99 } else { 98 },
        g.spindle,
        if g.coolant { 8 } else { 9 },
        g.units.rate(g.feed),
        number(g.rpm, 0),
    );
    out
}

/// `$EE`: every status code grblHAL has, `[ERRORCODE:n||description]`.
pub fn error_codes() -> String {
    ERROR_CODES
        .iter()
        .map(|(code, text)| format!("[ERRORCODE:{code}||{text}]{EOL}"))
        .collect()
}

/// `$EA`: every alarm code, `[ALARMCODE:n||description]`.
pub fn alarm_codes() -> String {
    ALARM_CODES
        .iter()
        .map(|(code, text)| format!("[ALARMCODE:{code}||{text}]{EOL}"))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formats() {
        // report.c's report_init_message, COMPATIBILITY_LEVEL 0.
        assert_eq!(banner(), "\r\nGrblHAL 1.1f ['$' or '$HELP' for help]\r\n");
        assert_eq!(response(Ok(())), "ok\r\n");
        assert_eq!(response(Err(GrblError::SystemGcLock)), "error:9\r\n");
        assert_eq!(alarm(Alarm::SoftLimit), "ALARM:2\r\n");
        assert_eq!(number(-0.0001, 3), "0.000");
        assert_eq!(number(-1.5, 3), "-1.500");
        let info = BuildInfo {
            build: "",
            blocks: 35,
            rx_size: 1024,
            sync_on_offset_change: true,
            legacy_realtime: true,
            homing: false,
            lathe: true,
        };
        assert!(build_info(&info).contains("[OPT:VNL,35,1024,4,0]"));
    }

    #[test]
    fn rates_are_truncated_and_rotary_c_stays_in_degrees() {
        // get_rate_value: (uint32_t)value; get_axis_values_inches: 4 decimals, C (rotary)
        // in degrees with 3.
        let mm = Units {
            diameter: false,
            inches: false,
            c_rotary: true,
        };
        assert_eq!(mm.rate(599.9), "599");
        let inches = Units { inches: true, ..mm };
        assert_eq!(
            inches.axes([25.4, 50.8, 90.0]),
            "1.0000,0.0000,2.0000,90.000"
        );
        assert_eq!(inches.rate(254.0), "10");
        let diameter = Units {
            diameter: true,
            ..mm
        };
        assert_eq!(diameter.axes([1.0, 0.0, 0.0]), "2.000,0.000,0.000,0.000");
    }
}
