//! Everything the controller prints: banner, responses, status reports, `$` listings.
//!
//! Formats are grbl 1.1's (`doc/markdown/interface.md` of gnea/grbl) as grblHAL prints them
//! (`report.c` of grblHAL/core): lines end in `\r\n`, positions have 3 decimals, rates none,
//! and axes are listed X, Y, Z, C, with Y present and always 0 as in an XYZC build.

use std::fmt::{self, Write};

use crate::error::{Alarm, GrblError};

/// Version in the banner and `[VER:]`.
pub const VERSION: &str = "1.1f";
/// The build date grblHAL prints after the version.
pub const BUILD: &str = "20240101";
/// grbl's line end.
pub const EOL: &str = "\r\n";

/// The controller's state, as the status report names it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum MachineState {
    /// Nothing to do.
    Idle,
    /// Executing queued motion.
    Run,
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

impl fmt::Display for MachineState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            MachineState::Idle => "Idle",
            MachineState::Run => "Run",
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

/// X, Y, Z, C with 3 decimals, X doubled in diameter mode (grblHAL's lathe mode, G7).
fn axes(xzc: [f64; 3], diameter: bool) -> String {
    let x = if diameter { xzc[0] * 2.0 } else { xzc[0] };
    format!(
        "{},{},{},{}",
        number(x, 3),
        number(0.0, 3),
        number(xzc[1], 3),
        number(xzc[2], 3)
    )
}

/// The start-up message, printed at power-up and after every soft reset.
pub fn banner() -> String {
    format!("{EOL}GrblHAL {VERSION} ['$' or '$HLP' for help]{EOL}")
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

/// What a status report shows.
#[derive(Debug, Clone, PartialEq)]
pub struct StatusSnapshot {
    /// State.
    pub state: MachineState,
    /// Machine position X, Z, C.
    pub position: [f64; 3],
    /// G7 in force: X is shown as a diameter.
    pub diameter: bool,
    /// Planner blocks free.
    pub blocks_free: usize,
    /// RX bytes free.
    pub rx_free: usize,
    /// N of the block executing, if it had one above 0.
    pub line: Option<u32>,
    /// Path speed, units/min.
    pub feed: f64,
    /// Spindle speed, rpm (0 when off).
    pub spindle: f64,
    /// The work coordinate offset, when this report carries it.
    pub wco: Option<[f64; 3]>,
    /// Feed, rapid and spindle overrides in percent, when this report carries them.
    pub overrides: Option<[u8; 3]>,
    /// `S` (M3) or `C` (M4) when the spindle runs and the overrides are shown.
    pub accessory: Option<char>,
}

/// `<State|MPos:…|Bf:…|Ln:…|FS:…|WCO:…|Ov:…|A:…>` in grblHAL's field order.
pub fn status(s: &StatusSnapshot) -> String {
    let mut out = format!(
        "<{}|MPos:{}|Bf:{},{}",
        s.state,
        axes(s.position, s.diameter),
        s.blocks_free,
        s.rx_free
    );
    if let Some(n) = s.line {
        let _ = write!(out, "|Ln:{n}");
    }
    let _ = write!(out, "|FS:{},{}", number(s.feed, 0), number(s.spindle, 0));
    if let Some(wco) = s.wco {
        let _ = write!(out, "|WCO:{}", axes(wco, s.diameter));
    }
    if let Some([f, r, sp]) = s.overrides {
        let _ = write!(out, "|Ov:{f},{r},{sp}");
        if let Some(a) = s.accessory {
            let _ = write!(out, "|A:{a}");
        }
    }
    out.push('>');
    out.push_str(EOL);
    out
}

/// The `$` help line (only the commands the simulator supports).
pub fn help() -> String {
    format!("[HLP:$$ $# $G $I $N $C $X $H ~ ! ? ctrl-x]{EOL}")
}

/// What `$$` lists: the settings a sender can use, in grbl's numbering, from the machine
/// profile. X, Y, Z, C are axes 0–3 (`$110`–`$113` and so on); Y, which never moves,
/// shows X's rate and acceleration and no travel.
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    /// `$11`, mm.
    pub junction_deviation: f64,
    /// `$30` and `$31`, rpm.
    pub spindle_max: f64,
    /// `$31`.
    pub spindle_min: f64,
    /// `$110`–`$113`: X, Y, Z mm/min, C deg/min.
    pub max_rate: [f64; 4],
    /// `$120`–`$123`: mm/s², C deg/s².
    pub accel: [f64; 4],
    /// `$130`–`$133`: travel length (max − min), 0 for none.
    pub travel: [f64; 4],
    /// `$398`: planner blocks.
    pub planner_blocks: usize,
}

impl Settings {
    /// Every setting as `(number, value text)`, in ascending order.
    pub fn list(&self) -> Vec<(u16, String)> {
        let mut out = vec![
            (10, "111".to_owned()), // MPos, Bf, Ln, FS, WCO, Ov
            (11, number(self.junction_deviation, 3)),
            (12, number(0.002, 3)),
            (13, "0".to_owned()), // report in mm
            (20, "1".to_owned()), // soft limits on
            (21, "0".to_owned()), // hard limits off
            (22, "0".to_owned()), // homing off
            (30, number(self.spindle_max, 3)),
            (31, number(self.spindle_min, 3)),
            (32, "2".to_owned()), // lathe mode (G7/G8)
        ];
        for (base, values) in [(110, self.max_rate), (120, self.accel), (130, self.travel)] {
            for (i, v) in values.iter().enumerate() {
                out.push((base + i as u16, number(*v, 3)));
            }
        }
        out.push((376, "8".to_owned())); // C (axis 3) is rotary
        out.push((398, self.planner_blocks.to_string()));
        out
    }

    /// One setting's value text, if it exists.
    pub fn get(&self, id: u16) -> Option<String> {
        self.list()
            .into_iter()
            .find_map(|(n, v)| (n == id).then_some(v))
    }
}

/// `$n=value` lines of every setting.
pub fn settings(settings: &Settings) -> String {
    settings
        .list()
        .into_iter()
        .map(|(n, v)| format!("${n}={v}{EOL}"))
        .collect()
}

/// `$I`: version, options with the planner blocks and RX buffer size, axes, firmware.
pub fn build_info(blocks: usize, rx_size: usize, sync_on_offset_change: bool) -> String {
    // V variable spindle, N line numbers, L homing does not lock at power-up; W: no buffer
    // sync when a work offset changes (shown when disabled).
    let w = if sync_on_offset_change { "" } else { "W" };
    format!(
        "[VER:{VERSION}.{BUILD}:whirl-sim]{EOL}[OPT:VNL{w},{blocks},{rx_size},4,0]{EOL}\
         [AXS:4:XYZC]{EOL}[NEWOPT:LATHE]{EOL}[FIRMWARE:grblHAL]{EOL}"
    )
}

/// `$#`: the coordinate systems (all zero), G28/G30 (zero), G92, tool offset, probe.
pub fn parameters(g92: [f64; 3], diameter: bool) -> String {
    let zero = axes([0.0; 3], false);
    let mut out = String::new();
    for name in ["G54", "G55", "G56", "G57", "G58", "G59", "G28", "G30"] {
        let _ = write!(out, "[{name}:{zero}]{EOL}");
    }
    let _ = write!(
        out,
        "[G92:{}]{EOL}[TLO:0.000]{EOL}[PRB:{zero}:0]{EOL}",
        axes(g92, diameter)
    );
    out
}

/// The parser state `[GC:…]` (`$G`).
#[derive(Debug, Clone, PartialEq)]
pub struct GcSnapshot {
    /// G0, G1 or G80.
    pub motion: u8,
    /// 54..=59.
    pub coord_system: u8,
    /// 17, 18, 19.
    pub plane: u8,
    /// G20 in force.
    pub inches: bool,
    /// G91 in force.
    pub incremental: bool,
    /// G93 in force.
    pub inverse_time: bool,
    /// G7 in force.
    pub diameter: bool,
    /// M3, M4 or M5.
    pub spindle: u8,
    /// M8 in force.
    pub coolant: bool,
    /// F as the parser holds it.
    pub feed: f64,
    /// S.
    pub rpm: f64,
}

/// `[GC:G0 G54 G17 G21 G90 G94 G8 M5 M9 T0 F0 S0]`.
pub fn gc_state(g: &GcSnapshot) -> String {
    format!(
        "[GC:G{} G{} G{} G{} G{} G{} G{} M{} M{} T0 F{} S{}]{EOL}",
        g.motion,
        g.coord_system,
        g.plane,
        if g.inches { 20 } else { 21 },
        if g.incremental { 91 } else { 90 },
        if g.inverse_time { 93 } else { 94 },
        if g.diameter { 7 } else { 8 },
        g.spindle,
        if g.coolant { 8 } else { 9 },
        number(g.feed, 0),
        number(g.rpm, 0),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formats() {
        assert_eq!(banner(), "\r\nGrblHAL 1.1f ['$' or '$HLP' for help]\r\n");
        assert_eq!(response(Ok(())), "ok\r\n");
        assert_eq!(response(Err(GrblError::SystemGcLock)), "error:9\r\n");
        assert_eq!(alarm(Alarm::SoftLimit), "ALARM:2\r\n");
        assert_eq!(number(-0.0001, 3), "0.000");
        assert_eq!(number(-1.5, 3), "-1.500");
        let s = StatusSnapshot {
            state: MachineState::Hold { complete: true },
            position: [1.0, -2.0, 90.0],
            diameter: false,
            blocks_free: 35,
            rx_free: 1023,
            line: Some(20),
            feed: 0.0,
            spindle: 0.0,
            wco: None,
            overrides: None,
            accessory: None,
        };
        assert_eq!(
            status(&s),
            "<Hold:0|MPos:1.000,0.000,-2.000,90.000|Bf:35,1023|Ln:20|FS:0,0>\r\n"
        );
        assert!(build_info(35, 1024, true).contains("[OPT:VNL,35,1024,4,0]"));
    }
}
