//! The CiA 402 power state machine (6040h in, 6041h out): the states, the controlword's
//! transitions, the statusword, and faults. Apart from the cycle and the communication
//! objects because it is the profile's own automaton, checked transition by transition.

use serde::Serialize;

use super::{Drive, DriveEvent};

/// CiA 402 power drive system states.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum PowerState {
    /// Statusword `x0xx 0000`.
    NotReadyToSwitchOn,
    /// `x1xx 0000`.
    SwitchOnDisabled,
    /// `x01x 0001`.
    ReadyToSwitchOn,
    /// `x01x 0011`.
    SwitchedOn,
    /// `x01x 0111`.
    OperationEnabled,
    /// `x00x 0111`.
    QuickStopActive,
    /// `x0xx 1111`.
    FaultReactionActive,
    /// `x0xx 1000`.
    Fault,
}

impl Drive {
    /// Statusword 6041h.
    pub fn statusword(&self) -> u16 {
        let state = match self.power {
            PowerState::NotReadyToSwitchOn => 0x00,
            PowerState::SwitchOnDisabled => 0x40,
            PowerState::ReadyToSwitchOn => 0x21,
            PowerState::SwitchedOn => 0x23,
            PowerState::OperationEnabled => 0x27,
            PowerState::QuickStopActive => 0x07,
            PowerState::FaultReactionActive => 0x0F,
            PowerState::Fault => 0x08,
        };
        let mut word = state | 1 << 4 | 1 << 9;
        if self.following() {
            word |= 1 << 12;
        }
        if self.following_error {
            word |= 1 << 13;
        }
        word
    }

    /// A fault from outside the CANopen interface (a machine's safety chain, a
    /// supervisor): the drive goes through Fault reaction active to Fault and sends EMCY
    /// `code`, as for a fault of its own. Nothing happens in Fault (the first fault
    /// stands).
    pub fn external_fault(&mut self, code: u16) {
        if self.power != PowerState::Fault {
            self.fault(code);
        }
    }

    /// Enters power state `state`, with an event if that is a change.
    pub(super) fn set_power(&mut self, state: PowerState) {
        if state != self.power {
            self.power = state;
            self.events.push(DriveEvent::Power {
                time: self.now,
                state,
            });
        }
    }

    /// A fault: through Fault reaction active to Fault, error register bit 0 (generic) set,
    /// EMCY `code` sent.
    pub(super) fn fault(&mut self, code: u16) {
        self.set_power(PowerState::FaultReactionActive);
        self.set_power(PowerState::Fault);
        self.error_register |= 0x01;
        self.events.push(DriveEvent::Fault {
            time: self.now,
            code,
        });
        self.emcy(code);
    }

    /// A controlword written (by SDO or RPDO).
    pub(super) fn command(&mut self, word: u16) {
        let rising_reset = word & 0x80 != 0 && self.controlword & 0x80 == 0;
        self.controlword = word;
        if self.power == PowerState::Fault {
            if rising_reset {
                self.following_error = false;
                self.error_register = 0;
                self.set_power(PowerState::SwitchOnDisabled);
                self.emcy(0x0000);
            }
            return;
        }
        if word & 0x80 != 0 {
            return;
        }
        self.set_power(next_power_state(self.power, word));
    }
}

/// CiA 402's transitions caused by a controlword with bit 7 low.
fn next_power_state(state: PowerState, word: u16) -> PowerState {
    use PowerState::*;
    let bits = word & 0x0F;
    let disable_voltage = bits & 0b0010 == 0;
    let quick_stop = !disable_voltage && bits & 0b0100 == 0;
    let shutdown = bits & 0b0111 == 0b0110;
    let switch_on = bits == 0b0111;
    let enable = bits == 0b1111;
    match state {
        SwitchOnDisabled if shutdown => ReadyToSwitchOn,
        ReadyToSwitchOn if switch_on => SwitchedOn,
        ReadyToSwitchOn if enable => OperationEnabled,
        SwitchedOn if enable => OperationEnabled,
        ReadyToSwitchOn | SwitchedOn if disable_voltage || quick_stop => SwitchOnDisabled,
        SwitchedOn | OperationEnabled if shutdown => ReadyToSwitchOn,
        OperationEnabled if switch_on => SwitchedOn,
        OperationEnabled if disable_voltage => SwitchOnDisabled,
        OperationEnabled if quick_stop => QuickStopActive,
        QuickStopActive if disable_voltage => SwitchOnDisabled,
        QuickStopActive if enable => OperationEnabled,
        other => other,
    }
}
