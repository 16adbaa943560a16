//! Tests of the drive, kept apart from it for length: NMT and heartbeat, the SDO server,
//! the power state machine, PDOs and their mapping, CSP and interpolated position cycles,
//! following errors, software limits and wrapping positions, all through frames.

use super::*;

const MS: Duration = Duration::from_millis(1);

fn booted(config: DriveConfig) -> Drive {
    let mut drive = Drive::new(config).unwrap();
    drive.take_output();
    drive.take_events();
    drive
}

/// Node 1, started (Operational), output drained.
fn operational() -> Drive {
    let mut drive = booted(DriveConfig::new(1));
    drive.receive(&Frame::data(0x000, &[0x01, 0x01]));
    drive.take_output();
    drive
}

/// Sends an SDO request to node 1 and returns the 8 answer bytes, if any.
fn sdo(drive: &mut Drive, request: [u8; 8]) -> Option<Vec<u8>> {
    drive.receive(&Frame::data(0x601, &request));
    let answers: Vec<Frame> = drive
        .take_output()
        .into_iter()
        .filter(|f| f.id == 0x581)
        .collect();
    assert!(answers.len() <= 1);
    answers.into_iter().next().map(|f| f.data)
}

/// Expedited download of `size` bytes of `value`; `Err(abort code)` on abort.
fn write(drive: &mut Drive, index: u16, sub: u8, value: u32, size: u8) -> Result<(), u32> {
    let [lo, hi] = index.to_le_bytes();
    let v = value.to_le_bytes();
    let command = 0x23 | ((4 - size) << 2);
    let answer = sdo(drive, [command, lo, hi, sub, v[0], v[1], v[2], v[3]]).unwrap();
    match answer[0] {
        0x60 => {
            assert_eq!(answer, [0x60, lo, hi, sub, 0, 0, 0, 0]);
            Ok(())
        }
        0x80 => Err(u32::from_le_bytes([
            answer[4], answer[5], answer[6], answer[7],
        ])),
        other => panic!("answer {other:02X}"),
    }
}

/// Expedited upload: (command byte, value) or `Err(abort code)`.
fn read(drive: &mut Drive, index: u16, sub: u8) -> Result<(u8, u32), u32> {
    let [lo, hi] = index.to_le_bytes();
    let answer = sdo(drive, [0x40, lo, hi, sub, 0, 0, 0, 0]).unwrap();
    let value = u32::from_le_bytes([answer[4], answer[5], answer[6], answer[7]]);
    if answer[0] == 0x80 {
        Err(value)
    } else {
        Ok((answer[0], value))
    }
}

fn sync(drive: &mut Drive) -> Vec<Frame> {
    drive.receive(&Frame::data(0x080, &[]));
    drive.take_output()
}

/// RPDO1 with controlword and target, as mapped at power-up.
fn rpdo1(drive: &mut Drive, controlword: u16, target: i32) {
    let mut data = controlword.to_le_bytes().to_vec();
    data.extend_from_slice(&target.to_le_bytes());
    drive.receive(&Frame::data(0x201, &data));
}

/// Walks to Operation enabled in CSP through RPDO1 on SYNC.
fn enabled() -> Drive {
    let mut drive = operational();
    write(&mut drive, 0x6060, 0, 8, 1).unwrap();
    for word in [0x06, 0x07, 0x0F] {
        rpdo1(&mut drive, word, 0);
        sync(&mut drive);
    }
    assert_eq!(drive.power_state(), PowerState::OperationEnabled);
    drive
}

/// Node 1 in interpolated position mode with RPDO1 remapped to controlword and
/// 60C1h sub-index 1 (CiA 301's procedure), started; output drained.
fn interpolating(config: DriveConfig) -> Drive {
    let mut drive = booted(config);
    write(&mut drive, 0x6060, 0, 7, 1).unwrap();
    write(&mut drive, 0x1400, 1, 0x8000_0201, 4).unwrap();
    write(&mut drive, 0x1600, 0, 0, 1).unwrap();
    write(&mut drive, 0x1600, 1, 0x6040_0010, 4).unwrap();
    write(&mut drive, 0x1600, 2, 0x60C1_0120, 4).unwrap();
    write(&mut drive, 0x1600, 0, 2, 1).unwrap();
    write(&mut drive, 0x1400, 1, 0x0000_0201, 4).unwrap();
    drive.receive(&Frame::data(0x000, &[0x01, 0x01]));
    drive.take_output();
    drive
}

/// The (set-point, actual) of each control cycle since the last call.
fn cycles(drive: &mut Drive) -> Vec<(i32, i32)> {
    drive
        .take_events()
        .into_iter()
        .filter_map(|e| match e {
            DriveEvent::Cycle { target, actual, .. } => Some((target, actual)),
            _ => None,
        })
        .collect()
}

#[test]
fn power_up_sends_boot_up_and_waits_pre_operational() {
    let mut drive = Drive::new(DriveConfig::new(3)).unwrap();
    // CiA 301: boot-up is one byte 0x00 on 0x700 + node.
    assert_eq!(drive.take_output(), [Frame::data(0x703, &[0x00])]);
    assert_eq!(drive.nmt_state(), NmtState::PreOperational);
    // CiA 402: Not ready to switch on and on to Switch on disabled by itself.
    assert_eq!(drive.power_state(), PowerState::SwitchOnDisabled);
    assert_eq!(drive.statusword(), 0x0250);
    assert_eq!(
        drive.take_events(),
        [
            DriveEvent::Power {
                time: Duration::ZERO,
                state: PowerState::SwitchOnDisabled
            },
            DriveEvent::Nmt {
                time: Duration::ZERO,
                state: NmtState::PreOperational
            },
        ]
    );
    assert_eq!(
        Drive::new(DriveConfig::new(0)).unwrap_err(),
        DriveConfigError::NodeId(0)
    );
    assert!(Drive::new(DriveConfig::new(128)).is_err());
    assert!(Drive::new(DriveConfig::new(127)).is_ok());
}

#[test]
fn nmt_commands_move_the_node() {
    let mut drive = booted(DriveConfig::new(2));
    // For another node, the wrong length, an unknown specifier: nothing.
    for data in [
        &[0x01, 0x03][..],
        &[0x01],
        &[0x01, 0x02, 0x00],
        &[0x03, 0x02],
    ] {
        drive.receive(&Frame::data(0x000, data));
        assert_eq!(drive.nmt_state(), NmtState::PreOperational);
    }
    drive.receive(&Frame::data(0x000, &[0x01, 0x02]));
    assert_eq!(drive.nmt_state(), NmtState::Operational);
    drive.receive(&Frame::data(0x000, &[0x02, 0x00])); // all nodes
    assert_eq!(drive.nmt_state(), NmtState::Stopped);
    drive.receive(&Frame::data(0x000, &[0x80, 0x02]));
    assert_eq!(drive.nmt_state(), NmtState::PreOperational);
    drive.receive(&Frame::data(0x000, &[0x01, 0x00]));
    assert_eq!(drive.nmt_state(), NmtState::Operational);
    // Reset communication: boot-up again, Pre-operational.
    drive.take_output();
    drive.receive(&Frame::data(0x000, &[0x82, 0x02]));
    assert_eq!(drive.take_output(), [Frame::data(0x702, &[0x00])]);
    assert_eq!(drive.nmt_state(), NmtState::PreOperational);
}

#[test]
fn resets_restore_their_objects() {
    let mut drive = booted(DriveConfig::new(1));
    write(&mut drive, 0x1017, 0, 100, 2).unwrap();
    write(&mut drive, 0x6060, 0, 8, 1).unwrap();
    write(&mut drive, 0x6040, 0, 0x06, 2).unwrap();
    write(&mut drive, 0x1800, 1, 0xC000_0181, 4).unwrap();
    // Reset communication: 1017h and the PDOs, not the profile's objects.
    drive.receive(&Frame::data(0x000, &[0x82, 0x01]));
    drive.take_output();
    assert_eq!(read(&mut drive, 0x1017, 0), Ok((0x4B, 0)));
    assert_eq!(read(&mut drive, 0x1800, 1), Ok((0x43, 0x4000_0181)));
    assert_eq!(read(&mut drive, 0x6060, 0), Ok((0x4F, 8)));
    assert_eq!(drive.power_state(), PowerState::ReadyToSwitchOn);
    // Reset node: the profile's objects too.
    drive.receive(&Frame::data(0x000, &[0x81, 0x01]));
    assert_eq!(drive.take_output(), [Frame::data(0x701, &[0x00])]);
    assert_eq!(read(&mut drive, 0x6060, 0), Ok((0x4F, 0)));
    assert_eq!(read(&mut drive, 0x6040, 0), Ok((0x4B, 0)));
    assert_eq!(drive.power_state(), PowerState::SwitchOnDisabled);
}

#[test]
fn heartbeats_follow_1017h() {
    let mut drive = booted(DriveConfig::new(1));
    drive.advance(Duration::from_secs(10));
    assert!(drive.take_output().is_empty(), "1017h = 0: no heartbeat");
    write(&mut drive, 0x1017, 0, 100, 2).unwrap();
    drive.advance(250 * MS);
    // At 10.1 s and 10.2 s, the Pre-operational byte 0x7F.
    assert_eq!(drive.take_output(), vec![Frame::data(0x701, &[0x7F]); 2]);
    drive.receive(&Frame::data(0x000, &[0x01, 0x01]));
    drive.take_output();
    drive.advance(50 * MS);
    assert_eq!(drive.take_output(), [Frame::data(0x701, &[0x05])]);
    drive.receive(&Frame::data(0x000, &[0x02, 0x01]));
    drive.advance(100 * MS);
    assert_eq!(drive.take_output(), [Frame::data(0x701, &[0x04])]);
    assert_eq!(drive.now(), Duration::from_millis(10_400));
    // A configured power-on period starts at boot-up.
    let mut beating = booted(DriveConfig {
        heartbeat_ms: 20,
        ..DriveConfig::new(4)
    });
    beating.advance(19 * MS);
    assert!(beating.take_output().is_empty());
    beating.advance(MS);
    assert_eq!(beating.take_output(), [Frame::data(0x704, &[0x7F])]);
}

#[test]
fn stopped_serves_no_sdo_and_no_sync() {
    let mut drive = operational();
    drive.receive(&Frame::data(0x000, &[0x02, 0x01]));
    assert_eq!(sdo(&mut drive, [0x40, 0x41, 0x60, 0, 0, 0, 0, 0]), None);
    assert!(sync(&mut drive).is_empty());
}

#[test]
fn uploads_answer_with_the_objects_size() {
    let mut drive = booted(DriveConfig {
        position: -5,
        ..DriveConfig::new(1)
    });
    // n = 4 − size in bits 3–2: 0x43 four bytes, 0x4B two, 0x4F one.
    assert_eq!(read(&mut drive, 0x1000, 0), Ok((0x43, 0x0002_0192)));
    assert_eq!(read(&mut drive, 0x1001, 0), Ok((0x4F, 0)));
    assert_eq!(read(&mut drive, 0x6041, 0), Ok((0x4B, 0x0250)));
    assert_eq!(read(&mut drive, 0x6061, 0), Ok((0x4F, 0)));
    assert_eq!(read(&mut drive, 0x6064, 0), Ok((0x43, -5i32 as u32)));
    assert_eq!(read(&mut drive, 0x607A, 0), Ok((0x43, -5i32 as u32)));
    assert_eq!(read(&mut drive, 0x6065, 0), Ok((0x43, 10_000)));
    assert_eq!(read(&mut drive, 0x1400, 0), Ok((0x4F, 2)));
    assert_eq!(read(&mut drive, 0x1400, 1), Ok((0x43, 0x201)));
    assert_eq!(read(&mut drive, 0x1401, 1), Ok((0x43, 0x8000_0301)));
    assert_eq!(read(&mut drive, 0x1800, 2), Ok((0x4F, 1)));
    assert_eq!(read(&mut drive, 0x1600, 0), Ok((0x4F, 2)));
    assert_eq!(read(&mut drive, 0x1600, 2), Ok((0x43, 0x607A_0020)));
    assert_eq!(read(&mut drive, 0x1A00, 1), Ok((0x43, 0x6041_0010)));
    assert_eq!(read(&mut drive, 0x1A03, 0), Ok((0x4F, 0)));
}

#[test]
fn the_identity_object_is_there_read_only() {
    // CiA 301 makes 1018h mandatory: sub-index 0 the highest sub-index (UNSIGNED8), 1–4
    // vendor-ID, product code, revision number, serial number (UNSIGNED32 each). A master
    // (python-canopen's `sdo[0x1018]`) reads it to tell which device it found.
    let mut drive = booted(DriveConfig::new(1));
    assert_eq!(read(&mut drive, 0x1018, 0), Ok((0x4F, 4)));
    assert_eq!(read(&mut drive, 0x1018, 1), Ok((0x43, 0)));
    assert_eq!(read(&mut drive, 0x1018, 2), Ok((0x43, 402)));
    assert_eq!(read(&mut drive, 0x1018, 3), Ok((0x43, 0x0001_0000)));
    assert_eq!(read(&mut drive, 0x1018, 4), Ok((0x43, 1)));
    assert_eq!(read(&mut drive, 0x1018, 5), Err(0x0609_0011));
    assert_eq!(write(&mut drive, 0x1018, 4, 1, 4), Err(0x0601_0002));
}

#[test]
fn sdo_aborts_carry_cia_301_codes() {
    let mut drive = booted(DriveConfig::new(1));
    assert_eq!(read(&mut drive, 0x2000, 0), Err(0x0602_0000));
    assert_eq!(read(&mut drive, 0x1404, 1), Err(0x0602_0000));
    assert_eq!(read(&mut drive, 0x6041, 1), Err(0x0609_0011));
    assert_eq!(read(&mut drive, 0x1800, 3), Err(0x0609_0011));
    assert_eq!(read(&mut drive, 0x1A00, 9), Err(0x0609_0011));
    assert_eq!(write(&mut drive, 0x6041, 0, 0, 2), Err(0x0601_0002));
    assert_eq!(write(&mut drive, 0x1000, 0, 0, 4), Err(0x0601_0002));
    assert_eq!(write(&mut drive, 0x1800, 0, 5, 1), Err(0x0601_0002));
    assert_eq!(write(&mut drive, 0x607A, 0, 0, 2), Err(0x0607_0013));
    assert_eq!(write(&mut drive, 0x6040, 0, 6, 4), Err(0x0607_0012));
    assert_eq!(write(&mut drive, 0x6060, 0, 1, 1), Err(0x0609_0030));
    assert_eq!(write(&mut drive, 0x6060, 0, 0xFF, 1), Err(0x0609_0030));
    // A segmented download (e = 0) and the segment services are not served.
    let segmented = [0x21, 0x7A, 0x60, 0, 4, 0, 0, 0];
    let upload_segment = [0x60, 0x7A, 0x60, 0, 0, 0, 0, 0];
    for request in [segmented, upload_segment] {
        assert_eq!(
            sdo(&mut drive, request),
            Some(vec![0x80, 0x7A, 0x60, 0, 0x01, 0x00, 0x04, 0x05])
        );
    }
    // A client's abort gets no answer; neither does a frame that is not 8 bytes.
    assert_eq!(sdo(&mut drive, [0x80, 0x7A, 0x60, 0, 0, 0, 0, 0x08]), None);
    drive.receive(&Frame::data(0x601, &[0x40, 0x41, 0x60, 0]));
    assert!(drive.take_output().is_empty());
}

#[test]
fn a_download_without_size_takes_the_objects_bytes() {
    let mut drive = booted(DriveConfig::new(1));
    // e = 1, s = 0: "unspecified number of bytes"; 607Ah takes all four.
    let answer = sdo(&mut drive, [0x22, 0x7A, 0x60, 0, 0x10, 0x27, 0, 0]);
    assert_eq!(answer, Some(vec![0x60, 0x7A, 0x60, 0, 0, 0, 0, 0]));
    assert_eq!(drive.target(), 10_000);
    // 6060h takes one: the bytes after it do not matter.
    sdo(&mut drive, [0x22, 0x60, 0x60, 0, 8, 0xAA, 0xBB, 0xCC]);
    assert_eq!(read(&mut drive, 0x6061, 0), Ok((0x4F, 8)));
}

#[test]
fn the_interpolation_period_is_60c2h_value_times_ten_to_the_index() {
    let mut drive = booted(DriveConfig::new(1));
    // Sub-index 0 holds the highest sub-index, 2; power-up 1 × 10⁻³ s. One byte each:
    // command 0x4F; the index −3 as INTEGER8 is FDh.
    assert_eq!(read(&mut drive, 0x60C2, 0), Ok((0x4F, 2)));
    assert_eq!(read(&mut drive, 0x60C2, 1), Ok((0x4F, 1)));
    assert_eq!(read(&mut drive, 0x60C2, 2), Ok((0x4F, 0xFD)));
    assert_eq!(drive.interpolation_period(), MS);
    let cases = [
        (4, -3, Duration::from_millis(4)),
        (25, -4, Duration::from_micros(2500)),
        (1, -6, Duration::from_micros(1)),
        (255, 0, Duration::from_secs(255)),
    ];
    for (value, index, period) in cases {
        write(&mut drive, 0x60C2, 1, value, 1).unwrap();
        write(&mut drive, 0x60C2, 2, u32::from(index as u8), 1).unwrap();
        assert_eq!(drive.interpolation_period(), period, "{value} × 10^{index}");
        assert_eq!(read(&mut drive, 0x60C2, 1), Ok((0x4F, value)));
        assert_eq!(
            read(&mut drive, 0x60C2, 2),
            Ok((0x4F, u32::from(index as u8)))
        );
    }
}

#[test]
fn impossible_interpolation_periods_are_refused() {
    let mut drive = booted(DriveConfig::new(1));
    write(&mut drive, 0x60C2, 1, 4, 1).unwrap();
    assert_eq!(write(&mut drive, 0x60C2, 0, 3, 1), Err(0x0601_0002));
    assert_eq!(read(&mut drive, 0x60C2, 3), Err(0x0609_0011));
    assert_eq!(write(&mut drive, 0x60C2, 3, 0, 1), Err(0x0609_0011));
    // Both are one byte.
    assert_eq!(write(&mut drive, 0x60C2, 1, 4, 2), Err(0x0607_0012));
    assert_eq!(write(&mut drive, 0x60C2, 2, 0xFD, 4), Err(0x0607_0012));
    // No period at all, or units above a second or below a microsecond.
    assert_eq!(write(&mut drive, 0x60C2, 1, 0, 1), Err(0x0609_0030));
    for index in [1i8, 63, -7, -128] {
        let byte = u32::from(index as u8);
        assert_eq!(write(&mut drive, 0x60C2, 2, byte, 1), Err(0x0609_0030));
    }
    assert_eq!(drive.interpolation_period(), Duration::from_millis(4));
}

#[test]
fn reset_node_restores_the_interpolation_period() {
    let mut drive = booted(DriveConfig::new(1));
    write(&mut drive, 0x60C2, 1, 4, 1).unwrap();
    // A profile object (6000h–9FFFh): reset communication keeps it, reset node does
    // not.
    drive.receive(&Frame::data(0x000, &[0x82, 0x01]));
    assert_eq!(drive.interpolation_period(), Duration::from_millis(4));
    drive.receive(&Frame::data(0x000, &[0x81, 0x01]));
    assert_eq!(drive.interpolation_period(), MS);
}

#[test]
fn the_power_state_machine_follows_the_controlword() {
    use PowerState::*;
    let mut drive = booted(DriveConfig::new(1));
    let mut step = |word: u32, expected: PowerState, statusword: u16| {
        write(&mut drive, 0x6040, 0, word, 2).unwrap();
        assert_eq!(drive.power_state(), expected, "after {word:02X}");
        assert_eq!(drive.statusword(), statusword, "after {word:02X}");
    };
    step(0x07, SwitchOnDisabled, 0x0250); // switch on is not transition 2
    step(0x06, ReadyToSwitchOn, 0x0231); // 2
    step(0x07, SwitchedOn, 0x0233); // 3
    step(0x0F, OperationEnabled, 0x0237); // 4 (no mode: bit 12 clear)
    step(0x07, SwitchedOn, 0x0233); // 5
    step(0x06, ReadyToSwitchOn, 0x0231); // 6
    step(0x00, SwitchOnDisabled, 0x0250); // 7
    step(0x06, ReadyToSwitchOn, 0x0231);
    step(0x0F, OperationEnabled, 0x0237); // 3 + 4
    step(0x06, ReadyToSwitchOn, 0x0231); // 8
    step(0x0F, OperationEnabled, 0x0237);
    step(0x00, SwitchOnDisabled, 0x0250); // 9
    step(0x06, ReadyToSwitchOn, 0x0231);
    step(0x07, SwitchedOn, 0x0233);
    step(0x02, SwitchOnDisabled, 0x0250); // 10
    step(0x06, ReadyToSwitchOn, 0x0231);
    step(0x0F, OperationEnabled, 0x0237);
    step(0x02, QuickStopActive, 0x0217); // 11
    step(0x06, QuickStopActive, 0x0217); // shutdown does not leave it
    step(0x0F, OperationEnabled, 0x0237); // 16
    step(0x0B, QuickStopActive, 0x0217); // quick stop with enable operation set
    step(0x00, SwitchOnDisabled, 0x0250); // 12
    step(0x86, SwitchOnDisabled, 0x0250); // bit 7 high: no command acts
}

#[test]
fn rpdo1_is_applied_at_sync_and_tpdo1_answers() {
    let mut drive = enabled();
    // Received between SYNCs, applied only at the next one; the last one wins.
    rpdo1(&mut drive, 0x0F, 300);
    rpdo1(&mut drive, 0x0F, 400);
    assert_eq!(drive.target(), 0);
    let frames = sync(&mut drive);
    assert_eq!(drive.target(), 400);
    assert_eq!(drive.position(), 400);
    // TPDO1: statusword 0x1237 (bit 12: following the target), position 400.
    assert_eq!(
        frames,
        [Frame::data(0x181, &[0x37, 0x12, 0x90, 0x01, 0, 0])]
    );
    // At most max_step (1000) counts a cycle.
    rpdo1(&mut drive, 0x0F, -2000);
    sync(&mut drive);
    assert_eq!(drive.position(), -600);
    sync(&mut drive);
    assert_eq!(drive.position(), -1600);
    let cycles: Vec<_> = drive
        .take_events()
        .into_iter()
        .filter_map(|e| match e {
            DriveEvent::Cycle { target, actual, .. } => Some((target, actual)),
            _ => None,
        })
        .collect();
    assert_eq!(
        cycles[cycles.len() - 3..],
        [(400, 400), (-2000, -600), (-2000, -1600)]
    );
}

#[test]
fn pdos_only_run_in_operational() {
    let mut drive = booted(DriveConfig::new(1));
    rpdo1(&mut drive, 0x06, 0);
    assert!(sync(&mut drive).is_empty(), "no TPDO in Pre-operational");
    assert_eq!(drive.power_state(), PowerState::SwitchOnDisabled);
    // An RPDO received in Operational but not applied is dropped on leaving it.
    drive.receive(&Frame::data(0x000, &[0x01, 0x01]));
    rpdo1(&mut drive, 0x06, 0);
    drive.receive(&Frame::data(0x000, &[0x80, 0x01]));
    drive.receive(&Frame::data(0x000, &[0x01, 0x01]));
    sync(&mut drive);
    assert_eq!(drive.power_state(), PowerState::SwitchOnDisabled);
    // SYNC with a counter byte is a SYNC; with more it is not.
    assert_eq!(drive.take_output().len(), 0);
    drive.receive(&Frame::data(0x080, &[7]));
    assert_eq!(drive.take_output().len(), 1);
    drive.receive(&Frame::data(0x080, &[7, 7]));
    assert!(drive.take_output().is_empty());
}

#[test]
fn a_short_rpdo_is_dropped_with_emcy_8210() {
    let mut drive = operational();
    drive.receive(&Frame::data(0x201, &[0x06, 0x00, 0x00]));
    assert_eq!(
        drive.take_output(),
        [Frame::data(0x081, &[0x10, 0x82, 0, 0, 0, 0, 0, 0])]
    );
    sync(&mut drive);
    assert_eq!(drive.power_state(), PowerState::SwitchOnDisabled);
    // Extra bytes are ignored.
    drive.receive(&Frame::data(0x201, &[0x06, 0, 0, 0, 0, 0, 0xFF, 0xFF]));
    sync(&mut drive);
    assert_eq!(drive.power_state(), PowerState::ReadyToSwitchOn);
}

#[test]
fn a_following_error_faults_with_emcy_8611_until_reset() {
    let mut drive = booted(DriveConfig {
        max_step: 10,
        following_error_window: 100,
        ..DriveConfig::new(1)
    });
    drive.receive(&Frame::data(0x000, &[0x01, 0x01]));
    write(&mut drive, 0x6060, 0, 8, 1).unwrap();
    for word in [0x06, 0x07, 0x0F] {
        rpdo1(&mut drive, word, 0);
        sync(&mut drive);
    }
    // 110 counts away: after one 10-count cycle 100 remain, within the window; then
    // 500 away: 480 remain.
    rpdo1(&mut drive, 0x0F, 110);
    sync(&mut drive);
    assert_eq!(drive.power_state(), PowerState::OperationEnabled);
    rpdo1(&mut drive, 0x0F, 500);
    let frames = sync(&mut drive);
    assert_eq!(drive.position(), 20);
    // EMCY 8611h with error register bit 0, then TPDO1 showing Fault (x0xx 1000) with
    // bit 13, following error.
    assert_eq!(
        frames,
        [
            Frame::data(0x081, &[0x11, 0x86, 0x01, 0, 0, 0, 0, 0]),
            Frame::data(0x181, &[0x18, 0x22, 20, 0, 0, 0]),
        ]
    );
    assert_eq!(read(&mut drive, 0x1001, 0), Ok((0x4F, 0x01)));
    assert!(drive.take_events().contains(&DriveEvent::Fault {
        time: Duration::ZERO,
        code: 0x8611
    }));
    // The fault holds: nothing moves, enable does nothing.
    rpdo1(&mut drive, 0x0F, 500);
    sync(&mut drive);
    assert_eq!(
        (drive.power_state(), drive.position()),
        (PowerState::Fault, 20)
    );
    // Fault reset on the rising edge of bit 7: EMCY 0000h, Switch on disabled.
    rpdo1(&mut drive, 0x80, 20);
    let frames = sync(&mut drive);
    assert_eq!(frames[0], Frame::data(0x081, &[0; 8]));
    assert_eq!(drive.power_state(), PowerState::SwitchOnDisabled);
    assert_eq!(drive.statusword(), 0x0250);
    assert_eq!(read(&mut drive, 0x1001, 0), Ok((0x4F, 0)));
}

#[test]
fn fault_reset_needs_an_edge() {
    let mut drive = enabled();
    write(&mut drive, 0x6065, 0, 0, 4).unwrap();
    write(&mut drive, 0x6040, 0, 0x80, 2).unwrap(); // bit 7 high before the fault
    rpdo1(&mut drive, 0x80, 5000);
    sync(&mut drive);
    // 0x80 did not count as a command: the drive kept running, 1000 counts a cycle,
    // and faulted with a window of 0.
    assert_eq!(drive.power_state(), PowerState::Fault);
    write(&mut drive, 0x6040, 0, 0x80, 2).unwrap();
    assert_eq!(drive.power_state(), PowerState::Fault, "no edge");
    write(&mut drive, 0x6040, 0, 0x00, 2).unwrap();
    write(&mut drive, 0x6040, 0, 0x80, 2).unwrap();
    assert_eq!(drive.power_state(), PowerState::SwitchOnDisabled);
}

#[test]
fn positions_wrap_modulo_2_pow_32() {
    let mut drive = booted(DriveConfig {
        position: i32::MAX - 500,
        ..DriveConfig::new(1)
    });
    drive.receive(&Frame::data(0x000, &[0x01, 0x01]));
    write(&mut drive, 0x6060, 0, 8, 1).unwrap();
    for word in [0x06, 0x07, 0x0F] {
        rpdo1(&mut drive, word, i32::MAX - 500);
        sync(&mut drive);
    }
    // 1000 counts on from i32::MAX − 500: past the top, to i32::MIN + 499, in one
    // cycle, within the window.
    rpdo1(&mut drive, 0x0F, i32::MIN + 499);
    let frames = sync(&mut drive);
    assert_eq!(drive.position(), i32::MIN + 499);
    assert_eq!(drive.power_state(), PowerState::OperationEnabled);
    let mut tpdo = vec![0x37, 0x12];
    tpdo.extend_from_slice(&(i32::MIN + 499).to_le_bytes());
    assert_eq!(frames, [Frame::data(0x181, &tpdo)]);
    // Back the other way, and a following error measured across the wrap too.
    rpdo1(&mut drive, 0x0F, i32::MAX - 20_000);
    sync(&mut drive);
    assert_eq!(drive.position(), i32::MAX - 500);
    assert_eq!(drive.power_state(), PowerState::Fault);
    assert!(drive.take_events().contains(&DriveEvent::Fault {
        time: Duration::ZERO,
        code: EMCY_FOLLOWING_ERROR
    }));
}

#[test]
fn a_target_beyond_the_software_limits_faults_before_moving() {
    let mut drive = booted(DriveConfig {
        software_limits: Some((-100, 5000)),
        ..DriveConfig::new(2)
    });
    drive.receive(&Frame::data(0x000, &[0x01, 0x02]));
    drive.receive(&Frame::data(0x602, &[0x2F, 0x60, 0x60, 0, 8, 0, 0, 0]));
    let rpdo = |drive: &mut Drive, word: u16, target: i32| {
        let mut data = word.to_le_bytes().to_vec();
        data.extend_from_slice(&target.to_le_bytes());
        drive.receive(&Frame::data(0x202, &data));
        drive.receive(&Frame::data(0x080, &[]));
        drive.take_output()
    };
    for word in [0x06, 0x07, 0x0F] {
        rpdo(&mut drive, word, 0);
    }
    // Up to the limit is fine; one count past it faults, with no motion, EMCY 8612h.
    rpdo(&mut drive, 0x0F, 5000);
    assert_eq!(drive.position(), 1000);
    let frames = rpdo(&mut drive, 0x0F, 5001);
    assert_eq!(drive.position(), 1000);
    assert_eq!(drive.power_state(), PowerState::Fault);
    assert_eq!(
        frames[0],
        Frame::data(0x082, &[0x12, 0x86, 0x01, 0, 0, 0, 0, 0])
    );
    // Reset, and a target below the limit does the same.
    rpdo(&mut drive, 0x80, 1000);
    for word in [0x06, 0x07, 0x0F] {
        rpdo(&mut drive, word, 1000);
    }
    assert_eq!(drive.power_state(), PowerState::OperationEnabled);
    rpdo(&mut drive, 0x0F, -101);
    assert_eq!(
        (drive.power_state(), drive.position()),
        (PowerState::Fault, 1000)
    );
}

#[test]
fn an_external_fault_sends_its_code_once() {
    let mut drive = enabled();
    drive.external_fault(0xFF64);
    assert_eq!(drive.power_state(), PowerState::Fault);
    assert_eq!(
        drive.take_output(),
        [Frame::data(0x081, &[0x64, 0xFF, 0x01, 0, 0, 0, 0, 0])]
    );
    // A second one while in Fault: the first stands, nothing is sent.
    drive.external_fault(0x9000);
    assert!(drive.take_output().is_empty());
    assert_eq!(read(&mut drive, 0x1001, 0), Ok((0x4F, 0x01)));
}

#[test]
fn window_ffffffff_switches_the_check_off() {
    let mut drive = booted(DriveConfig {
        max_step: 1,
        ..DriveConfig::new(1)
    });
    drive.receive(&Frame::data(0x000, &[0x01, 0x01]));
    write(&mut drive, 0x6065, 0, u32::MAX, 4).unwrap();
    write(&mut drive, 0x6060, 0, 8, 1).unwrap();
    for word in [0x06, 0x07, 0x0F] {
        rpdo1(&mut drive, word, 0);
        sync(&mut drive);
    }
    rpdo1(&mut drive, 0x0F, i32::MAX);
    sync(&mut drive);
    assert_eq!(drive.power_state(), PowerState::OperationEnabled);
    assert_eq!(drive.position(), 1);
}

#[test]
fn remapping_follows_the_procedure() {
    let mut drive = operational();
    let w = |drive: &mut Drive, index, sub, value, size| write(drive, index, sub, value, size);
    // Mapping while the PDO is valid: refused.
    assert_eq!(w(&mut drive, 0x1A00, 0, 0, 1), Err(0x0601_0000));
    assert_eq!(w(&mut drive, 0x1A00, 1, 0x6064_0020, 4), Err(0x0601_0000));
    // Destroy, transmission type 2, clear, map position only, count, create.
    w(&mut drive, 0x1800, 1, 0xC000_0181, 4).unwrap();
    w(&mut drive, 0x1800, 2, 2, 1).unwrap();
    // An entry while sub-index 0 is not 0: refused.
    assert_eq!(w(&mut drive, 0x1A00, 1, 0x6064_0020, 4), Err(0x0601_0000));
    w(&mut drive, 0x1A00, 0, 0, 1).unwrap();
    // Enabling with nothing mapped: refused.
    assert_eq!(w(&mut drive, 0x1800, 1, 0x4000_0181, 4), Err(0x0609_0030));
    w(&mut drive, 0x1A00, 1, 0x6064_0020, 4).unwrap();
    w(&mut drive, 0x1A00, 0, 1, 1).unwrap();
    w(&mut drive, 0x1800, 1, 0x4000_0181, 4).unwrap();
    // Type 2: every second SYNC, four bytes of position.
    assert!(sync(&mut drive).is_empty());
    assert_eq!(sync(&mut drive), [Frame::data(0x181, &[0, 0, 0, 0])]);
    assert!(sync(&mut drive).is_empty());
    // A valid PDO's identifier cannot change.
    assert_eq!(w(&mut drive, 0x1800, 1, 0x4000_0191, 4), Err(0x0609_0030));
}

#[test]
fn impossible_mappings_are_refused() {
    let mut drive = operational();
    write(&mut drive, 0x1400, 1, 0x8000_0201, 4).unwrap();
    write(&mut drive, 0x1600, 0, 0, 1).unwrap();
    let cases = [
        (1, 0x6041_0010, 0x0604_0041), // a TPDO object in an RPDO
        (1, 0x6065_0020, 0x0604_0041), // not mappable at all
        (1, 0x607A_0010, 0x0604_0041), // wrong length
        (0, 9, 0x0604_0042),           // nine entries
        (0, 3, 0x0604_0041),           // counting an entry never written
    ];
    for (sub, value, code) in cases {
        let size = if sub == 0 { 1 } else { 4 };
        assert_eq!(write(&mut drive, 0x1600, sub, value, size), Err(code));
    }
    // Three entries of 80 bits in all.
    for (sub, value) in [(1, 0x607A_0020), (2, 0x607A_0020), (3, 0x6040_0010)] {
        write(&mut drive, 0x1600, sub, value, 4).unwrap();
    }
    assert_eq!(write(&mut drive, 0x1600, 0, 3, 1), Err(0x0604_0042));
    write(&mut drive, 0x1600, 0, 2, 1).unwrap();
    // COB-IDs: 29-bit (bit 29), bits 11–28, identifier 0; transmission types.
    for cob in [0x2000_0201, 0x0000_0A01, 0x0000_0000] {
        assert_eq!(write(&mut drive, 0x1400, 1, cob, 4), Err(0x0609_0030));
    }
    for kind in [241, 252, 253] {
        assert_eq!(write(&mut drive, 0x1400, 2, kind, 1), Err(0x0609_0030));
    }
    for kind in [0, 240, 254, 255] {
        assert_eq!(write(&mut drive, 0x1400, 2, kind, 1), Ok(()));
    }
}

#[test]
fn asynchronous_pdos_act_on_change() {
    let mut drive = operational();
    // RPDO1 asynchronous (255): applied on receipt, no SYNC needed.
    write(&mut drive, 0x1400, 1, 0x8000_0201, 4).unwrap();
    write(&mut drive, 0x1400, 2, 255, 1).unwrap();
    write(&mut drive, 0x1400, 1, 0x0000_0201, 4).unwrap();
    rpdo1(&mut drive, 0x06, 0);
    assert_eq!(drive.power_state(), PowerState::ReadyToSwitchOn);
    // TPDO1 event-driven (255): sent when the statusword changes, not on SYNC.
    write(&mut drive, 0x1800, 1, 0xC000_0181, 4).unwrap();
    write(&mut drive, 0x1800, 2, 255, 1).unwrap();
    drive.take_output();
    drive.receive(&Frame::data(
        0x601,
        &[0x23, 0x00, 0x18, 1, 0x81, 0x01, 0, 0x40],
    ));
    let out = drive.take_output();
    assert_eq!(out[1], Frame::data(0x181, &[0x31, 0x02, 0, 0, 0, 0]));
    assert!(sync(&mut drive).is_empty());
    rpdo1(&mut drive, 0x07, 0);
    assert_eq!(
        drive.take_output(),
        [Frame::data(0x181, &[0x33, 0x02, 0, 0, 0, 0])]
    );
    // Acyclic synchronous (0): at a SYNC, only if changed.
    write(&mut drive, 0x1800, 1, 0xC000_0181, 4).unwrap();
    write(&mut drive, 0x1800, 2, 0, 1).unwrap();
    write(&mut drive, 0x1800, 1, 0x4000_0181, 4).unwrap();
    assert_eq!(sync(&mut drive).len(), 1);
    assert!(sync(&mut drive).is_empty());
    rpdo1(&mut drive, 0x06, 0);
    assert_eq!(sync(&mut drive).len(), 1);
}

#[test]
fn frames_that_are_not_canopens_are_ignored() {
    let mut drive = operational();
    let request = vec![0x40, 0x41, 0x60, 0, 0, 0, 0, 0];
    let odd = [
        Frame {
            extended: true,
            ..Frame::data(0x601, &request)
        },
        Frame {
            remote: true,
            data: vec![],
            ..Frame::data(0x601, &request)
        },
        Frame {
            id: 0x1601,
            ..Frame::data(0x601, &request)
        },
        Frame::data(0x601, &[0; 9]),
        Frame::data(0x602, &request),
    ];
    for frame in odd {
        drive.receive(&frame);
        assert!(drive.take_output().is_empty(), "{frame:?}");
    }
}
#[test]
fn interpolated_position_mode_7_is_accepted_and_displayed() {
    let mut drive = booted(DriveConfig::new(1));
    // CiA 402: 6060h = 7 selects interpolated position mode; 6061h shows it.
    write(&mut drive, 0x6060, 0, 7, 1).unwrap();
    assert_eq!(read(&mut drive, 0x6060, 0), Ok((0x4F, 7)));
    assert_eq!(read(&mut drive, 0x6061, 0), Ok((0x4F, 7)));
    // Profile position, homing, the cyclic synchronous velocity and torque modes are
    // not the sim's: refused, and the mode stays.
    for mode in [1, 6, 9, 10] {
        assert_eq!(write(&mut drive, 0x6060, 0, mode, 1), Err(0x0609_0030));
    }
    assert_eq!(read(&mut drive, 0x6061, 0), Ok((0x4F, 7)));
    write(&mut drive, 0x6060, 0, 8, 1).unwrap();
    assert_eq!(read(&mut drive, 0x6061, 0), Ok((0x4F, 8)));
    // Reset node: no mode.
    drive.receive(&Frame::data(0x000, &[0x81, 0x01]));
    assert_eq!(read(&mut drive, 0x6061, 0), Ok((0x4F, 0)));
}

#[test]
fn the_interpolation_data_record_60c1h_is_read_and_written_by_sdo() {
    let mut drive = booted(DriveConfig {
        position: -7,
        ..DriveConfig::new(1)
    });
    // Sub-index 0: one entry (the position set-point of linear interpolation), one
    // byte, read-only; sub-index 1: INTEGER32, the position actual value at power-up.
    assert_eq!(read(&mut drive, 0x60C1, 0), Ok((0x4F, 1)));
    assert_eq!(write(&mut drive, 0x60C1, 0, 2, 1), Err(0x0601_0002));
    assert_eq!(read(&mut drive, 0x60C1, 1), Ok((0x43, -7i32 as u32)));
    assert_eq!(drive.interpolation_data(), -7);
    write(&mut drive, 0x60C1, 1, -123_456i32 as u32, 4).unwrap();
    assert_eq!(read(&mut drive, 0x60C1, 1), Ok((0x43, -123_456i32 as u32)));
    assert_eq!(drive.interpolation_data(), -123_456);
    // Four bytes, no more, no fewer; no sub-index 2.
    assert_eq!(write(&mut drive, 0x60C1, 1, 5, 2), Err(0x0607_0013));
    assert_eq!(write(&mut drive, 0x60C1, 1, 5, 1), Err(0x0607_0013));
    assert_eq!(write(&mut drive, 0x60C1, 0, 1, 4), Err(0x0601_0002));
    assert_eq!(read(&mut drive, 0x60C1, 2), Err(0x0609_0011));
    assert_eq!(write(&mut drive, 0x60C1, 2, 0, 4), Err(0x0609_0011));
    assert_eq!(drive.interpolation_data(), -123_456);
    // 607Ah is another object: untouched.
    assert_eq!(drive.target(), -7);
    // The mode's set-point: 607Ah outside interpolated position mode, 60C1h in it.
    assert_eq!(drive.set_point(), -7);
    write(&mut drive, 0x6060, 0, 7, 1).unwrap();
    assert_eq!(drive.set_point(), -123_456);
    // A profile object: reset communication keeps it, reset node restores it.
    drive.receive(&Frame::data(0x000, &[0x82, 0x01]));
    assert_eq!(drive.interpolation_data(), -123_456);
    drive.receive(&Frame::data(0x000, &[0x81, 0x01]));
    assert_eq!(drive.interpolation_data(), -7);
}

#[test]
fn interpolation_data_maps_into_rpdos_only() {
    let mut drive = operational();
    write(&mut drive, 0x1400, 1, 0x8000_0201, 4).unwrap();
    write(&mut drive, 0x1600, 0, 0, 1).unwrap();
    // Sub-index 0 (the count) and another length are not the set-point.
    assert_eq!(
        write(&mut drive, 0x1600, 1, 0x60C1_0020, 4),
        Err(0x0604_0041)
    );
    assert_eq!(
        write(&mut drive, 0x1600, 1, 0x60C1_0008, 4),
        Err(0x0604_0041)
    );
    assert_eq!(
        write(&mut drive, 0x1600, 1, 0x60C1_0110, 4),
        Err(0x0604_0041)
    );
    assert_eq!(
        write(&mut drive, 0x1600, 1, 0x60C1_0220, 4),
        Err(0x0604_0041)
    );
    write(&mut drive, 0x1600, 1, 0x60C1_0120, 4).unwrap();
    assert_eq!(read(&mut drive, 0x1600, 1), Ok((0x43, 0x60C1_0120)));
    // The master's input, not the drive's output: no TPDO carries it.
    write(&mut drive, 0x1800, 1, 0xC000_0181, 4).unwrap();
    write(&mut drive, 0x1A00, 0, 0, 1).unwrap();
    assert_eq!(
        write(&mut drive, 0x1A00, 1, 0x60C1_0120, 4),
        Err(0x0604_0041)
    );
}

#[test]
fn ip_mode_is_active_only_with_bit_4_in_operation_enabled() {
    use PowerState::*;
    let mut drive = booted(DriveConfig::new(1));
    write(&mut drive, 0x6060, 0, 7, 1).unwrap();
    let mut step = |word: u32, expected: PowerState, statusword: u16| {
        write(&mut drive, 0x6040, 0, word, 2).unwrap();
        assert_eq!(drive.power_state(), expected, "after {word:02X}");
        assert_eq!(drive.statusword(), statusword, "after {word:02X}");
    };
    // Bit 4 does not take part in the state machine's commands, and below Operation
    // enabled it activates nothing.
    step(0x16, ReadyToSwitchOn, 0x0231);
    step(0x17, SwitchedOn, 0x0233);
    // Operation enabled without bit 4: ip mode inactive (statusword bit 12 clear).
    step(0x0F, OperationEnabled, 0x0237);
    // With bit 4: ip mode active (bit 12).
    step(0x1F, OperationEnabled, 0x1237);
    // Bit 4 cleared: inactive again, still Operation enabled.
    step(0x0F, OperationEnabled, 0x0237);
    step(0x1F, OperationEnabled, 0x1237);
    // Leaving Operation enabled ends it, whatever bit 4 says.
    step(0x17, SwitchedOn, 0x0233);
    step(0x1F, OperationEnabled, 0x1237);
    step(0x12, QuickStopActive, 0x0217);
    step(0x10, SwitchOnDisabled, 0x0250);
    // In CSP bit 12 does not wait for bit 4.
    write(&mut drive, 0x6060, 0, 8, 1).unwrap();
    for word in [0x06, 0x07] {
        write(&mut drive, 0x6040, 0, word, 2).unwrap();
    }
    write(&mut drive, 0x6040, 0, 0x0F, 2).unwrap();
    assert_eq!(drive.statusword(), 0x1237);
    // Nor in no mode does bit 4 make it.
    write(&mut drive, 0x6060, 0, 0, 1).unwrap();
    write(&mut drive, 0x6040, 0, 0x1F, 2).unwrap();
    assert_eq!(drive.statusword(), 0x0237);
}

/// RPDO1 as [`interpolating`] maps it: controlword, 60C1h sub-index 1.
fn ip_rpdo(drive: &mut Drive, controlword: u16, set_point: i32) -> Vec<Frame> {
    rpdo1(drive, controlword, set_point);
    sync(drive)
}

#[test]
fn set_points_move_the_drive_only_while_ip_mode_is_active() {
    let mut drive = interpolating(DriveConfig::new(1));
    for word in [0x06, 0x07, 0x0F] {
        ip_rpdo(&mut drive, word, 0);
    }
    assert_eq!(drive.power_state(), PowerState::OperationEnabled);
    // Enabled but ip mode inactive: the set-point is taken into 60C1h, not followed.
    let frames = ip_rpdo(&mut drive, 0x0F, 500);
    assert_eq!(drive.interpolation_data(), 500);
    assert_eq!(drive.position(), 0);
    assert_eq!(frames, [Frame::data(0x181, &[0x37, 0x02, 0, 0, 0, 0])]);
    assert!(cycles(&mut drive).is_empty());
    // Bit 4: ip mode active, and the same SYNC's set-point is followed.
    let frames = ip_rpdo(&mut drive, 0x1F, 500);
    assert_eq!(drive.position(), 500);
    assert_eq!(
        frames,
        [Frame::data(0x181, &[0x37, 0x12, 0xF4, 0x01, 0, 0])]
    );
    // One set-point a SYNC, at most max_step (1000) counts a cycle, as in CSP.
    ip_rpdo(&mut drive, 0x1F, 3000);
    assert_eq!(drive.position(), 1500);
    ip_rpdo(&mut drive, 0x1F, 3000);
    assert_eq!(drive.position(), 2500);
    // Bit 4 cleared: the drive holds where it is, the new set-point ignored.
    let frames = ip_rpdo(&mut drive, 0x0F, -4000);
    assert_eq!(drive.position(), 2500);
    assert_eq!(frames[0].data[..2], [0x37, 0x02]);
    assert_eq!(cycles(&mut drive), [(500, 500), (3000, 1500), (3000, 2500)]);
    // 607Ah played no part.
    assert_eq!(drive.target(), 0);
    assert_eq!(drive.set_point(), -4000);
    assert_eq!(drive.power_state(), PowerState::OperationEnabled);
}

#[test]
fn ip_set_points_meet_the_following_error_window_and_the_software_limits() {
    let mut drive = interpolating(DriveConfig {
        max_step: 10,
        following_error_window: 100,
        software_limits: Some((-100, 5000)),
        ..DriveConfig::new(1)
    });
    for word in [0x06, 0x07, 0x0F, 0x1F] {
        ip_rpdo(&mut drive, word, 0);
    }
    // 110 away: 100 remain after the cycle, in the window; 500 away: 480 remain.
    ip_rpdo(&mut drive, 0x1F, 110);
    assert_eq!(drive.power_state(), PowerState::OperationEnabled);
    let frames = ip_rpdo(&mut drive, 0x1F, 500);
    assert_eq!(drive.position(), 20);
    assert_eq!(
        frames,
        [
            Frame::data(0x081, &[0x11, 0x86, 0x01, 0, 0, 0, 0, 0]),
            Frame::data(0x181, &[0x18, 0x22, 20, 0, 0, 0]),
        ]
    );
    // Reset, enable again from where it stands, and a set-point past the limit faults
    // before it moves, with EMCY 8612h.
    ip_rpdo(&mut drive, 0x80, 20);
    for word in [0x06, 0x07, 0x0F, 0x1F] {
        ip_rpdo(&mut drive, word, 20);
    }
    assert_eq!(drive.statusword(), 0x1237);
    let frames = ip_rpdo(&mut drive, 0x1F, -101);
    assert_eq!(
        (drive.power_state(), drive.position()),
        (PowerState::Fault, 20)
    );
    assert_eq!(
        frames[0],
        Frame::data(0x081, &[0x12, 0x86, 0x01, 0, 0, 0, 0, 0])
    );
}
