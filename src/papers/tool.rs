//! Tools of revolution, described by their meridian region.
//!
//! A solid of revolution is fixed by the region it occupies in one meridian half-plane, in
//! coordinates (ρ, h): ρ ≥ 0 the distance from the tool axis, h the height along it from the
//! tool's reference point. The distance from any point in space to the solid is the 2D
//! distance from the point's (ρ, h) to that region, because the nearest point lies in the
//! same meridian half-plane. So every sweep computation needs only two things of a tool: its
//! signed distance in (ρ, h), and the heights it occupies at a given radius.
//!
//! Conventions per tool are in their docs: end mills have their tip at h = 0 and their shank
//! towards +h (without end); the whirling ring's torus is centred on h = 0; seed 000's
//! paraboloid sits on its centre plane h = 0 with its tip at h = b.

use serde::Serialize;

/// A tool of revolution, as its meridian region in (ρ, h).
pub trait Revolved {
    /// Signed distance from the meridian point (ρ ≥ 0, h) to the solid: negative inside.
    /// Exact outside and on the boundary; inside, exact for the torus, the paraboloid, the
    /// ball and the flat end mill, and a bound on the depth for the corner-radius mill.
    fn signed_distance(&self, rho: f64, h: f64) -> f64;

    /// The heights the solid occupies at radius ρ, as `(lowest, highest)` (the highest may be
    /// `f64::INFINITY` up a shank); `None` where the solid does not reach ρ. Every tool here is
    /// convex along h at any radius except the torus, whose span is its tube's chord.
    fn span_at(&self, rho: f64) -> Option<(f64, f64)>;

    /// The largest radius of the solid.
    fn max_radius(&self) -> f64;
}

/// The whirling ring swept by its spinning inserts: the circle of radius `ring` (R, ring centre
/// to insert nose centre) about the axis, thickened by the nose radius `nose` (r), centred on
/// h = 0. Needs R ≥ r.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Torus {
    /// R, mm.
    pub ring: f64,
    /// r, mm.
    pub nose: f64,
}

impl Revolved for Torus {
    fn signed_distance(&self, rho: f64, h: f64) -> f64 {
        (rho - self.ring).hypot(h) - self.nose
    }

    fn span_at(&self, rho: f64) -> Option<(f64, f64)> {
        let d = rho - self.ring;
        let half = (self.nose * self.nose - d * d).sqrt();
        (half >= 0.0).then_some((-half, half))
    }

    fn max_radius(&self) -> f64 {
        self.ring + self.nose
    }
}

/// Seed 000's circular paraboloid end mill, upper half: the solid between its centre plane
/// h = 0 and the cap h = a·ρ² + b (a < 0, b > 0), tip at h = b, radius √(−b/a) on the plane.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Paraboloid {
    /// a, 1/mm (negative).
    pub a: f64,
    /// b, mm (positive).
    pub b: f64,
}

impl Paraboloid {
    /// Radius where the cap meets the centre plane.
    pub fn base_radius(&self) -> f64 {
        (-self.b / self.a).sqrt()
    }
}

impl Revolved for Paraboloid {
    fn signed_distance(&self, rho: f64, h: f64) -> f64 {
        // Region: 0 ≤ h ≤ aρ² + b. Distance to the cap: the nearest point (s, as² + b) on the
        // parabola solves the cubic 2a²s³ + (2a(b − h) + 1)s − ρ = 0 (one real root for s ≥ 0
        // since a² > 0); Newton from s = ρ converges fast on this monotone cubic.
        let (a, b) = (self.a, self.b);
        let c1 = 2.0 * a * (b - h) + 1.0;
        let f = |s: f64| 2.0 * a * a * s * s * s + c1 * s - rho;
        let mut s = rho.clamp(0.0, self.base_radius());
        for _ in 0..60 {
            let df = 6.0 * a * a * s * s + c1;
            if df.abs() < 1e-300 {
                break;
            }
            let next = (s - f(s) / df).clamp(0.0, self.base_radius());
            if (next - s).abs() < 1e-15 * (1.0 + s) {
                s = next;
                break;
            }
            s = next;
        }
        let to_cap = (rho - s).hypot(h - (a * s * s + b));
        let to_base = if rho <= self.base_radius() {
            h.abs()
        } else {
            (rho - self.base_radius()).hypot(h)
        };
        let inside = h >= 0.0 && h <= a * rho * rho + b;
        let d = to_cap.min(to_base);
        if inside {
            -d
        } else {
            d
        }
    }

    fn span_at(&self, rho: f64) -> Option<(f64, f64)> {
        let top = self.a * rho * rho + self.b;
        (top >= 0.0).then_some((0.0, top))
    }

    fn max_radius(&self) -> f64 {
        self.base_radius()
    }
}

/// A ball end mill of radius `radius`: tip at h = 0, the ball's centre at h = r, the shank a
/// cylinder of radius r above it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct BallEnd {
    /// r, mm.
    pub radius: f64,
}

impl Revolved for BallEnd {
    fn signed_distance(&self, rho: f64, h: f64) -> f64 {
        let r = self.radius;
        if h < r {
            rho.hypot(h - r) - r
        } else {
            rho - r
        }
    }

    fn span_at(&self, rho: f64) -> Option<(f64, f64)> {
        // r − √(r² − ρ²), written so it keeps its digits for small ρ.
        let r = self.radius;
        (rho <= r).then(|| (rho * rho / (r + (r * r - rho * rho).sqrt()), f64::INFINITY))
    }

    fn max_radius(&self) -> f64 {
        self.radius
    }
}

/// A corner-radius (bull-nose) end mill: a flat tip of radius `flat` at h = 0, rounded into the
/// shank (radius flat + corner) by a quarter circle of radius `corner`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CornerRadius {
    /// Radius of the flat tip, mm.
    pub flat: f64,
    /// Corner radius, mm.
    pub corner: f64,
}

impl Revolved for CornerRadius {
    fn signed_distance(&self, rho: f64, h: f64) -> f64 {
        let (f, c) = (self.flat, self.corner);
        if h < c && rho > f {
            // Beside the corner's centre circle (ρ = f, h = c): the rounded edge.
            (rho - f).hypot(h - c) - c
        } else if h < c {
            // Under the flat tip: the distance to the plane h = 0, or inside.
            if h < 0.0 {
                -h
            } else {
                -(h.min(f + c - rho))
            }
        } else {
            rho - (f + c)
        }
    }

    fn span_at(&self, rho: f64) -> Option<(f64, f64)> {
        let (f, c) = (self.flat, self.corner);
        if rho <= f {
            Some((0.0, f64::INFINITY))
        } else if rho <= f + c {
            // c − √(c² − d²) with its digits kept; d may round to just above c at the rim.
            let d = (rho - f).min(c);
            Some((d * d / (c + (c * c - d * d).sqrt()), f64::INFINITY))
        } else {
            None
        }
    }

    fn max_radius(&self) -> f64 {
        self.flat + self.corner
    }
}

/// A flat end mill of radius `radius`, tip face at h = 0.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FlatEnd {
    /// Radius, mm.
    pub radius: f64,
}

impl Revolved for FlatEnd {
    fn signed_distance(&self, rho: f64, h: f64) -> f64 {
        let r = self.radius;
        match (rho <= r, h >= 0.0) {
            (true, true) => -(h.min(r - rho)),
            (true, false) => -h,
            (false, true) => rho - r,
            (false, false) => (rho - r).hypot(h),
        }
    }

    fn span_at(&self, rho: f64) -> Option<(f64, f64)> {
        (rho <= self.radius).then_some((0.0, f64::INFINITY))
    }

    fn max_radius(&self) -> f64 {
        self.radius
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every tool's signed distance is zero on the boundary its span describes, negative just
    /// inside and positive just outside.
    fn boundary_agrees(tool: &dyn Revolved, probes: &[f64]) {
        for &rho in probes {
            let Some((lo, hi)) = tool.span_at(rho) else {
                assert!(
                    tool.signed_distance(rho, 0.0) > 0.0
                        || tool.signed_distance(rho, 0.0).abs() < 1e-9
                );
                continue;
            };
            for h in [lo, hi].into_iter().filter(|h| h.is_finite()) {
                assert!(tool.signed_distance(rho, h).abs() < 1e-9, "ρ {rho} h {h}");
            }
            if hi > lo + 1e-6 {
                let mid = if hi.is_finite() {
                    (lo + hi) / 2.0
                } else {
                    lo + 1e-3
                };
                assert!(tool.signed_distance(rho, mid) < 0.0, "inside at ρ {rho}");
            }
            assert!(
                tool.signed_distance(rho, lo - 1e-3) > 0.0,
                "outside below at ρ {rho}"
            );
        }
    }

    #[test]
    fn spans_and_distances_describe_the_same_solids() {
        let probes = [0.0, 0.3, 1.0, 2.0, 2.9, 3.5, 5.0, 11.9];
        boundary_agrees(
            &Torus {
                ring: 3.0,
                nose: 1.0,
            },
            &probes,
        );
        boundary_agrees(&Paraboloid { a: -0.05, b: 7.2 }, &probes);
        boundary_agrees(&BallEnd { radius: 3.0 }, &probes);
        boundary_agrees(
            &CornerRadius {
                flat: 2.0,
                corner: 1.0,
            },
            &probes,
        );
        boundary_agrees(&FlatEnd { radius: 3.0 }, &probes);
    }

    #[test]
    fn the_seed_000_paraboloid_is_12_mm_in_radius_and_distances_are_exact_on_its_axis() {
        let p = Paraboloid { a: -0.05, b: 7.2 };
        assert!(
            (p.base_radius() - 12.0).abs() < 1e-12,
            "a·ρ² + b = 0 at ρ = 12"
        );
        assert!(
            (p.signed_distance(0.0, 10.0) - 2.8).abs() < 1e-12,
            "2.8 above the tip"
        );
        // The parabola's curvature at the tip is 2|a| = 0.1: radius 10. From its focus-side
        // axis point h = b − 1 the nearest boundary is the tip, 1 away.
        assert!((p.signed_distance(0.0, 6.2) + 1.0).abs() < 1e-12);
        // Point outside, off the cap: distance equals the distance to the nearest cap point.
        let s: f64 = 5.0;
        let on = (s, -0.05 * s * s + 7.2);
        let normal = glam::DVec2::new(2.0 * 0.05 * s, 1.0).normalize(); // outward cap normal
        let q = glam::DVec2::new(on.0, on.1) + 0.7 * normal;
        assert!((p.signed_distance(q.x, q.y) - 0.7).abs() < 1e-9);
    }
}
