//! The raceways against their definition: the ball of diameter D_w, centred on the
//! ball-centre diameter, touches each gothic-arch flank at the contact angle and lies inside
//! the groove everywhere else; the circular arc is the ball-arc groove.

use super::*;
use crate::geometry::profile::standard::StandardProfile;
use std::f64::consts::TAU;

/// A 1/8" ball (3.175 mm) on a 16 mm ball-centre diameter in a 15.5 mm shaft, conformity
/// 0.55, 45°: the sizes of the makers' 16x5 screws.
fn gothic(relief: Option<f64>) -> BallScrew {
    BallScrew::new(Raceway::GothicArch, 3.175, 0.55, None, 16.0, 15.5, relief).unwrap()
}

/// The flank arcs (radius r_g) of the pieces.
fn flank_arcs(screw: &BallScrew, pieces: &[AxialPiece]) -> Vec<(DVec2, f64, f64, f64)> {
    pieces
        .iter()
        .filter_map(|p| match *p {
            AxialPiece::Arc {
                centre,
                radius,
                start,
                end,
            } if (radius - screw.groove_radius()).abs() < 1e-12 => {
                Some((centre, radius, start, end))
            }
            _ => None,
        })
        .collect()
}

/// Whether `angle` lies between `a` and `b` (either order), up to a turn.
fn within(angle: f64, a: f64, b: f64) -> bool {
    let (lo, hi) = (a.min(b), a.max(b));
    [-2.0 * PI, 0.0, 2.0 * PI]
        .iter()
        .any(|k| (lo..=hi).contains(&(angle + k)))
}

fn continuous(pieces: &[AxialPiece], pitch: f64, crest: f64) {
    assert!(pieces[0].start().distance(DVec2::new(crest, -0.5 * pitch)) < 1e-12);
    assert!(
        pieces
            .last()
            .unwrap()
            .end()
            .distance(DVec2::new(crest, 0.5 * pitch))
            < 1e-12
    );
    for w in pieces.windows(2) {
        assert!(w[0].end().distance(w[1].start()) < 1e-12, "gap");
    }
}

#[test]
fn the_ball_touches_each_gothic_arch_flank_at_the_contact_angle() {
    let screw = gothic(None);
    let pieces = screw.pieces(5.0).unwrap();
    continuous(&pieces, 5.0, 7.75);
    let ball = DVec2::new(8.0, 0.0);
    let arcs = flank_arcs(&screw, &pieces);
    assert_eq!(arcs.len(), 2);
    for (centre, radius, start, end) in arcs {
        // Internally tangent: the ball's circle inside the flank's, touching it once.
        assert!((centre.distance(ball) + 0.5 * 3.175 - radius).abs() < 1e-12);
        assert!((radius - 0.55 * 3.175).abs() < 1e-12);
        // The touching point lies on the line of centres, beyond the ball's centre.
        let towards = (ball - centre).normalize();
        let touch = ball + 0.5 * 3.175 * towards;
        // 45° from the radial direction, inward, on the flank's own side.
        let angle = towards.y.abs().atan2(-towards.x).to_degrees();
        assert!((angle - 45.0).abs() < 1e-10, "{angle}");
        assert!(touch.x < 8.0 && touch.y.signum() == -centre.y.signum());
        // On the drawn flank, not on its circle's extension.
        assert!(within((touch - centre).to_angle(), start, end));
    }
    // Nowhere does the groove cut into the ball: every point is at least D_w/2 from its
    // centre.
    for p in &pieces {
        for k in 0..=400 {
            let (q, _, _) = p.eval(p.length() * k as f64 / 400.0);
            assert!(q.distance(ball) >= 0.5 * 3.175 - 1e-12, "{q}");
        }
    }
}

#[test]
fn the_gothic_arch_flanks_cross_below_the_ball_at_a_concave_cusp() {
    let screw = gothic(None);
    let pieces = screw.pieces(5.0).unwrap();
    let arcs: Vec<_> = pieces
        .iter()
        .filter(|p| matches!(p, AxialPiece::Arc { .. }))
        .collect();
    let cusp = arcs[0].end();
    assert!(cusp.y.abs() < 1e-12);
    // Below the ball: deeper than the ball's lowest point, as the offset centres put it.
    assert!(cusp.x < 8.0 - 0.5 * 3.175);
    assert!((cusp.x - screw.bottom_radius()).abs() < 1e-12);
    // The tangents turn inward there (a concave corner): the left flank arrives heading
    // towards +z and −rho... and leaves heading towards +z and +rho.
    let (_, arrive, _) = arcs[0].eval(arcs[0].length());
    let (_, leave, _) = arcs[1].eval(0.0);
    assert!(arrive.x < 0.0 && leave.x > 0.0);
    let profile = crate::geometry::profile::Profile::from_axial(pieces, 5.0 / TAU, TAU);
    let stretches = profile.concave_stretches(5.0 / TAU, 1.0);
    assert!(stretches.iter().any(|c| c.min_radius == 0.0));
}

#[test]
fn the_relief_rounds_the_cusp_tangent_to_both_flanks_below_the_contact_points() {
    let relief = 1.2;
    let screw = gothic(Some(relief));
    let pieces = screw.pieces(5.0).unwrap();
    continuous(&pieces, 5.0, 7.75);
    let arcs: Vec<_> = pieces
        .iter()
        .filter(|p| matches!(p, AxialPiece::Arc { .. }))
        .copied()
        .collect();
    assert_eq!(arcs.len(), 3);
    for w in arcs.windows(2) {
        let (_, out, _) = w[0].eval(w[0].length());
        let (_, inn, _) = w[1].eval(0.0);
        assert!(
            out.perp_dot(inn).atan2(out.dot(inn)).abs() < 1e-12,
            "not tangent"
        );
    }
    let AxialPiece::Arc { radius, centre, .. } = arcs[1] else {
        unreachable!()
    };
    assert_eq!(radius, relief);
    assert_eq!(centre.y, 0.0);
    // Shallower than the cusp, below the ball.
    let cusp = gothic(None).bottom_radius();
    assert!(screw.bottom_radius() > cusp && screw.bottom_radius() < 8.0 - 0.5 * 3.175);
    // The contact points are untouched: the ball still touches both flank arcs.
    assert!(within(
        (screw.contact_point() - screw.flank_centre()).to_angle(),
        match arcs[0] {
            AxialPiece::Arc { start, .. } => start,
            _ => unreachable!(),
        },
        match arcs[0] {
            AxialPiece::Arc { end, .. } => end,
            _ => unreachable!(),
        },
    ));
    // A relief as large as the nose leaves no concave stretch for a 1 mm nose.
    let profile = crate::geometry::profile::Profile::from_axial(pieces, 5.0 / TAU, TAU);
    assert!(profile.concave_stretches(5.0 / TAU, 1.0).is_empty());
}

#[test]
fn a_relief_as_large_as_the_ball_is_refused() {
    let err = BallScrew::new(
        Raceway::GothicArch,
        3.175,
        0.55,
        None,
        16.0,
        15.5,
        Some(1.5875),
    )
    .unwrap_err();
    assert_eq!(
        err,
        StandardError::ReliefReachesContact {
            relief: 1.5875,
            max: 1.5875
        }
    );
    assert!(err.to_string().contains("relief radius 1.5875 mm"));
}

#[test]
fn the_circular_arc_raceway_is_the_ball_arc_touching_at_the_bottom() {
    let screw = BallScrew::new(Raceway::CircularArc, 6.35, 0.54, None, 41.0, 39.5, None).unwrap();
    let arc = BallArc::new(6.35, 0.54 * 6.35, 41.0, 39.5).unwrap();
    assert_eq!(screw.pieces(10.0).unwrap(), arc.pieces(10.0).unwrap());
    // The ball's lowest point is the groove's bottom: d_0/2 − D_w/2.
    assert!((screw.bottom_radius() - (20.5 - 3.175)).abs() < 1e-12);
    assert_eq!(screw.contact_angle(), 0.0);
    // Given 0° explicitly is the same raceway.
    assert_eq!(
        BallScrew::new(
            Raceway::CircularArc,
            6.35,
            0.54,
            Some(0.0),
            41.0,
            39.5,
            None
        ),
        Ok(screw)
    );
}

#[test]
fn every_impossible_raceway_is_refused_naming_why() {
    let g = |f: f64, beta: Option<f64>, d0: f64, d: f64| {
        BallScrew::new(Raceway::GothicArch, 3.175, f, beta, d0, d, None).unwrap_err()
    };
    assert!(matches!(
        g(0.5, None, 16.0, 15.5),
        StandardError::GrooveRadiusTooSmall { .. }
    ));
    for beta in [0.0, 90.0, -10.0, f64::NAN] {
        assert!(matches!(
            g(0.55, Some(beta), 16.0, 15.5),
            StandardError::ContactAngleOutOfRange { .. }
        ));
    }
    assert!(matches!(
        g(0.55, None, 3.0, 2.0),
        StandardError::GrooveBottomNotAboveAxis { .. }
    ));
    // The flank centres sit (r_g − D_w/2)·cos 45° above the ball's centre: an outer diameter
    // reaching them would overhang.
    assert!(matches!(
        g(0.55, None, 16.0, 16.3),
        StandardError::GrooveOverhangs { .. }
    ));
    // The 45° contact point lies D_w/2·cos 45° = 1.1226 mm below the ball's centre: a shaft
    // whose outer radius is below it has no flank there.
    assert!(matches!(
        g(0.55, None, 16.0, 13.7),
        StandardError::ContactAboveOuterDiameter { .. }
    ));
    assert!(matches!(
        g(0.55, None, f64::NAN, 15.5),
        StandardError::NotPositive {
            name: "ball-centre diameter d_0",
            ..
        }
    ));
    assert!(matches!(
        BallScrew::new(
            Raceway::CircularArc,
            6.35,
            0.54,
            Some(45.0),
            41.0,
            39.5,
            None
        ),
        Err(StandardError::NotForRaceway {
            name: "contact angle",
            ..
        })
    ));
    assert!(matches!(
        BallScrew::new(
            Raceway::CircularArc,
            6.35,
            0.54,
            None,
            41.0,
            39.5,
            Some(1.0)
        ),
        Err(StandardError::NotForRaceway {
            name: "relief radius",
            ..
        })
    ));
    // Grooves wider than the pitch leave no crest.
    let screw = gothic(None);
    assert!(matches!(
        screw.pieces(screw.groove_width()),
        Err(StandardError::GroovesOverlap { .. })
    ));
}

#[test]
fn whirl_profile_lists_the_raceways_ball_and_contact_angle() {
    let form = StandardProfile::BallScrew(gothic(Some(1.2)));
    let rows = form.dimensions(5.0).unwrap();
    let value = |name: &str| rows.iter().find(|d| d.name == name).unwrap().value;
    assert_eq!(value("ball diameter D_w"), 3.175);
    assert!((value("raceway radius r_g") - 0.55 * 3.175).abs() < 1e-12);
    assert!((value("contact angle") - 45.0).abs() < 1e-12);
    assert_eq!(value("relief radius r_r"), 1.2);
    assert!(form.source().contains("gothic-arch"));
    assert_eq!(form.outer_diameter(), 15.5);
}
