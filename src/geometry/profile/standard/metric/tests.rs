//! `M` designations against ISO 262's sizes and the basic dimensions of ISO 724 (d2, D1) and
//! ISO 965-1 / ISO 898-1 (d3), values printed there to three decimals.

use super::super::designation::parse;
use super::super::tests::{assert_refused, dim};
use super::super::AxialPiece;

#[test]
fn metric_dimensions_are_iso_724_and_965_values() {
    // (designation, P, d, d2, D1, d3): ISO 724 Table 1 (d2 = D2, D1), ISO 898-1 (d3).
    let rows = [
        ("M20", 2.5, 20.0, 18.376, 17.294, 16.933),
        ("M10x1.25", 1.25, 10.0, 9.188, 8.647, 8.466),
        ("M6", 1.0, 6.0, 5.350, 4.917, 4.773),
        ("M64x4", 4.0, 64.0, 61.402, 59.670, 59.093),
    ];
    for (text, pitch, d, d2, d1, d3) in rows {
        let designation = parse(text).unwrap();
        assert_eq!(
            (designation.lead, designation.starts),
            (Some(pitch), Some(1))
        );
        let ext = designation.form.dimensions(pitch).unwrap();
        let nut = designation.form.internal_dimensions(pitch).unwrap();
        let close = |got: f64, want: f64, what: &str| {
            assert!((got - want).abs() < 5e-4, "{text} {what}: {got} ≠ {want}");
        };
        close(dim(&ext, "major diameter d"), d, "d");
        close(dim(&ext, "pitch diameter d2"), d2, "d2");
        close(dim(&ext, "minor diameter d3"), d3, "d3");
        close(dim(&nut, "minor diameter D1"), d1, "D1");
        close(dim(&nut, "pitch diameter D2"), d2, "D2");
        // ISO 68-1: crest flat P/8; ISO 965-1: root radius at least 0.125·P.
        close(dim(&ext, "crest width"), pitch / 8.0, "crest P/8");
        assert!(dim(&ext, "root radius R") >= 0.125 * pitch);
        assert_eq!(dim(&ext, "flank angle"), 60.0);
    }
}

#[test]
fn m20_sections_reach_d3_with_one_root_arc_and_the_nut_reaches_d() {
    let form = parse("M20").unwrap().form;
    let screw = form.pieces(2.5).unwrap();
    let arcs: Vec<_> = screw
        .iter()
        .filter(|p| matches!(p, AxialPiece::Arc { .. }))
        .collect();
    assert_eq!(arcs.len(), 1, "a full-radius root: {screw:?}");
    let lowest = (0..=200)
        .map(|k| arcs[0].eval(arcs[0].length() * k as f64 / 200.0).0.x)
        .fold(f64::INFINITY, f64::min);
    assert!((2.0 * lowest - 16.933).abs() < 5e-4, "d3: {}", 2.0 * lowest);
    let nut = form.internal_pieces(2.5).unwrap();
    assert!((2.0 * nut[0].start().x - 17.294).abs() < 5e-4, "bore at D1");
    let deepest = nut.iter().map(|p| p.start().x).fold(0.0, f64::max);
    assert!((2.0 * deepest - 20.0).abs() < 1e-12, "root at D");
    // The nut's root flat at D is P/8 wide (ISO 68-1).
    let root = nut
        .iter()
        .find(|p| (p.start().x - 10.0).abs() < 1e-12 && (p.end().x - 10.0).abs() < 1e-12)
        .unwrap();
    assert!((root.length() - 2.5 / 8.0).abs() < 1e-12);
}

#[test]
fn metric_designations_read_and_refuse() {
    let m = parse("M20x1.5-6g LH").err();
    assert!(m.is_some(), "LH after the class is not ISO's order");
    let d = parse("M20x1.5 LH-6g").unwrap();
    assert!(d.left_hand && !d.internal());
    assert!(parse("M20-6H").unwrap().internal());
    assert_eq!(parse("M 20").unwrap().lead, Some(2.5), "coarse by default");
    assert_eq!(parse("M20-5g6g").unwrap().class.as_deref(), Some("5g6g"));
    let cases = [
        ("M21", "ISO 262 has no nominal diameter 21 mm"),
        ("M20x1", "no pitch 1 mm for M20, only 2.5, 2, 1.5 mm"),
        ("M20-6x", "`6x` is not an ISO 965-1 tolerance class"),
        ("M20-6g6H", "`6g6H` is not an ISO 965-1 tolerance class"),
        ("M20xA", "pitch `A` is not a number"),
        ("M20 LH LH", "LH (left hand) is given twice"),
    ];
    assert_refused(&cases);
}
