//! The objects the session uses on a drive, as CiA 301 and 402 name and type them, and the
//! check of a profile's data sheets (`connection.drives.eds`) against them.

use std::path::Path;
use std::sync::Arc;

use super::*;
use crate::config::connection::{DriveMode, DriveSettings, EdsFiles};
use crate::config::eds::{DataType, Eds, Use};
use crate::protocol::canopen::session::objects::dictionary;
use crate::protocol::canopen::session::script::{configuration, mappings, Op};

/// The test drive's EDS, which python-canopen reads too.
const DRIVE: &str = include_str!("../../../../../tests/data/cia402-drive.eds");

fn drives(mode: DriveMode) -> DriveSettings {
    let mode = match mode {
        DriveMode::Csp => "csp",
        DriveMode::Ip => "ip",
    };
    toml::from_str(&format!(
        "counts_per_mm = [10000.0, 10000.0]\ncounts_per_degree = 2912.7\nmode = \"{mode}\""
    ))
    .unwrap()
}

/// `drives` with the data sheets `texts` (X, Z, C) as if read from `x.eds`, … (one
/// text for all: one file).
fn with_sheets(mut drives: DriveSettings, texts: &[&str]) -> DriveSettings {
    let sheets: Vec<Arc<Eds>> = texts
        .iter()
        .zip(["x.eds", "z.eds", "c.eds"])
        .map(|(text, name)| Arc::new(Eds::parse(text, Path::new(name)).unwrap()))
        .collect();
    drives.data_sheets = Some(match sheets.as_slice() {
        [one] => [one.clone(), one.clone(), one.clone()],
        [x, z, c] => [x.clone(), z.clone(), c.clone()],
        _ => panic!("one sheet or three"),
    });
    drives.eds = Some(EdsFiles::All("x.eds".into()));
    drives
}

/// (index, sub, type, use) of every object used in `operation`, sorted.
fn used(operation: Operation) -> Vec<(u16, u8, DataType, Use)> {
    let mut uses: Vec<_> = objects_used(operation)
        .into_iter()
        .map(|o| (o.index, o.sub, o.data_type, o.how))
        .collect();
    uses.sort_by_key(|&(index, sub, _, how)| (index, sub, how));
    uses
}

#[test]
fn the_objects_used_are_cia_301s_and_402s_with_their_types() {
    use DataType as T;
    let (u8_, u16_, u32_, i8_, i32_) = (
        T::UNSIGNED8,
        T::UNSIGNED16,
        T::UNSIGNED32,
        T::INTEGER8,
        T::INTEGER32,
    );
    // CiA 301: device type, heartbeat, RPDO1/TPDO1 communication (COB-ID UNSIGNED32,
    // transmission type UNSIGNED8) and mapping (count UNSIGNED8, entries UNSIGNED32);
    // CiA 402: controlword and statusword UNSIGNED16, modes of operation INTEGER8,
    // positions INTEGER32, following error window UNSIGNED32, interpolation time period
    // UNSIGNED8 value and INTEGER8 index.
    let common = [
        (0x1000, 0, u32_, Use::SdoRead),
        (0x1017, 0, u16_, Use::SdoWrite),
        (0x1400, 1, u32_, Use::SdoWrite),
        (0x1400, 2, u8_, Use::SdoWrite),
        (0x1600, 0, u8_, Use::SdoWrite),
        (0x1600, 1, u32_, Use::SdoWrite),
        (0x1600, 2, u32_, Use::SdoWrite),
        (0x1800, 1, u32_, Use::SdoWrite),
        (0x1800, 2, u8_, Use::SdoWrite),
        (0x1A00, 0, u8_, Use::SdoWrite),
        (0x1A00, 1, u32_, Use::SdoWrite),
        (0x1A00, 2, u32_, Use::SdoWrite),
        (0x6040, 0, u16_, Use::Rpdo(1)),
        (0x6041, 0, u16_, Use::Tpdo(1)),
        (0x6060, 0, i8_, Use::SdoWrite),
        (0x6064, 0, i32_, Use::SdoRead),
        (0x6064, 0, i32_, Use::Tpdo(1)),
        (0x6065, 0, u32_, Use::SdoWrite),
        (0x60C2, 1, u8_, Use::SdoWrite),
        (0x60C2, 2, i8_, Use::SdoWrite),
    ];
    let expected = |set_point: (u16, u8, DataType, Use)| {
        let mut all = common.to_vec();
        all.push(set_point);
        all.sort_by_key(|&(index, sub, _, how)| (index, sub, how));
        all
    };
    // The set-point: target position 607Ah in CSP, 60C1h sub-index 1 in ip mode.
    assert_eq!(
        used(Operation::CyclicSynchronousPosition),
        expected((0x607A, 0, i32_, Use::Rpdo(1)))
    );
    assert_eq!(
        used(Operation::InterpolatedPosition),
        expected((0x60C1, 1, i32_, Use::Rpdo(1)))
    );
    let names: Vec<_> = objects_used(Operation::CyclicSynchronousPosition)
        .into_iter()
        .map(|o| o.name)
        .collect();
    assert!(names.contains(&"target position".to_owned()), "{names:?}");
    assert!(
        names.contains(&"TPDO1 mapping parameter: mapped object 2".to_owned()),
        "{names:?}"
    );
}

#[test]
fn the_types_are_as_wide_as_what_the_script_writes_and_maps() {
    for operation in [
        Operation::CyclicSynchronousPosition,
        Operation::InterpolatedPosition,
    ] {
        let config = SessionConfig {
            operation,
            ..SessionConfig::default()
        };
        for op in configuration(node(1), &config, (4, -3)) {
            if let Op::Write(write) = op {
                let (name, data_type) = dictionary(write.index, write.sub).unwrap();
                assert_eq!(data_type.bits(), Some(8 * write.data.len() as u8), "{name}");
            }
        }
        for mapping in mappings(operation) {
            for entry in mapping.entries {
                let (name, data_type) = dictionary(entry.index, entry.sub).unwrap();
                assert_eq!(data_type.bits(), Some(entry.bits), "{name}");
            }
        }
    }
    // RPDO2's and TPDO4's parameters are named by their number.
    assert_eq!(
        dictionary(0x1401, 1).unwrap().0,
        "RPDO2 communication parameter: COB-ID used by RPDO"
    );
    assert_eq!(
        dictionary(0x1A03, 0).unwrap().0,
        "TPDO4 mapping parameter: number of mapped objects"
    );
    assert_eq!(dictionary(0x6061, 0), None);
}

#[test]
fn the_test_drives_eds_fits_either_mode() {
    for mode in [DriveMode::Csp, DriveMode::Ip] {
        let drives = with_sheets(drives(mode), &[DRIVE]);
        assert!(SessionConfig::for_drives(&drives).is_ok(), "{mode:?}");
    }
}

#[test]
fn a_read_only_target_position_is_refused_in_csp_and_unused_in_ip_mode() {
    let read_only = DRIVE.replace("\r\n", "\n").replace(
        "ParameterName=Target position\nObjectType=0x7\nDataType=0x0004\nAccessType=rww",
        "ParameterName=Target position\nObjectType=0x7\nDataType=0x0004\nAccessType=ro",
    );
    assert!(read_only.contains("Target position\nObjectType=0x7\nDataType=0x0004\nAccessType=ro\n"));
    let error =
        SessionConfig::for_drives(&with_sheets(drives(DriveMode::Csp), &[&read_only])).unwrap_err();
    assert_eq!(error.key, "connection.drives.eds");
    assert!(
        error.problem.starts_with(
            "the X, Z, C drives (nodes 1, 2, 3, in cyclic synchronous position (mode 8)): \
             EDS file x.eds does not fit:\n  - 607Ah:00 target position: whirl maps it into \
             RPDO1"
        ),
        "{}",
        error.problem
    );
    // In interpolated position mode the set-point is 60C1h sub-index 1: 607Ah is not used.
    assert!(SessionConfig::for_drives(&with_sheets(drives(DriveMode::Ip), &[&read_only])).is_ok());
}

#[test]
fn each_drives_sheet_is_checked_and_the_drive_named() {
    let no_heartbeat = DRIVE.replace("[1017]", "[2017]");
    let drives = with_sheets(drives(DriveMode::Csp), &[DRIVE, &no_heartbeat, DRIVE]);
    let error = SessionConfig::for_drives(&drives).unwrap_err();
    assert!(
        error.problem.starts_with("the Z drive (node 2, ")
            && error.problem.contains("EDS file z.eds does not fit")
            && error
                .problem
                .contains("1017h:00 producer heartbeat time: whirl writes it by SDO"),
        "{}",
        error.problem
    );
}

#[test]
fn data_sheets_named_but_not_read_are_refused() {
    let mut drives = drives(DriveMode::Csp);
    drives.eds = Some(EdsFiles::All("drive.eds".into()));
    let error = SessionConfig::for_drives(&drives).unwrap_err();
    assert_eq!(error.key, "connection.drives.eds");
    assert!(error.problem.contains("not read"), "{}", error.problem);
}
