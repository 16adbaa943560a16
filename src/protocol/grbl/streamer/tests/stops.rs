//! Stopping: errors (sticky or not), alarms, resets, a line too long for the reported
//! buffer, a failed preamble line.

use super::*;

#[test]
fn an_error_stops_sending_reports_the_line_and_clears_the_sticky_error() {
    let mut lines = moves(30);
    lines[5] = "G1 X5 Q1 F100".into();
    let mut fake = Fake::grblhal(128);
    fake.fail.push((lines[5].clone(), 20));
    let mut streamer = Streamer::new(lines.clone(), no_query()).unwrap();
    // One burst: the lines that fit go out, the controller answers them all.
    fake.write(&streamer.transmit().unwrap());
    let in_flight = sent_indices(&streamer.events().collect::<Vec<_>>());
    assert!(in_flight.len() > 7, "{in_flight:?}");
    fake.process_all();
    streamer.receive(&fake.take_output());
    let events: Vec<Event> = streamer.events().collect();
    assert_eq!(acked_indices(&events), vec![0, 1, 2, 3, 4]);
    assert!(events.contains(&Event::Error {
        index: 5,
        line: lines[5].clone(),
        code: 20,
        message: error_message(20),
    }));
    // The lines behind it got the sticky error: consequences, not failures.
    let rejected: Vec<usize> = events
        .iter()
        .filter_map(|e| match e {
            Event::Rejected { index, code: 20 } => Some(*index),
            _ => None,
        })
        .collect();
    assert_eq!(rejected, (6..in_flight.len()).collect::<Vec<_>>());
    assert_eq!(
        events
            .iter()
            .filter(|e| matches!(e, Event::Error { .. }))
            .count(),
        1
    );
    assert!(!streamer.is_finished());
    // Then exactly one empty line goes out, and no program line.
    let clear = streamer.transmit().unwrap();
    assert_eq!(clear, b"\n");
    assert_eq!(streamer.transmit(), None);
    fake.write(&clear);
    drive(&mut streamer, &mut fake);
    let events: Vec<Event> = streamer.events().collect();
    assert_eq!(
        events,
        vec![
            Event::AuxSent {
                line: Aux::ClearError,
                text: String::new()
            },
            Event::AuxAnswered {
                line: Aux::ClearError,
                error: None
            },
            Event::Stopped {
                reason: StopReason::Error {
                    line: LineRef::Program(5),
                    code: 20
                }
            },
        ]
    );
    assert_eq!(fake.executed, lines[..5]);
    // The controller is clear: a next line would run.
    fake.write(b"G0 X0\n");
    fake.process_all();
    assert_eq!(fake.take_output(), b"ok\r\n");
    let point = streamer.resume_point().unwrap();
    assert_eq!(
        point,
        ResumePoint {
            line_index: 5,
            basis: ResumeBasis::FailedLine,
            possibly_executed: 5..5,
            executed_after_failure: vec![],
        }
    );
    assert!(streamer
        .stop_reason()
        .unwrap()
        .to_string()
        .contains("program line 6"));
}

#[test]
fn without_a_sticky_error_later_lines_run_and_a_new_code_is_a_new_failure() {
    let mut lines = moves(12);
    lines[3] = "G1 X3 Q1 F100".into();
    lines[5] = "G1 X5 F0".into();
    let mut fake = Fake::grbl(128);
    fake.fail.push((lines[3].clone(), 20));
    fake.fail.push((lines[5].clone(), 22));
    let mut streamer = Streamer::new(lines.clone(), no_query()).unwrap();
    drive(&mut streamer, &mut fake);
    let events: Vec<Event> = streamer.events().collect();
    let failed: Vec<(usize, u16)> = events
        .iter()
        .filter_map(|e| match e {
            Event::Error { index, code, .. } => Some((*index, *code)),
            _ => None,
        })
        .collect();
    assert_eq!(failed, vec![(3, 20), (5, 22)]);
    let point = streamer.resume_point().unwrap();
    assert_eq!(point.line_index, 3);
    assert_eq!(point.basis, ResumeBasis::FailedLine);
    // grbl ran the valid lines that were already in its buffer.
    let after = point.executed_after_failure;
    assert!(after.starts_with(&[4, 6]), "{after:?}");
    assert!(after.iter().all(|&i| fake.executed.contains(&lines[i])));
    assert!(!fake.executed.contains(&lines[3]));
    assert_eq!(
        streamer.stop_reason(),
        Some(&StopReason::Error {
            line: LineRef::Program(3),
            code: 20
        })
    );
}

#[test]
fn an_alarm_stops_the_stream_and_later_refusals_are_its_consequence() {
    let mut streamer = Streamer::new(moves(30), no_query()).unwrap();
    let first = sent_count(&mut streamer);
    streamer.receive(b"ok\r\nok\r\nALARM:2\r\n[MSG:Reset to continue]\r\n");
    let events: Vec<Event> = streamer.events().collect();
    assert_eq!(
        events,
        vec![
            Event::Acked { index: 0 },
            Event::Acked { index: 1 },
            Event::Alarm {
                code: 2,
                message: alarm_message(2)
            },
            Event::Stopped {
                reason: StopReason::Alarm { code: 2 }
            },
            Event::Message("Reset to continue".into()),
        ]
    );
    // Nothing but real-time bytes goes out any more, whatever room there is.
    streamer.receive(b"error:9\r\n");
    assert_eq!(
        streamer.next_event(),
        Some(Event::Rejected { index: 2, code: 9 })
    );
    assert_eq!(streamer.transmit(), None);
    streamer.feed_hold();
    assert_eq!(streamer.transmit().unwrap(), b"!");
    // The reset that follows discards the rest, without a second stop.
    streamer.receive(b"Grbl 1.1h ['$' for help]\r\n");
    let events: Vec<Event> = streamer.events().collect();
    assert_eq!(events[0], Event::Reset);
    assert_eq!(
        events[1..],
        (3..first)
            .map(|index| Event::Discarded { index })
            .collect::<Vec<_>>()
    );
    assert_eq!(streamer.in_flight_bytes(), 0);
    // Nothing proves a line executed: resume at the start; 0 and 1 may have run.
    let point = streamer.resume_point().unwrap();
    assert_eq!(point.line_index, 0);
    assert_eq!(point.basis, ResumeBasis::StreamStart);
    assert_eq!(point.possibly_executed, 0..2);
}

#[test]
fn a_banner_mid_stream_is_a_reset() {
    let mut streamer = Streamer::new(moves(20), no_query()).unwrap();
    let sent = sent_count(&mut streamer);
    streamer.receive(b"ok\r\n\r\nGrbl 1.1h ['$' for help]\r\n[MSG:'$H'|'$X' to unlock]\r\n");
    let events: Vec<Event> = streamer.events().collect();
    assert_eq!(events[0], Event::Acked { index: 0 });
    assert_eq!(events[1], Event::Reset);
    let discarded: Vec<usize> = events
        .iter()
        .filter_map(|e| match e {
            Event::Discarded { index } => Some(*index),
            _ => None,
        })
        .collect();
    assert_eq!(discarded, (1..sent).collect::<Vec<_>>());
    assert!(events.contains(&Event::Stopped {
        reason: StopReason::ControllerReset
    }));
    assert_eq!(streamer.transmit(), None);
    assert_eq!(streamer.resume_point().unwrap().possibly_executed, 0..1);
}

#[test]
fn a_reported_buffer_too_small_for_a_line_stops_before_it() {
    let mut streamer = Streamer::new(
        program(&["G0 X0", "G1 X1.2345 Z2.3456 F100", "G0 X0"]),
        StreamerConfig::default(),
    )
    .unwrap();
    streamer.transmit().unwrap();
    streamer.receive(b"[OPT:V,15,16]\r\nok\r\n");
    assert_eq!(streamer.transmit().unwrap(), b"G0 X0\n");
    streamer.receive(b"ok\r\n");
    let stopped = streamer.events().next_back();
    assert_eq!(
        stopped,
        Some(Event::Stopped {
            reason: StopReason::LineTooLong {
                line: LineRef::Program(1),
                bytes: 24,
                budget: 15
            }
        })
    );
    let point = streamer.resume_point().unwrap();
    assert_eq!((point.line_index, point.basis), (1, ResumeBasis::NotSent));
}

#[test]
fn a_preamble_line_that_fails_stops_before_the_program() {
    let preamble = program(&["G21 G92 C0"]);
    let mut fake = Fake::grblhal(128);
    fake.fail.push(("G21 G92 C0".into(), 9));
    let mut streamer = Streamer::with_preamble(moves(3), preamble, no_query()).unwrap();
    drive(&mut streamer, &mut fake);
    assert!(fake.executed.is_empty());
    assert_eq!(
        streamer.stop_reason(),
        Some(&StopReason::Error {
            line: LineRef::Aux(Aux::Preamble(0)),
            code: 9
        })
    );
    let point = streamer.resume_point().unwrap();
    assert_eq!(
        (point.line_index, point.basis),
        (0, ResumeBasis::FailedPreamble)
    );
    let rejected = streamer
        .events()
        .filter(|e| matches!(e, Event::Rejected { code: 9, .. }))
        .count();
    assert_eq!(rejected, 3);
}
