//! Configuration: a profile's drives make the session's settings, impossible ones are
//! refused, the SDO script is written in order in either mode, and a failing configuration
//! stops the job before anything moves.

use super::*;
use crate::config::connection::DriveSettings;
use crate::protocol::canopen::cia301::SdoError;

/// A profile's `[connection.drives]`: counts for the sampler, the rest defaults.
fn drives(more: &str) -> DriveSettings {
    toml::from_str(&format!(
        "counts_per_mm = [10000.0, 10000.0]\ncounts_per_degree = 2912.7\n{more}"
    ))
    .unwrap()
}

#[test]
fn a_profiles_drives_make_the_session() {
    // The session's own defaults are a profile's: nodes 1-3, a 50 ms heartbeat
    // supervised at 150 ms, a 10 000-count window, cyclic synchronous position.
    assert_eq!(
        SessionConfig::for_drives(&drives("")),
        Ok(SessionConfig::default())
    );
    let config = SessionConfig::for_drives(&drives(
        "nodes = [10, 20, 30]\nheartbeat_ms = 20\nheartbeat_timeout_ms = 70\n\
         following_error_window = 2500",
    ))
    .unwrap();
    assert_eq!(config.nodes.map(NodeId::get), [10, 20, 30]);
    assert_eq!(config.heartbeat_ms, 20);
    assert_eq!(config.heartbeat_timeout, Duration::from_millis(70));
    assert_eq!(config.following_error_window, 2500);
    assert_eq!(
        SessionConfig {
            nodes: SessionConfig::default().nodes,
            heartbeat_ms: 50,
            heartbeat_timeout: Duration::from_millis(150),
            following_error_window: 10_000,
            ..config
        },
        SessionConfig::default()
    );
    // Interpolated position, everything else alike.
    assert_eq!(
        SessionConfig::for_drives(&drives("mode = \"ip\"")),
        Ok(SessionConfig {
            operation: Operation::InterpolatedPosition,
            ..SessionConfig::default()
        })
    );
    // Settings the profile refuses make no session, naming the key.
    for (more, key) in [
        ("nodes = [1, 0, 3]", "connection.drives.nodes"),
        ("nodes = [4, 4, 5]", "connection.drives.nodes"),
        ("heartbeat_ms = 0", "connection.drives.heartbeat_ms"),
        ("cycle_us = 0", "connection.drives.cycle_us"),
    ] {
        assert_eq!(
            SessionConfig::for_drives(&drives(more)).unwrap_err().key,
            key
        );
    }
}

#[test]
fn the_configuration_is_written_by_sdo_in_order() {
    let mut bench = Bench::plain();
    bench.run_until(|s| s.phase() == Phase::Enabling);
    let requests: Vec<[u8; 8]> = bench
        .sent
        .iter()
        .filter(|(_, f)| f.id().raw() == 0x601)
        .map(|(_, f)| f.data().try_into().unwrap())
        .collect();
    let header = |r: &[u8; 8]| (r[0], u16::from_le_bytes([r[1], r[2]]), r[3]);
    let value = |r: &[u8; 8]| u32::from_le_bytes([r[4], r[5], r[6], r[7]]);
    assert_eq!(header(&requests[0]), (0x40, 0x1000, 0));
    assert_eq!(
        (header(&requests[1]), value(&requests[1])),
        ((0x2B, 0x1017, 0), 10)
    );
    assert_eq!(
        (header(&requests[2]), value(&requests[2])),
        ((0x2F, 0x6060, 0), 8)
    );
    assert_eq!(
        (header(&requests[3]), value(&requests[3])),
        ((0x23, 0x6065, 0), 1000)
    );
    // 60C2h: the 2 ms cycle as 200 × 10⁻⁵ s, each sub-index one byte.
    assert_eq!(
        (header(&requests[4]), value(&requests[4])),
        ((0x2F, 0x60C2, 1), 200)
    );
    assert_eq!(
        (header(&requests[5]), value(&requests[5])),
        ((0x2F, 0x60C2, 2), (-5i8) as u8 as u32)
    );
    // RPDO1: invalid, type 1, clear, 6040h/16, 607Ah/32, two entries, valid.
    let rpdo: Vec<(u16, u8, u32)> = requests[6..13]
        .iter()
        .map(|r| (header(r).1, r[3], value(r)))
        .collect();
    assert_eq!(
        rpdo,
        [
            (0x1400, 1, 0x8000_0201),
            (0x1400, 2, 1),
            (0x1600, 0, 0),
            (0x1600, 1, 0x6040_0010),
            (0x1600, 2, 0x607A_0020),
            (0x1600, 0, 2),
            (0x1400, 1, 0x0000_0201),
        ]
    );
    assert_eq!(value(&requests[19]), 0x4000_0181);
    assert_eq!(requests.len(), 20);
    // NMT start to each node after the last answer, and the first SYNC with it.
    let tail: Vec<CanFrame> = bench.sent.iter().rev().take(4).rev().map(|s| s.1).collect();
    assert_eq!(
        tail,
        [
            std(0x000, &[0x01, 1]),
            std(0x000, &[0x01, 2]),
            std(0x000, &[0x01, 3]),
            std(0x080, &[])
        ]
    );
}

#[test]
fn operations_name_their_mode_and_set_point() {
    let csp = Operation::CyclicSynchronousPosition;
    let ip = Operation::InterpolatedPosition;
    assert_eq!(Operation::default(), csp);
    assert_eq!(SessionConfig::default().operation, csp);
    assert_eq!((csp.mode().value(), ip.mode().value()), (8, 7));
    assert_eq!(csp.set_point_object(), (0x607A, 0));
    assert_eq!(ip.set_point_object(), (0x60C1, 1));
    assert_eq!(csp.to_string(), "cyclic synchronous position (mode 8)");
    assert_eq!(ip.to_string(), "interpolated position (mode 7)");
    // Both take Operation enabled with bit 12; only IP asks for bit 4 to get it.
    for operation in [csp, ip] {
        assert!(operation.follows(0x1237));
        assert!(!operation.follows(0x0237));
        assert!(!operation.follows(0x1233));
    }
    assert_eq!((csp.running_bits(), ip.running_bits()), (0, 0x10));
}

#[test]
fn the_ip_configuration_is_written_by_sdo_in_order() {
    let mut csp = Bench::plain();
    csp.run_until(|s| s.phase() == Phase::Enabling);
    let mut ip = Bench::with(Operation::InterpolatedPosition);
    ip.run_until(|s| s.phase() == Phase::Enabling);
    let (csp, ip) = (csp.sdo_requests(), ip.sdo_requests());
    assert_eq!(ip.len(), 20);
    // 6060h = 7, interpolated position: one byte (0x2F).
    assert_eq!(ip[2], [0x2F, 0x60, 0x60, 0, 7, 0, 0, 0]);
    assert_eq!(csp[2], [0x2F, 0x60, 0x60, 0, 8, 0, 0, 0]);
    // 60C2h as in CSP: the 2 ms cycle, 200 × 10⁻⁵ s.
    assert_eq!(ip[4], [0x2F, 0xC2, 0x60, 1, 200, 0, 0, 0]);
    assert_eq!(ip[5], [0x2F, 0xC2, 0x60, 2, (-5i8) as u8, 0, 0, 0]);
    // RPDO1: invalid, type 1, clear, 6040h/16, 60C1h sub-index 1/32, two entries,
    // valid.
    let value = |r: &[u8; 8]| u32::from_le_bytes([r[4], r[5], r[6], r[7]]);
    let rpdo: Vec<(u16, u8, u32)> = ip[6..13]
        .iter()
        .map(|r| (u16::from_le_bytes([r[1], r[2]]), r[3], value(r)))
        .collect();
    assert_eq!(
        rpdo,
        [
            (0x1400, 1, 0x8000_0201),
            (0x1400, 2, 1),
            (0x1600, 0, 0),
            (0x1600, 1, 0x6040_0010),
            (0x1600, 2, 0x60C1_0120),
            (0x1600, 0, 2),
            (0x1400, 1, 0x0000_0201),
        ]
    );
    assert_eq!(value(&csp[10]), 0x607A_0020);
    // The rest as CSP writes it: device type, heartbeat, window, period, TPDO1.
    for k in (0..20).filter(|k| ![2, 10].contains(k)) {
        assert_eq!(ip[k], csp[k], "request {k}");
    }
}

#[test]
fn configuration_failures_stop_before_anything_moves() {
    // A device that is not CiA 402 (0191h).
    let mut bench = Bench::plain();
    bench.tamper = Some(Box::new(|f: CanFrame| {
        Some(
            if f.id().raw() == 0x581 && f.data()[..4] == [0x43, 0x00, 0x10, 0x00] {
                std(0x581, &[0x43, 0x00, 0x10, 0x00, 0x91, 0x01, 0x02, 0x00])
            } else {
                f
            },
        )
    }));
    bench.run_to_end();
    let reason = bench.stopped().unwrap();
    assert_eq!(
        *reason,
        StopReason::DeviceType {
            node: node(1),
            axis: Axis::X,
            device_type: 0x0002_0191
        }
    );
    assert_eq!(
        reason.to_string(),
        "node 1 (X) is not a CiA 402 drive: device type 0x00020191 (1000h)"
    );
    assert_eq!(bench.halted(), Some(&vec![]));
    assert!(bench.sent.iter().all(|(_, f)| f.id().raw() != 0x080));
    // A server abort: node 2 refuses 6060h.
    let mut bench = Bench::plain();
    bench.tamper = Some(Box::new(|f: CanFrame| {
        Some(if f.id().raw() == 0x582 && f.data()[1..3] == [0x60, 0x60] {
            std(0x582, &[0x80, 0x60, 0x60, 0x00, 0x30, 0x00, 0x09, 0x06])
        } else {
            f
        })
    }));
    bench.run_to_end();
    let reason = bench.stopped().unwrap();
    assert_eq!(
        reason.to_string(),
        "configuration failed: node 2 aborted SDO 6060h/00h: 0x06090030 (Invalid value for \
         parameter (download only))"
    );
    // No answer from node 3's SDO server: a timeout, and the client's abort.
    let mut bench = Bench::plain();
    bench.tamper = Some(Box::new(|f: CanFrame| (f.id().raw() != 0x583).then_some(f)));
    bench.run_to_end();
    assert!(matches!(
        bench.stopped(),
        Some(StopReason::Sdo(SdoError::Timeout { index: 0x1000, .. }))
    ));
    let abort = bench.sent.last().unwrap().1;
    assert_eq!(
        abort,
        std(0x603, &[0x80, 0x00, 0x10, 0x00, 0x00, 0x00, 0x04, 0x05])
    );
}

#[test]
fn impossible_configurations_are_refused() {
    let sp = || setpoints(Position::known(0.0, 0.0, 0.0));
    let cases = [
        (
            SessionConfig {
                nodes: [node(1), node(2), node(1)],
                ..config()
            },
            "CAN session: nodes: 1, 2, 1 are not three nodes",
        ),
        (
            SessionConfig {
                heartbeat_ms: 0,
                ..config()
            },
            "CAN session: heartbeat_ms: 0 switches the heartbeat off",
        ),
        (
            SessionConfig {
                heartbeat_timeout: 10 * MS,
                ..config()
            },
            "CAN session: heartbeat_timeout: 10ms is not longer than the producer's 10ms",
        ),
    ];
    for (config, message) in cases {
        assert_eq!(Session::new(config, sp()).unwrap_err().to_string(), message);
    }
    // 60C2h holds a cycle as at most 255 × 10^index s, whole microseconds.
    for (period, shown) in [
        (Duration::ZERO, "0ns"),
        (Duration::from_micros(2561), "2.561ms"),
    ] {
        let mut odd = sp();
        odd.period = period;
        assert_eq!(
            Session::new(config(), odd).unwrap_err().to_string(),
            format!(
                "CAN session: setpoints.period: {shown} is not a cycle 60C2h holds \
                 (value ≤ 255 × 10^index s, whole µs)"
            )
        );
    }
}
