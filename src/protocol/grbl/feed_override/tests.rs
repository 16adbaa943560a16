use super::*;

/// What grbl does with one byte (`protocol.c`), 10–200 %.
fn grbl(v: u16, byte: u8) -> u16 {
    let next = match byte {
        RESET => 100,
        COARSE_PLUS => v + 10,
        COARSE_MINUS => v.saturating_sub(10),
        FINE_PLUS => v + 1,
        FINE_MINUS => v.saturating_sub(1),
        other => panic!("not a feed override byte: {other:#x}"),
    };
    next.clamp(10, 200)
}

#[test]
fn the_bytes_reach_every_value_from_every_value_without_overshooting() {
    for from in 10..=200_u16 {
        for to in 10..=200_u16 {
            let mut v = from;
            let mut bytes = 0;
            while let Some(byte) = next_byte(Some(v), to) {
                let next = grbl(v, byte);
                // Never past the target (so grbl's clamp never bites), and always moving.
                assert!(next != v, "{from}→{to}: stuck at {v}");
                if byte != RESET {
                    assert!(
                        next.abs_diff(to) < v.abs_diff(to),
                        "{from}→{to}: {v}→{next}"
                    );
                }
                v = next;
                bytes += 1;
                assert!(bytes <= 30, "{from}→{to}: too many bytes");
            }
            assert_eq!(v, to, "{from}→{to}");
        }
    }
    // By hand: 100 → 137 is three coarse and seven fine; 195 → 100 one reset; 200 → 110
    // a reset and one coarse, not nine coarse.
    let path = |from: u16, to: u16| {
        let mut v = from;
        let mut out = vec![];
        while let Some(b) = next_byte(Some(v), to) {
            out.push(b);
            v = grbl(v, b);
        }
        out
    };
    let mut p137 = vec![COARSE_PLUS; 3];
    p137.extend([FINE_PLUS; 7]);
    assert_eq!(path(100, 137), p137);
    assert_eq!(path(195, 100), vec![RESET]);
    assert_eq!(path(200, 110), vec![RESET, COARSE_PLUS]);
    // Unknown: reset to a known 100 first.
    assert_eq!(next_byte(None, 120), Some(RESET));
}

#[test]
fn the_feed_override_reads_from_ov() {
    let f = |s: &[&str]| reported(&s.iter().map(|s| s.to_string()).collect::<Vec<_>>());
    assert_eq!(f(&["Ov:120,100,100", "Pn:Z"]), Some(120));
    assert_eq!(f(&["Pn:Z", "Ov:10,25,200"]), Some(10));
    assert_eq!(f(&["Pn:Z"]), None);
    assert_eq!(f(&["Ov:x,100,100"]), None);
}

#[test]
fn one_byte_goes_out_at_a_time_and_the_next_once_ov_shows_it() {
    let mut o = FeedOverride::default();
    // Unknown value: a reset first.
    assert_eq!(o.ask(112), Some(RESET));
    // Reports without Ov: and a second ask send nothing more.
    assert_eq!(o.on_report(None), (None, None));
    assert_eq!(o.ask(112), None);
    // Ov:100 confirms the reset (the value before it was unknown): +10 goes out.
    assert_eq!(
        o.on_report(Some(100)),
        (Some(COARSE_PLUS), Some(Change::Reported(100)))
    );
    // A report taken before the byte arrived still shows 100: wait, do not send again.
    assert_eq!(o.on_report(Some(100)), (None, None));
    assert_eq!(
        o.on_report(Some(110)),
        (Some(FINE_PLUS), Some(Change::Reported(110)))
    );
    assert_eq!(
        o.on_report(Some(111)),
        (Some(FINE_PLUS), Some(Change::Reported(111)))
    );
    assert_eq!(o.on_report(Some(112)), (None, Some(Change::Reported(112))));
    assert_eq!(o.asked(), None);
    assert_eq!(o.reported(), Some(112));
    // Someone turns the knob on the machine: reported, nothing sent.
    assert_eq!(o.on_report(Some(90)), (None, Some(Change::Reported(90))));
}

#[test]
fn a_controller_that_does_not_report_ov_is_given_up_on_after_grbls_refresh() {
    let mut o = FeedOverride::default();
    assert_eq!(o.ask(120), Some(RESET));
    for _ in 1..UNCONFIRMED_REPORTS {
        assert_eq!(o.on_report(None), (None, None));
    }
    assert_eq!(
        o.on_report(None),
        (
            None,
            Some(Change::NotTaken {
                asked: 120,
                reported: None
            })
        )
    );
    // Given up: nothing more goes out until asked again.
    assert_eq!(o.on_report(None), (None, None));
    assert_eq!(o.asked(), None);
}

#[test]
fn a_byte_the_controller_does_not_take_is_not_followed_by_another() {
    // A controller built with a 150 % ceiling: +10 from 150 changes nothing.
    let mut o = FeedOverride::default();
    o.on_report(Some(150));
    assert_eq!(o.ask(170), Some(COARSE_PLUS));
    for _ in 1..UNCONFIRMED_REPORTS {
        assert_eq!(o.on_report(Some(150)), (None, None));
    }
    assert_eq!(
        o.on_report(Some(150)).1,
        Some(Change::NotTaken {
            asked: 170,
            reported: Some(150)
        })
    );
}
