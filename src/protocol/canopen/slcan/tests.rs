//! Tests of the slcan protocol, kept apart from it for length: setup and transmit commands,
//! bitrates, the decoder's replies, timestamps, errors and resynchronisation.

use super::*;

#[test]
fn slcans_rates_are_the_ones_a_profile_takes() {
    assert_eq!(
        Bitrate::ALL.map(Bitrate::bits_per_second),
        crate::config::connection::CAN_BITRATES
    );
}

fn std_frame(id: u16, data: &[u8]) -> CanFrame {
    CanFrame::standard(id, data).unwrap()
}

fn frame_of(received: &Result<Received, SlcanError>) -> CanFrame {
    match received {
        Ok(Received::Frame { frame, .. }) => *frame,
        other => panic!("not a frame: {other:?}"),
    }
}

#[test]
fn setup_commands_are_lawicels() {
    // Lawicel: S0 = 10 kbit/s … S8 = 1 Mbit/s; O opens, C closes, Zn timestamps.
    assert_eq!(Command::SetBitrate(Bitrate::K10).encode(), b"S0\r");
    assert_eq!(Command::SetBitrate(Bitrate::K125).encode(), b"S4\r");
    assert_eq!(Command::SetBitrate(Bitrate::K500).encode(), b"S6\r");
    assert_eq!(Command::SetBitrate(Bitrate::M1).encode(), b"S8\r");
    assert_eq!(Command::Open.encode(), b"O\r");
    assert_eq!(Command::Close.encode(), b"C\r");
    assert_eq!(Command::Timestamps(true).encode(), b"Z1\r");
    assert_eq!(Command::Timestamps(false).encode(), b"Z0\r");
    assert_eq!(Command::Open.to_string(), "O\\r");
}

#[test]
fn bitrates_map_both_ways() {
    let table = [
        (10_000, 0),
        (20_000, 1),
        (50_000, 2),
        (100_000, 3),
        (125_000, 4),
        (250_000, 5),
        (500_000, 6),
        (800_000, 7),
        (1_000_000, 8),
    ];
    for (bps, code) in table {
        let rate = Bitrate::from_bits_per_second(bps).unwrap();
        assert_eq!((rate.code(), rate.bits_per_second()), (code, bps));
    }
    assert_eq!(Bitrate::from_bits_per_second(83_333), None);
}

#[test]
fn transmit_commands_follow_the_manuals_examples() {
    // The EasySYNC guide's examples: t34580123456789ABCDEF and t4560;
    // Titan's r0023 asks ID 002 for 3 bytes.
    let frame = std_frame(0x345, &[0x01, 0x23, 0x45, 0x67, 0x89, 0xAB, 0xCD, 0xEF]);
    assert_eq!(
        Command::Transmit(frame).encode(),
        b"t34580123456789ABCDEF\r"
    );
    assert_eq!(
        Command::Transmit(std_frame(0x456, &[])).encode(),
        b"t4560\r"
    );
    let rtr = CanFrame::remote(CanId::Standard(0x002), 3).unwrap();
    assert_eq!(Command::Transmit(rtr).encode(), b"r0023\r");
    let ext = CanFrame::new(CanId::Extended(0x1234_5678), &[0x01, 0x23]).unwrap();
    assert_eq!(Command::Transmit(ext).encode(), b"T1234567820123\r");
    let ext_rtr = CanFrame::remote(CanId::Extended(0x1FFF_FFFF), 8).unwrap();
    assert_eq!(Command::Transmit(ext_rtr).encode(), b"R1FFFFFFF8\r");
}

#[test]
fn replies_and_acks_decode() {
    let mut decoder = Decoder::new();
    assert_eq!(
        decoder.feed(b"\r\x07z\rZ\r"),
        vec![
            Ok(Received::Ok),
            Ok(Received::Error),
            Ok(Received::Transmitted { extended: false }),
            Ok(Received::Transmitted { extended: true }),
        ]
    );
}

#[test]
fn every_frame_kind_round_trips_through_the_decoder() {
    let frames = [
        std_frame(0x000, &[0x01, 0x00]),
        std_frame(0x7FF, &[0xFF; 8]),
        std_frame(0x080, &[]),
        CanFrame::new(CanId::Extended(0x1FFF_FFFF), &[0xA5]).unwrap(),
        CanFrame::remote(CanId::Standard(0x701), 1).unwrap(),
        CanFrame::remote(CanId::Extended(0), 0).unwrap(),
    ];
    let mut decoder = Decoder::new();
    for frame in frames {
        let got = decoder.feed(&Command::Transmit(frame).encode());
        assert_eq!(
            got,
            vec![Ok(Received::Frame {
                frame,
                timestamp_ms: None
            })]
        );
    }
}

#[test]
fn a_timestamp_is_four_more_digits() {
    // Z1: four hex digits of milliseconds after the data; 0xEA5F = 59999 is the last
    // before Lawicel's counter wraps.
    let mut decoder = Decoder::new();
    let got = decoder.feed(b"t18A22706EA5F\rr70110010\r");
    assert_eq!(
        got,
        vec![
            Ok(Received::Frame {
                frame: std_frame(0x18A, &[0x27, 0x06]),
                timestamp_ms: Some(59_999),
            }),
            Ok(Received::Frame {
                frame: CanFrame::remote(CanId::Standard(0x701), 1).unwrap(),
                timestamp_ms: Some(0x0010),
            }),
        ]
    );
}

#[test]
fn split_and_concatenated_input_decodes_the_same() {
    let stream = b"z\rt58186000600000000000\r\x07T000007013010203\r\r";
    let whole = Decoder::new().feed(stream);
    assert_eq!(whole.len(), 5);
    assert_eq!(
        frame_of(&whole[1]),
        std_frame(0x581, &[0x60, 0x00, 0x60, 0, 0, 0, 0, 0])
    );
    assert_eq!(
        frame_of(&whole[3]),
        CanFrame::new(CanId::Extended(0x701), &[0x01, 0x02, 0x03]).unwrap()
    );
    // One byte at a time, and every split in two.
    let mut decoder = Decoder::new();
    let bytewise: Vec<_> = stream.iter().flat_map(|b| decoder.feed(&[*b])).collect();
    assert_eq!(bytewise, whole);
    for cut in 0..stream.len() {
        let mut decoder = Decoder::new();
        let mut got = decoder.feed(&stream[..cut]);
        got.extend(decoder.feed(&stream[cut..]));
        assert_eq!(got, whole, "split at {cut}");
    }
}

#[test]
fn lower_case_hex_is_read() {
    let got = Decoder::new().feed(b"t7ff1ab\r");
    assert_eq!(frame_of(&got[0]), std_frame(0x7FF, &[0xAB]));
}

#[test]
fn errors_name_the_line_and_byte() {
    let mut decoder = Decoder::new();
    let got = decoder.feed(b"x12\rt12G0\rt1239\rt12320\rt8000\rT200000000\rt1\rzz\r");
    assert_eq!(
        got,
        vec![
            Err(SlcanError::Unknown { line: "x12".into() }),
            Err(SlcanError::Hex {
                line: "t12G0".into(),
                column: 3,
                byte: "G".into()
            }),
            Err(SlcanError::Dlc {
                line: "t1239".into(),
                byte: "9".into()
            }),
            Err(SlcanError::Length {
                line: "t12320".into(),
                expected: 9,
                found: 6
            }),
            Err(SlcanError::Id {
                line: "t8000".into(),
                error: FrameError::StandardId(0x800)
            }),
            Err(SlcanError::Id {
                line: "T200000000".into(),
                error: FrameError::ExtendedId(0x2000_0000)
            }),
            Err(SlcanError::Truncated { line: "t1".into() }),
            Err(SlcanError::Unknown { line: "zz".into() }),
        ]
    );
    // Bad data and bad timestamp digits are located too; a non-ASCII byte is escaped.
    let got = decoder.feed(b"t12310x\rt1230ZZZZ\rt123\x80\r");
    assert_eq!(
        got,
        vec![
            Err(SlcanError::Hex {
                line: "t12310x".into(),
                column: 6,
                byte: "x".into()
            }),
            Err(SlcanError::Hex {
                line: "t1230ZZZZ".into(),
                column: 5,
                byte: "Z".into()
            }),
            Err(SlcanError::Dlc {
                line: "t123\\x80".into(),
                byte: "\\x80".into()
            }),
        ]
    );
    assert_eq!(
        got[0].clone().unwrap_err().to_string(),
        "\"t12310x\": byte \"x\" at column 6 is not a hex digit"
    );
    // The decoder carries on after each error.
    assert_eq!(decoder.feed(b"\r"), vec![Ok(Received::Ok)]);
}

#[test]
fn a_bel_after_a_partial_line_reports_both() {
    let got = Decoder::new().feed(b"t12\x07\r");
    assert_eq!(
        got,
        vec![
            Err(SlcanError::Unterminated { line: "t12".into() }),
            Ok(Received::Error),
            Ok(Received::Ok),
        ]
    );
}

#[test]
fn an_overlong_line_costs_one_error_and_resyncs_at_cr() {
    let mut decoder = Decoder::new();
    let mut junk = vec![b'a'; MAX_LINE + 10];
    junk.extend_from_slice(b"\rz\r");
    let got = decoder.feed(&junk);
    assert_eq!(
        got,
        vec![
            Err(SlcanError::TooLong {
                start: "a".repeat(MAX_LINE + 1)
            }),
            Ok(Received::Transmitted { extended: false }),
        ]
    );
    // A BEL also ends the skipping (and is the error reply it always is).
    let mut long = vec![b'b'; MAX_LINE + 1];
    long.extend_from_slice(b"bb\x07z\r");
    let got = decoder.feed(&long);
    assert_eq!(got.len(), 3);
    assert_eq!(got[1], Ok(Received::Error));
    assert_eq!(got[2], Ok(Received::Transmitted { extended: false }));
    // The longest legal line, extended with 8 bytes and a timestamp, is not too long.
    let longest = b"T1FFFFFFF80011223344556677EA5F\r";
    assert_eq!(longest.len() - 1, MAX_LINE);
    assert!(decoder.feed(longest)[0].is_ok());
}
