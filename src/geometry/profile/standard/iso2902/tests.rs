//! `Tr` designations against ISO 2902's table and ISO 2904's basic dimensions: every expected
//! number below is a value of ISO 2904:2020 Table 1 (rounded there to the third decimal) or
//! of ISO 2901's design profile, not whirl's own output.

use super::super::designation::{parse, Designation, DesignationError};
use super::super::{AxialPiece, Dimension, StandardProfile};

/// The dimension named `name` of a list.
fn dim(dims: &[Dimension], name: &str) -> f64 {
    dims.iter()
        .find(|d| d.name == name)
        .unwrap_or_else(|| panic!("no {name} in {dims:?}"))
        .value
}

fn read(text: &str) -> Designation {
    parse(text).unwrap_or_else(|e| panic!("{text}: {e}"))
}

/// The refusal's words, checked to be a refusal (not `Unknown`) of the text given.
fn refusal(text: &str) -> String {
    match parse(text) {
        Err(e @ DesignationError::Refused { .. }) => e.to_string(),
        other => panic!("{text}: expected a refusal, got {other:?}"),
    }
}

/// ISO 2904:2020 Table 1 rows: d, P, d2 = D2, d3, D1, D4, h3 = H4, a_c.
const ISO_2904_ROWS: &[(&str, f64, [f64; 7])] = &[
    ("Tr 8x1.5", 1.5, [8.0, 7.25, 6.2, 6.5, 8.3, 0.9, 0.15]),
    ("Tr 10x2", 2.0, [10.0, 9.0, 7.5, 8.0, 10.5, 1.25, 0.25]),
    ("Tr 20x4", 4.0, [20.0, 18.0, 15.5, 16.0, 20.5, 2.25, 0.25]),
    ("Tr 40x7", 7.0, [40.0, 36.5, 32.0, 33.0, 41.0, 4.0, 0.5]),
    ("Tr 60x9", 9.0, [60.0, 55.5, 50.0, 51.0, 61.0, 5.0, 0.5]),
    (
        "Tr 100x20",
        20.0,
        [100.0, 90.0, 78.0, 80.0, 102.0, 11.0, 1.0],
    ),
];

#[test]
fn tr_dimensions_are_iso_2904_table_values() {
    for &(text, pitch, [d, d2, d3, d1, d4, h3, a_c]) in ISO_2904_ROWS {
        let designation = read(text);
        assert_eq!(designation.lead, Some(pitch), "{text}");
        assert_eq!(designation.starts, Some(1), "{text}");
        let form = designation.form;
        let ext = form.dimensions(pitch).unwrap();
        let nut = form.internal_dimensions(pitch).unwrap();
        let close = |got: f64, want: f64, what: &str| {
            assert!((got - want).abs() < 5e-4, "{text} {what}: {got} ≠ {want}");
        };
        close(dim(&ext, "major diameter d"), d, "d");
        close(dim(&ext, "pitch diameter d2"), d2, "d2");
        close(dim(&ext, "minor diameter d3"), d3, "d3");
        close(dim(&ext, "thread height h3"), h3, "h3");
        close(dim(&ext, "crest clearance a_c"), a_c, "a_c");
        close(dim(&ext, "flank angle"), 30.0, "flank angle");
        // ISO 2901 design profile: crest flat 0.366·P, root flat 0.366·P − 0.536·a_c
        // (the standard's coefficients, rounded there to three decimals).
        assert!((dim(&ext, "crest width") - 0.366 * pitch).abs() < 1e-3 * pitch);
        let root = 0.366 * pitch - 0.536 * a_c;
        assert!((dim(&ext, "root width") - root).abs() < 1e-3 * pitch);
        close(dim(&nut, "minor diameter D1"), d1, "D1");
        close(dim(&nut, "major diameter D4"), d4, "D4");
        close(dim(&nut, "pitch diameter D2"), d2, "D2");
        close(dim(&nut, "thread height H4"), h3, "H4");
    }
}

/// The lowest and highest radius a section reaches, and the slope |dz/dρ| of its steepest
/// line (a flank).
fn extent(pieces: &[AxialPiece]) -> (f64, f64, f64) {
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    let mut flank = 0.0_f64;
    for p in pieces {
        for q in [p.start(), p.end()] {
            lo = lo.min(q.x);
            hi = hi.max(q.x);
        }
        if let AxialPiece::Line { from, to } = p {
            let d = *to - *from;
            if d.x.abs() > 1e-9 {
                flank = flank.max((d.y / d.x).abs());
            }
        }
    }
    (lo, hi, flank)
}

#[test]
fn tr_40x7_screw_and_nut_sections_reach_the_table_diameters_with_15_degree_flanks() {
    let form = read("Tr 40x7").form;
    let screw = form.pieces(7.0).unwrap();
    let nut = form.internal_pieces(7.0).unwrap();
    // ISO 2904 Table 1, Tr 40x7: d3 = 32, d = 40; D1 = 33, D4 = 41.
    let (lo, hi, slope) = extent(&screw);
    assert!(
        (lo - 16.0).abs() < 1e-12 && (hi - 20.0).abs() < 1e-12,
        "{lo} {hi}"
    );
    assert!((slope - 15f64.to_radians().tan()).abs() < 1e-12, "{slope}");
    let (lo, hi, slope) = extent(&nut);
    assert!(
        (lo - 16.5).abs() < 1e-12 && (hi - 20.5).abs() < 1e-12,
        "{lo} {hi}"
    );
    assert!((slope - 15f64.to_radians().tan()).abs() < 1e-12, "{slope}");
    // The internal section's convention: one period from the bore (ρ = D1/2) at z = −P/2 to
    // the bore at z = +P/2, continuous, the groove running outward around z = 0.
    assert_eq!(nut.first().unwrap().start(), glam::DVec2::new(16.5, -3.5));
    assert_eq!(nut.last().unwrap().end(), glam::DVec2::new(16.5, 3.5));
    for w in nut.windows(2) {
        assert!(w[0].end().distance(w[1].start()) < 1e-12);
    }
    let deepest = nut
        .iter()
        .filter(|p| (p.start().x - 20.5).abs() < 1e-12 && (p.end().x - 20.5).abs() < 1e-12)
        .map(|p| 0.5 * (p.start().y + p.end().y))
        .next()
        .expect("a root flat at D4/2");
    assert!(
        deepest.abs() < 1e-12,
        "root flat centred at z = 0: {deepest}"
    );
}

#[test]
fn a_nut_keeps_the_root_fillets_as_arcs_of_the_same_radius() {
    let form = read("Tr 40x7").form.with_root_radius(0.5).unwrap();
    let nut = form.internal_pieces(7.0).unwrap();
    let arcs: Vec<_> = nut
        .iter()
        .filter_map(|p| match p {
            AxialPiece::Arc { centre, radius, .. } => Some((*centre, *radius)),
            AxialPiece::Line { .. } => None,
        })
        .collect();
    assert_eq!(arcs.len(), 2);
    for (centre, radius) in arcs {
        // Tangent to the root flat at D4/2 = 20.5 from inside the groove.
        assert_eq!(radius, 0.5);
        assert!((centre.x - (20.5 - 0.5)).abs() < 1e-12, "{centre}");
    }
}

#[test]
fn the_ways_a_drawing_writes_tr_read_alike() {
    let plain = read("Tr 40x7");
    assert_eq!(read("Tr40x7"), plain);
    assert_eq!(read("Tr 40 x 7"), plain);
    assert_eq!(read("Tr 40×7"), plain);
    assert!(!plain.left_hand && plain.class.is_none() && !plain.internal());
    assert!(plain.row.contains("10, 7, 3"), "{}", plain.row);

    // Two starts: lead 14, pitch 7 (ISO 2903's `Tr 40x14 P7`).
    for text in ["Tr 40 x 14 P7", "Tr 40x14P7", "Tr 40x14(P7)"] {
        let d = read(text);
        assert_eq!((d.lead, d.starts), (Some(14.0), Some(2)), "{text}");
    }
    let d = read("Tr 40x14 (P7) LH-8e");
    assert!(d.left_hand);
    assert_eq!(d.class.as_deref(), Some("8e"));
    assert!(!d.internal());
    let d = read("Tr 40x7 LH");
    assert!(d.left_hand && d.class.is_none());
    assert_eq!(read("Tr 40x7 7e").class.as_deref(), Some("7e"));
    assert_eq!(read("Tr 8x1,5").lead, Some(1.5), "ISO's decimal comma");
    // A capital tolerance position is the nut's (ISO 2903).
    let nut = read("Tr 40x7-7H");
    assert!(nut.internal());
    assert!(matches!(nut.form, StandardProfile::IsoTrapezoidal(_)));
}

#[test]
fn every_malformed_or_unlisted_tr_is_refused_naming_what() {
    let cases = [
        (
            "Tr 41x7",
            "no nominal diameter 41 mm; its diameters near it are 40, 42",
        ),
        ("Tr 5x1", "near it are 8"),
        ("Tr 320x44", "near it are 300"),
        ("Tr 40x5", "no pitch 5 mm for d = 40 mm, only 10, 7, 3 mm"),
        ("Tr 40x14 P5", "no pitch 5 mm"),
        ("Tr 40", "diameter x pitch"),
        ("Tr 40xA", "pitch `A` is not a number"),
        ("Tr Ax7", "nominal diameter `A` is not a number"),
        ("Tr 40x0", "pitch `0` is not a number above zero"),
        ("Tr 40x7 LH LH", "LH (left hand) is given twice"),
        ("Tr LH40x7", "LH (left hand) must follow the pitch"),
        (
            "Tr 40x15 P7",
            "lead 15 mm is not a whole number of pitches 7 mm",
        ),
        ("Tr 40x3 P7", "lead 3 mm is not a whole number"),
        (
            "Tr 40x7-6g",
            "`6g` is not one of ISO 2903's tolerance classes",
        ),
        ("Tr 40x7-", "`` is not one of ISO 2903's tolerance classes"),
    ];
    for (text, why) in cases {
        let said = refusal(text);
        assert!(said.contains(why), "{text}: {said}");
        assert!(said.contains(text), "names the designation: {said}");
    }
    // Not a Tr designation at all: no family reads it.
    assert!(matches!(
        parse("Track 40x7"),
        Err(DesignationError::Unknown { .. })
    ));
}
