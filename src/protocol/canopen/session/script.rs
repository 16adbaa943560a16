//! The SDO configuration script: the steps that set a node up before NMT start (device
//! type check, heartbeat, mode, following error window, cycle, PDO mappings), in order.

use std::collections::VecDeque;

use super::{Operation, SessionConfig};
use crate::protocol::canopen::cia301::{
    self, MapEntry, NodeId, PdoConfig, PdoDirection, PdoNumber, SdoWrite, EVERY_SYNC,
};
use crate::protocol::canopen::cia402::object;

/// One configuration step of a node.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) enum Op {
    /// Read 1000h and check it is CiA 402.
    CheckDeviceType,
    /// Write an object.
    Write(SdoWrite),
}

/// A node's configuration steps, in order (see the session's module docs).
pub(super) fn configuration(node: NodeId, config: &SessionConfig, cycle: (u8, i8)) -> VecDeque<Op> {
    let mut ops = VecDeque::from([
        Op::CheckDeviceType,
        Op::Write(SdoWrite::u16(
            object::PRODUCER_HEARTBEAT,
            0,
            config.heartbeat_ms,
        )),
        Op::Write(SdoWrite::u8(
            object::MODES_OF_OPERATION,
            0,
            config.operation.mode().value() as u8,
        )),
        Op::Write(SdoWrite::u32(
            object::FOLLOWING_ERROR_WINDOW,
            0,
            config.following_error_window,
        )),
        Op::Write(SdoWrite::u8(object::INTERPOLATION_TIME_PERIOD, 1, cycle.0)),
        Op::Write(SdoWrite::u8(
            object::INTERPOLATION_TIME_PERIOD,
            2,
            cycle.1 as u8,
        )),
    ]);
    let mappings = mappings(config.operation);
    for mapping in &mappings {
        let writes = cia301::pdo_mapping(node, mapping).expect("48 bits, valid entries");
        ops.extend(writes.into_iter().map(Op::Write));
    }
    ops
}

/// The PDOs the session maps on every drive: RPDO1 the controlword and the mode's
/// set-point, TPDO1 the statusword and the position actual value, both every SYNC.
pub(super) fn mappings(operation: Operation) -> [PdoConfig; 2] {
    let pdo = PdoNumber::new(1).expect("PDO 1");
    let entry = |index, bits| MapEntry {
        index,
        sub: 0,
        bits,
    };
    let (set_point, sub) = operation.set_point_object();
    [
        PdoConfig {
            direction: PdoDirection::Receive,
            number: pdo,
            transmission: EVERY_SYNC,
            entries: vec![
                entry(object::CONTROLWORD, 16),
                MapEntry {
                    index: set_point,
                    sub,
                    bits: 32,
                },
            ],
        },
        PdoConfig {
            direction: PdoDirection::Transmit,
            number: pdo,
            transmission: EVERY_SYNC,
            entries: vec![
                entry(object::STATUSWORD, 16),
                entry(object::POSITION_ACTUAL, 32),
            ],
        },
    ]
}
