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
fn the_faster_rate_sets_the_blend_and_a_quicker_second_move_deepens_it() {
    // 1 mm of X over 2°: X allows 400·2/1 = 800°/s² of C, halved 400; 2° in 0.04 s, 50°/s. The
    // other move is C-limited (1800°/s²) and slower: 2° in 0.1 s, 20°/s. Each move blends at
    // its own rate, so the faster one sets the corner, whichever comes first.
    let steep = segment(1.0, 0.0, 2.0, 0.04);
    let slow = segment(0.0, 0.01, 2.0, 0.1);
    assert_eq!(steep.c_accel(LATHE), 400.0);
    assert_eq!(slow.c_accel(LATHE), 1800.0);
    // |Δs| = |(0.5, 0) − (0, 0.005)|.
    let kink = 0.5f64.hypot(0.005);
    // Into the quicker move: 50²·1800 / (2·400·(20 + √1800)²), deeper than 50²/(8·400).
    let quicker = Corner::between(&steep, &slow, LATHE).unwrap();
    let expected = 2500.0 * 1800.0 / (800.0 * (20.0 + 1800f64.sqrt()).powi(2)) * kink;
    assert!(expected > 2500.0 / 3200.0 * kink);
    assert!(
        (quicker.deviation() - expected).abs() < 1e-12,
        "{quicker:?}"
    );
    // Into the slower one: the smaller acceleration, 50²/(8·400).
    let slower = Corner::between(&slow, &steep, LATHE).unwrap();
    assert!((slower.deviation() - 2500.0 / 3200.0 * kink).abs() < 1e-12);
    for corner in [quicker, slower] {
        assert_eq!(corner.blend_rate, 50.0);
        assert_eq!(corner.accel(), 400.0);
        // 2500/800 = 3.1° of C into moves of 2°.
        assert!(corner.overlaps());
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

/// Follows the blend of `corner` in time: the first move decelerating from ω_b to rest at
/// its own acceleration, the second accelerating from rest at its own up to ω_b; returns the
/// largest X/Z distance, at the same C, of the machine from the two moves' lines.
fn follow(corner: &Corner, first: &Segment, second: &Segment) -> f64 {
    let w = corner.blend_rate;
    let (a1, a2) = (corner.accel_first, corner.accel_second);
    let ([x1, z1], [x2, z2]) = (first.slope(), second.slope());
    let (total, ramp) = (w / a1, w / a2);
    let mut largest: f64 = 0.0;
    let n = 200_000;
    for k in 0..=n {
        let t = total * k as f64 / n as f64;
        let r = a1 / 2.0 * (total - t).powi(2);
        let p = if t < ramp {
            a2 / 2.0 * t * t
        } else {
            a2 / 2.0 * ramp * ramp + w * (t - ramp)
        };
        // Relative to the corner: the machine, and the polyline at the machine's C.
        let (x, z, c) = (-x1 * r + x2 * p, -z1 * r + z2 * p, p - r);
        let (px, pz) = if c < 0.0 {
            (x1 * c, z1 * c)
        } else {
            (x2 * c, z2 * c)
        };
        largest = largest.max((x - px).hypot(z - pz));
    }
    largest
}

#[test]
fn the_formula_is_where_the_superposed_blend_passes_the_corner() {
    // The derivation, checked by following the blend itself: the first move has
    // r(t) = (a₁/2)(T − t)² of C to go, T = ω_b/a₁, the second has made p(t) = (a₂/2)t²; the
    // machine's X/Z distance from the polyline at the same C is largest where C passes the
    // corner, and equal to the formula there (to the 200 000 steps' resolution). Slopes not
    // at right angles, not symmetric.
    let agree = |first: Segment, second: Segment| {
        let corner = Corner::between(&first, &second, LATHE).unwrap();
        let followed = follow(&corner, &first, &second);
        assert!(
            (followed - corner.deviation()).abs() <= 2e-5 * corner.deviation(),
            "followed {followed}, formula {}: {corner:?}",
            corner.deviation()
        );
    };
    // Both C-limited (1800°/s²): ω_b²/(8a).
    agree(
        segment(0.08, 0.002, 1.5, 0.05),
        segment(-0.02, 0.003, 2.5, 0.06),
    );
    // The second twice as quick: 0.4 mm of X over 2° allows 2000°/s², halved 1000, and C's
    // own 1800 (√1.8 = 1.34, below 1.618: the second is still accelerating where they meet).
    agree(
        segment(0.4, 0.002, 2.0, 0.05),
        segment(-0.02, 0.003, 2.5, 0.06),
    );
    // The other way round the smaller acceleration governs, and the formula bounds the blend.
    let (first, second) = (
        segment(-0.02, 0.003, 2.5, 0.06),
        segment(0.4, 0.002, 2.0, 0.05),
    );
    let corner = Corner::between(&first, &second, LATHE).unwrap();
    assert!(follow(&corner, &first, &second) <= corner.deviation() * (1.0 + 1e-8));
    // Far quicker (4.5×: 400 against 1800): the second reaches ω_b before they meet, and the
    // formula overstates.
    let (first, second) = (segment(1.0, 0.0, 2.0, 0.04), segment(0.0, 0.01, 2.0, 0.04));
    let corner = Corner::between(&first, &second, LATHE).unwrap();
    assert!(follow(&corner, &first, &second) < corner.deviation());
    // And the blend reaches ω_b²/(2a) of C into the moves: r(0) with the smaller a.
    assert!((corner.reach_deg() - 2500.0 / 800.0).abs() < 1e-12);
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
    program.moves.push(linked(12.0, 1.0, 14.0, 0.01));
    let found = corners(&program, LATHE);
    let pairs: Vec<(usize, usize)> = found.iter().map(|c| (c.first, c.second)).collect();
    assert_eq!(pairs, [(1, 4), (6, 7), (7, 8)]);
    assert!(found.iter().all(|c| c.corner.is_some()));
    // The machine stops after move 4 (a feed follows) and after move 8 (the end).
    let stops: Vec<bool> = found.iter().map(|c| c.into_stop).collect();
    assert_eq!(stops, [true, false, true]);
    assert_eq!(found[1].margin(), MARGIN);
    assert_eq!(found[2].margin(), STOP_MARGIN);
}

#[test]
fn a_program_within_the_share_is_left_exactly_as_it_was() {
    // 5°/s: 25/(8·1800)·0.1 = 0.17 µm at the sharper corners, under 1 µm / 1.15.
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

#[test]
fn the_corners_as_posted_set_the_cap() {
    // Straight as planned, but the middle vertex is posted 1 µm off: a corner of
    // |Δs| = 2·0.001/2 = 0.001 mm/°, which at 50°/s cuts 2500/14400·0.001 = 0.17 µm, beyond
    // 0.1 µm / 1.15. The cap sees the posted corner.
    let planned = zigzag(10.0, &[(0.0, 0.001, 2.0, 0.04), (0.0, 0.001, 2.0, 0.04)]);
    let mut posted = planned.clone();
    if let Move::Linked { x, .. } = &mut posted.moves[1] {
        *x += 0.001;
    }
    let mut own = planned.clone();
    assert_eq!(cap_linked_feeds(&mut own, LATHE, 0.0001).slowed, 0);
    let mut program = planned.clone();
    let did = cap_linked_feeds_as_posted(&mut program, &posted, LATHE, 0.0001);
    assert_eq!(did.slowed, 2);
    assert!(
        (STOP_MARGIN * did.max_deviation_mm - 0.0001).abs() < 1e-12,
        "{did:?}"
    );
    // Its positions stay as planned.
    assert_eq!(program.moves[1].target(), planned.moves[1].target());
    // A posted program with other linked moves says nothing of these corners.
    let mut unlike = posted.clone();
    unlike.moves.pop();
    let mut program = planned.clone();
    assert_eq!(
        cap_linked_feeds_as_posted(&mut program, &unlike, LATHE, 0.0001).slowed,
        0
    );
    assert_eq!(program, planned);
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
            prop_assert!(at.margin() * corner.deviation() <= share, "{:?}", at);
            prop_assert!(!corner.overlaps(), "{:?}", at);
            prop_assert!(corner.deviation() <= did.max_deviation_mm);
        }
        // A second pass finds nothing to do.
        let mut again = capped.clone();
        prop_assert_eq!(cap_linked_feeds(&mut again, LATHE, share).slowed, 0);
        prop_assert_eq!(again, capped);
    }
}
