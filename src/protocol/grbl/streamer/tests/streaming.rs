//! Streaming: character counting, pairing the answers, `$I`'s buffer size, the banner,
//! real-time bytes, polls, progress and the checks before anything is sent.

use super::*;

#[test]
fn a_program_streams_to_done_in_order() {
    let lines = moves(40);
    let mut streamer = Streamer::new(lines.clone(), StreamerConfig::default()).unwrap();
    let mut fake = Fake::grblhal(128);
    drive(&mut streamer, &mut fake);
    let events: Vec<Event> = streamer.events().collect();
    assert_eq!(fake.executed, lines);
    assert_eq!(sent_indices(&events), (0..40).collect::<Vec<_>>());
    assert_eq!(acked_indices(&events), (0..40).collect::<Vec<_>>());
    assert_eq!(events.last(), Some(&Event::Done));
    assert_eq!(events.iter().filter(|e| **e == Event::Done).count(), 1);
    assert_eq!(streamer.progress().acked, 40);
    assert_eq!(streamer.resume_point(), None);
    // The buffer was kept full: 127 bytes hold 9 lines of 12–13 bytes.
    assert!(fake.max_fill > 100, "{}", fake.max_fill);
}

#[test]
fn whole_lines_only_up_to_the_budget() {
    // 4 lines of 40 bytes with `\n`: three fit 127 bytes, the fourth waits for an ok.
    let line = "G1 X1.2345 Z-0.5678 C123.4567 F1234.567".to_string();
    assert_eq!(line.len() + 1, 40);
    let mut streamer = Streamer::new(vec![line.clone(); 4], no_query()).unwrap();
    let first = streamer.transmit().unwrap();
    assert_eq!(first.len(), 120);
    assert_eq!(streamer.in_flight_bytes(), 120);
    assert_eq!(streamer.transmit(), None);
    streamer.receive(b"ok\r\n");
    assert_eq!(
        streamer.transmit().unwrap(),
        format!("{line}\n").into_bytes()
    );
    assert_eq!(streamer.in_flight_bytes(), 120);
}

#[test]
fn answers_pair_in_order_in_bursts_split_reads_and_between_push_messages() {
    let lines = moves(6);
    let mut streamer = Streamer::new(lines, no_query()).unwrap();
    streamer.transmit().unwrap();
    // Two oks in one read, one split over three reads, push messages in between that
    // answer nothing (a startup line's `:ok` included).
    streamer.receive(b"ok\r\nok\r\n<Run|MPos:1,0,0|FS:100,0>\r\no");
    streamer.receive(b"k");
    streamer.receive(b"\r\n[MSG:Pgm End]\r\n>G54:ok\r\nok\nok\r");
    streamer.receive(b"\n");
    assert_eq!(streamer.in_flight_bytes(), 11);
    let events: Vec<Event> = streamer.events().collect();
    assert_eq!(acked_indices(&events), vec![0, 1, 2, 3, 4]);
    assert!(events.contains(&Event::Message("Pgm End".into())));
    assert!(events.contains(&Event::Feedback(">G54:ok".into())));
    streamer.receive(b"ok\r\n");
    assert_eq!(streamer.next_event(), Some(Event::Acked { index: 5 }));
    assert_eq!(streamer.next_event(), Some(Event::Done));
    // An answer with nothing in flight is reported, not paired.
    streamer.receive(b"ok\r\n");
    assert_eq!(
        streamer.next_event(),
        Some(Event::Unrecognized("ok".into()))
    );
}

#[test]
fn a_banner_before_the_stream_is_no_reset_and_can_gate_it() {
    let config = StreamerConfig {
        wait_for_banner: true,
        ..StreamerConfig::default()
    };
    let mut streamer = Streamer::new(moves(3), config).unwrap();
    assert_eq!(streamer.transmit(), None);
    // Real-time bytes are not held back.
    assert!(streamer.poll(Duration::ZERO));
    assert_eq!(streamer.transmit().unwrap(), b"?");
    streamer.receive(b"\r\nGrblHAL 1.1f ['$' or '$HELP' for help]\r\n");
    assert_eq!(
        streamer.next_event(),
        Some(Event::Banner(
            "GrblHAL 1.1f ['$' or '$HELP' for help]".into()
        ))
    );
    assert_eq!(streamer.transmit().unwrap(), b"$I\n");

    // Without waiting, a banner before any line is informational too.
    let mut streamer = Streamer::new(moves(3), no_query()).unwrap();
    streamer.receive(b"Grbl 1.1h ['$' for help]\r\n");
    assert!(matches!(streamer.next_event(), Some(Event::Banner(_))));
    assert!(streamer.transmit().is_some());
}

#[test]
fn the_rx_size_of_build_info_is_adopted() {
    let lines: Vec<String> = (0..60)
        .map(|i| format!("G1 X{i:03} Z-1.000 C{i:03}.5 F100"))
        .collect();
    let mut fake = Fake::grblhal(1024);
    let mut streamer = Streamer::new(lines.clone(), StreamerConfig::default()).unwrap();
    // `$I` alone first: the program waits for the size.
    assert_eq!(streamer.transmit().unwrap(), b"$I\n");
    assert_eq!(streamer.transmit(), None);
    fake.write(b"$I\n");
    fake.process_all();
    streamer.receive(&fake.take_output());
    let events: Vec<Event> = streamer.events().collect();
    assert!(events.contains(&Event::RxSize { bytes: 1024 }));
    assert!(events.contains(&Event::Feedback("[VER:1.1f.20250102:]".into())));
    assert_eq!(streamer.rx_size(), 1024);
    assert_eq!(streamer.planner_blocks(), Some(35));
    // The burst fills the buffer but for the reserve left to real-time bytes: 1023 bytes
    // less 128 (an eighth).
    let burst = streamer.transmit().unwrap();
    assert!(
        burst.len() > 800 && burst.len() <= 1023 - 128,
        "{}",
        burst.len()
    );
    fake.write(&burst);
    drive(&mut streamer, &mut fake);
    assert_eq!(fake.executed, lines);
    assert!(fake.max_fill > 800 && fake.max_fill <= 1023 - 128);

    // An OPT line without a size, or grbl without `$I`, keeps the default.
    let mut fake = Fake::grbl(128);
    fake.opt = None;
    let mut streamer = Streamer::new(moves(5), StreamerConfig::default()).unwrap();
    drive(&mut streamer, &mut fake);
    assert_eq!(streamer.rx_size(), 128);
    assert_eq!(fake.executed, moves(5));
}

#[test]
fn a_failed_build_info_query_clears_the_sticky_error_and_streams() {
    let mut fake = Fake::grblhal(128);
    fake.opt = None;
    let mut streamer = Streamer::new(moves(3), StreamerConfig::default()).unwrap();
    streamer.transmit().unwrap();
    streamer.receive(b"error:3\r\n");
    assert_eq!(
        streamer.events().next_back(),
        Some(Event::AuxAnswered {
            line: Aux::BuildInfo,
            error: Some(3)
        })
    );
    let out = streamer.transmit().unwrap();
    assert_eq!(out, b"\nG1 X0 F100\nG1 X1 F100\nG1 X2 F100\n");
    fake.write(&out);
    drive(&mut streamer, &mut fake);
    assert_eq!(streamer.events().next_back(), Some(Event::Done));
    assert_eq!(fake.executed, moves(3));
}

#[test]
fn status_reports_are_parsed_and_the_wco_kept() {
    let mut streamer = Streamer::new(moves(1), no_query()).unwrap();
    streamer
        .receive(b"<Idle|MPos:1.000,0.000,-2.000,90.000|FS:0,0|WCO:0.000,0.000,1.000,45.000>\r\n");
    streamer.receive(b"<Run|MPos:2.000,0.000,-2.000,90.000|Bf:30,1000|FS:100,3000>\r\n");
    let events: Vec<Event> = streamer.events().collect();
    let Event::Status(first) = &events[0] else {
        panic!("{events:?}");
    };
    assert_eq!(first.wco, Some(vec![0.0, 0.0, 1.0, 45.0]));
    let Event::Status(second) = &events[1] else {
        panic!("{events:?}");
    };
    assert_eq!(second.wco, None);
    assert_eq!(streamer.last_wco(), Some(&[0.0, 0.0, 1.0, 45.0][..]));
    let work = second.work_position(streamer.last_wco()).unwrap();
    assert_eq!(work, vec![2.0, 0.0, -3.0, 45.0]);
    assert_eq!(streamer.last_status(), Some(second));
}

#[test]
fn real_time_bytes_bypass_the_count() {
    let mut streamer = Streamer::new(moves(30), no_query()).unwrap();
    streamer.transmit().unwrap();
    let full = streamer.in_flight_bytes();
    assert!(full > 114, "{full}");
    assert_eq!(streamer.transmit(), None);
    streamer.feed_hold();
    assert!(streamer.poll(Duration::from_secs(1)));
    streamer.resume();
    assert_eq!(streamer.transmit().unwrap(), b"!?~");
    assert_eq!(streamer.in_flight_bytes(), full);
    // They go ahead of lines that go out in the same call.
    streamer.feed_hold();
    streamer.receive(b"ok\r\n");
    let out = streamer.transmit().unwrap();
    assert_eq!(out[0], b'!');
    assert_eq!(&out[1..], b"G1 X11 F100\n");
    // A soft reset stops the stream at once.
    streamer.soft_reset();
    assert_eq!(streamer.transmit().unwrap(), [realtime::SOFT_RESET]);
    assert!(streamer.events().any(|e| e
        == Event::Stopped {
            reason: StopReason::SoftReset
        }));
    streamer.receive(b"ok\r\n");
    assert_eq!(streamer.transmit(), None);
    // Its banner is the expected reset: in-flight lines are discarded.
    streamer.receive(b"GrblHAL 1.1f ['$' or '$HELP' for help]\r\n");
    let events: Vec<Event> = streamer.events().collect();
    assert_eq!(events[1], Event::Reset);
    assert!(matches!(events[2], Event::Discarded { index: 2 }));
    assert_eq!(streamer.in_flight_bytes(), 0);
    assert_eq!(streamer.stop_reason(), Some(&StopReason::SoftReset));
}

#[test]
fn polls_at_the_configured_interval() {
    let ms = Duration::from_millis;
    let mut streamer = Streamer::new(Vec::new(), no_query()).unwrap();
    assert!(streamer.poll(ms(1000)));
    assert!(!streamer.poll(ms(1100)));
    assert!(!streamer.poll(ms(1199)));
    assert!(streamer.poll(ms(1200)));
    assert!(!streamer.poll(ms(1350)));
    assert!(streamer.poll(ms(1400)));
    // Due twice before a transmit: one `?` (grbl ignores a second before it reports).
    assert!(streamer.poll(ms(1600)));
    assert_eq!(streamer.transmit().unwrap(), b"?");
    // A clock that goes back is not due, and does not panic.
    assert!(!streamer.poll(ms(10)));
    let mut quiet = Streamer::new(
        Vec::new(),
        StreamerConfig {
            poll_interval: None,
            ..no_query()
        },
    )
    .unwrap();
    assert!(!quiet.poll(ms(0)));
    assert_eq!(quiet.transmit(), None);
    assert_eq!(quiet.next_event(), Some(Event::Done));
}

#[test]
fn progress_and_eta() {
    let mut streamer = Streamer::new(moves(4), no_query()).unwrap();
    streamer.transmit();
    streamer.receive(b"ok\r\n");
    let progress = streamer.progress();
    assert_eq!((progress.acked, progress.total), (1, 4));
    assert_eq!(progress.fraction(), 0.25);
    assert_eq!(progress.eta_seconds(&[1.0, 2.0, 3.0, 4.0]), Some(9.0));
    assert_eq!(progress.eta_seconds(&[1.0]), None);
    let executing = Progress {
        executing: Some(3),
        ..progress
    };
    assert_eq!(executing.eta_seconds(&[1.0, 2.0, 3.0, 4.0]), Some(4.0));
    let empty = Progress {
        acked: 0,
        executing: None,
        total: 0,
    };
    assert_eq!((empty.fraction(), empty.eta_seconds(&[])), (1.0, Some(0.0)));
}

#[test]
fn unstreamable_programs_are_refused_before_anything_is_sent() {
    let refused =
        |lines: &[&str], config: StreamerConfig| Streamer::new(program(lines), config).unwrap_err();
    assert_eq!(
        refused(&["G0 X0", "G1 X1 (why?)"], no_query()),
        StreamerError::ForbiddenByte {
            line: LineRef::Program(1),
            column: 11,
            byte: b'?'
        }
    );
    assert!(matches!(
        refused(&["G0 X0\r"], no_query()),
        StreamerError::ForbiddenByte { byte: b'\r', .. }
    ));
    assert!(matches!(
        refused(&["(é)"], no_query()),
        StreamerError::ForbiddenByte { byte: 0xc3, .. }
    ));
    let long = "G1 X1".repeat(30);
    assert!(matches!(
        Streamer::new(vec![long.clone()], no_query()).unwrap_err(),
        StreamerError::LineTooLong {
            bytes: 151,
            budget: 127,
            ..
        }
    ));
    let wide = StreamerConfig {
        rx_size: 1024,
        ..no_query()
    };
    assert!(Streamer::new(vec![long], wide).is_ok());
    assert_eq!(
        refused(
            &["G0 X0"],
            StreamerConfig {
                start_line: 2,
                ..no_query()
            }
        ),
        StreamerError::StartBeyondEnd { start: 2, len: 1 }
    );
    assert_eq!(
        refused(
            &["G0 X0"],
            StreamerConfig {
                rx_size: 1,
                ..no_query()
            }
        ),
        StreamerError::RxTooSmall(1)
    );
    // Lines before the start line are not sent, so not checked.
    let config = StreamerConfig {
        start_line: 1,
        ..no_query()
    };
    let mut streamer = Streamer::new(program(&["?", "G0 X0"]), config).unwrap();
    assert_eq!(streamer.transmit().unwrap(), b"G0 X0\n");
}

#[test]
fn an_empty_program_or_start_at_the_end_is_done_at_once() {
    let mut streamer = Streamer::new(Vec::new(), no_query()).unwrap();
    assert_eq!(streamer.next_event(), Some(Event::Done));
    assert_eq!(streamer.transmit(), None);
    let config = StreamerConfig {
        start_line: 2,
        ..StreamerConfig::default()
    };
    let mut fake = Fake::grblhal(128);
    let mut streamer = Streamer::new(moves(2), config).unwrap();
    drive(&mut streamer, &mut fake);
    assert_eq!(streamer.events().next_back(), Some(Event::Done));
    assert!(fake.executed.is_empty());
}
