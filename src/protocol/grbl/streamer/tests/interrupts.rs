//! Interrupting a stream (a feed hold, nothing after it, the end once the machine stands)
//! and the state check before the first line (held, in alarm, busy), against answers
//! written by hand in grbl 1.1's formats.

use super::*;

fn checking() -> StreamerConfig {
    StreamerConfig {
        query_build_info: false,
        check_state: true,
        ..StreamerConfig::default()
    }
}

fn numbered(n: usize) -> Vec<String> {
    (1..=n).map(|i| format!("N{i} G1 X{i} F100")).collect()
}

#[test]
fn an_interrupt_holds_at_once_sends_no_line_after_and_waits_for_the_machine_to_stand() {
    let mut streamer = Streamer::new(numbered(40), no_query()).unwrap();
    streamer.transmit().unwrap();
    let sent = sent_indices(&streamer.events().collect::<Vec<_>>()).len();
    assert!(sent > 3 && sent < 40, "{sent}");
    // The first three are answered; N2 is executing.
    streamer.receive(b"ok\nok\nok\n<Run|MPos:2.000,0.000,0.000,0.000|Ln:2>\n");
    streamer.interrupt("SIGINT");
    // The feed hold goes out alone, ahead of anything: no line, even with room for one.
    assert_eq!(streamer.transmit(), Some(vec![b'!']));
    let events: Vec<Event> = streamer.events().collect();
    assert!(events.contains(&Event::Stopped {
        reason: StopReason::Interrupted {
            reason: "SIGINT".into()
        }
    }));
    assert!(streamer.is_finished());
    // Decelerating is not standing; a completed hold is.
    streamer.receive(b"<Hold:1|MPos:2.500,0.000,0.000,0.000|Ln:2>\n");
    assert!(!streamer.is_standing());
    streamer.receive(b"ok\n<Hold:0|MPos:2.600,0.000,0.000,0.000|Ln:3>\n");
    assert!(streamer.is_standing());
    assert_eq!(streamer.transmit(), None);
    // Held inside N3 (index 2): it may be part done, the lines after it have not run.
    let resume = streamer.resume_point().unwrap();
    assert_eq!(resume.line_index, 2);
    assert_eq!(resume.basis, ResumeBasis::ExecutingLine { line_no: 3 });
    assert_eq!(resume.possibly_executed, 2..3);
}

#[test]
fn an_alarmed_machine_stands_a_running_one_is_held_again() {
    for (report, standing) in [
        ("<Alarm|MPos:0.000,0.000,0.000,0.000>\n", true),
        ("<Run|MPos:0.000,0.000,0.000,0.000>\n", false),
    ] {
        let mut streamer = Streamer::new(numbered(5), no_query()).unwrap();
        streamer.transmit();
        // A report from before the interrupt proves nothing.
        streamer.receive(report.as_bytes());
        streamer.interrupt("stop");
        assert!(!streamer.is_standing(), "{report}");
        assert_eq!(streamer.transmit(), Some(vec![b'!']));
        streamer.receive(report.as_bytes());
        assert_eq!(streamer.is_standing(), standing, "{report}");
        // Still running after the hold: the hold did not take, and goes out again.
        let again = (!standing).then(|| vec![b'!']);
        assert_eq!(streamer.transmit(), again, "{report}");
    }
}

#[test]
fn one_idle_report_is_not_a_standing_machine() {
    // Issue 21: a controller starved between moves reported Idle for a moment while lines
    // sent to it were still on their way; the bridge took it as standing and left, and the
    // controller ran them. Standing needs every line answered, the planner and the receive
    // buffer empty (`Bf:`) and Idle in more than one report.
    let idle = "<Idle|MPos:1.000,0.000,0.000,0.000|Bf:100,1023>\n";
    let mut streamer = Streamer::new(numbered(5), no_query()).unwrap();
    streamer.transmit().unwrap();
    streamer.receive(b"ok\nok\n");
    streamer.interrupt("SIGINT");
    assert_eq!(streamer.transmit(), Some(vec![b'!']));
    // Idle with three lines unanswered: not standing, and the hold goes out again, since a
    // hold that found the machine idle may not have taken.
    streamer.receive(idle.as_bytes());
    assert!(!streamer.is_standing());
    assert_eq!(streamer.transmit(), Some(vec![b'!']));
    // Every line answered, but a block still queued (99 of 100 free): not standing.
    streamer.receive(b"ok\nok\nok\n<Idle|MPos:1.000,0.000,0.000,0.000|Bf:99,1023>\n");
    assert!(!streamer.is_standing());
    // Bytes still in the receive buffer: not standing either.
    streamer.receive(b"<Idle|MPos:1.000,0.000,0.000,0.000|Bf:100,1000>\n");
    assert!(!streamer.is_standing());
    // A first Idle with everything empty follows a report that was not: not yet.
    let mut streamer = Streamer::new(numbered(2), no_query()).unwrap();
    streamer.transmit().unwrap();
    streamer.receive(b"ok\nok\n<Run|MPos:1.000,0.000,0.000,0.000|Bf:99,1023>\n");
    streamer.interrupt("SIGINT");
    streamer.transmit();
    streamer.receive(idle.as_bytes());
    assert!(!streamer.is_standing());
    // The second in a row is the controller's evidence.
    streamer.receive(idle.as_bytes());
    assert!(streamer.is_standing());
    // Without `Bf:` no Idle proves it: the hold, sent again, is what ends the wait.
    let mut streamer = Streamer::new(numbered(2), no_query()).unwrap();
    streamer.transmit().unwrap();
    streamer.receive(b"ok\nok\n");
    streamer.interrupt("SIGINT");
    for _ in 0..3 {
        streamer.receive(b"<Idle|MPos:1.000,0.000,0.000,0.000>\n");
    }
    assert!(!streamer.is_standing());
    streamer.receive(b"<Hold:0|MPos:1.000,0.000,0.000,0.000>\n");
    assert!(streamer.is_standing());
}

#[test]
fn the_state_is_asked_before_the_first_line_and_an_idle_controller_gets_the_program() {
    let mut streamer = Streamer::new(numbered(3), checking()).unwrap();
    assert_eq!(streamer.transmit(), Some(vec![b'?']));
    assert_eq!(streamer.transmit(), None);
    streamer.receive(b"<Idle|MPos:0.000,0.000,0.000,0.000>\n");
    let out = streamer.transmit().unwrap();
    assert!(out.starts_with(b"N1 G1 X1 F100\n"), "{out:?}");
}

#[test]
fn a_held_controller_is_reset_at_rest_and_asked_again() {
    let mut streamer = Streamer::new(numbered(3), checking()).unwrap();
    streamer.transmit();
    streamer.receive(b"<Hold:0|MPos:5.000,0.000,0.000,0.000>\n");
    // grbl's realtime_cmds.md: a reset not in motion keeps the position, no alarm.
    assert_eq!(streamer.transmit(), Some(vec![realtime::SOFT_RESET]));
    // A poll's `?` that went out before the reset is answered before its banner: held
    // still, and no reason to give up.
    streamer.receive(b"<Hold:0|MPos:5.000,0.000,0.000,0.000>\n");
    assert!(!streamer.is_finished());
    streamer.receive(b"\r\nGrbl 1.1h ['$' for help]\r\n");
    assert_eq!(streamer.transmit(), Some(vec![b'?']));
    streamer.receive(b"<Idle|MPos:5.000,0.000,0.000,0.000>\n");
    assert!(streamer.transmit().unwrap().starts_with(b"N1 "));
    // Still held after the reset: refused, nothing sent.
    let mut streamer = Streamer::new(numbered(3), checking()).unwrap();
    streamer.transmit();
    streamer.receive(b"<Hold:0|MPos:5.000,0.000,0.000,0.000>\n");
    streamer.transmit();
    streamer.receive(b"Grbl 1.1h ['$' for help]\n");
    streamer.transmit();
    streamer.receive(b"<Hold:0|MPos:5.000,0.000,0.000,0.000>\n");
    assert_eq!(streamer.transmit(), None);
    assert!(matches!(
        streamer.stop_reason(),
        Some(StopReason::Busy { state }) if state.contains("held")
    ));
}

#[test]
fn a_controller_in_alarm_is_refused_with_the_unlock_offered_or_unlocked_when_asked() {
    let mut streamer = Streamer::new(numbered(3), checking()).unwrap();
    streamer.transmit();
    streamer.receive(b"<Alarm|MPos:5.000,0.000,0.000,0.000>\n");
    assert_eq!(streamer.transmit(), None);
    assert_eq!(streamer.stop_reason(), Some(&StopReason::AlarmAtStart));
    let said = StopReason::AlarmAtStart.to_string();
    assert!(said.contains("--unlock") && said.contains("$X"), "{said}");
    // Nothing ran: the resume point is where the stream was to start.
    assert_eq!(streamer.resume_point().unwrap().line_index, 0);

    let unlocking = StreamerConfig {
        unlock: true,
        ..checking()
    };
    let mut streamer = Streamer::new(numbered(3), unlocking.clone()).unwrap();
    streamer.transmit();
    streamer.receive(b"<Alarm|MPos:5.000,0.000,0.000,0.000>\n");
    // `$X` alone, and the program only once it is answered.
    assert_eq!(streamer.transmit(), Some(b"$X\n".to_vec()));
    assert_eq!(streamer.transmit(), None);
    streamer.receive(b"[MSG:Caution: Unlocked]\nok\n");
    assert!(streamer.transmit().unwrap().starts_with(b"N1 "));
    // A refused unlock stops the stream on it.
    let mut streamer = Streamer::new(numbered(3), unlocking).unwrap();
    streamer.transmit();
    streamer.receive(b"<Alarm|MPos:5.000,0.000,0.000,0.000>\n");
    streamer.transmit();
    streamer.receive(b"error:9\n");
    drain_until_finished(&mut streamer);
    assert_eq!(
        streamer.stop_reason(),
        Some(&StopReason::Error {
            line: LineRef::Aux(Aux::Unlock),
            code: 9
        })
    );
}

#[test]
fn a_busy_controller_is_refused_before_any_line() {
    for (report, word) in [
        ("<Run|MPos:0.000,0.000,0.000,0.000>\n", "running"),
        ("<Jog|MPos:0.000,0.000,0.000,0.000>\n", "jogging"),
        ("<Home|MPos:0.000,0.000,0.000,0.000>\n", "homing"),
        ("<Door:1|MPos:0.000,0.000,0.000,0.000>\n", "door"),
    ] {
        let mut streamer = Streamer::new(numbered(3), checking()).unwrap();
        streamer.transmit();
        streamer.receive(report.as_bytes());
        assert_eq!(streamer.transmit(), None, "{report}");
        let said = streamer.stop_reason().unwrap().to_string();
        assert!(
            said.contains(word) && said.contains("nothing was sent"),
            "{said}"
        );
    }
}

/// Answers the empty clearing line until the stream has stopped.
fn drain_until_finished(streamer: &mut Streamer) {
    for _ in 0..4 {
        if streamer.is_finished() {
            return;
        }
        if streamer.transmit().is_some() {
            streamer.receive(b"ok\n");
        }
    }
    assert!(streamer.is_finished());
}
