//! Unified designations against ASME B1.1's series and its basic dimensions (Table 2:
//! basic pitch diameter E and basic minor diameter of the internal thread, inches, printed to
//! four decimals).

use super::super::designation::{parse, DesignationError};
use super::super::tests::{assert_refused, dim};
use super::super::{StandardProfile, MM_PER_INCH};

#[test]
fn unified_basic_dimensions_are_b1_1s() {
    // (designation, tpi, basic major D, E, basic minor of the internal thread), inches.
    let rows = [
        ("1/4-20 UNC-2A", 20.0, 0.25, 0.2175, 0.1959),
        ("1/2-13 UNC", 13.0, 0.5, 0.4500, 0.4167),
        ("3/4-16 UNF-2A", 16.0, 0.75, 0.7094, 0.6823),
        ("#10-32 UNF", 32.0, 0.19, 0.1697, 0.1562),
    ];
    for (text, tpi, major, e, minor) in rows {
        let designation = parse(text).unwrap();
        let pitch = MM_PER_INCH / tpi;
        assert_eq!(designation.starts, Some(1));
        assert!((designation.lead.unwrap() - pitch).abs() < 1e-12, "{text}");
        let ext = designation.form.dimensions(pitch).unwrap();
        let nut = designation.form.internal_dimensions(pitch).unwrap();
        let inches = |mm: f64| mm / MM_PER_INCH;
        let close = |got: f64, want: f64, what: &str| {
            assert!((got - want).abs() < 5e-5, "{text} {what}: {got} ≠ {want}");
        };
        close(inches(dim(&ext, "major diameter d")), major, "D");
        close(inches(dim(&ext, "pitch diameter d2")), e, "E");
        close(inches(dim(&nut, "minor diameter D1")), minor, "minor");
        assert_eq!(dim(&ext, "flank angle"), 60.0);
        // B1.1's UNR root: radius 0.108·P to 0.144·P (rounded to 3 decimals of P).
        let r = dim(&ext, "root radius R") / pitch;
        assert!((0.108..=0.1445).contains(&r), "{text}: root radius {r}·P");
    }
}

#[test]
fn unified_designations_read_and_refuse() {
    let read = |text: &str| parse(text).unwrap_or_else(|e| panic!("{text}: {e}"));
    let major = |text: &str| read(text).form.outer_diameter() / MM_PER_INCH;
    assert!((major("10-32 UNF") - 0.19).abs() < 1e-12, "a number size");
    assert!((major("1-8 UNC") - 1.0).abs() < 1e-12, "1 in at 8 tpi");
    assert!((major("1-64 UNC") - 0.073).abs() < 1e-12, "#1 at 64 tpi");
    assert!((major("1 1/2-6 UNC-2A") - 1.5).abs() < 1e-12);
    assert!((major("1-1/2-6 UNC") - 1.5).abs() < 1e-12);
    assert!((major("2-8 UN-2A") - 2.0).abs() < 1e-12, "constant pitch");
    assert!((major("1/4-20 UNRC-2A") - 0.25).abs() < 1e-12);
    let left = read("3/4-16 UNF-2A-LH");
    assert!(left.left_hand && !left.internal());
    assert!(read("#10-32 UNF-3B").internal(), "B is the internal thread");
    assert!(matches!(
        read("1/4-20 UNC").form,
        StandardProfile::Unified(_)
    ));
    let refused = [
        ("1/4-24 UNC", "20 threads per inch"),
        ("5/32-20 UNC", "no size"),
        ("1-10 UN", "constant-pitch"),
        ("1/4-20 UNC-4A", "class"),
        ("1/4 UNC", "size-threads per inch"),
        ("1/4-20 UNC-2A-LH-LH", "twice"),
    ];
    assert_refused(&refused);
    assert!(matches!(
        parse("1/4-20 UNIVERSAL"),
        Err(DesignationError::Unknown { .. })
    ));
}
