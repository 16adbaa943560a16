//! The shop overview (`whirl serve --shop`): every machine of the shop as its bridge
//! publishes it on the broker (`docs/shop.md`), with a link to each bridge's console, and
//! the shop's history from the shared run records. It reads; it never starts a cut, which
//! is done at the machine.
//!
//! - [`view`]: the machines as their messages leave them (sans-I/O);
//! - [`feed`]: the subscription to the broker that feeds it;
//! - [`page`]: the overview's routes and page, behind the console's gate.

pub mod feed;
pub mod page;
pub mod view;

use std::collections::BTreeSet;
use std::sync::{Mutex, OnceLock};

use rumqttc::{AsyncClient, QoS};

use crate::telemetry::message::{self, Command, Machine};
use view::{MachineRow, ShopView};

/// The overview's state: the view, and a counter each change moves for the pages.
#[derive(Debug)]
pub struct Shop {
    prefix: String,
    view: Mutex<ShopView>,
    changes: tokio::sync::watch::Sender<u64>,
    /// Topics whose payload did not read, each said once.
    said: Mutex<BTreeSet<String>>,
    /// The shop's token, which a bridge's console takes a Hold with.
    token: Option<String>,
    /// The broker's client, once [`feed::follow`] has made it.
    client: OnceLock<AsyncClient>,
}

/// Why the overview did not send a Hold.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum HoldError {
    /// No such machine has reported.
    #[error("no machine \"{0}\" has reported to the broker")]
    Unknown(String),
    /// Only a running machine is held.
    #[error("machine \"{0}\" is not running (it is {1})")]
    NotRunning(String, String),
    /// The overview has no token, so no bridge would take its Hold.
    #[error(
        "the overview has no token (--token): a bridge takes a Hold only with its console's \
         token, the shop's; start the overview with it"
    )]
    NoToken,
    /// The broker cannot take it now.
    #[error("the broker cannot take the Hold now: {0}")]
    Broker(String),
}

impl Shop {
    /// The overview of the machines under `prefix`, holding with `token`.
    pub fn new(prefix: &str, token: Option<String>) -> Shop {
        Shop {
            prefix: prefix.to_owned(),
            view: Mutex::new(ShopView::new(prefix)),
            changes: tokio::sync::watch::Sender::new(0),
            said: Mutex::default(),
            token,
            client: OnceLock::new(),
        }
    }

    /// Sends a Hold to `machine`'s bridge, asked by `by`: only for a running machine, with
    /// the shop's token. Whether the bridge took it shows as the machine's state.
    pub fn hold(&self, machine: &str, by: &str) -> Result<(), HoldError> {
        let row = self
            .rows()
            .into_iter()
            .find(|r| r.topic == machine)
            .ok_or_else(|| HoldError::Unknown(machine.to_owned()))?;
        if !(row.online && row.state == Some(Machine::Running)) {
            let now = match (row.online, row.state) {
                (false, _) => "offline".to_owned(),
                (true, Some(state)) => serde_json::to_value(state)
                    .ok()
                    .and_then(|v| v.as_str().map(str::to_owned))
                    .unwrap_or_default(),
                (true, None) => "not yet reported".to_owned(),
            };
            return Err(HoldError::NotRunning(machine.to_owned(), now));
        }
        let token = self.token.clone().ok_or(HoldError::NoToken)?;
        let command = Command {
            command: "hold".into(),
            token,
            by: by.to_owned(),
        };
        let client = self
            .client
            .get()
            .ok_or_else(|| HoldError::Broker("not connected yet".into()))?;
        client
            .try_publish(
                format!("{}/{machine}/{}", self.prefix, message::COMMAND),
                QoS::AtLeastOnce,
                false,
                serde_json::to_vec(&command).expect("a command serialises"),
            )
            .map_err(|e| HoldError::Broker(e.to_string()))
    }

    /// The subscriptions that feed it.
    pub fn filters(&self) -> [String; 3] {
        lock(&self.view).filters()
    }

    /// One message from the broker; a payload that does not read is said once a topic.
    pub fn take(&self, topic: &str, payload: &[u8]) {
        match lock(&self.view).apply(topic, payload) {
            Ok(true) => {
                self.changes.send_modify(|n| *n += 1);
            }
            Ok(false) => {}
            Err(unreadable) => {
                if lock(&self.said).insert(unreadable.topic.clone()) {
                    tracing::warn!("shop overview: {unreadable}");
                }
            }
        }
    }

    /// Every machine.
    pub fn rows(&self) -> Vec<MachineRow> {
        lock(&self.view).rows()
    }

    /// Moves whenever a row changes.
    pub fn subscribe(&self) -> tokio::sync::watch::Receiver<u64> {
        self.changes.subscribe()
    }
}

fn lock<T>(mutex: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    mutex
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::telemetry::message::{State, Status};

    fn shop_with(token: Option<&str>, online: bool, state: Machine) -> Shop {
        let shop = Shop::new("whirl", token.map(str::to_owned));
        let status = Status {
            online,
            machine: "Lathe 3".into(),
            bridge: "cell-2".into(),
            pid: 1,
            session: "s".into(),
            version: "0".into(),
            since: "t".into(),
            keepalive_s: 10,
            console: None,
            reason: None,
        };
        let state = State {
            session: "s".into(),
            seq: 1,
            time: "t".into(),
            state,
            run: None,
            alarm: None,
            feed_override: None,
            last: None,
        };
        shop.take(
            "whirl/lathe-3/status",
            &serde_json::to_vec(&status).unwrap(),
        );
        shop.take("whirl/lathe-3/state", &serde_json::to_vec(&state).unwrap());
        shop
    }

    #[test]
    fn a_hold_goes_only_to_a_running_machine_with_the_shops_token() {
        let token = Some("shop-floor-token-0123");
        assert_eq!(
            shop_with(token, true, Machine::Running).hold("lathe-4", "me"),
            Err(HoldError::Unknown("lathe-4".into()))
        );
        assert_eq!(
            shop_with(token, true, Machine::Idle).hold("lathe-3", "me"),
            Err(HoldError::NotRunning("lathe-3".into(), "idle".into()))
        );
        assert_eq!(
            shop_with(token, false, Machine::Running).hold("lathe-3", "me"),
            Err(HoldError::NotRunning("lathe-3".into(), "offline".into()))
        );
        assert_eq!(
            shop_with(None, true, Machine::Running).hold("lathe-3", "me"),
            Err(HoldError::NoToken)
        );
        assert!(matches!(
            shop_with(token, true, Machine::Running).hold("lathe-3", "me"),
            Err(HoldError::Broker(_))
        ));
    }
}
