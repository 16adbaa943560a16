//! The envelope of a smooth motion by the grazing condition N · V = 0: a second, independent
//! way to seed 000's section.
//!
//! Seeds 001 (Hendriko, Eq. 5) and 004 (Bedi & Mann, §3) build the swept envelope from the
//! points of the moving tool surface whose normal N is perpendicular to their velocity V:
//! points with N · V > 0 are pushing into the material, points with N · V < 0 are leaving
//! space already cut, and only the grazing points leave their imprint. For a tool of
//! revolution translated along seed 000's [`Helix`] (axis parallel to y, no rotation, so
//! V(φ) = (−R sin φ, −p/2π, R cos φ) for every point), a surface point is given by a meridian
//! point (ρ, h) with outward meridian normal (n_ρ, n_h) and an angle θ about the tool axis:
//!
//! ```text
//! P = C(φ) + (ρ cos θ, h, ρ sin θ),   N = (n_ρ cos θ, n_h, n_ρ sin θ),
//! N · V = R n_ρ sin(θ − φ) − n_h p/(2π) = 0   ⇒   sin δ = n_h p / (2π R n_ρ),  δ = θ − φ,
//! ```
//!
//! two offsets δ per meridian point (asin q and π − asin q), none where |q| > 1 (near the tip
//! of seed 000's cap, where the surface is too flat to graze the axial part of the motion).
//! The envelope point lies in the observer plane z = 0 when
//! R sin φ + ρ sin(φ + δ) = 0, i.e. φ = atan2(−ρ sin δ, R + ρ cos δ) + kπ: everything in closed
//! form per meridian point, no search in φ, no maximum — which is why it checks
//! [`section`](super::section) independently.
//!
//! What it does not cover: grazing gives the envelope of the smooth surface only. The rim where
//! seed 000's cap meets its centre plane is an edge; the part of the section it generates
//! (seed 000's Eq. 12, next to both ends of the groove) is the trace of that swept curve, not a
//! grazing envelope, and needs the rim sweep (the reach edge in [`section`](super::section)).
//! The grazing points of the cap are exactly the Eq. 10 part: the rim's grazing points are the
//! two switch points where Eq. 10 hands over to Eq. 12. Grazing is also only a necessary
//! condition: for a general tool a grazing point may be cut away by another instant, so it is
//! a candidate for the boundary, which the section's maximum decides.

use super::helix::Helix;
use super::tool::Paraboloid;
use glam::{DVec2, DVec3};
use std::f64::consts::{PI, TAU};

/// A tool's meridian boundary curve, t ↦ (ρ, h), with its outward unit normal in the meridian
/// plane. Outward means away from the solid: for seed 000's cap, up and away from the axis.
pub trait MeridianCurve {
    /// The parameter interval.
    fn domain(&self) -> (f64, f64);
    /// The meridian point (ρ, h) at t.
    fn point(&self, t: f64) -> DVec2;
    /// The outward unit normal (n_ρ, n_h) at t.
    fn normal(&self, t: f64) -> DVec2;
}

/// Seed 000's cap h = aρ² + b (a < 0 < b), parametrised by ρ ∈ [0, √(−b/a)] from the tip to the
/// rim.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParaboloidCap {
    /// a, 1/mm (negative).
    pub a: f64,
    /// b, mm (positive).
    pub b: f64,
}

impl From<Paraboloid> for ParaboloidCap {
    fn from(p: Paraboloid) -> Self {
        ParaboloidCap { a: p.a, b: p.b }
    }
}

impl MeridianCurve for ParaboloidCap {
    fn domain(&self) -> (f64, f64) {
        (0.0, (-self.b / self.a).sqrt())
    }

    fn point(&self, t: f64) -> DVec2 {
        DVec2::new(t, self.a * t * t + self.b)
    }

    fn normal(&self, t: f64) -> DVec2 {
        // The gradient of h − aρ² − b, which grows out of the solid (h ≤ aρ² + b).
        DVec2::new(-2.0 * self.a * t, 1.0).normalize()
    }
}

/// A grazing point of the moving tool surface that lies in the observer plane z = 0.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GrazingPoint {
    /// The meridian parameter.
    pub t: f64,
    /// The tool rotation angle φ at which the point is in the plane, rad.
    pub phi: f64,
    /// The angle θ of the surface point about the tool axis (from +x towards +z), rad.
    pub theta: f64,
    /// The surface point in space at φ (its z is 0 to rounding).
    pub position: DVec3,
    /// The outward unit surface normal there.
    pub normal: DVec3,
    /// The point in the observer plane, (x, y).
    pub section: DVec2,
}

/// The offsets δ = θ − φ at which a meridian point with outward normal `n` = (n_ρ, n_h) grazes:
/// R n_ρ sin δ = n_h p/(2π). None, one (|q| = 1) or two. A face perpendicular to the axis
/// (n_ρ = 0) grazes nowhere unless p = 0, when it grazes everywhere; neither gives envelope
/// points, so both return none.
pub fn grazing_offsets(n: DVec2, helix: &Helix) -> Vec<f64> {
    let lhs = helix.radius * n.x;
    let rhs = n.y * helix.pitch / TAU;
    if lhs == 0.0 {
        return Vec::new();
    }
    let q = rhs / lhs;
    if q.is_nan() || q.abs() > 1.0 {
        return Vec::new();
    }
    let d = q.asin();
    if q.abs() == 1.0 {
        vec![d]
    } else {
        vec![d, PI - d]
    }
}

/// All grazing points at meridian parameter `t` that lie in the observer plane for some φ in
/// the helix's range (none for an invalid helix, see [`Helix::validate`]).
pub fn plane_points(curve: &dyn MeridianCurve, helix: &Helix, t: f64) -> Vec<GrazingPoint> {
    if helix.validate().is_err() {
        return Vec::new();
    }
    let (m, n) = (curve.point(t), curve.normal(t));
    let (rho, h) = (m.x, m.y);
    let mut out = Vec::new();
    for delta in grazing_offsets(n, helix) {
        let (sd, cd) = delta.sin_cos();
        let (u, v) = (-rho * sd, helix.radius + rho * cd);
        if u == 0.0 && v == 0.0 {
            // ρ = R, δ = π: the point sits on the screw axis at every φ.
            continue;
        }
        let base = u.atan2(v);
        let k0 = ((helix.phi_start - base) / PI).ceil() as i64;
        let k1 = ((helix.phi_end - base) / PI).floor() as i64;
        for k in k0..=k1 {
            let phi = base + PI * k as f64;
            let theta = phi + delta;
            let (st, ct) = theta.sin_cos();
            let position = helix.position(phi) + DVec3::new(rho * ct, h, rho * st);
            let normal = DVec3::new(n.x * ct, n.y, n.x * st);
            out.push(GrazingPoint {
                t,
                phi,
                theta,
                position,
                normal,
                section: DVec2::new(position.x, position.y),
            });
        }
    }
    out
}

/// The grazing points of the groove around x = −R (the tool centre on the x < 0 side,
/// cos φ < 0), from `samples` + 1 equally spaced meridian parameters, ordered by x. Samples
/// where the surface cannot graze are skipped, so the points cover the envelope part of the
/// section only (see the module docs).
pub fn section_points(
    curve: &dyn MeridianCurve,
    helix: &Helix,
    samples: usize,
) -> Vec<GrazingPoint> {
    let (t0, t1) = curve.domain();
    let n = samples.max(1);
    let mut out: Vec<GrazingPoint> = (0..=n)
        .flat_map(|i| {
            let t = if i == n {
                t1
            } else {
                t0 + (t1 - t0) * i as f64 / n as f64
            };
            plane_points(curve, helix, t)
        })
        .filter(|g| g.phi.cos() < 0.0 && g.section.is_finite())
        .collect();
    out.sort_by(|a, b| a.section.x.total_cmp(&b.section.x));
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::papers::section::seed000::{Case, TABLE_1};
    use crate::papers::section::{top_at, upper_boundary};

    fn cap() -> ParaboloidCap {
        ParaboloidCap {
            a: TABLE_1.a,
            b: TABLE_1.b,
        }
    }

    fn helix(c: &Case) -> Helix {
        Helix::one_turn(c.r, c.p)
    }

    #[test]
    fn the_cap_normal_is_outward_and_normal_to_the_meridian() {
        let cap = cap();
        for t in [0.0, 1.0, 5.0, 11.0] {
            let n = cap.normal(t);
            let d = 1e-6;
            let tangent = cap.point(t + d) - cap.point(t - d);
            assert!(n.dot(tangent).abs() < 1e-9 && (n.length() - 1.0).abs() < 1e-12);
            assert!(n.y > 0.0 && n.x >= 0.0, "up and away from the axis");
        }
    }

    #[test]
    fn its_points_graze_and_lie_in_the_observer_plane() {
        let c = TABLE_1;
        let h = helix(&c);
        let pts = section_points(&cap(), &h, 400);
        assert!(pts.len() > 400);
        for g in &pts {
            let v = h.velocity(g.phi);
            assert!(g.normal.dot(v).abs() < 1e-12 * v.length(), "N · V = 0");
            assert!(g.position.z.abs() < 1e-12, "z = 0");
            // The point is on the tool surface at φ: its meridian coordinates satisfy the cap.
            let local = g.position - h.position(g.phi);
            let rho = local.x.hypot(local.z);
            assert!((local.y - (c.a * rho * rho + c.b)).abs() < 1e-9);
        }
    }

    #[test]
    fn it_agrees_with_eq_10_and_the_section_on_the_eq_10_part() {
        let c = TABLE_1;
        let h = helix(&c);
        let pts = section_points(&cap(), &h, 2000);
        let (far, near) = c.switches();
        let tool = crate::papers::tool::Paraboloid { a: c.a, b: c.b };
        let poly = upper_boundary(&tool, &h, (-32.0, -8.0), 1e-4).unwrap();
        let interpolate = |x: f64| {
            let i = poly.partition_point(|p| p.x <= x).clamp(1, poly.len() - 1);
            let (p, q) = (poly[i - 1], poly[i]);
            p.y + (q.y - p.y) * (x - p.x) / (q.x - p.x)
        };
        for g in &pts {
            let (x, y) = (g.section.x, g.section.y);
            // Every grazing point of the cap is on the Eq. 10 part, between the switches.
            assert!(
                far - 1e-9 <= x && x <= near + 1e-9,
                "{x} outside [{far}, {near}]"
            );
            assert!((y - c.eq10(x)).abs() < 1e-9, "Eq. 10 at {x}");
            assert!(
                (y - top_at(&tool, &h, x).unwrap().y).abs() < 1e-9,
                "top at {x}"
            );
            assert!((y - interpolate(x)).abs() <= 1e-4, "polyline at {x}");
        }
        // The envelope covers the Eq. 10 part end to end: its rim points are the switches.
        assert!((pts[0].section.x - far).abs() < 1e-9);
        assert!((pts[pts.len() - 1].section.x - near).abs() < 1e-9);
    }

    #[test]
    fn near_the_tip_the_cap_cannot_graze() {
        // q = p/(2πR·(−2aρ)) exceeds 1 below ρ = p/(4π|a|R): too flat to face the feed.
        let c = TABLE_1;
        let h = helix(&c);
        let rho_min = c.p / (4.0 * PI * -c.a * c.r);
        assert!(plane_points(&cap(), &h, 0.99 * rho_min).is_empty());
        assert!(plane_points(&cap(), &h, 0.0).is_empty());
        assert!(!plane_points(&cap(), &h, 1.01 * rho_min).is_empty());
    }

    #[test]
    fn with_no_pitch_it_is_the_tools_own_section() {
        // p = 0: the cap grazes where its normal is radial to the screw axis, at φ = π, and
        // traces y = a (x + R)² + b.
        let c = Case { p: 0.0, ..TABLE_1 };
        let pts = section_points(&cap(), &helix(&c), 500);
        for g in &pts {
            let x = g.section.x;
            assert!((g.section.y - (c.a * (x + c.r).powi(2) + c.b)).abs() < 1e-9);
            assert!((g.phi - PI).abs() < 1e-12);
        }
    }
}
