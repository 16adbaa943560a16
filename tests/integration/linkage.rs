//! The linkage against facts of the geometry: screw invariance, the left/right mirror, and
//! the contact conditions themselves, on the three-lobe groove ρ(φ) = 30 − 5·cos 3φ.

use glam::{DVec2, DVec3};
use proptest::prelude::*;
use std::f64::consts::{PI, TAU};
use whirl::geometry::linkage::{turn, Linkage, Ring, Whirling};
use whirl::geometry::profile::surface_normal;
use whirl::geometry::profile::ProfilePoint;

/// The profile point at polar angle φ, its tangent running with φ (optionally mirrored y → −y,
/// which reverses the direction of increasing polar angle).
fn lobe(phi: f64, mirror: bool) -> ProfilePoint {
    let rho = 30.0 - 5.0 * (3.0 * phi).cos();
    let drho = 15.0 * (3.0 * phi).sin();
    let pos = DVec2::from_angle(phi) * rho;
    let tangent =
        (DVec2::from_angle(phi) * drho + DVec2::from_angle(phi + PI / 2.0) * rho).normalize();
    if mirror {
        // The mirror image runs the other way round; flip the tangent to keep φ increasing.
        ProfilePoint {
            u: 0.0,
            pos: DVec2::new(pos.x, -pos.y),
            tangent: DVec2::new(-tangent.x, tangent.y),
        }
    } else {
        ProfilePoint {
            u: 0.0,
            pos,
            tangent,
        }
    }
}

fn linkage(whirling: Whirling, p: f64, delta_deg: f64) -> Linkage {
    let radius = if whirling == Whirling::Internal {
        50.0
    } else {
        45.0
    };
    Linkage {
        p,
        ring: Ring {
            whirling,
            radius,
            nose: 1.0,
            installation: delta_deg.to_radians(),
            edge_half_angle: PI / 2.0,
        },
    }
}

/// Torus of kinematics.md at (X, C, Z): signed distance of the workpiece point q, and the
/// tool's outward normal at its nearest point.
fn torus(l: &Linkage, q: DVec3, x: f64, c: f64, z: f64) -> (f64, DVec3) {
    let de = l.p.signum() * l.ring.installation;
    let a = DVec3::new(0.0, l.ring.whirling.k() * de.sin(), de.cos());
    let d = turn(q, c) - DVec3::new(x, 0.0, z);
    let along = d.dot(a);
    let radial_v = d - along * a;
    let tip = radial_v.normalize() * l.ring.radius; // nearest point of the tip circle
    let to_q = d - tip;
    (to_q.length() - l.ring.nose, turn(to_q.normalize(), -c))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// The poses (C − t, X, Z + p·t) all cut the same profile point, at θ = t: the torus touches
    /// the surface point S(u, t) there, tangent to the surface.
    #[test]
    fn screw_motion_carries_a_contact_to_the_same_profile_point(
        phi in 0.0..TAU / 3.0,
        t in -7.0..7.0f64,
        right in any::<bool>(),
        internal in any::<bool>(),
        delta in 5.0..30.0f64,
    ) {
        let p = if right { 60.0 / TAU } else { -60.0 / TAU };
        let w = if internal { Whirling::Internal } else { Whirling::External };
        let l = linkage(w, p, delta);
        let point = lobe(phi, false);
        let Ok(contact) = l.solve(&point) else { return Ok(()) };
        let pose = contact.pose;
        let s = turn(DVec3::new(point.pos.x, point.pos.y, 0.0), t) + DVec3::Z * p * t;
        let (gap, tool_normal) = torus(&l, s, pose.x, pose.c - t, pose.z + p * t);
        prop_assert!(gap.abs() < 1e-9, "gap {gap}");
        // The tool's outward normal at the contact is the surface normal turned by t, reversed
        // (the tool lies on the groove side).
        let n = turn(surface_normal(point.pos, point.tangent, p), t);
        prop_assert!((tool_normal + n).length() < 1e-6, "{tool_normal} vs {n}");
        prop_assert!((contact.phase - (pose.c - t + (pose.z + p * t) / p)).abs() < 1e-9);
    }

    /// Mirroring the workpiece (y → −y) turns a right-hand groove into a left-hand one and the
    /// machine's C into −C: the mirrored point's pose is (X, −C, Z).
    #[test]
    fn left_hand_is_the_mirror_of_right_hand(
        phi in 0.0..TAU / 3.0,
        internal in any::<bool>(),
        delta in 5.0..30.0f64,
    ) {
        let w = if internal { Whirling::Internal } else { Whirling::External };
        let p = 60.0 / TAU;
        let (Ok(right), Ok(left)) = (
            linkage(w, p, delta).solve(&lobe(phi, false)),
            linkage(w, -p, delta).solve(&lobe(phi, true)),
        ) else { return Ok(()) };
        prop_assert!((right.pose.x - left.pose.x).abs() < 1e-9);
        prop_assert!((right.pose.z - left.pose.z).abs() < 1e-9);
        let dc = (right.pose.c + left.pose.c).rem_euclid(TAU);
        prop_assert!(dc.min(TAU - dc) < 1e-9, "C {} vs {}", right.pose.c, left.pose.c);
    }
}

#[test]
fn the_lobe_is_solvable_everywhere_for_both_hands_and_both_whirlings() {
    // Guard for the property tests above: their early returns must not hide a failing solver.
    for w in [Whirling::Internal, Whirling::External] {
        for p in [60.0 / TAU, -60.0 / TAU] {
            for k in 0..=120 {
                let phi = TAU / 3.0 * k as f64 / 120.0;
                for mirror in [false, true] {
                    linkage(w, p, 20.0).solve(&lobe(phi, mirror)).unwrap();
                }
            }
        }
    }
}
