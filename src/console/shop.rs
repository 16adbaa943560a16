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
use std::sync::Mutex;

use view::{MachineRow, ShopView};

/// The overview's state: the view, and a counter each change moves for the pages.
#[derive(Debug)]
pub struct Shop {
    view: Mutex<ShopView>,
    changes: tokio::sync::watch::Sender<u64>,
    /// Topics whose payload did not read, each said once.
    said: Mutex<BTreeSet<String>>,
}

impl Shop {
    /// The overview of the machines under `prefix`.
    pub fn new(prefix: &str) -> Shop {
        Shop {
            view: Mutex::new(ShopView::new(prefix)),
            changes: tokio::sync::watch::Sender::new(0),
            said: Mutex::default(),
        }
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
