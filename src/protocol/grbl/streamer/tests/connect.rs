//! Connecting: a controller whose banner waits in the port, one that resets when the port
//! opens (it drops what is sent while it boots, then prints its banner), one whose banner
//! comes after its first answer; and the rule that once the program has started a banner
//! is a reset.

use super::*;

const BANNER: &[u8] = b"\r\nGrblHAL 1.1f ['$' or '$HELP' for help]\r\n";
const IDLE: &[u8] = b"<Idle|MPos:0.000,0.000,0.000,0.000|Bf:35,1023|FS:0,0>\r\n";

/// `whirl stream`'s configuration: `$I` and the state asked first.
fn connecting() -> StreamerConfig {
    StreamerConfig {
        check_state: true,
        ..StreamerConfig::default()
    }
}

/// Answers `$I` as grblHAL does, with a 1024-byte buffer.
fn build_info() -> &'static [u8] {
    b"[VER:1.1f.20260817:]\r\n[OPT:VNL,35,1024,4,0]\r\nok\r\n"
}

fn no_reset(events: &[Event]) {
    assert!(
        !events
            .iter()
            .any(|e| matches!(e, Event::Reset | Event::Stopped { .. })),
        "{events:?}"
    );
}

#[test]
fn a_banner_waiting_in_the_port_is_read_as_the_boot() {
    let mut streamer = Streamer::new(moves(3), connecting()).unwrap();
    assert_eq!(streamer.transmit().unwrap(), b"?");
    // The banner from before the port opened, then the answer to `?`.
    streamer.receive(BANNER);
    // Asked again: a `?` sent before a banner may have been lost in the boot.
    assert_eq!(streamer.transmit().unwrap(), b"?");
    streamer.receive(IDLE);
    assert_eq!(streamer.transmit().unwrap(), b"$I\n");
    streamer.receive(build_info());
    assert!(streamer.transmit().unwrap().starts_with(b"G1 X0 F100\n"));
    let events: Vec<Event> = streamer.events().collect();
    assert!(events.iter().any(|e| matches!(e, Event::Banner(_))));
    no_reset(&events);
}

#[test]
fn a_board_that_resets_on_open_is_asked_until_it_answers() {
    let mut streamer = Streamer::new(moves(3), connecting()).unwrap();
    // Booting: the `?` and the polls' are dropped, nothing answers, no line goes out.
    assert_eq!(streamer.transmit().unwrap(), b"?");
    for tick in 1..=5 {
        assert!(streamer.poll(DEFAULT_POLL_INTERVAL * tick));
        assert_eq!(streamer.transmit().unwrap(), b"?");
    }
    // The boot ends with the banner (grblHAL prints it before it reads anything).
    streamer.receive(BANNER);
    assert_eq!(streamer.transmit().unwrap(), b"?");
    streamer.receive(IDLE);
    assert_eq!(streamer.transmit().unwrap(), b"$I\n");
    no_reset(&streamer.events().collect::<Vec<_>>());
}

#[test]
fn a_banner_after_the_first_answer_but_before_the_program_is_a_late_boot() {
    // A board that answers `?`, then prints its banner (some print it when the host opens
    // their USB port): `$I` was in flight and is lost with the buffer.
    let mut streamer = Streamer::new(moves(3), connecting()).unwrap();
    streamer.transmit();
    streamer.receive(IDLE);
    assert_eq!(streamer.transmit().unwrap(), b"$I\n");
    streamer.receive(BANNER);
    assert_eq!(streamer.in_flight_bytes(), 0);
    // The state is asked again, then `$I`, then the program.
    assert_eq!(streamer.transmit().unwrap(), b"?");
    assert_eq!(streamer.transmit(), None);
    streamer.receive(IDLE);
    assert_eq!(streamer.transmit().unwrap(), b"$I\n");
    streamer.receive(build_info());
    assert_eq!(streamer.rx_size(), 1024);
    let lines = streamer.transmit().unwrap();
    assert_eq!(lines, b"G1 X0 F100\nG1 X1 F100\nG1 X2 F100\n");
    streamer.receive(b"ok\r\nok\r\nok\r\n");
    let events: Vec<Event> = streamer.events().collect();
    no_reset(&events);
    assert_eq!(events.last(), Some(&Event::Done));
    // A boot found in alarm (homing required, say) is refused as at the start.
    let mut streamer = Streamer::new(moves(3), connecting()).unwrap();
    streamer.transmit();
    streamer.receive(IDLE);
    streamer.transmit();
    streamer.receive(BANNER);
    streamer.transmit();
    streamer.receive(b"<Alarm|MPos:0.000,0.000,0.000,0.000|Bf:35,1023|FS:0,0>\r\n");
    assert_eq!(streamer.stop_reason(), Some(&StopReason::AlarmAtStart));
}

#[test]
fn without_the_state_check_a_banner_before_the_program_sends_build_info_again() {
    let mut streamer = Streamer::new(moves(2), StreamerConfig::default()).unwrap();
    assert_eq!(streamer.transmit().unwrap(), b"$I\n");
    streamer.receive(BANNER);
    assert_eq!(streamer.transmit().unwrap(), b"$I\n");
    streamer.receive(build_info());
    assert!(streamer.transmit().unwrap().starts_with(b"G1 X0 F100\n"));
    no_reset(&streamer.events().collect::<Vec<_>>());
}

#[test]
fn once_the_program_has_started_a_banner_is_a_reset() {
    let mut streamer = Streamer::new(moves(3), connecting()).unwrap();
    streamer.transmit();
    streamer.receive(IDLE);
    streamer.transmit();
    streamer.receive(build_info());
    assert!(streamer.transmit().is_some());
    streamer.receive(b"ok\r\n");
    streamer.receive(BANNER);
    let events: Vec<Event> = streamer.events().collect();
    assert!(events.contains(&Event::Reset));
    assert_eq!(streamer.stop_reason(), Some(&StopReason::ControllerReset));
    assert_eq!(streamer.transmit(), None);
}

#[test]
fn a_stream_resumed_behind_a_preamble_has_started_with_its_first_preamble_line() {
    let config = StreamerConfig {
        query_build_info: false,
        ..connecting()
    };
    let lines = program(&["G21 G90 G94", "G1 X1 F100", "G1 X2"]);
    let mut streamer = Streamer::resume_from(lines, 2, config).unwrap();
    streamer.transmit();
    streamer.receive(IDLE);
    let out = streamer.transmit().unwrap();
    assert!(!out.starts_with(b"G1 X2"), "the preamble first: {out:?}");
    streamer.receive(BANNER);
    assert_eq!(streamer.stop_reason(), Some(&StopReason::ControllerReset));
}
