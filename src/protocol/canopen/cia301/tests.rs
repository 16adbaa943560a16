//! Tests of the CiA 301 framing, kept apart from it for length: COB-IDs, NMT, heartbeats,
//! emergencies, the expedited SDO client and its aborts, and PDO mapping.

use super::*;

fn node(id: u8) -> NodeId {
    NodeId::new(id).unwrap()
}

fn pdo(n: u8) -> PdoNumber {
    PdoNumber::new(n).unwrap()
}

fn frame(id: u16, data: &[u8]) -> CanFrame {
    CanFrame::standard(id, data).unwrap()
}

const MS: Duration = Duration::from_millis(1);

#[test]
fn node_and_pdo_numbers_are_range_checked() {
    assert_eq!(NodeId::new(0), Err(CanopenError::NodeId(0)));
    assert_eq!(NodeId::new(128), Err(CanopenError::NodeId(128)));
    assert_eq!(node(127).get(), 127);
    assert_eq!(PdoNumber::new(0), Err(CanopenError::PdoNumber(0)));
    assert_eq!(PdoNumber::new(5), Err(CanopenError::PdoNumber(5)));
    assert_eq!(node(3).to_string(), "3");
}

#[test]
fn cob_ids_are_the_predefined_connection_set() {
    let n = node(2);
    assert_eq!((cob::NMT, cob::SYNC, cob::TIME), (0x000, 0x080, 0x100));
    assert_eq!(cob::emcy(n), 0x082);
    let tpdos: Vec<u16> = (1..=4).map(|k| cob::tpdo(pdo(k), n)).collect();
    assert_eq!(tpdos, [0x182, 0x282, 0x382, 0x482]);
    let rpdos: Vec<u16> = (1..=4).map(|k| cob::rpdo(pdo(k), n)).collect();
    assert_eq!(rpdos, [0x202, 0x302, 0x402, 0x502]);
    assert_eq!(cob::sdo_response(n), 0x582);
    assert_eq!(cob::sdo_request(n), 0x602);
    assert_eq!(cob::heartbeat(n), 0x702);
}

#[test]
fn classify_inverts_the_cob_ids() {
    let n = node(3);
    assert_eq!(Cob::classify(0x000), Cob::Nmt);
    assert_eq!(Cob::classify(0x080), Cob::Sync);
    assert_eq!(Cob::classify(0x100), Cob::Time);
    assert_eq!(Cob::classify(cob::emcy(n)), Cob::Emcy(n));
    for k in 1..=4 {
        assert_eq!(Cob::classify(cob::tpdo(pdo(k), n)), Cob::Tpdo(pdo(k), n));
        assert_eq!(Cob::classify(cob::rpdo(pdo(k), n)), Cob::Rpdo(pdo(k), n));
    }
    assert_eq!(Cob::classify(0x583), Cob::SdoResponse(n));
    assert_eq!(Cob::classify(0x603), Cob::SdoRequest(n));
    assert_eq!(Cob::classify(0x703), Cob::Heartbeat(n));
    // LSS (0x7E4/0x7E5), node 0 of per-node objects, unused function code 13.
    for id in [0x7E5, 0x580, 0x700, 0x683, 0x180] {
        assert_eq!(Cob::classify(id), Cob::Other(id));
    }
}

#[test]
fn nmt_commands_are_two_bytes_on_0x000() {
    let table = [
        (NmtCommand::Start, 0x01),
        (NmtCommand::Stop, 0x02),
        (NmtCommand::EnterPreOperational, 0x80),
        (NmtCommand::ResetNode, 0x81),
        (NmtCommand::ResetCommunication, 0x82),
    ];
    for (command, cs) in table {
        assert_eq!(command.frame(Some(node(2))), frame(0x000, &[cs, 2]));
    }
    assert_eq!(NmtCommand::Start.frame(None), frame(0x000, &[0x01, 0x00]));
    assert_eq!(sync_frame(), frame(0x080, &[]));
}

#[test]
fn heartbeats_decode_every_state() {
    let table = [
        (0x00, NmtState::BootUp),
        (0x04, NmtState::Stopped),
        (0x05, NmtState::Operational),
        (0x7F, NmtState::PreOperational),
    ];
    for (byte, state) in table {
        let got = decode_heartbeat(&frame(0x701, &[byte])).unwrap();
        assert_eq!(
            got,
            Heartbeat {
                node: node(1),
                state
            }
        );
        assert_eq!(state.byte(), byte);
    }
}

#[test]
fn heartbeat_errors() {
    assert_eq!(
        decode_heartbeat(&frame(0x701, &[0x06])),
        Err(CanopenError::HeartbeatState { node: 1, byte: 6 })
    );
    assert_eq!(
        decode_heartbeat(&frame(0x701, &[0x05, 0x00])),
        Err(CanopenError::Length {
            what: "heartbeat",
            expected: 1,
            found: 2
        })
    );
    let guard_request = CanFrame::remote(CanId::Standard(0x701), 1).unwrap();
    let wrong = [guard_request, frame(0x581, &[0x05]), frame(0x700, &[0x05])];
    for bad in wrong {
        assert!(matches!(
            decode_heartbeat(&bad),
            Err(CanopenError::NotA { .. })
        ));
    }
    assert_eq!(
        decode_heartbeat(&frame(0x281, &[0]))
            .unwrap_err()
            .to_string(),
        "frame 281#00 is not a heartbeat"
    );
}

#[test]
fn emergency_messages_decode() {
    // CiA 402's following error 8611h, error register bit 0 (generic), then
    // manufacturer bytes.
    let emcy = decode_emcy(&frame(0x083, &[0x11, 0x86, 0x01, 1, 2, 3, 4, 5])).unwrap();
    assert_eq!(
        emcy,
        Emergency {
            node: node(3),
            code: 0x8611,
            register: 0x01,
            manufacturer: [1, 2, 3, 4, 5]
        }
    );
    assert!(!emcy.is_reset());
    assert_eq!(emcy.class(), "monitoring");
    let reset = decode_emcy(&frame(0x083, &[0; 8])).unwrap();
    assert!(reset.is_reset());
    assert_eq!(reset.class(), "error reset or no error");
    assert_eq!(
        decode_emcy(&frame(0x083, &[0; 3])),
        Err(CanopenError::Length {
            what: "emergency message",
            expected: 8,
            found: 3
        })
    );
    assert!(matches!(
        decode_emcy(&frame(0x080, &[0; 8])),
        Err(CanopenError::NotA { .. })
    ));
}

#[test]
fn emergency_classes_follow_the_code_table() {
    let class = |code| {
        let data = u16::to_le_bytes(code);
        decode_emcy(&frame(0x081, &[data[0], data[1], 0, 0, 0, 0, 0, 0]))
            .unwrap()
            .class()
    };
    assert_eq!(class(0x1000), "generic error");
    assert_eq!(class(0x2310), "current");
    assert_eq!(class(0x3210), "voltage");
    assert_eq!(class(0x4210), "temperature");
    assert_eq!(class(0x5000), "device hardware");
    assert_eq!(class(0x6100), "device software");
    assert_eq!(class(0x7300), "additional modules");
    assert_eq!(class(0x8130), "communication");
    assert_eq!(class(0x8210), "protocol error");
    assert_eq!(class(0x9000), "external error");
    assert_eq!(class(0xF000), "additional functions");
    assert_eq!(class(0xFF01), "device specific");
    assert_eq!(class(0xA000), "reserved");
}

#[test]
fn expedited_downloads_encode_their_size() {
    // CiA 301: initiate download with e = s = 1 and n = 4 − size: 0x2F, 0x2B, 0x27, 0x23.
    for (data, command) in [
        (&[0x08][..], 0x2F),
        (&[0x0F, 0x00][..], 0x2B),
        (&[1, 2, 3][..], 0x27),
        (&[0xE8, 0x03, 0, 0][..], 0x23),
    ] {
        let mut client = SdoClient::new(node(1), 50 * MS);
        client.download(0x6060, 0, data, Duration::ZERO).unwrap();
        let sent = client.transmit().unwrap();
        assert_eq!(sent.id(), CanId::Standard(0x601));
        assert_eq!(&sent.data()[..4], &[command, 0x60, 0x60, 0x00]);
        assert_eq!(&sent.data()[4..4 + data.len()], data);
        assert!(sent.data()[4 + data.len()..].iter().all(|b| *b == 0));
        let done = client.receive(&frame(0x581, &[0x60, 0x60, 0x60, 0, 0, 0, 0, 0]));
        assert_eq!(
            done,
            Some(Ok(SdoDone::Downloaded {
                index: 0x6060,
                sub: 0
            }))
        );
        assert!(!client.is_busy());
    }
}

#[test]
fn expedited_uploads_return_the_indicated_bytes() {
    let mut client = SdoClient::new(node(2), 50 * MS);
    for (command, expected) in [
        (0x4F, &[0x37][..]),
        (0x4B, &[0x37, 0x06][..]),
        (0x47, &[0x37, 0x06, 0x01][..]),
        (0x43, &[0x37, 0x06, 0x01, 0x02][..]),
        // e = 1, s = 0: size not indicated, all four bytes.
        (0x42, &[0x37, 0x06, 0x01, 0x02][..]),
    ] {
        client.upload(0x6041, 0, Duration::ZERO).unwrap();
        assert_eq!(
            client.transmit(),
            Some(frame(0x602, &[0x40, 0x41, 0x60, 0, 0, 0, 0, 0]))
        );
        let answer = frame(0x582, &[command, 0x41, 0x60, 0, 0x37, 0x06, 0x01, 0x02]);
        assert_eq!(
            client.receive(&answer),
            Some(Ok(SdoDone::Uploaded {
                index: 0x6041,
                sub: 0,
                data: expected.to_vec()
            }))
        );
    }
}

#[test]
fn a_server_abort_is_reported_with_its_meaning() {
    let mut client = SdoClient::new(node(1), 50 * MS);
    client.download(0x6041, 0, &[0, 0], Duration::ZERO).unwrap();
    client.transmit();
    let abort = frame(0x581, &[0x80, 0x41, 0x60, 0x00, 0x02, 0x00, 0x01, 0x06]);
    let err = client.receive(&abort).unwrap().unwrap_err();
    assert_eq!(
        err,
        SdoError::Aborted {
            node: node(1),
            index: 0x6041,
            sub: 0,
            code: AbortCode::READ_ONLY
        }
    );
    assert_eq!(
        err.to_string(),
        "node 1 aborted SDO 6041h/00h: 0x06010002 (Attempt to write a read only object)"
    );
    // The server aborted, so the client sends nothing back.
    assert_eq!(client.transmit(), None);
}

#[test]
fn abort_codes_carry_cia_301_meanings() {
    assert_eq!(
        AbortCode::NO_OBJECT.meaning(),
        Some("Object does not exist in the object dictionary")
    );
    assert_eq!(
        AbortCode::NO_SUB.meaning(),
        Some("Sub-index does not exist")
    );
    assert_eq!(
        AbortCode(0x0607_0010).meaning(),
        Some("Data type does not match, length of service parameter does not match")
    );
    assert_eq!(
        AbortCode(0x0604_0041).meaning(),
        Some("Object cannot be mapped to the PDO")
    );
    assert_eq!(AbortCode(0x1234_5678).meaning(), None);
    assert_eq!(
        AbortCode(0x1234_5678).to_string(),
        "0x12345678 (not a CiA 301 code)"
    );
}

#[test]
fn a_timeout_fails_the_transfer_and_aborts_it() {
    let mut client = SdoClient::new(node(3), 20 * MS);
    let start = Duration::from_secs(5);
    client.upload(0x6064, 0, start).unwrap();
    client.transmit();
    assert_eq!(client.poll(start + 19 * MS), None);
    assert!(client.is_busy());
    assert_eq!(
        client.poll(start + 20 * MS),
        Some(SdoError::Timeout {
            node: node(3),
            index: 0x6064,
            sub: 0,
            timeout: 20 * MS
        })
    );
    // Abort 0x05040000 "SDO protocol timed out", little-endian.
    assert_eq!(
        client.transmit(),
        Some(frame(0x603, &[0x80, 0x64, 0x60, 0, 0x00, 0x00, 0x04, 0x05]))
    );
    assert_eq!(client.poll(start + 40 * MS), None);
    // A late answer is ignored, and the client is free again.
    let late = frame(0x583, &[0x43, 0x64, 0x60, 0, 1, 0, 0, 0]);
    assert_eq!(client.receive(&late), None);
    assert!(client.upload(0x6064, 0, start + 40 * MS).is_ok());
}

#[test]
fn one_transfer_at_a_time_and_expedited_sizes_only() {
    let mut client = SdoClient::new(node(1), 20 * MS);
    assert_eq!(
        client.download(0x607A, 0, &[], Duration::ZERO),
        Err(SdoError::Size(0))
    );
    assert_eq!(
        client.download(0x607A, 0, &[0; 5], Duration::ZERO),
        Err(SdoError::Size(5))
    );
    assert!(!client.is_busy());
    client.upload(0x6041, 0, Duration::ZERO).unwrap();
    assert_eq!(
        client.upload(0x6064, 0, Duration::ZERO),
        Err(SdoError::Busy { node: node(1) })
    );
    assert_eq!(
        client.download(0x6040, 0, &[6, 0], Duration::ZERO),
        Err(SdoError::Busy { node: node(1) })
    );
}

#[test]
fn frames_for_others_are_not_taken() {
    let mut client = SdoClient::new(node(1), 20 * MS);
    client.upload(0x6041, 0, Duration::ZERO).unwrap();
    let answer = [0x4B, 0x41, 0x60, 0, 0x37, 0x06, 0, 0];
    assert_eq!(client.receive(&frame(0x582, &answer)), None);
    assert_eq!(client.receive(&frame(0x601, &answer)), None);
    let ext = CanFrame::new(CanId::Extended(0x581), &answer).unwrap();
    assert_eq!(client.receive(&ext), None);
    assert!(client.is_busy());
    assert!(client.receive(&frame(0x581, &answer)).is_some());
}

#[test]
fn protocol_violations_abort_with_a_reason() {
    let cases: [(bool, Vec<u8>, AbortCode, &str); 5] = [
        (
            false,
            vec![0x60, 0x40, 0x60],
            AbortCode::GENERAL,
            "response of 3 bytes, SDO frames have 8",
        ),
        (
            false,
            vec![0x43, 0x40, 0x60, 0, 0, 0, 0, 0],
            AbortCode::COMMAND,
            "server command specifier 2, expected 3",
        ),
        (
            true,
            vec![0x60, 0x40, 0x60, 0, 0, 0, 0, 0],
            AbortCode::COMMAND,
            "server command specifier 3, expected 2",
        ),
        (
            false,
            vec![0x60, 0x41, 0x60, 0, 0, 0, 0, 0],
            AbortCode::GENERAL,
            "response for 6041h/00h",
        ),
        (
            true,
            vec![0x41, 0x40, 0x60, 0, 20, 0, 0, 0],
            AbortCode::GENERAL,
            "segmented upload, which this client does not implement",
        ),
    ];
    for (upload, answer, code, reason) in cases {
        let mut client = SdoClient::new(node(1), 20 * MS);
        if upload {
            client.upload(0x6040, 0, Duration::ZERO).unwrap();
        } else {
            client.download(0x6040, 0, &[6, 0], Duration::ZERO).unwrap();
        }
        client.transmit();
        let err = client.receive(&frame(0x581, &answer)).unwrap().unwrap_err();
        assert_eq!(
            err,
            SdoError::Protocol {
                node: node(1),
                index: 0x6040,
                sub: 0,
                reason: reason.to_string(),
                code
            }
        );
        let mut abort = vec![0x80, 0x40, 0x60, 0];
        abort.extend_from_slice(&code.0.to_le_bytes());
        assert_eq!(client.transmit(), Some(frame(0x601, &abort)));
        assert!(!client.is_busy());
    }
}

#[test]
fn typed_writes_are_little_endian() {
    assert_eq!(SdoWrite::u8(0x6060, 0, 8).data, [8]);
    assert_eq!(SdoWrite::u16(0x1017, 0, 100).data, [100, 0]);
    assert_eq!(SdoWrite::u32(0x6065, 0, 0x0102_0304).data, [4, 3, 2, 1]);
    assert_eq!(SdoWrite::i32(0x607A, 0, -2).data, [0xFE, 0xFF, 0xFF, 0xFF]);
    // 1016h: node 1 watched with 250 ms → 0x000100FA.
    assert_eq!(heartbeat_consumer_entry(node(1), 250), 0x0001_00FA);
}

#[test]
fn a_tpdo_mapping_follows_the_procedure() {
    // TPDO1 of node 2 carrying statusword 6041h (16 bits) and position actual
    // 6064h (32 bits), sent every SYNC.
    let config = PdoConfig {
        direction: PdoDirection::Transmit,
        number: pdo(1),
        transmission: EVERY_SYNC,
        entries: vec![
            MapEntry {
                index: 0x6041,
                sub: 0,
                bits: 16,
            },
            MapEntry {
                index: 0x6064,
                sub: 0,
                bits: 32,
            },
        ],
    };
    let writes = pdo_mapping(node(2), &config).unwrap();
    assert_eq!(
        writes,
        vec![
            SdoWrite::u32(0x1800, 1, 0xC000_0182),
            SdoWrite::u8(0x1800, 2, 1),
            SdoWrite::u8(0x1A00, 0, 0),
            SdoWrite::u32(0x1A00, 1, 0x6041_0010),
            SdoWrite::u32(0x1A00, 2, 0x6064_0020),
            SdoWrite::u8(0x1A00, 0, 2),
            SdoWrite::u32(0x1800, 1, 0x4000_0182),
        ]
    );
}

#[test]
fn an_rpdo_mapping_uses_the_receive_objects() {
    let config = PdoConfig {
        direction: PdoDirection::Receive,
        number: pdo(2),
        transmission: EVERY_SYNC,
        entries: vec![MapEntry {
            index: 0x607A,
            sub: 0,
            bits: 32,
        }],
    };
    let writes = pdo_mapping(node(3), &config).unwrap();
    assert_eq!(writes[0], SdoWrite::u32(0x1401, 1, 0x8000_0303));
    assert_eq!(writes[2], SdoWrite::u8(0x1601, 0, 0));
    assert_eq!(writes[3], SdoWrite::u32(0x1601, 1, 0x607A_0020));
    assert_eq!(writes[5], SdoWrite::u32(0x1401, 1, 0x0000_0303));
}

#[test]
fn impossible_mappings_are_refused() {
    let mut config = PdoConfig {
        direction: PdoDirection::Receive,
        number: pdo(1),
        transmission: EVERY_SYNC,
        entries: vec![],
    };
    assert_eq!(
        pdo_mapping(node(1), &config),
        Err(CanopenError::EmptyMapping)
    );
    config.entries = vec![
        MapEntry {
            index: 0x607A,
            sub: 0,
            bits: 32
        };
        3
    ];
    assert_eq!(
        pdo_mapping(node(1), &config),
        Err(CanopenError::MappingBits(96))
    );
    config.entries = vec![MapEntry {
        index: 0x6040,
        sub: 0,
        bits: 0,
    }];
    assert_eq!(
        pdo_mapping(node(1), &config),
        Err(CanopenError::ZeroWidth {
            index: 0x6040,
            sub: 0
        })
    );
    config.entries = vec![MapEntry {
        index: 0x6040,
        sub: 0,
        bits: 16,
    }];
    for reserved in [241, 251] {
        config.transmission = reserved;
        assert_eq!(
            pdo_mapping(node(1), &config),
            Err(CanopenError::TransmissionType(reserved))
        );
    }
    for fine in [0, 240, 252, 255] {
        config.transmission = fine;
        assert!(pdo_mapping(node(1), &config).is_ok());
    }
}
