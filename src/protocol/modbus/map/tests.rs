//! The register map by hand and against `tests/data/modbus-golden.json`: word orders,
//! slots and their CRC, the identification and status blocks, alarm codes.

use super::*;
use crate::post::modbus::segments;
use crate::program::{Move, Program};

#[test]
fn crc_is_crc16_modbus() {
    // The catalogue check value of CRC-16/MODBUS (init 0xFFFF, poly 0x8005 reflected,
    // no final XOR) over ASCII "123456789".
    assert_eq!(crc16(b"123456789"), 0x4B37);
    // The empty message leaves the initial value.
    assert_eq!(crc16(b""), 0xFFFF);
    // The slot CRC reads each register high byte first.
    assert_eq!(slot_crc(&[0x3132, 0x3334]), crc16(b"1234"));
}

#[test]
fn word_orders() {
    // 0x12345678: high word 0x1234 first by default, reversed for low word first.
    assert_eq!(
        WordOrder::HighFirst.u32_words(0x1234_5678),
        [0x1234, 0x5678]
    );
    assert_eq!(WordOrder::LowFirst.u32_words(0x1234_5678), [0x5678, 0x1234]);
    assert_eq!(WordOrder::LowFirst.u32_from([0x5678, 0x1234]), 0x1234_5678);
    // −1 as i32 is all ones in two's complement.
    assert_eq!(
        WordOrder::HighFirst.u32_words(-1i32 as u32),
        [0xFFFF, 0xFFFF]
    );
    let v = 0x0102_0304_0506_0708i64;
    assert_eq!(
        WordOrder::HighFirst.i64_words(v),
        [0x0102, 0x0304, 0x0506, 0x0708]
    );
    assert_eq!(
        WordOrder::LowFirst.i64_words(v),
        [0x0708, 0x0506, 0x0304, 0x0102]
    );
    for order in [WordOrder::HighFirst, WordOrder::LowFirst] {
        for v in [0, 1, -1, i64::MIN, i64::MAX, -7_000_001_234] {
            assert_eq!(order.i64_from(order.i64_words(v)), v);
        }
    }
    assert_eq!(WordOrder::default(), WordOrder::HighFirst);
    assert_eq!(WordOrder::from_register(1), Ok(WordOrder::LowFirst));
    assert_eq!(WordOrder::LowFirst.register(), 1);
    assert!(matches!(
        WordOrder::from_register(2),
        Err(MapError::Register {
            register: 5,
            value: 2,
            ..
        })
    ));
}

#[test]
fn c_near_700_000_degrees_is_held_exactly() {
    // 700 000.1234° = 7 000 001 234 units of 10⁻⁴ °, beyond i32 (2 147 483 647):
    // 7 000 001 234 − 2³² = 2 705 033 938 = 0xA13B_8AD2, so the i64 is
    // 0x0000_0001_A13B_8AD2 and the words are 0x0000 0x0001 0xA13B 0x8AD2.
    let program = Program {
        moves: vec![Move::Linked {
            x: 12.5,
            z: -3.25,
            c: 700_000.123_4,
            minutes: 0.001,
        }],
    };
    let segs = segments(&program).unwrap();
    assert_eq!(
        segs[0],
        Segment::Linked {
            x: 125_000,
            z: -32_500,
            c: 7_000_001_234,
            duration_us: 60_000
        }
    );
    let slot = segs[0].encode(1, WordOrder::HighFirst);
    assert_eq!(&slot[8..12], &[0x0000, 0x0001, 0xA13B, 0x8AD2]);
    let slot = segs[0].encode(1, WordOrder::LowFirst);
    assert_eq!(&slot[8..12], &[0x8AD2, 0xA13B, 0x0001, 0x0000]);
    // And the negative turn, two's complement: each word inverted, plus one at the
    // bottom (!0x8AD2 + 1 = 0x752E, !0xA13B = 0x5EC4, !0x0001 = 0xFFFE).
    assert_eq!(
        WordOrder::HighFirst.i64_words(-7_000_001_234),
        [0xFFFF, 0xFFFE, 0x5EC4, 0x752E]
    );
}

#[test]
fn a_linked_slot_by_hand() {
    // Sequence 0x00012345, a linked move to X 12.5 mm, Z −3.25 mm, C 90°, 60 ms, high
    // word first. By the layout: SEQ 0x0001 0x2345; KIND 0x0701 (kind 1, flags X Z C);
    // 0; X 125 000 = 0x0001E848; Z −32 500 = 0xFFFF810C; C 900 000 = 0x000DBBA0 in
    // four words; PARAM 60 000 = 0x0000EA60; 0; CRC.
    let segment = Segment::Linked {
        x: 125_000,
        z: -32_500,
        c: 900_000,
        duration_us: 60_000,
    };
    let slot = segment.encode(0x0001_2345, WordOrder::HighFirst);
    let body = [
        0x0001, 0x2345, 0x0701, 0, 0x0001, 0xE848, 0xFFFF, 0x810C, 0, 0, 0x000D, 0xBBA0, 0x0000,
        0xEA60, 0,
    ];
    assert_eq!(&slot[..15], &body);
    let bytes: Vec<u8> = body.iter().flat_map(|r: &u16| r.to_be_bytes()).collect();
    assert_eq!(slot[15], crc16(&bytes));
}

#[test]
fn other_kinds_by_hand() {
    let order = WordOrder::HighFirst;
    // A rapid of Z alone: kind 2, flag Z (0x0200); X and C stay 0.
    let slot = Segment::Rapid {
        x: None,
        z: Some(10_000),
        c: None,
    }
    .encode(7, order);
    assert_eq!(&slot[..8], &[0, 7, 0x0202, 0, 0, 0, 0, 10_000]);
    // A feed of X at 50 mm/min = 50 000 thousandths.
    let slot = Segment::Feed {
        x: Some(-5),
        z: None,
        c: None,
        feed: 50_000,
    }
    .encode(8, order);
    assert_eq!(&slot[2..6], &[0x0103, 0, 0xFFFF, 0xFFFB]);
    assert_eq!(&slot[12..14], &[0, 50_000]);
    let param = |s: Segment| {
        let slot = s.encode(1, order);
        (slot[2], order.u32_from([slot[12], slot[13]]))
    };
    assert_eq!(
        param(Segment::Dwell {
            duration_us: 1_500_000
        }),
        (4, 1_500_000)
    );
    assert_eq!(param(Segment::SpindleOn { rpm: 2_500_500 }), (5, 2_500_500));
    assert_eq!(param(Segment::SpindleOff), (6, 0));
    assert_eq!(param(Segment::ProgramEnd), (7, 0));
}

#[test]
fn sequence_numbers_skip_zero() {
    assert_eq!(next_sequence(1), 2);
    assert_eq!(next_sequence(u32::MAX), 1);
}

fn ident_registers() -> [u16; 8] {
    [0x5748, 0x524C, 1, 32, 16, 0, 1000, 500]
}

#[test]
fn identification_decodes_and_is_checked() {
    let ident = Identification::decode(&ident_registers()).unwrap();
    assert_eq!(
        ident,
        Identification {
            slots: 32,
            word_order: WordOrder::HighFirst,
            max_segment_rate: 1000,
            watchdog_timeout: Duration::from_millis(500),
        }
    );
    // "WHRL" in ASCII.
    assert_eq!(MAGIC[0].to_be_bytes(), *b"WH");
    assert_eq!(MAGIC[1].to_be_bytes(), *b"RL");
    for (register, value) in [
        (0, 0x4857),
        (1, 0x4C52),
        (2, 2),
        (3, 1),
        (3, 65),
        (4, 8),
        (5, 2),
        (6, 0),
        (7, 0),
    ] {
        let mut r = ident_registers();
        r[register] = value;
        assert!(
            matches!(
                Identification::decode(&r),
                Err(MapError::Register { register: got, value: v, .. })
                    if usize::from(got) == register && v == value
            ),
            "register {register} = {value}"
        );
    }
    assert_eq!(
        Identification::decode(&[0; 7]),
        Err(MapError::Length {
            what: "identification block",
            expected: 8,
            got: 7
        })
    );
}

#[test]
fn status_decodes_in_both_word_orders() {
    // Alarm 2 at segment 70 000 (0x00011170) with error 15, TAIL 3, executed 65 537
    // (0x00010001), X 12.5 mm, Z −0.0001 mm, C 700 000.1234°, CONTROL RUN, HEAD 5,
    // WATCHDOG 9.
    let high = [
        3, 2, 0x0001, 0x1170, 15, 3, 0x0001, 0x0001, 0x0001, 0xE848, 0xFFFF, 0xFFFF, 0x0000,
        0x0001, 0xA13B, 0x8AD2, 1, 5, 9,
    ];
    let low = [
        3, 2, 0x1170, 0x0001, 15, 3, 0x0001, 0x0001, 0xE848, 0x0001, 0xFFFF, 0xFFFF, 0x8AD2,
        0xA13B, 0x0001, 0x0000, 1, 5, 9,
    ];
    let expected = Status {
        state: State::Alarm,
        alarm: Some(AlarmReport {
            code: AlarmCode::SoftLimit,
            sequence: 70_000,
            detail: 15,
        }),
        tail: 3,
        executed: 65_537,
        x: 125_000,
        z: -1,
        c: 7_000_001_234,
        control: control::RUN,
        head: 5,
        watchdog: 9,
    };
    assert_eq!(Status::decode(&high, WordOrder::HighFirst), Ok(expected));
    assert_eq!(Status::decode(&low, WordOrder::LowFirst), Ok(expected));
    assert_eq!(expected.position(), [12.5, -0.0001, 700_000.123_4]);
    let mut bad = high;
    bad[0] = 5;
    assert!(matches!(
        Status::decode(&bad, WordOrder::HighFirst),
        Err(MapError::Register {
            register: 16,
            value: 5,
            ..
        })
    ));
    assert!(matches!(
        Status::decode(&high[..18], WordOrder::HighFirst),
        Err(MapError::Length {
            expected: 19,
            got: 18,
            ..
        })
    ));
    // No alarm: state idle and code 0.
    let mut none = high;
    none[0] = 0;
    none[1] = 0;
    assert_eq!(
        Status::decode(&none, WordOrder::HighFirst).unwrap().alarm,
        None
    );
    // An alarm state without a code, or a code without the alarm state, is refused.
    let mut no_code = high;
    no_code[1] = 0;
    let mut no_state = high;
    no_state[0] = 1;
    for r in [no_code, no_state] {
        assert!(matches!(
            Status::decode(&r, WordOrder::HighFirst),
            Err(MapError::Register { register: 17, .. })
        ));
    }
}

#[test]
fn alarm_codes_round_trip_and_read() {
    for code in [2, 3, 64, 101, 102, 103, 104, 105, 7] {
        assert_eq!(AlarmCode::from_register(code).unwrap().code(), code);
    }
    assert_eq!(AlarmCode::from_register(0), None);
    assert_eq!(AlarmCode::from_register(7), Some(AlarmCode::Other(7)));
    let report = AlarmReport {
        code: AlarmCode::Refused,
        sequence: 12,
        detail: 11,
    };
    assert_eq!(
        report.to_string(),
        "alarm 105 (segment refused by the controller) at segment 12, controller error 11"
    );
    let report = AlarmReport {
        code: AlarmCode::Watchdog,
        sequence: 0,
        detail: 0,
    };
    assert_eq!(report.to_string(), "alarm 104 (watchdog)");
    for (code, text) in [
        (AlarmCode::SoftLimit, "target outside the travel"),
        (AlarmCode::AbortCycle, "reset while moving"),
        (AlarmCode::ProfileError, "profile error beyond Δ"),
        (AlarmCode::SlotCrc, "slot CRC"),
        (AlarmCode::Sequence, "sequence number out of order"),
        (AlarmCode::Segment, "invalid segment"),
        (AlarmCode::Other(7), "controller alarm"),
    ] {
        assert!(code.to_string().ends_with(&format!("({text})")));
    }
    for (value, state) in [
        (0, State::Idle),
        (1, State::Running),
        (2, State::Held),
        (3, State::Alarm),
        (4, State::Done),
    ] {
        assert_eq!(State::from_register(value), Ok(state));
    }
}

// ---- The golden fixture, tests/data/modbus-golden.json ----
//
// Registers and bytes worked out by hand from docs/modbus.md and read by the simulator's
// tests too: this side's one definition of each number, its slots, its decoding of the
// identification and status blocks, and the control and HEAD writes of its stream must
// all agree with it.

use crate::post::modbus::{ANGULAR_UNITS_PER_DEG, LINEAR_UNITS_PER_MM};
use crate::protocol::modbus::{Request, Response, RingWriter, WriterOptions};
use serde_json::Value;

const GOLDEN: &str = include_str!(concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/tests/data/modbus-golden.json"
));

fn golden() -> Value {
    serde_json::from_str(GOLDEN).expect("tests/data/modbus-golden.json is JSON")
}

/// A number of the fixture: a JSON integer, or a hex string such as "0x0302".
fn int(v: &Value) -> i64 {
    match v {
        Value::Number(n) => n.as_i64().expect("an integer"),
        Value::String(s) => {
            let hex = s.strip_prefix("0x").expect("a hex string starts 0x");
            i64::from_str_radix(hex, 16).expect("hex digits")
        }
        other => panic!("not a number: {other}"),
    }
}

fn word(v: &Value) -> u16 {
    u16::try_from(int(v)).expect("a 16-bit value")
}

fn words(v: &Value) -> Vec<u16> {
    v.as_array().expect("a list").iter().map(word).collect()
}

/// "57 48 …" as bytes.
fn hex_bytes(v: &Value) -> Vec<u8> {
    v.as_str()
        .expect("hex bytes")
        .split_whitespace()
        .map(|b| u8::from_str_radix(b, 16).expect("a hex byte"))
        .collect()
}

/// Registers as they go on the wire, each high byte first.
fn wire(registers: &[u16]) -> Vec<u8> {
    registers.iter().flat_map(|r| r.to_be_bytes()).collect()
}

fn list(v: &Value) -> &[Value] {
    v.as_array().expect("a list of cases")
}

fn named<'a>(cases: &'a Value, name: &str) -> &'a Value {
    list(cases)
        .iter()
        .find(|c| c["name"] == name)
        .unwrap_or_else(|| panic!("no case {name}"))
}

/// A request PDU of the fixture as the request it stands for (FC16 by its header:
/// address, quantity and byte count; the values follow it).
fn pdu_request(v: &Value) -> Request {
    let b = hex_bytes(v);
    let at = |k: usize| u16::from_be_bytes([b[k], b[k + 1]]);
    match b[0] {
        3 => Request::ReadHolding {
            address: at(1),
            count: at(3),
        },
        6 => Request::WriteSingle {
            address: at(1),
            value: at(3),
        },
        16 => {
            assert_eq!(usize::from(b[5]), 2 * usize::from(at(3)), "byte count");
            Request::WriteMultiple {
                address: at(1),
                values: vec![0; usize::from(at(3))],
            }
        }
        f => panic!("function {f} is not in the map"),
    }
}

/// `request` with an FC16's values zeroed, to compare with [`pdu_request`].
fn shape(request: &Request) -> Request {
    match request {
        Request::WriteMultiple { address, values } => Request::WriteMultiple {
            address: *address,
            values: vec![0; values.len()],
        },
        other => other.clone(),
    }
}

fn orders() -> [(&'static str, WordOrder); 2] {
    [
        ("high_first", WordOrder::HighFirst),
        ("low_first", WordOrder::LowFirst),
    ]
}

fn control_bit(name: &str) -> u16 {
    match name {
        "RUN" => control::RUN,
        "HOLD" => control::HOLD,
        "RESUME" => control::RESUME,
        "RESET_ALARM" => control::RESET_ALARM,
        "ABORT" => control::ABORT,
        "END" => control::END,
        other => panic!("no control bit {other}"),
    }
}

#[test]
fn golden_numbers_are_this_side_s() {
    let g = golden();
    let m = &g["map"];
    let registers = [
        ("MAGIC_0", reg::MAGIC),
        ("MAGIC_1", reg::MAGIC + 1),
        ("MAP_VERSION", reg::MAP_VERSION),
        ("SLOT_COUNT", reg::SLOT_COUNT),
        ("SLOT_SIZE", reg::SLOT_SIZE),
        ("WORD_ORDER", reg::WORD_ORDER),
        ("MAX_SEGMENT_RATE", reg::MAX_SEGMENT_RATE),
        ("WATCHDOG_TIMEOUT", reg::WATCHDOG_TIMEOUT),
        ("STATE", reg::STATE),
        ("ALARM_CODE", reg::ALARM_CODE),
        ("ALARM_SEQ", reg::ALARM_SEQ),
        ("ALARM_DETAIL", reg::ALARM_DETAIL),
        ("TAIL", reg::TAIL),
        ("EXECUTED_SEQ", reg::EXECUTED_SEQ),
        ("POS_X", reg::POS_X),
        ("POS_Z", reg::POS_Z),
        ("POS_C", reg::POS_C),
        ("CONTROL", reg::CONTROL),
        ("HEAD", reg::HEAD),
        ("WATCHDOG", reg::WATCHDOG),
        ("RING", reg::RING),
    ];
    assert_eq!(m["registers"].as_object().unwrap().len(), registers.len());
    for (name, address) in registers {
        assert_eq!(word(&m["registers"][name]), address, "{name}");
    }
    assert_eq!(word(&m["identification_length"]), reg::IDENT_LEN);
    assert_eq!(word(&m["status_length"]), reg::STATUS_LEN);
    assert_eq!(int(&m["unit_id"]), i64::from(UNIT_ID));
    assert_eq!(words(&m["magic"]), MAGIC);
    assert_eq!(word(&m["map_version"]), MAP_VERSION);
    assert_eq!(word(&m["slot_size"]), SLOT_SIZE);
    assert_eq!(word(&m["slot_count"]["min"]), MIN_SLOTS);
    assert_eq!(word(&m["slot_count"]["max"]), MAX_SLOTS);
    assert_eq!(word(&m["max_read"]), MAX_READ);
    assert_eq!(word(&m["max_write"]), MAX_WRITE);
    let offsets = [
        ("SEQ", offset::SEQ),
        ("KIND", offset::KIND),
        ("X", offset::X),
        ("Z", offset::Z),
        ("C", offset::C),
        ("PARAM", offset::PARAM),
        ("CRC", offset::CRC),
    ];
    assert_eq!(m["slot_offsets"].as_object().unwrap().len(), offsets.len());
    for (name, at) in offsets {
        assert_eq!(int(&m["slot_offsets"][name]), at as i64, "{name}");
    }
    for (name, order) in orders() {
        assert_eq!(word(&m["word_order"][name]), order.register(), "{name}");
        assert_eq!(WordOrder::from_register(order.register()), Ok(order));
    }
    let bits = m["control"].as_object().unwrap();
    assert_eq!(bits.len(), 6);
    for (name, bit) in bits {
        assert_eq!(word(bit), control_bit(name), "{name}");
    }
    let kinds = [
        ("linked", kind::LINKED),
        ("rapid", kind::RAPID),
        ("feed", kind::FEED),
        ("dwell", kind::DWELL),
        ("spindle_on", kind::SPINDLE_ON),
        ("spindle_off", kind::SPINDLE_OFF),
        ("program_end", kind::PROGRAM_END),
    ];
    assert_eq!(m["kinds"].as_object().unwrap().len(), kinds.len());
    for (name, code) in kinds {
        assert_eq!(word(&m["kinds"][name]), code, "{name}");
    }
    for (name, bit) in [("X", flag::X), ("Z", flag::Z), ("C", flag::C)] {
        assert_eq!(word(&m["flags"][name]), bit, "{name}");
    }
    for (name, state) in [
        ("idle", State::Idle),
        ("running", State::Running),
        ("held", State::Held),
        ("alarm", State::Alarm),
        ("done", State::Done),
    ] {
        assert_eq!(State::from_register(word(&m["states"][name])), Ok(state));
    }
    let alarms = [
        ("soft_limit", AlarmCode::SoftLimit),
        ("abort_cycle", AlarmCode::AbortCycle),
        ("profile_error", AlarmCode::ProfileError),
        ("slot_crc", AlarmCode::SlotCrc),
        ("sequence", AlarmCode::Sequence),
        ("segment", AlarmCode::Segment),
        ("watchdog", AlarmCode::Watchdog),
        ("refused", AlarmCode::Refused),
    ];
    assert_eq!(m["alarms"].as_object().unwrap().len(), alarms.len());
    for (name, alarm) in alarms {
        let code = word(&m["alarms"][name]);
        assert_eq!(alarm.code(), code, "{name}");
        assert_eq!(AlarmCode::from_register(code), Some(alarm), "{name}");
    }
    // The map's units as the segments carry them (post::modbus), checked here too.
    let units = &m["units"];
    assert_eq!(int(&units["linear_per_mm"]) as f64, LINEAR_UNITS_PER_MM);
    assert_eq!(
        int(&units["angular_per_degree"]) as f64,
        ANGULAR_UNITS_PER_DEG
    );
    let check = &g["crc"]["check"];
    assert_eq!(
        crc16(check["ascii"].as_str().unwrap().as_bytes()),
        word(&check["crc"])
    );
}

#[test]
fn golden_identification_blocks_decode() {
    let g = golden();
    for case in list(&g["identification"]) {
        let name = case["name"].as_str().unwrap();
        let registers = words(&case["registers"]);
        assert_eq!(wire(&registers), hex_bytes(&case["bytes"]), "{name}");
        assert_eq!(
            pdu_request(&case["request_pdu"]),
            Request::ReadHolding {
                address: reg::MAGIC,
                count: reg::IDENT_LEN
            },
            "{name}"
        );
        assert_eq!(
            Identification::decode(&registers),
            Ok(Identification {
                slots: word(&case["slots"]),
                word_order: WordOrder::from_register(word(&case["word_order"])).unwrap(),
                max_segment_rate: word(&case["max_segment_rate"]),
                watchdog_timeout: Duration::from_millis(int(&case["watchdog_timeout_ms"]) as u64),
            }),
            "{name}"
        );
    }
}

/// The segment a slot case describes: its kind, the axes given (null for an axis
/// without its flag) and `PARAM`.
fn golden_segment(case: &Value) -> Segment {
    let axis = |name: &str| (!case[name].is_null()).then(|| int(&case[name]));
    let linear = |name: &str| axis(name).map(|v| i32::try_from(v).expect("an i32"));
    let (x, z, c) = (linear("x"), linear("z"), axis("c"));
    let param = u32::try_from(int(&case["param"])).expect("a u32");
    let no_axes = x.is_none() && z.is_none() && c.is_none();
    let segment = match word(&case["kind"]) {
        kind::LINKED => Segment::Linked {
            x: x.unwrap(),
            z: z.unwrap(),
            c: c.unwrap(),
            duration_us: param,
        },
        kind::RAPID => Segment::Rapid { x, z, c },
        kind::FEED => Segment::Feed {
            x,
            z,
            c,
            feed: param,
        },
        kind::DWELL => Segment::Dwell { duration_us: param },
        kind::SPINDLE_ON => Segment::SpindleOn { rpm: param },
        kind::SPINDLE_OFF => Segment::SpindleOff,
        kind::PROGRAM_END => Segment::ProgramEnd,
        other => panic!("kind {other} is not in the map"),
    };
    if !matches!(
        segment,
        Segment::Linked { .. } | Segment::Rapid { .. } | Segment::Feed { .. }
    ) {
        assert!(no_axes, "{case}");
    }
    segment
}

#[test]
fn golden_slots_encode() {
    let g = golden();
    for case in list(&g["slots"]) {
        let name = case["name"].as_str().unwrap();
        let segment = golden_segment(case);
        let sequence = u32::try_from(int(&case["sequence"])).unwrap();
        for (order_name, order) in orders() {
            let expected = &case[order_name];
            let slot = segment.encode(sequence, order);
            assert_eq!(
                slot.to_vec(),
                words(&expected["registers"]),
                "{name}, {order_name}"
            );
            assert_eq!(slot[offset::KIND], word(&case["kind_register"]), "{name}");
            // The bytes on the wire, and the CRC over the 30 before it, carried high
            // byte first as the register it is.
            let bytes = wire(&slot);
            assert_eq!(bytes, hex_bytes(&expected["bytes"]), "{name}, {order_name}");
            let crc = crc16(&bytes[..2 * offset::CRC]);
            assert_eq!(slot[offset::CRC], crc, "{name}, {order_name}");
            assert_eq!(bytes[2 * offset::CRC..], crc.to_be_bytes());
        }
    }
}

#[test]
fn golden_status_blocks_decode() {
    let g = golden();
    for case in list(&g["status"]) {
        let name = case["name"].as_str().unwrap();
        assert_eq!(
            pdu_request(&case["request_pdu"]),
            Request::ReadHolding {
                address: reg::STATE,
                count: reg::STATUS_LEN
            },
            "{name}"
        );
        let code = word(&case["alarm_code"]);
        let expected = Status {
            state: State::from_register(word(&case["state"])).unwrap(),
            alarm: AlarmCode::from_register(code).map(|code| AlarmReport {
                code,
                sequence: u32::try_from(int(&case["alarm_seq"])).unwrap(),
                detail: word(&case["alarm_detail"]),
            }),
            tail: word(&case["tail"]),
            executed: u32::try_from(int(&case["executed_seq"])).unwrap(),
            x: i32::try_from(int(&case["x"])).unwrap(),
            z: i32::try_from(int(&case["z"])).unwrap(),
            c: int(&case["c"]),
            control: word(&case["control"]),
            head: word(&case["head"]),
            watchdog: word(&case["watchdog"]),
        };
        for (order_name, order) in orders() {
            let registers = words(&case[order_name]);
            assert_eq!(
                Status::decode(&registers, order),
                Ok(expected),
                "{name}, {order_name}"
            );
        }
        let p = &case["position"];
        let mm = |k: &str| p[k].as_f64().unwrap();
        assert_eq!(
            expected.position(),
            [mm("x_mm"), mm("z_mm"), mm("c_deg")],
            "{name}"
        );
    }
}

/// The controller's side of a stream, as far as the fixture's identification and the
/// ring's HEAD and TAIL go: idle, no alarm, TAIL where the test puts it.
struct GoldenRing {
    ident: Vec<u16>,
    control: u16,
    head: u16,
    tail: u16,
    watchdog: u16,
}

impl GoldenRing {
    fn answer(&mut self, request: &Request) -> Response {
        match *request {
            Request::ReadHolding { address, count }
                if (address, count) == (reg::MAGIC, reg::IDENT_LEN) =>
            {
                Response::ReadHolding(self.ident.clone())
            }
            Request::ReadHolding { address, count }
                if (address, count) == (reg::STATE, reg::STATUS_LEN) =>
            {
                let mut r = vec![0; usize::from(reg::STATUS_LEN)];
                let at = |register: u16| usize::from(register - reg::STATE);
                r[at(reg::TAIL)] = self.tail;
                r[at(reg::CONTROL)] = self.control;
                r[at(reg::HEAD)] = self.head;
                r[at(reg::WATCHDOG)] = self.watchdog;
                Response::ReadHolding(r)
            }
            Request::WriteSingle { address, value } => {
                match address {
                    reg::CONTROL => {
                        if value & !self.control & control::ABORT != 0 {
                            (self.head, self.tail) = (0, 0);
                        }
                        self.control = value;
                    }
                    reg::HEAD => self.head = value,
                    reg::WATCHDOG => self.watchdog = value,
                    other => panic!("FC06 to register {other}"),
                }
                Response::WriteSingle { address, value }
            }
            Request::WriteMultiple {
                address,
                ref values,
            } => Response::WriteMultiple {
                address,
                count: values.len() as u16,
            },
            ref other => panic!("unexpected {other:?}"),
        }
    }
}

fn golden_drive(w: &mut RingWriter, ring: &mut GoldenRing, now: Duration) -> Vec<Request> {
    let mut sent = Vec::new();
    while let Some(request) = w.poll(now) {
        w.response(Ok(ring.answer(&request)));
        sent.push(request);
    }
    sent
}

#[test]
fn golden_control_and_head_writes_of_a_stream() {
    let g = golden();
    let ident = named(&g["identification"], "identification_low_first");
    let linked = named(&g["slots"], "linked");
    let [first, full, wraps] =
        ["head_first_slot", "head_full", "head_wraps"].map(|n| named(&g["head"], n));
    for case in [first, full, wraps] {
        assert_eq!(case["slots"], ident["slots"]);
    }
    // Five linked moves numbered from the fixture's, into the ring of 4 that
    // identification_low_first describes.
    let options = WriterOptions {
        first_sequence: u32::try_from(int(&linked["sequence"])).unwrap(),
        ..WriterOptions::default()
    };
    let mut w = RingWriter::new(vec![golden_segment(linked); 5], options).unwrap();
    let mut ring = GoldenRing {
        ident: words(&ident["registers"]),
        control: 0,
        head: 0,
        tail: 0,
        watchdog: 0,
    };
    let mut sent = golden_drive(&mut w, &mut ring, Duration::ZERO);
    assert_eq!(sent[0], pdu_request(&ident["request_pdu"]));
    assert_eq!(
        sent[1],
        pdu_request(&named(&g["status"], "status_done")["request_pdu"])
    );
    // The first slot after the flush, and its HEAD write; the slot is the fixture's,
    // low word first.
    let k = sent
        .iter()
        .position(|r| matches!(r, Request::WriteMultiple { .. }))
        .unwrap();
    assert_eq!(shape(&sent[k]), pdu_request(&first["slot_write_pdu"]));
    assert_eq!(
        sent[k],
        Request::WriteMultiple {
            address: reg::RING,
            values: words(&linked["low_first"]["registers"]),
        }
    );
    assert_eq!(sent[k + 1], pdu_request(&first["head_write_pdu"]));
    // Full at HEAD 3, TAIL 0: after that HEAD write no slot, but RUN.
    let head = word(&full["head"]);
    assert_eq!(ring.tail, word(&full["tail"]));
    let k = sent
        .iter()
        .position(|r| {
            *r == Request::WriteSingle {
                address: reg::HEAD,
                value: head,
            }
        })
        .unwrap();
    assert_eq!(
        sent[k + 1..],
        [Request::WriteSingle {
            address: reg::CONTROL,
            value: control::RUN
        }]
    );
    // A hold whose answer is lost (the same word re-sent), then a resume.
    w.hold();
    let hold = w.poll(Duration::ZERO).unwrap();
    sent.push(hold.clone());
    w.timeout();
    assert_eq!(w.poll(Duration::ZERO), Some(hold.clone()));
    w.response(Ok(ring.answer(&hold)));
    sent.push(hold);
    sent.extend(golden_drive(&mut w, &mut ring, Duration::ZERO));
    w.resume();
    sent.extend(golden_drive(&mut w, &mut ring, Duration::ZERO));
    // The controller takes slots up to TAIL 2: HEAD 3 wraps to 0 (and on, to the end).
    ring.tail = word(&wraps["tail"]);
    assert_eq!(ring.head, word(&wraps["head"]));
    let later = golden_drive(&mut w, &mut ring, Duration::from_millis(50));
    let k = later
        .iter()
        .position(|r| matches!(r, Request::ReadHolding { .. }))
        .unwrap();
    assert_eq!(shape(&later[k + 1]), pdu_request(&wraps["slot_write_pdu"]));
    assert_eq!(later[k + 2], pdu_request(&wraps["head_write_pdu"]));
    sent.extend(later);
    // Every control word the stream wrote is the fixture's, in its order.
    let written: Vec<Request> = sent
        .iter()
        .filter(|r| matches!(r, Request::WriteSingle { address, .. } if *address == reg::CONTROL))
        .cloned()
        .collect();
    let writes: Vec<&Value> = list(&g["control"]["writes"])
        .iter()
        .filter(|c| c["by_the_bridge"] == true)
        .collect();
    let expected: Vec<Request> = writes.iter().map(|c| pdu_request(&c["pdu"])).collect();
    assert_eq!(written, expected);
    // And each says its edges with this side's bits.
    let all = control::RUN
        | control::HOLD
        | control::RESUME
        | control::RESET_ALARM
        | control::ABORT
        | control::END;
    for case in list(&g["control"]["writes"]) {
        let (before, value) = (word(&case["before"]), word(&case["value"]));
        assert_eq!(
            pdu_request(&case["pdu"]),
            Request::WriteSingle {
                address: reg::CONTROL,
                value
            }
        );
        let rising = case["rising"]
            .as_array()
            .unwrap()
            .iter()
            .fold(0, |bits, name| bits | control_bit(name.as_str().unwrap()));
        if case["exception"].is_null() {
            assert_eq!(value & !all, 0, "{case}");
            assert_eq!(value & !before, rising, "{case}");
        } else {
            assert_ne!(value & !all, 0, "a reserved bit: {case}");
        }
    }
}
