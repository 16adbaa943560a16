//! Properties, over generated programs and controller output: the count never overflows the
//! receive buffer, and nothing panics.

use super::*;
use proptest::prelude::*;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// Character counting never lets the unanswered bytes exceed the receive buffer,
    /// whatever the line lengths and however the answers are timed and split.
    #[test]
    fn unanswered_bytes_never_exceed_the_receive_buffer(
        lengths in proptest::collection::vec(0usize..=120, 1..80),
        rx_size in prop_oneof![Just(128usize), Just(200), Just(1024)],
        query in any::<bool>(),
        steps in proptest::collection::vec((0u8..3, 1usize..40), 0..600),
    ) {
        let lines: Vec<String> = lengths
            .iter()
            .enumerate()
            .map(|(i, &n)| format!("{i}{}", "A".repeat(n)).chars().take(n.max(1)).collect())
            .collect();
        let config = StreamerConfig {
            query_build_info: query,
            // Without `$I` the streamer must be told the size.
            rx_size: if query { DEFAULT_RX_SIZE } else { rx_size },
            ..StreamerConfig::default()
        };
        let mut streamer = Streamer::new(lines.clone(), config).unwrap();
        let mut fake = Fake::grbl(rx_size);
        let mut wire: VecDeque<u8> = VecDeque::new();
        let mut events = Vec::new();
        let mut step = |action: u8, amount: usize, streamer: &mut Streamer, fake: &mut Fake| {
            match action {
                0 => {
                    if let Some(bytes) = streamer.transmit() {
                        fake.write(&bytes);
                    }
                }
                1 => {
                    for _ in 0..amount % 4 + 1 {
                        fake.process();
                    }
                }
                _ => {
                    wire.extend(fake.take_output());
                    let n = amount.min(wire.len());
                    let chunk: Vec<u8> = wire.drain(..n).collect();
                    streamer.receive(&chunk);
                }
            }
        };
        for &(action, amount) in &steps {
            step(action, amount, &mut streamer, &mut fake);
            prop_assert!(!fake.overflowed);
            prop_assert!(fake.buffered() < rx_size);
            prop_assert!(streamer.in_flight_bytes() < streamer.rx_size());
            prop_assert!(streamer.rx_size() <= rx_size);
            events.extend(streamer.events());
        }
        for _ in 0..10_000 {
            if streamer.is_finished() {
                break;
            }
            for action in 0..3 {
                step(action, usize::MAX, &mut streamer, &mut fake);
                prop_assert!(!fake.overflowed);
                prop_assert!(streamer.in_flight_bytes() < streamer.rx_size());
            }
            events.extend(streamer.events());
        }
        prop_assert_eq!(&fake.executed, &lines);
        let all: Vec<usize> = (0..lines.len()).collect();
        prop_assert_eq!(sent_indices(&events), all.clone());
        prop_assert_eq!(acked_indices(&events), all);
        prop_assert_eq!(events.last(), Some(&Event::Done));
    }

    /// Any bytes from the controller, in any chunks, between transmits: no panic, the
    /// count stays within the buffer, and only sent lines are ever answered.
    #[test]
    fn any_controller_output_is_survived(
        chunks in proptest::collection::vec(
            prop_oneof![
                proptest::collection::vec(any::<u8>(), 0..24),
                prop_oneof![
                    Just(b"ok\r\n".to_vec()),
                    Just(b"error:20\r\n".to_vec()),
                    Just(b"error:9\n".to_vec()),
                    Just(b"ALARM:2\r\n".to_vec()),
                    Just(b"Grbl 1.1h ['$' for help]\r\n".to_vec()),
                    Just(b"<Idle|MPos:0,0,0|Bf:15,127|Ln:3>\r\n".to_vec()),
                    Just(b"[OPT:V,15,64]\r\n".to_vec()),
                    Just(b"[OPT:V,15,0]\r\n".to_vec()),
                    Just(b"\r".to_vec()),
                ],
            ],
            0..60,
        ),
        commands in proptest::collection::vec(0u8..8, 0..60),
    ) {
        let lines: Vec<String> = (0..30).map(|i| format!("N{i} G1 X{i} F100")).collect();
        let mut streamer = Streamer::new(lines, StreamerConfig::default()).unwrap();
        let mut sent = std::collections::HashSet::new();
        for (i, chunk) in chunks.iter().enumerate() {
            match commands.get(i) {
                Some(0) => streamer.feed_hold(),
                Some(1) => streamer.resume(),
                Some(2) => streamer.soft_reset(),
                Some(3) => {
                    streamer.poll(Duration::from_millis(i as u64 * 100));
                }
                _ => {}
            }
            let _ = streamer.transmit();
            streamer.receive(chunk);
            prop_assert!(streamer.in_flight_bytes() < streamer.rx_size());
            for event in streamer.events() {
                match event {
                    Event::Sent { index, .. } => {
                        sent.insert(index);
                    }
                    Event::Acked { index }
                    | Event::Error { index, .. }
                    | Event::Rejected { index, .. }
                    | Event::Discarded { index } => prop_assert!(sent.contains(&index)),
                    _ => {}
                }
            }
            let _ = streamer.resume_point();
            let _ = streamer.progress();
        }
    }
}
