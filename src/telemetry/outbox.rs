//! The messages waiting for the broker, in order: what to publish next, what the broker
//! has taken, what to send again after a reconnection. No socket: the MQTT edge tells it
//! what happened and publishes what it hands out.
//!
//! Messages that matter (QoS 1: the status, the state, the events) wait in one queue, in
//! the order they were made, until the broker acknowledges them. MQTT 3.1.1 has a broker
//! acknowledge QoS 1 messages in the order it received them (section 4.6, [MQTT-4.6.0-2]),
//! so each PUBACK is the oldest one sent: the queue needs no packet ids. A connection lost
//! leaves the unacknowledged ones at the queue's head, and the next connection sends them
//! again (the reader tells a second delivery by its `seq`). The queue is bounded: past
//! `capacity`, the oldest message not yet sent is dropped, and counted. Progress (QoS 0)
//! never waits: only the newest is kept, and only while connected.

use std::collections::VecDeque;

/// One message to publish: its topic under the machine's root and its payload.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Outgoing {
    /// The topic's last level (`state`, `event`, …).
    pub topic: &'static str,
    /// The JSON payload.
    pub payload: Vec<u8>,
    /// QoS 1 (acknowledged) rather than 0.
    pub acknowledged: bool,
    /// Retained by the broker for later subscribers.
    pub retain: bool,
}

/// The queue, and what of it is out.
#[derive(Debug)]
pub struct Outbox {
    /// QoS 1 messages not yet acknowledged, oldest first; the first `sent` are out.
    queue: VecDeque<Outgoing>,
    sent: usize,
    /// The most QoS 1 messages out at once.
    window: usize,
    capacity: usize,
    dropped: u64,
    progress: Option<Outgoing>,
    connected: bool,
    /// The bridge's birth, first on every connection.
    birth: Outgoing,
    /// The bridge's goodbye, once it is closing.
    goodbye: Option<Outgoing>,
    /// The newest state made, sent again on a connection that has none queued: a broker
    /// restarted without persistence has lost its retained copy.
    state: Option<Outgoing>,
}

impl Outbox {
    /// An outbox whose connections start with `birth`, keeping at most `capacity` messages
    /// and sending at most `window` before their acknowledgements.
    pub fn new(birth: Outgoing, capacity: usize, window: usize) -> Outbox {
        Outbox {
            queue: VecDeque::new(),
            sent: 0,
            window: window.max(1),
            capacity: capacity.max(1),
            dropped: 0,
            progress: None,
            connected: false,
            birth,
            goodbye: None,
            state: None,
        }
    }

    /// A QoS 1 message to deliver. Returns whether one had to be dropped for it (the queue
    /// full while the broker is away). A status message is the goodbye (see
    /// [`Outbox::connected`]); a retained one (the state) is kept as the newest.
    pub fn push(&mut self, message: Outgoing) -> bool {
        if message.topic == self.birth.topic {
            self.goodbye = Some(message.clone());
        } else if message.retain {
            self.state = Some(message.clone());
        }
        self.queue.push_back(message);
        if self.queue.len() <= self.capacity {
            return false;
        }
        // The oldest not yet out goes; if all are out, the newest waits no more.
        let oldest = if self.sent < self.queue.len() - 1 {
            self.sent
        } else {
            self.queue.len() - 1
        };
        self.queue.remove(oldest);
        self.dropped += 1;
        true
    }

    /// A progress message: replaces the one not yet published; dropped while offline.
    pub fn progress(&mut self, message: Outgoing) {
        if self.connected {
            self.progress = Some(message);
        }
    }

    /// A connection is up (the broker's CONNACK): the birth goes first, then the newest
    /// state if none is queued, then what waited, from its oldest unacknowledged message.
    /// A goodbye not yet acknowledged stays last, after all the run handed over: a reader
    /// takes it as the session's end. One the broker has is said first in the birth's
    /// place: a birth then would show a bridge that has stopped as online.
    pub fn connected(&mut self) {
        self.connected = true;
        self.sent = 0;
        let status = self.birth.topic;
        let goodbye_waits = self.goodbye.as_ref().is_some_and(|goodbye| {
            self.queue
                .iter()
                .any(|m| m.topic == status && m.payload == goodbye.payload)
        });
        self.queue.retain(|m| m.topic != status);
        if let Some(state) = &self.state {
            if !self.queue.iter().any(|m| m.topic == state.topic) {
                self.queue.push_front(state.clone());
            }
        }
        match &self.goodbye {
            Some(goodbye) if goodbye_waits => {
                self.queue.push_front(self.birth.clone());
                self.queue.push_back(goodbye.clone());
            }
            Some(goodbye) => self.queue.push_front(goodbye.clone()),
            None => self.queue.push_front(self.birth.clone()),
        }
    }

    /// The connection is gone: what was out and not acknowledged is sent again on the
    /// next one; progress is not kept.
    pub fn disconnected(&mut self) {
        self.connected = false;
        self.sent = 0;
        self.progress = None;
    }

    /// The broker acknowledged a QoS 1 message: the oldest one out.
    pub fn acked(&mut self) {
        if self.sent > 0 {
            self.queue.pop_front();
            self.sent -= 1;
        }
    }

    /// The next message to publish now, if any: QoS 1 ones in order while fewer than the
    /// window are out, then the newest progress.
    pub fn to_send(&mut self) -> Option<Outgoing> {
        if !self.connected {
            return None;
        }
        if self.sent < self.window {
            if let Some(message) = self.queue.get(self.sent) {
                self.sent += 1;
                return Some(message.clone());
            }
        }
        self.progress.take()
    }

    /// The last message [`Outbox::to_send`] handed out could not be handed on (the
    /// client's queue full): it is the next to send again.
    pub fn unsend(&mut self, message: Outgoing) {
        if message.acknowledged {
            self.sent = self.sent.saturating_sub(1);
        } else if self.progress.is_none() {
            self.progress = Some(message);
        }
    }

    /// QoS 1 messages not yet acknowledged.
    pub fn waiting(&self) -> usize {
        self.queue.len()
    }

    /// Messages dropped so far because the queue was full.
    pub fn dropped(&self) -> u64 {
        self.dropped
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn message(topic: &'static str, n: u8) -> Outgoing {
        Outgoing {
            topic,
            payload: vec![n],
            acknowledged: true,
            retain: topic == "state",
        }
    }

    fn birth() -> Outgoing {
        message("status", 0)
    }

    fn drain(outbox: &mut Outbox) -> Vec<(&'static str, u8)> {
        std::iter::from_fn(|| outbox.to_send())
            .map(|m| (m.topic, m.payload[0]))
            .collect()
    }

    #[test]
    fn nothing_goes_before_the_connection_and_the_birth_goes_first() {
        let mut outbox = Outbox::new(birth(), 10, 10);
        outbox.push(message("event", 1));
        assert_eq!(outbox.to_send(), None);
        outbox.connected();
        assert_eq!(drain(&mut outbox), [("status", 0), ("event", 1)]);
    }

    #[test]
    fn a_lost_connection_sends_the_unacknowledged_again_in_order() {
        let mut outbox = Outbox::new(birth(), 10, 10);
        outbox.connected();
        for n in 1..=3 {
            outbox.push(message("event", n));
        }
        assert_eq!(drain(&mut outbox).len(), 4);
        outbox.acked(); // the birth
        outbox.acked(); // event 1
        outbox.disconnected();
        outbox.push(message("event", 4));
        outbox.connected();
        assert_eq!(
            drain(&mut outbox),
            [("status", 0), ("event", 2), ("event", 3), ("event", 4)]
        );
        for _ in 0..4 {
            outbox.acked();
        }
        assert_eq!(outbox.waiting(), 0);
    }

    #[test]
    fn no_more_than_the_window_is_out_before_its_acknowledgements() {
        let mut outbox = Outbox::new(birth(), 10, 2);
        outbox.connected();
        outbox.push(message("event", 1));
        outbox.push(message("event", 2));
        assert_eq!(drain(&mut outbox), [("status", 0), ("event", 1)]);
        outbox.acked();
        assert_eq!(drain(&mut outbox), [("event", 2)]);
    }

    #[test]
    fn a_full_queue_drops_its_oldest_unsent_message_and_counts_it() {
        let mut outbox = Outbox::new(birth(), 3, 10);
        for n in 1..=3 {
            assert!(!outbox.push(message("event", n)));
        }
        assert!(outbox.push(message("event", 4)));
        assert_eq!(outbox.dropped(), 1);
        outbox.connected();
        assert_eq!(
            drain(&mut outbox),
            [("status", 0), ("event", 2), ("event", 3), ("event", 4)]
        );
    }

    #[test]
    fn a_reconnection_restores_the_retained_state_if_none_is_queued() {
        let mut outbox = Outbox::new(birth(), 10, 10);
        outbox.connected();
        outbox.push(message("state", 7));
        assert_eq!(drain(&mut outbox).len(), 2);
        outbox.acked();
        outbox.acked();
        outbox.disconnected();
        outbox.connected();
        assert_eq!(drain(&mut outbox), [("status", 0), ("state", 7)]);
    }

    #[test]
    fn a_message_not_handed_on_goes_next_and_is_acknowledged_in_its_place() {
        let mut outbox = Outbox::new(birth(), 10, 10);
        outbox.connected();
        outbox.push(message("event", 1));
        outbox.push(message("event", 2));
        assert_eq!(outbox.to_send().map(|m| m.topic), Some("status"));
        let refused = outbox.to_send().unwrap();
        outbox.unsend(refused);
        assert_eq!(drain(&mut outbox), [("event", 1), ("event", 2)]);
        for _ in 0..3 {
            outbox.acked();
        }
        assert_eq!(outbox.waiting(), 0);
    }

    #[test]
    fn a_goodbye_made_before_the_first_connection_goes_after_what_waited() {
        let mut outbox = Outbox::new(birth(), 10, 10);
        outbox.push(message("event", 1));
        outbox.push(message("state", 2));
        outbox.push(message("status", 9));
        outbox.connected();
        assert_eq!(
            drain(&mut outbox),
            [("status", 0), ("event", 1), ("state", 2), ("status", 9)]
        );
    }

    #[test]
    fn a_goodbye_lost_with_its_connection_is_sent_again_last() {
        let mut outbox = Outbox::new(birth(), 10, 10);
        outbox.connected();
        outbox.push(message("event", 1));
        outbox.push(message("status", 9));
        assert_eq!(drain(&mut outbox).len(), 3);
        outbox.acked(); // the birth
        outbox.disconnected();
        outbox.connected();
        assert_eq!(
            drain(&mut outbox),
            [("status", 0), ("event", 1), ("status", 9)]
        );
    }

    #[test]
    fn once_the_broker_has_the_goodbye_a_later_connection_says_it_in_the_births_place() {
        let mut outbox = Outbox::new(birth(), 10, 10);
        outbox.connected();
        outbox.push(message("status", 9));
        assert_eq!(drain(&mut outbox).len(), 2);
        outbox.acked();
        outbox.acked();
        outbox.disconnected();
        outbox.connected();
        assert_eq!(drain(&mut outbox), [("status", 9)]);
    }

    #[test]
    fn progress_keeps_only_the_newest_and_only_while_connected() {
        let progress = |n| Outgoing {
            acknowledged: false,
            ..message("progress", n)
        };
        let mut outbox = Outbox::new(birth(), 10, 10);
        outbox.progress(progress(1));
        outbox.connected();
        outbox.progress(progress(2));
        outbox.progress(progress(3));
        assert_eq!(drain(&mut outbox), [("status", 0), ("progress", 3)]);
        outbox.progress(progress(4));
        outbox.disconnected();
        outbox.connected();
        assert_eq!(drain(&mut outbox), [("status", 0)]);
    }
}
