//! The serial protocol: answers, the banner, `$` commands, the RX buffer, real-time bytes,
//! line ends and lengths, sticky errors.

use super::*;
use crate::MachineState;

#[test]
fn banner_at_power_up_and_after_reset() {
    // grbl's interface.md: the start-up message prints at power-up and after every reset.
    let banner = "\r\nGrblHAL 1.1f ['$' or '$HELP' for help]\r\n";
    let mut sim = Controller::new(&profile(), ControllerOptions::default()).unwrap();
    assert_eq!(sim.take_output(), banner.as_bytes());
    sim.receive(&[0x18]);
    assert_eq!(sim.take_output(), banner.as_bytes());
}

#[test]
fn one_response_per_line_in_order() {
    let mut sim = new_sim();
    // ok, error:20 (G2 unsupported), error:20 (sticky), ok (empty line clears),
    // ok ($ command), error:3 (unknown $), ok, ok (comment-only line after an ok).
    let out = send(
        &mut sim,
        "G21 G90\nG2 X1\nG0 X1\n\n$G\n$Q\n\nG0 Z1 (comment)\n(only a comment)\n",
    );
    assert_eq!(
        responses(&out),
        ["ok", "error:20", "error:20", "ok", "ok", "error:3", "ok", "ok", "ok"]
    );
    // The events number the lines in the order they were answered.
    let lines: Vec<u64> = sim
        .take_events()
        .iter()
        .filter_map(|e| match e {
            Event::Line { line, .. } => Some(*line),
            _ => None,
        })
        .collect();
    assert_eq!(lines, (1..=9).collect::<Vec<u64>>());
}

#[test]
fn line_ends_cr_lf_and_pairs() {
    let mut sim = new_sim();
    // \r alone, \n alone, and \r\n (one end, not an extra empty line).
    let out = send(&mut sim, "G0 X1\rG0 X2\nG0 X3\r\n");
    assert_eq!(responses(&out), ["ok", "ok", "ok"]);
    // stream.py's wake-up "\r\n\r\n" is two empty lines: two oks.
    assert_eq!(responses(&send(&mut sim, "\r\n\r\n")), ["ok", "ok"]);
}

#[test]
fn line_length_limit_is_error_11() {
    let mut sim = new_sim();
    // grblHAL's line buffer holds 256 characters; the 257th overflows it.
    let fits = format!("G0 X1 ({})", "a".repeat(256 - 8));
    assert_eq!(fits.len(), 256);
    assert_eq!(responses(&send(&mut sim, &format!("{fits}\n"))), ["ok"]);
    let long = format!("G0 X1 ({})", "a".repeat(257 - 8));
    assert_eq!(
        responses(&send(&mut sim, &format!("{long}\n"))),
        ["error:11"]
    );
    // error:11 is sticky too, until an empty line.
    assert_eq!(
        responses(&send(&mut sim, "G0 X2\n\nG0 X2\n")),
        ["error:11", "ok", "ok"]
    );
}

#[test]
fn sticky_error_until_empty_line_dollar_or_reset() {
    let mut sim = new_sim();
    // grblHAL (COMPATIBILITY_LEVEL 0): after error:N, G-code lines repeat it unparsed.
    let out = send(&mut sim, "G1 X1\nG0 X5\nG0 X6\n");
    assert_eq!(responses(&out), ["error:22", "error:22", "error:22"]);
    sim.advance(1.0).unwrap();
    assert_eq!(sim.position().x, 0.0, "refused lines do not move");
    // A successful $ command clears it …
    let out = send(&mut sim, "$G\nG0 X5\n");
    assert_eq!(responses(&out), ["ok", "ok"]);
    // … a failing one sets its own code …
    run_until_idle(&mut sim, 0.05, 10.0);
    let out = send(&mut sim, "$Q\nG0 X6\n");
    assert_eq!(responses(&out), ["error:3", "error:3"]);
    // … and a soft reset clears it.
    sim.receive(&[0x18]);
    output(&mut sim);
    assert_eq!(responses(&send(&mut sim, "G0 X6\n")), ["ok"]);
}

#[test]
fn build_info_reports_blocks_and_rx_size() {
    // interface.md: [OPT:…,blocks,rx] — the planner blocks and the RX buffer size.
    for (blocks, rx) in [(35, 1024), (15, 128)] {
        let mut sim = sim_with(ControllerOptions {
            planner_blocks: blocks,
            rx_buffer_size: rx,
            ..ControllerOptions::default()
        });
        let out = send(&mut sim, "$I\n");
        let opt = out
            .iter()
            .find(|l| l.starts_with("[OPT:"))
            .expect("an OPT line");
        let fields: Vec<&str> = opt
            .trim_start_matches("[OPT:")
            .trim_end_matches(']')
            .split(',')
            .collect();
        assert_eq!(fields[1], blocks.to_string(), "{opt}");
        assert_eq!(fields[2], rx.to_string(), "{opt}");
        assert!(out.iter().any(|l| l.starts_with("[VER:")));
        assert_eq!(out.last().map(String::as_str), Some("ok"));
        // The status report's free counts start at the same sizes (the ring keeps one
        // byte free).
        let status = send(&mut sim, "?");
        assert!(
            status[0].contains(&format!("|Bf:{blocks},{}|", rx - 1)),
            "{status:?}"
        );
    }
}

#[test]
fn settings_list_the_profiles_axes_in_grbl_numbering() {
    let mut sim = new_sim();
    let out = send(&mut sim, "$$\n");
    // sim.toml: X and Z 3000 mm/min, 500 mm/s², X −5..160, Z −300..300; C 72000 deg/min,
    // 7200 deg/s², unlimited. X Y Z C are axes 0..3.
    for expected in [
        "$110=3000.000",
        "$112=3000.000",
        "$113=72000.000",
        "$120=500.000",
        "$123=7200.000",
        "$130=165.000",
        "$132=600.000",
        "$133=0.000",
        "$20=1",
        "$22=0",
    ] {
        assert!(
            out.iter().any(|l| l == expected),
            "{expected} missing: {out:?}"
        );
    }
    assert_eq!(out.last().map(String::as_str), Some("ok"));
    assert_eq!(send(&mut sim, "$112\n"), ["$112=3000.000", "ok"]);
    // A setting grblHAL does not have is error:53, "setting disabled" (report.c's
    // report_grbl_setting).
    assert_eq!(send(&mut sim, "$999\n"), ["error:53"]);
}

#[test]
fn dollar_commands_and_their_errors() {
    let mut sim = new_sim();
    // report.c's report_help_message, whatever the build.
    assert_eq!(
        send(&mut sim, "$\n"),
        [
            "[HLP:$$ $# $G $I $N $x=val $Nx=line $J=line $SLP $C $X $H $B ~ ! ? ctrl-x]",
            "ok"
        ]
    );
    // report.c's report_gcode_modes in lathe mode: G7/G8 after the coordinate system,
    // G97 after the feed mode, then G40 G49 G98 G50, S through ftoa with no decimals.
    assert_eq!(
        send(&mut sim, "$G\n"),
        [
            "[GC:G0 G54 G8 G17 G21 G90 G94 G97 G40 G49 G98 G50 M5 M9 T0 F0 S0.]",
            "ok"
        ]
    );
    assert_eq!(send(&mut sim, "$N\n"), ["$N0=", "$N1=", "ok"]);
    // No homing switches: error 5.
    assert_eq!(send(&mut sim, "$H\n"), ["error:5"]);
    // Not idle (a move under way): $$, $I, $N, $C and settings answer error 8 (system.c).
    send(&mut sim, "\nG0 X100\n");
    sim.advance(0.1).unwrap();
    for command in ["$$", "$I", "$N", "$C", "$11", "$11=0.02"] {
        assert_eq!(
            send(&mut sim, &format!("{command}\n")),
            ["error:8"],
            "{command}"
        );
    }
    // $G, $# and $X are allowed in any state.
    assert_eq!(send(&mut sim, "$X\n"), ["ok"]);
    assert_eq!(
        send(&mut sim, "$#\n").last().map(String::as_str),
        Some("ok")
    );
    let params = {
        run_until_idle(&mut sim, 0.05, 10.0);
        send(&mut sim, "G92 X0\n$#\n")
    };
    assert!(
        params.contains(&"[G92:100.000,0.000,0.000,0.000]".to_owned()),
        "{params:?}"
    );
}

#[test]
fn realtime_status_mid_line_does_not_corrupt_it() {
    let mut sim = new_sim();
    sim.receive(b"N7 G0 X");
    let out = send(&mut sim, "?");
    // The report comes at once; the half line is still waiting.
    assert_eq!(out.len(), 1);
    assert!(
        out[0].starts_with("<Idle|MPos:0.000,0.000,0.000,0.000|"),
        "{out:?}"
    );
    let out = send(&mut sim, "1?2!~0\n");
    // One more report (the `!` held the idle machine, `~` released it), then the answer.
    assert_eq!(out.iter().filter(|l| l.starts_with('<')).count(), 1);
    assert_eq!(responses(&out), ["ok"]);
    run_until_idle(&mut sim, 0.05, 10.0);
    // The line that ran is "N7 G0 X120".
    assert_eq!(sim.position().x, 120.0);
    let blocks = executed(&sim.take_events());
    assert_eq!(blocks[0].n, Some(7));
}

#[test]
fn status_report_fields() {
    let mut sim = sim_35();
    send(&mut sim, "M3 S3000\nN42 G1 X50 F600\n");
    sim.advance(1.0).unwrap();
    let report = send(&mut sim, "?").remove(0);
    // State, MPos with X Y Z C (Y always 0), buffer state, the executing N, feed 600 and
    // the spindle speed, then (report.c: the override counter starts at 0 with the
    // banner) the overrides and the spindle running clockwise.
    assert!(report.starts_with("<Run|MPos:"), "{report}");
    let fields: Vec<&str> = report.trim_matches(['<', '>']).split('|').collect();
    let mpos: Vec<f64> = fields[1]
        .trim_start_matches("MPos:")
        .split(',')
        .map(|v| v.parse().unwrap())
        .collect();
    assert_eq!(mpos.len(), 4);
    assert_eq!(mpos[1], 0.0);
    // After 1 s at 10 mm/s (with a 0.01 s ramp at 500 mm/s²): 9.9 mm.
    assert!((mpos[0] - 9.9).abs() < 1e-3, "{report}");
    assert_eq!(fields[2], "Bf:34,1023");
    assert_eq!(fields[3], "Ln:42");
    assert_eq!(fields[4], "FS:600,3000");
    assert_eq!(fields[5..], ["Ov:100,100,100", "A:S", "TLR:0"]);
}

#[test]
fn rx_bytes_leave_the_buffer_only_when_the_planner_takes_the_line() {
    let mut sim = sim_35();
    // 35 blocks fill the planner, the 36th line waits in the parser for room.
    let program: String = (1..=36).map(|i| format!("G1 X{i} F60\n")).collect();
    sim.receive(program.as_bytes());
    assert_eq!(responses(&output(&mut sim)).len(), 35);
    assert_eq!(sim.blocks_free(), 0);
    assert_eq!(sim.rx_free(), 1023);
    // The next line stays in the RX buffer, byte for byte.
    sim.receive(b"G1 X37 F60\n");
    assert_eq!(sim.rx_free(), 1023 - 11);
    assert!(output(&mut sim).is_empty());
    // When the first block completes (1 mm at 1 mm/s), the waiting line is planned and
    // answered, and the buffered one is read and waits in its place.
    run(&mut sim, 1.1, 0.01);
    assert_eq!(responses(&output(&mut sim)), ["ok"]);
    assert_eq!(sim.rx_free(), 1023);
}

/// Streams `lines` with character counting against `budget` bytes, advancing 10 ms at a
/// time; returns the answers and whether the controller reported an overflow.
fn stream_counting(rx_size: usize, lines: Vec<String>, budget: usize) -> (Vec<String>, bool) {
    let mut sim = sim_with(ControllerOptions {
        rx_buffer_size: rx_size,
        ..ControllerOptions::default()
    });
    let mut sender = CountingSender::new(lines, budget);
    let mut overflow = false;
    for _ in 0..100_000 {
        sender.service(&mut sim);
        overflow |= sim
            .take_events()
            .iter()
            .any(|e| matches!(e, Event::RxOverflow { .. }));
        if sender.done() {
            break;
        }
        sim.advance(0.01).unwrap();
    }
    assert!(sender.done(), "stream did not finish");
    (sender.answers, overflow)
}

#[test]
fn character_counting_never_overflows_at_128_or_1024() {
    for rx in [128, 1024] {
        let lines = zigzag(600);
        let count = lines.len();
        // The budget is the size `$I` reports. The ring holds one byte less, but the line
        // the parser is blocked on is always counted in flight and already out of the
        // buffer, so the buffer never holds more than the budget less that line.
        let (answers, overflow) = stream_counting(rx, lines, rx);
        assert!(!overflow, "rx {rx}");
        assert_eq!(answers.len(), count);
        assert!(answers.iter().all(|a| a == "ok"), "rx {rx}");
    }
}

#[test]
fn ignoring_character_counting_overflows_and_is_reported() {
    for rx in [128, 1024] {
        let mut sim = sim_with(ControllerOptions {
            rx_buffer_size: rx,
            ..ControllerOptions::default()
        });
        let lines = zigzag(600);
        let text: String = lines.iter().map(|l| format!("{l}\n")).collect();
        sim.receive(text.as_bytes());
        let printed = output(&mut sim);
        assert!(printed.contains(&"[MSG:RX overflow]".to_owned()), "rx {rx}");
        let events = sim.take_events();
        assert!(events
            .iter()
            .any(|e| matches!(e, Event::RxOverflow { dropped, .. } if *dropped > 0)));
        // Every line still gets exactly one answer; the damaged ones error:11.
        let mut answers = responses(&printed);
        for _ in 0..10_000 {
            if answers.len() == lines.len() {
                break;
            }
            sim.advance(0.05).unwrap();
            answers.extend(responses(&output(&mut sim)));
        }
        assert_eq!(answers.len(), lines.len(), "rx {rx}");
        assert!(answers.contains(&"error:11".to_owned()), "rx {rx}");
    }
}

#[test]
fn idle_feed_hold_is_hold_0_and_cycle_start_releases_it() {
    let mut sim = new_sim();
    sim.receive(b"!");
    assert_eq!(sim.state(), MachineState::Hold { complete: true });
    // Lines are still taken while held, but nothing moves.
    assert_eq!(responses(&send(&mut sim, "G0 X10\n")), ["ok"]);
    sim.advance(1.0).unwrap();
    assert_eq!(sim.position().x, 0.0);
    sim.receive(b"~");
    run_until_idle(&mut sim, 0.05, 10.0);
    assert_eq!(sim.position().x, 10.0);
}

/// A controller whose planner and RX buffer are filled by one slow move and as many
/// 9-byte lines (`G1 X1.0\n` and the like) as fill the buffer up to `free` bytes free.
fn filled(options: ControllerOptions, free: usize) -> Controller {
    let mut sim = sim_with(options);
    let blocks = sim.options().planner_blocks;
    // One move of 10 mm at 1 mm/min runs for ten minutes: nothing leaves the planner.
    let mut text = String::from("G1 X10 F1\n");
    for i in 0..blocks {
        text.push_str(&format!("X{}\n", 20 + i % 50));
    }
    sim.receive(text.as_bytes());
    sim.take_output();
    let fill = sim.rx_free() - free;
    // Lines of `X1.5` padded with spaces to nine bytes, then the rest as one line.
    let mut bytes = Vec::new();
    while bytes.len() + 9 <= fill {
        bytes.extend_from_slice(b"X1.5    \n");
    }
    bytes.resize(fill - 1, b' ');
    bytes.push(b'\n');
    sim.receive(&bytes);
    assert_eq!(sim.rx_free(), free);
    sim
}

#[test]
fn a_link_with_backpressure_holds_real_time_bytes_behind_a_full_buffer() {
    // The receive interrupt (grblHAL's UART drivers): `?` and `!` act at a full buffer.
    let mut sim = filled(ControllerOptions::default(), 0);
    let answer = send(&mut sim, "?");
    assert!(answer[0].starts_with("<Run|"), "{answer:?}");
    // grblHAL's Simulator (mcu.c reads the UART only with more than 100 bytes free): at
    // 100 free a `?` and a `!` wait in the link; the machine runs on unheld.
    let options = ControllerOptions {
        rx_backpressure: Some(100),
        ..ControllerOptions::default()
    };
    let mut sim = filled(options.clone(), 100);
    assert!(send(&mut sim, "?!").is_empty());
    run(&mut sim, 1.0, 0.01);
    assert!(output(&mut sim).is_empty());
    assert_eq!(sim.state(), MachineState::Run);
    // With one byte more free the link delivers again: the report, then the hold.
    let mut sim = filled(options.clone(), 101);
    assert!(send(&mut sim, "?")[0].starts_with("<Run|"));
    sim.receive(b"!");
    assert!(matches!(sim.state(), MachineState::Hold { .. }));
    // Held bytes wait in order and arrive as lines are read: the slow move ends after
    // 600 s, the planner takes a line from the buffer, and the `?` behind it is answered.
    let mut sim = filled(options, 100);
    sim.receive(b"?");
    run(&mut sim, 601.0, 0.5);
    let printed = output(&mut sim);
    assert!(
        printed.iter().any(|l| l.starts_with("<Run|")),
        "{printed:?}"
    );
    // A reserve that leaves no room is refused.
    let bad = Controller::new(
        &profile(),
        ControllerOptions {
            rx_buffer_size: 128,
            rx_backpressure: Some(127),
            ..ControllerOptions::default()
        },
    );
    assert!(matches!(
        bad,
        Err(crate::ConfigError::Option {
            name: "rx_backpressure",
            ..
        })
    ));
}

#[test]
fn the_planner_holds_grblhals_default_100_blocks() {
    // grblHAL's config.h: DEFAULT_PLANNER_BUFFER_BLOCKS 100, shown by `$398`, `Bf:` and
    // `[OPT:…,blocks,rx]`.
    let mut sim = new_sim();
    assert_eq!(send(&mut sim, "$398\n"), ["$398=100", "ok"]);
    assert!(send(&mut sim, "?")[0].contains("|Bf:100,1023|"));
    let info = send(&mut sim, "$I\n");
    assert!(
        info.iter()
            .any(|l| l.starts_with("[OPT:") && l.ends_with(",100,1024,4,0]")),
        "{info:?}"
    );
}
