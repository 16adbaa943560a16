//! Resuming: where the stream stops being known to have run, and the preamble that goes on
//! from there.

use super::*;
use crate::protocol::grbl::resume::ResumeError;

const POSTED: &str = "\
G21 G90 G94
M3 S3000
G0 X20 Z5 C0
G93 G1 Z-0.5 C90 F100
G1 Z-1 C180 F100
G92 C0
G1 Z-1.5 C90 F100
G1 Z-2 C180 F100
G92 C0
G1 Z-2.5 C90 F100
G1 Z-3 C180 F100
G94
G0 X30
M5
M2";

#[test]
fn resume_streams_the_preamble_then_the_line() {
    let lines: Vec<String> = POSTED.lines().map(str::to_owned).collect();
    let mut streamer = Streamer::resume_from(lines.clone(), 7, no_query()).unwrap();
    let out = String::from_utf8(streamer.transmit().unwrap()).unwrap();
    let expected: String = ["G21 G92 C90", "G21 G90 G93", "M3 S3000"]
        .iter()
        .chain(
            lines[7..]
                .iter()
                .map(String::as_str)
                .collect::<Vec<_>>()
                .iter(),
        )
        .map(|l| format!("{l}\n"))
        .collect();
    assert_eq!(out, expected);
    let events: Vec<Event> = streamer.events().collect();
    assert!(matches!(
        events[0],
        Event::AuxSent {
            line: Aux::Preamble(0),
            ..
        }
    ));
    assert_eq!(sent_indices(&events), (7..lines.len()).collect::<Vec<_>>());
    assert_eq!(streamer.progress().acked, 7);
    // Nothing resumes past the end, or with unreadable history.
    assert!(matches!(
        Streamer::resume_from(lines.clone(), 99, no_query()),
        Err(StreamerError::Resume(ResumeError::BeyondEnd { .. }))
    ));
}

#[test]
fn error_then_resume_runs_every_line_exactly_once() {
    let good: Vec<String> = POSTED.lines().map(str::to_owned).collect();
    let mut bad = good.clone();
    bad[7] = "G1 Z-2 C180 F100 Q1".into();
    let mut fake = Fake::grblhal(128);
    fake.fail.push((bad[7].clone(), 20));
    let mut first = Streamer::new(bad, StreamerConfig::default()).unwrap();
    drive(&mut first, &mut fake);
    let point = first.resume_point().unwrap();
    assert_eq!(point.line_index, 7);
    assert_eq!(point.possibly_executed, 7..7);
    let mut second =
        Streamer::resume_from(good.clone(), point.line_index, StreamerConfig::default()).unwrap();
    drive(&mut second, &mut fake);
    assert_eq!(second.events().next_back(), Some(Event::Done));
    // Every program line ran exactly once, in order, the preamble between the streams.
    let preamble = ["G21 G92 C90", "G21 G90 G93", "M3 S3000"].map(String::from);
    let expected: Vec<String> = good[..7]
        .iter()
        .chain(&preamble)
        .chain(&good[7..])
        .cloned()
        .collect();
    assert_eq!(fake.executed, expected);
}

#[test]
fn after_an_alarm_line_numbers_say_where_execution_was() {
    let lines: Vec<String> = (0..20)
        .map(|i| format!("N{} G1 X{i} F100", 10 * (i + 1)))
        .collect();
    let wide = StreamerConfig {
        rx_size: 1024,
        ..no_query()
    };
    let mut streamer = Streamer::new(lines.clone(), wide).unwrap();
    let sent = sent_count(&mut streamer);
    streamer.receive(&b"ok\r\n".repeat(8));
    // N40 is index 3: lines 0–2 are done, 3 was executing.
    streamer.receive(b"<Run|MPos:3.5,0,0|Bf:10,60|Ln:40|FS:100,0>\r\n");
    assert_eq!(streamer.progress().executing, Some(3));
    streamer.receive(b"ALARM:1\r\n");
    let point = streamer.resume_point().unwrap();
    assert_eq!(point.line_index, 3);
    assert_eq!(point.basis, ResumeBasis::ExecutingLine { line_no: 40 });
    assert_eq!(point.possibly_executed, 3..8);
    assert!(sent > 8);
    // Sent events carry the N numbers.
    let mut again = Streamer::new(lines, no_query()).unwrap();
    again.transmit();
    assert_eq!(
        again.next_event(),
        Some(Event::Sent {
            index: 0,
            line_no: Some(10)
        })
    );
}

#[test]
fn after_an_alarm_an_empty_planner_proves_lines_done() {
    let mut streamer = Streamer::new(moves(20), no_query()).unwrap();
    streamer.transmit();
    streamer.receive(&b"ok\r\n".repeat(5));
    // Idle alone proves nothing: grbl may not have started the cycle yet.
    streamer.receive(b"<Idle|MPos:0,0,0|FS:0,0>\r\n");
    streamer.receive(b"<Idle|MPos:0,0,0|Bf:14,100|FS:0,0>\r\n");
    assert_eq!(streamer.resume_point(), None);
    // With every block free (15 is the most seen, so the planner size) it does.
    streamer.receive(b"<Idle|MPos:0,0,0|Bf:15,127|FS:0,0>\r\n");
    streamer.receive(&b"ok\r\n".repeat(3));
    streamer.receive(b"<Run|MPos:0,0,0|Bf:13,60|FS:100,0>\r\nALARM:3\r\n");
    // After the alarm nothing more is proven, even by an idle report.
    streamer.receive(b"<Idle|MPos:0,0,0|Bf:15,127|FS:0,0>\r\n");
    let point = streamer.resume_point().unwrap();
    assert_eq!(point.line_index, 5);
    assert_eq!(point.basis, ResumeBasis::PlannerEmpty);
    assert_eq!(point.possibly_executed, 5..8);
}
