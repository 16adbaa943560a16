//! Tests of the register bank, kept apart from it for length: slots run as G-code, the
//! ring, the executed sequence, alarms, the watchdog, hold, abort and bad requests.

use super::*;
use crate::error::{Alarm as GrblAlarm, GrblError};
use crate::guard::{Breach, Guard, Measured};
use crate::machine::{Axis, Machine, Number};
use crate::record::ExecutedBlock;
use crate::ControllerOptions;

/// X 0–100 mm, Z ±200 mm at 3000 mm/min and 500 mm/s², C unlimited at 72 000 °/min
/// and 7200 °/s², 64-bit numbers.
fn machine() -> Machine {
    let linear = |min, max| Axis {
        min: Some(min),
        max: Some(max),
        max_rate: 3000.0,
        accel: 500.0,
    };
    Machine {
        x: linear(0.0, 100.0),
        z: linear(-200.0, 200.0),
        c: Axis {
            min: None,
            max: None,
            max_rate: 72_000.0,
            accel: 7200.0,
        },
        number: Number::F64,
        max_line_length: 256,
        spindle_rpm: None,
    }
}

/// A bank in front of a controller with a planner of 35 blocks (`$398=35`), which the
/// figures of these tests count on.
fn bank_on(machine: &Machine, options: BankOptions) -> Bank {
    let controller = Controller::new(
        machine,
        ControllerOptions {
            planner_blocks: 35,
            ..ControllerOptions::default()
        },
    )
    .unwrap();
    Bank::new(controller, options).unwrap()
}

fn bank(slots: u16) -> Bank {
    bank_on(
        &machine(),
        BankOptions {
            slots,
            ..BankOptions::default()
        },
    )
}

/// A slot as docs/modbus.md lays it out, written here word by word: SEQ, KIND, 0,
/// X (i32), Z (i32), C (i64), PARAM, 0, CRC over registers 0–14 high byte first.
fn slot(sequence: u32, kind: u16, xzc: [i64; 3], param: u32, low_first: bool) -> [u16; 16] {
    let words = |value: u64, n: usize| -> Vec<u16> {
        let mut w: Vec<u16> = (0..n).rev().map(|k| (value >> (16 * k)) as u16).collect();
        if low_first {
            w.reverse();
        }
        w
    };
    let mut r = Vec::new();
    r.extend(words(u64::from(sequence), 2));
    r.extend([kind, 0]);
    r.extend(words(u64::from(xzc[0] as i32 as u32), 2));
    r.extend(words(u64::from(xzc[1] as i32 as u32), 2));
    r.extend(words(xzc[2] as u64, 4));
    r.extend(words(u64::from(param), 2));
    r.push(0);
    let bytes: Vec<u8> = r.iter().flat_map(|w| [(w >> 8) as u8, *w as u8]).collect();
    r.push(crc16(&bytes));
    r.try_into().unwrap()
}

/// A linked move (kind 1, flags X Z C = 0x0701), mm, mm, degrees, seconds.
fn linked(sequence: u32, x: f64, z: f64, c: f64, seconds: f64) -> [u16; 16] {
    let units = |v: f64| (v * 1e4).round() as i64;
    let micros = (seconds * 1e6).round() as u32;
    slot(
        sequence,
        0x0701,
        [units(x), units(z), units(c)],
        micros,
        false,
    )
}

fn read(bank: &mut Bank, address: u16, count: u16) -> Result<Vec<u16>, Exception> {
    match bank.request(&Request::ReadHolding { address, count })? {
        Response::ReadHolding(values) => Ok(values),
        other => panic!("a read answered {other:?}"),
    }
}

fn reg(bank: &mut Bank, address: u16) -> u16 {
    read(bank, address, 1).unwrap()[0]
}

fn write(bank: &mut Bank, address: u16, value: u16) -> Result<Response, Exception> {
    bank.request(&Request::WriteSingle { address, value })
}

fn write_slot(bank: &mut Bank, index: u16, values: &[u16]) -> Result<Response, Exception> {
    bank.request(&Request::WriteMultiple {
        address: 256 + 16 * index,
        values: values.to_vec(),
    })
}

/// Writes `slots` from HEAD on, then moves HEAD past them; the HEAD write's answer.
fn publish(bank: &mut Bank, slots: &[[u16; 16]]) -> Result<Response, Exception> {
    let n = reg(bank, 3);
    let mut head = reg(bank, 33);
    for s in slots {
        write_slot(bank, head, s).unwrap();
        head = (head + 1) % n;
    }
    write(bank, 33, head)
}

/// STATE, ALARM_CODE, ALARM_SEQ (high word first), ALARM_DETAIL.
fn alarm(bank: &mut Bank) -> (u16, u16, u32, u16) {
    let r = read(bank, 16, 5).unwrap();
    (r[0], r[1], (u32::from(r[2]) << 16) | u32::from(r[3]), r[4])
}

/// (TAIL, HEAD, EXECUTED_SEQ).
fn ring(bank: &mut Bank) -> (u16, u16, u32) {
    let r = read(bank, 21, 3).unwrap();
    (
        r[0],
        reg(bank, 33),
        (u32::from(r[1]) << 16) | u32::from(r[2]),
    )
}

fn lines(events: &[Event]) -> Vec<(String, Option<GrblError>)> {
    events
        .iter()
        .filter_map(|e| match e {
            Event::Line { text, error, .. } => Some((text.clone(), *error)),
            _ => None,
        })
        .collect()
}

fn executed(events: &[Event]) -> Vec<u32> {
    events
        .iter()
        .filter_map(|e| match e {
            Event::Executed(b) if b.completed => b.n,
            _ => None,
        })
        .collect()
}

/// Advances in 10 ms steps until `done` or `seconds` have passed; the events.
fn run(bank: &mut Bank, seconds: f64, done: impl Fn(&mut Bank) -> bool) -> Vec<Event> {
    let mut events = bank.take_events();
    let mut t = 0.0;
    while t < seconds && !done(bank) {
        bank.advance(0.01).unwrap();
        events.extend(bank.take_events());
        t += 0.01;
    }
    events
}

fn state(bank: &mut Bank) -> u16 {
    reg(bank, 16)
}

#[test]
fn identification_block() {
    let mut b = bank(4);
    assert_eq!(
        read(&mut b, 0, 8),
        Ok(vec![0x5748, 0x524C, 1, 4, 16, 0, 1000, 1000])
    );
    // "WHRL".
    assert_eq!([0x57, 0x48, 0x52, 0x4C], *b"WHRL");
    let mut low = bank_on(
        &machine(),
        BankOptions {
            word_order: WordOrder::LowFirst,
            max_segment_rate: 250,
            watchdog_timeout_ms: 200,
            ..BankOptions::default()
        },
    );
    assert_eq!(read(&mut low, 3, 5), Ok(vec![32, 16, 1, 250, 200]));
    // Power-up: idle, no alarm, empty ring, nothing executed, at the origin.
    assert_eq!(read(&mut b, 16, 19), Ok(vec![0; 19]));
}

#[test]
fn slots_run_as_the_g_code_they_stand_for() {
    let mut b = bank(8);
    let units = |v: f64| (v * 1e4).round() as i64;
    let slots = [
        // Rapid X10 Z0 C0 (flags X Z C).
        slot(1, 0x0702, [units(10.0), 0, 0], 0, false),
        // Spindle on at 2500.5 rpm.
        slot(2, 5, [0; 3], 2_500_500, false),
        // Feed X alone to 9.5 mm at 100 mm/min.
        slot(3, 0x0103, [units(9.5), 0, 0], 100_000, false),
        // Linked to X 9.5, Z 1, C 360 in 0.5 s: F = 1 / (0.5 / 60) = 120.
        linked(4, 9.5, 1.0, 360.0, 0.5),
        // Dwell 0.25 s, spindle off, program end.
        slot(5, 4, [0; 3], 250_000, false),
        slot(6, 6, [0; 3], 0, false),
        slot(7, 7, [0; 3], 0, false),
    ];
    assert!(publish(&mut b, &slots).is_ok());
    // RUN clear: published, waiting.
    assert_eq!(ring(&mut b), (0, 7, 0));
    assert_eq!(state(&mut b), 0);
    write(&mut b, 32, 1 | 32).unwrap();
    assert_eq!(state(&mut b), 1);
    let events = run(&mut b, 30.0, |b| state(b) == 4);
    let expected = [
        "N1 G0 X10 Z0 C0",
        "N2 M3 S2500.5",
        "N3 G94 G1 X9.5 F100",
        "N4 G93 G1 X9.5 Z1 C360 F120",
        "N5 G4 P0.25",
        "N6 M5",
        "N7 M2",
    ];
    let got = lines(&events);
    assert_eq!(
        got,
        expected.map(|t| (t.to_owned(), None)).to_vec(),
        "every slot one line, answered ok"
    );
    assert_eq!(executed(&events), vec![1, 3, 4]);
    // Done: TAIL caught up with HEAD, everything executed, at X 9.5, Z 1, C 360
    // (95 000 = 0x00017318, 10 000, 3 600 000 = 0x0036EE80).
    assert_eq!(ring(&mut b), (7, 7, 7));
    assert_eq!(
        read(&mut b, 24, 8),
        Ok(vec![0x0001, 0x7318, 0, 10_000, 0, 0, 0x0036, 0xEE80])
    );
}

#[test]
fn c_near_700_000_degrees() {
    for low_first in [false, true] {
        let mut b = bank_on(
            &machine(),
            BankOptions {
                word_order: if low_first {
                    WordOrder::LowFirst
                } else {
                    WordOrder::HighFirst
                },
                ..BankOptions::default()
            },
        );
        // A rapid of C alone (flag C, 0x0402) to 700 000.1234° = 7 000 001 234 units.
        let s = slot(1, 0x0402, [0, 0, 7_000_001_234], 0, low_first);
        assert!(publish(&mut b, &[s]).is_ok());
        write(&mut b, 32, 1 | 32).unwrap();
        let events = run(&mut b, 1000.0, |b| state(b) == 4);
        // The line carries every digit; grblHAL's read_float keeps 9 significant ones,
        // so the controller goes to 700 000.123° = 7 000 001 230 units; 7 000 001 230 −
        // 2³² = 2 705 033 934 = 0xA13B·65 536 + 0x8ACE: 0x0000 0x0001 0xA13B 0x8ACE.
        assert_eq!(lines(&events)[0].0, "N1 G0 C700000.1234");
        let c = read(&mut b, 28, 4).unwrap();
        let high = [0x0000, 0x0001, 0xA13B, 0x8ACE];
        if low_first {
            assert_eq!(c, high.iter().rev().copied().collect::<Vec<_>>());
        } else {
            assert_eq!(c, high);
        }
    }
}

#[test]
fn the_ring_fills_empties_and_wraps() {
    let mut b = bank(4);
    let moves: Vec<[u16; 16]> = (1..=6)
        .map(|k| linked(k, 10.0, f64::from(k), 0.0, 0.1))
        .collect();
    // Empty: HEAD = TAIL = 0. Three slots fill a ring of four.
    assert_eq!(ring(&mut b), (0, 0, 0));
    assert!(publish(&mut b, &moves[0..3]).is_ok());
    assert_eq!(ring(&mut b), (0, 3, 0));
    // Full ((3 + 1) mod 4 = TAIL 0): a fourth is refused, 03, and HEAD stays.
    write_slot(&mut b, 3, &moves[3]).unwrap();
    assert_eq!(write(&mut b, 33, 0), Err(Exception::IllegalDataValue));
    // Backwards is as far beyond the free slots.
    assert_eq!(write(&mut b, 33, 1), Err(Exception::IllegalDataValue));
    // The same value again publishes nothing and is answered.
    assert!(write(&mut b, 33, 3).is_ok());
    assert_eq!(ring(&mut b), (0, 3, 0));
    // RUN: the planner takes all three at once, TAIL catches up: empty again.
    write(&mut b, 32, 1).unwrap();
    assert_eq!(ring(&mut b).0, 3);
    // Three more go to slots 3, 0, 1: HEAD wraps to 2.
    assert!(publish(&mut b, &moves[3..6]).is_ok());
    assert_eq!(ring(&mut b).1, 2);
    write(&mut b, 32, 1 | 32).unwrap();
    let events = run(&mut b, 30.0, |b| state(b) == 4);
    assert_eq!(executed(&events), vec![1, 2, 3, 4, 5, 6]);
    assert_eq!(ring(&mut b), (2, 2, 6));
}

#[test]
fn executed_trails_tail() {
    let mut b = bank(8);
    let moves: Vec<[u16; 16]> = (1..=3)
        .map(|k| linked(k, 10.0, f64::from(k), 0.0, 0.5))
        .collect();
    publish(&mut b, &moves).unwrap();
    write(&mut b, 32, 1 | 32).unwrap();
    // Taken into the planner at once, executed over 1.5 s and more.
    assert_eq!(ring(&mut b), (3, 3, 0));
    b.advance(0.25).unwrap();
    assert_eq!(ring(&mut b), (3, 3, 0));
    assert_eq!(state(&mut b), 1);
    run(&mut b, 10.0, |b| state(b) == 4);
    assert_eq!(ring(&mut b), (3, 3, 3));
}

#[test]
fn a_slot_written_twice_runs_once() {
    let mut b = bank(4);
    let s = linked(1, 5.0, 1.0, 90.0, 0.2);
    // Written, its answer "lost", written again: the same slot.
    assert!(write_slot(&mut b, 0, &s).is_ok());
    assert!(write_slot(&mut b, 0, &s).is_ok());
    assert!(write(&mut b, 33, 1).is_ok());
    // A copy arriving after publication changes nothing and is accepted, as is HEAD
    // written again; a write that would change the published slot is refused, 06.
    assert!(write_slot(&mut b, 0, &s).is_ok());
    assert!(write(&mut b, 256 + 4, s[4]).is_ok());
    assert!(write(&mut b, 33, 1).is_ok());
    let mut other = s;
    other[5] ^= 1;
    assert_eq!(
        write_slot(&mut b, 0, &other),
        Err(Exception::ServerDeviceBusy)
    );
    assert_eq!(
        write(&mut b, 256 + 5, other[5]),
        Err(Exception::ServerDeviceBusy)
    );
    // A refused FC16 writes nothing, not even its part in the free slot 1 after it.
    let mut spanning = s[8..].to_vec();
    spanning[0] ^= 1;
    spanning.extend([7; 4]);
    assert_eq!(
        b.request(&Request::WriteMultiple {
            address: 256 + 8,
            values: spanning
        }),
        Err(Exception::ServerDeviceBusy)
    );
    assert_eq!(read(&mut b, 256 + 16, 4), Ok(vec![0; 4]));
    write(&mut b, 32, 1 | 32).unwrap();
    let events = run(&mut b, 10.0, |b| state(b) == 4);
    assert_eq!(executed(&events), vec![1]);
    assert_eq!(lines(&events).len(), 1);
    assert_eq!(ring(&mut b), (1, 1, 1));
}

#[test]
fn a_bad_crc_raises_alarm_101() {
    let mut b = bank(4);
    let mut s = linked(1, 5.0, 0.0, 0.0, 0.1);
    s[15] ^= 1;
    // First after a flush: no sequence number expected yet, ALARM_SEQ 0.
    assert_eq!(publish(&mut b, &[s]), Err(Exception::ServerDeviceFailure));
    assert_eq!(alarm(&mut b), (3, 101, 0, 0));
    assert_eq!(ring(&mut b), (0, 0, 0));
    // With 1 published, a bad slot 2 names sequence 2.
    let mut b = bank(4);
    publish(&mut b, &[linked(1, 5.0, 0.0, 0.0, 0.1)]).unwrap();
    let mut s = linked(2, 5.0, 1.0, 0.0, 0.1);
    s[6] ^= 0x0100;
    assert_eq!(publish(&mut b, &[s]), Err(Exception::ServerDeviceFailure));
    assert_eq!(alarm(&mut b), (3, 101, 2, 0));
    // An all-zero slot (never written) fails the CRC too.
    let mut b = bank(4);
    assert_eq!(write(&mut b, 33, 1), Err(Exception::ServerDeviceFailure));
    assert_eq!(alarm(&mut b).1, 101);
    // In alarm, HEAD cannot move (04) but may be written as it is.
    assert_eq!(write(&mut b, 33, 2), Err(Exception::ServerDeviceFailure));
    assert!(write(&mut b, 33, 0).is_ok());
}

#[test]
fn sequence_numbers_out_of_order_raise_alarm_102() {
    let case = |sequences: &[u32]| {
        let mut b = bank(8);
        let slots: Vec<[u16; 16]> = sequences
            .iter()
            .map(|&s| linked(s, 5.0, 0.0, 0.0, 0.1))
            .collect();
        let (good, last) = slots.split_at(slots.len() - 1);
        if !good.is_empty() {
            publish(&mut b, good).unwrap();
        }
        assert_eq!(publish(&mut b, last), Err(Exception::ServerDeviceFailure));
        (alarm(&mut b), reg(&mut b, 33))
    };
    // Skipped: 2 expected after 1.
    assert_eq!(case(&[1, 3]), ((3, 102, 2, 0), 1));
    // Repeated.
    assert_eq!(case(&[1, 1]), ((3, 102, 2, 0), 1));
    // 0 is never a sequence number.
    assert_eq!(case(&[0]), ((3, 102, 0, 0), 0));
    // Wrapping: after 4 294 967 295 comes 1, not 0.
    assert_eq!(case(&[u32::MAX, 0]), ((3, 102, 1, 0), 1));
    let mut b = bank(8);
    let wrap = [
        linked(u32::MAX, 5.0, 0.0, 0.0, 0.1),
        linked(1, 5.0, 1.0, 0.0, 0.1),
    ];
    assert!(publish(&mut b, &wrap).is_ok());
    // Two slots in one HEAD write, the second bad: neither is published.
    let mut b = bank(8);
    write_slot(&mut b, 0, &linked(1, 5.0, 0.0, 0.0, 0.1)).unwrap();
    write_slot(&mut b, 1, &linked(3, 5.0, 0.0, 0.0, 0.1)).unwrap();
    assert_eq!(write(&mut b, 33, 2), Err(Exception::ServerDeviceFailure));
    assert_eq!(ring(&mut b), (0, 0, 0));
    assert_eq!(alarm(&mut b), (3, 102, 2, 0));
}

#[test]
fn invalid_segments_raise_alarm_103() {
    let bad = [
        // Unknown kind.
        slot(1, 9, [0; 3], 0, false),
        slot(1, 0, [0; 3], 0, false),
        // A linked move without its C flag, or lasting 0 µs.
        slot(1, 0x0301, [1, 1, 0], 1000, false),
        slot(1, 0x0701, [1, 1, 1], 0, false),
        // A rapid with a PARAM; an axis holding a value without its flag.
        slot(1, 0x0102, [1, 0, 0], 5, false),
        slot(1, 0x0102, [1, 5, 0], 0, false),
        // A feed of 0.
        slot(1, 0x0103, [1, 0, 0], 0, false),
        // A dwell, spindle off or program end with axes or a PARAM.
        slot(1, 0x0104, [1, 0, 0], 0, false),
        slot(1, 0x0105, [1, 0, 0], 10, false),
        slot(1, 6, [0; 3], 1, false),
        slot(1, 7, [0; 3], 1, false),
        // A flag bit the map does not define.
        slot(1, 0x0802, [0; 3], 0, false),
    ];
    for s in bad {
        let mut b = bank(4);
        assert_eq!(
            publish(&mut b, &[s]),
            Err(Exception::ServerDeviceFailure),
            "{s:04x?}"
        );
        assert_eq!(alarm(&mut b), (3, 103, 1, 0), "{s:04x?}");
    }
    // The reserved registers 3 and 14 must be 0 (the CRC recomputed to match).
    for reserved in [3, 14] {
        let mut s = slot(1, 6, [0; 3], 0, false);
        s[reserved] = 1;
        let bytes: Vec<u8> = s[..15].iter().flat_map(|w| w.to_be_bytes()).collect();
        s[15] = crc16(&bytes);
        let mut b = bank(4);
        assert_eq!(publish(&mut b, &[s]), Err(Exception::ServerDeviceFailure));
        assert_eq!(alarm(&mut b).1, 103);
    }
}

#[test]
fn exception_codes_for_every_bad_request() {
    let mut b = bank(4);
    let request = |b: &mut Bank, r: Request| b.request(&r).err();
    let read_req = |address, count| Request::ReadHolding { address, count };
    let multi = |address, n: usize| Request::WriteMultiple {
        address,
        values: vec![0; n],
    };
    use Exception::*;
    let cases = [
        // 01: not 03, 06 or 16.
        (Request::Other { function: 4 }, IllegalFunction),
        // 03: Modbus's quantities.
        (read_req(0, 0), IllegalDataValue),
        (read_req(0, 126), IllegalDataValue),
        (multi(256, 0), IllegalDataValue),
        (multi(256, 124), IllegalDataValue),
        // 02: unmapped registers, alone or inside a range.
        (read_req(8, 1), IllegalDataAddress),
        (read_req(0, 9), IllegalDataAddress),
        (read_req(30, 6), IllegalDataAddress),
        (read_req(255, 2), IllegalDataAddress),
        (read_req(256 + 64, 1), IllegalDataAddress),
        (read_req(65535, 2), IllegalDataAddress),
        // 02: read-only and unmapped registers written.
        (
            Request::WriteSingle {
                address: 0,
                value: 1,
            },
            IllegalDataAddress,
        ),
        (
            Request::WriteSingle {
                address: 21,
                value: 1,
            },
            IllegalDataAddress,
        ),
        (
            Request::WriteSingle {
                address: 100,
                value: 1,
            },
            IllegalDataAddress,
        ),
        (
            Request::WriteSingle {
                address: 320,
                value: 1,
            },
            IllegalDataAddress,
        ),
        // 02: FC16 on the control registers, the identification, past the ring.
        (multi(32, 1), IllegalDataAddress),
        (multi(33, 1), IllegalDataAddress),
        (multi(0, 2), IllegalDataAddress),
        (multi(256 + 63, 2), IllegalDataAddress),
        (multi(65535, 2), IllegalDataAddress),
        // 03: a reserved control bit, HEAD ≥ N.
        (
            Request::WriteSingle {
                address: 32,
                value: 0x40,
            },
            IllegalDataValue,
        ),
        (
            Request::WriteSingle {
                address: 33,
                value: 4,
            },
            IllegalDataValue,
        ),
    ];
    for (r, exception) in cases {
        assert_eq!(request(&mut b, r.clone()), Some(exception), "{r:?}");
    }
    // The good ones: status and control in one read, a whole ring, a slot by FC16.
    assert_eq!(read(&mut b, 16, 19).map(|v| v.len()), Ok(19));
    assert_eq!(read(&mut b, 256, 64).map(|v| v.len()), Ok(64));
    assert_eq!(
        b.request(&multi(256 + 48, 16)),
        Ok(Response::WriteMultiple {
            address: 304,
            count: 16
        })
    );
    assert_eq!(
        write(&mut b, 34, 7),
        Ok(Response::WriteSingle {
            address: 34,
            value: 7
        })
    );
    assert_eq!(reg(&mut b, 34), 7);
    // Nothing refused changed anything.
    assert_eq!(read(&mut b, 16, 18), Ok(vec![0; 18]));
}

#[test]
fn the_watchdog_faults_when_not_fed() {
    let mut b = bank(4);
    // Not armed with RUN clear.
    b.advance(5.0).unwrap();
    assert_eq!(state(&mut b), 0);
    // RUN arms it (timer from now, t = 5). 0.999 s later: fine; fed; fine again 0.999 s
    // after that.
    write(&mut b, 32, 1).unwrap();
    b.advance(0.999).unwrap();
    assert_eq!(state(&mut b), 0);
    write(&mut b, 34, 1).unwrap();
    b.advance(0.999).unwrap();
    assert_eq!(state(&mut b), 0);
    // The same value again is not a change: 1 s after the last change, alarm 104.
    write(&mut b, 34, 1).unwrap();
    b.advance(0.0005).unwrap();
    assert_eq!(state(&mut b), 0);
    b.advance(0.001).unwrap();
    assert_eq!(alarm(&mut b), (3, 104, 0, 0));
    // RESET_ALARM with RUN still set arms it afresh, from the reset on.
    b.advance(3.0).unwrap();
    write(&mut b, 32, 1 | 8).unwrap();
    b.advance(0.9).unwrap();
    assert_eq!(alarm(&mut b), (0, 0, 0, 0));
    b.advance(0.2).unwrap();
    assert_eq!(alarm(&mut b).1, 104);
    // With END set it is off: the controller has every segment.
    let mut b = bank(4);
    write(&mut b, 32, 1 | 32).unwrap();
    b.advance(10.0).unwrap();
    assert_eq!(state(&mut b), 4);
    // Clearing END arms it afresh.
    write(&mut b, 32, 1).unwrap();
    b.advance(0.9).unwrap();
    assert_eq!(state(&mut b), 0);
    b.advance(0.2).unwrap();
    assert_eq!(alarm(&mut b).1, 104);
}

#[test]
fn a_watchdog_stop_while_moving_holds_then_resets() {
    let mut b = bank(4);
    publish(&mut b, &[linked(1, 50.0, 0.0, 0.0, 5.0)]).unwrap();
    write(&mut b, 32, 1).unwrap();
    b.advance(1.0).unwrap();
    // Alarm at 1 s: a feed hold, not yet at rest, so RESET_ALARM must wait (06).
    assert_eq!(alarm(&mut b).1, 104);
    assert_eq!(
        b.controller().state(),
        MachineState::Hold { complete: false }
    );
    assert_eq!(write(&mut b, 32, 1 | 8), Err(Exception::ServerDeviceBusy));
    let events = run(&mut b, 2.0, |b| {
        b.controller().state() == MachineState::Idle
    });
    // Stopped short of X 50, then reset: the move was cut short, never completed.
    assert!(events.iter().any(|e| matches!(e, Event::Reset { .. })));
    assert!(executed(&events).is_empty());
    let x = b.controller().position().x;
    assert!(x > 0.0 && x < 50.0, "{x}");
    // At rest: RESET_ALARM clears it and flushes; any sequence number may start.
    assert!(write(&mut b, 32, 1 | 32 | 8).is_ok());
    assert_eq!(alarm(&mut b), (4, 0, 0, 0));
    assert_eq!(ring(&mut b), (0, 0, 0));
    assert!(publish(&mut b, &[linked(500, 50.0, 0.0, 0.0, 1.0)]).is_ok());
    let events = run(&mut b, 10.0, |b| state(b) == 4);
    assert_eq!(executed(&events), vec![500]);
}

#[test]
fn a_line_queued_during_an_alarm_stop_is_not_taken() {
    // 45 linked moves of 1 mm along Z in 0.2 s each (5 mm/s; at 500 mm/s² the first
    // starts 0.005 s late, v/2a, and the rest follow at full speed), so block k ends at
    // 0.2·k + 0.005 s. The planner takes 35 lines at once and a line waits for room;
    // blocks 1–4 make room for lines 36–39 by 0.805 s.
    let mut b = bank_on(
        &machine(),
        BankOptions {
            slots: 64,
            watchdog_timeout_ms: 1003,
            ..BankOptions::default()
        },
    );
    let moves: Vec<[u16; 16]> = (1..=45)
        .map(|k| linked(k, 0.0, f64::from(k), 0.0, 0.2))
        .collect();
    publish(&mut b, &moves).unwrap();
    write(&mut b, 32, 1).unwrap();
    // The watchdog stops it at 1.003 s, 0.01 mm before block 5 ends: the hold needs
    // 0.025 mm (v²/2a), so block 5 completes while slowing and line 40 finds room.
    // It is queued only to be purged by the reset: TAIL stays after line 39.
    let events = run(&mut b, 2.0, |b| {
        b.controller().state() == MachineState::Idle && alarm(b).1 == 104
    });
    assert_eq!(executed(&events), vec![1, 2, 3, 4, 5]);
    assert_eq!(ring(&mut b).0, 39);
    assert_eq!(alarm(&mut b), (3, 104, 0, 0));
}

#[test]
fn a_target_beyond_the_travel_is_alarm_2() {
    let mut b = bank(4);
    let slots = [
        linked(1, 50.0, 0.0, 0.0, 0.5),
        // X 150: outside 0–100.
        linked(2, 150.0, 0.0, 0.0, 0.5),
    ];
    publish(&mut b, &slots).unwrap();
    write(&mut b, 32, 1 | 32).unwrap();
    let events = run(&mut b, 5.0, |b| state(b) == 3);
    // grbl's soft limit: ALARM:2, the line answered error:15; the segment it refused
    // is 2, and TAIL stays on it.
    assert!(events.iter().any(|e| matches!(
        e,
        Event::Alarm {
            alarm: GrblAlarm::SoftLimit,
            ..
        }
    )));
    assert_eq!(alarm(&mut b), (3, 2, 2, 15));
    assert_eq!(ring(&mut b).0, 1);
    // RESET_ALARM (the machine is at rest): idle, flushed.
    write(&mut b, 32, 1 | 32 | 8).unwrap();
    assert_eq!(alarm(&mut b), (4, 0, 0, 0));
    assert_eq!(ring(&mut b), (0, 0, 0));
    assert_eq!(b.controller().state(), MachineState::Idle);
}

#[test]
fn a_line_the_controller_refuses_is_alarm_105() {
    // A controller whose lines hold 16 characters: the linked line is longer, so
    // grbl answers error:11.
    let mut m = machine();
    m.max_line_length = 16;
    let mut b = bank_on(&m, BankOptions::default());
    publish(&mut b, &[linked(1, 5.0, 0.0, 0.0, 0.1)]).unwrap();
    write(&mut b, 32, 1).unwrap();
    assert_eq!(alarm(&mut b), (3, 105, 1, 11));
}

/// A guard that finds every block beyond Δ.
#[derive(Debug)]
struct Strict;

impl Guard for Strict {
    fn executed(&mut self, _: &ExecutedBlock) -> Result<(), Breach> {
        Err(Breach {
            message: "beyond Δ".into(),
        })
    }
    fn program_end(&mut self) -> Result<(), Breach> {
        Ok(())
    }
    fn measured(&self) -> Measured {
        Measured::default()
    }
}

#[test]
fn the_delta_guard_stops_a_slot_stream_with_alarm_64() {
    let mut controller = Controller::new(&machine(), ControllerOptions::default()).unwrap();
    controller.set_guard(Box::new(Strict));
    let mut b = Bank::new(controller, BankOptions::default()).unwrap();
    let moves: Vec<[u16; 16]> = (1..=3)
        .map(|k| linked(k, 10.0, f64::from(k), 0.0, 0.2))
        .collect();
    publish(&mut b, &moves).unwrap();
    write(&mut b, 32, 1 | 32).unwrap();
    run(&mut b, 5.0, |b| state(b) == 3);
    assert_eq!(alarm(&mut b).1, 64);
    // Nothing more is taken.
    b.advance(1.0).unwrap();
    assert_eq!(alarm(&mut b).1, 64);
}

#[test]
fn hold_and_resume() {
    let mut b = bank(4);
    publish(&mut b, &[linked(1, 50.0, 0.0, 0.0, 2.0)]).unwrap();
    write(&mut b, 32, 1 | 32).unwrap();
    b.advance(0.5).unwrap();
    assert_eq!(state(&mut b), 1);
    write(&mut b, 32, 1 | 32 | 2).unwrap();
    b.advance(1.0).unwrap();
    assert_eq!(state(&mut b), 2);
    assert_eq!(
        b.controller().state(),
        MachineState::Hold { complete: true }
    );
    // Writing the same word again is no new edge; RESUME is.
    write(&mut b, 32, 1 | 32 | 2).unwrap();
    write(&mut b, 32, 1 | 32 | 4).unwrap();
    assert_eq!(state(&mut b), 1);
    let events = run(&mut b, 10.0, |b| state(b) == 4);
    assert_eq!(executed(&events), vec![1]);
}

#[test]
fn abort_stops_and_flushes() {
    let mut b = bank(4);
    publish(
        &mut b,
        &[
            linked(1, 50.0, 0.0, 0.0, 2.0),
            linked(2, 60.0, 0.0, 0.0, 1.0),
        ],
    )
    .unwrap();
    write(&mut b, 32, 1).unwrap();
    b.advance(0.5).unwrap();
    assert!(write(&mut b, 32, 1 | 16).is_ok());
    // Coming to rest: held, and HEAD cannot move until then (06).
    assert_eq!(state(&mut b), 2);
    write_slot(&mut b, 2, &linked(3, 5.0, 0.0, 0.0, 0.1)).unwrap();
    assert_eq!(write(&mut b, 33, 3), Err(Exception::ServerDeviceBusy));
    run(&mut b, 2.0, |b| state(b) != 2);
    assert_eq!(state(&mut b), 0);
    assert_eq!(ring(&mut b), (0, 0, 0));
    assert_eq!(b.controller().state(), MachineState::Idle);
    // At rest, an abort is complete when answered. Then a new stream, any number.
    write(&mut b, 32, 1).unwrap();
    assert!(write(&mut b, 32, 1 | 16).is_ok());
    assert_eq!(state(&mut b), 0);
    assert!(publish(&mut b, &[linked(77, 5.0, 0.0, 0.0, 0.1)]).is_ok());
    write(&mut b, 32, 1 | 32).unwrap();
    let events = run(&mut b, 5.0, |b| state(b) == 4);
    assert_eq!(executed(&events), vec![77]);
}

#[test]
fn a_stopped_stream_stands_held_without_the_watchdog_and_the_next_flushes_it() {
    // docs/modbus.md, "Stopping and resuming": the bridge's stop is a HOLD edge, then,
    // the machine standing, CONTROL = 0. A watchdog of 2 s, which the stop beats.
    let mut b = bank_on(
        &machine(),
        BankOptions {
            slots: 4,
            watchdog_timeout_ms: 2000,
            ..BankOptions::default()
        },
    );
    publish(
        &mut b,
        &[
            linked(1, 5.0, 0.0, 0.0, 0.5),
            linked(2, 50.0, 0.0, 0.0, 2.0),
            linked(3, 60.0, 0.0, 0.0, 1.0),
        ],
    )
    .unwrap();
    write(&mut b, 32, 1).unwrap();
    b.advance(0.7).unwrap();
    write(&mut b, 32, 1 | 2).unwrap();
    run(&mut b, 2.0, |b| {
        b.controller().state() == MachineState::Hold { complete: true }
    });
    write(&mut b, 32, 0).unwrap();
    // RUN clear: the watchdog is not armed, so the bridge may go. Held it stays, the first
    // segment executed, the second interrupted, the third still in the ring.
    b.advance(5.0).unwrap();
    assert_eq!(state(&mut b), 2);
    assert_eq!(alarm(&mut b).1, 0);
    assert_eq!(ring(&mut b).2, 1);
    // The next stream: CONTROL 0, then ABORT, which the map allows in any state: at rest, it
    // is complete when answered, and any first sequence number goes.
    write(&mut b, 32, 0).unwrap();
    write(&mut b, 32, 16).unwrap();
    assert_eq!(state(&mut b), 0);
    assert_eq!(ring(&mut b), (0, 0, 0));
    assert!(publish(&mut b, &[linked(9, 5.0, 0.0, 0.0, 0.1)]).is_ok());
    write(&mut b, 32, 1 | 32).unwrap();
    let events = run(&mut b, 5.0, |b| state(b) == 4);
    assert_eq!(executed(&events), vec![9]);
}

#[test]
fn options_and_time_are_checked() {
    let controller = || Controller::new(&machine(), ControllerOptions::default()).unwrap();
    for (options, name) in [
        (
            BankOptions {
                slots: 1,
                ..BankOptions::default()
            },
            "slots",
        ),
        (
            BankOptions {
                slots: 65,
                ..BankOptions::default()
            },
            "slots",
        ),
        (
            BankOptions {
                watchdog_timeout_ms: 0,
                ..BankOptions::default()
            },
            "watchdog_timeout_ms",
        ),
        (
            BankOptions {
                max_segment_rate: 0,
                ..BankOptions::default()
            },
            "max_segment_rate",
        ),
    ] {
        assert!(matches!(
            Bank::new(controller(), options),
            Err(ConfigError::Option { name: n, .. }) if n == name
        ));
    }
    let mut b = bank(4);
    assert_eq!(b.advance(-1.0), Err(TimeError(-1.0)));
    assert!(b.advance(f64::NAN).is_err());
}

#[test]
fn numbers_are_written_exactly() {
    assert_eq!(decimal(125_000, 4), "12.5");
    assert_eq!(decimal(-5, 4), "-0.0005");
    assert_eq!(decimal(0, 4), "0");
    assert_eq!(decimal(-30_000, 4), "-3");
    assert_eq!(decimal(i64::MIN, 4), "-922337203685477.5808");
    // 7 µs: F = 60 000 000 / 7 = 8 571 428.571429 (to 10⁻⁶).
    let s = Segment::Linked {
        xzc: [0; 3],
        micros: 7,
    };
    assert_eq!(s.line(3), "N3 G93 G1 X0 Z0 C0 F8571428.571429");
}

// ---- The golden fixture, tests/data/modbus-golden.json ----
//
// Registers and bytes worked out by hand from docs/modbus.md and read by the bridge's tests
// too: the bank's one definition of each number, the slots it decodes, the identification
// and status it serves, and the control word's edges must all agree with it.

use serde_json::Value;

const GOLDEN: &str = include_str!(concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../tests/data/modbus-golden.json"
));

fn golden() -> Value {
    serde_json::from_str(GOLDEN).expect("tests/data/modbus-golden.json is JSON")
}

/// A number of the fixture: a JSON integer, or a hex string such as "0x0302".
fn num(v: &Value) -> i64 {
    match v {
        Value::Number(n) => n.as_i64().expect("an integer"),
        Value::String(s) => {
            let hex = s.strip_prefix("0x").expect("a hex string starts 0x");
            i64::from_str_radix(hex, 16).expect("hex digits")
        }
        other => panic!("not a number: {other}"),
    }
}

fn u16_of(v: &Value) -> u16 {
    u16::try_from(num(v)).expect("a 16-bit value")
}

fn u32_of(v: &Value) -> u32 {
    u32::try_from(num(v)).expect("a 32-bit value")
}

fn registers_of(v: &Value) -> Vec<u16> {
    v.as_array().expect("a list").iter().map(u16_of).collect()
}

fn bytes_of(v: &Value) -> Vec<u8> {
    v.as_str()
        .expect("hex bytes")
        .split_whitespace()
        .map(|b| u8::from_str_radix(b, 16).expect("a hex byte"))
        .collect()
}

/// Registers as Modbus sends them, each high byte first.
fn on_the_wire(registers: &[u16]) -> Vec<u8> {
    registers
        .iter()
        .flat_map(|r| [(r >> 8) as u8, *r as u8])
        .collect()
}

fn cases(v: &Value) -> &[Value] {
    v.as_array().expect("a list of cases")
}

fn case<'a>(v: &'a Value, name: &str) -> &'a Value {
    cases(v)
        .iter()
        .find(|c| c["name"] == name)
        .unwrap_or_else(|| panic!("no case {name}"))
}

/// A request PDU of the fixture as the bank's request; an FC16 (given by its header)
/// carries `values`.
fn request_of(pdu: &Value, values: &[u16]) -> Request {
    let b = bytes_of(pdu);
    let word = |k: usize| (u16::from(b[k]) << 8) | u16::from(b[k + 1]);
    match b[0] {
        0x03 => Request::ReadHolding {
            address: word(1),
            count: word(3),
        },
        0x06 => Request::WriteSingle {
            address: word(1),
            value: word(3),
        },
        0x10 => {
            assert_eq!(usize::from(word(3)), values.len(), "quantity");
            assert_eq!(usize::from(b[5]), 2 * values.len(), "byte count");
            Request::WriteMultiple {
                address: word(1),
                values: values.to_vec(),
            }
        }
        f => panic!("function {f:#04x} is not in the map"),
    }
}

fn order_of(name: &str) -> (WordOrder, bool) {
    match name {
        "high_first" => (WordOrder::HighFirst, false),
        "low_first" => (WordOrder::LowFirst, true),
        other => panic!("no word order {other}"),
    }
}

fn golden_bank(slots: u16, word_order: WordOrder) -> Bank {
    bank_on(
        &machine(),
        BankOptions {
            slots,
            word_order,
            // Long enough for the scenarios below, which feed it nowhere.
            watchdog_timeout_ms: 60_000,
            ..BankOptions::default()
        },
    )
}

/// A control bit by the fixture's name for it.
fn bit(g: &Value, name: &str) -> u16 {
    u16_of(&g["map"]["control"][name])
}

/// The segment the bank should read from a slot case, by the kind's name in the fixture.
fn golden_segment(g: &Value, s: &Value) -> Segment {
    let kind = num(&s["kind"]);
    let (name, _) = g["map"]["kinds"]
        .as_object()
        .unwrap()
        .iter()
        .find(|(_, code)| num(code) == kind)
        .expect("a kind the map names");
    let axes = ["x", "z", "c"].map(|a| (!s[a].is_null()).then(|| num(&s[a])));
    let param = u32_of(&s["param"]);
    let none = axes == [None; 3];
    match name.as_str() {
        "linked" => Segment::Linked {
            xzc: axes.map(|a| a.expect("a linked move gives every axis")),
            micros: param,
        },
        "rapid" => Segment::Rapid { axes },
        "feed" => Segment::Feed { axes, milli: param },
        "dwell" if none => Segment::Dwell { micros: param },
        "spindle_on" if none => Segment::SpindleOn { milli: param },
        "spindle_off" if none => Segment::SpindleOff,
        "program_end" if none => Segment::ProgramEnd,
        other => panic!("slot case {} as {other}", s["name"]),
    }
}

#[test]
fn golden_numbers_are_the_bank_s() {
    let g = golden();
    let m = &g["map"];
    let registers = [
        ("MAGIC_0", MAGIC_0),
        ("MAGIC_1", MAGIC_1),
        ("MAP_VERSION", MAP_VERSION),
        ("SLOT_COUNT", SLOT_COUNT),
        ("SLOT_SIZE", SLOT_SIZE),
        ("WORD_ORDER", WORD_ORDER),
        ("MAX_SEGMENT_RATE", MAX_SEGMENT_RATE),
        ("WATCHDOG_TIMEOUT", WATCHDOG_TIMEOUT),
        ("STATE", STATE),
        ("ALARM_CODE", ALARM_CODE),
        ("ALARM_SEQ", ALARM_SEQ),
        ("ALARM_DETAIL", ALARM_DETAIL),
        ("TAIL", TAIL),
        ("EXECUTED_SEQ", EXECUTED_SEQ),
        ("POS_X", POS_X),
        ("POS_Z", POS_Z),
        ("POS_C", POS_C),
        ("CONTROL", CONTROL),
        ("HEAD", HEAD),
        ("WATCHDOG", WATCHDOG),
        ("RING", RING),
    ];
    assert_eq!(m["registers"].as_object().unwrap().len(), registers.len());
    for (name, address) in registers {
        assert_eq!(u16_of(&m["registers"][name]), address, "{name}");
    }
    // The blocks as long as the fixture says: read whole, and not one register more.
    let mut b = bank(4);
    for (first, len) in [
        (MAGIC_0, u16_of(&m["identification_length"])),
        (STATE, u16_of(&m["status_length"])),
    ] {
        assert_eq!(read(&mut b, first, len).map(|r| r.len()), Ok(len.into()));
        assert_eq!(
            read(&mut b, first, len + 1),
            Err(Exception::IllegalDataAddress)
        );
    }
    assert_eq!(num(&m["unit_id"]), i64::from(super::super::serve::UNIT_ID));
    assert_eq!(registers_of(&m["magic"]), MAGIC);
    assert_eq!(u16_of(&m["map_version"]), VERSION);
    assert_eq!(u16_of(&m["slot_size"]), SLOT);
    assert_eq!(
        (
            u16_of(&m["slot_count"]["min"]),
            u16_of(&m["slot_count"]["max"])
        ),
        (*SLOTS.start(), *SLOTS.end())
    );
    assert_eq!(u16_of(&m["max_read"]), MAX_READ);
    assert_eq!(num(&m["max_write"]), MAX_WRITE as i64);
    let offsets = [
        ("SEQ", SLOT_SEQ),
        ("KIND", SLOT_KIND),
        ("X", SLOT_X),
        ("Z", SLOT_Z),
        ("C", SLOT_C),
        ("PARAM", SLOT_PARAM),
        ("CRC", SLOT_CRC),
    ];
    assert_eq!(m["slot_offsets"].as_object().unwrap().len(), offsets.len());
    for (name, offset) in offsets {
        assert_eq!(num(&m["slot_offsets"][name]), offset as i64, "{name}");
    }
    let reserved: Vec<usize> = cases(&m["reserved_offsets"])
        .iter()
        .map(|v| num(v) as usize)
        .collect();
    assert_eq!(reserved, SLOT_RESERVED);
    for name in ["high_first", "low_first"] {
        assert_eq!(u16_of(&m["word_order"][name]), order_of(name).0.register());
    }
    let control = [
        ("RUN", RUN),
        ("HOLD", HOLD),
        ("RESUME", RESUME),
        ("RESET_ALARM", RESET_ALARM),
        ("ABORT", ABORT),
        ("END", END),
    ];
    assert_eq!(m["control"].as_object().unwrap().len(), control.len());
    for (name, value) in control {
        assert_eq!(bit(&g, name), value, "{name}");
    }
    let kinds = [
        ("linked", KIND_LINKED),
        ("rapid", KIND_RAPID),
        ("feed", KIND_FEED),
        ("dwell", KIND_DWELL),
        ("spindle_on", KIND_SPINDLE_ON),
        ("spindle_off", KIND_SPINDLE_OFF),
        ("program_end", KIND_PROGRAM_END),
    ];
    assert_eq!(m["kinds"].as_object().unwrap().len(), kinds.len());
    for (name, code) in kinds {
        assert_eq!(u16_of(&m["kinds"][name]), code, "{name}");
        assert_eq!(code & !KIND_MASK, 0);
    }
    for (name, flag) in [("X", FLAG_X), ("Z", FLAG_Z), ("C", FLAG_C)] {
        assert_eq!(u16_of(&m["flags"][name]), flag, "{name}");
    }
    for (name, state) in [
        ("idle", IDLE),
        ("running", RUNNING),
        ("held", HELD),
        ("alarm", ALARM),
        ("done", DONE),
    ] {
        assert_eq!(u16_of(&m["states"][name]), state, "{name}");
    }
    let alarms = [
        ("soft_limit", u16::from(GrblAlarm::SoftLimit.code())),
        ("abort_cycle", u16::from(GrblAlarm::AbortCycle.code())),
        ("profile_error", u16::from(GrblAlarm::ProfileError.code())),
        ("slot_crc", ALARM_CRC),
        ("sequence", ALARM_SEQUENCE),
        ("segment", ALARM_SEGMENT),
        ("watchdog", ALARM_WATCHDOG),
        ("refused", ALARM_REFUSED),
    ];
    assert_eq!(m["alarms"].as_object().unwrap().len(), alarms.len());
    for (name, code) in alarms {
        assert_eq!(u16_of(&m["alarms"][name]), code, "{name}");
    }
    let units = &m["units"];
    let per = |decimals: u32| 10i64.pow(decimals);
    assert_eq!(num(&units["linear_per_mm"]), per(LINEAR_DECIMALS));
    assert_eq!(num(&units["angular_per_degree"]), per(ANGULAR_DECIMALS));
    assert_eq!(num(&units["duration_per_second"]), per(MICRO_DECIMALS));
    assert_eq!(num(&units["feed_per_mm_per_minute"]), per(MILLI_DECIMALS));
    assert_eq!(num(&units["spindle_per_rpm"]), per(MILLI_DECIMALS));
    assert_eq!(
        MICROS_PER_MINUTE,
        60 * num(&units["duration_per_second"]) as u128
    );
    let check = &g["crc"]["check"];
    assert_eq!(
        crc16(check["ascii"].as_str().unwrap().as_bytes()),
        u16_of(&check["crc"])
    );
}

#[test]
fn golden_identification_is_served() {
    let g = golden();
    for c in cases(&g["identification"]) {
        let name = c["name"].as_str().unwrap();
        let (order, _) = order_of(["high_first", "low_first"][num(&c["word_order"]) as usize]);
        let mut b = bank_on(
            &machine(),
            BankOptions {
                slots: u16_of(&c["slots"]),
                word_order: order,
                watchdog_timeout_ms: u16_of(&c["watchdog_timeout_ms"]),
                max_segment_rate: u16_of(&c["max_segment_rate"]),
                feed_override: true,
            },
        );
        let expected = registers_of(&c["registers"]);
        assert_eq!(on_the_wire(&expected), bytes_of(&c["bytes"]), "{name}");
        assert_eq!(
            b.request(&request_of(&c["request_pdu"], &[])),
            Ok(Response::ReadHolding(expected)),
            "{name}"
        );
    }
}

#[test]
fn golden_slots_decode() {
    let g = golden();
    for s in cases(&g["slots"]) {
        let name = s["name"].as_str().unwrap();
        let expected = golden_segment(&g, s);
        let sequence = u32_of(&s["sequence"]);
        for order_name in ["high_first", "low_first"] {
            let (order, _) = order_of(order_name);
            let registers = registers_of(&s[order_name]["registers"]);
            let bytes = bytes_of(&s[order_name]["bytes"]);
            assert_eq!(on_the_wire(&registers), bytes, "{name}, {order_name}");
            // The CRC over the 30 bytes of registers 0–14, in register 15 high byte first.
            let crc = crc16(&bytes[..2 * SLOT_CRC]);
            assert_eq!(registers[SLOT_CRC], crc, "{name}, {order_name}");
            assert_eq!(registers[SLOT_KIND], u16_of(&s["kind_register"]));
            assert_eq!(
                Segment::parse(&registers, order),
                Some(expected),
                "{name}, {order_name}"
            );
            assert_eq!(
                expected.line(sequence % LINE_NUMBERS),
                s["gcode"].as_str().unwrap()
            );
            // Published into an empty ring it passes every check at the HEAD write.
            let mut b = golden_bank(4, order);
            assert!(write_slot(&mut b, 0, &registers).is_ok());
            assert!(write(&mut b, HEAD, 1).is_ok(), "{name}, {order_name}");
            assert_eq!(b.queue.front(), Some(&(sequence, expected)));
        }
    }
}

#[test]
fn golden_status_is_served() {
    let g = golden();
    let done = case(&g["status"], "status_done");
    let alarmed = case(&g["status"], "status_alarm_sequence");
    let slots = cases(&g["slots"]);
    for order_name in ["high_first", "low_first"] {
        let (order, _) = order_of(order_name);
        let mut b = golden_bank(32, order);
        let status = |b: &mut Bank, c: &Value| b.request(&request_of(&c["request_pdu"], &[]));
        // The fixture's program, published at once and run to the end.
        for (k, s) in slots.iter().enumerate() {
            let registers = registers_of(&s[order_name]["registers"]);
            write_slot(&mut b, k as u16, &registers).unwrap();
        }
        assert!(write(&mut b, HEAD, slots.len() as u16).is_ok());
        write(&mut b, CONTROL, bit(&g, "RUN") | bit(&g, "END")).unwrap();
        let mut t = 0.0;
        while state(&mut b) != DONE && t < 2000.0 {
            b.advance(0.5).unwrap();
            t += 0.5;
        }
        assert_eq!(
            status(&mut b, done),
            Ok(Response::ReadHolding(registers_of(&done[order_name]))),
            "{order_name}"
        );
        // END cleared, the watchdog fed, and the first slot again where the next is
        // expected: alarm 102, nothing moves.
        write(&mut b, CONTROL, u16_of(&alarmed["control"])).unwrap();
        write(&mut b, WATCHDOG, u16_of(&alarmed["watchdog"])).unwrap();
        let first = registers_of(&case(&g["slots"], "rapid_x_z")[order_name]["registers"]);
        let head = u16_of(&done["head"]);
        write_slot(&mut b, head, &first).unwrap();
        assert_eq!(
            write(&mut b, HEAD, head + 1),
            Err(Exception::ServerDeviceFailure)
        );
        assert_eq!(
            status(&mut b, alarmed),
            Ok(Response::ReadHolding(registers_of(&alarmed[order_name]))),
            "{order_name}"
        );
    }
}

#[test]
fn golden_control_word_edges() {
    let g = golden();
    let mut b = golden_bank(4, WordOrder::HighFirst);
    let slot_of = |name: &str| registers_of(&case(&g["slots"], name)["high_first"]["registers"]);
    // A slot waiting with RUN clear, for the flush to drop.
    write_slot(&mut b, 0, &slot_of("rapid_x_z")).unwrap();
    write(&mut b, HEAD, 1).unwrap();
    for w in cases(&g["control"]["writes"]) {
        let (before, value) = (u16_of(&w["before"]), u16_of(&w["value"]));
        let rising: Vec<&str> = cases(&w["rising"])
            .iter()
            .map(|r| r.as_str().unwrap())
            .collect();
        assert_eq!(reg(&mut b, CONTROL), before, "{w}");
        let state_before = state(&mut b);
        let answer = b.request(&request_of(&w["pdu"], &[]));
        if !w["exception"].is_null() {
            assert_eq!(
                answer.map_err(Exception::code),
                Err(num(&w["exception"]) as u8),
                "{w}"
            );
            assert_eq!(reg(&mut b, CONTROL), before, "refused, unchanged: {w}");
            continue;
        }
        assert_eq!(
            answer,
            Ok(Response::WriteSingle {
                address: CONTROL,
                value
            })
        );
        assert_eq!(reg(&mut b, CONTROL), value);
        match rising[..] {
            // No edge: nothing happens (a level kept, a bit falling, a word re-sent).
            [] => assert_eq!(state(&mut b), state_before, "{w}"),
            ["ABORT"] => {
                // At rest, the flush is complete when answered. A new stream: the feed.
                assert_eq!(ring(&mut b), (0, 0, 0));
                write_slot(&mut b, 0, &slot_of("feed_x")).unwrap();
                write(&mut b, HEAD, 1).unwrap();
            }
            ["RUN"] => {
                assert_eq!(state(&mut b), RUNNING);
                b.advance(0.5).unwrap();
                assert_eq!(state(&mut b), RUNNING);
            }
            ["HOLD"] => {
                b.advance(0.5).unwrap();
                assert_eq!(state(&mut b), HELD);
                assert_eq!(
                    b.controller().state(),
                    MachineState::Hold { complete: true }
                );
            }
            ["RESUME"] => assert_eq!(state(&mut b), RUNNING),
            ["END"] => {
                run(&mut b, 30.0, |b| state(b) == DONE);
                assert_eq!(state(&mut b), DONE);
                let feed = u32_of(&case(&g["slots"], "feed_x")["sequence"]);
                assert_eq!(ring(&mut b), (1, 1, feed));
            }
            // Without an alarm, nothing.
            ["RESET_ALARM"] => assert_eq!(state(&mut b), state_before),
            _ => panic!("no check for {rising:?}"),
        }
    }
}

#[test]
fn golden_head_writes() {
    let g = golden();
    let slot_of = |name: &str| registers_of(&case(&g["slots"], name)["high_first"]["registers"]);
    let slot_write = |b: &mut Bank, c: &Value, values: &[u16]| {
        let request = request_of(&c["slot_write_pdu"], values);
        let Request::WriteMultiple { address, .. } = request else {
            unreachable!()
        };
        assert_eq!(address, u16_of(&c["slot_address"]));
        b.request(&request)
    };
    let head_write = |b: &mut Bank, c: &Value| {
        let request = request_of(&c["head_write_pdu"], &[]);
        assert_eq!(
            request,
            Request::WriteSingle {
                address: HEAD,
                value: u16_of(&c["new_head"])
            }
        );
        b.request(&request).map_err(Exception::code)
    };
    let expect = |c: &Value| match &c["exception"] {
        Value::Null => Ok(Response::WriteSingle {
            address: HEAD,
            value: u16_of(&c["new_head"]),
        }),
        code => Err(num(code) as u8),
    };
    // After a flush (power-up): the first slot and HEAD 1.
    let first = case(&g["head"], "head_first_slot");
    let mut b = golden_bank(u16_of(&first["slots"]), WordOrder::HighFirst);
    assert_eq!(
        (reg(&mut b, TAIL), reg(&mut b, HEAD)),
        (u16_of(&first["tail"]), u16_of(&first["head"]))
    );
    assert!(slot_write(&mut b, first, &slot_of("rapid_x_z")).is_ok());
    assert_eq!(head_write(&mut b, first), expect(first));
    assert_eq!(reg(&mut b, HEAD), u16_of(&first["new_head"]));
    // Full: three published with RUN clear, HEAD 3, TAIL 0. Slot 3 may be written (not
    // published), but HEAD cannot pass it.
    let full = case(&g["head"], "head_full");
    let mut b = golden_bank(u16_of(&full["slots"]), WordOrder::HighFirst);
    let program = ["rapid_x_z", "spindle_on", "dwell"].map(|n| {
        let r: [u16; 16] = slot_of(n).try_into().unwrap();
        r
    });
    assert!(publish(&mut b, &program).is_ok());
    assert_eq!(
        (reg(&mut b, TAIL), reg(&mut b, HEAD)),
        (u16_of(&full["tail"]), u16_of(&full["head"]))
    );
    assert!(slot_write(&mut b, full, &slot_of("feed_x")).is_ok());
    assert_eq!(head_write(&mut b, full), expect(full));
    assert_eq!(reg(&mut b, HEAD), u16_of(&full["head"]));
    // RUN: the rapid is taken at once, the spindle start once done, and the dwell is under
    // way: TAIL 2. Now HEAD 3 wraps to 0.
    let wraps = case(&g["head"], "head_wraps");
    write(&mut b, CONTROL, RUN).unwrap();
    run(&mut b, 5.0, |b| reg(b, TAIL) == u16_of(&wraps["tail"]));
    assert_eq!(
        (reg(&mut b, TAIL), reg(&mut b, HEAD)),
        (u16_of(&wraps["tail"]), u16_of(&wraps["head"]))
    );
    assert!(slot_write(&mut b, wraps, &slot_of("feed_x")).is_ok());
    assert_eq!(head_write(&mut b, wraps), expect(wraps));
    assert_eq!(reg(&mut b, HEAD), u16_of(&wraps["new_head"]));
    assert_eq!(b.queue.len(), 2, "the dwell in flight and the feed");
}

#[test]
fn feed_override_is_a_register_of_percent_within_grbls_range() {
    let mut b = bank(8);
    assert_eq!(reg(&mut b, FEED_OVERRIDE), 100);
    assert!(write(&mut b, FEED_OVERRIDE, 150).is_ok());
    assert_eq!(reg(&mut b, FEED_OVERRIDE), 150);
    assert_eq!(b.controller().feed_override(), 150);
    // Outside 10–200: refused, and nothing changes.
    assert_eq!(
        write(&mut b, FEED_OVERRIDE, 9),
        Err(Exception::IllegalDataValue)
    );
    assert_eq!(
        write(&mut b, FEED_OVERRIDE, 201),
        Err(Exception::IllegalDataValue)
    );
    assert_eq!(b.controller().feed_override(), 150);
    assert!(write(&mut b, FEED_OVERRIDE, 10).is_ok());
    assert_eq!(b.controller().feed_override(), 10);
    // A map built before the register: exception 02 both ways.
    let mut old = bank_on(
        &machine(),
        BankOptions {
            feed_override: false,
            ..BankOptions::default()
        },
    );
    assert_eq!(
        write(&mut old, FEED_OVERRIDE, 120),
        Err(Exception::IllegalDataAddress)
    );
    assert_eq!(
        read(&mut old, FEED_OVERRIDE, 1),
        Err(Exception::IllegalDataAddress)
    );
    assert_eq!(old.controller().feed_override(), 100);
}
