//! Acme and Stub Acme designations against the ASME series and basic dimensions. Expected
//! numbers are in inches as the standards print them: ASME B1.5 (1/2-10 2G screw: minor
//! diameter max 0.3800, total depth 0.0600, crest flat 0.3707P) and B1.8's table of Stub Acme
//! basic dimensions (3/4-6: D2 = 0.7000, D1 = 0.6500, h = 0.0500, flat 0.0704).

use super::super::designation::{parse, Designation, DesignationError};
use super::super::{Dimension, StandardProfile, MM_PER_INCH};

fn dim_in(dims: &[Dimension], name: &str) -> f64 {
    dims.iter()
        .find(|d| d.name == name)
        .unwrap_or_else(|| panic!("no {name} in {dims:?}"))
        .value
        / MM_PER_INCH
}

fn read(text: &str) -> Designation {
    parse(text).unwrap_or_else(|e| panic!("{text}: {e}"))
}

#[test]
fn acme_1_2_10_has_b1_5_dimensions() {
    let d = read("1/2-10 ACME-2G");
    assert!(matches!(d.form, StandardProfile::Acme(_)));
    assert_eq!(d.class.as_deref(), Some("2G"));
    assert_eq!((d.lead, d.starts), (Some(2.54), Some(1)));
    let pitch = 2.54;
    let ext = d.form.dimensions(pitch).unwrap();
    let close = |got: f64, want: f64, what: &str| {
        assert!((got - want).abs() < 5e-5, "{what}: {got} in ≠ {want} in");
    };
    close(dim_in(&ext, "major diameter"), 0.5, "major");
    close(dim_in(&ext, "pitch diameter"), 0.45, "pitch diameter");
    close(dim_in(&ext, "minor diameter"), 0.38, "minor (2G max)");
    close(dim_in(&ext, "thread height"), 0.06, "total depth");
    close(
        dim_in(&ext, "crest width"),
        0.3707 * 0.1,
        "crest flat 0.3707P",
    );
    // Root flat of the screw: 0.3707P − 0.259 × allowance (0.020 in at 10 tpi).
    close(
        dim_in(&ext, "root width"),
        0.3707 * 0.1 - 0.259 * 0.020,
        "root flat",
    );
    // The nut: minor diameter d − P = 0.4000, major d + allowance = 0.5200 (B1.5 basic).
    let nut = d.form.internal_dimensions(pitch).unwrap();
    close(dim_in(&nut, "minor diameter"), 0.4, "nut minor");
    close(dim_in(&nut, "major diameter"), 0.52, "nut major");
}

#[test]
fn stub_acme_3_4_6_has_b1_8_dimensions() {
    let d = read("3/4-6 STUB ACME");
    assert!(matches!(d.form, StandardProfile::StubAcme(_)));
    let pitch = MM_PER_INCH / 6.0;
    let ext = d.form.dimensions(pitch).unwrap();
    let close = |got: f64, want: f64, what: &str| {
        assert!((got - want).abs() < 5e-5, "{what}: {got} in ≠ {want} in");
    };
    close(dim_in(&ext, "pitch diameter"), 0.7, "D2");
    close(dim_in(&ext, "basic thread height h"), 0.05, "h = 0.3P");
    close(dim_in(&ext, "crest width"), 0.0704, "flat 0.4224P");
    let flank = ext.iter().find(|d| d.name == "flank angle").unwrap();
    assert_eq!((flank.value, flank.unit), (29.0, "°"));
    let nut = d.form.internal_dimensions(pitch).unwrap();
    close(dim_in(&nut, "minor diameter"), 0.65, "D1 = D − 2h");
    close(dim_in(&nut, "pitch diameter"), 0.7, "D2");
}

#[test]
fn the_ways_a_drawing_writes_acme_read_alike() {
    let a = read("1 1/2-4 ACME-2G");
    assert_eq!(read("1-1/2-4 ACME-2G"), a);
    assert_eq!(read("1.500-4 ACME-2G"), a);
    assert_eq!(read("1 1/2-4 acme-2g").form, a.form);
    assert_eq!(a.form.outer_diameter(), 1.5 * MM_PER_INCH);
    let lh = read("1 1/2-4 ACME-2G-LH");
    assert!(lh.left_hand && !a.left_hand);
    assert_eq!(read("1/2-10 ACME").class, None);
    // Multi-start: pitch 0.2 in, lead 0.4 in: two starts.
    let two = read("1-0.2P-0.4L-ACME-2G");
    assert_eq!(two.starts, Some(2));
    assert!((two.lead.unwrap() - 0.4 * MM_PER_INCH).abs() < 1e-12);
    // An Acme class names screw and nut alike: the job says which it cuts.
    assert!(!read("1/2-10 ACME-2G").internal());
}

#[test]
fn every_malformed_or_unlisted_acme_is_refused_naming_what() {
    let cases = [
        ("1/2-12 ACME-2G", "gives size 1/2 in 10 threads per inch"),
        ("9/16-10 ACME-2G", "series has no size 9/16 in"),
        (
            "1/2-10 ACME-5G",
            "`5G` is not a class of ASME B1.5, which has 2G, 3G, 4G",
        ),
        ("1/2-10 ACME-2C", "`2C` is not a class"),
        (
            "3/4-6 STUB ACME-3G",
            "not a class of ASME B1.8 (Stub Acme), which has 2G",
        ),
        ("1/2-10 ACME-2G-LH-LH", "LH (left hand) is given twice"),
        ("ACME", "write size-threads per inch"),
        ("1/2-X ACME", "threads per inch `X` is not a number"),
        ("1/2/3-10 ACME", "size (in) `2/3` is not a number"),
        ("1 1/2 1/4-4 ACME", "`1 1/2 1/4` is not a size in inches"),
        ("1-0.2P-0.3L-ACME", "not a whole number of pitches"),
    ];
    for (text, why) in cases {
        let said = match parse(text) {
            Err(e @ DesignationError::Refused { .. }) => e.to_string(),
            other => panic!("{text}: expected a refusal, got {other:?}"),
        };
        assert!(said.contains(why), "{text}: {said}");
    }
}
