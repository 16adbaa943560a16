//! Tests of the standard profiles, kept apart from them for length: the pieces' evaluation,
//! each family against its standard's tables and refusals, and the chain conventions as
//! properties.

use super::*;
use proptest::prelude::*;
use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};

const TOL: f64 = 1e-12;

/// The value of the dimension `name` among `dims`.
pub(super) fn dim(dims: &[Dimension], name: &str) -> f64 {
    dims.iter()
        .find(|d| d.name == name)
        .unwrap_or_else(|| panic!("no {name} in {dims:?}"))
        .value
}

/// Each designation of `cases` is refused by its family with words containing the case's.
pub(super) fn assert_refused(cases: &[(&str, &str)]) {
    for (text, why) in cases {
        let said = match designation::parse(text) {
            Err(e @ designation::DesignationError::Refused { .. }) => e.to_string(),
            other => panic!("{text}: expected a refusal, got {other:?}"),
        };
        assert!(said.contains(why), "{text}: {said}");
    }
}

/// Checks the chain conventions every profile must meet; returns a description of the
/// first violation.
fn chain_violation(pieces: &[AxialPiece], pitch: f64, crest_rho: f64) -> Option<String> {
    let first = pieces.first()?;
    let last = pieces.last()?;
    if first.start().distance(DVec2::new(crest_rho, -0.5 * pitch)) > TOL {
        return Some(format!("first piece starts at {}", first.start()));
    }
    if last.end().distance(DVec2::new(crest_rho, 0.5 * pitch)) > TOL {
        return Some(format!("last piece ends at {}", last.end()));
    }
    for (i, w) in pieces.windows(2).enumerate() {
        if w[0].end().distance(w[1].start()) > TOL {
            return Some(format!("gap after piece {i}"));
        }
    }
    let mut last_z = f64::NEG_INFINITY;
    for (i, p) in pieces.iter().enumerate() {
        let len = p.length();
        if len.is_nan() || len <= 0.0 {
            return Some(format!("piece {i} has length {len}"));
        }
        let (p0, _, _) = p.eval(0.0);
        let (p1, _, _) = p.eval(len);
        if p0.distance(p.start()) > TOL || p1.distance(p.end()) > TOL {
            return Some(format!("piece {i}: eval disagrees with start/end"));
        }
        for k in 0..=16 {
            let (pt, tangent, _) = p.eval(len * k as f64 / 16.0);
            if (tangent.length() - 1.0).abs() > 1e-12 {
                return Some(format!("piece {i}: tangent not unit"));
            }
            if pt.y < last_z - TOL {
                return Some(format!("piece {i}: z decreases"));
            }
            if pt.x > crest_rho + TOL {
                return Some(format!("piece {i}: above the crest"));
            }
            last_z = pt.y;
        }
    }
    None
}

/// z values where the straight pieces cross the radius `rho` (strictly inside the piece).
fn crossings(pieces: &[AxialPiece], rho: f64) -> Vec<f64> {
    pieces
        .iter()
        .filter_map(|p| match *p {
            AxialPiece::Line { from, to } if (from.x - rho) * (to.x - rho) < 0.0 => {
                let t = (rho - from.x) / (to.x - from.x);
                Some(from.y + t * (to.y - from.y))
            }
            _ => None,
        })
        .collect()
}

fn min_rho(pieces: &[AxialPiece]) -> f64 {
    pieces
        .iter()
        .flat_map(|p| {
            let len = p.length();
            (0..=1000).map(move |k| p.eval(len * k as f64 / 1000.0).0.x)
        })
        .fold(f64::INFINITY, f64::min)
}

/// Angle (degrees) between a line piece and the radial direction.
fn angle_to_radial_deg(from: DVec2, to: DVec2) -> f64 {
    let d = to - from;
    d.y.abs().atan2(d.x.abs()).to_degrees()
}

/// The flank lines: neither radial-only nor axial-only.
fn flanks(pieces: &[AxialPiece]) -> Vec<(DVec2, DVec2)> {
    pieces
        .iter()
        .filter_map(|p| match *p {
            AxialPiece::Line { from, to }
                if (to.x - from.x).abs() > 1e-9 && (to.y - from.y).abs() > 1e-9 =>
            {
                Some((from, to))
            }
            _ => None,
        })
        .collect()
}

/// Total length of the axial lines at the given radius.
fn flat_at(pieces: &[AxialPiece], rho: f64) -> f64 {
    pieces
        .iter()
        .filter_map(|p| match *p {
            AxialPiece::Line { from, to }
                if (from.x - rho).abs() < 1e-9 && (to.x - rho).abs() < 1e-9 =>
            {
                Some(to.y - from.y)
            }
            _ => None,
        })
        .sum()
}

fn assert_close(a: f64, b: f64, tol: f64) {
    assert!((a - b).abs() <= tol, "{a} vs {b} (tol {tol})");
}

// ---------- AxialPiece ----------

#[test]
fn line_eval_walks_the_segment() {
    let line = AxialPiece::Line {
        from: DVec2::new(1.0, 2.0),
        to: DVec2::new(4.0, 6.0),
    };
    assert_close(line.length(), 5.0, TOL);
    let (p, t, k) = line.eval(2.5);
    assert!(p.distance(DVec2::new(2.5, 4.0)) < TOL);
    assert!(t.distance(DVec2::new(0.6, 0.8)) < TOL);
    assert_eq!(k, 0.0);
    // Clamped beyond the ends.
    assert!(line.eval(-1.0).0.distance(line.start()) < TOL);
    assert!(line.eval(99.0).0.distance(line.end()) < TOL);
}

#[test]
fn malformed_arc_does_not_panic() {
    for radius in [f64::NAN, -1.0, 0.0] {
        let arc = AxialPiece::Arc {
            centre: DVec2::ZERO,
            radius,
            start: 0.0,
            end: 1.0,
        };
        let _ = arc.eval(0.5);
        let _ = arc.eval(f64::NAN);
    }
}

#[test]
fn degenerate_line_does_not_panic() {
    let p = DVec2::new(1.0, 1.0);
    let line = AxialPiece::Line { from: p, to: p };
    let (q, t, k) = line.eval(0.5);
    assert_eq!((q, t, k), (p, DVec2::ZERO, 0.0));
    let (q, _, _) = line.eval(f64::NAN);
    assert!(q.x.is_nan() || q == p);
}

#[test]
fn arc_eval_counter_clockwise_and_clockwise() {
    let c = DVec2::new(10.0, 0.0);
    let ccw = AxialPiece::Arc {
        centre: c,
        radius: 2.0,
        start: 0.0,
        end: FRAC_PI_2,
    };
    assert_close(ccw.length(), PI, TOL);
    assert!(ccw.start().distance(DVec2::new(12.0, 0.0)) < TOL);
    assert!(ccw.end().distance(DVec2::new(10.0, 2.0)) < TOL);
    let (p, t, k) = ccw.eval(0.5 * PI);
    let s2 = 2f64.sqrt();
    assert!(p.distance(c + DVec2::new(s2, s2)) < TOL);
    assert!(t.distance(DVec2::new(-1.0, 1.0) / s2) < TOL);
    assert_close(k, 0.5, TOL);

    let cw = AxialPiece::Arc {
        centre: c,
        radius: 2.0,
        start: FRAC_PI_2,
        end: 0.0,
    };
    let (p, t, k) = cw.eval(0.0);
    assert!(p.distance(DVec2::new(10.0, 2.0)) < TOL);
    assert!(t.distance(DVec2::new(1.0, 0.0)) < TOL);
    assert_close(k, -0.5, TOL);
    assert!(cw.eval(cw.length()).0.distance(cw.end()) < TOL);
}

// ---------- ISO trapezoidal ----------

#[test]
fn iso_crest_clearance_follows_the_standard_table() {
    assert_eq!(iso2904_crest_clearance(1.5), Ok(0.15));
    for p in [2.0, 3.0, 4.0, 5.0] {
        assert_eq!(iso2904_crest_clearance(p), Ok(0.25), "P = {p}");
    }
    for p in [6.0, 7.0, 8.0, 9.0, 10.0, 12.0] {
        assert_eq!(iso2904_crest_clearance(p), Ok(0.5), "P = {p}");
    }
    for p in [14.0, 16.0, 18.0, 20.0, 24.0, 32.0, 44.0] {
        assert_eq!(iso2904_crest_clearance(p), Ok(1.0), "P = {p}");
    }
}

#[test]
fn iso_pitch_outside_the_standard_needs_an_explicit_clearance() {
    for p in [1.0, 1.49, 44.5, 60.0] {
        assert!(matches!(
            iso2904_crest_clearance(p),
            Err(StandardError::PitchOutsideStandard { .. })
        ));
        let tr = IsoTrapezoidal::new(40.0, None, None).unwrap();
        assert!(matches!(
            tr.pieces(p),
            Err(StandardError::PitchOutsideStandard { .. })
        ));
    }
    let tr = IsoTrapezoidal::new(40.0, None, Some(0.1)).unwrap();
    let pieces = tr.pieces(1.0).unwrap();
    assert_close(min_rho(&pieces), 20.0 - (0.5 + 0.1), 1e-9);
}

/// Minor diameters d3 from ISO 2904's table of basic dimensions (as republished, e.g. in
/// DIN 103-4 tables): Tr 8×1.5 → 6.2, Tr 10×2 → 7.5, Tr 42×3 → 38.5, Tr 42×7 → 34,
/// Tr 46×8 → 37.
#[test]
fn iso_minor_diameter_matches_the_standard_table() {
    for (d, p, d3) in [
        (8.0, 1.5, 6.2),
        (10.0, 2.0, 7.5),
        (42.0, 3.0, 38.5),
        (42.0, 7.0, 34.0),
        (46.0, 8.0, 37.0),
    ] {
        let tr = IsoTrapezoidal::new(d, None, None).unwrap();
        assert_close(tr.minor_diameter(p).unwrap(), d3, 1e-9);
        // The curve itself reaches exactly down to d3/2.
        assert_close(min_rho(&tr.pieces(p).unwrap()), 0.5 * d3, 1e-9);
    }
}

#[test]
fn iso_flanks_make_15_degrees_with_the_radial_direction() {
    for r in [0.0, 0.1, 0.25] {
        let tr = IsoTrapezoidal::new(40.0, Some(r), None).unwrap();
        let pieces = tr.pieces(7.0).unwrap();
        let f = flanks(&pieces);
        assert_eq!(f.len(), 2);
        for (a, b) in f {
            assert_close(angle_to_radial_deg(a, b), 15.0, 1e-9);
        }
    }
}

#[test]
fn iso_width_at_pitch_line_is_half_the_pitch() {
    // Basic profile (a_c = 0) and design profile alike: the thread is P/2 thick on the
    // pitch diameter d2 = d − H1 = d − P/2.
    for a_c in [Some(0.0), None] {
        let (d, p) = (40.0, 7.0);
        let tr = IsoTrapezoidal::new(d, Some(0.3), a_c).unwrap();
        let z = crossings(&tr.pieces(p).unwrap(), 0.5 * (d - 0.5 * p));
        assert_eq!(z.len(), 2);
        assert_close(z[1] - z[0], 0.5 * p, 1e-9);
        assert_close(z[0] + z[1], 0.0, 1e-9);
    }
}

#[test]
fn iso_flats_match_the_basic_profile() {
    let (d, p) = (40.0, 7.0);
    // ISO 2901: the basic profile has flats w = 0.366 P (rounded in the standard), equal
    // at crest and root since tooth and groove are alike.
    let basic = IsoTrapezoidal::new(d, None, Some(0.0)).unwrap();
    let pieces = basic.pieces(p).unwrap();
    let crest = flat_at(&pieces, 0.5 * d);
    let root = flat_at(&pieces, 0.5 * d - 0.5 * p);
    assert_close(crest / p, 0.366, 5e-4);
    assert_close(root, crest, 1e-9);
    // Design profile: same crest, root narrowed by the extra depth a_c on both flanks.
    let design = IsoTrapezoidal::new(d, None, None).unwrap();
    let a_c = 0.5;
    let pieces = design.pieces(p).unwrap();
    assert_close(flat_at(&pieces, 0.5 * d), crest, 1e-9);
    let root_design = flat_at(&pieces, 0.5 * d - 0.5 * p - a_c);
    assert_close(
        root_design,
        root - 2.0 * a_c * 15f64.to_radians().tan(),
        1e-9,
    );
}

#[test]
fn iso_root_fillets_are_tangent_and_keep_the_depth() {
    let (d, p, r) = (40.0, 7.0, 0.5); // r = R2max = a_c
    let tr = IsoTrapezoidal::new(d, Some(r), None).unwrap();
    assert_close(tr.iso_max_root_radius(p).unwrap(), 0.5, 0.0);
    let pieces = tr.pieces(p).unwrap();
    assert!(chain_violation(&pieces, p, 0.5 * d).is_none());
    let arcs: Vec<_> = pieces
        .iter()
        .enumerate()
        .filter(|(_, q)| matches!(q, AxialPiece::Arc { .. }))
        .map(|(i, _)| i)
        .collect();
    assert_eq!(arcs.len(), 2);
    for i in arcs {
        let arc = pieces[i];
        let (_, t_in, k) = arc.eval(0.0);
        let (_, t_out, _) = arc.eval(arc.length());
        let (_, t_prev, _) = pieces[i - 1].eval(pieces[i - 1].length());
        let (_, t_next, _) = pieces[i + 1].eval(0.0);
        assert!(t_in.distance(t_prev) < 1e-12, "not tangent to the flank");
        assert!(t_out.distance(t_next) < 1e-12, "not tangent to the root");
        assert_close(k, -1.0 / r, 1e-12);
    }
    // The fillets round the corners off, the root flat stays at d3/2.
    assert_close(min_rho(&pieces), 0.5 * (d - 2.0 * (0.5 * p + 0.5)), 1e-9);
}

#[test]
fn iso_full_radius_root_is_one_arc_tangent_to_both_flanks() {
    let (d, p) = (40.0, 7.0);
    let b = 15f64.to_radians();
    // Largest radius: tangent to both flanks and to the root line, i.e. the circle
    // inscribed in the root corner pair; the root flat is 2·w_r wide and each tangent point
    // lies r·tan(45° − β/2) from its corner.
    let root_flat = 0.5 * p * (1.0 - b.tan()) - 2.0 * 0.5 * b.tan();
    let r_max = 0.5 * root_flat / (FRAC_PI_4 - 0.5 * b).tan();
    let tr = IsoTrapezoidal::new(d, Some(r_max), None).unwrap();
    let pieces = tr.pieces(p).unwrap();
    assert!(chain_violation(&pieces, p, 0.5 * d).is_none());
    assert_eq!(pieces.len(), 5);
    let arc = pieces[2];
    let (_, t0, _) = arc.eval(0.0);
    let (_, t1, _) = arc.eval(arc.length());
    assert!(t0.distance(pieces[1].eval(0.0).1) < 1e-12);
    assert!(t1.distance(pieces[3].eval(0.0).1) < 1e-12);
    assert_close(min_rho(&pieces), 0.5 * d - (0.5 * p + 0.5), 1e-9);

    let too_big = IsoTrapezoidal::new(d, Some(r_max * 1.001), None).unwrap();
    match too_big.pieces(p) {
        Err(StandardError::RootRadiusTooLarge { max, .. }) => assert_close(max, r_max, 1e-12),
        other => panic!("expected RootRadiusTooLarge, got {other:?}"),
    }
}

#[test]
fn iso_sharp_root_has_only_lines() {
    let tr = IsoTrapezoidal::new(20.0, None, None).unwrap();
    let pieces = tr.pieces(4.0).unwrap();
    assert_eq!(pieces.len(), 5);
    assert!(pieces.iter().all(|p| matches!(p, AxialPiece::Line { .. })));
    assert!(chain_violation(&pieces, 4.0, 10.0).is_none());
}

#[test]
fn iso_rejects_bad_dimensions() {
    for d in [0.0, -10.0, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            IsoTrapezoidal::new(d, None, None),
            Err(StandardError::NotPositive {
                name: "major diameter d",
                ..
            })
        ));
    }
    for r in [-0.1, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            IsoTrapezoidal::new(20.0, Some(r), None),
            Err(StandardError::Negative {
                name: "root radius",
                ..
            })
        ));
    }
    for a in [-0.1, f64::NAN] {
        assert!(matches!(
            IsoTrapezoidal::new(20.0, None, Some(a)),
            Err(StandardError::Negative {
                name: "crest clearance a_c",
                ..
            })
        ));
    }
    let tr = IsoTrapezoidal::new(20.0, None, None).unwrap();
    for p in [0.0, -2.0, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            tr.pieces(p),
            Err(StandardError::NotPositive { name: "pitch", .. })
        ));
    }
    for p in [0.0, f64::NAN] {
        assert!(matches!(
            iso2904_crest_clearance(p),
            Err(StandardError::NotPositive { name: "pitch", .. })
        ));
    }
}

#[test]
fn iso_minor_diameter_must_stay_positive() {
    // Tr 2×2: h3 = 1.25, d3 = −0.5.
    let tr = IsoTrapezoidal::new(2.0, None, None).unwrap();
    match tr.pieces(2.0) {
        Err(StandardError::MinorDiameterNotPositive { minor, .. }) => {
            assert_close(minor, -0.5, 1e-12)
        }
        other => panic!("expected MinorDiameterNotPositive, got {other:?}"),
    }
}

#[test]
fn iso_flanks_cross_when_the_clearance_is_too_deep() {
    // Flanks meet where the groove half-width P/4 − (depth − P/4)·tan15° reaches zero.
    let tr = IsoTrapezoidal::new(40.0, None, Some(2.0)).unwrap();
    assert!(matches!(
        tr.pieces(2.0),
        Err(StandardError::FlanksCross { .. })
    ));
}

// ---------- Acme ----------

#[test]
fn acme_minor_diameters_match_published_2g_limits() {
    // Maximum minor diameter of 2G screws (= basic form) from published ASME B1.5
    // tables, inch: 3/8-12 → 0.2817, 1/2-10 → 0.3800, 5/8-8 → 0.4800, 1-5 → 0.7800,
    // 1-10 → 0.8800.
    for (d_in, tpi, minor_in) in [
        (0.375, 12.0, 0.2817),
        (0.5, 10.0, 0.38),
        (0.625, 8.0, 0.48),
        (1.0, 5.0, 0.78),
        (1.0, 10.0, 0.88),
    ] {
        let p = MM_PER_INCH / tpi;
        let acme = AcmeGeneralPurpose::new(d_in * MM_PER_INCH, None).unwrap();
        let got = 2.0 * min_rho(&acme.pieces(p).unwrap()) / MM_PER_INCH;
        assert_close(got, minor_in, 5.1e-5);
        assert_close(
            acme.minor_diameter(p).unwrap() / MM_PER_INCH,
            minor_in,
            5.1e-5,
        );
    }
}

#[test]
fn acme_depths_and_flats_match_the_basic_dimension_table() {
    // ASME B1.5 "Acme thread form, basic dimensions" (inch): pitch, total depth of thread
    // (all screws), flat at crest of screw (0.3707 P), flat at root of screw.
    for (p_in, depth_in, crest_in, root_in) in [
        (0.0625, 0.0362, 0.0232, 0.0206),
        (0.1, 0.0600, 0.0371, 0.0319),
        (0.25, 0.1350, 0.0927, 0.0875),
    ] {
        let d = 2.0 * MM_PER_INCH;
        let p = p_in * MM_PER_INCH;
        let acme = AcmeGeneralPurpose::new(d, None).unwrap();
        let pieces = acme.pieces(p).unwrap();
        let depth = 0.5 * d - min_rho(&pieces);
        assert_close(depth / MM_PER_INCH, depth_in, 5.1e-5);
        let crest = flat_at(&pieces, 0.5 * d);
        let root = flat_at(&pieces, 0.5 * d - depth);
        assert_close(crest / MM_PER_INCH, crest_in, 5.1e-5);
        assert_close(root / MM_PER_INCH, root_in, 5.1e-5);
    }
}

#[test]
fn acme_flanks_make_14_5_degrees_and_width_is_half_pitch() {
    let (d, p) = (25.4, 5.08);
    let acme = AcmeGeneralPurpose::new(d, Some(0.2)).unwrap();
    let pieces = acme.pieces(p).unwrap();
    assert!(chain_violation(&pieces, p, 0.5 * d).is_none());
    let f = flanks(&pieces);
    assert_eq!(f.len(), 2);
    for (a, b) in f {
        assert_close(angle_to_radial_deg(a, b), 14.5, 1e-9);
    }
    let z = crossings(&pieces, 0.5 * (d - 0.5 * p));
    assert_eq!(z.len(), 2);
    assert_close(z[1] - z[0], 0.5 * p, 1e-9);
}

#[test]
fn acme_allowance_switches_at_ten_threads_per_inch() {
    let coarse = asme_b1_5_minor_diameter_allowance(MM_PER_INCH / 10.0).unwrap();
    let fine = asme_b1_5_minor_diameter_allowance(MM_PER_INCH / 12.0).unwrap();
    assert_close(coarse, 0.508, 1e-12);
    assert_close(fine, 0.254, 1e-12);
}

#[test]
fn acme_rejects_bad_dimensions() {
    for d in [0.0, -1.0, f64::NAN] {
        assert!(matches!(
            AcmeGeneralPurpose::new(d, None),
            Err(StandardError::NotPositive {
                name: "major diameter d",
                ..
            })
        ));
    }
    assert!(matches!(
        AcmeGeneralPurpose::new(25.0, Some(-0.01)),
        Err(StandardError::Negative {
            name: "root radius",
            ..
        })
    ));
    let acme = AcmeGeneralPurpose::new(25.0, None).unwrap();
    assert!(matches!(
        acme.pieces(-1.0),
        Err(StandardError::NotPositive { name: "pitch", .. })
    ));
    // Depth 0.5·P + 0.127 on a 1 mm shaft with P = 2 mm: no core left.
    assert!(matches!(
        AcmeGeneralPurpose::new(1.0, None).unwrap().pieces(2.0),
        Err(StandardError::MinorDiameterNotPositive { .. })
    ));
    // P = 0.1 mm: the 0.254 mm allowance alone makes the flanks cross.
    assert!(matches!(
        acme.pieces(0.1),
        Err(StandardError::FlanksCross { .. })
    ));
    assert!(matches!(
        AcmeGeneralPurpose::new(25.0, Some(2.0))
            .unwrap()
            .pieces(5.08),
        Err(StandardError::RootRadiusTooLarge { .. })
    ));
}

// ---------- Ball-arc ----------

fn ball_4010() -> BallArc {
    // 40 mm screw, 10 mm lead, 6.35 mm balls, conformity 0.53.
    BallArc::new(6.35, 0.53 * 6.35, 40.5, 39.5).unwrap()
}

#[test]
fn ball_arc_depth_and_crest() {
    let g = ball_4010();
    let p = 10.0;
    let pieces = g.pieces(p).unwrap();
    assert!(chain_violation(&pieces, p, 0.5 * 39.5).is_none());
    // Depth below the outer diameter: d/2 − (d_0/2 − D_w/2).
    let depth = 0.5 * 39.5 - min_rho(&pieces);
    assert_close(depth, 0.5 * 39.5 - (0.5 * 40.5 - 0.5 * 6.35), 1e-9);
    assert_close(g.depth(), depth, 1e-9);
    // Crest lines lie on the outer diameter, together P minus the groove width.
    let crest = flat_at(&pieces, 0.5 * 39.5);
    assert_close(crest, p - g.groove_width(), 1e-9);
    assert_close(g.conformity(), 0.53, 1e-12);
}

#[test]
fn ball_arc_holds_the_ball_touching_only_at_the_bottom() {
    let g = ball_4010();
    let pieces = g.pieces(10.0).unwrap();
    let arc = pieces[1];
    let AxialPiece::Arc { radius, .. } = arc else {
        panic!("middle piece must be the groove arc");
    };
    assert_close(radius, 0.53 * 6.35, 0.0);
    let ball_centre = DVec2::new(0.5 * 40.5, 0.0);
    let ball_r = 0.5 * 6.35;
    let mut closest = f64::INFINITY;
    for k in 0..=200 {
        let (pt, _, curvature) = arc.eval(arc.length() * k as f64 / 200.0);
        // On the groove circle of radius r_g about the arc centre.
        assert_close(pt.distance(g.arc_centre()), radius, 1e-9);
        assert_close(curvature, -1.0 / radius, 1e-12);
        // Never inside the ball.
        let gap = pt.distance(ball_centre) - ball_r;
        assert!(gap > -1e-9, "groove cuts into the ball: {gap}");
        closest = closest.min(gap);
    }
    // Touches it (at the bottom, k = 100).
    assert_close(closest, 0.0, 1e-9);
    let (bottom, tangent, _) = arc.eval(0.5 * arc.length());
    assert!(bottom.distance(DVec2::new(0.5 * (40.5 - 6.35), 0.0)) < 1e-9);
    assert!(tangent.distance(DVec2::Y) < 1e-9);
    // The arc ends on the outer diameter.
    assert_close(arc.start().x, 0.5 * 39.5, 1e-9);
    assert_close(arc.end().x, 0.5 * 39.5, 1e-9);
}

#[test]
fn ball_arc_rejects_bad_dimensions() {
    let names = [
        "ball diameter D_w",
        "groove radius r_g",
        "ball-centre diameter d_0",
        "outer diameter d",
    ];
    for (i, name) in names.iter().enumerate() {
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let mut v = [6.35, 3.4, 40.5, 39.5];
            v[i] = bad;
            match BallArc::new(v[0], v[1], v[2], v[3]) {
                Err(StandardError::NotPositive { name: n, .. }) => assert_eq!(n, *name),
                other => panic!("{name} = {bad}: {other:?}"),
            }
        }
    }
    assert!(matches!(
        BallArc::new(6.35, 3.175, 40.5, 39.5),
        Err(StandardError::GrooveRadiusTooSmall { .. })
    ));
    assert!(matches!(
        BallArc::new(6.35, 3.4, 6.35, 5.0),
        Err(StandardError::GrooveBottomNotAboveAxis { .. })
    ));
    // Groove bottom diameter 40.5 − 6.35 = 34.15.
    assert!(matches!(
        BallArc::new(6.35, 3.4, 40.5, 34.15),
        Err(StandardError::OuterDiameterNotAboveGrooveBottom { .. })
    ));
    // Arc centre diameter 34.15 + 2·3.4 = 40.95.
    assert!(matches!(
        BallArc::new(6.35, 3.4, 40.5, 41.0),
        Err(StandardError::GrooveOverhangs { .. })
    ));
    let g = ball_4010();
    assert!(matches!(
        g.pieces(g.groove_width()),
        Err(StandardError::GroovesOverlap { .. })
    ));
    assert!(matches!(
        g.pieces(5.0),
        Err(StandardError::GroovesOverlap { .. })
    ));
    assert!(matches!(
        g.pieces(f64::NAN),
        Err(StandardError::NotPositive { name: "pitch", .. })
    ));
}

#[test]
fn standard_profile_dispatches() {
    let profiles = [
        StandardProfile::IsoTrapezoidal(IsoTrapezoidal::new(40.0, Some(0.2), None).unwrap()),
        StandardProfile::Acme(AcmeGeneralPurpose::new(40.0, Some(0.2)).unwrap()),
        StandardProfile::BallArc(ball_4010()),
    ];
    for prof in profiles {
        let pieces = prof.pieces(10.0).unwrap();
        assert!(chain_violation(&pieces, 10.0, 0.5 * prof.outer_diameter()).is_none());
    }
}

#[test]
fn errors_name_the_dimension() {
    let e = IsoTrapezoidal::new(-1.0, None, None).unwrap_err();
    assert!(e.to_string().contains("major diameter d"));
    let e = ball_4010().pieces(1.0).unwrap_err();
    assert!(e.to_string().contains("grooves overlap"));
}

// ---------- properties ----------

proptest! {
    #[test]
    fn iso_chain_is_continuous_and_closed(
        p in 1.5f64..44.0,
        d_extra in 1.0f64..200.0,
        r_frac in 0.0f64..=1.0,
    ) {
        let a_c = iso2904_crest_clearance(p).unwrap();
        let d = 2.0 * (0.5 * p + a_c) + d_extra;
        let b = 15f64.to_radians();
        let root_half = 0.25 * p * (1.0 - b.tan()) - a_c * b.tan();
        let r_max = root_half / (FRAC_PI_4 - 0.5 * b).tan();
        let tr = IsoTrapezoidal::new(d, Some(r_frac * r_max), None).unwrap();
        let pieces = tr.pieces(p).unwrap();
        prop_assert_eq!(chain_violation(&pieces, p, 0.5 * d), None);
        prop_assert!((min_rho(&pieces) - (0.5 * d - 0.5 * p - a_c)).abs() < 1e-9);
    }

    #[test]
    fn acme_chain_is_continuous_and_closed(
        tpi in 1.0f64..16.0,
        d_extra in 1.0f64..150.0,
        r_frac in 0.0f64..=1.0,
    ) {
        let p = MM_PER_INCH / tpi;
        let allowance = asme_b1_5_minor_diameter_allowance(p).unwrap();
        let d = p + allowance + d_extra;
        let b = 14.5f64.to_radians();
        let root_half = 0.25 * p * (1.0 - b.tan()) - 0.5 * allowance * b.tan();
        let r_max = root_half / (FRAC_PI_4 - 0.5 * b).tan();
        let acme = AcmeGeneralPurpose::new(d, Some(r_frac * r_max)).unwrap();
        let pieces = acme.pieces(p).unwrap();
        prop_assert_eq!(chain_violation(&pieces, p, 0.5 * d), None);
    }

    #[test]
    fn ball_arc_chain_is_continuous_and_closed(
        dw in 1.0f64..20.0,
        conformity in 0.505f64..0.6,
        d0_extra in 1.0f64..100.0,
        od_frac in 0.05f64..0.95,
        crest_frac in 0.01f64..1.0,
    ) {
        let rg = conformity * dw;
        let d0 = dw + d0_extra;
        let bottom = 0.5 * (d0 - dw);
        let centre = bottom + rg;
        let outer = bottom + od_frac * (centre - bottom);
        let g = BallArc::new(dw, rg, d0, 2.0 * outer).unwrap();
        let p = g.groove_width() * (1.0 + crest_frac);
        let pieces = g.pieces(p).unwrap();
        prop_assert_eq!(chain_violation(&pieces, p, outer), None);
        prop_assert!((min_rho(&pieces) - bottom).abs() < 1e-9);
    }
}
