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

/// B1.1's basic pitch diameter `E = D − 0.649519·P` and basic minor diameter (internal)
/// `D − 1.082532·P`, inches, for a designation of basic major diameter `major` at `tpi`
/// (to 1e-6 in: B1.1 prints the constants to six decimals).
fn assert_basic(text: &str, tpi: f64, major: f64) {
    let designation = parse(text).unwrap_or_else(|e| panic!("{text}: {e}"));
    let pitch = MM_PER_INCH / tpi;
    assert!(
        (designation.lead.unwrap() - pitch).abs() < 1e-12,
        "{text}: lead"
    );
    assert_eq!(designation.starts, Some(1), "{text}");
    let p = 1.0 / tpi;
    let inches = |mm: f64| mm / MM_PER_INCH;
    let ext = designation.form.dimensions(pitch).unwrap();
    let nut = designation.form.internal_dimensions(pitch).unwrap();
    let close = |got: f64, want: f64, what: &str| {
        assert!((got - want).abs() < 1e-6, "{text} {what}: {got} ≠ {want}");
    };
    close(inches(dim(&ext, "major diameter d")), major, "D");
    close(
        inches(dim(&ext, "pitch diameter d2")),
        major - 0.649519 * p,
        "E",
    );
    close(
        inches(dim(&nut, "pitch diameter D2")),
        major - 0.649519 * p,
        "E of the nut",
    );
    close(
        inches(dim(&nut, "minor diameter D1")),
        major - 1.082532 * p,
        "minor",
    );
}

#[test]
fn unef_is_b1_1s_extra_fine_series() {
    // Sizes and threads per inch as the sources of `UNEF` print them: 12-32 (microadvances),
    // 5/8-24 and 11/16-24 (eFunda), 1 3/16-18 (Eisen; missing from FreeCAD's table).
    for (text, tpi, major) in [
        ("1/4-32 UNEF", 32.0, 0.25),
        ("12-32 UNEF", 32.0, 0.216),
        ("#12-32 UNEF-2A", 32.0, 0.216),
        ("5/8-24 UNEF-2A", 24.0, 0.625),
        ("11/16-24 UNEF", 24.0, 0.6875),
        ("1 3/16-18 UNEF-3A", 18.0, 1.1875),
        ("1-11/16-18 UNREF-2A-LH", 18.0, 1.6875),
    ] {
        assert_basic(text, tpi, major);
    }
    // eFunda's 15/16-20 UNEF-3A row: class 3A has no allowance, so its maximum major and
    // pitch diameters, 0.9375 and 0.9050 in, are the basic D and E.
    let text = "15/16-20 UNEF-3A";
    let designation = parse(text).unwrap();
    let ext = designation.form.dimensions(MM_PER_INCH / 20.0).unwrap();
    let inches = |name: &str| dim(&ext, name) / MM_PER_INCH;
    assert!((inches("major diameter d") - 0.9375).abs() < 1e-9);
    assert!((inches("pitch diameter d2") - 0.9050).abs() < 5e-5);
    // The nut (class B) is read as UNC's and UNF's are.
    let nut = parse("11/16-24 UNEF-2B").unwrap();
    assert!(nut.internal() && !nut.left_hand);
    assert!(!parse("11/16-24 UNEF-2A").unwrap().internal());
    let refused = [
        // 1/4 in takes 32 threads per inch in UNEF (28 is its UNF pitch).
        ("1/4-28 UNEF", "gives size 1/4 32 threads per inch, not 28"),
        ("1/2-20 UNREF", "gives size 1/2 28 threads per inch, not 20"),
        ("#10-32 UNEF", "no size #10; its sizes run #12 to 1 11/16"),
        ("1 3/4-16 UNEF", "no size 1 3/4"),
        ("1/4-32 UNEF-2C", "class"),
    ];
    assert_refused(&refused);
}

#[test]
fn uns_takes_any_size_and_pitch() {
    // B1.1's special series: the basic profile on any size and pitch.
    for (text, tpi, major) in [
        ("0.500-24 UNS-2A", 24.0, 0.5),
        ("1/2-24 UNS", 24.0, 0.5),
        (".5-24 UNRS-3A", 24.0, 0.5),
        // #10 and #12 from B1.1's tables; 10-48 and 12-56 are UNS rows of microadvances' chart.
        ("#10-48 UNS", 48.0, 0.19),
        ("#12-56 UNS-2A", 56.0, 0.216),
        ("#0-90 UNS", 90.0, 0.06),
        ("0-90 UNS", 90.0, 0.06),
        ("1 1/2-7 UNS", 7.0, 1.5),
        ("2.375-11.5 UNS-2B", 11.5, 2.375),
        ("10.0-6 UNS", 6.0, 10.0),
    ] {
        assert_basic(text, tpi, major);
    }
    let nut = parse("0.500-24 UNS-2B").unwrap();
    assert!(nut.internal());
    assert!(matches!(nut.form, StandardProfile::Unified(_)));
    assert!(parse("3/4-13 UNS-1A-LH").unwrap().left_hand);
    let refused = [
        (
            "10-48 UNS",
            "both B1.1's number size #10 (0.19 in) and 10 in: write `#10`",
        ),
        ("1-20 UNS", "write `#1` or `1.000`"),
        (
            "#7-40 UNS",
            "no number size #7; its number sizes are #0, #1",
        ),
        (
            "0.0-24 UNS",
            "the size (in) `0.0` is not a number above zero",
        ),
        (
            "1/2-0 UNS",
            "the threads per inch `0` is not a number above zero",
        ),
        ("1/2 UNS", "size-threads per inch"),
        ("1/2-24 UNS-3C", "class"),
        // 0.05 in at 4 threads per inch: the screw's minor diameter D − 1.22687·P and the
        // nut's D − 1.082532·P are both below zero.
        (
            "0.05-4 UNS",
            "0.05 in at 4 threads per inch is not a thread: minor diameter",
        ),
        ("0.05-4 UNS-2B", "is not a thread: minor diameter"),
    ];
    assert_refused(&refused);
}
