//! The session against scripted `linuxcncrsh` answers, in the forms LinuxCNC 2.9 gives
//! them (see the module docs).

use super::*;

const T0: Duration = Duration::ZERO;

fn config() -> SessionConfig {
    SessionConfig {
        end_position: Some([0.0, -12.0, 7200.0]),
        ..SessionConfig::new("/tmp/job.ngc")
    }
}

/// Expects `request` next (at `now`) and answers it with `reply`.
fn exchange(session: &mut Session, now: Duration, request: &str, reply: &str) {
    let sent = session.transmit(now).expect("a request is due");
    assert_eq!(String::from_utf8(sent).unwrap(), format!("{request}\r\n"));
    session.receive(reply.as_bytes());
}

/// Logs in (the server echoes until `set echo off` has been read), the enable password
/// answered `enable_reply`.
fn logged_in_as(config: SessionConfig, enable_reply: &str) -> Session {
    let mut s = Session::new(config);
    exchange(
        &mut s,
        T0,
        "hello EMC whirl 1.0",
        "HELLO ACK EMCNETSVR 1.1\r\n",
    );
    exchange(
        &mut s,
        T0,
        "set verbose on",
        "set verbose on\r\nSET VERBOSE ACK\n\r",
    );
    exchange(
        &mut s,
        T0,
        "set echo off",
        "set echo off\r\nSET ECHO ACK\n\r",
    );
    exchange(&mut s, T0, "set enable EMCTOO", enable_reply);
    s
}

fn logged_in(config: SessionConfig) -> Session {
    logged_in_as(config, "SET ENABLE ACK\n\r")
}

/// Logged in, the machine found out of E-stop and on, auto mode, the program opened: its
/// `get error` is next.
fn opened() -> Session {
    let mut s = logged_in(config());
    exchange(&mut s, T0, "get estop", "ESTOP OFF\r\n");
    exchange(&mut s, T0, "get machine", "MACHINE ON\r\n");
    exchange(&mut s, T0, "set mode auto", "SET MODE ACK\n\r");
    exchange(&mut s, T0, "set open /tmp/job.ngc", "SET OPEN ACK\n\r");
    s
}

fn running() -> Session {
    let mut s = opened();
    exchange(&mut s, T0, "get error", "ERROR OK\r\n");
    exchange(&mut s, T0, "set run", "SET RUN ACK\n\r");
    assert_eq!(s.next_event(), Some(Event::Running));
    s
}

/// One status poll at `now`.
fn poll(s: &mut Session, now: Duration, state: &str, line: u64, pos: [f64; 3], error: &str) {
    exchange(
        s,
        now,
        "get program_status",
        &format!("PROGRAM_STATUS {state}\r\n"),
    );
    exchange(
        s,
        now,
        "get program_line",
        &format!("PROGRAM_LINE {line}\r\n"),
    );
    let [x, z, c] = pos;
    exchange(
        s,
        now,
        "get abs_act_pos",
        &format!("ABS_ACT_POS {x:.6} 0.000000 {z:.6} 0.000000 0.000000 {c:.6}\r\n"),
    );
    exchange(s, now, "get error", &format!("ERROR {error}\r\n"));
}

#[test]
fn a_program_runs_to_its_end_position_and_completes() {
    let mut s = running();
    poll(&mut s, T0, "RUNNING", 9, [1.0, -13.0, 0.0], "OK");
    assert!(s.transmit(T0).is_none(), "the next poll waits its interval");
    assert_eq!(s.deadline(), Some(Duration::from_millis(100)));
    let t1 = Duration::from_millis(100);
    poll(&mut s, t1, "IDLE", 0, [0.0, -12.0, 7200.0], "OK");
    assert_eq!(s.ending(), Some(&Ending::Completed));
    assert_eq!(s.deadline(), None);
    assert!(s.transmit(t1).is_none());
}

#[test]
fn idle_away_from_the_end_without_an_error_is_an_abort_outside_the_bridge() {
    let mut s = running();
    poll(&mut s, T0, "RUNNING", 40, [20.0, -13.0, 90.0], "OK");
    poll(
        &mut s,
        Duration::from_secs(1),
        "IDLE",
        40,
        [20.0, -13.0, 95.0],
        "OK",
    );
    match s.ending() {
        Some(Ending::Aborted { reason, line: 40 }) => {
            assert!(reason.contains("stopped outside whirl"), "{reason}")
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn an_idle_program_not_yet_started_is_not_an_ending() {
    let mut s = running();
    poll(&mut s, T0, "IDLE", 0, [0.0; 3], "OK");
    assert_eq!(
        s.ending(),
        None,
        "set run is acknowledged before the task runs it"
    );
}

#[test]
fn an_error_from_linuxcnc_ends_the_run_in_its_words_at_the_line_reached() {
    let mut s = running();
    poll(
        &mut s,
        T0,
        "RUNNING",
        120,
        [20.0, -13.0, 90.0],
        "Bad character 'y' used",
    );
    assert_eq!(
        s.next_event(),
        Some(Event::Error("Bad character 'y' used".into()))
    );
    assert!(matches!(s.next_event(), Some(Event::Status(_))));
    poll(
        &mut s,
        Duration::from_secs(1),
        "IDLE",
        300,
        [20.0, -12.5, 900.0],
        "OK",
    );
    assert_eq!(
        s.ending(),
        Some(&Ending::Failed {
            error: "Bad character 'y' used".into(),
            line: 300
        })
    );
}

#[test]
fn e_stop_and_machine_off_are_refused_unless_the_profile_allows_power_on() {
    let mut s = logged_in(config());
    exchange(&mut s, T0, "get estop", "ESTOP ON\r\n");
    match s.ending() {
        Some(Ending::Refused(why)) => assert!(why.contains("power_on = false"), "{why}"),
        other => panic!("{other:?}"),
    }
    let mut s = logged_in(config());
    exchange(&mut s, T0, "get estop", "ESTOP OFF\r\n");
    exchange(&mut s, T0, "get machine", "MACHINE OFF\r\n");
    assert!(matches!(s.ending(), Some(Ending::Refused(_))));

    let mut s = logged_in(SessionConfig {
        power_on: true,
        ..config()
    });
    exchange(&mut s, T0, "get estop", "ESTOP ON\r\n");
    exchange(&mut s, T0, "set estop off", "SET ESTOP ACK\n\r");
    exchange(&mut s, T0, "get machine", "MACHINE OFF\r\n");
    exchange(&mut s, T0, "set machine on", "SET MACHINE ACK\n\r");
    exchange(&mut s, T0, "set mode auto", "SET MODE ACK\n\r");
    assert_eq!(s.ending(), None);
}

#[test]
fn a_program_linuxcnc_cannot_open_is_refused_in_its_words() {
    let mut s = opened();
    exchange(
        &mut s,
        T0,
        "get error",
        "ERROR Unable to open file </tmp/job.ngc>\r\n",
    );
    assert_eq!(
        s.ending(),
        Some(&Ending::Refused(
            "LinuxCNC cannot open the program: Unable to open file </tmp/job.ngc>".into()
        ))
    );
}

#[test]
fn a_nak_is_explained_by_the_error_linuxcnc_reports() {
    let mut s = logged_in(config());
    exchange(&mut s, T0, "get estop", "ESTOP OFF\r\n");
    exchange(&mut s, T0, "get machine", "MACHINE ON\r\n");
    exchange(&mut s, T0, "set mode auto", "SET MODE NAK\n\r");
    exchange(
        &mut s,
        T0,
        "get error",
        "ERROR can't do that in this mode\r\n",
    );
    assert_eq!(
        s.ending(),
        Some(&Ending::Refused(
            "LinuxCNC would not go to auto mode (LinuxCNC: can't do that in this mode)".into()
        ))
    );
}

#[test]
fn wrong_passwords_are_refused_naming_the_key() {
    let mut s = Session::new(config());
    exchange(&mut s, T0, "hello EMC whirl 1.0", "HELLO NAK\r\n");
    match s.ending() {
        Some(Ending::Refused(why)) => assert!(why.contains("connect_password"), "{why}"),
        other => panic!("{other:?}"),
    }
    let s = logged_in_as(config(), "SET ENABLE NAK\n\r");
    match s.ending() {
        Some(Ending::Refused(why)) => assert!(why.contains("enable_password"), "{why}"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_silent_server_ends_the_session_at_the_answer_deadline() {
    let mut s = running();
    poll(&mut s, T0, "RUNNING", 77, [1.0, -13.0, 5.0], "OK");
    let t = Duration::from_millis(100);
    assert!(s.transmit(t).is_some());
    let deadline = t + Duration::from_secs(2);
    assert_eq!(s.deadline(), Some(deadline));
    s.poll(deadline - Duration::from_millis(1));
    assert_eq!(s.ending(), None);
    s.poll(deadline);
    assert_eq!(
        s.ending(),
        Some(&Ending::Silent {
            request: "get program_status".into(),
            line: 77
        })
    );
}

#[test]
fn hold_resume_and_abort_go_before_queued_polls() {
    let mut s = running();
    let t = Duration::from_millis(100);
    exchange(
        &mut s,
        t,
        "get program_status",
        "PROGRAM_STATUS RUNNING\r\n",
    );
    s.command(Command::Hold);
    exchange(&mut s, t, "set pause", "SET PAUSE ACK\n\r");
    // The poll that was under way is dropped; the next one comes at its time.
    let t2 = Duration::from_millis(200);
    poll(&mut s, t2, "PAUSED", 12, [3.0, -13.0, 10.0], "OK");
    s.command(Command::Resume);
    exchange(&mut s, t2, "set resume", "SET RESUME ACK\n\r");
    s.command(Command::Abort);
    exchange(&mut s, t2, "set abort", "SET ABORT ACK\n\r");
    poll(
        &mut s,
        Duration::from_millis(300),
        "IDLE",
        0,
        [3.0, -13.0, 11.0],
        "OK",
    );
    assert_eq!(
        s.ending(),
        Some(&Ending::Aborted {
            reason: "aborted by the operator".into(),
            line: 12
        })
    );
}

#[test]
fn a_stop_holds_the_machine_and_ends_the_session_at_the_line_reached() {
    let mut s = running();
    poll(&mut s, T0, "RUNNING", 501, [20.0, -13.0, 900.0], "OK");
    s.command(Command::Stop("interrupted (SIGINT)".into()));
    exchange(&mut s, T0, "set pause", "SET PAUSE ACK\n\r");
    assert_eq!(
        s.ending(),
        Some(&Ending::Held {
            reason: "interrupted (SIGINT)".into(),
            line: 501
        })
    );
}

#[test]
fn a_stop_before_the_program_runs_ends_with_nothing_run() {
    let mut s = logged_in(config());
    s.command(Command::Stop("interrupted (SIGTERM)".into()));
    match s.ending() {
        Some(Ending::Refused(why)) => assert!(why.contains("nothing ran"), "{why}"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn stray_and_empty_lines_are_skipped_and_answers_may_arrive_in_pieces() {
    let mut s = running();
    let sent = s.transmit(T0).unwrap();
    assert_eq!(sent, b"get program_status\r\n");
    s.receive(b"\r\n\nSET BOGUS NAK\n\rPROGRAM_ST");
    assert!(s.transmit(T0).is_none(), "still waiting for the answer");
    s.receive(b"ATUS PAUSED\r\n");
    assert_eq!(
        String::from_utf8(s.transmit(T0).unwrap()).unwrap(),
        "get program_line\r\n"
    );
}
