//! grblHAL's settings as `$$` lists them, `$n` reads them and `$n=value` writes them.
//!
//! The table is the core's setting list (`setting_detail[]` in grblHAL/core `settings.c`)
//! as a 4-axis X Y Z C lathe build prints it (`report_grbl_settings` in `report.c` lists the
//! available settings in ascending order). The names, units, formats and ranges are the ones
//! `$ES` reports; the defaults are the core's (`config.h`), except those the machine profile
//! or the controller's options decide (rates, accelerations, travel, spindle range, junction
//! deviation, planner blocks, soft limits). Settings of hardware the simulated board does
//! not have are not listed, as grblHAL's `is_setting_available` hides them: the probe
//! (`$6`, `$19`, `$65`), laser mode (`$9`) and control inputs (`$14`, `$17`).
//!
//! Writing follows `settings_store_setting` (`settings.c`): the value is read as a number
//! (`read_float` for decimals, `read_uint` for the rest; either failing is `error:2`),
//! checked against its format and range (`setting_validate_me`: `error:4` below zero
//! without a minimum, `error:52` out of range), then by the setting's own rule (soft limits
//! and limited jogging need homing, `error:10`; laser mode needs a laser, `error:17`).
//! Which settings change what the simulator does is the controller's business; see the
//! crate's README.

use crate::error::GrblError;
use crate::interpreter::read_float;

/// How a setting's value is written and checked (grblHAL's `setting_datatype_t`, in the
/// numbering `$ES` prints).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// 0 or 1.
    Bool,
    /// A bit mask over the names in the setting's format.
    Bitfield,
    /// A bit mask whose first bit enables the rest.
    XBitfield,
    /// One of the names in the setting's format.
    Radio,
    /// A mask over the axes X Y Z C.
    AxisMask,
    /// A whole number.
    Integer,
    /// A decimal number, printed with the format's decimals.
    Decimal,
}

impl Format {
    /// The number `$ES` prints for it.
    fn code(self) -> u8 {
        match self {
            Format::Bool => 0,
            Format::Bitfield => 1,
            Format::XBitfield => 2,
            Format::Radio => 3,
            Format::AxisMask => 4,
            Format::Integer => 5,
            Format::Decimal => 6,
        }
    }
}

/// One setting as grblHAL describes it (`setting_detail_t`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Def {
    /// Its number.
    pub id: u16,
    /// The group `$EG` lists it under.
    pub group: u16,
    /// Its name.
    pub name: &'static str,
    /// Its unit, if it has one.
    pub unit: &'static str,
    /// How its value is written.
    pub format: Format,
    /// The format string: the names of a bit field or radio button, or the picture of a
    /// number (`#####0.000`: three decimals).
    pub spec: &'static str,
    /// The least value, if limited.
    pub min: &'static str,
    /// The greatest value, if limited.
    pub max: &'static str,
    /// A change takes effect at the next reboot.
    pub reboot: bool,
    /// 0 is allowed below the minimum (the setting is then off).
    pub allow_null: bool,
    /// The core's default.
    pub default: &'static str,
}

#[allow(clippy::too_many_arguments)]
const fn def(
    id: u16,
    group: u16,
    name: &'static str,
    unit: &'static str,
    datatype: u8,
    spec: &'static str,
    min: &'static str,
    max: &'static str,
    reboot: bool,
    allow_null: bool,
    default: &'static str,
) -> Def {
    let format = match datatype {
        0 => Format::Bool,
        1 => Format::Bitfield,
        2 => Format::XBitfield,
        3 => Format::Radio,
        4 => Format::AxisMask,
        5 => Format::Integer,
        _ => Format::Decimal,
    };
    Def {
        id,
        group,
        name,
        unit,
        format,
        spec,
        min,
        max,
        reboot,
        allow_null,
        default,
    }
}

/// Every setting listed, in ascending order.
pub const TABLE: [Def; 85] = [
    def(0, 35, "Step pulse time", "microseconds", 6, "#0.0", "2.0", "", false, false, "5.0"),
    def(1, 35, "Step idle delay", "milliseconds", 5, "####0", "", "65535", false, false, "25"),
    def(2, 35, "Step pulse invert", "", 4, "", "", "", false, false, "0"),
    def(3, 35, "Step direction invert", "", 4, "", "", "", false, false, "0"),
    def(4, 35, "Invert stepper enable output(s)", "", 4, "", "", "", false, false, "15"),
    def(5, 3, "Invert limit inputs", "", 4, "", "", "", false, false, "0"),
    def(10, 1, "Status report options", "", 1, "Position in machine coordinate,Buffer state,Line numbers,Feed & speed,Pin state,Work coordinate offset,Overrides,Probe coordinates,Buffer sync on WCO change,Parser state,Alarm substatus,Run substatus,Enable when homing,Distance-to-go", "", "", false, false, "511"),
    def(11, 1, "Junction deviation", "mm", 6, "#####0.000", "", "", false, false, "0.010"),
    def(12, 1, "Arc tolerance", "mm", 6, "#####0.000", "", "", false, false, "0.002"),
    def(13, 1, "Report in inches", "", 0, "", "", "", false, false, "0"),
    def(15, 5, "Invert coolant outputs", "", 1, "Flood,Mist", "", "", false, false, "0"),
    def(18, 3, "Pullup disable limit inputs", "", 4, "", "", "", false, false, "0"),
    def(20, 3, "Soft limits enable", "", 0, "", "", "", false, false, "0"),
    def(21, 3, "Hard limits enable", "", 2, "Enable,Strict mode,Disable for rotary axes", "", "", false, false, "0"),
    def(22, 11, "Homing cycle", "", 2, "Enable,Enable single axis commands,Homing on startup required,Set machine origin to 0,Two switches shares one input,Allow manual,Override locks,N/A,N/A,Per axis feedrates,Run startup scripts only on homing completed", "", "", false, false, "0"),
    def(23, 11, "Homing direction invert", "", 4, "", "", "", false, false, "0"),
    def(24, 11, "Homing locate feed rate", "mm/min", 6, "#####0.0", "", "", false, false, "25.0"),
    def(25, 11, "Homing search seek rate", "mm/min", 6, "#####0.0", "", "", false, false, "500.0"),
    def(26, 11, "Homing switch debounce delay", "milliseconds", 5, "##0", "", "", false, false, "250"),
    def(27, 11, "Homing switch pull-off distance", "mm", 6, "#####0.000", "", "", false, false, "1.000"),
    def(28, 1, "G73 Retract distance", "mm", 6, "#####0.000", "", "", false, false, "0.100"),
    def(29, 35, "Pulse delay", "microseconds", 6, "#0.0", "", "20", false, false, "0.0"),
    def(30, 6, "Maximum spindle speed", "RPM", 6, "#####0.000", "", "", false, false, "1000.000"),
    def(31, 6, "Minimum spindle speed", "RPM", 6, "#####0.000", "", "", false, false, "0.000"),
    def(32, 1, "Mode of operation", "", 3, "Normal,Laser mode,Lathe mode", "", "", false, false, "2"),
    def(33, 6, "Spindle PWM frequency", "Hz", 6, "#####0", "", "", false, false, "5000.0"),
    def(34, 6, "Spindle PWM off value", "percent", 6, "##0.0", "", "100", false, false, "0.0"),
    def(35, 6, "Spindle PWM min value", "percent", 6, "##0.0", "", "100", false, false, "0.0"),
    def(36, 6, "Spindle PWM max value", "percent", 6, "##0.0", "", "100", false, false, "100.0"),
    def(37, 35, "Steppers to keep enabled", "", 4, "", "", "", false, false, "0"),
    def(39, 1, "Enable legacy RT commands", "", 0, "", "", "", false, false, "1"),
    def(40, 14, "Limit jog commands", "", 0, "", "", "", false, false, "0"),
    def(41, 13, "Parking cycle", "", 2, "Enable,Deactivate upon init,Enable parking override control", "", "", false, false, "0"),
    def(42, 13, "Parking axis", "", 3, "X,Y,Z", "", "", false, false, "2"),
    def(43, 11, "Homing passes", "", 5, "##0", "1", "128", false, false, "1"),
    def(44, 11, "Axes homing, first phase", "", 4, "", "", "", false, false, "4"),
    def(45, 11, "Axes homing, second phase", "", 4, "", "", "", false, false, "3"),
    def(46, 11, "Axes homing, third phase", "", 4, "", "", "", false, false, "0"),
    def(47, 11, "Axes homing, fourth phase", "", 4, "", "", "", false, false, "0"),
    def(56, 13, "Parking pull-out distance", "mm", 6, "###0.0", "", "", false, false, "5.0"),
    def(57, 13, "Parking pull-out rate", "mm/min", 6, "###0.0", "", "", false, false, "100.0"),
    def(58, 13, "Parking target", "mm", 6, "-###0.0", "-100000", "", false, false, "-5.0"),
    def(59, 13, "Parking fast rate", "mm/min", 6, "###0.0", "", "", false, false, "500.0"),
    def(60, 1, "Restore overrides", "", 0, "", "", "", false, false, "0"),
    def(61, 13, "Safety door options", "", 1, "Ignore when idle,Keep coolant state on door open", "", "", false, false, "0"),
    def(62, 1, "Sleep enable", "", 0, "", "", "", false, false, "0"),
    def(63, 1, "Feed hold actions", "", 1, "Disable laser during hold,Restore spindle and coolant state on resume,Set RPM to minimum (except for laser M4)", "", "", false, false, "3"),
    def(64, 1, "Force init alarm", "", 0, "", "", "", false, false, "0"),
    def(100, 43, "X-axis travel resolution", "step/mm", 6, "#####0.000##", "", "", false, false, "250.00000"),
    def(101, 44, "Y-axis travel resolution", "step/mm", 6, "#####0.000##", "", "", false, false, "250.00000"),
    def(102, 45, "Z-axis travel resolution", "step/mm", 6, "#####0.000##", "", "", false, false, "250.00000"),
    def(103, 46, "C-axis travel resolution", "step/deg", 6, "#####0.000##", "", "", false, false, "250.00000"),
    def(110, 43, "X-axis maximum rate", "mm/min", 6, "#####0.000", "", "", false, false, "500.000"),
    def(111, 44, "Y-axis maximum rate", "mm/min", 6, "#####0.000", "", "", false, false, "500.000"),
    def(112, 45, "Z-axis maximum rate", "mm/min", 6, "#####0.000", "", "", false, false, "500.000"),
    def(113, 46, "C-axis maximum rate", "deg/min", 6, "#####0.000", "", "", false, false, "500.000"),
    def(120, 43, "X-axis acceleration", "mm/sec^2", 6, "#####0.000", "", "", false, false, "10.000"),
    def(121, 44, "Y-axis acceleration", "mm/sec^2", 6, "#####0.000", "", "", false, false, "10.000"),
    def(122, 45, "Z-axis acceleration", "mm/sec^2", 6, "#####0.000", "", "", false, false, "10.000"),
    def(123, 46, "C-axis acceleration", "deg/sec^2", 6, "#####0.000", "", "", false, false, "10.000"),
    def(130, 43, "X-axis maximum travel", "mm", 6, "#####0.000", "", "", false, false, "200.000"),
    def(131, 44, "Y-axis maximum travel", "mm", 6, "#####0.000", "", "", false, false, "200.000"),
    def(132, 45, "Z-axis maximum travel", "mm", 6, "#####0.000", "", "", false, false, "200.000"),
    def(133, 46, "C-axis maximum travel", "deg", 6, "#####0.000", "", "", false, false, "200.000"),
    def(341, 9, "Tool change mode", "", 3, "Normal,Manual touch off,Manual touch off @ G59.3,Automatic touch off @ G59.3,Ignore M6", "", "", false, false, "0"),
    def(342, 9, "Tool change probing distance", "mm", 6, "#####0.0", "", "", false, false, "30.0"),
    def(343, 9, "Tool change locate feed rate", "mm/min", 6, "#####0.0", "", "", false, false, "25.0"),
    def(344, 9, "Tool change search seek rate", "mm/min", 6, "#####0.0", "", "", false, false, "200.0"),
    def(345, 9, "Tool change probe pull-off rate", "mm/min", 6, "#####0.0", "", "", false, false, "200.0"),
    def(346, 9, "Tool change options", "", 1, "Restore position after M6,Change tool at G30,Fast probe pull off", "", "", false, false, "1"),
    def(376, 35, "Rotary axes", "", 1, "C-Axis", "", "", false, false, "1"),
    def(384, 1, "Disable G92 persistence", "", 0, "", "", "", false, false, "0"),
    def(392, 13, "Spindle on delay", "s", 6, "#0.0", "0.5", "20", false, true, "4.0"),
    def(393, 13, "Coolant on delay", "s", 6, "#0.0", "0.5", "20", false, true, "1.0"),
    def(394, 6, "Spindle on delay", "s", 6, "#0.0", "0.5", "20", false, true, "0.0"),
    def(398, 1, "Planner buffer blocks", "", 5, "####0", "30", "1000", true, false, "100"),
    def(481, 1, "Autoreport interval", "ms", 5, "###0", "100", "1000", true, true, "0"),
    def(485, 9, "Keep tool number over reboot", "", 0, "", "", "", false, false, "0"),
    def(486, 1, "Lock coordinate systems", "", 1, "G59.1,G59.2,G59.3", "", "", false, false, "0"),
    def(538, 35, "Fast rotary go to G28", "", 1, "C-Axis", "", "", false, false, "0"),
    def(539, 6, "Spindle off delay", "s", 6, "#0.0", "0.5", "20", false, true, "0.0"),
    def(673, 5, "Coolant on delay", "s", 6, "#0.0", "0.5", "20", false, true, "0.0"),
    def(676, 1, "Reset actions", "", 1, "Clear homed status if position was lost,Clear offsets (except G92),Clear rapids override,Clear feed override", "", "", false, false, "15"),
    def(680, 35, "Stepper enable delay", "ms", 5, "##0", "", "500", false, false, "0"),
    def(701, 1, "Rotary options", "", 2, "Fix feedrate,Revert metric conversion", "", "", false, false, "0"),
];

/// The setting groups `$EG` lists (grblHAL's `setting_group_detail[]`): number, parent,
/// name. Only groups that hold a listed setting.
pub const GROUPS: [(u16, u16, &str); 15] = [
    (0, 0, "Root"),
    (1, 0, "General"),
    (3, 0, "Limits"),
    (5, 0, "Coolant"),
    (6, 0, "Spindle"),
    (9, 0, "Tool change"),
    (11, 0, "Homing"),
    (13, 0, "Parking/Safety door"),
    (14, 0, "Jogging"),
    (35, 0, "Stepper"),
    (42, 0, "Axis"),
    (43, 42, "X-axis"),
    (44, 42, "Y-axis"),
    (45, 42, "Z-axis"),
    (46, 42, "C-axis"),
];

/// Bits of `$10`, the status report options (grblHAL's `reportmask_t`, `settings.h`).
pub mod report_bits {
    /// Positions as `MPos` (machine), else `WPos` (work).
    pub const MACHINE_POSITION: u32 = 1 << 0;
    /// `Bf:` planner blocks and RX bytes free.
    pub const BUFFER_STATE: u32 = 1 << 1;
    /// `Ln:` the executing line's N.
    pub const LINE_NUMBERS: u32 = 1 << 2;
    /// `FS:` feed and spindle speed.
    pub const FEED_SPEED: u32 = 1 << 3;
    /// `WCO:` the work coordinate offset, now and then.
    pub const WORK_COORD_OFFSET: u32 = 1 << 5;
    /// `Ov:` the overrides, now and then.
    pub const OVERRIDES: u32 = 1 << 6;
    /// Wait for the queue to empty before a work offset changes.
    pub const SYNC_ON_WCO_CHANGE: u32 = 1 << 8;
    /// `Alarm:N`: the alarm's number after the state.
    pub const ALARM_SUBSTATE: u32 = 1 << 10;
}

/// The controller's settings: one value per [`TABLE`] entry.
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    values: Vec<f64>,
}

/// What the machine profile and the controller's options decide of the settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Initial {
    /// `$11`, mm.
    pub junction_deviation: f64,
    /// `$30` and `$31`, rpm: maximum and minimum spindle speed.
    pub spindle: (f64, f64),
    /// `$110`–`$113`, units/min, X Y Z C.
    pub max_rate: [f64; 4],
    /// `$120`–`$123`, units/s².
    pub accel: [f64; 4],
    /// `$130`–`$133`, units: the travel's length, 0 for none.
    pub travel: [f64; 4],
    /// `$398`.
    pub planner_blocks: usize,
    /// `$10` bit 8.
    pub sync_on_offset_change: bool,
}

fn index(id: u16) -> Option<usize> {
    TABLE.iter().position(|d| d.id == id)
}

/// The number of names in a bit field's or radio button's format.
fn entries(spec: &str) -> u32 {
    spec.split(',').count() as u32
}

/// Decimals a number's picture asks for (grblHAL's `get_decimal_places`: one without a
/// point).
fn decimals(spec: &str) -> usize {
    spec.find('.').map_or(1, |dot| spec.len() - dot - 1)
}

/// grblHAL's `read_uint`: an optional `+`, digits, and a fraction of zeros at most; `None`
/// for a sign, a non-zero fraction or no digit at all.
fn read_uint(text: &str) -> Option<u32> {
    let text = text.strip_prefix('+').unwrap_or(text);
    let (mut value, mut any, mut point) = (0u32, false, false);
    for byte in text.bytes() {
        match byte {
            b'0'..=b'9' if point => {
                any = true;
                if byte != b'0' {
                    return None;
                }
            }
            b'0'..=b'9' => {
                any = true;
                value = value
                    .saturating_mul(10)
                    .saturating_add(u32::from(byte - b'0'));
            }
            b'.' if !point => point = true,
            _ => break,
        }
    }
    any.then_some(value)
}

/// A limit of the table (`""`: none) as a number.
fn limit(text: &str) -> Option<f64> {
    let mut at = 0;
    (!text.is_empty())
        .then(|| read_float(text.as_bytes(), &mut at))
        .flatten()
}

impl Settings {
    /// The core's defaults, with what the machine and the options decide.
    pub fn new(initial: &Initial) -> Settings {
        let mut values: Vec<f64> = TABLE
            .iter()
            .map(|d| limit(d.default).unwrap_or(0.0))
            .collect();
        let mut set = |id: u16, value: f64| {
            if let Some(i) = index(id) {
                values[i] = value;
            }
        };
        set(11, initial.junction_deviation);
        set(30, initial.spindle.0);
        set(31, initial.spindle.1);
        for axis in 0..4u16 {
            let i = usize::from(axis);
            set(110 + axis, initial.max_rate[i]);
            set(120 + axis, initial.accel[i]);
            set(130 + axis, initial.travel[i]);
        }
        set(398, initial.planner_blocks as f64);
        let report = 511
            & !if initial.sync_on_offset_change {
                0
            } else {
                report_bits::SYNC_ON_WCO_CHANGE
            };
        set(10, f64::from(report));
        // The simulator's soft limits are on from the start, the profile's travel (see
        // the README: grblHAL would need homing for that).
        set(20, 1.0);
        Settings { values }
    }

    fn get(&self, id: u16) -> f64 {
        index(id).map_or(0.0, |i| self.values[i])
    }

    fn put(&mut self, id: u16, value: f64) {
        if let Some(i) = index(id) {
            self.values[i] = value;
        }
    }

    /// The value of setting `id` as `$$` prints it, if it is listed.
    pub fn text(&self, id: u16) -> Option<String> {
        let i = index(id)?;
        Some(Self::format(&TABLE[i], self.values[i]))
    }

    fn format(def: &Def, value: f64) -> String {
        match def.format {
            Format::Decimal => crate::report::number(value, decimals(def.spec)),
            _ => format!("{}", value as u32),
        }
    }

    /// Every setting as `(number, value)`, ascending, as `$$` prints them.
    pub fn list(&self) -> Vec<(u16, String)> {
        TABLE
            .iter()
            .zip(&self.values)
            .map(|(d, &v)| (d.id, Self::format(d, v)))
            .collect()
    }

    /// Writes setting `id` from the text after `=` (leading spaces allowed), as
    /// `settings_store_setting` does; see the module docs for the errors.
    pub fn store(&mut self, id: u16, text: &str) -> Result<(), GrblError> {
        let i = index(id).ok_or(GrblError::SettingDisabled)?;
        let def = TABLE[i];
        let text = text.trim_start_matches(' ');
        let value = if def.format == Format::Decimal {
            let mut at = 0;
            let value = read_float(text.as_bytes(), &mut at).ok_or(GrblError::BadNumberFormat)?;
            if let Some(min) = limit(def.min) {
                if !(value >= min || (def.allow_null && value == 0.0)) {
                    return Err(GrblError::SettingValueOutOfRange);
                }
            } else if value < 0.0 {
                return Err(GrblError::NegativeValue);
            }
            if limit(def.max).is_some_and(|max| value > max) {
                return Err(GrblError::SettingValueOutOfRange);
            }
            value
        } else {
            let value = read_uint(text).ok_or(GrblError::BadNumberFormat)?;
            let within = match def.format {
                Format::Bool => value <= 1,
                Format::Bitfield | Format::XBitfield => {
                    u64::from(value) < 1u64 << entries(def.spec)
                }
                Format::Radio => value < entries(def.spec),
                // Four axes: X Y Z C.
                Format::AxisMask => value < 1 << 4,
                _ => {
                    let (min, max) = (limit(def.min), limit(def.max));
                    let v = f64::from(value);
                    min.is_none_or(|min| v >= min || (def.allow_null && value == 0))
                        && max.is_none_or(|max| v <= max)
                }
            };
            if !within {
                return Err(GrblError::SettingValueOutOfRange);
            }
            f64::from(value)
        };
        self.apply(id, value)
    }

    /// The setting's own rule (grblHAL's `set_…` function for it), then the value stored.
    fn apply(&mut self, id: u16, value: f64) -> Result<(), GrblError> {
        let value = match id {
            // `set_soft_limits_enable`, `set_jog_soft_limited`: only with homing enabled.
            20 | 40 if value != 0.0 && !self.homing_enabled() => {
                return Err(GrblError::SoftLimitError)
            }
            // `set_hard_limits_enable`: the other bits only with the first.
            21 if value as u32 & 1 == 0 => 0.0,
            // `set_homing_enable`: disabling homing disables soft limits and limited jogs.
            22 if value as u32 & 1 == 0 => {
                self.put(20, 0.0);
                self.put(40, 0.0);
                0.0
            }
            // `set_mode`: laser mode needs a spindle that can be a laser; the ring is not.
            32 if value == 1.0 => return Err(GrblError::SettingDisabledLaser),
            // A rate or acceleration of 0 would stop the axis for ever (grblHAL takes it;
            // the simulator's planner cannot divide by it).
            110 | 112 | 113 | 120 | 122 | 123 if value == 0.0 => {
                return Err(GrblError::NonPositiveValue)
            }
            _ => value,
        };
        self.put(id, value);
        Ok(())
    }

    /// `$10`, the status report options (see [`report_bits`]).
    pub fn report_mask(&self) -> u32 {
        self.get(10) as u32
    }

    /// `$11`, mm.
    pub fn junction_deviation(&self) -> f64 {
        self.get(11)
    }

    /// `$13`: positions and rates reported in inches.
    pub fn report_inches(&self) -> bool {
        self.get(13) != 0.0
    }

    /// `$20`: soft limits on.
    pub fn soft_limits(&self) -> bool {
        self.get(20) != 0.0
    }

    /// `$22` bit 0: homing enabled.
    pub fn homing_enabled(&self) -> bool {
        self.get(22) as u32 & 1 != 0
    }

    /// `$32 = 2`: lathe mode (G7/G8, X as a diameter in G7).
    pub fn lathe_mode(&self) -> bool {
        self.get(32) == 2.0
    }

    /// `$39`: `?`, `!` and `~` are real-time commands everywhere.
    pub fn legacy_realtime(&self) -> bool {
        self.get(39) != 0.0
    }

    /// `$40`: a jog beyond the soft limits is cut to them instead of refused.
    pub fn jog_soft_limited(&self) -> bool {
        self.get(40) != 0.0
    }

    /// `$110`–`$113` of X, Z, C (units/min).
    pub fn max_rate(&self) -> [f64; 3] {
        [110, 112, 113].map(|id| self.get(id))
    }

    /// `$120`–`$123` of X, Z, C (units/s²).
    pub fn accel(&self) -> [f64; 3] {
        [120, 122, 123].map(|id| self.get(id))
    }

    /// `$130`–`$133` of X, Z, C: the travel's length, 0 for none.
    pub fn travel(&self) -> [f64; 3] {
        [130, 132, 133].map(|id| self.get(id))
    }

    /// `$44`–`$47` name axes to home (with `$22`'s single-axis or manual homing as
    /// alternatives): the report shows `H:` when asked (`report.c`).
    pub fn homing_axes(&self) -> bool {
        [44, 45, 46, 47].iter().any(|&id| self.get(id) != 0.0)
            || self.get(22) as u32 & 0b10_0010 != 0
    }

    /// `$376` bit 0: C is rotary (never scaled to inches).
    pub fn c_rotary(&self) -> bool {
        self.get(376) as u32 & 1 != 0
    }

    /// `$384`: G92 offsets are forgotten at a reset.
    pub fn g92_volatile(&self) -> bool {
        self.get(384) != 0.0
    }
}

/// `$ES`: every setting as `[SETTING:id|group|name|unit|datatype|format|min|max|reboot|null]`
/// (grblHAL's `report_settings_details`, machine readable).
pub fn details() -> String {
    let eol = crate::report::EOL;
    TABLE
        .iter()
        .map(|d| {
            format!(
                "[SETTING:{}|{}|{}|{}|{}|{}|{}|{}|{}|{}]{eol}",
                d.id,
                d.group,
                d.name,
                d.unit,
                d.format.code(),
                d.spec,
                d.min,
                d.max,
                u8::from(d.reboot),
                u8::from(d.allow_null)
            )
        })
        .collect()
}

/// `$EG`: the setting groups as `[SETTINGGROUP:id|parent|name]`.
pub fn groups() -> String {
    let eol = crate::report::EOL;
    GROUPS
        .iter()
        .map(|(id, parent, name)| format!("[SETTINGGROUP:{id}|{parent}|{name}]{eol}"))
        .collect()
}
