//! The feed override through the streamer: real-time bytes out one at a time, each after
//! a status report's `Ov:` shows the one before, and events for what the controller says.

use super::*;
use crate::protocol::grbl::feed_override::{COARSE_PLUS, FINE_PLUS, RESET, UNCONFIRMED_REPORTS};

/// A streamer past its state check, with nothing left to send.
fn started() -> Streamer {
    let config = StreamerConfig {
        wait_for_banner: false,
        check_state: false,
        ..no_query()
    };
    let mut s = Streamer::new(program(&["G4 P0"]), config).unwrap();
    assert_eq!(s.transmit().unwrap(), b"G4 P0\n");
    s
}

fn report(ov: Option<u16>) -> Vec<u8> {
    match ov {
        Some(v) => format!("<Run|MPos:0,0,0|FS:100,0|Ov:{v},100,100>\r\n").into_bytes(),
        None => b"<Run|MPos:0,0,0|FS:100,0>\r\n".to_vec(),
    }
}

#[test]
fn the_override_goes_out_a_byte_a_report_and_is_read_back_from_ov() {
    let mut s = started();
    s.feed_override(111);
    // Not known yet: back to 100 % first.
    assert_eq!(s.transmit(), Some(vec![RESET]));
    s.receive(&report(Some(100)));
    assert_eq!(s.transmit(), Some(vec![COARSE_PLUS]));
    let events: Vec<Event> = s.events().collect();
    assert!(events.contains(&Event::FeedOverride { percent: 100 }));
    // A report taken before the byte took: nothing more goes out.
    s.receive(&report(Some(100)));
    assert_eq!(s.transmit(), None);
    s.receive(&report(Some(110)));
    assert_eq!(s.transmit(), Some(vec![FINE_PLUS]));
    s.receive(&report(Some(111)));
    assert_eq!(s.transmit(), None);
    assert_eq!(s.reported_feed_override(), Some(111));
    let events: Vec<Event> = s.events().collect();
    assert!(events.contains(&Event::FeedOverride { percent: 111 }));
}

#[test]
fn a_controller_without_ov_is_reported_not_taking_the_override() {
    let mut s = started();
    s.feed_override(120);
    assert_eq!(s.transmit(), Some(vec![RESET]));
    for _ in 0..UNCONFIRMED_REPORTS {
        s.receive(&report(None));
    }
    let events: Vec<Event> = s.events().collect();
    assert!(
        events.contains(&Event::FeedOverrideNotTaken {
            asked: 120,
            reported: None
        }),
        "{events:?}"
    );
    assert_eq!(s.transmit(), None);
}
