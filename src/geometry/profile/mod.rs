//! Groove cross-sections: one period of the transverse profile `P(u)` of kinematics.md.
//!
//! A [`Profile`] is a curve in the transverse plane `z = 0` that covers one period of polar
//! angle (`2π / starts`) with the polar angle increasing along its parameter `u`; the next
//! period is the same curve turned by the period angle. It is built from
//! - sampled points, fitted by a periodic cubic spline ([`points`], [`spline`]), or
//! - the exact axial section of a standard thread ([`standard`]), turned into the transverse
//!   section by kinematics.md's rule: the axial point `(ρ, z)` is the transverse point at radius
//!   `ρ` and polar angle `−z / p`, or
//! - a CAD drawing ([`drawing`]): its lines, arcs and splines kept as the exact curves they are
//!   ([`Piece::Line`], [`Piece::Arc`], [`Piece::Nurbs`]), in either section.
//!
//! Convex corners (a crest edge of a standard thread) are kept sharp: they become a
//! [`Piece::Corner`] along which the point stays put and the tangent turns, so the ring rolls
//! its nose around the edge. A concave corner cannot be cut by a nose of finite radius and is
//! reported by [`Profile::concave_stretches`].

pub mod axial_section;
pub mod drawing;
pub mod nurbs;
pub mod points;
pub mod smoothing;
pub mod spline;
pub mod standard;
#[cfg(test)]
pub(crate) mod testing;

use glam::{DVec2, DVec3};
use num_complex::Complex64;
use nurbs::Nurbs;
use spline::Spline;
use standard::AxialPiece;
use std::f64::consts::PI;

/// Outward unit normal of the helical surface at the profile point `(pos, tangent)`, θ = 0,
/// of an external groove (a screw: the material inside): `n ∝ (p·y′, −p·x′, x·x′ + y·y′)`,
/// oriented so that its in-plane part points away from the material (to the right of a
/// tangent running with increasing polar angle). [`Material::normal`] gives either side's.
pub fn surface_normal(pos: DVec2, tangent: DVec2, p: f64) -> DVec3 {
    let n = DVec3::new(p * tangent.y, -p * tangent.x, pos.dot(tangent));
    (n * p.signum()).normalize()
}

/// Which side of the groove's surface the material lies (kinematics.md, "Internal grooves").
///
/// A screw's groove has the material inside (towards the axis), a nut's outside. The side
/// sets which way the surface normal points (always from the material into the groove),
/// which edges are convex, and so which turns a nose can roll round.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Material {
    /// An external groove (a screw shaft): the material lies nearer the axis.
    #[default]
    Inside,
    /// An internal groove (a nut): the material lies outside the surface, the bore is the
    /// groove's smallest radius.
    Outside,
}

impl Material {
    /// +1 inside, −1 outside: the sign that turns the external groove's orientations (the
    /// normal, a convex turn) into this side's.
    pub fn sign(self) -> f64 {
        match self {
            Material::Inside => 1.0,
            Material::Outside => -1.0,
        }
    }

    /// The outward unit normal (from the material into the groove) at `(pos, tangent)`:
    /// [`surface_normal`]'s, reversed when the material lies outside.
    pub fn normal(self, pos: DVec2, tangent: DVec2, p: f64) -> DVec3 {
        self.sign() * surface_normal(pos, tangent, p)
    }
}

/// A point of the transverse profile with its first-order geometry.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProfilePoint {
    /// Parameter along the profile.
    pub u: f64,
    /// Position `(x, y)` in the transverse plane, mm.
    pub pos: DVec2,
    /// Unit tangent, pointing the way the polar angle increases.
    pub tangent: DVec2,
}

/// One piece of a profile, traversed with the polar angle increasing.
#[derive(Debug, Clone)]
pub enum Piece {
    /// A transverse spline, parameter = chord length.
    Spline(Spline),
    /// An axial-section piece seen in the transverse plane (lead parameter `p`), traversed from
    /// its end to its start when `reversed` (needed where `−z / p` decreases along the piece).
    Axial {
        /// The exact axial piece.
        piece: AxialPiece,
        /// Lead parameter p = ±lead / 2π.
        p: f64,
        /// Whether the piece is traversed from its end to its start.
        reversed: bool,
    },
    /// A straight line of the transverse section; parameter = length.
    Line {
        /// Start point.
        from: DVec2,
        /// End point.
        to: DVec2,
    },
    /// A circular arc of the transverse section; parameter = arc length.
    Arc {
        /// Centre.
        centre: DVec2,
        /// Radius, mm.
        radius: f64,
        /// Polar angle of the start point about the centre, radians.
        start: f64,
        /// Angle swept, radians: positive counter-clockwise.
        sweep: f64,
    },
    /// A NURBS curve of the transverse section (`axial: None`), or of an axial section
    /// (points `(ρ, z)`) seen in the transverse plane for lead parameter `p` (`axial: Some(p)`),
    /// mapped as [`Piece::Axial`] maps lines and arcs. Parameter = arc length in its own
    /// section, as for lines and arcs: a profile's nodes are spaced along its parameter, so a
    /// curve drawn as a spline is planned as the same curve drawn otherwise.
    Nurbs {
        /// The curve, oriented the way the polar angle increases.
        curve: Nurbs,
        /// The lead parameter p for an axial section.
        axial: Option<f64>,
        /// Its arc length at parameters along it ([`Nurbs::arc_table`]).
        table: Vec<(f64, f64)>,
    },
    /// A convex edge: the point stays at `at` while the tangent angle turns from `from` to `to`
    /// (radians; `to > from` where the material lies inside, `to < from` where it lies
    /// outside, as a nut's crest edge turns the tangent clockwise). Its parameter length is
    /// the turning angle's size, in radians.
    Corner {
        /// The edge point.
        at: DVec2,
        /// Tangent angle arriving at the edge.
        from: f64,
        /// Tangent angle leaving the edge.
        to: f64,
    },
}

impl Piece {
    fn length(&self) -> f64 {
        match self {
            Piece::Spline(s) => s.length(),
            Piece::Axial { piece, .. } => piece.length(),
            Piece::Line { from, to } => from.distance(*to),
            Piece::Arc { radius, sweep, .. } => radius * sweep.abs(),
            Piece::Nurbs { table, .. } => table.last().map_or(0.0, |&(_, s)| s),
            Piece::Corner { from, to, .. } => (to - from).abs(),
        }
    }

    /// A NURBS piece of the transverse section, or of an axial one for lead parameter `p`.
    pub fn nurbs(curve: Nurbs, axial: Option<f64>) -> Piece {
        let table = curve.arc_table();
        Piece::Nurbs {
            curve,
            axial,
            table,
        }
    }

    /// Position, first and second derivative with respect to the piece's own parameter.
    fn eval(&self, s: f64) -> (DVec2, DVec2, DVec2) {
        match self {
            Piece::Spline(spline) => {
                let e = spline.eval(s);
                (c2v(e.p), c2v(e.d1), c2v(e.d2))
            }
            Piece::Axial { piece, p, reversed } => {
                let len = piece.length();
                let (a, mut t, kappa) = piece.eval(if *reversed { len - s } else { s });
                // d²A/ds² = κ · (t turned by +90°), unchanged by reversing the direction.
                let d2a = kappa * DVec2::new(-t.y, t.x);
                if *reversed {
                    t = -t;
                }
                axial_seen(a, t, d2a, *p)
            }
            Piece::Line { from, to } => {
                let t = (*to - *from).normalize_or_zero();
                let s = s.max(0.0).min(from.distance(*to));
                (*from + t * s, t, DVec2::ZERO)
            }
            Piece::Arc {
                centre,
                radius,
                start,
                sweep,
            } => {
                let sense = sweep.signum();
                let s = s.max(0.0).min(radius * sweep.abs());
                let radial = DVec2::from_angle(start + sense * s / radius);
                (
                    *centre + *radius * radial,
                    sense * radial.perp(),
                    -radial / *radius,
                )
            }
            Piece::Nurbs {
                curve,
                axial,
                table,
            } => {
                // By arc length: dt/ds = 1/|C′|, d²t/ds² = −(C′·C″)/|C′|⁴.
                let (c, c1, c2) = curve.eval(curve.at_length(table, s));
                let speed = c1.length();
                let (dt, ddt) = (1.0 / speed, -c1.dot(c2) / speed.powi(4));
                let (d1, d2) = (c1 * dt, c2 * dt * dt + c1 * ddt);
                match axial {
                    Some(p) => axial_seen(c, d1, d2, *p),
                    None => (c, d1, d2),
                }
            }
            Piece::Corner { at, from, to } => {
                let angle = from + (to - from).signum() * s.clamp(0.0, (to - from).abs());
                (*at, DVec2::from_angle(angle), DVec2::ZERO)
            }
        }
    }
}

/// The signed angle from `a` to `b`, radians (counter-clockwise positive), exact near zero:
/// `atan2` of their cross and dot products. (`DVec2::angle_to` takes an `acos` of the
/// normalised dot product, which reads a tangent join as a kink of about 1.5·10⁻⁸ rad, the
/// square root of the rounding; at a nut's fillet such a kink became a corner turned the
/// wrong way.)
fn turning(a: DVec2, b: DVec2) -> f64 {
    a.perp_dot(b).atan2(a.dot(b))
}

/// An axial-section point `a = (ρ, z)` with its derivatives along some parameter, seen in the
/// transverse plane for lead parameter `p`: radius ρ at polar angle φ = −z / p, so
/// `P = ρ e^{iφ}`, `P′ = e^{iφ}(ρ′ + iρφ′)`, `P″ = e^{iφ}(ρ″ − ρφ′² + i(2ρ′φ′ + ρφ″))`.
fn axial_seen(a: DVec2, d1: DVec2, d2: DVec2, p: f64) -> (DVec2, DVec2, DVec2) {
    let (rho, z) = (a.x, a.y);
    let (phi, dphi, ddphi) = (-z / p, -d1.y / p, -d2.y / p);
    let e = Complex64::from_polar(1.0, phi);
    let pos = e * rho;
    let first = e * Complex64::new(d1.x, rho * dphi);
    let second = e * Complex64::new(d2.x - rho * dphi * dphi, 2.0 * d1.x * dphi + rho * ddphi);
    (c2v(pos), c2v(first), c2v(second))
}

fn c2v(c: Complex64) -> DVec2 {
    DVec2::new(c.re, c.im)
}

/// One period of a groove's transverse section.
#[derive(Debug, Clone)]
pub struct Profile {
    pieces: Vec<Piece>,
    /// Parameter at the start of each piece, plus the total length at the end.
    offsets: Vec<f64>,
    period: f64,
    /// For a spline through rounded points, how much the rounding alone can bend it.
    rounding: Option<Rounding>,
    /// For a curve fitted to points within a band, how far it lies from them.
    fit: Option<Fit>,
    /// Which side of the surface the material lies.
    material: Material,
}

/// How far a profile fitted to rounded or measured points ([`smoothing`]) lies from them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fit {
    /// The largest distance from a point, mm.
    pub deviation: f64,
    /// The file line of the point where it is reached.
    pub line: usize,
    /// The widest band a point was fitted within, mm: half its last decimal, or the
    /// tolerance the job states.
    pub band: f64,
    /// How the points spread within their bands.
    pub spread: smoothing::Spread,
}

/// How much the rounding of sampled points (to the decimals they are written to) can bend the
/// spline through them: a spline's second derivatives follow the points' second differences
/// divided by the squared spacing, so points packed closer than their decimals resolve give a
/// curve whose curvature is the rounding's, not the groove's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rounding {
    /// Bound on the change of the spline's second derivative (its curvature in the transverse
    /// plane) that the rounding can make, 1/mm.
    pub bend: f64,
    /// The spacing of the points where that bound is reached, mm.
    pub spacing: f64,
    /// How far those points can lie from their unrounded places, mm.
    pub err: f64,
}

/// A concave stretch the insert nose cannot follow (its radius is below the nose radius).
#[derive(Debug, Clone, PartialEq)]
pub struct ConcaveStretch {
    /// Where the stretch is tightest.
    pub at: DVec2,
    /// Its smallest radius of curvature, mm (0 for a sharp concave corner).
    pub min_radius: f64,
    /// Depth of material the nose leaves there, mm (infinite where the nose cannot enter).
    pub depth_left: f64,
}

impl Profile {
    /// A profile from its pieces, in order of increasing polar angle, covering one period.
    pub fn new(pieces: Vec<Piece>, period: f64) -> Profile {
        let mut offsets = vec![0.0];
        for piece in &pieces {
            offsets.push(offsets.last().copied().unwrap_or(0.0) + piece.length());
        }
        Profile {
            pieces,
            offsets,
            period,
            rounding: None,
            fit: None,
            material: Material::Inside,
        }
    }

    /// The same curve with the material on side `material` (a nut's groove: outside).
    pub fn with_material(mut self, material: Material) -> Profile {
        self.material = material;
        self
    }

    /// Which side of the surface the material lies.
    pub fn material(&self) -> Material {
        self.material
    }

    /// The outward unit normal (from the material into the groove) at `point`, θ = 0, for
    /// lead parameter `p`.
    pub fn normal(&self, point: &ProfilePoint, p: f64) -> DVec3 {
        self.material.normal(point.pos, point.tangent, p)
    }

    /// For a profile fitted to points within a band, how far it lies from them (`None` for
    /// exact pieces, exact points, and points too few to smooth).
    pub fn fit(&self) -> Option<Fit> {
        self.fit
    }

    /// For a profile through points, how many it passes through over one period (after
    /// mirroring a half period, less a closing point); `None` for a standard's exact pieces.
    pub fn spline_points(&self) -> Option<usize> {
        match self.pieces.as_slice() {
            [Piece::Spline(spline)] => Some(spline.knots().len() - 1),
            _ => None,
        }
    }

    /// For a profile fitted through rounded points, how much the rounding can bend it (`None`
    /// for exact pieces and exact points).
    pub fn rounding(&self) -> Option<Rounding> {
        self.rounding
    }

    /// A profile from the axial pieces of one period (ordered by increasing z), for lead
    /// parameter `p`, the material inside (a screw). Sharp convex edges become
    /// [`Piece::Corner`]s; sharp concave ones are kept as they are and reported by
    /// [`Profile::concave_stretches`].
    pub fn from_axial(axial: Vec<AxialPiece>, p: f64, period: f64) -> Profile {
        Profile::from_axial_of(axial, p, period, Material::Inside)
    }

    /// [`Profile::from_axial`] with the material on side `material`. A nut's section
    /// (kinematics.md, "Internal grooves") runs outward from the bore at both ends, and its
    /// convex edges turn the tangent the other way (clockwise along increasing polar angle).
    pub fn from_axial_of(
        axial: Vec<AxialPiece>,
        p: f64,
        period: f64,
        material: Material,
    ) -> Profile {
        let reversed = p > 0.0;
        let mut ordered = axial;
        if reversed {
            ordered.reverse();
        }
        let smooth: Vec<Piece> = ordered
            .into_iter()
            .map(|piece| Piece::Axial { piece, p, reversed })
            .collect();
        Profile::joined(smooth, period, material)
    }

    /// A profile from smooth pieces that follow each other in order of increasing polar angle
    /// over one period: a [`Piece::Corner`] is put at every sharp convex join (the last piece
    /// joins the first turned by the period); sharp concave joins are kept as they are and
    /// reported by [`Profile::concave_stretches`]. Convex and concave are seen from
    /// `material`'s side.
    pub fn joined(smooth: Vec<Piece>, period: f64, material: Material) -> Profile {
        let mut pieces = Vec::with_capacity(smooth.len() * 2);
        let n = smooth.len();
        for (i, piece) in smooth.iter().enumerate() {
            pieces.push(piece.clone());
            let (end, d_out, _) = piece.eval(piece.length());
            let next = &smooth[(i + 1) % n];
            let (_, mut d_in, _) = next.eval(0.0);
            if i + 1 == n {
                d_in = DVec2::from_angle(period).rotate(d_in);
            }
            let turn = turning(d_out, d_in);
            if turn * material.sign() > 1e-9 {
                let from = d_out.to_angle();
                pieces.push(Piece::Corner {
                    at: end,
                    from,
                    to: from + turn,
                });
            }
        }
        Profile::new(pieces, period).with_material(material)
    }

    /// Polar period `2π / starts`, radians.
    pub fn period(&self) -> f64 {
        self.period
    }

    /// Total parameter length of one period.
    pub fn length(&self) -> f64 {
        self.offsets.last().copied().unwrap_or(0.0)
    }

    /// Parameters where pieces join: the natural places to put samples.
    pub fn breaks(&self) -> &[f64] {
        &self.offsets
    }

    fn locate(&self, u: f64) -> (usize, f64) {
        let u = u.clamp(0.0, self.length());
        let i = self
            .offsets
            .partition_point(|&o| o <= u)
            .saturating_sub(1)
            .min(self.pieces.len() - 1);
        (i, u - self.offsets[i])
    }

    /// Position, first and second derivative at `u`.
    pub fn derivatives(&self, u: f64) -> (DVec2, DVec2, DVec2) {
        let (i, s) = self.locate(u);
        self.pieces[i].eval(s)
    }

    /// The profile point at parameter `u` (clamped to one period).
    pub fn point(&self, u: f64) -> ProfilePoint {
        let (pos, d1, _) = self.derivatives(u);
        ProfilePoint {
            u,
            pos,
            tangent: d1.normalize(),
        }
    }

    /// Smallest and largest radius from the screw axis over the period.
    pub fn radius_range(&self) -> (f64, f64) {
        let n = 2000;
        (0..=n)
            .map(|i| self.point(self.length() * i as f64 / n as f64).pos.length())
            .fold((f64::INFINITY, 0.0), |(lo, hi), r| (lo.min(r), hi.max(r)))
    }

    /// Concave stretches tighter than a nose of radius `nose`, judged by the helical surface's
    /// normal curvature across the groove (perpendicular to the helix through the point): that
    /// is the direction in which the nose has to fit into the groove.
    ///
    /// The depth left is that of a nose tangent to both sides of an arc of the stretch's
    /// smallest radius `ρ` spanning the stretch's turning angle `θ`: `(r − ρ)(1/cos(θ/2) − 1)`;
    /// infinite from `θ ≥ π` on, where the nose cannot enter at all.
    pub fn concave_stretches(&self, p: f64, nose: f64) -> Vec<ConcaveStretch> {
        let mut found = Vec::new();
        // Stretch, turning angle.
        let mut current: Option<(ConcaveStretch, f64)> = None;
        let mut close = |current: &mut Option<(ConcaveStretch, f64)>| {
            if let Some((mut stretch, turn)) = current.take() {
                stretch.depth_left = if turn >= PI {
                    f64::INFINITY
                } else {
                    (nose - stretch.min_radius) * (1.0 / (turn / 2.0).cos() - 1.0)
                };
                found.push(stretch);
            }
        };
        for (u, du) in self.sample_cells() {
            let (i_piece, _) = self.locate(u);
            let (kappa, width) = match &self.pieces[i_piece] {
                Piece::Corner { .. } => (-1.0, 0.0), // convex: never concave
                _ => self.cross_curvature(u, p),
            };
            if kappa > 1.0 / nose {
                let at = self.point(u).pos;
                let entry = current.get_or_insert((
                    ConcaveStretch {
                        at,
                        min_radius: f64::INFINITY,
                        depth_left: 0.0,
                    },
                    0.0,
                ));
                if 1.0 / kappa < entry.0.min_radius {
                    entry.0.min_radius = 1.0 / kappa;
                    entry.0.at = at;
                }
                entry.1 += kappa * width * du;
            } else {
                close(&mut current);
            }
        }
        close(&mut current);
        // Sharp concave joins between smooth pieces.
        for (i, piece) in self.pieces.iter().enumerate() {
            let Some(next) = self.pieces.get(i + 1) else {
                break;
            };
            if matches!(piece, Piece::Corner { .. }) || matches!(next, Piece::Corner { .. }) {
                continue;
            }
            let (end, d_out, _) = piece.eval(piece.length());
            let (_, d_in, _) = next.eval(0.0);
            let turn = turning(d_out, d_in) * self.material.sign();
            if turn < -1e-9 {
                let n_out = self.normal3(end, d_out, p);
                let n_in = self.normal3(end, d_in, p);
                let turn3 = n_out.angle_between(n_in);
                found.push(ConcaveStretch {
                    at: end,
                    min_radius: 0.0,
                    depth_left: if turn3 >= PI {
                        f64::INFINITY
                    } else {
                        nose * (1.0 / (turn3 / 2.0).cos() - 1.0)
                    },
                });
            }
        }
        found
    }

    /// The cells the concave check samples, as (middle, width), in order: 4000 equal cells over
    /// the period, split further at the knots and mid-spans of spline pieces. Every knot span
    /// (a separate cubic) thus has two samples of its own however dense or uneven the points,
    /// so no stretch of a dense spline hides between samples and none has its turning summed
    /// from too few.
    fn sample_cells(&self) -> Vec<(f64, f64)> {
        const GRID: usize = 4000;
        let length = self.length();
        let mut cuts: Vec<f64> = (0..=GRID)
            .map(|k| length * k as f64 / GRID as f64)
            .collect();
        for (piece, offset) in self.pieces.iter().zip(&self.offsets) {
            if let Piece::Spline(spline) = piece {
                for span in spline.knots().windows(2) {
                    cuts.push(offset + span[0]);
                    cuts.push(offset + (span[0] + span[1]) / 2.0);
                }
            }
            if let Piece::Nurbs { table, .. } = piece {
                // The table's rows: eight to a knot span.
                cuts.extend(table.iter().step_by(4).map(|&(_, s)| offset + s));
            }
        }
        cuts.sort_by(f64::total_cmp);
        cuts.windows(2)
            .filter(|w| w[1] > w[0])
            .map(|w| ((w[0] + w[1]) / 2.0, w[1] - w[0]))
            .collect()
    }

    fn normal3(&self, pos: DVec2, tangent: DVec2, p: f64) -> DVec3 {
        self.material.normal(pos, tangent, p)
    }

    /// Normal curvature of the helical surface at `(u, θ = 0)` across the groove (positive where
    /// the surface is concave, i.e. bends towards its outward normal), and the length of that
    /// cross direction per unit of `u`.
    fn cross_curvature(&self, u: f64, p: f64) -> (f64, f64) {
        use glam::DVec3;
        let (pos, d1, d2) = self.derivatives(u);
        let n = self.material.normal(pos, d1, p);
        let su = DVec3::new(d1.x, d1.y, 0.0);
        let st = DVec3::new(-pos.y, pos.x, p);
        let suu = DVec3::new(d2.x, d2.y, 0.0);
        let sut = DVec3::new(-d1.y, d1.x, 0.0);
        let stt = DVec3::new(-pos.x, -pos.y, 0.0);
        let (e, f, g) = (su.dot(su), su.dot(st), st.dot(st));
        let (l, m, nn) = (suu.dot(n), sut.dot(n), stt.dot(n));
        let dt = -f / g; // (du, dθ) = (1, −F/G) is perpendicular to the helix
        let first = e + 2.0 * f * dt + g * dt * dt;
        let second = l + 2.0 * m * dt + nn * dt * dt;
        (second / first, first.sqrt())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    /// An axial section of one pitch `pitch`: a flat crest and a semicircular-ish root arc,
    /// convex-cornered where they meet.
    fn arc_groove(pitch: f64, outer: f64, radius: f64) -> Vec<AxialPiece> {
        let centre = DVec2::new(outer, 0.0);
        let reach = radius; // arc meets the outer radius at z = ±radius
        vec![
            AxialPiece::Line {
                from: DVec2::new(outer, -pitch / 2.0),
                to: DVec2::new(outer, -reach),
            },
            AxialPiece::Arc {
                centre,
                radius,
                start: 1.5 * PI,
                end: 0.5 * PI,
            },
            AxialPiece::Line {
                from: DVec2::new(outer, reach),
                to: DVec2::new(outer, pitch / 2.0),
            },
        ]
    }

    #[test]
    fn axial_profile_covers_one_period_with_polar_angle_increasing() {
        for p in [8.0, -8.0] {
            let period = TAU / 2.0;
            let pitch = period * f64::abs(p);
            let prof = Profile::from_axial(arc_groove(pitch, 20.0, 3.0), p, period);
            let first = prof.point(0.0).pos;
            let last = prof.point(prof.length()).pos;
            let turned = DVec2::from_angle(period).rotate(first);
            assert!((last - turned).length() < 1e-9, "closes by the period turn");
            let mut prev = first.to_angle();
            for i in 1..=500 {
                let q = prof.point(prof.length() * i as f64 / 500.0);
                let mut a = q.pos.to_angle();
                while a < prev - PI {
                    a += TAU;
                }
                assert!(a >= prev - 1e-12, "polar angle must not decrease");
                prev = a;
                // The transverse point at radius ρ and angle −z/p lies on the axial section.
                let z = -a * p;
                let rho = q.pos.length();
                let zz = ((z + pitch / 2.0).rem_euclid(pitch)) - pitch / 2.0;
                let expected = if zz.abs() >= 3.0 {
                    20.0
                } else {
                    20.0 - (9.0 - zz * zz).sqrt()
                };
                assert!(
                    (rho - expected).abs() < 1e-9,
                    "ρ {rho} vs {expected} at z {zz}"
                );
            }
        }
    }

    /// The quarter circle of radius 2 about `centre` from angle 90° to 180°, as a rational
    /// quadratic NURBS.
    fn quarter(centre: DVec2) -> Nurbs {
        Nurbs::new(
            2,
            vec![0.0, 0.0, 0.0, 1.0, 1.0, 1.0],
            vec![
                centre + DVec2::new(0.0, 2.0),
                centre + DVec2::new(-2.0, 2.0),
                centre + DVec2::new(-2.0, 0.0),
            ],
            vec![1.0, std::f64::consts::FRAC_1_SQRT_2, 1.0],
        )
        .unwrap()
    }

    #[test]
    fn a_nurbs_piece_runs_at_unit_speed_with_the_curvature_of_its_curve() {
        let piece = Piece::nurbs(quarter(DVec2::new(5.0, 1.0)), None);
        assert!((piece.length() - PI).abs() < 1e-9, "a quarter of 2π·2");
        for k in 0..=50 {
            let (pos, d1, d2) = piece.eval(piece.length() * k as f64 / 50.0);
            let radial = (pos - DVec2::new(5.0, 1.0)) / 2.0;
            assert!((radial.length() - 1.0).abs() < 1e-12, "on the circle");
            assert!(
                (d1.length() - 1.0).abs() < 1e-9,
                "unit speed: {}",
                d1.length()
            );
            assert!((d2 + radial / 2.0).length() < 1e-8, "d² = −n/r: {d2}");
        }
    }

    #[test]
    fn an_axial_nurbs_piece_is_seen_as_the_same_axial_arc() {
        let p = 7.0 / TAU;
        let nurbs = Piece::nurbs(quarter(DVec2::new(20.0, 0.0)), Some(p));
        let arc = Piece::Axial {
            piece: AxialPiece::Arc {
                centre: DVec2::new(20.0, 0.0),
                radius: 2.0,
                start: 0.5 * PI,
                end: PI,
            },
            p,
            reversed: false,
        };
        assert!((nurbs.length() - arc.length()).abs() < 1e-9);
        for k in 0..=50 {
            let s = arc.length() * k as f64 / 50.0;
            let (a, b) = (nurbs.eval(s), arc.eval(s));
            assert!((a.0 - b.0).length() < 1e-9, "{s}: {:?} vs {:?}", a.0, b.0);
            assert!((a.1 - b.1).length() < 1e-8, "{s}: {:?} vs {:?}", a.1, b.1);
            assert!((a.2 - b.2).length() < 1e-6, "{s}: {:?} vs {:?}", a.2, b.2);
        }
    }

    #[test]
    fn crest_edges_become_convex_corners() {
        let prof = Profile::from_axial(arc_groove(20.0, 20.0, 3.0), 10.0 / PI, PI);
        let corners = prof
            .pieces
            .iter()
            .filter(|p| matches!(p, Piece::Corner { .. }))
            .count();
        assert_eq!(corners, 2, "both crest edges of the groove");
        assert!(prof.concave_stretches(10.0 / PI, 1.0).is_empty());
    }

    #[test]
    fn a_nuts_tangent_fillet_joins_make_no_corner() {
        // ISO 2904 Tr 40x7 nut with root fillets tangent to flanks and root flat: its only
        // sharp edges are the two bore edges, convex with the material outside, so the
        // tangent turns clockwise there (the screw's turn counter-clockwise).
        use standard::{IsoTrapezoidal, StandardProfile};
        for fillet in [0.5, 0.6, 0.7, 0.9] {
            let screw = StandardProfile::IsoTrapezoidal(
                IsoTrapezoidal::new(40.0, Some(fillet), None).unwrap(),
            );
            let p = 7.0 / TAU;
            let pieces = screw.internal_pieces(7.0).unwrap();
            let prof = Profile::from_axial_of(pieces, p, TAU, Material::Outside);
            let corners: Vec<(f64, f64)> = prof
                .pieces
                .iter()
                .filter_map(|p| match *p {
                    Piece::Corner { from, to, .. } => Some((from, to)),
                    _ => None,
                })
                .collect();
            assert_eq!(corners.len(), 2, "fillet {fillet}: {corners:?}");
            assert!(corners.iter().all(|(from, to)| to < from), "{corners:?}");
            assert!(prof.concave_stretches(p, 0.4).is_empty(), "fillet {fillet}");
            // A nose of 0.6 mm does not fit a 0.5 mm fillet.
            if fillet == 0.5 {
                assert!(!prof.concave_stretches(p, 0.6).is_empty());
            }
        }
    }

    #[test]
    fn a_root_arc_tighter_than_the_nose_is_reported() {
        let p = 10.0 / PI;
        let prof = Profile::from_axial(arc_groove(20.0, 20.0, 3.0), p, PI);
        let found = prof.concave_stretches(p, 4.0);
        assert_eq!(found.len(), 1, "{found:?}");
        // The groove is a half circle of radius 3: its normal section across the groove is
        // close to the axial one, so the radius is close to 3, and a bigger nose cannot enter.
        assert!((found[0].min_radius - 3.0).abs() < 0.2, "{found:?}");
        assert!(found[0].depth_left > 0.0);
    }

    #[test]
    fn the_concave_check_samples_every_knot_span_of_a_dense_uneven_spline() {
        // A circle of radius 30 over half a turn: 50 points, and 20 000 more packed into 0.1°
        // (0.05 mm of arc, knot spans of 2.6 nm, against cells of 4000 over 94 mm: 23 µm).
        let mut phis: Vec<f64> = (0..50).map(|k| PI * k as f64 / 50.0).collect();
        phis.extend((1..=20_000).map(|k| 0.1f64.to_radians() * k as f64 / 20_001.0 + 0.5));
        phis.sort_by(f64::total_cmp);
        let rows: Vec<points::Row> = phis
            .iter()
            .enumerate()
            .map(|(i, phi)| points::Row {
                line: i + 1,
                a: 30.0 * phi.cos(),
                b: 30.0 * phi.sin(),
            })
            .collect();
        let prof = points::profile(&rows, points::Section::Transverse, false, 10.0, 2).unwrap();
        let Piece::Spline(spline) = &prof.pieces[0] else {
            panic!("a profile from points is one spline");
        };
        let cells = prof.sample_cells();
        let total: f64 = cells.iter().map(|&(_, width)| width).sum();
        assert!(
            (total - prof.length()).abs() < 1e-9,
            "the cells cover the period"
        );
        let mut middles = cells.iter().map(|&(u, _)| u).peekable();
        for span in spline.knots().windows(2) {
            let mut inside = 0;
            while middles.next_if(|&u| u < span[1]).is_some() {
                inside += 1;
            }
            assert!(inside >= 2, "{inside} samples in the knot span {span:?}");
        }
    }
}
