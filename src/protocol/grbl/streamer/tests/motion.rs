//! When the motion is done: the status reports after the last acknowledgement that prove
//! the planner empty ([`Event::MotionDone`]), and the holds that are no stall.

use super::*;

/// A streamer of `n` moves with every line sent and acknowledged, its events read up to
/// [`Event::Done`]. With `opt`, `$I` goes first and is answered `[OPT:opt]`.
fn all_acked(n: usize, opt: Option<&str>) -> Streamer {
    let config = StreamerConfig {
        query_build_info: opt.is_some(),
        ..StreamerConfig::default()
    };
    let mut streamer = Streamer::new(moves(n), config).unwrap();
    if let Some(opt) = opt {
        assert_eq!(streamer.transmit().unwrap(), b"$I\n");
        streamer.receive(format!("[VER:1.1f.20250102:]\r\n[OPT:{opt}]\r\nok\r\n").as_bytes());
    }
    streamer.transmit().unwrap();
    streamer.receive(&b"ok\r\n".repeat(n));
    assert_eq!(streamer.events().next_back(), Some(Event::Done));
    streamer
}

/// Reads one status report (`body` between `<` and `>`) and returns the events after its
/// [`Event::Status`].
fn report(streamer: &mut Streamer, body: &str) -> Vec<Event> {
    streamer.receive(format!("<{body}>\r\n").as_bytes());
    let events: Vec<Event> = streamer.events().collect();
    assert!(
        matches!(events.first(), Some(Event::Status(_))),
        "{events:?}"
    );
    events[1..].to_vec()
}

#[test]
fn the_motion_is_done_at_an_idle_report_with_every_planner_block_of_build_info_free() {
    let mut streamer = all_acked(5, Some("VNMSL,35,1024"));
    assert_eq!(streamer.planner_blocks(), Some(35));
    assert!(report(&mut streamer, "Run|MPos:1,0,0|Bf:30,1000|FS:100,0").is_empty());
    // `Idle` with a block still queued: grbl answered before starting the cycle. With
    // `$I`'s 35 blocks, 34 free is not empty, though no report ever showed more.
    assert!(report(&mut streamer, "Idle|MPos:2,0,0|Bf:34,1023|FS:0,0").is_empty());
    assert_eq!(
        report(&mut streamer, "Idle|MPos:4,0,0|Bf:35,1023|FS:0,0"),
        [Event::MotionDone]
    );
    // Once.
    assert!(report(&mut streamer, "Idle|MPos:4,0,0|Bf:35,1023|FS:0,0").is_empty());
    assert!(streamer.is_finished());
    assert_eq!(streamer.resume_point(), None);
}

#[test]
fn without_build_info_the_most_free_blocks_ever_reported_is_the_planner_size() {
    let mut streamer = Streamer::new(moves(5), no_query()).unwrap();
    streamer.transmit().unwrap();
    // Before the stream ran: the whole planner free.
    streamer.receive(b"<Idle|MPos:0,0,0|Bf:15,127|FS:0,0>\r\n");
    streamer.receive(&b"ok\r\n".repeat(5));
    assert_eq!(streamer.events().next_back(), Some(Event::Done));
    assert_eq!(streamer.planner_blocks(), None);
    assert!(report(&mut streamer, "Run|MPos:1,0,0|Bf:12,127|FS:100,0").is_empty());
    assert!(report(&mut streamer, "Idle|MPos:3,0,0|Bf:14,127|FS:0,0").is_empty());
    assert_eq!(
        report(&mut streamer, "Idle|MPos:4,0,0|Bf:15,127|FS:0,0"),
        [Event::MotionDone]
    );

    // With no report before, the first one's free blocks are the most ever seen.
    let mut streamer = all_acked(3, None);
    assert_eq!(
        report(&mut streamer, "Idle|MPos:2,0,0|Bf:15,127|FS:0,0"),
        [Event::MotionDone]
    );
}

#[test]
fn without_a_buffer_field_two_idle_reports_in_a_row_end_the_motion() {
    let mut streamer = all_acked(3, Some("V,15,128"));
    assert!(report(&mut streamer, "Idle|MPos:0,0,0|FS:0,0").is_empty());
    // A `Run` between restarts the count: the first `Idle` came before the cycle.
    assert!(report(&mut streamer, "Run|MPos:1,0,0|FS:100,0").is_empty());
    assert!(report(&mut streamer, "Idle|MPos:2,0,0|FS:0,0").is_empty());
    assert_eq!(
        report(&mut streamer, "Idle|MPos:2,0,0|FS:0,0"),
        [Event::MotionDone]
    );
    assert!(report(&mut streamer, "Idle|MPos:2,0,0|FS:0,0").is_empty());
}

#[test]
fn only_reports_read_after_the_last_ok_count() {
    let mut streamer = Streamer::new(moves(3), no_query()).unwrap();
    streamer.transmit().unwrap();
    // Before every line is acknowledged an empty planner proves lines done, not the end.
    streamer.receive(b"ok\r\n<Idle|MPos:0,0,0|Bf:15,127|FS:0,0>\r\n");
    // Nor does a report in the read that brings the last `ok`: `Done` comes after it.
    streamer.receive(b"ok\r\nok\r\n<Idle|MPos:2,0,0|Bf:15,127|FS:0,0>\r\n");
    let events: Vec<Event> = streamer.events().collect();
    assert!(!events.contains(&Event::MotionDone), "{events:?}");
    assert_eq!(events.last(), Some(&Event::Done));
    assert_eq!(
        report(&mut streamer, "Idle|MPos:2,0,0|Bf:15,127|FS:0,0"),
        [Event::MotionDone]
    );

    // An empty program is done before any report: the first empty planner ends it.
    let mut streamer = Streamer::new(Vec::new(), no_query()).unwrap();
    assert_eq!(streamer.next_event(), Some(Event::Done));
    assert_eq!(
        report(&mut streamer, "Idle|MPos:0,0,0|Bf:15,127|FS:0,0"),
        [Event::MotionDone]
    );
}

#[test]
fn a_stopped_stream_never_ends_its_motion() {
    let mut streamer = all_acked(3, None);
    assert!(report(&mut streamer, "Run|MPos:1,0,0|Bf:13,127|FS:100,0").is_empty());
    // An alarm with moves pending stops the stream: its motion never finished.
    streamer.receive(b"ALARM:2\r\n");
    assert!(streamer.events().any(|e| e
        == Event::Stopped {
            reason: StopReason::Alarm { code: 2 }
        }));
    assert!(report(&mut streamer, "Idle|MPos:1,0,0|Bf:15,127|FS:0,0").is_empty());
    assert!(report(&mut streamer, "Idle|MPos:1,0,0|FS:0,0").is_empty());
}

#[test]
fn a_hold_is_no_stall_and_no_end_of_motion() {
    let mut streamer = all_acked(5, Some("VNMSL,35,1024"));
    assert!(!streamer.is_held());
    assert!(report(&mut streamer, "Run|MPos:1,0,0|Bf:31,1023|FS:100,0").is_empty());
    // The caller's hold: held from the request on, before the controller says so.
    streamer.feed_hold();
    assert!(streamer.is_held());
    assert_eq!(streamer.transmit().unwrap(), b"!");
    assert!(report(&mut streamer, "Hold:1|MPos:1.5,0,0|Bf:32,1023|FS:20,0").is_empty());
    assert!(report(&mut streamer, "Hold:0|MPos:1.6,0,0|Bf:32,1023|FS:0,0").is_empty());
    // Resumed: still held until a report says otherwise.
    streamer.resume();
    assert!(streamer.is_held());
    assert!(report(&mut streamer, "Run|MPos:2,0,0|Bf:33,1023|FS:100,0").is_empty());
    assert!(!streamer.is_held());
    // The controller's own holds: a safety door, a tool change.
    for held in ["Door:1", "Tool"] {
        let body = format!("{held}|MPos:3,0,0|Bf:34,1023|FS:0,0");
        assert!(report(&mut streamer, &body).is_empty());
        assert!(streamer.is_held(), "{held}");
    }
    assert_eq!(
        report(&mut streamer, "Idle|MPos:4,0,0|Bf:35,1023|FS:0,0"),
        [Event::MotionDone]
    );
    assert!(!streamer.is_held());
}

#[test]
fn polling_the_model_controller_after_done_ends_the_motion() {
    let mut fake = Fake::grblhal(1024);
    let mut streamer = Streamer::new(moves(20), StreamerConfig::default()).unwrap();
    drive(&mut streamer, &mut fake);
    assert_eq!(streamer.events().next_back(), Some(Event::Done));
    // The model still has moves planned, then none.
    fake.status = "<Run|MPos:19,0,0,0|Bf:33,1023|FS:100,0>".into();
    assert!(streamer.poll(Duration::from_secs(1)));
    fake.write(&streamer.transmit().unwrap());
    streamer.receive(&fake.take_output());
    assert!(!streamer.events().any(|e| e == Event::MotionDone));
    fake.status = "<Idle|MPos:20,0,0,0|Bf:35,1023|FS:0,0>".into();
    assert!(streamer.poll(Duration::from_millis(1200)));
    fake.write(&streamer.transmit().unwrap());
    streamer.receive(&fake.take_output());
    assert_eq!(streamer.events().next_back(), Some(Event::MotionDone));
}
