//! The node solver of kinematics.md: one profile point → one machine pose (X, C, Z) and its
//! phase ψ = C + Z / p.
//!
//! For a surface point M (taken at θ = 0) with outward normal n, the insert nose centre is
//! N = M + r·n. Turning the workpiece by C, conditions (1) and (2) of kinematics.md give Z and X
//! in closed form, and the meridian condition (3) is one equation g(C) = 0, bracketed near the
//! cutting-side angle C₀ and solved with Brent's method.

use crate::geometry::brent;
use crate::geometry::profile::{Material, ProfilePoint};
use glam::{DVec2, DVec3};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;
use std::fmt;

/// Which side of the workpiece the ring cuts from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Whirling {
    /// The ring encloses the workpiece and cuts on the −X side (k = +1).
    Internal,
    /// A cutter disk beside the workpiece cuts on the +X side (k = −1).
    External,
    /// A head inside a nut's bore, its inserts pointing outward, cuts the internal groove on
    /// the +X side (k = −1), its centre nearer the axis than the contact (kinematics.md,
    /// "Internal grooves").
    Bore,
}

impl Whirling {
    /// kinematics.md's k: +1 internal, −1 external and bore.
    pub fn k(self) -> f64 {
        match self {
            Whirling::Internal => 1.0,
            Whirling::External | Whirling::Bore => -1.0,
        }
    }

    /// The side of the groove's surface the material lies on for the grooves this tool cuts:
    /// a ring or a disk cuts a screw (inside), a bore head a nut (outside).
    pub fn material(self) -> Material {
        match self {
            Whirling::Internal | Whirling::External => Material::Inside,
            Whirling::Bore => Material::Outside,
        }
    }

    /// The job file's word for it.
    pub fn name(self) -> &'static str {
        match self {
            Whirling::Internal => "internal",
            Whirling::External => "external",
            Whirling::Bore => "bore",
        }
    }
}

/// The whirling ring as the linkage sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ring {
    /// Internal or external whirling.
    pub whirling: Whirling,
    /// R: ring centre to insert nose centre, mm.
    pub radius: f64,
    /// r: insert nose radius, mm.
    pub nose: f64,
    /// δ ≥ 0: installation angle, radians.
    pub installation: f64,
    /// Half the insert's cutting-edge arc, radians: the largest angle between the contact
    /// direction −n and the insert's axis (the ring's radial direction at N, inwards for internal
    /// whirling, outwards for external and bore) at which the edge still cuts.
    pub edge_half_angle: f64,
}

/// A machine pose in the kinematics.md frame: X, Z in mm, C in radians.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Pose {
    /// Ring-centre offset from the spindle axis, mm.
    pub x: f64,
    /// Workpiece turn, radians.
    pub c: f64,
    /// Axial position of the ring centre, mm.
    pub z: f64,
}

impl Pose {
    /// The phase ψ = C + Z / p, invariant along the screw motion.
    pub fn phase(&self, p: f64) -> f64 {
        self.c + self.z / p
    }
}

/// A solved contact: the pose and what the planner needs to know about it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contact {
    /// The machine pose that touches the point at θ = 0.
    pub pose: Pose,
    /// Its phase ψ.
    pub phase: f64,
    /// |n_M · x̂|: how much of an X error shows as a normal error at the contact.
    pub normal_x: f64,
}

/// Why a profile point has no pose.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LinkageError {
    /// The ring circle cannot pass through the nose centre in its tilted plane.
    #[error(
        "the ring cannot reach the point: the nose centre lies {needed:.3} mm from the ring's \
         plane axis but the ring radius is {radius:.3} mm (negative square root)"
    )]
    OutOfReach {
        /// |N_y| / cos δe at the best turn found.
        needed: f64,
        /// R.
        radius: f64,
    },
    /// g(C) has no root near the cutting side.
    #[error("no pose touches the point: the meridian condition has no root within ±90° of the cutting side")]
    NoRoot,
    /// The contact would be outside the insert's cutting edge.
    #[error(
        "the contact lies {angle_deg:.1}° off the insert's axis, beyond its cutting edge (±{limit_deg:.1}°)"
    )]
    OffEdge {
        /// Angle between −n and the insert axis.
        angle_deg: f64,
        /// The edge's half arc.
        limit_deg: f64,
    },
}

/// Turn a vector about z by `c` radians.
pub fn turn(v: DVec3, c: f64) -> DVec3 {
    let (s, co) = c.sin_cos();
    turned(v, s, co)
}

/// The linkage for one groove (lead parameter p) and one ring.
#[derive(Debug, Clone, Copy)]
pub struct Linkage {
    /// Lead parameter p = ±lead / 2π (+ right hand).
    pub p: f64,
    /// The ring.
    pub ring: Ring,
}

/// The ring's tilt as conditions (1) to (3) use it, its trigonometry taken once for a solve
/// rather than at every evaluation of g(C).
#[derive(Debug, Clone, Copy)]
struct Tilt {
    /// kinematics.md's k.
    k: f64,
    /// tan δe.
    tan: f64,
    /// cos δe.
    cos: f64,
    /// The ring axis a_M.
    axis: DVec3,
    /// Which root of condition (2) places the ring centre: +1 on the +X side of N (a ring or
    /// a disk), −1 on the axis side (a bore head, whose contact is beyond its centre).
    side: f64,
}

/// `v` turned about the z axis by the angle whose sine and cosine are `s` and `co`: [`turn`]
/// with its sine and cosine given.
fn turned(v: DVec3, s: f64, co: f64) -> DVec3 {
    DVec3::new(co * v.x - s * v.y, s * v.x + co * v.y, v.z)
}

/// Angle step of the bracket search around C₀, and how far it looks.
const BRACKET_STEP: f64 = PI / 360.0;
const BRACKET_REACH: f64 = PI / 2.0;

impl Linkage {
    /// Signed installation angle δe = sign(p)·δ.
    pub fn delta_e(&self) -> f64 {
        self.p.signum() * self.ring.installation
    }

    /// The ring axis a_M = (0, k·sin δe, cos δe), fixed in the machine frame.
    pub fn axis(&self) -> DVec3 {
        let de = self.delta_e();
        DVec3::new(0.0, self.ring.whirling.k() * de.sin(), de.cos())
    }

    fn tilt(&self) -> Tilt {
        let de = self.delta_e();
        Tilt {
            k: self.ring.whirling.k(),
            tan: de.tan(),
            cos: de.cos(),
            axis: self.axis(),
            side: match self.ring.whirling {
                Whirling::Internal | Whirling::External => 1.0,
                Whirling::Bore => -1.0,
            },
        }
    }

    /// Z and X that put the turned nose centre `n_m` on the tip circle (conditions 1 and 2), or
    /// the reach needed when the square root is negative.
    fn place(&self, tilt: &Tilt, n_m: DVec3) -> Result<(f64, f64), f64> {
        let z = n_m.z + tilt.k * tilt.tan * n_m.y;
        let needed = n_m.y.abs() / tilt.cos;
        let radius = self.ring.radius;
        if needed > radius {
            return Err(needed);
        }
        Ok((
            n_m.x + tilt.side * (radius * radius - needed * needed).sqrt(),
            z,
        ))
    }

    /// g(C): the meridian condition (3), n_M · (a_M × (N_M − O_M)); NaN out of reach.
    fn meridian(&self, tilt: &Tilt, nose: DVec3, normal: DVec3, c: f64) -> f64 {
        let (s, co) = c.sin_cos();
        let n_m = turned(nose, s, co);
        match self.place(tilt, n_m) {
            Ok((x, z)) => turned(normal, s, co).dot(tilt.axis.cross(n_m - DVec3::new(x, 0.0, z))),
            Err(_) => f64::NAN,
        }
    }

    /// The pose that touches the profile point at θ = 0 (kinematics.md, "The linkage"), of a
    /// groove whose material lies on the side the ring cuts ([`Whirling::material`]).
    pub fn solve(&self, point: &ProfilePoint) -> Result<Contact, LinkageError> {
        let normal = self
            .ring
            .whirling
            .material()
            .normal(point.pos, point.tangent, self.p);
        self.solve_normal(point.pos, normal)
    }

    /// The pose that touches the surface point `pos` (θ = 0) whose outward normal is `normal`.
    pub fn solve_normal(&self, pos: DVec2, normal: DVec3) -> Result<Contact, LinkageError> {
        let nose = DVec3::new(pos.x, pos.y, 0.0) + self.ring.nose * normal;
        let c0 = match self.ring.whirling {
            Whirling::Internal => PI - nose.y.atan2(nose.x),
            Whirling::External | Whirling::Bore => -nose.y.atan2(nose.x),
        };
        let tilt = self.tilt();
        let g = |c: f64| self.meridian(&tilt, nose, normal, c);
        let c = self.bracketed_root(&tilt, g, c0, nose)?;
        let n_m = turn(nose, c);
        let (x, z) = self
            .place(&tilt, n_m)
            .map_err(|needed| LinkageError::OutOfReach {
                needed,
                radius: self.ring.radius,
            })?;
        let centre = DVec3::new(x, 0.0, z);
        let inward = (centre - n_m).normalize();
        let insert_axis = match self.ring.whirling {
            Whirling::Internal => inward,
            Whirling::External | Whirling::Bore => -inward,
        };
        let normal_m = turn(normal, c);
        let off = (-normal_m).angle_between(insert_axis);
        if off > self.ring.edge_half_angle + 1e-12 {
            return Err(LinkageError::OffEdge {
                angle_deg: off.to_degrees(),
                limit_deg: self.ring.edge_half_angle.to_degrees(),
            });
        }
        let pose = Pose { x, c, z };
        Ok(Contact {
            pose,
            phase: pose.phase(self.p),
            normal_x: normal_m.x.abs(),
        })
    }

    /// Signed distance from the workpiece point `q` (frame W) to the ring's torus at `pose`:
    /// distance to the tip circle minus the nose radius. Negative inside the tool.
    pub fn gap(&self, q: DVec3, pose: &Pose) -> f64 {
        self.torus(pose).gap(turn(q, pose.c))
    }

    /// The ring's torus at `pose`, in the machine frame.
    pub fn torus(&self, pose: &Pose) -> Torus {
        Torus {
            centre: DVec3::new(pose.x, 0.0, pose.z),
            axis: self.axis(),
            radius: self.ring.radius,
            nose: self.ring.nose,
        }
    }

    /// The root of `g` nearest `c0`: step outwards on both sides until the sign changes, stop
    /// a side where the ring goes out of reach (the square root of condition 2 turns
    /// negative), then polish with Brent. With no root, the error says whether the search ran
    /// out of reach or out of angle.
    fn bracketed_root(
        &self,
        tilt: &Tilt,
        g: impl Fn(f64) -> f64,
        c0: f64,
        nose: DVec3,
    ) -> Result<f64, LinkageError> {
        let g0 = g(c0);
        if g0 == 0.0 {
            return Ok(c0);
        }
        let steps = (BRACKET_REACH / BRACKET_STEP).round() as usize;
        // Per side: the last angle and value, and whether the side has left the reach.
        let mut sides = [(c0, g0, false); 2];
        let mut out_of_reach = None;
        for k in 1..=steps {
            for ((prev_c, prev_g, left), dir) in sides.iter_mut().zip([1.0, -1.0]) {
                if *left {
                    continue;
                }
                let c = c0 + dir * BRACKET_STEP * k as f64;
                let gc = g(c);
                if gc == 0.0 {
                    return Ok(c);
                }
                if prev_g.is_finite() && gc.is_finite() && prev_g.signum() != gc.signum() {
                    return brent::root(&g, *prev_c, c, 1e-14, 200).ok_or(LinkageError::NoRoot);
                }
                // A side that leaves the reachable range is done; one that starts outside it
                // may still walk into it.
                *left = prev_g.is_finite() && !gc.is_finite();
                if *left {
                    out_of_reach = self.place(tilt, turn(nose, c)).err();
                }
                (*prev_c, *prev_g) = (c, gc);
            }
        }
        Err(match out_of_reach {
            Some(needed) => LinkageError::OutOfReach {
                needed,
                radius: self.ring.radius,
            },
            None => LinkageError::NoRoot,
        })
    }
}

/// The swept ring at one pose, in the machine frame: the tip circle (centre, unit axis,
/// radius R) thickened by the nose radius r.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Torus {
    /// Ring centre O_M.
    pub centre: DVec3,
    /// Unit ring axis a_M.
    pub axis: DVec3,
    /// R.
    pub radius: f64,
    /// r.
    pub nose: f64,
}

impl Torus {
    /// Signed distance from `q_m` (machine frame) to the torus: distance to the tip circle
    /// minus r; negative inside the tool.
    pub fn gap(&self, q_m: DVec3) -> f64 {
        let d = q_m - self.centre;
        let along = d.dot(self.axis);
        let radial = (d - along * self.axis).length();
        (radial - self.radius).hypot(along) - self.nose
    }
}

impl fmt::Display for Pose {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "X {:.4} mm, C {:.4}°, Z {:.4} mm",
            self.x,
            self.c.to_degrees(),
            self.z
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    fn ring(whirling: Whirling, radius: f64, nose: f64, delta_deg: f64) -> Ring {
        Ring {
            whirling,
            radius,
            nose,
            installation: delta_deg.to_radians(),
            edge_half_angle: PI / 2.0,
        }
    }

    /// A point of a radial-normal stretch: the tangent is perpendicular to the radius.
    fn radial_point(rho: f64, phi: f64) -> ProfilePoint {
        ProfilePoint {
            u: 0.0,
            pos: DVec2::from_angle(phi) * rho,
            tangent: DVec2::from_angle(phi + PI / 2.0),
        }
    }

    #[test]
    fn radial_normal_points_match_the_check_values_for_any_installation_angle() {
        for delta in [0.0, 5.0, 18.0, 33.0] {
            for (rho, phi) in [(25.0, 0.0), (35.0, 1.0), (27.5, -2.5)] {
                for p in [14.0, -9.5] {
                    let (r, big_r) = (1.2, 60.0);
                    let internal = Linkage {
                        p,
                        ring: ring(Whirling::Internal, big_r, r, delta),
                    };
                    let c = internal.solve(&radial_point(rho, phi)).unwrap();
                    assert!((c.pose.x - (big_r - (rho + r))).abs() < 1e-9);
                    assert!(angle_eq(c.pose.c, PI - phi), "{} vs {}", c.pose.c, PI - phi);
                    assert!(c.pose.z.abs() < 1e-9);
                    let external = Linkage {
                        p,
                        ring: ring(Whirling::External, big_r, r, delta),
                    };
                    let c = external.solve(&radial_point(rho, phi)).unwrap();
                    assert!((c.pose.x - (big_r + rho + r)).abs() < 1e-9);
                    assert!(angle_eq(c.pose.c, -phi));
                    assert!(c.pose.z.abs() < 1e-9);
                }
            }
        }
    }

    #[test]
    fn a_bore_head_meets_the_radial_check_values() {
        // A nut's root or bore (the material outside, the normal towards the axis): the nose
        // centre lies at ρ − r, beyond the head's centre, so X = ρ − r − R, C = −φ, Z = 0,
        // whatever δ and the hand. Its meridian normal points at the insert's outward axis.
        for delta in [0.0, 3.0, 18.0, 33.0] {
            for (rho, phi) in [(20.5, 0.0), (16.5, 1.0), (18.0, -2.5)] {
                for p in [7.0 / TAU, -9.5] {
                    let (r, big_r) = (0.4, 12.0);
                    let bore = Linkage {
                        p,
                        ring: ring(Whirling::Bore, big_r, r, delta),
                    };
                    let c = bore.solve(&radial_point(rho, phi)).unwrap();
                    assert!((c.pose.x - (rho - r - big_r)).abs() < 1e-9, "{:?}", c.pose);
                    assert!(angle_eq(c.pose.c, -phi), "{} vs {}", c.pose.c, -phi);
                    assert!(c.pose.z.abs() < 1e-9);
                    // The head's torus touches the surface point there and keeps its centre
                    // nearer the axis than the contact.
                    let q = DVec3::new(rho * phi.cos(), rho * phi.sin(), 0.0);
                    assert!(bore.gap(q, &c.pose).abs() < 1e-9);
                    assert!(c.pose.x < rho);
                }
            }
        }
    }

    #[test]
    fn the_screws_normal_puts_a_bore_heads_nose_two_radii_into_the_wall() {
        // The nut's outward normal is the screw's reversed, so a nose placed by the screw's
        // rule (centre r behind the surface, in the nut's wall) sits 2r further out: the
        // bore head solved for the same radial point with the nut's normal and with the
        // screw's differs by 2r in X.
        // A nose that cuts all round (half angle π), so that the screw's rule gives a pose to
        // compare rather than a refusal: its contact lies on the back of a real insert.
        let l = Linkage {
            p: 7.0 / TAU,
            ring: Ring {
                edge_half_angle: PI,
                ..ring(Whirling::Bore, 12.0, 0.4, 3.0)
            },
        };
        let point = radial_point(20.5, 0.3);
        let nut = l.solve(&point).unwrap();
        let screw_normal = Material::Inside.normal(point.pos, point.tangent, l.p);
        let wrong = l.solve_normal(point.pos, screw_normal).unwrap();
        assert!((wrong.pose.x - nut.pose.x - 0.8).abs() < 1e-9);
    }

    fn angle_eq(a: f64, b: f64) -> bool {
        let d = (a - b).rem_euclid(TAU);
        d.min(TAU - d) < 1e-9
    }

    #[test]
    fn reproduces_the_reference_linkage_vectors() {
        let csv = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/tests/data/linkage-vectors.csv"
        ))
        .expect("tests/data/linkage-vectors.csv");
        let mut rows = 0;
        for line in csv.lines().skip(1) {
            let f: Vec<&str> = line.split(',').collect();
            let num = |i: usize| f[i].parse::<f64>().unwrap();
            let whirling = if f[1] == "internal" {
                Whirling::Internal
            } else {
                Whirling::External
            };
            let sign = if f[2] == "right" { 1.0 } else { -1.0 };
            let starts = num(4);
            let p = sign * num(3) / TAU;
            let linkage = Linkage {
                p,
                ring: ring(whirling, num(5), num(6), num(7)),
            };
            // The profile ρ(φ) = 30 − 5 cos(3φ) and its tangent, exactly.
            let phi = num(8).to_radians();
            let rho = 30.0 - 5.0 * (starts * phi).cos();
            let drho = 5.0 * starts * (starts * phi).sin();
            let pos = DVec2::from_angle(phi) * rho;
            let tangent = (DVec2::from_angle(phi) * drho + DVec2::from_angle(phi + PI / 2.0) * rho)
                .normalize();
            let c = linkage
                .solve(&ProfilePoint {
                    u: 0.0,
                    pos,
                    tangent,
                })
                .unwrap();
            let (x, cc, z, psi) = (num(10), num(11).to_radians(), num(12), num(13).to_radians());
            assert!((c.pose.x - x).abs() < 1e-7, "{line}: X {}", c.pose.x);
            assert!((c.pose.z - z).abs() < 1e-7, "{line}: Z {}", c.pose.z);
            assert!(
                angle_eq(c.pose.c, cc),
                "{line}: C {}",
                c.pose.c.to_degrees()
            );
            let period = TAU / starts;
            let d = (c.phase - psi).rem_euclid(period);
            assert!(
                d.min(period - d) < 1e-9,
                "{line}: ψ {}",
                c.phase.to_degrees()
            );
            rows += 1;
        }
        assert_eq!(rows, 26);
    }

    fn lobe_point(phi: f64) -> ProfilePoint {
        let rho = 30.0 - 5.0 * (3.0 * phi).cos();
        let drho = 15.0 * (3.0 * phi).sin();
        let tangent =
            (DVec2::from_angle(phi) * drho + DVec2::from_angle(phi + PI / 2.0) * rho).normalize();
        ProfilePoint {
            u: 0.0,
            pos: DVec2::from_angle(phi) * rho,
            tangent,
        }
    }

    #[test]
    fn a_narrow_cutting_edge_cuts_the_root_but_not_the_flank() {
        let mut r = ring(Whirling::Internal, 50.0, 1.0, 20.0);
        r.edge_half_angle = 10f64.to_radians();
        let l = Linkage {
            p: 60.0 / TAU,
            ring: r,
        };
        // At the root the normal is radial: the contact is on the insert's axis.
        l.solve(&lobe_point(0.0)).unwrap();
        // Mid-flank the normal leans far from it.
        let e = l.solve(&lobe_point(30f64.to_radians())).unwrap_err();
        let LinkageError::OffEdge {
            angle_deg,
            limit_deg,
        } = e
        else {
            panic!("{e}")
        };
        assert!(angle_deg > 10.0 && (limit_deg - 10.0).abs() < 1e-9, "{e}");
    }

    #[test]
    fn a_ring_tilted_far_from_the_helix_finds_no_pose_on_the_flank() {
        // Tilted 20° against a 5 mm lead (a lead angle of 1.5° at 30 mm): on the flank the
        // meridian condition has no root within ±90° of the cutting side.
        let l = Linkage {
            p: 5.0 / TAU,
            ring: ring(Whirling::Internal, 45.0, 1.0, 20.0),
        };
        let e = l.solve(&lobe_point(30f64.to_radians())).unwrap_err();
        assert_eq!(e, LinkageError::NoRoot);
    }
}
