//! Stops, stalls, starting on a held controller, and where the controller is: the rules of
//! the module docs' "Starting on a held controller", "Stopping", "Stalls" and "Where the
//! controller is", against the hand-kept controller.

use super::*;

/// A writer with `options` streaming `n` linked segments into a fake of `slots`, started
/// and filled.
fn started_with(n: usize, slots: u16, options: WriterOptions) -> (RingWriter, Fake) {
    let mut w = RingWriter::new(linked(n), options).unwrap();
    let mut fake = Fake::new(slots);
    drive(&mut w, &mut fake, Duration::ZERO);
    events(&mut w);
    (w, fake)
}

/// Drives the writer every poll interval (50 ms) from `from` up to `to`, with `each`
/// changing the controller before every step; every request sent and event seen.
fn run_between(
    w: &mut RingWriter,
    fake: &mut Fake,
    from: Duration,
    to: Duration,
    mut each: impl FnMut(Duration, &mut Fake),
) -> (Vec<Request>, Vec<(Duration, WriterEvent)>) {
    let (mut sent, mut seen) = (Vec::new(), Vec::new());
    let mut now = from;
    while now <= to && !w.is_finished() {
        each(now, fake);
        sent.extend(drive(w, fake, now));
        seen.extend(events(w).into_iter().map(|e| (now, e)));
        now += 50 * MS;
    }
    (sent, seen)
}

fn publishes(sent: &[Request]) -> bool {
    sent.iter().any(|r| {
        matches!(r, Request::WriteMultiple { .. })
            || matches!(r, Request::WriteSingle { address, .. } if *address == reg::HEAD)
    })
}

#[test]
fn a_stop_writes_a_hold_edge_and_clears_run_once_the_machine_stands() {
    let (mut w, mut fake) = started(20, 8);
    events(&mut w);
    w.stop();
    let edges = drive(&mut w, &mut fake, Duration::ZERO);
    // "A rising edge is a bit written as 1 when the register held 0 there": HOLD written 0
    // with the levels (RUN), then 1.
    let run = control::RUN;
    assert_eq!(
        edges,
        [
            write(reg::CONTROL, run),
            write(reg::CONTROL, run | control::HOLD)
        ]
    );
    // Held, slowing down: the position still changes, so the writer waits. The controller
    // takes slots meanwhile; none is written in their place.
    let (sent, seen) = run_between(&mut w, &mut fake, 50 * MS, 200 * MS, |now, fake| {
        (fake.state, fake.tail) = (2, 5);
        fake.x = (now.as_millis() as i32).min(150);
    });
    assert!(!publishes(&sent), "{sent:?}");
    // 50, 100, 150 ms: the position moves; 200 ms: it reads as before: the machine stands,
    // and RUN is cleared (CONTROL = 0).
    assert_eq!(control_words(&sent), [0]);
    assert_eq!(sent.last(), Some(&write(reg::CONTROL, 0)));
    assert_eq!(seen.last(), Some(&(200 * MS, WriterEvent::Stopped)));
    assert!(w.is_finished());
    assert_eq!(w.poll(Duration::from_secs(1)), None);
}

#[test]
fn a_stop_waits_for_the_stand_no_longer_than_its_limit_and_leaves_run_set() {
    let options = WriterOptions {
        stand_timeout: 300 * MS,
        ..WriterOptions::default()
    };
    let (mut w, mut fake) = started_with(20, 8, options);
    w.stop();
    // The controller ignores the edge and keeps running.
    fake.state = 1;
    let (sent, seen) = run_between(
        &mut w,
        &mut fake,
        Duration::ZERO,
        Duration::from_secs(1),
        |now, fake| {
            fake.x = now.as_millis() as i32;
        },
    );
    let failed = seen.iter().find_map(|(t, e)| match e {
        WriterEvent::Failed(error) => Some((*t, error.clone())),
        _ => None,
    });
    let Some((at, error)) = failed else {
        panic!("no failure: {seen:?}");
    };
    assert_eq!(at, 300 * MS);
    assert!(matches!(
        error,
        WriterError::NotHeld {
            state: State::Running,
            ..
        }
    ));
    assert!(error.to_string().contains("RUN is left set"), "{error}");
    // RUN never cleared: the watchdog stops the machine once the bridge is gone.
    assert!(!control_words(&sent).contains(&0), "{sent:?}");
    assert!(w.is_finished());
}

#[test]
fn another_clients_hold_is_a_stall_that_ends_held() {
    let options = WriterOptions {
        stall_timeout: Some(Duration::from_secs(1)),
        ..WriterOptions::default()
    };
    let (mut w, mut fake) = started_with(20, 8, options);
    // Another client writes HOLD over RUN; the controller holds and stands.
    (fake.control, fake.state) = (control::RUN | control::HOLD, 2);
    let (sent, seen) = run_between(
        &mut w,
        &mut fake,
        50 * MS,
        Duration::from_secs(3),
        |_, _| {},
    );
    // The first status read at 50 ms is the last news: one second after it, the stall.
    let stalled = seen
        .iter()
        .find(|(_, e)| matches!(e, WriterEvent::Stalled { .. }))
        .expect("a stall");
    assert_eq!(
        *stalled,
        (
            1050 * MS,
            WriterEvent::Stalled {
                waited: Duration::from_secs(1)
            }
        )
    );
    // The edge rises although the register held HOLD: cleared first, then set; then, the
    // machine standing, RUN cleared.
    let run = control::RUN;
    assert_eq!(control_words(&sent), [run, run | control::HOLD, 0]);
    assert_eq!(seen.last().map(|(_, e)| e), Some(&WriterEvent::Stopped));
}

#[test]
fn news_from_the_controller_and_the_callers_hold_keep_the_stall_off() {
    let limit = Duration::from_secs(1);
    let options = WriterOptions {
        stall_timeout: Some(limit),
        ..WriterOptions::default()
    };
    let stalled = |seen: &[(Duration, WriterEvent)]| {
        seen.iter()
            .find(|(_, e)| matches!(e, WriterEvent::Stalled { .. }))
            .map(|(t, _)| *t)
    };
    // EXECUTED_SEQ moves every 900 ms: never a second without news.
    let (mut w, mut fake) = started_with(20, 8, options.clone());
    let (_, seen) = run_between(
        &mut w,
        &mut fake,
        50 * MS,
        Duration::from_secs(4),
        |now, fake| {
            fake.executed = (now.as_millis() / 900) as u32;
        },
    );
    assert_eq!(stalled(&seen), None);
    // The caller's hold: nothing changes for three seconds, and that is no stall; from the
    // resume on, the clock runs again.
    let (mut w, mut fake) = started_with(20, 8, options);
    w.hold();
    let (_, seen) = run_between(
        &mut w,
        &mut fake,
        50 * MS,
        Duration::from_secs(3),
        |_, _| {},
    );
    assert_eq!(stalled(&seen), None);
    w.resume();
    let resumed = Duration::from_secs(3);
    let (_, seen) = run_between(&mut w, &mut fake, resumed + 50 * MS, resumed * 2, |_, _| {});
    let at = stalled(&seen).expect("a stall after the resume");
    assert!(
        at >= resumed + limit && at <= resumed + limit + 50 * MS,
        "{at:?}"
    );
}

#[test]
fn a_held_controller_is_flushed_and_streamed_a_running_one_refused_untouched() {
    // Held: a stopped run's controller. The start is an idle one's: CONTROL 0, the ABORT
    // that flushes the ring, the slots.
    let mut w = writer(linked(3));
    let mut fake = Fake::new(8);
    (fake.state, fake.head, fake.tail) = (2, 5, 2);
    let sent = drive(&mut w, &mut fake, Duration::ZERO);
    assert_eq!(
        sent[..4],
        [
            read(0, 8),
            read(16, 19),
            write(reg::CONTROL, 0),
            write(reg::CONTROL, control::ABORT)
        ]
    );
    assert_eq!(published(&events(&mut w)), [(1, 0), (2, 1), (3, 2)]);
    // Running another program: refused, and nothing was written.
    let mut w = writer(linked(3));
    let mut fake = Fake::new(8);
    fake.state = 1;
    let sent = drive(&mut w, &mut fake, Duration::ZERO);
    assert!(
        sent.iter()
            .all(|r| matches!(r, Request::ReadHolding { .. })),
        "{sent:?}"
    );
    let failure = events(&mut w).into_iter().find_map(|e| match e {
        WriterEvent::Failed(error) => Some(error.to_string()),
        _ => None,
    });
    assert_eq!(
        failure.as_deref(),
        Some(
            "the controller is running (another program is under way), not idle, held or \
             done; nothing was written"
        )
    );
}

#[test]
fn executed_and_taken_count_from_the_flush_and_the_first_sequence() {
    let options = WriterOptions {
        first_sequence: 5,
        ..WriterOptions::default()
    };
    let mut w = RingWriter::new(linked(20), options).unwrap();
    let mut fake = Fake::new(8);
    // A finished program's EXECUTED_SEQ, read before the flush: not this stream's.
    (fake.state, fake.executed) = (4, 99);
    drive(&mut w, &mut fake, Duration::ZERO);
    assert_eq!((w.executed(), w.taken()), (0, 0));
    // Seven published (8 slots, one kept empty); the controller took three and reports
    // segment 6 done: the first two (5, 6) executed.
    (fake.state, fake.tail, fake.executed) = (1, 3, 6);
    drive(&mut w, &mut fake, 50 * MS);
    assert_eq!((w.executed(), w.taken()), (2, 3));
    // Past u32::MAX the numbers wrap to 1 (0 is never used): MAX, 1, 2 are three.
    let options = WriterOptions {
        first_sequence: u32::MAX,
        ..WriterOptions::default()
    };
    let mut w = RingWriter::new(linked(5), options).unwrap();
    let mut fake = Fake::new(8);
    drive(&mut w, &mut fake, Duration::ZERO);
    (fake.tail, fake.executed) = (3, 2);
    drive(&mut w, &mut fake, 50 * MS);
    assert_eq!(w.executed(), 3);
}

#[test]
fn a_stop_before_streaming_ends_at_once_and_done_beats_a_stop() {
    let mut w = writer(linked(3));
    w.stop();
    assert_eq!(events(&mut w), [WriterEvent::Stopped]);
    assert_eq!(w.poll(Duration::ZERO), None);
    // Everything published (END set): a stop whose status reads done has nothing left to
    // resume.
    let (mut w, mut fake) = started(2, 8);
    events(&mut w);
    w.stop();
    drive(&mut w, &mut fake, Duration::ZERO);
    (fake.state, fake.tail) = (4, 2);
    drive(&mut w, &mut fake, 50 * MS);
    assert_eq!(events(&mut w).last(), Some(&WriterEvent::Done));
}

#[test]
fn an_abort_during_a_stop_goes_ahead_of_it() {
    let (mut w, mut fake) = started(20, 8);
    events(&mut w);
    w.stop();
    w.abort();
    let sent = drive(&mut w, &mut fake, Duration::ZERO);
    assert_eq!(sent, [write(reg::CONTROL, control::RUN | control::ABORT)]);
    assert_eq!(events(&mut w), [WriterEvent::Aborted]);
}
