//! Worms against DIN 3975-1's definitions: the basic dimensions from m, z1, q; ZA straight at
//! α in the axial section; ZN straight at α in the space's normal section; ZI the involute
//! helicoid of its base cylinder, whose section by a plane tangent to that cylinder is a
//! straight line along the base helix. The curved sections are checked against points built
//! from those definitions here, not from the form's own code.

use super::*;
use crate::geometry::profile::standard::StandardProfile;
use crate::geometry::profile::Profile;
use std::f64::consts::TAU;

/// m = 2, z1 = 1, q = 10, α = 20°: d1 = 20, d_a1 = 24, d_f1 = 15.2 (c* = 0.2).
fn worm(flank: WormFlank) -> Worm {
    Worm::new(flank, 2.0, 1, 10.0, None, None, None).unwrap()
}

/// Distance from `q` to the chain of pieces.
pub(super) fn distance_to_chain(pieces: &[AxialPiece], q: DVec2) -> f64 {
    pieces
        .iter()
        .map(|p| match *p {
            AxialPiece::Line { from, to } => {
                let d = to - from;
                let t = ((q - from).dot(d) / d.length_squared()).clamp(0.0, 1.0);
                q.distance(from + t * d)
            }
            AxialPiece::Arc {
                centre,
                radius,
                start,
                end,
            } => {
                let a = (q - centre).to_angle();
                let (lo, hi) = (start.min(end), start.max(end));
                let inside = [-TAU, 0.0, TAU]
                    .iter()
                    .any(|k| (lo..=hi).contains(&(a + k)));
                if inside {
                    (q.distance(centre) - radius).abs()
                } else {
                    q.distance(p.start()).min(q.distance(p.end()))
                }
            }
        })
        .fold(f64::INFINITY, f64::min)
}

fn chain_is_continuous(pieces: &[AxialPiece], pitch: f64, crest: f64) {
    assert!(pieces[0].start().distance(DVec2::new(crest, -0.5 * pitch)) < 1e-12);
    let last = pieces.last().unwrap().end();
    assert!(last.distance(DVec2::new(crest, 0.5 * pitch)) < 1e-12);
    for w in pieces.windows(2) {
        assert!(
            w[0].end().distance(w[1].start()) < 1e-12,
            "gap {} {:?}",
            w[0].end().distance(w[1].start()),
            w
        );
        assert!(w[0].end().y <= w[1].end().y + 1e-12, "z falls");
    }
}

#[test]
fn the_basic_dimensions_follow_din_3975_from_m_z1_q() {
    let w = worm(WormFlank::ZA);
    assert!((w.axial_pitch() - PI * 2.0).abs() < 1e-12);
    assert!((w.lead() - PI * 2.0).abs() < 1e-12);
    assert_eq!(w.reference_diameter(), 20.0);
    assert_eq!(w.tip_diameter(), 24.0);
    assert!((w.root_diameter() - 15.2).abs() < 1e-12);
    assert!((w.lead_angle().to_degrees() - 0.1f64.atan().to_degrees()).abs() < 1e-12);
    let two = Worm::new(WormFlank::ZA, 2.0, 2, 10.0, None, None, None).unwrap();
    assert!((two.lead() - 4.0 * PI).abs() < 1e-12);
}

#[test]
fn a_za_flank_is_straight_at_alpha_and_the_space_is_half_the_pitch_at_d1() {
    let w = worm(WormFlank::ZA);
    let px = w.axial_pitch();
    let pieces = w.pieces(px).unwrap();
    chain_is_continuous(&pieces, px, 12.0);
    let flanks: Vec<_> = pieces
        .iter()
        .filter_map(|p| match *p {
            AxialPiece::Line { from, to } if (from.x - to.x).abs() > 0.5 => Some((from, to)),
            _ => None,
        })
        .collect();
    assert_eq!(flanks.len(), 2);
    for (from, to) in &flanks {
        let d = *to - *from;
        let angle = d.y.abs().atan2(d.x.abs()).to_degrees();
        assert!((angle - 20.0).abs() < 1e-10, "{angle}");
        // Where the flank crosses the reference cylinder (rho = 10), the space is p_x/2.
        let t = (10.0 - from.x) / d.x;
        assert!(((from.y + t * d.y).abs() - 0.25 * px).abs() < 1e-12);
    }
    // No concave stretch for a nose smaller than the root fillet 0.2·m = 0.4 mm.
    let p = w.lead() / TAU;
    let profile = Profile::from_axial(pieces, p, TAU);
    assert!(profile.concave_stretches(p, 0.35).is_empty());
    let (lo, hi) = profile.radius_range();
    assert!((lo - 7.6).abs() < 1e-6 && (hi - 12.0).abs() < 1e-12);
}

/// Points of ZI's right flank (z > 0) from the involute helicoid's definition: the
/// straight generator in the plane x = r_b tangent to the base cylinder, parallel to the base
/// helix (direction (0, r_b, p)), swept along the helix into the axial half-plane.
fn zi_generator_points(w: &Worm, rho_from: f64, rho_to: f64) -> Vec<DVec2> {
    let (m, r1) = (2.0, 10.0);
    let gamma = (1.0f64 / 10.0).atan();
    let alpha_t = (20f64.to_radians().tan() / gamma.sin()).atan();
    let rb = r1 * alpha_t.cos();
    assert!((2.0 * rb - w.base_diameter()).abs() < 1e-12);
    let p = m * 1.0 / 2.0; // lead / 2π = z1·m/2
    let swept = |u: f64| {
        let (x, y, z) = (rb, u, u * p / rb);
        DVec2::new(x.hypot(y), z - p * y.atan2(x))
    };
    // Shift along z so that the flank crosses the reference cylinder at +p_x/4.
    let u1 = (r1 * r1 - rb * rb).sqrt();
    let shift = 0.25 * PI * m - swept(u1).y;
    let (u0, u_end) = (
        (rho_from * rho_from - rb * rb).sqrt(),
        (rho_to * rho_to - rb * rb).sqrt(),
    );
    (0..=2000)
        .map(|k| {
            let q = swept(u0 + (u_end - u0) * k as f64 / 2000.0);
            DVec2::new(q.x, q.y + shift)
        })
        .collect()
}

#[test]
fn a_zi_flank_is_the_involute_helicoid_within_a_hundredth_of_a_micrometre() {
    let w = worm(WormFlank::ZI);
    let px = w.axial_pitch();
    let pieces = w.pieces(px).unwrap();
    chain_is_continuous(&pieces, px, 12.0);
    // From below the reference cylinder (above the root fillet) to the tip.
    let worst = zi_generator_points(&w, 8.2, 12.0)
        .into_iter()
        .map(|q| distance_to_chain(&pieces, q))
        .fold(0.0, f64::max);
    assert!(worst <= FLANK_TOLERANCE, "{worst}");
    // And it is a curve, not a line: the straight chord from root to tip misses it.
    let pts = zi_generator_points(&w, 8.2, 12.0);
    let (a, b) = (pts[0], pts[2000]);
    let mid = pts[1000];
    assert!((mid - a).perp_dot((b - a).normalize()).abs() > 100.0 * FLANK_TOLERANCE);
}

#[test]
fn the_axial_pressure_angle_of_zi_at_d1_is_atan_tan_alpha_over_cos_gamma() {
    let w = worm(WormFlank::ZI);
    let px = w.axial_pitch();
    let pieces = w.pieces(px).unwrap();
    let expected = (20f64.to_radians().tan() / (0.1f64).atan().cos()).atan();
    // The arc crossing rho = 10 on the right flank: its tangent there.
    let mut found = false;
    for p in &pieces {
        if let AxialPiece::Arc { centre, radius, .. } = *p {
            let (s, e) = (p.start(), p.end());
            if s.y > 0.0 && (s.x - 10.0) * (e.x - 10.0) <= 0.0 && (s.x - e.x).abs() > 0.0 {
                let dz = (radius * radius - (10.0 - centre.x).powi(2)).sqrt();
                let q = DVec2::new(
                    10.0,
                    if s.y > centre.y {
                        centre.y + dz
                    } else {
                        centre.y - dz
                    },
                );
                let radial = q - centre;
                let tangent = radial.perp();
                let angle = tangent.y.abs().atan2(tangent.x.abs());
                // The arcs lie within 0.01 µm of the curve over spans of tenths of a mm: the
                // slope agrees to about 1e-5 rad.
                assert!((angle - expected).abs() < 1e-4, "{angle} vs {expected}");
                found = true;
            }
        }
    }
    assert!(found);
    assert!((w.axial_pressure_angle() - expected).abs() < 1e-15);
}

/// Points of ZN's right flank from its definition: the straight blade in the plane normal to
/// the space's helix at the reference cylinder, the normal space width `(p_x/2)·cos γ`, at α
/// to the radial direction; each point swept along the helix into the axial half-plane.
fn zn_blade_points(t_from: f64, t_to: f64) -> Vec<glam::DVec2> {
    use glam::DVec3;
    let (m, r1, p) = (2.0, 10.0, 1.0);
    let helix = DVec3::new(0.0, r1, p).normalize();
    let radial = DVec3::X;
    let across = radial.cross(helix).normalize(); // in the normal plane, towards +z
    assert!(across.z > 0.0);
    let gamma = (p / r1).atan();
    let half_space = 0.25 * PI * m * gamma.cos();
    let tan_a = 20f64.to_radians().tan();
    (0..=2000)
        .map(|k| {
            let t = t_from + (t_to - t_from) * k as f64 / 2000.0;
            let q = DVec3::new(r1, 0.0, 0.0) + t * radial + (half_space + t * tan_a) * across;
            DVec2::new(q.x.hypot(q.y), q.z - p * q.y.atan2(q.x))
        })
        .collect()
}

#[test]
fn a_zn_flank_is_the_swept_straight_blade_within_a_hundredth_of_a_micrometre() {
    let w = worm(WormFlank::ZN);
    let px = w.axial_pitch();
    let pieces = w.pieces(px).unwrap();
    chain_is_continuous(&pieces, px, 12.0);
    let pts: Vec<_> = zn_blade_points(-1.8, 1.99)
        .into_iter()
        .filter(|q| q.x > 8.2 && q.x < 12.0)
        .collect();
    assert!(pts.len() > 1500);
    let worst = pts
        .iter()
        .map(|q| distance_to_chain(&pieces, *q))
        .fold(0.0, f64::max);
    assert!(worst <= FLANK_TOLERANCE, "{worst}");
}

#[test]
fn curved_flanks_join_their_fillets_and_arcs_without_a_corner() {
    let zk = WormFlank::ZK {
        wheel_diameter: 250.0,
    };
    for flank in [WormFlank::ZN, WormFlank::ZI, zk] {
        let w = worm(flank);
        let pieces = w.pieces(w.axial_pitch()).unwrap();
        // Only the two crest edges turn; every other joint is tangent.
        let kinks = pieces
            .windows(2)
            .filter(|pair| {
                let (_, out, _) = pair[0].eval(pair[0].length());
                let (_, inn, _) = pair[1].eval(0.0);
                out.perp_dot(inn).atan2(out.dot(inn)).abs() > 1e-9
            })
            .count();
        let turns: Vec<f64> = pieces
            .windows(2)
            .map(|pair| {
                let (_, out, _) = pair[0].eval(pair[0].length());
                let (_, inn, _) = pair[1].eval(0.0);
                out.perp_dot(inn).atan2(out.dot(inn))
            })
            .filter(|t| t.abs() > 1e-9)
            .collect();
        assert_eq!(kinks, 2, "{flank:?} {turns:?}");
        let p = w.lead() / TAU;
        let count = pieces.len();
        let profile = Profile::from_axial(pieces, p, TAU);
        // The profile adds a corner at each crest edge and nowhere else: its pieces are the
        // axial ones and two corners (a corner between tangent arcs would make the ring
        // roll on the spot mid-flank).
        assert_eq!(profile.breaks().len(), count + 2 + 1, "{flank:?}");
        assert!(profile.concave_stretches(p, 0.35).is_empty(), "{flank:?}");
    }
}

#[test]
fn every_impossible_worm_is_refused_naming_why() {
    let new = |flank, m, z1, q, a: Option<f64>, c: Option<f64>, r: Option<f64>| {
        Worm::new(flank, m, z1, q, a, c, r).unwrap_err()
    };
    for a in [0.0, 45.0, f64::NAN] {
        assert_eq!(
            new(WormFlank::ZA, 2.0, 1, 10.0, Some(a), None, None).to_string(),
            StandardError::PressureAngleOutOfRange { degrees: a }.to_string()
        );
    }
    assert!(matches!(
        new(WormFlank::ZA, f64::NAN, 1, 10.0, None, None, None),
        StandardError::NotPositive {
            name: "module m",
            ..
        }
    ));
    assert!(matches!(
        new(WormFlank::ZA, 2.0, 0, 10.0, None, None, None),
        StandardError::NotPositive {
            name: "starts z1",
            ..
        }
    ));
    assert!(matches!(
        new(WormFlank::ZA, 2.0, 1, 2.0, None, None, None),
        StandardError::MinorDiameterNotPositive { .. }
    ));
    // q = 6, z1 = 3: tan γ = 0.5, tan α_t = tan 20° / sin γ, d_b = 12·cos α_t = 9.31 mm,
    // above the root diameter 12 − 4.8 = 7.2 mm.
    assert!(matches!(
        new(WormFlank::ZI, 2.0, 3, 6.0, None, None, None),
        StandardError::RootInsideBaseCylinder { .. }
    ));
    // At 40° the flanks, 2.4 mm deep below d1 with a space of π mm there, meet above the
    // root: p_x/2 − 2·1.2·m·tan 40° < 0.
    assert!(matches!(
        new(WormFlank::ZA, 2.0, 1, 10.0, Some(40.0), None, Some(0.0)),
        StandardError::FlanksCross { .. }
    ));
    let StandardError::RootRadiusTooLarge { radius, max } =
        new(WormFlank::ZI, 2.0, 1, 10.0, None, None, Some(5.0))
    else {
        panic!("not refused for its root radius")
    };
    assert_eq!(radius, 5.0);
    assert!(max > 0.4 && max < 5.0);
    assert!(Worm::new(WormFlank::ZI, 2.0, 1, 10.0, None, None, Some(max)).is_ok());
    assert!(matches!(
        worm(WormFlank::ZA).pieces(5.0),
        Err(StandardError::PitchNotModule { .. })
    ));
    for d0 in [0.0, -250.0, f64::NAN] {
        let zk = WormFlank::ZK { wheel_diameter: d0 };
        assert!(matches!(
            new(zk, 2.0, 1, 10.0, None, None, None),
            StandardError::NotPositive {
                name: "wheel diameter d0",
                ..
            }
        ));
    }
    // m = 2, z1 = 2, q = 6: a wheel of 100 mm is near enough a plane to cut near ZI, whose
    // base cylinder (7.87 mm, as above) lies outside the 7.2 mm root: no flank reaches it.
    // A 10 mm wheel's envelope does.
    let zk = |wheel_diameter| WormFlank::ZK { wheel_diameter };
    assert!(matches!(
        new(zk(100.0), 2.0, 2, 6.0, None, None, None),
        StandardError::NoWheelEnvelope { wheel, .. } if wheel == 100.0
    ));
    assert!(Worm::new(zk(10.0), 2.0, 2, 6.0, None, None, None).is_ok());
}

#[test]
fn a_designation_fixes_the_form_the_lead_and_the_starts() {
    use super::super::designation::parse;
    let d = parse("ZI m2 z1 q10").unwrap();
    assert_eq!(d.form, StandardProfile::Worm(worm(WormFlank::ZI)));
    assert!((d.lead.unwrap() - 2.0 * PI).abs() < 1e-12);
    assert_eq!(d.starts, Some(1));
    assert!(!d.left_hand);
    let d = parse("ZA m2.5 z2 q10 a15 LH").unwrap();
    let StandardProfile::Worm(w) = d.form else {
        panic!()
    };
    assert_eq!(
        (w.flank(), w.module(), w.starts(), w.quotient()),
        (WormFlank::ZA, 2.5, 2, 10.0)
    );
    assert!((w.pressure_angle().to_degrees() - 15.0).abs() < 1e-12);
    assert!((d.lead.unwrap() - 5.0 * PI).abs() < 1e-12);
    assert!(d.left_hand);
    let d = parse("ZK m2 z1 q10 D250").unwrap();
    assert_eq!(
        d.form,
        StandardProfile::Worm(worm(WormFlank::ZK {
            wheel_diameter: 250.0
        }))
    );
    assert!((d.lead.unwrap() - 2.0 * PI).abs() < 1e-12);
}

#[test]
fn a_malformed_worm_designation_is_refused_naming_the_word() {
    use super::super::designation::{parse, DesignationError};
    for (text, names) in [
        ("ZI m2 z1", "module, starts and diameter quotient"),
        ("ZI m2 z1.5 q10", "whole number"),
        ("ZI m2 z1 q10 x3", "`x3`"),
        ("ZI m-2 z1 q10", "`m-2`"),
        ("ZI m2 m3 z1 q10", "`m` is given twice"),
        ("ZK m2 z1 q10", "the wheel's diameter"),
        ("ZI m2 z1 q10 D250", "D (a wheel's diameter) belongs to ZK"),
    ] {
        match parse(text) {
            Err(e @ DesignationError::Refused { .. }) => {
                assert!(e.to_string().contains(names), "{text}: {e}")
            }
            other => panic!("{text}: {other:?}"),
        }
    }
    assert!(matches!(
        parse("ZI m2 z3 q6"),
        Err(DesignationError::Form {
            error: StandardError::RootInsideBaseCylinder { .. },
            ..
        })
    ));
}

#[test]
fn whirl_profile_lists_the_worms_din_3975_dimensions() {
    let form = StandardProfile::Worm(worm(WormFlank::ZI));
    let rows = form.dimensions(PI * 2.0).unwrap();
    let value = |name: &str| {
        rows.iter()
            .find(|d| d.name == name)
            .unwrap_or_else(|| panic!("no {name}"))
            .value
    };
    assert_eq!(value("reference diameter d1"), 20.0);
    assert_eq!(value("tip diameter d_a1"), 24.0);
    assert!((value("root diameter d_f1") - 15.2).abs() < 1e-12);
    assert!((value("axial tooth thickness s_x1") - 0.5 * PI * 2.0).abs() < 1e-12);
    assert!(form.source().contains("DIN 3975-1"));
    assert_eq!(form.outer_diameter(), 24.0);
    let zk = StandardProfile::Worm(worm(WormFlank::ZK {
        wheel_diameter: 250.0,
    }));
    let rows = zk.dimensions(PI * 2.0).unwrap();
    let d0 = rows.iter().find(|d| d.name == "wheel diameter d0").unwrap();
    assert_eq!(d0.value, 250.0);
    // Dressed to leave π mm of space on d1, the wheel is about as thick as the space's
    // normal width there, π·cos γ.
    let s0 = rows
        .iter()
        .find(|d| d.name == "wheel thickness at d0")
        .unwrap();
    assert!(
        (s0.value - PI * 0.1f64.atan().cos()).abs() < 0.05,
        "{}",
        s0.value
    );
}
