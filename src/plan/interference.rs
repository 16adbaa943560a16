//! The global check of kinematics.md: no other part of the ring cuts below the target surface.
//!
//! The contact conditions only make the ring touch one point; the rest of the torus may still
//! pass through a flank, the crest of a neighbouring thread or the core. For poses spread over
//! the period this searches the whole groove surface within the ring's axial reach, every
//! start included, for points inside the tool.

use crate::geometry::linkage::{turn, Linkage, Torus};
use crate::geometry::minimise::golden;
use crate::geometry::profile::Profile;
use crate::plan::table::Table;
use glam::{DVec2, DVec3};
use std::f64::consts::TAU;

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

/// Golden-section steps refining a scan minimum: they shrink its bracket of two scan steps
/// (under 3 mm of the helix) by 0.618³⁰, to under 2 nm, where the gap, flat at its minimum,
/// is off by less than 10⁻¹⁰ mm.
const REFINE_STEPS: usize = 30;

/// Points skipped at once above which the scan lands on the next by the helix's formula (a
/// sine and a cosine) rather than stepping to it.
const JUMP: usize = 8;

/// What the gaps computed here may be off by, mm: their rounding and the scan's rotation
/// accumulated over a helix, with room to spare. The bounds that let the scan pass over points
/// and minima are taken this much on the safe side.
const SLACK: f64 = 1e-9;

/// Check poses spread over the table. `tolerance` is the depth below which a touch counts as
/// the contact itself (the table's own accuracy).
///
/// At each pose, every helix of the groove surface through one of the profile points spread
/// along it, every start's, is scanned over the ring's axial reach for where it comes within
/// a scan step (1 mm, or r if smaller) of the tool, and each minimum of the scan that comes
/// near is refined to the deepest point around it. The first pose and helix (in that order)
/// whose deepest point lies more than `tolerance` inside the tool is refused.
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
    let scan = Scan {
        span: 2.0 * reach / p.abs(),
        step: ring.nose.min(1.0),
        tolerance,
        nose: ring.nose,
        radius: ring.radius,
    };
    let scan = &scan;
    let helices: Vec<Helix> = (0..starts)
        .flat_map(|start| {
            let turn_start = DVec2::from_angle(table.period * f64::from(start));
            (0..HELICES).map(move |k| {
                let v = profile
                    .point(profile.length() * k as f64 / HELICES as f64)
                    .pos;
                Helix::new(turn_start.rotate(v), p, scan)
            })
        })
        .collect();
    let mut stretches = Vec::new();
    let n = table.samples.len();
    for k in 0..POSES.min(n) {
        let sample = &table.samples[k * (n - 1) / POSES.min(n)];
        let pose = sample.contact.pose;
        let at = AtPose::new(linkage.torus(&pose), pose.c, p, reach);
        for helix in &helices {
            let Some((theta, depth)) = helix.deepest(&at, &mut stretches) else {
                continue;
            };
            if depth > tolerance {
                let hit = turn(helix.point(pose.c, theta), -pose.c); // back to the workpiece frame
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
    Ok(())
}

/// The ring at one pose as the scans see it: its torus, the work's turn c, where the scans
/// start (θ, of the ring's axial reach `reach` about its centre's Z), and the least and
/// greatest distance of the tip circle from the work's axis ([`radial_span`]).
struct AtPose {
    torus: Torus,
    c: f64,
    lo: f64,
    reach: f64,
    closest: f64,
    farthest: f64,
}

impl AtPose {
    fn new(torus: Torus, c: f64, p: f64, reach: f64) -> AtPose {
        let z = torus.centre.z;
        let (closest, farthest) = radial_span(&torus);
        AtPose {
            torus,
            c,
            lo: ((z - reach) / p).min((z + reach) / p),
            reach,
            closest,
            farthest,
        }
    }
}

/// The least and greatest distance of a point of `torus`'s tip circle from the work's axis.
///
/// The circle is O + R·(cos t·x̂ + sin t·(a × x̂)) (its axis a has no x part), so a point's
/// squared distance from the axis is X² + R²·a_z² + 2XR·cos t + R²·a_y²·cos² t, a convex
/// quadratic in cos t: largest at cos t = ±1, (|X| + R)², and least at its vertex
/// cos t = −X/(R·a_y²) when that lies within ±1, else at cos t = ±1, (|X| − R)².
fn radial_span(torus: &Torus) -> (f64, f64) {
    let (x, r) = (torus.centre.x, torus.radius);
    let (ay, az) = (torus.axis.y, torus.axis.z);
    let vertex = -x / (r * ay * ay);
    let least = if vertex.abs() <= 1.0 {
        (x * x + r * r * az * az - x * x / (ay * ay))
            .max(0.0)
            .sqrt()
    } else {
        (x.abs() - r).abs()
    };
    (least, x.abs() + r)
}

/// What every helix's scan shares: its length in θ, its step along the helix (mm), the depth
/// that counts, and the ring's nose and radius (mm).
struct Scan {
    span: f64,
    step: f64,
    tolerance: f64,
    nose: f64,
    radius: f64,
}

/// The helix of the groove through the profile point `base` (workpiece frame, θ = 0), seen in
/// the machine frame at a pose that turns the work by c: θ ↦ Rz(c + θ)·base + p·θ·ẑ; and the
/// figures of its scan, which are the same at every pose.
struct Helix {
    base: DVec2,
    p: f64,
    /// |base|, mm: the helix's distance from the axis.
    radius: f64,
    /// The azimuth of `base`.
    azimuth: f64,
    /// Scan steps over [`Scan::span`], each `dtheta` and `arc` mm of the helix.
    count: usize,
    dtheta: f64,
    arc: f64,
    /// The rotation of one step.
    sin: f64,
    cos: f64,
    /// A point of the scan counts where its gap is at most this, mm.
    near: f64,
    /// How far from the tip circle a point that counts can lie, mm: r + `near`, and the slack.
    reach_d: f64,
}

impl Helix {
    fn new(base: DVec2, p: f64, scan: &Scan) -> Helix {
        let radius = base.length();
        let count = (scan.span * radius.max(p.abs()) / scan.step)
            .ceil()
            .max(2.0) as usize;
        let dtheta = scan.span / count as f64;
        let arc = radius.hypot(p) * dtheta;
        let (sin, cos) = dtheta.sin_cos();
        let mut helix = Helix {
            base,
            p,
            radius,
            azimuth: base.to_angle(),
            count,
            dtheta,
            arc,
            sin,
            cos,
            near: scan.step,
            reach_d: 0.0,
        };
        helix.near = scan.step.min(helix.may_hide_depth_below(scan));
        helix.reach_d = scan.nose + helix.near + SLACK;
        helix
    }

    fn point(&self, c: f64, theta: f64) -> DVec3 {
        turn(DVec3::new(self.base.x, self.base.y, 0.0), c + theta) + DVec3::Z * self.p * theta
    }

    /// The deepest point of the helix inside the ring at `pose`, over the scan of the ring's
    /// axial reach: its θ and depth (mm, positive inside), if it finds a point inside the tool.
    /// `stretches` is room for [`Helix::near_stretches`].
    ///
    /// A scan at the helix's step finds the minima of the gap, and golden-section search
    /// refines each that comes near the tool (within [`Helix::near`]) within its two
    /// neighbours. Three bounds spare work without changing what is found, for only points of
    /// the scan within `near` can be such minima:
    ///
    /// - **Where the helix can come near.** [`Helix::near_stretches`]: the scan runs over
    ///   those alone.
    /// - **Points far from the tool.** The gap is a distance (to the tip circle, less r), so
    ///   it changes by at most the arc between two points; from a point whose gap exceeds
    ///   `near` by g, the next g of arc lies above it too and is not evaluated.
    /// - **Minima that cannot go deep.** [`Helix::may_hide_depth_below`] sets `near`: a
    ///   minimum of the scan above it holds no point deeper than the tolerance, and only
    ///   those decide the outcome.
    fn deepest(&self, pose: &AtPose, stretches: &mut Vec<(usize, usize)>) -> Option<(f64, f64)> {
        let (torus, c) = (&pose.torus, pose.c);
        let at = |i: usize| pose.lo + self.dtheta * i as f64;
        let mut worst: Option<(f64, f64)> = None;
        // Point i, between the ends, where the scan has a minimum that comes near the tool:
        // refined within its neighbours.
        let mut consider = |i: usize, before: f64, here: f64, after: f64| {
            if (1..self.count).contains(&i) && here <= self.near && here <= before && here <= after
            {
                let gap = |theta: f64| torus.gap(self.point(c, theta));
                let refined = golden(gap, at(i - 1), at(i + 1), REFINE_STEPS);
                let (t, g) = if refined.1 < here {
                    refined
                } else {
                    (at(i), here)
                };
                if g < 0.0 && worst.is_none_or(|w| -g > w.1) {
                    worst = Some((t, -g));
                }
            }
        };
        // Consecutive points are stepped along the helix by a fixed rotation (no trig per
        // point); the scan jumps over points known to lie above `near`, which count as +∞,
        // and lands by the helix's formula.
        self.near_stretches(pose, stretches);
        for &(first, last) in stretches.iter() {
            let mut point = self.point(c, at(first));
            let (mut before, mut here) = (f64::INFINITY, f64::INFINITY);
            let mut i = first;
            while i <= last {
                let g = torus.gap(point);
                if i > 0 {
                    consider(i - 1, before, here, g);
                }
                // The next `skip` points lie within `skip`·arc of this one, so above `near`
                // (the cast rounds down, and takes what is not above zero to zero).
                let skip = (((g - self.near - SLACK) / self.arc) as usize).min(self.count);
                (before, here) = if skip == 0 {
                    (here, g)
                } else {
                    (f64::INFINITY, f64::INFINITY)
                };
                i += skip + 1;
                if skip >= JUMP {
                    point = self.point(c, at(i));
                } else {
                    for _ in 0..=skip {
                        point = DVec3::new(
                            self.cos * point.x - self.sin * point.y,
                            self.sin * point.x + self.cos * point.y,
                            point.z + self.p * self.dtheta,
                        );
                    }
                }
            }
            // The point after the stretch lies above `near`.
            consider(last, before, here, f64::INFINITY);
        }
        worst
    }

    /// The stretches of the scan at `pose` (first and last index, merged, in order) outside
    /// which no point of the helix comes within [`Helix::reach_d`] of the tip circle, into
    /// `stretches`.
    ///
    /// Every point of the helix lies |base| = ρ_B from the axis, and every point of the circle
    /// between [`AtPose::closest`] and [`AtPose::farthest`] from it: where these are further
    /// apart than D, nothing comes within D. Otherwise: a point within D of the circle lies
    /// within D of the ring's plane (|h| ≤ D) and at a distance ρ from the ring's axis within
    /// D of R. The helix's point at azimuth ψ lies |q − O|² = ρ_B² + X² − 2Xρ_B·cos ψ +
    /// (z − Z)² from the ring's centre (X, 0, Z), and ρ² = |q − O|² − h²; so R − D ≤ ρ ≤ R + D
    /// needs (R − D)² − ρ_B² − X² − reach² ≤ −2Xρ_B·cos ψ ≤ (R + D)² + D² − ρ_B² − X²: a band
    /// of cos ψ, one or two arcs of ψ, which the helix passes once a turn. Each stretch is
    /// widened to whole scan steps.
    fn near_stretches(&self, pose: &AtPose, stretches: &mut Vec<(usize, usize)>) {
        stretches.clear();
        let (r, x, d, rho) = (
            pose.torus.radius,
            pose.torus.centre.x,
            self.reach_d,
            self.radius,
        );
        if (pose.closest - rho).max(rho - pose.farthest) > d {
            return;
        }
        let least = if r > d {
            (r - d).powi(2) - rho * rho - x * x - pose.reach * pose.reach
        } else {
            f64::NEG_INFINITY
        };
        let most = (r + d).powi(2) + d * d - rho * rho - x * x;
        let s = -2.0 * x * rho;
        if s.abs() < SLACK {
            if least <= 0.0 && 0.0 <= most {
                stretches.push((0, self.count));
            }
            return;
        }
        let (a, b) = (least / s, most / s);
        let (cos_lo, cos_hi) = (a.min(b).max(-1.0), a.max(b).min(1.0));
        if cos_lo > cos_hi {
            return;
        }
        if cos_lo <= -1.0 && cos_hi >= 1.0 {
            stretches.push((0, self.count));
            return;
        }
        // cos ψ in [cos_lo, cos_hi]: ψ in [α, β] or in [−β, −α] (mod 2π), ψ = c + θ + the
        // azimuth of base.
        let (alpha, beta) = (cos_hi.acos(), cos_lo.acos());
        let (lo, offset) = (pose.lo, pose.c + self.azimuth);
        let hi = lo + self.dtheta * self.count as f64;
        let mut add = |psi_a: f64, psi_b: f64| {
            let (ta, tb) = (psi_a - offset, psi_b - offset);
            let k_first = ((lo - tb) / TAU).ceil() as i64;
            let k_last = ((hi - ta) / TAU).floor() as i64;
            for k in k_first..=k_last {
                let shift = TAU * k as f64;
                let first = ((ta + shift - lo) / self.dtheta).floor().max(0.0) as usize;
                let last =
                    (((tb + shift - lo) / self.dtheta).ceil().max(0.0) as usize).min(self.count);
                if first <= last {
                    stretches.push((first, last));
                }
            }
        };
        add(alpha, beta);
        add(-beta, -alpha);
        stretches.sort_unstable();
        let mut merged = 0;
        for k in 1..stretches.len() {
            let (first, last) = stretches[k];
            if first <= stretches[merged].1 + 1 {
                stretches[merged].1 = stretches[merged].1.max(last);
            } else {
                merged += 1;
                stretches[merged] = (first, last);
            }
        }
        stretches.truncate(merged + 1);
    }

    /// The scan gap below which a minimum may hide a point deeper than the tolerance between
    /// its neighbours (see [`Helix::deepest`]); the scan step where the bound does not apply.
    ///
    /// Along the helix (arc length u, curvature κ = |base|/(|base|² + p²)) the squared distance
    /// D to the tip circle has D'' = u'ᵀ·∇²D·u' + ∇D·u'', where ∇D has length 2f (f the
    /// distance) and ∇²D the eigenvalues 2, 2 and 2(1 − R/ρ), ρ the distance from the ring's
    /// axis: so |D''| ≤ M = 2 + 2·f·κ wherever ρ ≥ R/2, which f ≤ R/2 ensures. Between a
    /// minimum's neighbours, an arc s away, f stays below r + step + s (the gap changes by at
    /// most the arc), and D above D_min − M·s²/8: a point there lies deeper than the
    /// tolerance t only if f_min < √((r − t)² + M·s²/8).
    fn may_hide_depth_below(&self, scan: &Scan) -> f64 {
        let (r, t, s) = (scan.nose, scan.tolerance, self.arc);
        let f_max = r + scan.step + s;
        if t >= r || f_max > scan.radius / 2.0 {
            return scan.step;
        }
        let kappa = self.radius / (self.radius * self.radius + self.p * self.p);
        let m = 2.0 + 2.0 * f_max * kappa;
        ((r - t).powi(2) + m * s * s / 8.0).sqrt() - r + SLACK
    }
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
        // The point named lies that deep inside the ring at the pose that cuts the point
        // named, as the linkage measures it.
        let pose = table
            .samples
            .iter()
            .find(|s| (s.pos.x, s.pos.y) == (e.at_x, e.at_y))
            .expect("a pose of the table")
            .contact
            .pose;
        let gap = linkage.gap(DVec3::new(e.hit_x, e.hit_y, e.hit_z), &pose);
        assert!((gap + e.depth).abs() < 1e-9, "{gap} {e}");
    }

    #[test]
    fn a_ring_that_clears_the_work_passes() {
        // The reference case of linkage-vectors.csv: R·cos δ − r = 46.0 mm clears the 35 mm
        // crest all round.
        let (profile, table, linkage) = setup(50.0, 20.0, 60.0);
        check(&profile, &table, &linkage, 3, 1e-3).unwrap();
    }

    #[test]
    fn a_helix_through_the_nose_is_found_as_deep_as_it_passes() {
        // An untilted ring (axis ẑ) with its centre at (X, 0, Z): a helix of radius ρ comes
        // nearest its tip circle where its point lies on the line through the ring's centre
        // and the axis, on the far side of the axis from the centre (ψ = π for X > 0, 0 for
        // X < 0), at |X| + ρ from the centre, and in the ring's plane (θ = Z/p). With
        // ρ = R − |X| − r + d it passes d inside the tube of radius r there, and nowhere
        // deeper: everywhere else it is further from the circle.
        let (radius, nose) = (40.0, 1.6);
        for (x, p, d) in [
            (21.0, 10.0 / TAU, 0.003),
            (21.0, 10.0 / TAU, 0.4),
            (5.0, -60.0 / TAU, 0.01),
            (-12.0, 30.0 / TAU, 0.0007),
        ] {
            let z = 1.3;
            let reach = nose + 1.0;
            let scan = Scan {
                span: 2.0 * reach / f64::abs(p),
                step: nose.min(1.0),
                tolerance: 5e-4,
                nose,
                radius,
            };
            let torus = Torus {
                centre: DVec3::new(x, 0.0, z),
                axis: DVec3::Z,
                radius,
                nose,
            };
            let theta = z / p;
            let psi: f64 = if x > 0.0 { PI } else { 0.0 };
            for (depth, found) in [(d, true), (-0.01, false)] {
                let rho = radius - f64::abs(x) - nose + depth;
                let helix = Helix::new(DVec2::new(rho, 0.0), p, &scan);
                let pose = AtPose::new(torus, psi - theta, p, reach);
                let deepest = helix.deepest(&pose, &mut Vec::new());
                if found {
                    let (at, got) = deepest.expect("the helix passes inside the tube");
                    assert!((got - depth).abs() < 1e-9, "{x} {p} {depth}: {got}");
                    assert!(
                        (at - theta).abs() < 1e-4,
                        "{x} {p} {depth}: at {at}, not {theta}"
                    );
                } else {
                    assert_eq!(deepest, None, "{x} {p}: 0.01 mm outside the tube");
                }
            }
        }
    }

    #[test]
    fn the_tip_circle_lies_between_the_radii_found() {
        // The radii of the circle's points, sampled every 0.1°, lie between the least and
        // greatest found, and reach them to within the sampling.
        for (x, delta_deg) in [
            (21.0, 4.4),
            (0.0, 30.0),
            (-12.0, 0.0),
            (95.0, 20.0),
            (3.0, 80.0),
        ] {
            let axis = DVec3::new(
                0.0,
                f64::to_radians(delta_deg).sin(),
                f64::to_radians(delta_deg).cos(),
            );
            let torus = Torus {
                centre: DVec3::new(x, 0.0, 2.0),
                axis,
                radius: 40.0,
                nose: 1.0,
            };
            let (least, most) = radial_span(&torus);
            let e2 = axis.cross(DVec3::X);
            let radii: Vec<f64> = (0..3600)
                .map(|k| {
                    let t = TAU * f64::from(k) / 3600.0;
                    let q = torus.centre + 40.0 * (t.cos() * DVec3::X + t.sin() * e2);
                    q.x.hypot(q.y)
                })
                .collect();
            let (lo, hi) = radii.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), r| {
                (lo.min(*r), hi.max(*r))
            });
            assert!(least <= lo + 1e-9 && hi <= most + 1e-9, "{x} {delta_deg}");
            assert!(
                lo - least < 0.01 && most - hi < 0.01,
                "{x} {delta_deg}: {least} {lo}"
            );
        }
    }
}
