use super::*;
use crate::geometry::linkage::{Linkage, Ring, Whirling};
use crate::plan::budget::{cusp_at, insert_turn};

/// An internal ring of R = 30 mm, nose 0.5 mm, on a 4 mm lead.
fn linkage() -> Linkage {
    Linkage {
        p: 4.0 / std::f64::consts::TAU,
        ring: Ring {
            whirling: Whirling::Internal,
            radius: 30.0,
            nose: 0.5,
            installation: 0.0,
            edge_half_angle: std::f64::consts::FRAC_PI_2,
        },
    }
}

#[test]
fn the_cusp_grows_with_the_square_of_the_override() {
    // Four inserts, the ring at 2000 rpm, the work at 20 rpm: the work turns
    // 2π·20/(4·2000) = π/200 rad between hits; at ρ = 5 mm that is an arc s = π/40 mm, and
    // the cusp s²/8·(1/5 − 1/30) = (π/40)²/48 mm, worked out by hand.
    let l = linkage();
    let planned = cusp_at(5.0, &l, insert_turn(4, 20.0, 2000.0));
    let by_hand = (std::f64::consts::PI / 40.0).powi(2) / 48.0;
    assert!((planned - by_hand).abs() < 1e-15, "{planned} vs {by_hand}");
    // An override k turns the work k times as fast; the ring keeps its speed.
    let cap = FeedCap::new(0.01, 0.005, planned, GRBL);
    for percent in [10_u16, 50, 100, 137, 200] {
        let k = f64::from(percent) / 100.0;
        let at = cusp_at(5.0, &l, insert_turn(4, 20.0 * k, 2000.0));
        assert!((cap.cusp_at(percent) - at).abs() < 1e-15, "{percent} %");
    }
}

#[test]
fn the_cap_is_where_the_cusp_fills_its_share() {
    // Δ = 10 µm, the program held to 8.5 µm with a 4 µm cusp in it: the cusp may take
    // 4 + 1.5 = 5.5 µm, so k² = 5.5/4 and k = 1.1726…: 117 % is the fastest whole percent.
    let cap = FeedCap::new(0.01, 0.0085, 0.004, GRBL);
    assert!((cap.cusp_share_mm - 0.0055).abs() < 1e-15);
    assert_eq!(cap.max_percent, 117);
    assert!(cap.cusp_at(117) <= cap.cusp_share_mm);
    assert!(cap.cusp_at(118) > cap.cusp_share_mm);
    assert_eq!(cap.check(117), Ok(117));
    let refused = cap.check(118).unwrap_err();
    assert!(matches!(
        refused,
        OverrideError::AboveCap {
            asked: 118,
            max: 117,
            ..
        }
    ));
    let text = refused.to_string();
    assert!(text.contains("118 %") && text.contains("117 %"), "{text}");
    assert!(
        text.contains("insert cusp") && text.contains("square"),
        "{text}"
    );
    // Slowing down is always allowed, down to the controller's least.
    assert_eq!(cap.check(10), Ok(10));
    let below = cap.check(9).unwrap_err();
    assert!(matches!(
        below,
        OverrideError::BelowRange {
            asked: 9,
            min: 10,
            ..
        }
    ));
    assert!(below.to_string().contains("grbl's"), "{below}");
}

#[test]
fn the_controller_caps_a_cusp_with_room_to_spare() {
    // A 0.1 µm cusp with 5 µm unspent: 100·√51 ≈ 714 %, past grbl's 200 %.
    let cap = FeedCap::new(0.01, 0.005, 0.0001, GRBL);
    assert_eq!(cap.max_percent, 200);
    assert!((cap.cusp_limit_percent - 100.0 * 51f64.sqrt()).abs() < 1e-9);
    assert!(
        cap.reason.contains("200 %") && cap.reason.contains("grbl's"),
        "{}",
        cap.reason
    );
    assert!(cap.reason.contains("714 %"), "{}", cap.reason);
    // No cusp at all (the ring flatter than the work): only the controller caps it.
    let nil = FeedCap::new(0.01, 0.009, 0.0, MODBUS);
    assert_eq!(nil.max_percent, 200);
    assert!(nil.cusp_limit_percent.is_infinite());
    assert!(
        nil.reason.contains("Modbus") && nil.reason.contains("nil"),
        "{}",
        nil.reason
    );
}

#[test]
fn a_plan_that_spends_all_of_delta_runs_no_faster_than_planned() {
    // Exactly spent: k = 1.
    let spent = FeedCap::new(0.01, 0.01, 0.003, GRBL);
    assert_eq!(spent.max_percent, 100);
    assert!(spent.check(101).is_err());
    // Over-spent (a measured plan at its limit): still 100 %, the plan itself, and says why.
    let over = FeedCap::new(0.01, 0.0102, 0.003, GRBL);
    assert_eq!(over.max_percent, 100);
    assert!(over.reason.contains("already spends"), "{}", over.reason);
}

#[test]
fn a_key_pressed_too_often_is_held_at_the_cap_with_the_reason() {
    let cap = FeedCap::new(0.01, 0.0085, 0.004, GRBL);
    let (held, why) = cap.clamp(127);
    assert_eq!(held, 117);
    let why = why.unwrap();
    assert!(
        why.contains("117 %") && why.contains("insert cusp"),
        "{why}"
    );
    let (held, why) = cap.clamp(0);
    assert_eq!(held, 10);
    assert!(why.unwrap().contains("slowest"));
    assert_eq!(cap.clamp(90), (90, None));
}
