//! The buttress thread against DIN 513-1's profile: its factors of P tie the flank angles,
//! the crest flat, the root radius and the thread height together, so the section drawn from
//! some of them must show the others.

use super::super::designation::{parse, DesignationError};
use super::super::tests::assert_refused;
use super::super::{AxialPiece, StandardError};
use super::Buttress;

/// The lowest radius of the section, sampled along its pieces.
fn lowest(pieces: &[AxialPiece]) -> f64 {
    pieces
        .iter()
        .flat_map(|p| (0..=400).map(move |k| p.eval(p.length() * k as f64 / 400.0).0.x))
        .fold(f64::INFINITY, f64::min)
}

/// The groove's width at radius `rho`, where the two flank lines cross it.
fn width_at(pieces: &[AxialPiece], rho: f64) -> f64 {
    let crossing = |p: &AxialPiece| match *p {
        AxialPiece::Line { from, to } if (from.x - rho) * (to.x - rho) < 0.0 => {
            Some(from.y + (to.y - from.y) * (rho - from.x) / (to.x - from.x))
        }
        _ => None,
    };
    let zs: Vec<f64> = pieces.iter().filter_map(crossing).collect();
    assert_eq!(zs.len(), 2, "two flanks cross ρ {rho}");
    (zs[1] - zs[0]).abs()
}

#[test]
fn s48x8_has_din_513s_depth_flanks_crest_and_pitch_line() {
    // DIN 513-1, S 48x8: d3 = d − 1.73554·P = 34.11568 mm, crest flat e = 0.26384·P =
    // 2.11072 mm, d2 = d − 0.75·P = 42 mm where the groove is P/2 wide, flanks 30° (−z) and
    // 3° (+z), root radius R = 0.12427·P = 0.99416 mm.
    let pitch = 8.0;
    let d = parse("S 48x8").unwrap();
    assert_eq!((d.lead, d.starts, d.left_hand), (Some(8.0), Some(1), false));
    let pieces = d.form.pieces(pitch).unwrap();
    // The table's factors are rounded to 5 decimals: 1e-5·P each.
    let tolerance = 2.0 * 1e-5 * pitch;
    assert!((2.0 * lowest(&pieces) - 34.11568).abs() < tolerance);
    let land = pieces[0].length() + pieces[pieces.len() - 1].length();
    assert!((land - 2.11072).abs() < tolerance, "crest flat {land}");
    assert!(
        (width_at(&pieces, 21.0) - 4.0).abs() < tolerance,
        "width at d2"
    );
    let angle = |p: &AxialPiece| {
        let (a, b) = (p.start(), p.end());
        ((b.y - a.y) / (b.x - a.x)).abs().atan().to_degrees()
    };
    assert!((angle(&pieces[1]) - 30.0).abs() < 1e-9, "−z flank");
    assert!((angle(&pieces[3]) - 3.0).abs() < 1e-9, "+z flank");
    match pieces[2] {
        AxialPiece::Arc { radius, .. } => assert!((radius - 0.99416).abs() < tolerance),
        other => panic!("the root is one arc, not {other:?}"),
    }
    // Continuous, z never decreasing, one period from −P/2 to P/2 at the crest.
    for pair in pieces.windows(2) {
        assert!(pair[0].end().distance(pair[1].start()) < 1e-12);
    }
    assert_eq!(pieces[0].start().y, -4.0);
    assert_eq!(pieces[4].end().y, 4.0);
    assert_eq!(pieces[0].start().x, 24.0);
}

#[test]
fn buttress_designations_read_and_refuse() {
    let two = parse("S48x16P8 LH-7h").unwrap();
    assert_eq!((two.lead, two.starts), (Some(16.0), Some(2)));
    assert!(two.left_hand && !two.internal());
    assert_eq!(two.class.as_deref(), Some("7h"));
    assert_eq!(parse("S 48 × 8").unwrap().lead, Some(8.0));
    let refused = [
        ("S 48x8-7H", "nut"),
        ("S 48x8-9q", "tolerance classes"),
        ("S 48", "diameter x pitch"),
        ("S 48x12P5", "whole number of pitches"),
        ("S 10x8", "minor diameter"),
        ("S 48xP8", "not a number"),
    ];
    assert_refused(&refused);
    assert!(matches!(
        parse("Sx8"),
        Err(DesignationError::Unknown { .. })
    ));
}

#[test]
fn the_buttress_nut_is_not_drawn() {
    let form = parse("S 48x8").unwrap().form;
    assert!(matches!(
        form.internal_pieces(8.0),
        Err(StandardError::NoInternalForm { .. })
    ));
    assert!(Buttress::new(-1.0).is_err());
}

#[test]
fn a_load_flank_on_the_minus_z_side_mirrors_the_section() {
    let plus = Buttress::new(48.0).unwrap();
    let minus = plus.with_load_flank(super::LoadFlank::MinusZ);
    let (a, b) = (plus.pieces(8.0).unwrap(), minus.pieces(8.0).unwrap());
    let angle = |p: &AxialPiece| {
        let (s, e) = (p.start(), p.end());
        ((e.y - s.y) / (e.x - s.x)).abs().atan().to_degrees()
    };
    assert!((angle(&b[1]) - 3.0).abs() < 1e-9, "−z flank");
    assert!((angle(&b[3]) - 30.0).abs() < 1e-9, "+z flank");
    // Point for point the mirror image, still continuous and running towards +z.
    for pair in b.windows(2) {
        assert!(pair[0].end().distance(pair[1].start()) < 1e-12);
    }
    for (p, q) in a.iter().zip(b.iter().rev()) {
        for k in 0..=20 {
            let s = p.length() * k as f64 / 20.0;
            let (x, y) = (p.eval(s).0, q.eval(q.length() - s).0);
            assert!(
                (x.x - y.x).abs() < 1e-12 && (x.y + y.y).abs() < 1e-12,
                "{x} {y}"
            );
        }
        let (kp, kq) = (p.eval(0.0).2, q.eval(0.0).2);
        assert_eq!(kp, kq, "the root stays concave");
    }
}
