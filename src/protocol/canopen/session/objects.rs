//! The objects the session uses on a drive, and how: what a drive's EDS must offer
//! ([`crate::config::eds`]), taken from the configuration script itself so that the
//! two cannot drift apart, with CiA 301's and CiA 402's names and data types.

use super::script::{configuration, mappings, Op};
use std::sync::Arc;

use super::{Operation, SessionConfig};
use crate::config::connection::{DriveSettings, SettingError};
use crate::config::eds::{DataType, ObjectUse, Use};
use crate::protocol::canopen::cia301::{NodeId, PdoDirection};
use crate::protocol::canopen::cia402::object;

/// Every object the session (and the CAN transport, which reads where the drives stand
/// before the run) reads, writes or maps on a drive running `operation`, each use once,
/// in the order of the configuration.
pub fn objects_used(operation: Operation) -> Vec<ObjectUse> {
    let config = SessionConfig {
        operation,
        ..SessionConfig::default()
    };
    // The node and the cycle change values, never which objects are used.
    let node = NodeId::new(1).expect("node 1");
    let mut uses: Vec<(u16, u8, Use)> = Vec::new();
    for op in configuration(node, &config, (4, -3)) {
        uses.push(match op {
            Op::CheckDeviceType => (object::DEVICE_TYPE, 0, Use::SdoRead),
            Op::Write(write) => (write.index, write.sub, Use::SdoWrite),
        });
    }
    for mapping in mappings(operation) {
        let number = u16::from(mapping.number.get());
        let how = match mapping.direction {
            PdoDirection::Receive => Use::Rpdo(number),
            PdoDirection::Transmit => Use::Tpdo(number),
        };
        uses.extend(mapping.entries.iter().map(|e| (e.index, e.sub, how)));
    }
    // `transport::can` reads the drives' positions by SDO before the session starts.
    uses.push((object::POSITION_ACTUAL, 0, Use::SdoRead));
    let mut seen = Vec::new();
    uses.retain(|used| {
        let new = !seen.contains(used);
        seen.push(*used);
        new
    });
    uses.into_iter()
        .map(|(index, sub, how)| {
            let (name, data_type) = dictionary(index, sub)
                .unwrap_or_else(|| panic!("{index:04X}h:{sub:02X} is in the dictionary"));
            ObjectUse {
                index,
                sub,
                name,
                data_type,
                how,
            }
        })
        .collect()
}

/// Checks the drives' data sheets (`connection.drives.eds`) against
/// [`objects_used`] in their mode: each sheet once, the error naming the drives it is
/// for, the file and every object that does not fit.
pub(super) fn check_data_sheets(drives: &DriveSettings) -> Result<(), SettingError> {
    let refuse = |problem: String| SettingError {
        key: "connection.drives.eds".into(),
        problem,
    };
    let Some(sheets) = &drives.data_sheets else {
        return match &drives.eds {
            Some(_) => Err(refuse(
                "the data sheets were not read: a profile's loading reads them \
                 (MachineProfile::load, DriveSettings::read_data_sheets)"
                    .into(),
            )),
            None => Ok(()),
        };
    };
    let operation = Operation::from(drives.mode);
    let uses = objects_used(operation);
    for (slot, sheet) in sheets.iter().enumerate() {
        if sheets[..slot].iter().any(|seen| Arc::ptr_eq(seen, sheet)) {
            continue;
        }
        let served: Vec<usize> = (0..3)
            .filter(|&other| Arc::ptr_eq(&sheets[other], sheet))
            .collect();
        if let Err(mismatch) = sheet.check(&uses) {
            let axes: Vec<&str> = served.iter().map(|&k| ["X", "Z", "C"][k]).collect();
            let nodes: Vec<String> = served
                .iter()
                .map(|&k| drives.nodes[k].to_string())
                .collect();
            let drive = if served.len() == 1 { "drive" } else { "drives" };
            let node = if served.len() == 1 { "node" } else { "nodes" };
            return Err(refuse(format!(
                "the {} {drive} ({node} {}, in {operation}): {mismatch}",
                axes.join(", "),
                nodes.join(", "),
            )));
        }
    }
    Ok(())
}

/// The name and data type CiA 301 (communication objects) or CiA 402 (the drive profile)
/// give an object the session uses; `None` for any other.
pub(super) fn dictionary(index: u16, sub: u8) -> Option<(String, DataType)> {
    let named = |name: &str, data_type| Some((name.to_owned(), data_type));
    // The PDO parameters, 1400h–15FFh RPDO communication, 1600h–17FFh RPDO mapping,
    // 1800h–19FFh TPDO communication, 1A00h–1BFFh TPDO mapping.
    if (0x1400..=0x1BFF).contains(&index) {
        let pdo = if index < 0x1800 { "RPDO" } else { "TPDO" };
        let n = (index & 0x01FF) + 1;
        return if index & 0x0200 == 0 {
            match sub {
                1 => named(
                    &format!("{pdo}{n} communication parameter: COB-ID used by {pdo}"),
                    DataType::UNSIGNED32,
                ),
                2 => named(
                    &format!("{pdo}{n} communication parameter: transmission type"),
                    DataType::UNSIGNED8,
                ),
                _ => None,
            }
        } else {
            match sub {
                0 => named(
                    &format!("{pdo}{n} mapping parameter: number of mapped objects"),
                    DataType::UNSIGNED8,
                ),
                1..=64 => named(
                    &format!("{pdo}{n} mapping parameter: mapped object {sub}"),
                    DataType::UNSIGNED32,
                ),
                _ => None,
            }
        };
    }
    match (index, sub) {
        (object::DEVICE_TYPE, 0) => named("device type", DataType::UNSIGNED32),
        (object::PRODUCER_HEARTBEAT, 0) => named("producer heartbeat time", DataType::UNSIGNED16),
        (object::CONTROLWORD, 0) => named("controlword", DataType::UNSIGNED16),
        (object::STATUSWORD, 0) => named("statusword", DataType::UNSIGNED16),
        (object::MODES_OF_OPERATION, 0) => named("modes of operation", DataType::INTEGER8),
        (object::POSITION_ACTUAL, 0) => named("position actual value", DataType::INTEGER32),
        (object::FOLLOWING_ERROR_WINDOW, 0) => {
            named("following error window", DataType::UNSIGNED32)
        }
        (object::TARGET_POSITION, 0) => named("target position", DataType::INTEGER32),
        (object::INTERPOLATION_DATA, 1) => named(
            "interpolation data record: first entry",
            DataType::INTEGER32,
        ),
        (object::INTERPOLATION_TIME_PERIOD, 1) => {
            named("interpolation time period: value", DataType::UNSIGNED8)
        }
        (object::INTERPOLATION_TIME_PERIOD, 2) => {
            named("interpolation time period: index", DataType::INTEGER8)
        }
        _ => None,
    }
}
