//! What a grbl sender sees of grblHAL beyond grbl 1.1: its status report fields and their
//! refresh, the complete report (0x87), settings written with `$n=value`, jogging, `$I`,
//! the enumerations, its error numbers. Each expectation names the grblHAL/core source it
//! comes from.

use super::*;
use crate::MachineState;

/// The status report's fields after the state, without `<`, `>`.
fn fields(report: &str) -> Vec<String> {
    report
        .trim_matches(['<', '>'])
        .split('|')
        .skip(1)
        .map(str::to_owned)
        .collect()
}

/// The optional fields of the next report (everything after `FS:`).
fn optional(sim: &mut Controller) -> Vec<String> {
    let report = send(sim, "?").remove(0);
    let all = fields(&report);
    let fs = all.iter().position(|f| f.starts_with("FS:")).unwrap();
    all[fs + 1..].to_vec()
}

#[test]
fn reports_after_the_banner_show_overrides_first_and_wco_next() {
    // report.c: report_init_message zeroes both refresh counters; the first report shows
    // Ov (its counter is 0) with A: and TLR: (set by the reset), and delays the WCO due in
    // the same report to the next one; then nothing until a counter runs out, after 10
    // idle reports (REPORT_*_REFRESH_IDLE_COUNT, config.h).
    let mut sim = new_sim();
    assert_eq!(optional(&mut sim), ["Ov:100,100,100", "A:", "TLR:0"]);
    assert_eq!(optional(&mut sim), ["WCO:0.000,0.000,0.000,0.000"]);
    for _ in 0..8 {
        assert!(optional(&mut sim).is_empty());
    }
    // A refresh of Ov adds A: only for a spindle or coolant that is on.
    assert_eq!(optional(&mut sim), ["Ov:100,100,100"]);
    assert_eq!(optional(&mut sim), ["WCO:0.000,0.000,0.000,0.000"]);
    // After a soft reset the same again.
    sim.receive(&[0x18]);
    output(&mut sim);
    assert_eq!(optional(&mut sim), ["Ov:100,100,100", "A:", "TLR:0"]);
}

#[test]
fn changes_put_their_field_in_the_next_report() {
    let mut sim = new_sim();
    optional(&mut sim);
    optional(&mut sim);
    // G92: system_flag_wco_change; a coordinate system: WCS and WCO (gcode.c).
    send(&mut sim, "G92 X-1\n");
    assert_eq!(optional(&mut sim), ["WCO:1.000,0.000,0.000,0.000"]);
    send(&mut sim, "G55\n");
    assert_eq!(
        optional(&mut sim),
        ["WCO:1.000,0.000,0.000,0.000", "WCS:G55"]
    );
    // G7 (Report_LatheXMode, which asks for WCO too): X doubled, D:1.
    send(&mut sim, "G7\n");
    assert_eq!(optional(&mut sim), ["WCO:2.000,0.000,0.000,0.000", "D:1"]);
    // The spindle (spindle_control.c) and the coolant (coolant_control.c): A:S, A:SF.
    send(&mut sim, "M3 S1000\n");
    assert_eq!(optional(&mut sim), ["A:S"]);
    send(&mut sim, "M8\n");
    assert_eq!(optional(&mut sim), ["A:SF"]);
    // An override (planner.c): Ov, with A: as the override refresh shows it.
    sim.receive(&[0x91]);
    assert_eq!(optional(&mut sim), ["Ov:110,100,100", "A:SF"]);
    // $G asks for the homed state (system.c).
    send(&mut sim, "$G\n");
    assert_eq!(optional(&mut sim), ["H:0"]);
}

#[test]
fn the_complete_report_carries_every_field() {
    // 0x87, CMD_STATUS_REPORT_ALL (protocol.c, report.c): WCO, WCS, Ov, A:, Sc:, MPG:, H:,
    // D:, T:, TLR: and FW:grblHAL; no P: on a board without probe selection.
    let mut sim = new_sim();
    sim.receive(&[0x87]);
    let report = output(&mut sim).remove(0);
    assert_eq!(
        fields(&report)[3..],
        [
            "WCO:0.000,0.000,0.000,0.000",
            "WCS:G54",
            "Ov:100,100,100",
            "A:",
            "Sc:",
            "MPG:0",
            "H:0",
            "D:0",
            "T:0",
            "TLR:0",
            "FW:grblHAL"
        ]
    );
    // It clears what it showed: the next plain report has nothing more.
    assert!(optional(&mut sim).is_empty());
    // In alarm it names the alarm.
    send(&mut sim, "G0 Z-400\n");
    sim.receive(&[0x87]);
    assert!(output(&mut sim)[0].starts_with("<Alarm:2|"));
    assert!(send(&mut sim, "?")[0].starts_with("<Alarm|"));
}

#[test]
fn the_status_report_mask_and_inches_shape_the_report() {
    let mut sim = sim_35();
    optional(&mut sim);
    send(&mut sim, "G92 X-1\n");
    // $10=0: WPos and no buffer, line, speed or offsets (settings.h reportmask_t).
    assert_eq!(send(&mut sim, "$10=0\n"), ["ok"]);
    assert_eq!(
        send(&mut sim, "?"),
        ["<Idle|WPos:-1.000,0.000,0.000,0.000>"]
    );
    assert_eq!(send(&mut sim, "$10=2\n"), ["ok"]);
    assert_eq!(
        send(&mut sim, "?"),
        ["<Idle|WPos:-1.000,0.000,0.000,0.000|Bf:35,1023>"]
    );
    // $13=1: inches with 4 decimals, the rotary C in degrees (get_axis_values_inches).
    send(&mut sim, "$10=511\n$13=1\nG92.1\nG0 X25.4 C90\n");
    run_until_idle(&mut sim, 0.01, 10.0);
    let report = send(&mut sim, "?").remove(0);
    assert!(
        report.starts_with("<Idle|MPos:1.0000,0.0000,0.0000,90.000|"),
        "{report}"
    );
}

#[test]
fn settings_are_written_checked_and_kept() {
    let mut sim = new_sim();
    // settings.c: read_float / read_uint failing is error:2; setting_validate_me: out of
    // range 52, negative without a minimum 4; the set_ functions: 10 without homing, 17
    // without a laser; report.c / settings.c: an unknown setting 53.
    for (line, answer) in [
        ("$0=1", "error:52"),
        ("$0=abc", "error:2"),
        ("$1=70000", "error:52"),
        ("$1=1.5", "error:2"),
        ("$1=-1", "error:2"),
        ("$11=-0.01", "error:4"),
        ("$2=16", "error:52"),
        ("$13=2", "error:52"),
        ("$20=1", "error:10"),
        ("$40=1", "error:10"),
        ("$32=1", "error:17"),
        ("$32=3", "error:52"),
        ("$376=2", "error:52"),
        ("$398=20", "error:52"),
        ("$999=1", "error:53"),
        ("$-1", "error:3"),
        ("$1.5", "error:3"),
    ] {
        assert_eq!(send(&mut sim, &format!("{line}\n\n"))[0], answer, "{line}");
    }
    // Written, kept, listed.
    assert_eq!(send(&mut sim, "$1=255\n"), ["ok"]);
    assert_eq!(send(&mut sim, "$1\n"), ["$1=255", "ok"]);
    assert_eq!(send(&mut sim, "$11= 0.02\n"), ["ok"]);
    assert!(send(&mut sim, "$$\n").contains(&"$11=0.020".to_owned()));
    // A soft reset keeps them (they are stored).
    sim.receive(&[0x18]);
    output(&mut sim);
    assert_eq!(send(&mut sim, "$1\n"), ["$1=255", "ok"]);
    // The simulator's own refusal: a rate of 0 would stop the axis for ever.
    assert_eq!(send(&mut sim, "$110=0\n"), ["error:19"]);
}

#[test]
fn the_settings_are_grblhals_for_a_four_axis_lathe() {
    let mut sim = new_sim();
    let out = send(&mut sim, "$$\n");
    let ids: Vec<u16> = out
        .iter()
        .filter_map(|l| l.strip_prefix('$')?.split('=').next()?.parse().ok())
        .collect();
    assert!(ids.windows(2).all(|w| w[0] < w[1]), "ascending: {ids:?}");
    // config.h's defaults: $10=511 (bit 8, sync on WCO change, on), $32=2 (lathe mode,
    // DEFAULT_LATHE_MODE), $39=1 (legacy real-time commands), $376=1: C, axis 3, is rotary
    // and is printed shifted right by 3 (settings.c get_int, Settings_RotaryAxes).
    for expected in ["$10=511", "$32=2", "$39=1", "$376=1", "$100=250.00000"] {
        assert!(out.contains(&expected.to_owned()), "{expected}: {out:?}");
    }
    // The settings of hardware the board does not have are not listed.
    for absent in ["$6=", "$9=", "$14=", "$17=", "$19=", "$65="] {
        assert!(!out.iter().any(|l| l.starts_with(absent)), "{absent}");
    }
    assert_eq!(send(&mut sim, "$376=1\n"), ["ok"]);
    assert_eq!(send(&mut sim, "$376\n"), ["$376=1", "ok"]);
    // Sync on offset change off: $10 without bit 8, W in [OPT:].
    let mut sim = sim_with(ControllerOptions {
        sync_on_offset_change: false,
        ..ControllerOptions::default()
    });
    assert_eq!(send(&mut sim, "$10\n"), ["$10=255", "ok"]);
    assert!(send(&mut sim, "$I\n")
        .iter()
        .any(|l| l.starts_with("[OPT:VNLW,")));
}

#[test]
fn rate_and_travel_settings_change_the_machine() {
    let mut sim = new_sim();
    // $110 = 600 mm/min: a 10 mm rapid along X at 10 mm/s and 500 mm/s² takes
    // L/v + v/a = 1 + 0.02 s.
    assert_eq!(send(&mut sim, "$110=600\nG0 X10\n"), ["ok", "ok"]);
    run_until_idle(&mut sim, 0.001, 10.0);
    let block = executed(&sim.take_events()).remove(0);
    assert!((block.end_time - block.start_time - 1.02).abs() < 1e-9);
    // $130 from the profile's X −5..160 (165 mm): 100 mm makes X −5..95.
    assert_eq!(send(&mut sim, "$130=100\n"), ["ok"]);
    assert_eq!(
        send(&mut sim, "G0 X96\n"),
        ["ALARM:2", "[MSG:Reset to continue]", "error:15"]
    );
    // Disabling homing disables soft limits (settings.c set_homing_enable).
    sim.receive(&[0x18]);
    send(&mut sim, "$X\n");
    assert_eq!(send(&mut sim, "$22=0\n$20\n"), ["ok", "$20=0", "ok"]);
    assert_eq!(send(&mut sim, "G0 X96\n"), ["ok"]);
}

#[test]
fn lathe_mode_g92_persistence_and_rotary_c_are_settings() {
    let mut sim = new_sim();
    // $32=0 (settings.c set_mode): G7/G8 refused (gcode.c), not in $G.
    send(&mut sim, "G7\n$32=0\n");
    assert_eq!(send(&mut sim, "G7\n"), ["error:20"]);
    assert_eq!(
        send(&mut sim, "\n$G\n")[1],
        "[GC:G0 G54 G17 G21 G90 G94 G40 G49 G98 G50 M5 M9 T0 F0 S0.]"
    );
    // $376=0: C is linear, scaled by G20.
    send(&mut sim, "$376=0\nG20 G0 C1\n");
    run_until_idle(&mut sim, 0.01, 10.0);
    assert!((sim.position().c - 25.4).abs() < 1e-4);
    // $384=1: G92 forgotten at a reset.
    send(&mut sim, "G21 G92 X5\n$384=1\n");
    sim.receive(&[0x18]);
    output(&mut sim);
    assert!(send(&mut sim, "$#\n").contains(&"[G92:0.000,0.000,0.000,0.000]".to_owned()));
}

#[test]
fn a_jog_runs_like_a_g1_and_states_jog() {
    let mut sim = new_sim();
    // 10 mm at 600 mm/min (10 mm/s) and 500 mm/s²: L/v + v/a = 1.02 s.
    assert_eq!(send(&mut sim, "$J=G91 X10 F600\n"), ["ok"]);
    assert_eq!(sim.state(), MachineState::Jog);
    assert!(send(&mut sim, "?")[0].starts_with("<Jog|"));
    // G-code is locked out while jogging (protocol.c), a feed hold does nothing
    // (state_machine.c), another jog queues behind.
    assert_eq!(send(&mut sim, "G0 X0\n"), ["error:9"]);
    sim.receive(b"!");
    assert_eq!(sim.state(), MachineState::Jog);
    assert_eq!(send(&mut sim, "\n$J=G91 X5 F600\n"), ["ok", "ok"]);
    run_until_idle(&mut sim, 0.001, 10.0);
    let blocks = executed(&sim.take_events());
    assert_eq!(blocks.len(), 2);
    assert!(blocks.iter().all(|b| b.kind == crate::MoveKind::Jog));
    assert_eq!(sim.position().x, 15.0);
    assert_eq!(sim.state(), MachineState::Idle);
    // The feed override does not apply to a jog (mc_jog_execute: no_feed_override).
    sim.receive(&[0x92, 0x92, 0x92, 0x92, 0x92]);
    send(&mut sim, "$J=G91 X-10 F600\n");
    run_until_idle(&mut sim, 0.001, 10.0);
    let block = executed(&sim.take_events()).remove(0);
    assert!((block.end_time - block.start_time - 1.02).abs() < 1e-9);
    // The parser's modes are left alone: still G90, and G0 X0 is absolute.
    sim.receive(&[0x90]);
    assert_eq!(send(&mut sim, "G0 X0\n"), ["ok"]);
    run_until_idle(&mut sim, 0.001, 10.0);
    assert_eq!(sim.position().x, 0.0);
}

#[test]
fn jog_words_units_and_machine_coordinates() {
    let mut sim = new_sim();
    send(&mut sim, "G92 X-10\n");
    // G90: work coordinates (X1 is machine 11); G53: machine coordinates; G20: inches
    // for X and the feed, not for the rotary C.
    send(&mut sim, "$J=G90 X1 F600\n");
    run_until_idle(&mut sim, 0.001, 10.0);
    assert_eq!(sim.position().x, 11.0);
    send(&mut sim, "$J=G53 X1 F600\n");
    run_until_idle(&mut sim, 0.001, 10.0);
    assert_eq!(sim.position().x, 1.0);
    send(&mut sim, "$J=G20 G91 X1 C1 F10\n");
    run_until_idle(&mut sim, 0.001, 10.0);
    let block = executed(&sim.take_events()).pop().unwrap();
    assert!((block.to.x - 26.4).abs() < 1e-5 && (block.to.c - 1.0).abs() < 1e-6);
    // $G: still G21 G90.
    assert!(send(&mut sim, "$G\n")[0].contains(" G21 G90 "));
}

#[test]
fn jog_errors_are_grblhals() {
    let mut sim = new_sim();
    // gcode.c with the jog flag: F required (22), unused S (36), any G or M code but
    // G20/G21, G90/G91 and G53 (16); system.c: `$J` without `=` is 3.
    for (line, answer) in [
        ("$J=G91 X1", "error:22"),
        ("$J=G91 X1 F0", "error:22"),
        ("$J=G91 X1 F100 S5", "error:36"),
        ("$J=G91 G1 X1 F100", "error:16"),
        ("$J=G91 G0 X1 F100", "error:16"),
        ("$J=G91 X1 F100 M3", "error:16"),
        ("$J=G4 P1 F100", "error:16"),
        ("$J=G91 G2 X1 F100", "error:20"),
        ("$J", "error:3"),
    ] {
        assert_eq!(send(&mut sim, &format!("{line}\n\n"))[0], answer, "{line}");
    }
    // Beyond the soft limits: refused, no alarm (motion_control.c mc_jog_execute).
    assert_eq!(send(&mut sim, "$J=G53 X200 F600\n"), ["error:15"]);
    assert_eq!(sim.state(), MachineState::Idle);
    // Only idle or jogging (system.c jog): a program running, check mode, an alarm.
    send(&mut sim, "\nG0 X50\n");
    assert_eq!(send(&mut sim, "$J=G91 X1 F100\n"), ["error:8"]);
    run_until_idle(&mut sim, 0.01, 10.0);
    send(&mut sim, "$C\n");
    assert_eq!(send(&mut sim, "$J=G91 X1 F100\n"), ["error:8"]);
    send(&mut sim, "$C\n");
    output(&mut sim);
    // A critical alarm refuses it before anything (system.c: no allow_blocking), while the
    // settings stay readable.
    send(&mut sim, "G0 Z-400\n");
    assert_eq!(
        send(&mut sim, "$J=G91 X1 F100\n$11\n"),
        ["error:79", "$11=0.010", "ok"]
    );
}

#[test]
fn limited_jogs_stop_at_the_travel() {
    // $40=1 (with homing enabled, settings.c): the target is cut to the soft limits
    // instead of refused (mc_jog_execute: apply_travel_limits).
    let mut sim = new_sim();
    assert_eq!(send(&mut sim, "$22=1\n$40=1\n"), ["ok", "ok"]);
    assert_eq!(send(&mut sim, "$J=G53 X500 F6000\n"), ["ok"]);
    run_until_idle(&mut sim, 0.01, 10.0);
    assert_eq!(sim.position().x, 160.0);
}

#[test]
fn jog_cancel_stops_the_jog_and_drops_the_buffer() {
    let mut sim = new_sim();
    send(&mut sim, "$J=G91 X100 F600\n");
    run(&mut sim, 1.0, 0.001);
    // 0x85 (protocol.c CMD_JOG_CANCEL): the RX buffer is emptied, the half line with it,
    // and the jog slows to a stop at 500 mm/s² (10 mm/s → 0.1 mm more).
    sim.receive(b"$J=G91 X5");
    sim.receive(&[0x85]);
    assert_eq!(sim.state(), MachineState::Jog);
    run(&mut sim, 0.5, 0.001);
    assert_eq!(sim.state(), MachineState::Idle);
    let blocks = executed(&sim.take_events());
    assert_eq!(blocks.len(), 1);
    assert!(!blocks[0].completed);
    // Up to 1 s: 0.01 s of ramp and 0.99 s at 10 mm/s, 9.9 mm; then 0.1 mm of braking.
    let stop = sim.position().x;
    assert!((stop - 10.0).abs() < 1e-6, "{stop}");
    // The half line went: its end is an empty line; the next jog starts where the machine
    // stopped.
    assert_eq!(send(&mut sim, "\n$J=G91 X1 F600\n"), ["ok", "ok"]);
    run_until_idle(&mut sim, 0.001, 10.0);
    assert!((sim.position().x - (stop + 1.0)).abs() < 1e-6);
    // Idle, it only empties the buffer.
    sim.receive(b"G0 X");
    sim.receive(&[0x85]);
    assert_eq!(send(&mut sim, "\n"), ["ok"]);
}

#[test]
fn g_codes_grblhal_takes_and_refuses() {
    let mut sim = new_sim();
    // gcode.c: G98/G99 (modal group 10) are taken; G12 is no G-code (20); a macro call
    // without P is 28, one to a macro the controller does not have 39 (ngc_params.c).
    assert!(send(&mut sim, "G99\n$G\n")[1].contains(" G99 "));
    for (line, answer) in [
        ("G98", "ok"),
        ("G12", "error:20"),
        ("G66", "error:28"),
        ("G65 P9999", "error:39"),
        ("G67", "ok"),
        ("G53 G0 X1", "ok"),
        ("G80 G53 X1", "error:30"),
        ("G53 G92 X1", "error:21"),
    ] {
        assert_eq!(send(&mut sim, &format!("{line}\n\n"))[0], answer, "{line}");
    }
    // G53 moves in machine coordinates whatever G92 and G91 say.
    send(&mut sim, "G92 X-5\nG91 G53 G0 X2\n");
    run_until_idle(&mut sim, 0.01, 10.0);
    assert_eq!(sim.position().x, 2.0);
}

#[test]
fn ln_shows_the_last_line_number_when_nothing_is_queued() {
    // report.c: the current block's N, else gc_state.line_number, the N of the last line
    // the parser executed (0 without one).
    let mut sim = new_sim();
    send(&mut sim, "N7 G0 X1\n");
    run_until_idle(&mut sim, 0.01, 10.0);
    assert!(send(&mut sim, "?")[0].contains("|Ln:7|"));
    send(&mut sim, "G92 X0\n");
    assert!(!send(&mut sim, "?")[0].contains("|Ln:"));
}

#[test]
fn build_info_help_and_enumerations() {
    let mut sim = new_sim();
    let info = send(&mut sim, "$I\n");
    // report.c report_build_info: ENUMS, RT+ with $39=1, NOPROBE without a probe, LATHE in
    // lathe mode, SED always.
    assert!(info.contains(&"[NEWOPT:ENUMS,RT+,NOPROBE,LATHE,SED]".to_owned()));
    assert!(info.contains(&"[AXS:4:XYZC]".to_owned()));
    assert!(info.contains(&"[FIRMWARE:grblHAL]".to_owned()));
    // $I= sets the build string (system.c build_info); 69 characters or more are refused.
    assert_eq!(send(&mut sim, "$I=my lathe\n"), ["ok"]);
    assert!(send(&mut sim, "$I\n")[0].ends_with(":my lathe]"));
    assert_eq!(
        send(&mut sim, &format!("$I={}\n", "x".repeat(69))),
        ["error:3"]
    );
    // system.c: `$HLP` is no command; `$HELP` lists topics.
    assert_eq!(send(&mut sim, "$HLP\n\n")[0], "error:3");
    assert_eq!(
        send(&mut sim, "$HELP\n")[..3],
        ["Help topics:", " Commands", " Settings"]
    );
    // The enumerations ENUMS promises.
    let errors = send(&mut sim, "$EE\n");
    assert!(errors.contains(
        &"[ERRORCODE:53||Setting is not available, possibly due to limited driver support.]"
            .to_owned()
    ));
    assert!(send(&mut sim, "$EA\n")[1].starts_with("[ALARMCODE:2||Soft limit alarm."));
    assert!(send(&mut sim, "$ES\n")
        .contains(&"[SETTING:110|43|X-axis maximum rate|mm/min|6|#####0.000|||0|0]".to_owned()));
    assert!(send(&mut sim, "$EG\n").contains(&"[SETTINGGROUP:46|42|C-axis]".to_owned()));
    assert_eq!(send(&mut sim, "$SED=110\n"), ["[SETTINGDESCR:110|]", "ok"]);
}

#[test]
fn the_error_and_alarm_texts_are_grblhals() {
    use crate::error::{ALARM_CODES, ERROR_CODES};
    use crate::{Alarm, GrblError};
    // Every code the simulator answers is in grblHAL's table with the same text.
    let errors = [
        GrblError::ExpectedCommandLetter,
        GrblError::BadNumberFormat,
        GrblError::InvalidStatement,
        GrblError::NegativeValue,
        GrblError::HomingDisabled,
        GrblError::IdleError,
        GrblError::SystemGcLock,
        GrblError::SoftLimitError,
        GrblError::Overflow,
        GrblError::TravelExceeded,
        GrblError::InvalidJogCommand,
        GrblError::SettingDisabledLaser,
        GrblError::NonPositiveValue,
        GrblError::UnsupportedCommand,
        GrblError::ModalGroupViolation,
        GrblError::UndefinedFeedRate,
        GrblError::CommandValueNotInteger,
        GrblError::AxisCommandConflict,
        GrblError::WordRepeated,
        GrblError::NoAxisWords,
        GrblError::InvalidLineNumber,
        GrblError::ValueWordMissing,
        GrblError::G53InvalidMotionMode,
        GrblError::AxisWordsExist,
        GrblError::InvalidTarget,
        GrblError::UnusedWords,
        GrblError::ValueOutOfRange,
        GrblError::SettingValueOutOfRange,
        GrblError::SettingDisabled,
        GrblError::NotAllowedCriticalEvent,
    ];
    for error in errors {
        let text = ERROR_CODES.iter().find(|(c, _)| *c == error.code());
        assert_eq!(
            text.map(|t| t.1.to_owned()),
            Some(error.to_string()),
            "{error:?}"
        );
    }
    for alarm in [Alarm::SoftLimit, Alarm::AbortCycle, Alarm::ProfileError] {
        assert!(
            ALARM_CODES.iter().any(|(c, _)| *c == alarm.code()),
            "{alarm:?}"
        );
    }
}

#[test]
fn a_line_right_after_a_jog_cancel_runs() {
    // grbl suspends the main loop after a jog cancel until the machine stands (the jog's
    // cancel completes, then the state is Idle), so the line sent right after 0x85 is read
    // in Idle and runs: `ok` on grblHAL, not the `error:9` of a line read while jogging.
    let mut sim = new_sim();
    send(&mut sim, "$J=G91 X100 F600\n");
    run(&mut sim, 0.5, 0.001);
    sim.receive(&[0x85]);
    assert!(send(&mut sim, "G1 X20 F600\n").is_empty());
    run(&mut sim, 0.1, 0.001);
    assert_eq!(responses(&output(&mut sim)), ["ok"]);
}
