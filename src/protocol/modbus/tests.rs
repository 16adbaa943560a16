//! The ring writer against a controller kept by hand as `docs/modbus.md` states it: the
//! start, back-pressure, re-sends, exceptions, alarms, the caller's commands; stops,
//! stalls and where the controller is in [`stops`].

mod stops;

use super::map::{AlarmCode, WordOrder};
use super::*;

const MS: Duration = Duration::from_millis(1);

/// The controller's answers as `docs/modbus.md` states them, kept by hand: the
/// registers the writer reads, HEAD and TAIL, the control word's flush, and every
/// request in a log. TAIL moves only when a test says the controller took slots.
struct Fake {
    slots: u16,
    order: WordOrder,
    rate: u16,
    timeout_ms: u16,
    state: u16,
    alarm: u16,
    alarm_seq: u32,
    detail: u16,
    tail: u16,
    head: u16,
    control: u16,
    watchdog: u16,
    /// `EXECUTED_SEQ`.
    executed: u32,
    /// `POS_X`, 0.1 µm.
    x: i32,
    ring: Vec<u16>,
}

impl Fake {
    fn new(slots: u16) -> Fake {
        Fake {
            slots,
            order: WordOrder::HighFirst,
            rate: 1000,
            timeout_ms: 400,
            state: 0,
            alarm: 0,
            alarm_seq: 0,
            detail: 0,
            tail: 0,
            head: 0,
            control: 0,
            watchdog: 0,
            executed: 0,
            x: 0,
            ring: vec![0; usize::from(slots) * 16],
        }
    }

    fn answer(&mut self, request: &Request) -> Result<Response, Exception> {
        match *request {
            Request::ReadHolding {
                address: 0,
                count: 8,
            } => Ok(Response::ReadHolding(vec![
                0x5748,
                0x524C,
                1,
                self.slots,
                16,
                self.order.register(),
                self.rate,
                self.timeout_ms,
            ])),
            Request::ReadHolding {
                address: 16,
                count: 19,
            } => {
                let mut r = vec![self.state, self.alarm];
                r.extend(self.order.u32_words(self.alarm_seq));
                r.extend([self.detail, self.tail]);
                r.extend(self.order.u32_words(self.executed));
                r.extend(self.order.u32_words(self.x as u32));
                r.extend([0; 6]);
                r.extend([self.control, self.head, self.watchdog]);
                Ok(Response::ReadHolding(r))
            }
            Request::WriteSingle { address, value } => {
                match address {
                    32 => {
                        if value & !self.control & control::ABORT != 0 {
                            self.head = 0;
                            self.tail = 0;
                        }
                        self.control = value;
                    }
                    33 => self.head = value,
                    34 => self.watchdog = value,
                    _ => return Err(Exception::IllegalDataAddress),
                }
                Ok(Response::WriteSingle { address, value })
            }
            Request::WriteMultiple {
                address,
                ref values,
            } if address >= 256 => {
                let at = usize::from(address - 256);
                self.ring[at..at + values.len()].copy_from_slice(values);
                Ok(Response::WriteMultiple {
                    address,
                    count: values.len() as u16,
                })
            }
            _ => Err(Exception::IllegalDataAddress),
        }
    }

    /// The sequence number in slot `i`.
    fn sequence_in(&self, i: u16) -> u32 {
        let at = usize::from(i) * 16;
        self.order.u32_from([self.ring[at], self.ring[at + 1]])
    }
}

/// Sends and answers requests until the writer waits; returns them.
fn drive(writer: &mut RingWriter, fake: &mut Fake, now: Duration) -> Vec<Request> {
    let mut sent = Vec::new();
    while let Some(request) = writer.poll(now) {
        let answer = fake.answer(&request);
        writer.response(answer);
        sent.push(request);
    }
    sent
}

fn events(writer: &mut RingWriter) -> Vec<WriterEvent> {
    std::iter::from_fn(|| writer.next_event()).collect()
}

fn published(events: &[WriterEvent]) -> Vec<(u32, u16)> {
    events
        .iter()
        .filter_map(|e| match *e {
            WriterEvent::Published { sequence, slot } => Some((sequence, slot)),
            _ => None,
        })
        .collect()
}

fn linked(n: usize) -> Vec<Segment> {
    (0..n)
        .map(|i| Segment::Linked {
            x: 100_000,
            z: i as i32 * 1000,
            c: i as i64 * 3_600_000,
            duration_us: 10_000,
        })
        .collect()
}

fn read(address: u16, count: u16) -> Request {
    Request::ReadHolding { address, count }
}

fn write(address: u16, value: u16) -> Request {
    Request::WriteSingle { address, value }
}

fn writer(segments: Vec<Segment>) -> RingWriter {
    RingWriter::new(segments, WriterOptions::default()).unwrap()
}

/// A writer streaming `n` linked segments into a fake of `slots`, started and filled.
fn started(n: usize, slots: u16) -> (RingWriter, Fake) {
    let mut w = writer(linked(n));
    let mut fake = Fake::new(slots);
    drive(&mut w, &mut fake, Duration::ZERO);
    (w, fake)
}

#[test]
fn identify_inspect_flush_fill_then_run() {
    let mut w = writer(linked(5));
    let mut fake = Fake::new(4);
    // Leftovers of an earlier stream, which the flush clears.
    (fake.head, fake.tail, fake.control) = (2, 1, control::RUN | control::END);
    let sent = drive(&mut w, &mut fake, Duration::ZERO);
    let kinds: Vec<Request> = sent
        .iter()
        .map(|r| match r {
            Request::WriteMultiple { address, .. } => read(*address, 0),
            other => other.clone(),
        })
        .collect();
    // Doc, "The bridge's stream": identification, status, CONTROL 0 then ABORT (16),
    // slots 0, 1, 2 each followed by its HEAD write, and the ring of 4 is full
    // (HEAD 3 + 1 = TAIL 0 mod 4): RUN (1) and wait.
    assert_eq!(
        kinds,
        vec![
            read(0, 8),
            read(16, 19),
            write(32, 0),
            write(32, 16),
            read(256, 0),
            write(33, 1),
            read(272, 0),
            write(33, 2),
            read(288, 0),
            write(33, 3),
            write(32, 1),
        ]
    );
    for (slot, sequence) in [(0, 1), (1, 2), (2, 3)] {
        assert_eq!(fake.sequence_in(slot), sequence);
        let at = usize::from(slot) * 16;
        assert_eq!(fake.ring[at + 15], map::slot_crc(&fake.ring[at..at + 15]));
    }
    let ev = events(&mut w);
    assert!(matches!(ev[0], WriterEvent::Identified(i) if i.slots == 4));
    assert!(matches!(ev[1], WriterEvent::Status(_)));
    assert_eq!(published(&ev), vec![(1, 0), (2, 1), (3, 2)]);
    assert!(!w.is_finished());
}

/// The control words a run wrote, in order.
fn control_words(sent: &[Request]) -> Vec<u16> {
    sent.iter()
        .filter_map(|r| match *r {
            Request::WriteSingle { address, value } if address == reg::CONTROL => Some(value),
            _ => None,
        })
        .collect()
}

#[test]
fn hold_and_resume_are_edges_written_ahead_of_slots_then_cleared() {
    let mut fake = Fake::new(8);
    let mut w = writer(linked(20));
    let mut sent = drive(&mut w, &mut fake, Duration::ZERO);
    let started = control_words(&sent);
    // The start: CONTROL 0, ABORT (the flush), then RUN once the ring is filled.
    assert_eq!(started, [0, control::ABORT, control::RUN]);
    w.hold();
    w.hold();
    sent = drive(&mut w, &mut fake, Duration::ZERO);
    // Each hold is a rising edge over RUN, cleared again so the next is one too.
    let hold = control::RUN | control::HOLD;
    assert_eq!(
        control_words(&sent),
        [hold, control::RUN, hold, control::RUN]
    );
    // Nothing else went out: the ring is full, so no slot was waiting.
    assert_eq!(sent.len(), 4);
    fake.tail = 4;
    w.resume();
    sent = drive(&mut w, &mut fake, 60 * MS);
    let resume = control::RUN | control::RESUME;
    assert_eq!(control_words(&sent)[..2], [resume, control::RUN]);
    // The command went before the slots the freed room let in.
    assert_eq!(sent[0], write(reg::CONTROL, resume));
    assert!(sent[2..]
        .iter()
        .any(|r| matches!(r, Request::WriteMultiple { .. })));
    assert!(!w.is_finished());
}

#[test]
fn an_abort_flushes_the_ring_and_ends_the_stream() {
    let mut fake = Fake::new(8);
    let mut w = writer(linked(20));
    drive(&mut w, &mut fake, Duration::ZERO);
    events(&mut w);
    w.abort();
    let sent = drive(&mut w, &mut fake, Duration::ZERO);
    assert_eq!(sent, [write(reg::CONTROL, control::RUN | control::ABORT)]);
    assert_eq!((fake.head, fake.tail), (0, 0), "the controller flushed");
    assert_eq!(events(&mut w), [WriterEvent::Aborted]);
    assert!(w.is_finished());
    assert_eq!(w.poll(Duration::from_secs(1)), None);
    // Before the stream began, an abort ends it without a word to the controller.
    let mut early = writer(linked(3));
    early.abort();
    assert_eq!(events(&mut early), [WriterEvent::Aborted]);
    assert_eq!(early.poll(Duration::ZERO), None);
}

#[test]
fn a_full_ring_holds_the_writer_back_and_wraps() {
    let (mut w, mut fake) = started(5, 4);
    events(&mut w);
    // 50 ms: the status poll; TAIL has not moved, so nothing is written.
    assert_eq!(drive(&mut w, &mut fake, 50 * MS), vec![read(16, 19)]);
    assert_eq!(drive(&mut w, &mut fake, 60 * MS), vec![]);
    // The controller takes two slots. At 100 ms the watchdog (a quarter of 400 ms) and
    // the status; then slot 3 and slot 0 (wrapping), and END with the last.
    fake.tail = 2;
    let sent = drive(&mut w, &mut fake, 100 * MS);
    let addresses: Vec<(u16, Option<u16>)> = sent
        .iter()
        .map(|r| match *r {
            Request::ReadHolding { address, .. } => (address, None),
            Request::WriteSingle { address, value } => (address, Some(value)),
            Request::WriteMultiple { address, .. } => (address, None),
        })
        .collect();
    assert_eq!(
        addresses,
        vec![
            (34, Some(1)),
            (16, None),
            (256 + 48, None),
            (33, Some(0)),
            (256, None),
            (33, Some(1)),
            (32, Some(control::RUN | control::END)),
        ]
    );
    assert_eq!(published(&events(&mut w)), vec![(4, 3), (5, 0)]);
    // With END written the watchdog is no longer fed; the status is polled until done.
    assert_eq!(drive(&mut w, &mut fake, 200 * MS), vec![read(16, 19)]);
    (fake.tail, fake.state) = (1, 4);
    assert_eq!(drive(&mut w, &mut fake, 250 * MS), vec![read(16, 19)]);
    let ev = events(&mut w);
    assert_eq!(ev.last(), Some(&WriterEvent::Done));
    assert!(w.is_finished());
    assert_eq!(w.poll(300 * MS), None);
}

#[test]
fn everything_fits_runs_with_end_at_once() {
    let (mut w, mut fake) = started(2, 8);
    assert_eq!(fake.control, control::RUN | control::END);
    fake.state = 4;
    fake.tail = 2;
    drive(&mut w, &mut fake, 50 * MS);
    assert_eq!(events(&mut w).last(), Some(&WriterEvent::Done));
}

#[test]
fn the_watchdog_counts_up_every_quarter_timeout() {
    let (mut w, mut fake) = started(10, 2);
    let mut values = Vec::new();
    for t in (10..=350).step_by(10) {
        for r in drive(&mut w, &mut fake, t * MS) {
            if let Request::WriteSingle { address: 34, value } = r {
                values.push((t, value));
            }
        }
    }
    assert_eq!(values, vec![(100, 1), (200, 2), (300, 3)]);
}

#[test]
fn a_timed_out_write_is_sent_again_unchanged() {
    let mut w = writer(linked(2));
    let mut fake = Fake::new(4);
    // Through the flush.
    for _ in 0..4 {
        let r = w.poll(Duration::ZERO).unwrap();
        w.response(fake.answer(&r));
    }
    // The slot write lands but its answer is lost; the copy lands again.
    let slot = w.poll(Duration::ZERO).unwrap();
    fake.answer(&slot).unwrap();
    assert_eq!(w.poll(Duration::ZERO), None, "one request at a time");
    w.timeout();
    assert_eq!(w.poll(Duration::ZERO), Some(slot.clone()));
    w.response(fake.answer(&slot));
    // The HEAD write lands, its answer is lost, the copy publishes nothing more.
    let head = w.poll(Duration::ZERO).unwrap();
    assert_eq!(head, write(33, 1));
    fake.answer(&head).unwrap();
    w.timeout();
    assert_eq!(w.poll(Duration::ZERO), Some(head.clone()));
    w.response(fake.answer(&head));
    // The next slot carries the next number: nothing repeated, nothing skipped.
    drive(&mut w, &mut fake, Duration::ZERO);
    assert_eq!(published(&events(&mut w)), vec![(1, 0), (2, 1)]);
    assert_eq!((fake.sequence_in(0), fake.sequence_in(1)), (1, 2));
}

#[test]
fn no_answer_after_the_retries_fails() {
    let mut w = writer(linked(1));
    let first = w.poll(Duration::ZERO).unwrap();
    // Sent once and re-sent three times (max_retries), then given up.
    for _ in 0..3 {
        w.timeout();
        assert_eq!(w.poll(Duration::ZERO), Some(first.clone()));
    }
    w.timeout();
    assert!(w.is_finished());
    assert_eq!(
        events(&mut w),
        vec![WriterEvent::Failed(WriterError::NoAnswer {
            request: first,
            attempts: 4
        })]
    );
}

#[test]
fn busy_is_retried_after_the_poll_interval() {
    let mut w = writer(linked(1));
    let mut fake = Fake::new(4);
    for _ in 0..4 {
        let r = w.poll(Duration::ZERO).unwrap();
        w.response(fake.answer(&r));
    }
    let slot = w.poll(10 * MS).unwrap();
    w.response(Err(Exception::ServerDeviceBusy));
    assert_eq!(w.poll(59 * MS), None);
    assert_eq!(w.poll(60 * MS), Some(slot));
    assert!(!w.is_finished());
}

#[test]
fn a_refused_slot_ends_with_its_alarm() {
    let mut w = writer(linked(1));
    let mut fake = Fake::new(4);
    for _ in 0..5 {
        let r = w.poll(Duration::ZERO).unwrap();
        w.response(fake.answer(&r));
    }
    // The HEAD write is refused (04): the controller raised alarm 101 at sequence 1.
    assert_eq!(w.poll(Duration::ZERO), Some(write(33, 1)));
    w.response(Err(Exception::ServerDeviceFailure));
    (fake.state, fake.alarm, fake.alarm_seq) = (3, 101, 1);
    assert_eq!(drive(&mut w, &mut fake, Duration::ZERO), vec![read(16, 19)]);
    let ev = events(&mut w);
    assert_eq!(
        ev.last(),
        Some(&WriterEvent::Alarm(AlarmReport {
            code: AlarmCode::SlotCrc,
            sequence: 1,
            detail: 0
        }))
    );
    assert!(published(&ev).is_empty());
    assert!(w.is_finished());
}

#[test]
fn a_failure_without_an_alarm_is_an_error() {
    let mut w = writer(linked(1));
    let mut fake = Fake::new(4);
    for _ in 0..5 {
        let r = w.poll(Duration::ZERO).unwrap();
        w.response(fake.answer(&r));
    }
    w.poll(Duration::ZERO);
    w.response(Err(Exception::ServerDeviceFailure));
    drive(&mut w, &mut fake, Duration::ZERO);
    assert_eq!(
        events(&mut w).last(),
        Some(&WriterEvent::Failed(WriterError::Exception {
            request: write(33, 1),
            exception: Exception::ServerDeviceFailure
        }))
    );
    // Before streaming, 04 is an error at once.
    let mut w = writer(linked(1));
    w.poll(Duration::ZERO);
    w.response(Err(Exception::ServerDeviceFailure));
    assert!(matches!(
        events(&mut w)[..],
        [WriterEvent::Failed(WriterError::Exception {
            exception: Exception::ServerDeviceFailure,
            ..
        })]
    ));
}

#[test]
fn an_alarm_in_the_status_ends_the_stream() {
    let (mut w, mut fake) = started(10, 4);
    (fake.state, fake.alarm, fake.alarm_seq, fake.detail) = (3, 2, 3, 15);
    drive(&mut w, &mut fake, 50 * MS);
    let ev = events(&mut w);
    assert_eq!(
        ev.last(),
        Some(&WriterEvent::Alarm(AlarmReport {
            code: AlarmCode::SoftLimit,
            sequence: 3,
            detail: 15
        }))
    );
    assert!(w.is_finished());
    // Answers and timeouts after the end are ignored.
    w.response(Ok(Response::ReadHolding(vec![])));
    w.timeout();
    assert_eq!(w.next_event(), None);
}

#[test]
fn sequence_numbers_wrap_past_u32_max() {
    let options = WriterOptions {
        first_sequence: u32::MAX,
        ..WriterOptions::default()
    };
    let mut w = RingWriter::new(linked(3), options).unwrap();
    let mut fake = Fake::new(8);
    drive(&mut w, &mut fake, Duration::ZERO);
    assert_eq!(
        published(&events(&mut w)),
        vec![(u32::MAX, 0), (1, 1), (2, 2)]
    );
    assert_eq!(&fake.ring[0..2], &[0xFFFF, 0xFFFF]);
    assert_eq!(&fake.ring[16..18], &[0, 1]);
    assert_eq!(
        RingWriter::new(
            linked(1),
            WriterOptions {
                first_sequence: 0,
                ..WriterOptions::default()
            }
        )
        .unwrap_err(),
        WriterError::ZeroSequence
    );
}

#[test]
fn low_word_first_controllers_get_low_word_first_slots() {
    let mut w = writer(linked(2));
    let mut fake = Fake::new(4);
    fake.order = WordOrder::LowFirst;
    drive(&mut w, &mut fake, Duration::ZERO);
    // Sequence 2 low word first: 0x0002 then 0x0000.
    assert_eq!(&fake.ring[16..18], &[2, 0]);
    fake.tail = 2;
    fake.state = 4;
    drive(&mut w, &mut fake, 50 * MS);
    assert_eq!(events(&mut w).last(), Some(&WriterEvent::Done));
}

#[test]
fn refusals_before_streaming() {
    let first_event = |fake: &mut Fake, segments: Vec<Segment>| {
        let mut w = writer(segments);
        drive(&mut w, fake, Duration::ZERO);
        assert!(w.is_finished());
        events(&mut w)
            .into_iter()
            .find(|e| matches!(e, WriterEvent::Failed(_)))
            .unwrap()
    };
    // Not idle: running.
    let mut fake = Fake::new(4);
    fake.state = 1;
    assert!(matches!(
        first_event(&mut fake, linked(1)),
        WriterEvent::Failed(WriterError::NotReady(Status {
            state: State::Running,
            ..
        }))
    ));
    // In alarm from before.
    let mut fake = Fake::new(4);
    (fake.state, fake.alarm) = (3, 104);
    let WriterEvent::Failed(e) = first_event(&mut fake, linked(1)) else {
        unreachable!()
    };
    assert_eq!(
        e.to_string(),
        "the controller is in alarm 104 (watchdog), not idle, held or done; nothing was \
         written"
    );
    // Not a whirl map.
    let mut fake = Fake::new(1);
    assert!(matches!(
        first_event(&mut fake, linked(1)),
        WriterEvent::Failed(WriterError::Map(MapError::Register { register: 3, .. }))
    ));
    // 10 ms segments on a controller of at most 50 segments/s (20 ms).
    let mut fake = Fake::new(4);
    fake.rate = 50;
    assert!(matches!(
        first_event(&mut fake, linked(1)),
        WriterEvent::Failed(WriterError::Segments(SegmentError::TooShort {
            min_us: 20_000,
            ..
        }))
    ));
}

#[test]
fn malformed_answers_fail_the_stream() {
    let failed = |answers: &dyn Fn(&Request) -> Option<Result<Response, Exception>>| {
        let mut w = writer(linked(1));
        let mut fake = Fake::new(4);
        while let Some(r) = w.poll(Duration::ZERO) {
            let answer = answers(&r).unwrap_or_else(|| fake.answer(&r));
            w.response(answer);
        }
        match events(&mut w).pop() {
            Some(WriterEvent::Failed(e)) => e,
            other => panic!("expected a failure, got {other:?}"),
        }
    };
    // A read answered with the wrong number of registers.
    let e = failed(&|r| (*r == read(0, 8)).then(|| Ok(Response::ReadHolding(vec![0x5748]))));
    assert!(matches!(e, WriterError::BadResponse { .. }));
    // A write echoed with another value.
    let e = failed(&|r| {
        (*r == write(32, 16)).then_some(Ok(Response::WriteSingle {
            address: 32,
            value: 0,
        }))
    });
    assert!(matches!(e, WriterError::BadResponse { .. }));
    // A slot write answered as a read.
    let e = failed(&|r| {
        matches!(r, Request::WriteMultiple { .. }).then(|| Ok(Response::ReadHolding(vec![])))
    });
    assert!(matches!(e, WriterError::BadResponse { .. }));
    // A slot write acknowledged at another address.
    let e = failed(&|r| {
        matches!(r, Request::WriteMultiple { .. }).then_some(Ok(Response::WriteMultiple {
            address: 0,
            count: 16,
        }))
    });
    assert!(matches!(e, WriterError::BadResponse { .. }));
    // Exceptions other than 04 and 06.
    let e = failed(&|r| (*r == write(33, 1)).then_some(Err(Exception::IllegalDataValue)));
    assert_eq!(
        e,
        WriterError::Exception {
            request: write(33, 1),
            exception: Exception::IllegalDataValue
        }
    );
    assert_eq!(
        e.to_string(),
        "FC06 write 0x0001 to register 33: exception 03 (illegal data value)"
    );
    let e = failed(&|r| (*r == read(0, 8)).then_some(Err(Exception::IllegalFunction)));
    assert!(
        e.to_string().ends_with("exception 01 (illegal function)"),
        "{e}"
    );
    let e = failed(&|r| {
        matches!(r, Request::WriteMultiple { .. }).then_some(Err(Exception::IllegalDataAddress))
    });
    assert_eq!(
        e.to_string(),
        "FC16 write 16 registers at 256: exception 02 (illegal data address)"
    );
    // A status block that does not decode (state 9).
    let e = failed(&|r| {
        (*r == read(16, 19)).then(|| {
            let mut regs = vec![0; 19];
            regs[0] = 9;
            Ok(Response::ReadHolding(regs))
        })
    });
    assert!(matches!(
        e,
        WriterError::Map(MapError::Register { register: 16, .. })
    ));
    assert_eq!(
        Exception::ServerDeviceBusy.to_string(),
        "exception 06 (server device busy)"
    );
    assert_eq!(read(16, 19).to_string(), "FC03 read 19 registers at 16");
}

#[test]
fn a_caller_out_of_step_fails_the_stream() {
    let mut w = writer(linked(1));
    w.response(Ok(Response::ReadHolding(vec![])));
    assert_eq!(
        events(&mut w),
        vec![WriterEvent::Failed(WriterError::Unexpected("a response"))]
    );
    let mut w = writer(linked(1));
    w.timeout();
    let e = WriterError::Unexpected("a timeout");
    assert_eq!(e.to_string(), "a timeout with no request outstanding");
    assert_eq!(events(&mut w), vec![WriterEvent::Failed(e)]);
}

#[test]
fn a_ring_flushed_under_the_stream_is_noticed() {
    let (mut w, mut fake) = started(10, 4);
    // Someone else aborted: HEAD and TAIL read 0 where the writer wrote 3.
    (fake.head, fake.tail) = (0, 0);
    drive(&mut w, &mut fake, 50 * MS);
    assert_eq!(
        events(&mut w).last(),
        Some(&WriterEvent::Failed(WriterError::RingReset {
            written: 3,
            read: 0
        }))
    );
}

#[test]
fn a_program_streams_from_its_blocks() {
    // segments() and the writer together: the program's blocks, then M2.
    use crate::program::{Move, Program};
    let program = Program {
        moves: vec![Move::SpindleOn { rpm: 1000.0 }, Move::SpindleOff],
    };
    let mut w = writer(crate::post::modbus::segments(&program).unwrap());
    let mut fake = Fake::new(8);
    drive(&mut w, &mut fake, Duration::ZERO);
    let kinds: Vec<u16> = (0..3).map(|i| fake.ring[i * 16 + 2]).collect();
    assert_eq!(
        kinds,
        vec![
            map::kind::SPINDLE_ON,
            map::kind::SPINDLE_OFF,
            map::kind::PROGRAM_END
        ]
    );
}
