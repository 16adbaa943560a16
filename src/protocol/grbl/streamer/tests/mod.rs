//! The streamer's unit tests, against the model controller ([`Fake`]) or bytes written by
//! hand: the fixtures here, the tests by topic in the sibling files.

mod connect;
mod feed_override;
mod interrupts;
mod motion;
mod properties;
mod resume;
mod stops;
mod streaming;

use super::*;
use crate::protocol::grbl::fake::Fake;

fn program(lines: &[&str]) -> Vec<String> {
    lines.iter().map(|l| l.to_string()).collect()
}

/// `n` lines of `G1 X<i> F100`, each about a dozen bytes.
fn moves(n: usize) -> Vec<String> {
    (0..n).map(|i| format!("G1 X{i} F100")).collect()
}

fn no_query() -> StreamerConfig {
    StreamerConfig {
        query_build_info: false,
        ..StreamerConfig::default()
    }
}

/// Runs streamer and controller against each other until the stream finishes or
/// nothing moves; checks the buffer invariants on the way.
fn drive(streamer: &mut Streamer, fake: &mut Fake) {
    for _ in 0..10_000 {
        let sent = streamer.transmit();
        if let Some(bytes) = &sent {
            fake.write(bytes);
        }
        assert!(!fake.overflowed, "receive buffer overflowed");
        assert!(streamer.in_flight_bytes() < streamer.rx_size());
        fake.process_all();
        let output = fake.take_output();
        streamer.receive(&output);
        if streamer.is_finished() && sent.is_none() && output.is_empty() {
            return;
        }
    }
    panic!("stream did not finish");
}

fn sent_indices(events: &[Event]) -> Vec<usize> {
    events
        .iter()
        .filter_map(|e| match e {
            Event::Sent { index, .. } => Some(*index),
            _ => None,
        })
        .collect()
}

fn acked_indices(events: &[Event]) -> Vec<usize> {
    events
        .iter()
        .filter_map(|e| match e {
            Event::Acked { index } => Some(*index),
            _ => None,
        })
        .collect()
}

/// Transmits once and returns how many program lines went out.
fn sent_count(streamer: &mut Streamer) -> usize {
    streamer.transmit().unwrap();
    sent_indices(&streamer.events().collect::<Vec<_>>()).len()
}
