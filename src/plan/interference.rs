//! The global check of kinematics.md: no other part of the ring cuts below the target surface.
//!
//! The contact conditions only make the ring touch one point; the rest of the torus may still
//! pass through a flank, the crest of a neighbouring thread or the core. For poses spread over
//! the period this searches the whole groove surface within the ring's axial reach, every
//! start included, for points inside the tool.

use crate::geometry::linkage::{turn, Linkage};
use crate::geometry::minimise::golden;
use crate::geometry::profile::Profile;
use crate::plan::table::Table;
use glam::{DVec2, DVec3};

/// A pose of the planned path that cuts the target surface elsewhere.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error(
    "interference: cutting profile point ({at_x:.4}, {at_y:.4}), the ring also cuts {depth:.4} mm \
     below the target surface at the point ({hit_x:.4}, {hit_y:.4}, z {hit_z:.4}) of the groove \
     (a flank, a neighbouring thread or the core)"
)]
pub struct Interference {
    /// The profile point being cut.
    pub at_x: f64,
    /// See `at_x`.
    pub at_y: f64,
    /// The surface point cut into, workpiece frame.
    pub hit_x: f64,
    /// See `hit_x`.
    pub hit_y: f64,
    /// See `hit_x`.
    pub hit_z: f64,
    /// How deep, mm.
    pub depth: f64,
}

/// How many poses and surface helices to check per period.
const POSES: usize = 64;
const HELICES: usize = 120;

/// Check poses spread over the table. `tolerance` is the depth below which a touch counts as
/// the contact itself (the table's own accuracy).
pub fn check(
    profile: &Profile,
    table: &Table,
    linkage: &Linkage,
    starts: u32,
    tolerance: f64,
) -> Result<(), Interference> {
    let p = linkage.p;
    let ring = linkage.ring;
    let reach = ring.radius * ring.installation.sin() + ring.nose + 1.0;
    let step = ring.nose.min(1.0);
    let helices: Vec<DVec2> = (0..HELICES)
        .map(|k| {
            profile
                .point(profile.length() * k as f64 / HELICES as f64)
                .pos
        })
        .collect();
    let n = table.samples.len();
    for k in 0..POSES.min(n) {
        let sample = &table.samples[k * (n - 1) / POSES.min(n)];
        let pose = sample.contact.pose;
        let torus = linkage.torus(&pose);
        for start in 0..starts {
            let turn_start = table.period * f64::from(start);
            for v in &helices {
                // The helix through this profile point, seen in the machine frame at this pose:
                // θ ↦ Rz(C + θ)·B + p·θ·ẑ.
                let base = DVec2::from_angle(turn_start).rotate(*v);
                let point = |theta: f64| {
                    turn(DVec3::new(base.x, base.y, 0.0), pose.c + theta) + DVec3::Z * p * theta
                };
                let gap = |theta: f64| torus.gap(point(theta));
                let (lo, hi) = sorted((pose.z - reach) / p, (pose.z + reach) / p);
                let count = ((hi - lo) * base.length().max(p.abs()) / step)
                    .ceil()
                    .max(2.0);
                // The scan steps the point along the helix by a fixed rotation (no trig per
                // sample); refinement evaluates `gap` exactly.
                let dtheta = (hi - lo) / count;
                let (sin, cos) = dtheta.sin_cos();
                let start = point(lo);
                let mut xy = DVec2::new(start.x, start.y);
                let mut z = start.z;
                let scan = std::iter::from_fn(|| {
                    let g = torus.gap(DVec3::new(xy.x, xy.y, z));
                    xy = DVec2::new(cos * xy.x - sin * xy.y, sin * xy.x + cos * xy.y);
                    z += p * dtheta;
                    Some(g)
                });
                if let Some((theta, depth)) = deepest(gap, scan, lo, hi, count as usize, step) {
                    if depth > tolerance {
                        let hit = turn(point(theta), -pose.c); // back to the workpiece frame
                        return Err(Interference {
                            at_x: sample.pos.x,
                            at_y: sample.pos.y,
                            hit_x: hit.x,
                            hit_y: hit.y,
                            hit_z: hit.z,
                            depth,
                        });
                    }
                }
            }
        }
    }
    Ok(())
}

fn sorted(a: f64, b: f64) -> (f64, f64) {
    if a <= b {
        (a, b)
    } else {
        (b, a)
    }
}

/// The deepest point (most negative gap) along `[lo, hi]`: a scan at `step`, refined by golden
/// section around every scan minimum that comes near the tool.
///
/// `scan` yields the gap at the `count + 1` evenly spaced scan points, `gap` evaluates it
/// anywhere; a minimum counts when it is within `near` of the tool.
fn deepest(
    gap: impl Fn(f64) -> f64,
    mut scan: impl Iterator<Item = f64>,
    lo: f64,
    hi: f64,
    count: usize,
    near: f64,
) -> Option<(f64, f64)> {
    let at = |i: usize| lo + (hi - lo) * i as f64 / count as f64;
    let mut next = || scan.next().unwrap_or(f64::INFINITY);
    let mut worst: Option<(f64, f64)> = None;
    let mut window = [next(), next(), 0.0];
    for i in 1..count {
        window[2] = next();
        let [before, here, after] = window;
        if here <= near && here <= before && here <= after {
            let refined = golden(&gap, at(i - 1), at(i + 1), 50);
            let (t, g) = if refined.1 < here {
                refined
            } else {
                (at(i), here)
            };
            if g < 0.0 && worst.is_none_or(|w| -g > w.1) {
                worst = Some((t, -g));
            }
        }
        window = [here, after, 0.0];
    }
    worst
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::linkage::{Ring, Whirling};
    use crate::geometry::profile::testing::lobe;
    use std::f64::consts::{PI, TAU};

    fn setup(radius: f64, delta_deg: f64, lead: f64) -> (Profile, Table, Linkage) {
        let profile = lobe(lead);
        let linkage = Linkage {
            p: lead / TAU,
            ring: Ring {
                whirling: Whirling::Internal,
                radius,
                nose: 1.0,
                installation: delta_deg.to_radians(),
                edge_half_angle: PI / 2.0,
            },
        };
        let table = Table::build(&profile, &linkage, 1e-4).expect("the contact itself is fine");
        (profile, table, linkage)
    }

    #[test]
    fn a_ring_whose_far_side_passes_through_the_crest_is_caught() {
        // Tilted 45°, a 40 mm ring passes within R·cos δ = 28.3 mm of the axis on the side
        // away from the contact: through the 35 mm crest of the neighbouring lobes.
        let (profile, table, linkage) = setup(40.0, 45.0, 200.0);
        let e = check(&profile, &table, &linkage, 3, 1e-3).unwrap_err();
        assert!(e.depth > 0.1, "{e}");
        let hit_radius = e.hit_x.hypot(e.hit_y);
        assert!(
            (25.0..=35.0 + 1e-6).contains(&hit_radius),
            "a point of the groove: {e}"
        );
    }

    #[test]
    fn a_ring_that_clears_the_work_passes() {
        // The reference case of linkage-vectors.csv: R·cos δ − r = 46.0 mm clears the 35 mm
        // crest all round.
        let (profile, table, linkage) = setup(50.0, 20.0, 60.0);
        check(&profile, &table, &linkage, 3, 1e-3).unwrap();
    }
}
