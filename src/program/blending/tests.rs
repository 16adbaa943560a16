use super::*;
use crate::program::Position;
use proptest::prelude::*;

/// The LinuxCNC lathe's accelerations (machine-profiles/linuxcnc-lathe.toml).
const LATHE: Accels = Accels {
    x: 400.0,
    z: 400.0,
    c: 3600.0,
};

fn segment(dx: f64, dz: f64, dc: f64, seconds: f64) -> Segment {
    Segment {
        dx,
        dz,
        dc,
        seconds,
    }
}

fn linked(x: f64, z: f64, c: f64, minutes: f64) -> Move {
    Move::Linked { x, z, c, minutes }
}

/// A program that starts at (x0, 0, 0) and runs the given linked moves, each given as
/// (ΔX, ΔZ, ΔC, seconds).
fn zigzag(x0: f64, moves: &[(f64, f64, f64, f64)]) -> Program {
    let mut program = Program {
        moves: vec![Move::Rapid {
            x: Some(x0),
            z: Some(0.0),
            c: Some(0.0),
        }],
    };
    let (mut x, mut z, mut c) = (x0, 0.0, 0.0);
    for &(dx, dz, dc, seconds) in moves {
        (x, z, c) = (x + dx, z + dz, c + dc);
        program.moves.push(linked(x, z, c, seconds / 60.0));
    }
    program
}

/// Every linked move's (ΔC, minutes), in order.
fn linked_moves(program: &Program) -> Vec<(f64, f64)> {
    program
        .steps(Position::UNKNOWN)
        .filter_map(|s| match *s.action {
            Move::Linked { minutes, .. } => Some((s.to.c? - s.from.c?, minutes)),
            _ => None,
        })
        .collect()
}

#[test]
fn a_corner_gives_the_formulas_value() {
    // Both moves 2° in 0.04 s (ω = 50°/s); slopes (0.05, 0.0005) and (−0.05, 0.0005) mm/°, so
    // |Δs| = 0.1 mm/°. X: 400·2/0.1 = 8000°/s², Z: 400·2/0.001 = 800 000°/s², C 3600°/s²:
    // C limits, halved, a = 1800°/s². Deviation 50²/(8·1800)·0.1 mm, reach 50²/(2·1800)°.
    let first = segment(0.1, 0.001, 2.0, 0.04);
    let second = segment(-0.1, 0.001, 2.0, 0.04);
    assert_eq!(first.rate(), 50.0);
    assert_eq!(first.c_accel(LATHE), 1800.0);
    let corner = Corner::between(&first, &second, LATHE).unwrap();
    assert!((corner.kink - 0.1).abs() < 1e-15);
    let expected = 2500.0 / 14_400.0 * 0.1;
    assert!((corner.deviation() - expected).abs() < 1e-15, "{corner:?}");
    assert!((corner.reach_deg() - 2500.0 / 3600.0).abs() < 1e-15);
    // 0.69° reaches past the middle of neither 2° move.
    assert!(!corner.overlaps());
}

#[test]
fn the_slower_rate_and_the_smaller_acceleration_set_the_blend() {
    // 1 mm of X over 2°: X allows 400·2/1 = 800°/s² of C, halved 400. The other move is C-limited
    // (1800°/s²) but slower: 2° in 0.1 s, 20°/s.
    let steep = segment(1.0, 0.0, 2.0, 0.04);
    let slow = segment(0.0, 0.01, 2.0, 0.1);
    assert_eq!(steep.c_accel(LATHE), 400.0);
    assert_eq!(slow.c_accel(LATHE), 1800.0);
    for (a, b) in [(&steep, &slow), (&slow, &steep)] {
        let corner = Corner::between(a, b, LATHE).unwrap();
        assert_eq!(corner.blend_rate, 20.0);
        assert_eq!(corner.accel, 400.0);
        // |Δs| = |(0.5, 0) − (0, 0.005)|.
        let kink = 0.5f64.hypot(0.005);
        assert!((corner.deviation() - 400.0 / 3200.0 * kink).abs() < 1e-15);
    }
}

#[test]
fn a_move_that_does_not_move_x_drops_the_x_term() {
    // With ΔX = 0 only C and Z can limit: Z allows 400·2/0.5 = 1600°/s² of C, halved 800. A
    // vanishing ΔX would otherwise have given an unlimited term, not a zero one.
    assert_eq!(segment(0.0, 0.5, 2.0, 1.0).c_accel(LATHE), 800.0);
    // Neither X nor Z: C's own acceleration, halved.
    assert_eq!(segment(0.0, 0.0, 2.0, 1.0).c_accel(LATHE), 1800.0);
    // Direction does not matter.
    assert_eq!(segment(0.0, -0.5, -2.0, 1.0).c_accel(LATHE), 800.0);
}

#[test]
fn the_formula_is_where_the_superposed_blend_passes_the_corner() {
    // The derivation, checked by following the blend itself: the first move has
    // r(t) = (a/2)(T − t)² of C to go, the second has made p(t) = (a/2)t², T = ω_b/a; the
    // machine's X/Z distance from the polyline at the same C is largest where C passes the
    // corner, and equal to the formula there. Slopes not at right angles, not symmetric.
    let first = segment(0.08, 0.002, 1.5, 0.05);
    let second = segment(-0.02, 0.003, 2.5, 0.06);
    let corner = Corner::between(&first, &second, LATHE).unwrap();
    let (a, w) = (corner.accel, corner.blend_rate);
    let ([x1, z1], [x2, z2]) = (first.slope(), second.slope());
    let total = w / a;
    let mut largest: f64 = 0.0;
    let n = 100_000;
    for k in 0..=n {
        let t = total * k as f64 / n as f64;
        let (r, p) = (a / 2.0 * (total - t).powi(2), a / 2.0 * t * t);
        // Relative to the corner: the machine, and the polyline at the machine's C.
        let (x, z, c) = (-x1 * r + x2 * p, -z1 * r + z2 * p, p - r);
        let (px, pz) = if c < 0.0 {
            (x1 * c, z1 * c)
        } else {
            (x2 * c, z2 * c)
        };
        largest = largest.max((x - px).hypot(z - pz));
    }
    assert!(
        (largest - corner.deviation()).abs() <= 1e-9 * corner.deviation(),
        "followed {largest}, formula {}",
        corner.deviation()
    );
    // And it reaches ω_b²/(2a) of C into each move: r(0) and p(T).
    assert!((a / 2.0 * total * total - corner.reach_deg()).abs() < 1e-15);
}

#[test]
fn a_move_that_does_not_turn_c_is_not_modelled() {
    let turning = segment(0.1, 0.0, 2.0, 0.1);
    let still = segment(0.1, 0.0, 0.0, 0.1);
    assert_eq!(Corner::between(&turning, &still, LATHE), None);
    assert_eq!(Corner::between(&still, &turning, LATHE), None);
}

#[test]
fn corners_are_between_linked_moves_with_no_other_motion_between() {
    let mut program = zigzag(10.0, &[(0.1, 0.0, 2.0, 0.1), (-0.1, 0.0, 2.0, 0.1)]);
    // A comment and a spindle command do not part them; a feed does.
    program.moves.insert(2, Move::Comment("note".into()));
    program.moves.insert(3, Move::SpindleOn { rpm: 1000.0 });
    program.moves.push(Move::Feed {
        x: Some(12.0),
        z: None,
        c: None,
        feed: 100.0,
    });
    program.moves.push(linked(12.0, 1.0, 10.0, 0.01));
    program.moves.push(linked(12.5, 1.0, 12.0, 0.01));
    let found = corners(&program, LATHE);
    let pairs: Vec<(usize, usize)> = found.iter().map(|c| (c.first, c.second)).collect();
    assert_eq!(pairs, [(1, 4), (6, 7)]);
    assert!(found.iter().all(|c| c.corner.is_some()));
}

#[test]
fn a_program_within_the_share_is_left_exactly_as_it_was() {
    // 5°/s: 25/(8·1800)·0.1 = 0.17 µm at the sharper corners, under 1 µm / 1.1.
    let program = zigzag(
        10.0,
        &[
            (0.1, 0.001, 2.0, 0.4),
            (-0.1, 0.001, 2.0, 0.4),
            (0.05, 0.001, 2.0, 0.4),
            (-0.02, 0.001, 2.0, 0.4),
        ],
    );
    let mut capped = program.clone();
    let did = cap_linked_feeds(&mut capped, LATHE, 0.001);
    assert_eq!(capped, program);
    assert_eq!(did.slowed, 0);
    assert_eq!(did.added_s, 0.0);
    assert_eq!(did.corners, 3);
    assert!(did.max_deviation_mm > 0.0 && MARGIN * did.max_deviation_mm <= 0.001);
}

#[test]
fn capping_meets_every_corner_and_slows_only_where_needed() {
    // 50°/s: 0.0174 mm at the ±0.05 mm/° corners, far beyond 1 µm. The first three moves meet
    // at sharp corners; the last two only meet nearly straight ones (|Δs| = 0.00005 mm/°:
    // 0.009 µm at 50°/s) and keep their pace.
    let mut program = zigzag(
        10.0,
        &[
            (0.1, 0.001, 2.0, 0.04),
            (-0.1, 0.001, 2.0, 0.04),
            (0.1, 0.001, 2.0, 0.04),
            (0.1001, 0.001, 2.0, 0.04),
            (0.1002, 0.001, 2.0, 0.04),
        ],
    );
    let before = linked_moves(&program);
    let did = cap_linked_feeds(&mut program, LATHE, 0.001);
    let after = linked_moves(&program);
    assert_eq!(did.slowed, 3);
    assert_eq!(after[3..], before[3..]);
    assert!(after[..3].iter().zip(&before).all(|(a, b)| a.1 > b.1));
    let added: f64 = before
        .iter()
        .zip(&after)
        .map(|(b, a)| (a.1 - b.1) * 60.0)
        .sum();
    assert!((did.added_s - added).abs() < 1e-12, "{did:?}");
    for at in corners(&program, LATHE) {
        let corner = at.corner.unwrap();
        assert!(MARGIN * corner.deviation() <= 0.001, "{at:?}");
        assert!(!corner.overlaps(), "{at:?}");
    }
    // The sharp corners are held at the share: the cap slows no more than it must.
    assert!(
        MARGIN * did.max_deviation_mm > 0.001 * (1.0 - 1e-9),
        "{did:?}"
    );
}

#[test]
fn a_blend_too_long_for_its_move_is_capped_even_on_a_straight_line() {
    // Collinear moves cut no corner, but at 100°/s and 1800°/s² a blend reaches 2.8° into
    // moves 1° long: the cap holds each blend to half a move, ω ≤ sqrt(a·|ΔC|).
    let mut program = zigzag(10.0, &[(0.0, 0.0, 1.0, 0.01); 4]);
    let did = cap_linked_feeds(&mut program, LATHE, 0.001);
    assert_eq!(did.slowed, 4);
    assert_eq!(did.max_deviation_mm, 0.0);
    for at in corners(&program, LATHE) {
        let corner = at.corner.unwrap();
        assert!(!corner.overlaps(), "{at:?}");
        assert!(corner.blend_rate > 0.999 * 1800f64.sqrt(), "{at:?}");
    }
}

proptest! {
    #[test]
    fn capping_only_lengthens_and_leaves_every_corner_within(
        moves in prop::collection::vec(
            (-0.5f64..0.5, -0.05f64..0.05, 0.05f64..5.0, 0.001f64..0.5),
            1..40,
        ),
        share in 1e-5f64..1e-2,
    ) {
        let program = zigzag(20.0, &moves);
        let mut capped = program.clone();
        let did = cap_linked_feeds(&mut capped, LATHE, share);
        // Only `minutes` of linked moves changes, and only ever grows.
        prop_assert_eq!(capped.moves.len(), program.moves.len());
        let mut slowed = 0;
        for (before, after) in program.moves.iter().zip(&capped.moves) {
            match (before, after) {
                (
                    Move::Linked { x, z, c, minutes },
                    Move::Linked { x: x2, z: z2, c: c2, minutes: m2 },
                ) => {
                    prop_assert_eq!((x, z, c), (x2, z2, c2));
                    prop_assert!(m2 >= minutes);
                    if m2 > minutes {
                        slowed += 1;
                    }
                }
                _ => prop_assert_eq!(before, after),
            }
        }
        prop_assert_eq!(slowed, did.slowed);
        prop_assert!(did.added_s >= 0.0);
        let found = corners(&capped, LATHE);
        prop_assert_eq!(found.len(), moves.len() - 1);
        for at in found {
            let corner = at.corner.unwrap();
            prop_assert!(MARGIN * corner.deviation() <= share, "{:?}", at);
            prop_assert!(!corner.overlaps(), "{:?}", at);
            prop_assert!(corner.deviation() <= did.max_deviation_mm);
        }
        // A second pass finds nothing to do.
        let mut again = capped.clone();
        prop_assert_eq!(cap_linked_feeds(&mut again, LATHE, share).slowed, 0);
        prop_assert_eq!(again, capped);
    }
}
