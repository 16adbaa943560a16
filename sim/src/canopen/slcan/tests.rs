//! Tests of the slcan adapter, kept apart from it for length: the channel's setup,
//! frames both ways, refused commands and timestamps.

use super::*;

fn opened() -> SlcanAdapter {
    let mut adapter = SlcanAdapter::new();
    adapter.receive(b"S6\rO\r");
    assert_eq!(adapter.take_output(), b"\r\r");
    adapter
}

#[test]
fn setup_follows_the_channel_state() {
    let mut adapter = SlcanAdapter::new();
    // O before a bit rate; C while closed; S9 does not exist.
    adapter.receive(b"O\rC\rS9\r");
    assert_eq!(adapter.take_output(), b"\x07\x07\x07");
    adapter.receive(b"S4\r");
    assert_eq!(adapter.bitrate(), Some(125_000));
    adapter.receive(b"O\r");
    assert!(adapter.is_open());
    // No bit rate change and no second open while open.
    adapter.receive(b"S8\rO\r");
    assert_eq!(adapter.take_output(), b"\r\r\x07\x07");
    assert_eq!(adapter.bitrate(), Some(125_000));
    adapter.receive(b"C\r");
    assert!(!adapter.is_open());
    adapter.receive(b"S8\r");
    assert_eq!(adapter.bitrate(), Some(1_000_000));
    assert_eq!(adapter.take_output(), b"\r\r");
}

#[test]
fn every_bitrate_code_is_lawicels() {
    let rates = [
        10_000, 20_000, 50_000, 100_000, 125_000, 250_000, 500_000, 800_000, 1_000_000,
    ];
    for (code, rate) in rates.into_iter().enumerate() {
        let mut adapter = SlcanAdapter::new();
        adapter.receive(format!("S{code}\r").as_bytes());
        assert_eq!(adapter.bitrate(), Some(rate));
    }
}

#[test]
fn transmits_go_to_the_bus_and_are_acknowledged() {
    let mut adapter = opened();
    adapter.receive(b"t34580123456789ABCDEF\rt4560\rT1234567820123\rr0023\rR1FFFFFFF0\r");
    assert_eq!(adapter.take_output(), b"z\rz\rZ\rz\rZ\r");
    let frames = adapter.take_transmitted();
    assert_eq!(
        frames[0],
        Frame::data(0x345, &[0x01, 0x23, 0x45, 0x67, 0x89, 0xAB, 0xCD, 0xEF])
    );
    assert_eq!(frames[1], Frame::data(0x456, &[]));
    assert_eq!(
        frames[2],
        Frame {
            id: 0x1234_5678,
            extended: true,
            remote: false,
            dlc: 2,
            data: vec![0x01, 0x23]
        }
    );
    assert_eq!(
        frames[3],
        Frame {
            id: 2,
            extended: false,
            remote: true,
            dlc: 3,
            data: vec![]
        }
    );
    assert!(frames[4].remote && frames[4].extended && frames[4].id == 0x1FFF_FFFF);
    // Lower-case hex is taken too.
    adapter.receive(b"t7ff1ab\r");
    assert_eq!(adapter.take_transmitted(), [Frame::data(0x7FF, &[0xAB])]);
}

#[test]
fn malformed_transmits_are_refused() {
    let mut adapter = opened();
    for bad in [
        "t12",         // no DLC
        "t12G0",       // bad id digit
        "t8000",       // id beyond 11 bits
        "T200000000",  // id beyond 29 bits
        "t1239",       // DLC 9
        "t1232AA",     // data shorter than DLC
        "t1231AABB",   // data longer than DLC
        "t1231AX",     // bad data digit
        "r12310",      // a remote request with data
        "t123\u{e9}0", // not ASCII
    ] {
        adapter.receive(format!("{bad}\r").as_bytes());
        assert_eq!(adapter.take_output(), b"\x07", "{bad}");
    }
    assert!(adapter.take_transmitted().is_empty());
    // And every transmit while closed.
    let mut closed = SlcanAdapter::new();
    closed.receive(b"S6\rt1230\r");
    assert_eq!(closed.take_output(), b"\r\x07");
}

#[test]
fn unknown_empty_and_overlong_commands_get_bel() {
    let mut adapter = opened();
    adapter.receive(b"\rX\rZ2\r");
    assert_eq!(adapter.take_output(), b"\x07\x07\x07");
    let mut long = vec![b'T'; LONGEST_COMMAND + 5];
    long.extend_from_slice(b"\rt1230\r");
    adapter.receive(&long);
    assert_eq!(adapter.take_output(), b"\x07z\r");
    // The longest legal command still fits.
    adapter.receive(b"T1FFFFFFF80011223344556677\r");
    assert_eq!(adapter.take_output(), b"Z\r");
}

#[test]
fn commands_split_anywhere_act_the_same() {
    let stream = b"S6\rO\rt1232AABB\rC\r";
    for cut in 0..stream.len() {
        let mut adapter = SlcanAdapter::new();
        adapter.receive(&stream[..cut]);
        adapter.receive(&stream[cut..]);
        assert_eq!(adapter.take_output(), b"\r\rz\r\r", "cut at {cut}");
        assert_eq!(
            adapter.take_transmitted(),
            [Frame::data(0x123, &[0xAA, 0xBB])]
        );
    }
}

#[test]
fn bus_frames_reach_the_host_only_while_open() {
    let mut adapter = SlcanAdapter::new();
    adapter.deliver(&Frame::data(0x701, &[0x00]));
    assert!(adapter.take_output().is_empty());
    adapter.receive(b"S8\rO\r");
    adapter.take_output();
    adapter.deliver(&Frame::data(0x701, &[0x00]));
    adapter.deliver(&Frame {
        id: 0x1234,
        extended: true,
        remote: false,
        dlc: 1,
        data: vec![0xFE],
    });
    adapter.deliver(&Frame {
        id: 0x701,
        extended: false,
        remote: true,
        dlc: 1,
        data: vec![],
    });
    // Impossible frames are not written.
    adapter.deliver(&Frame::data(0x800, &[]));
    adapter.deliver(&Frame::data(0x100, &[0; 9]));
    assert_eq!(adapter.take_output(), b"t701100\rT000012341FE\rr7011\r");
}

#[test]
fn timestamps_are_milliseconds_wrapping_each_minute() {
    let mut adapter = opened();
    adapter.receive(b"Z1\r");
    adapter.take_output();
    adapter.advance(Duration::from_millis(59_999));
    adapter.deliver(&Frame::data(0x181, &[]));
    adapter.advance(Duration::from_millis(2));
    adapter.deliver(&Frame::data(0x181, &[]));
    assert_eq!(adapter.take_output(), b"t1810EA5F\rt18100001\r");
    adapter.receive(b"Z0\r");
    adapter.deliver(&Frame::data(0x181, &[]));
    assert_eq!(adapter.take_output(), b"\rt1810\r");
}
