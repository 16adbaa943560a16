//! ZK against its definition: the flank is the furthest the wheel's cone reaches into the
//! axial section as the worm screws past it, and a wheel of unbounded diameter is a plane,
//! whose envelope is the involute helicoid (ZI) of the same normal pressure angle.

use super::super::tests::distance_to_chain;
use super::super::{Worm, WormFlank, FLANK_TOLERANCE};
use glam::{DVec2, DVec3};
use std::f64::consts::{FRAC_PI_4, PI};

/// m = 2, z1 = 1, q = 10, α0 = 20°, a wheel of diameter `wheel_diameter`.
fn zk(wheel_diameter: f64) -> Worm {
    Worm::new(
        WormFlank::ZK { wheel_diameter },
        2.0,
        1,
        10.0,
        None,
        None,
        None,
    )
    .unwrap()
}

/// The wheel's left cone as the module documentation defines it, written out here: the point
/// at wheel radius `big_r` and angle `theta` from the direction towards the worm's axis.
fn cone(worm: &Worm, big_r: f64, theta: f64) -> DVec3 {
    let wheel = worm.wheel().unwrap();
    let (r0, w0) = (0.5 * wheel.diameter(), 0.5 * wheel.thickness());
    let a0 = 0.5 * worm.reference_diameter() + r0;
    let gamma = worm.lead_angle();
    let e1 = DVec3::new(-1.0, 0.0, 0.0);
    let e2 = DVec3::new(0.0, gamma.cos(), gamma.sin());
    let u = DVec3::new(0.0, -gamma.sin(), gamma.cos());
    let w = w0 - (big_r - r0) * worm.pressure_angle().tan();
    DVec3::new(a0, 0.0, 0.0) + big_r * (theta.cos() * e1 + theta.sin() * e2) - w * u
}

/// How far along the axis (towards −z) the wheel reaches at radius `rho` of the axial
/// section: over the cone's angles, each point at that radius carried along the helix into
/// the half-plane y = 0, the least z. The wheel ends a little past the radius that cuts the
/// root, `a0 − r_f`: angles whose point at `rho` would lie beyond that are not the wheel's
/// (a cone without end would reach the axial section from far round the worm). By
/// bisection on the wheel radius, a scan of the angle and a golden-section search about its
/// best: no envelope condition.
fn reach(worm: &Worm, rho: f64) -> f64 {
    let p = 0.5 * worm.lead() / PI;
    let a0 = 0.5 * worm.reference_diameter() + 0.5 * worm.wheel().unwrap().diameter();
    let tip = a0 - 0.5 * worm.root_diameter() + worm.module();
    let at_radius = |theta: f64| {
        let (mut lo, mut hi) = (tip - 20.0, tip);
        let radius = |big_r: f64| {
            let q = cone(worm, big_r, theta);
            q.x.hypot(q.y)
        };
        if radius(hi) > rho {
            return f64::INFINITY;
        }
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if radius(mid) > rho {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let q = cone(worm, 0.5 * (lo + hi), theta);
        q.z - p * q.y.atan2(q.x)
    };
    const SCAN: i32 = 2000;
    let step = 0.6 / f64::from(SCAN);
    let best = (-SCAN / 2..=SCAN / 2)
        .map(|k| f64::from(k) * step)
        .min_by(|a, b| at_radius(*a).total_cmp(&at_radius(*b)))
        .unwrap();
    let (mut a, mut b) = (best - step, best + step);
    let g = 0.5 * (5f64.sqrt() - 1.0);
    for _ in 0..100 {
        let (c, d) = (b - g * (b - a), a + g * (b - a));
        if at_radius(c) < at_radius(d) {
            b = d;
        } else {
            a = c;
        }
    }
    at_radius(0.5 * (a + b))
}

#[test]
fn the_zk_flank_is_the_furthest_reach_of_the_wheels_cone() {
    let w = zk(250.0);
    let pieces = w.pieces(w.axial_pitch()).unwrap();
    let (rf, ra) = (0.5 * w.root_diameter(), 0.5 * w.tip_diameter());
    for k in 0..=20 {
        let rho = rf + (ra - rf) * f64::from(k) / 20.0;
        let by_reach = reach(&w, rho);
        let flank = w.wheel().unwrap().flank_z(rho).unwrap();
        assert!(
            (flank - by_reach).abs() < 1e-8,
            "ρ {rho}: {flank} vs {by_reach}"
        );
        // Above the root fillet (0.4 mm, tangent to the flank well within m/2 of the root)
        // the arcs standing for the flank are within their tolerance of it.
        if rho >= rf + 0.5 * w.module() {
            let off = distance_to_chain(&pieces, DVec2::new(rho, by_reach));
            assert!(off <= FLANK_TOLERANCE + 1e-8, "ρ {rho}: {off}");
        }
    }
}

#[test]
fn a_zk_wheel_is_dressed_to_leave_half_the_axial_pitch_on_the_reference_cylinder() {
    for d0 in [60.0, 250.0, 600.0] {
        let w = zk(d0);
        let z = w
            .wheel()
            .unwrap()
            .flank_z(0.5 * w.reference_diameter())
            .unwrap();
        assert!((z + FRAC_PI_4 * w.module()).abs() < 1e-10, "d0 {d0}: {z}");
    }
}

#[test]
fn a_zk_wheel_without_bound_cuts_the_involute_helicoid_of_its_profile_angle() {
    let zi = Worm::new(WormFlank::ZI, 2.0, 1, 10.0, None, None, None).unwrap();
    let (rf, ra) = (0.5 * zi.root_diameter(), 0.5 * zi.tip_diameter());
    let worst = |d0: f64| {
        let w = zk(d0);
        (0..=20)
            .map(|k| {
                let rho = rf + (ra - rf) * f64::from(k) / 20.0;
                (w.flank_z(rho) - zi.flank_z(rho)).abs()
            })
            .fold(0.0, f64::max)
    };
    // The wheel's cone departs from its tangent plane by about (contact length)²/d0 over the
    // contact: a hundred times the diameter, a hundredth of the difference.
    let (near, far) = (worst(1e4), worst(1e6));
    assert!(
        far < 1e-6 && (50.0..200.0).contains(&(near / far)),
        "{near} {far}"
    );
}
