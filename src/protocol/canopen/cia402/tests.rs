//! Tests of the CiA 402 profile, kept apart from it for length: statusword decoding, the
//! controlword commands, the walk between states, faults, modes and objects.

use super::*;
use std::time::Duration;
use PowerState::*;

#[test]
fn cycle_periods_are_written_as_60c2h_value_and_power_of_ten() {
    let us = Duration::from_micros;
    // 4 ms = 40 × 10⁻⁴ s; 1 ms = 100 × 10⁻⁵ s; 250 µs as is; 2.5 ms = 250 × 10⁻⁵ s.
    assert_eq!(interpolation_time_period(us(4000)), Some((40, -4)));
    assert_eq!(interpolation_time_period(us(1000)), Some((100, -5)));
    assert_eq!(interpolation_time_period(us(250)), Some((250, -6)));
    assert_eq!(interpolation_time_period(us(2500)), Some((250, -5)));
    assert_eq!(
        interpolation_time_period(Duration::from_secs(100)),
        Some((100, 0))
    );
    // Significant digits beyond 255, sub-microseconds, zero, beyond 255 s: not exact.
    assert_eq!(interpolation_time_period(us(2560)), None);
    assert_eq!(
        interpolation_time_period(Duration::from_nanos(4_000_500)),
        None
    );
    assert_eq!(interpolation_time_period(Duration::ZERO), None);
    assert_eq!(interpolation_time_period(Duration::from_secs(1000)), None);
}

#[test]
fn statuswords_decode_by_the_standard_masks() {
    // Typical words: remote (bit 9) and voltage enabled (bit 4) set, as drives report.
    let table = [
        (0x0000, NotReadyToSwitchOn),
        (0x0250, SwitchOnDisabled),
        (0x0231, ReadyToSwitchOn),
        (0x0233, SwitchedOn),
        (0x1637, OperationEnabled),
        (0x0217, QuickStopActive),
        (0x021F, FaultReactionActive),
        (0x2218, Fault),
        (0x0208, Fault),
    ];
    for (word, state) in table {
        assert_eq!(PowerState::from_statusword(word), Ok(state), "{word:04X}");
    }
    // Don't-care bits do not matter: bit 5 in Switch on disabled and Fault,
    // everything above bit 6.
    assert_eq!(PowerState::from_statusword(0xFFF0), Ok(SwitchOnDisabled));
    assert_eq!(PowerState::from_statusword(0x0028), Ok(Fault));
}

#[test]
fn words_matching_no_pattern_are_refused() {
    // Ready to switch on without quick stop (bit 5); fault with bit 6; bit 1 alone.
    for word in [0x0001, 0x0048, 0x0002, 0x0063] {
        assert_eq!(
            PowerState::from_statusword(word),
            Err(UnknownStatusword(word))
        );
    }
    assert_eq!(
        UnknownStatusword(0x48).to_string(),
        "statusword 0x0048 matches no CiA 402 state"
    );
}

#[test]
fn statusword_bits() {
    let word = Statusword(0x3EB7);
    assert_eq!(word.state(), Ok(OperationEnabled));
    assert!(word.voltage_enabled());
    assert!(word.warning());
    assert!(word.remote());
    assert!(word.target_reached());
    assert!(word.internal_limit());
    assert!(word.following_target());
    assert!(word.following_error());
    let plain = Statusword(0x0027);
    assert!(!plain.voltage_enabled() && !plain.warning() && !plain.remote());
    assert!(!plain.target_reached() && !plain.internal_limit());
    assert!(!plain.following_target() && !plain.following_error());
    // The same bit 12 in interpolated position mode.
    assert!(word.ip_mode_active() && Statusword(0x1237).ip_mode_active());
    assert!(!plain.ip_mode_active());
}

#[test]
fn commands_are_the_profiles_words() {
    assert_eq!(Command::Shutdown.word(), 0x06);
    assert_eq!(Command::SwitchOn.word(), 0x07);
    assert_eq!(Command::EnableOperation.word(), 0x0F);
    assert_eq!(Command::DisableOperation.word(), 0x07);
    assert_eq!(Command::DisableVoltage.word(), 0x00);
    assert_eq!(Command::QuickStop.word(), 0x02);
    assert_eq!(Command::FaultReset.word(), 0x80);
    // Enable ip mode is bit 4, outside every command's bits.
    assert_eq!(ENABLE_IP_MODE, 1 << 4);
    for command in [
        Command::Shutdown,
        Command::SwitchOn,
        Command::EnableOperation,
        Command::DisableVoltage,
        Command::QuickStop,
        Command::FaultReset,
    ] {
        assert_eq!(command.word() & ENABLE_IP_MODE, 0, "{command:?}");
    }
}

/// The transitions of CiA 402's state diagram that commands cause, as (from, word, to).
fn transition(state: PowerState, word: u16) -> PowerState {
    let fault_reset = word & 0x80 != 0;
    let (so, ev, qs, eo) = (word & 1 != 0, word & 2 != 0, word & 4 != 0, word & 8 != 0);
    let shutdown = ev && qs && !so;
    let disable_voltage = !ev;
    let quick_stop = ev && !qs;
    match state {
        Fault if fault_reset => SwitchOnDisabled,
        _ if fault_reset => state,
        SwitchOnDisabled if shutdown => ReadyToSwitchOn,
        ReadyToSwitchOn if so && ev && qs => SwitchedOn,
        ReadyToSwitchOn if disable_voltage || quick_stop => SwitchOnDisabled,
        SwitchedOn if so && ev && qs && eo => OperationEnabled,
        SwitchedOn if shutdown => ReadyToSwitchOn,
        SwitchedOn if disable_voltage || quick_stop => SwitchOnDisabled,
        OperationEnabled if so && ev && qs && !eo => SwitchedOn,
        OperationEnabled if shutdown => ReadyToSwitchOn,
        OperationEnabled if disable_voltage => SwitchOnDisabled,
        OperationEnabled if quick_stop => QuickStopActive,
        QuickStopActive if disable_voltage => SwitchOnDisabled,
        _ => state,
    }
}

#[test]
fn every_state_walks_to_every_target() {
    let targets = [
        (Target::SwitchOnDisabled, SwitchOnDisabled),
        (Target::ReadyToSwitchOn, ReadyToSwitchOn),
        (Target::SwitchedOn, SwitchedOn),
        (Target::OperationEnabled, OperationEnabled),
    ];
    let starts = [
        SwitchOnDisabled,
        ReadyToSwitchOn,
        SwitchedOn,
        OperationEnabled,
        QuickStopActive,
        Fault,
    ];
    for (target, wanted) in targets {
        for start in starts {
            let mut state = start;
            let mut steps = 0;
            while state != wanted {
                state = transition(state, next_controlword(state, target));
                steps += 1;
                assert!(steps <= 5, "{start:?} → {target:?} stuck at {state:?}");
            }
            // Once there, the word holds the state.
            assert_eq!(transition(state, next_controlword(state, target)), wanted);
        }
    }
}

#[test]
fn the_walk_up_is_one_transition_a_command() {
    let target = Target::OperationEnabled;
    assert_eq!(next_controlword(SwitchOnDisabled, target), 0x06); // 2
    assert_eq!(next_controlword(ReadyToSwitchOn, target), 0x07); // 3
    assert_eq!(next_controlword(SwitchedOn, target), 0x0F); // 4
    assert_eq!(next_controlword(OperationEnabled, target), 0x0F);
    assert_eq!(next_controlword(QuickStopActive, target), 0x00); // 12
    assert_eq!(next_controlword(Fault, target), 0x80); // 15
                                                       // States the drive leaves by itself get a harmless word with bit 7 low.
    assert_eq!(next_controlword(NotReadyToSwitchOn, target), 0x00);
    assert_eq!(next_controlword(FaultReactionActive, target), 0x00);
    // Down in one transition each: 5, 8, 9.
    assert_eq!(next_controlword(OperationEnabled, Target::SwitchedOn), 0x07);
    assert_eq!(
        next_controlword(OperationEnabled, Target::ReadyToSwitchOn),
        0x06
    );
    assert_eq!(
        next_controlword(OperationEnabled, Target::SwitchOnDisabled),
        0x00
    );
}

#[test]
fn a_lasting_fault_gets_a_fresh_edge_every_other_word() {
    let mut sequencer = PowerSequencer::new(Target::OperationEnabled);
    let fault = 0x0218;
    let words: Vec<u16> = (0..4)
        .map(|_| sequencer.controlword(fault).unwrap())
        .collect();
    assert_eq!(words, [0x80, 0x00, 0x80, 0x00]);
    // After the reset the walk goes on with bit 7 low.
    assert_eq!(sequencer.controlword(0x0250), Ok(0x06));
    assert!(!sequencer.reached(0x0250));
    assert_eq!(sequencer.controlword(0x0231), Ok(0x07));
    assert_eq!(sequencer.controlword(0x0233), Ok(0x0F));
    assert!(sequencer.reached(0x1237));
    sequencer.set_target(Target::SwitchOnDisabled);
    assert!(!sequencer.reached(0x1237));
    assert_eq!(sequencer.controlword(0x1237), Ok(0x00));
    assert_eq!(
        sequencer.controlword(0x0001),
        Err(UnknownStatusword(0x0001))
    );
}

#[test]
fn a_fault_straight_after_a_reset_word_waits_one_word() {
    // The last word had bit 7 high (a fault reset that did not clear the fault):
    // the next must drop it before another edge can happen.
    let mut sequencer = PowerSequencer::new(Target::SwitchedOn);
    assert_eq!(sequencer.controlword(0x0008), Ok(0x80));
    assert_eq!(sequencer.controlword(0x000F), Ok(0x00)); // fault reaction: wait
    assert_eq!(sequencer.controlword(0x0008), Ok(0x80));
}

#[test]
fn modes_of_operation_values() {
    assert_eq!(Mode::CyclicSynchronousPosition.value(), 8);
    assert_eq!(Mode::InterpolatedPosition.value(), 7);
    assert_eq!(Mode::ProfilePosition.value(), 1);
    assert_eq!(Mode::CyclicSynchronousTorque.value(), 10);
    for value in [1, 2, 3, 4, 6, 7, 8, 9, 10] {
        assert_eq!(Mode::from_value(value).unwrap().value(), value);
    }
    for value in [0, 5, 11, -1] {
        assert_eq!(Mode::from_value(value), None);
    }
}

#[test]
fn object_indices() {
    use object::*;
    assert_eq!((CONTROLWORD, STATUSWORD), (0x6040, 0x6041));
    assert_eq!(
        (MODES_OF_OPERATION, MODES_OF_OPERATION_DISPLAY),
        (0x6060, 0x6061)
    );
    assert_eq!((TARGET_POSITION, POSITION_ACTUAL), (0x607A, 0x6064));
    assert_eq!(
        (FOLLOWING_ERROR_WINDOW, INTERPOLATION_DATA),
        (0x6065, 0x60C1)
    );
    assert_eq!((PRODUCER_HEARTBEAT, CONSUMER_HEARTBEAT), (0x1017, 0x1016));
    assert_eq!((DEVICE_TYPE, ERROR_REGISTER), (0x1000, 0x1001));
    assert_eq!(EMCY_FOLLOWING_ERROR, 0x8611);
}
