//! `$` commands (grblHAL's `system.c`): settings, reports, check mode, unlock and jogging,
//! each allowed in the states grblHAL allows it, and what a setting written changes.

use std::collections::VecDeque;

use super::{dialect, dynamics, Controller, Exec};
use crate::error::GrblError;
use crate::interpreter::{self, Step};
use crate::motion::Tag;
use crate::report::{self, Flags, MachineState};
use crate::settings;
use crate::system::SystemCommand;

/// The longest build string `$I=` stores (grblHAL's `stored_line_t` holds
/// `MAX_STORED_LINE_LENGTH` = 70 bytes with its terminator; `system.c` refuses a string of
/// 69 or more, `error:3`).
const MAX_BUILD_INFO: usize = 68;

impl Controller {
    /// Runs a `$` command; returns its result (`None` while a jog waits for planner room:
    /// it is answered when queued) and whether a soft reset follows the answer. States and
    /// errors as grblHAL's `system.c` has them for each command.
    pub(super) fn system(
        &mut self,
        command: SystemCommand,
        tag: Tag,
    ) -> (Option<Result<(), GrblError>>, bool) {
        if self.critical && !command.allowed_during_critical() {
            return (Some(Err(GrblError::NotAllowedCriticalEvent)), false);
        }
        let state = self.state();
        // Idle, or in alarm or check mode: where grblHAL reads and writes settings and
        // prints `$I` and `$N`.
        let settled = matches!(
            state,
            MachineState::Idle | MachineState::Alarm | MachineState::Check
        );
        let needs = |ok: bool| {
            if ok {
                Ok(())
            } else {
                Err(GrblError::IdleError)
            }
        };
        let result = match command {
            SystemCommand::Help => {
                self.output.push_str(&report::help());
                Ok(())
            }
            SystemCommand::HelpTopics => {
                self.output.push_str(&help_topics());
                Ok(())
            }
            SystemCommand::Settings => needs(!matches!(
                state,
                MachineState::Run | MachineState::Hold { .. }
            ))
            .map(|()| self.output.push_str(&report::settings(&self.settings))),
            SystemCommand::Setting(id) => needs(settled).and_then(|()| {
                let value = self.settings.text(id).ok_or(GrblError::SettingDisabled)?;
                self.output
                    .push_str(&format!("${id}={value}{}", report::EOL));
                Ok(())
            }),
            SystemCommand::SetSetting(id, value) => needs(settled)
                .and_then(|()| self.settings.store(id, &value))
                .map(|()| self.settings_changed(id)),
            SystemCommand::ParserState => {
                let gc = self.gc_report();
                self.output.push_str(&gc);
                // `$G` asks for the homed state in the next report (`system.c`).
                self.tracker.add(Flags {
                    homed: true,
                    ..Flags::default()
                });
                Ok(())
            }
            SystemCommand::Parameters => {
                let text = report::parameters(self.parser.g92, self.units());
                self.output.push_str(&text);
                Ok(())
            }
            SystemCommand::BuildInfo => needs(settled).map(|()| {
                let text = report::build_info(&report::BuildInfo {
                    build: &self.build_info,
                    blocks: self.options.planner_blocks,
                    rx_size: self.options.rx_buffer_size,
                    sync_on_offset_change: self.dialect.sync_on_offset_change,
                    legacy_realtime: self.settings.legacy_realtime(),
                    homing: self.settings.homing_enabled(),
                    lathe: self.settings.lathe_mode(),
                });
                self.output.push_str(&text);
            }),
            SystemCommand::SetBuildInfo(text) => needs(settled).and_then(|()| {
                if text.len() > MAX_BUILD_INFO {
                    return Err(GrblError::InvalidStatement);
                }
                self.build_info = text;
                Ok(())
            }),
            SystemCommand::StartupLines => needs(settled).map(|()| {
                self.output
                    .push_str(&format!("$N0={0}$N1={0}", report::EOL));
            }),
            SystemCommand::Home => needs(matches!(state, MachineState::Idle | MachineState::Alarm))
                .and(Err(GrblError::HomingDisabled)),
            SystemCommand::Unlock => {
                if self.alarm.take().is_some() {
                    self.output.push_str(&report::message("Caution: Unlocked"));
                }
                Ok(())
            }
            SystemCommand::CheckMode => {
                if self.check_mode.is_some() && state == MachineState::Check {
                    self.output.push_str(&report::message("Disabled"));
                    return (Some(Ok(())), true);
                }
                needs(state == MachineState::Idle).map(|()| {
                    self.check_mode = Some(self.parser.g92);
                    self.output.push_str(&report::message("Enabled"));
                })
            }
            SystemCommand::Jog(gcode) => {
                return match self.jog(&gcode, tag) {
                    Ok(true) => (Some(Ok(())), false),
                    Ok(false) => (None, false),
                    Err(error) => (Some(Err(error)), false),
                };
            }
            SystemCommand::AlarmCodes => {
                self.output.push_str(&report::alarm_codes());
                Ok(())
            }
            SystemCommand::ErrorCodes => {
                self.output.push_str(&report::error_codes());
                Ok(())
            }
            SystemCommand::SettingGroups => {
                self.output.push_str(&settings::groups());
                Ok(())
            }
            SystemCommand::SettingDetails => {
                self.output.push_str(&settings::details());
                Ok(())
            }
            SystemCommand::SettingDescription(id) => {
                // grblHAL (`output_setting_description`) prints the description of a setting
                // it has and nothing for another; the simulator has no descriptions to give
                // and prints what grblHAL prints for a setting without one.
                let mut at = 0;
                match interpreter::read_float(id.as_bytes(), &mut at) {
                    None => Err(GrblError::BadNumberFormat),
                    Some(id) if id.fract() != 0.0 => Err(GrblError::InvalidStatement),
                    Some(id) => {
                        let id = id.clamp(0.0, f64::from(u16::MAX)) as u16;
                        if self.settings.text(id).is_some() {
                            self.output
                                .push_str(&format!("[SETTINGDESCR:{id}|]{}", report::EOL));
                        }
                        Ok(())
                    }
                }
            }
            SystemCommand::Unsupported => Err(GrblError::InvalidStatement),
        };
        (Some(result), false)
    }

    /// A jog, `$J=` with `gcode` (grblHAL's `jog` in `system.c`, then `gc_execute_block`
    /// and `mc_jog_execute` in `motion_control.c`): only idle or jogging (`error:8`); a
    /// target beyond the soft limits is refused, `error:15` and no alarm, or with `$40=1`
    /// cut to them. `Ok(true)`: queued; `Ok(false)`: waiting for planner room (the line is
    /// then executed like a G1 and answered once queued).
    pub(super) fn jog(&mut self, gcode: &str, tag: Tag) -> Result<bool, GrblError> {
        if !matches!(self.state(), MachineState::Idle | MachineState::Jog) {
            return Err(GrblError::IdleError);
        }
        let mut jog = interpreter::jog(gcode, &self.parser, self.dialect)?;
        if self.settings.soft_limits() {
            let limits = self.limits();
            let target = &mut jog.request.target;
            if self.settings.jog_soft_limited() {
                for (t, (min, max)) in target.iter_mut().zip(limits) {
                    *t = t.clamp(min, max);
                }
            } else if self.outside_travel(*target) {
                return Err(GrblError::TravelExceeded);
            }
        }
        self.parser.position = jog.request.target;
        let tag = Tag { n: jog.n, ..tag };
        self.exec = Some(Exec {
            tag,
            text: String::new(),
            steps: VecDeque::from([Step::Motion(jog.request)]),
            dwell: None,
            soft_limit: false,
        });
        self.jogging = self.jogging || self.state() == MachineState::Idle;
        if self.run_exec_quietly() {
            return Ok(true);
        }
        Ok(false)
    }

    /// Runs the line just made the executing one without answering it; `true` if it is
    /// done (its steps all taken), `false` if it waits.
    pub(super) fn run_exec_quietly(&mut self) -> bool {
        let Some(mut exec) = self.exec.take() else {
            return true;
        };
        while let Some(Step::Motion(request)) = exec.steps.front().copied() {
            if self.motion.blocks_free() == 0 {
                self.exec = Some(exec);
                return false;
            }
            self.motion.push(request, exec.tag);
            exec.steps.pop_front();
        }
        true
    }

    /// A setting was written: what it changes beyond its value.
    pub(super) fn settings_changed(&mut self, id: u16) {
        match id {
            10 | 32 | 376 => {
                self.dialect = dialect(self.dialect.numbers, &self.settings);
                if !self.settings.lathe_mode() {
                    // `set_mode`: leaving lathe mode ends diameter mode.
                    self.parser.diameter = false;
                }
            }
            11 | 110..=123 => self.motion.set_dynamics(dynamics(&self.settings)),
            // `set_report_inches` refreshes the WCO (`system_flag_wco_change`).
            13 => self.tracker.add(Flags {
                wco: true,
                ..Flags::default()
            }),
            130..=133 => {
                let lengths = self.settings.travel();
                for (i, length) in lengths.into_iter().enumerate() {
                    self.travel[i] = travel(self.profile_travel[i], length);
                }
            }
            _ => {}
        }
    }
}

/// An axis' soft limits after `$13n` = `length`: the profile's, which `$$` shows as their
/// span, kept while the span is; else from the profile's minimum over `length`; an axis
/// the profile leaves unlimited gets grblHAL's own travel, `[−length, 0]`
/// (`settings.axis[].max_travel` is stored negative), and none for a length of 0.
fn travel(profile: (Option<f64>, Option<f64>), length: f64) -> (Option<f64>, Option<f64>) {
    match profile {
        // To within the 3 decimals `$$` shows: a span written back as read changes nothing.
        (Some(min), Some(max)) if (max - min - length).abs() < 5e-4 => profile,
        (Some(min), Some(_)) => (Some(min), Some(min + length)),
        _ if length == 0.0 => (None, None),
        _ => (Some(-length), Some(0.0)),
    }
}

/// `$HELP` (`report_help` without a topic): the topics, then the setting groups' names in
/// order.
fn help_topics() -> String {
    let eol = report::EOL;
    let mut groups: Vec<&str> = settings::GROUPS
        .iter()
        .filter(|(id, ..)| *id != 0)
        .map(|(_, _, name)| *name)
        .collect();
    groups.sort_unstable();
    let mut out = format!("Help topics:{eol} Commands{eol} Settings{eol}");
    for name in groups {
        out.push_str(&format!(" {name}{eol}"));
    }
    out
}
