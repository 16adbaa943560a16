//! NMT and heartbeat (CiA 301's node control): the NMT states, the commands on 0x000, the
//! resets, boot-up and the heartbeat producer. Apart because it decides which services run
//! at all, whatever the profile does.

use std::time::Duration;

use serde::Serialize;

use super::pdo::default_pdos;
use super::{Drive, DriveEvent};

/// The NMT states a drive can be in after boot-up.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum NmtState {
    /// Heartbeat byte 0x7F.
    PreOperational,
    /// 0x05.
    Operational,
    /// 0x04.
    Stopped,
}

impl NmtState {
    fn heartbeat(self) -> u8 {
        match self {
            NmtState::PreOperational => 0x7F,
            NmtState::Operational => 0x05,
            NmtState::Stopped => 0x04,
        }
    }
}

impl Drive {
    /// Lets `dt` pass: heartbeats fall due.
    pub fn advance(&mut self, dt: Duration) {
        let end = self.now + dt;
        while let Some(due) = self.next_heartbeat.filter(|due| *due <= end) {
            self.now = due;
            self.send(0x700, &[self.nmt.heartbeat()]);
            self.next_heartbeat = Some(due + Duration::from_millis(self.heartbeat_ms.into()));
        }
        self.now = end;
    }

    /// Enters NMT state `state`: leaving Operational drops the RPDOs waiting for SYNC,
    /// entering it starts the TPDOs' counts and change detection afresh.
    pub(super) fn set_nmt(&mut self, state: NmtState) {
        if state == self.nmt {
            return;
        }
        if self.nmt == NmtState::Operational {
            self.rpdo.iter_mut().for_each(|pdo| pdo.received = None);
        }
        if state == NmtState::Operational {
            for pdo in &mut self.tpdo {
                pdo.last_sent = None;
                pdo.syncs = 0;
            }
        }
        self.nmt = state;
        self.events.push(DriveEvent::Nmt {
            time: self.now,
            state,
        });
    }

    /// Communication objects to power-on values, boot-up, Pre-operational.
    pub(super) fn reset_communication(&mut self) {
        (self.rpdo, self.tpdo) = default_pdos(self.config.node);
        self.heartbeat_ms = self.config.heartbeat_ms;
        self.restart_heartbeat();
        self.send(0x700, &[0x00]);
        self.nmt = NmtState::PreOperational;
        self.events.push(DriveEvent::Nmt {
            time: self.now,
            state: NmtState::PreOperational,
        });
    }

    /// The next heartbeat one 1017h period from now, or none with 1017h = 0.
    pub(super) fn restart_heartbeat(&mut self) {
        self.next_heartbeat = (self.heartbeat_ms > 0)
            .then(|| self.now + Duration::from_millis(self.heartbeat_ms.into()));
    }

    /// An NMT command on 0x000: specifier, then this node or 0 for all.
    pub(super) fn nmt_command(&mut self, data: &[u8]) {
        let [specifier, node] = data else { return };
        if *node != 0 && *node != self.config.node {
            return;
        }
        match specifier {
            0x01 => self.set_nmt(NmtState::Operational),
            0x02 => self.set_nmt(NmtState::Stopped),
            0x80 => self.set_nmt(NmtState::PreOperational),
            0x81 => {
                self.reset_application();
                self.reset_communication();
            }
            0x82 => self.reset_communication(),
            _ => {}
        }
    }
}
