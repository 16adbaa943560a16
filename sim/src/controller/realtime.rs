//! Real-time commands (grblHAL's `protocol_enqueue_realtime_command`): status and parser
//! reports, feed hold, cycle start, overrides, soft reset and jog cancel, acted on the
//! moment their byte arrives, ahead of any line; and the alarms and reports they print.

use super::{Controller, Event, OVERRIDE_MAX, OVERRIDE_MIN};
use crate::error::Alarm;
use crate::guard::Breach;
use crate::interpreter::{MotionMode, ParserState};
use crate::protocol::Realtime;
use crate::report::{self, Flags, GcSnapshot, MachineState, StatusSnapshot, Tracker, Units};

impl Controller {
    pub(super) fn realtime(&mut self, command: Realtime) {
        match command {
            Realtime::Reset => self.soft_reset(),
            Realtime::StatusReport => {
                let report = self.status_report();
                self.output.push_str(&report);
            }
            Realtime::CompleteStatusReport => {
                self.tracker.add(Flags::everything());
                let report = self.status_report();
                self.output.push_str(&report);
            }
            Realtime::JogCancel => self.jog_cancel(),
            Realtime::ParserStateReport => {
                let gc = self.gc_report();
                self.output.push_str(&gc);
            }
            Realtime::FeedHold => {
                // Not during a jog: grblHAL's `state_set` refuses a hold from `Jog`
                // (`state_machine.c`); 0x85 is the way to stop one.
                if matches!(self.state(), MachineState::Idle | MachineState::Run) {
                    self.motion.feed_hold();
                }
            }
            Realtime::CycleStart => {
                if self.alarm.is_none() && self.motion.resume() {
                    self.pump();
                }
            }
            Realtime::FeedOverride(step) => {
                let next = step.apply(self.feed_override, OVERRIDE_MIN, OVERRIDE_MAX);
                self.set_overrides(next, self.rapid_override);
            }
            Realtime::RapidOverride(percent) => self.set_overrides(self.feed_override, percent),
            Realtime::SpindleOverride(step) => {
                let next = step.apply(self.spindle_override, OVERRIDE_MIN, OVERRIDE_MAX);
                if next != self.spindle_override {
                    self.tracker.add(Flags {
                        overrides: true,
                        ..Flags::default()
                    });
                }
                self.spindle_override = next;
            }
        }
        self.note_state();
    }

    pub(super) fn set_overrides(&mut self, feed: u8, rapid: u8) {
        if (feed, rapid) != (self.feed_override, self.rapid_override) {
            self.feed_override = feed;
            self.rapid_override = rapid;
            self.tracker.add(Flags {
                overrides: true,
                ..Flags::default()
            });
            self.motion
                .set_overrides(f64::from(feed) / 100.0, f64::from(rapid) / 100.0);
        }
    }

    /// grbl's soft reset: stop dead (an alarm if moving), forget every buffered byte and
    /// queued block, restore the parser's defaults, print the banner.
    pub(super) fn soft_reset(&mut self) {
        let moving = self.motion.abort(self.now);
        if moving {
            self.raise(Alarm::AbortCycle);
        }
        self.exec = None;
        self.jogging = false;
        self.jog_cancelling = false;
        self.rx.clear();
        self.assembler.clear();
        self.last_error = None;
        // grblHAL keeps G92 across a reset (stored in NVS) unless `$384=1`; changes made in
        // check mode are dropped with it.
        let g92 = self.check_mode.take().unwrap_or(self.parser.g92);
        let g92 = if self.settings.g92_volatile() {
            [0.0; 3]
        } else {
            g92
        };
        self.parser = ParserState::new(self.motion.position(), g92);
        self.critical = false;
        self.spindle.on = false;
        self.coolant = false;
        self.spindle_override = 100;
        self.set_overrides(100, 100);
        self.tracker = Tracker::after_reset();
        self.output.push_str(&report::banner());
        if self.alarm.is_some() {
            self.output
                .push_str(&report::message("'$H'|'$X' to unlock"));
        }
        self.events.push(Event::Reset { time: self.now });
        self.collect_executed();
    }

    pub(super) fn raise(&mut self, alarm: Alarm) {
        self.raise_with(alarm, None);
    }

    pub(super) fn raise_with(&mut self, alarm: Alarm, breach: Option<Breach>) {
        self.alarm = Some(alarm);
        self.critical |= alarm.is_critical();
        self.output.push_str(&report::alarm(alarm));
        if let Some(b) = &breach {
            self.output.push_str(&report::message(&b.message));
        }
        if alarm.is_critical() {
            self.output.push_str(&report::message("Reset to continue"));
        }
        self.events.push(Event::Alarm {
            time: self.now,
            alarm,
            breach,
        });
    }

    pub(super) fn units(&self) -> Units {
        Units {
            diameter: self.parser.diameter,
            inches: self.settings.report_inches(),
            c_rotary: self.settings.c_rotary(),
        }
    }

    pub(super) fn status_report(&mut self) -> String {
        let state = self.state();
        // The executing block's N, else the parser's last (grblHAL's `Ln:` falls back on
        // `gc_state.line_number`, `report.c`).
        let line = match self.motion.head_tag() {
            Some(tag) => tag.n.unwrap_or(0),
            None => self.parser.line_number,
        };
        let spindle_rpm = self.spindle.rpm * f64::from(self.spindle_override) / 100.0;
        let snapshot = StatusSnapshot {
            state,
            alarm: self.alarm,
            position: self.motion.position(),
            offset: self.parser.g92,
            coord_system: self.parser.coord_system,
            units: self.units(),
            mask: self.settings.report_mask(),
            lathe: self.settings.lathe_mode(),
            homing_axes: self.settings.homing_axes(),
            blocks_free: self.blocks_free(),
            rx_free: self.rx.free(),
            line: Some(line).filter(|&n| n > 0),
            feed: self.motion.speed() * 60.0,
            spindle: (self.spindle.on, self.spindle.ccw, spindle_rpm),
            coolant: self.coolant,
            overrides: [
                self.feed_override,
                self.rapid_override,
                self.spindle_override,
            ],
        };
        report::status(&snapshot, &mut self.tracker)
    }

    pub(super) fn gc_report(&self) -> String {
        let p = &self.parser;
        report::gc_state(&GcSnapshot {
            motion: match p.motion {
                MotionMode::Rapid => 0,
                MotionMode::Linear => 1,
                MotionMode::Cancelled => 80,
            },
            coord_system: p.coord_system,
            g92: p.g92 != [0.0; 3],
            lathe: self.settings.lathe_mode(),
            diameter: p.diameter,
            plane: p.plane,
            inches: p.inches,
            incremental: p.incremental,
            inverse_time: p.inverse_time,
            retract_r: p.retract_r,
            spindle: match (p.spindle.on, p.spindle.ccw) {
                (false, _) => 5,
                (true, false) => 3,
                (true, true) => 4,
            },
            coolant: p.coolant,
            feed: p.feed,
            rpm: p.spindle.rpm,
            units: self.units(),
        })
    }

    /// Jog cancel (0x85, grblHAL's `CMD_JOG_CANCEL`): the RX buffer and the line being
    /// read are dropped unanswered and the sticky error cleared, whatever the state; a jog
    /// slows to a stop and its queue is dropped, and the parser takes the position the
    /// machine stopped at. Until it stands the main loop reads no further line (grbl's
    /// suspend for a jog cancel), so a G-code line sent right after the cancel finds the
    /// machine idle and runs (`ok`, as on grblHAL) instead of `error:9`. A jog line already
    /// waiting for planner room is not in the buffer: as in grblHAL's `mc_line`, it is
    /// queued once the cancel has emptied the planner, and starts a new jog.
    pub(super) fn jog_cancel(&mut self) {
        self.rx.clear();
        self.assembler.clear();
        self.last_error = None;
        if self.state() == MachineState::Jog {
            self.jog_cancelling = true;
            self.motion.cancel(self.now);
            self.collect_executed();
            self.pump();
        }
    }
}
