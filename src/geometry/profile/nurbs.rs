//! Non-uniform rational B-spline curves in a plane, as CAD drawings carry them (a DXF
//! `SPLINE`: degree, knot vector, control points, weights).
//!
//! The profile keeps a drawn spline as the curve it is, not as samples: [`Nurbs::eval`] gives
//! the exact position and first and second derivatives, the derivatives of the rational curve
//! `C = A / W` (with `A = Σ Nᵢ wᵢ Pᵢ`, `W = Σ Nᵢ wᵢ`) from those of its numerator and
//! denominator: `C′ = (A′ − W′C) / W`, `C″ = (A″ − 2W′C′ − W″C) / W`. The B-spline basis and
//! its derivatives follow Cox–de Boor's recursion (Piegl and Tiller, *The NURBS Book*, §2.2
//! and §2.3).

use glam::DVec2;

/// A planar NURBS curve over its valid parameter range `[knots[degree], knots[n]]`, where `n`
/// is the number of control points.
#[derive(Debug, Clone, PartialEq)]
pub struct Nurbs {
    degree: usize,
    knots: Vec<f64>,
    points: Vec<DVec2>,
    weights: Vec<f64>,
}

/// Why a curve's data do not make a NURBS curve.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum NurbsError {
    /// Degree zero, or too few control points for the degree.
    #[error("degree {degree} with {points} control points (a curve needs degree ≥ 1 and more control points than its degree)")]
    Degree {
        /// The degree.
        degree: usize,
        /// The number of control points.
        points: usize,
    },
    /// The knot vector's length is not control points + degree + 1.
    #[error("{knots} knots for {points} control points of degree {degree}: a NURBS has control points + degree + 1 knots")]
    KnotCount {
        /// Knots given.
        knots: usize,
        /// Control points.
        points: usize,
        /// Degree.
        degree: usize,
    },
    /// Knots that decrease, are not finite, or leave an empty parameter range.
    #[error("the knots must be finite, never decrease and span a range: {0}")]
    Knots(String),
    /// A weight that is not a finite number above zero, or a weight count that is wrong.
    #[error("weights must be one finite positive number per control point: {0}")]
    Weights(String),
    /// A control point that is not finite.
    #[error("control point {index} is not finite")]
    Point {
        /// Its index, from 0.
        index: usize,
    },
}

impl Nurbs {
    /// A curve from its degree, knots, control points and weights (empty weights: all 1, a
    /// plain B-spline), checked.
    pub fn new(
        degree: usize,
        knots: Vec<f64>,
        points: Vec<DVec2>,
        weights: Vec<f64>,
    ) -> Result<Nurbs, NurbsError> {
        if degree == 0 || points.len() <= degree {
            return Err(NurbsError::Degree {
                degree,
                points: points.len(),
            });
        }
        if knots.len() != points.len() + degree + 1 {
            return Err(NurbsError::KnotCount {
                knots: knots.len(),
                points: points.len(),
                degree,
            });
        }
        if let Some(i) = knots.iter().position(|k| !k.is_finite()) {
            return Err(NurbsError::Knots(format!("knot {i} is {}", knots[i])));
        }
        if let Some(i) = knots.windows(2).position(|w| w[1] < w[0]) {
            return Err(NurbsError::Knots(format!(
                "knot {} ({}) is below knot {i} ({})",
                i + 1,
                knots[i + 1],
                knots[i]
            )));
        }
        if knots[points.len()] <= knots[degree] {
            return Err(NurbsError::Knots(
                "the valid parameter range is empty".into(),
            ));
        }
        if let Some(index) = points.iter().position(|p| !p.is_finite()) {
            return Err(NurbsError::Point { index });
        }
        let weights = if weights.is_empty() {
            vec![1.0; points.len()]
        } else {
            weights
        };
        if weights.len() != points.len() {
            return Err(NurbsError::Weights(format!(
                "{} weights for {} control points",
                weights.len(),
                points.len()
            )));
        }
        if let Some(i) = weights.iter().position(|w| !(w.is_finite() && *w > 0.0)) {
            return Err(NurbsError::Weights(format!("weight {i} is {}", weights[i])));
        }
        Ok(Nurbs {
            degree,
            knots,
            points,
            weights,
        })
    }

    /// The valid parameter range.
    pub fn domain(&self) -> (f64, f64) {
        (self.knots[self.degree], self.knots[self.points.len()])
    }

    /// The same curve traversed the other way: knots mirrored, control points and weights
    /// reversed (exact; the parameter runs over the same range).
    pub fn reversed(&self) -> Nurbs {
        let (a, b) = (self.knots[0], self.knots[self.knots.len() - 1]);
        Nurbs {
            degree: self.degree,
            knots: self.knots.iter().rev().map(|k| a + b - k).collect(),
            points: self.points.iter().rev().copied().collect(),
            weights: self.weights.iter().rev().copied().collect(),
        }
    }

    /// The same curve with every control point mapped by `f` (an affine map, such as a change
    /// of units, maps a NURBS exactly).
    pub fn map(&self, f: impl Fn(DVec2) -> DVec2) -> Nurbs {
        Nurbs {
            points: self.points.iter().map(|&p| f(p)).collect(),
            ..self.clone()
        }
    }

    /// Start and end points.
    pub fn ends(&self) -> (DVec2, DVec2) {
        let (a, b) = self.domain();
        (self.eval(a).0, self.eval(b).0)
    }

    /// The knot span `i` with `knots[i] ≤ t < knots[i + 1]` inside the valid range (the last
    /// non-empty span for `t` at its end).
    fn span(&self, t: f64) -> usize {
        let n = self.points.len();
        if t >= self.knots[n] {
            let mut i = n - 1;
            while self.knots[i] >= self.knots[n] {
                i -= 1;
            }
            return i;
        }
        let i = self.knots.partition_point(|&k| k <= t).saturating_sub(1);
        i.clamp(self.degree, n - 1)
    }

    /// The `degree + 1` non-zero basis functions at `t` in span `i`, with their first and
    /// second derivatives (Piegl and Tiller's algorithm A2.3, written for derivatives up to 2).
    fn basis(&self, i: usize, t: f64) -> [Vec<f64>; 3] {
        let p = self.degree;
        let u = &self.knots;
        // ndu[j][r]: basis values (on and below the diagonal) and knot differences (above).
        let mut ndu = vec![vec![0.0; p + 1]; p + 1];
        let mut left = vec![0.0; p + 1];
        let mut right = vec![0.0; p + 1];
        ndu[0][0] = 1.0;
        for j in 1..=p {
            left[j] = t - u[i + 1 - j];
            right[j] = u[i + j] - t;
            let mut saved = 0.0;
            for r in 0..j {
                ndu[j][r] = right[r + 1] + left[j - r];
                let temp = ndu[r][j - 1] / ndu[j][r];
                ndu[r][j] = saved + right[r + 1] * temp;
                saved = left[j - r] * temp;
            }
            ndu[j][j] = saved;
        }
        let nd = 2.min(p);
        let mut ders = [vec![0.0; p + 1], vec![0.0; p + 1], vec![0.0; p + 1]];
        for (j, value) in ders[0].iter_mut().enumerate() {
            *value = ndu[j][p];
        }
        for r in 0..=p {
            let (mut s1, mut s2) = (0usize, 1usize);
            let mut a = [vec![0.0; p + 1], vec![0.0; p + 1]];
            a[0][0] = 1.0;
            for k in 1..=nd {
                let mut d = 0.0;
                let rk = r as isize - k as isize;
                let pk = p - k;
                if r >= k {
                    a[s2][0] = a[s1][0] / ndu[pk + 1][rk as usize];
                    d = a[s2][0] * ndu[rk as usize][pk];
                }
                let j1 = if rk >= -1 { 1 } else { (-rk) as usize };
                let j2 = if r as isize - 1 <= pk as isize {
                    k - 1
                } else {
                    p - r
                };
                for j in j1..=j2 {
                    let idx = (rk + j as isize) as usize;
                    a[s2][j] = (a[s1][j] - a[s1][j - 1]) / ndu[pk + 1][idx];
                    d += a[s2][j] * ndu[idx][pk];
                }
                if r <= pk {
                    a[s2][k] = -a[s1][k - 1] / ndu[pk + 1][r];
                    d += a[s2][k] * ndu[r][pk];
                }
                ders[k][r] = d;
                std::mem::swap(&mut s1, &mut s2);
            }
        }
        // The k-th derivatives carry the factor p!/(p − k)!.
        let mut factor = p as f64;
        for (k, row) in ders.iter_mut().enumerate().take(nd + 1).skip(1) {
            for value in row.iter_mut() {
                *value *= factor;
            }
            factor *= (p - k) as f64;
        }
        ders
    }

    /// Position, first and second derivative with respect to the knot parameter at `t`
    /// (clamped to the valid range).
    pub fn eval(&self, t: f64) -> (DVec2, DVec2, DVec2) {
        let (a, b) = self.domain();
        let t = t.max(a).min(b);
        let i = self.span(t);
        let ders = self.basis(i, t);
        let mut num = [DVec2::ZERO; 3];
        let mut den = [0.0; 3];
        for j in 0..=self.degree {
            let k = i - self.degree + j;
            let (w, pt) = (self.weights[k], self.points[k]);
            for (d, row) in ders.iter().enumerate() {
                num[d] += row[j] * w * pt;
                den[d] += row[j] * w;
            }
        }
        let c = num[0] / den[0];
        let c1 = (num[1] - den[1] * c) / den[0];
        let c2 = (num[2] - 2.0 * den[1] * c1 - den[2] * c) / den[0];
        (c, c1, c2)
    }

    /// The curve's length to about 10⁻⁹ of itself.
    pub fn length(&self) -> f64 {
        self.arc_table().last().map_or(0.0, |&(_, s)| s)
    }

    /// The arc length from `a` to `b` (within one knot span, where the curve is smooth):
    /// five-point Gauss–Legendre quadrature of the speed.
    fn arc(&self, a: f64, b: f64) -> f64 {
        const NODES: [(f64, f64); 5] = [
            (0.0, 0.568_888_888_888_888_9),
            (-0.538_469_310_105_683_1, 0.478_628_670_499_366_5),
            (0.538_469_310_105_683_1, 0.478_628_670_499_366_5),
            (-0.906_179_845_938_664, 0.236_926_885_056_189_08),
            (0.906_179_845_938_664, 0.236_926_885_056_189_08),
        ];
        let (mid, half) = ((a + b) / 2.0, (b - a) / 2.0);
        NODES
            .iter()
            .map(|(x, w)| w * half * self.eval(mid + x * half).1.length())
            .sum()
    }

    /// The arc length along the curve at the bounds of eight equal parts of every knot span:
    /// `(t, s)` pairs from `(start, 0)` to `(end, length)`, for [`Nurbs::at_length`].
    pub fn arc_table(&self) -> Vec<(f64, f64)> {
        const PARTS: usize = 8;
        let breaks = self.breaks();
        let mut table = vec![(breaks[0], 0.0)];
        let mut s = 0.0;
        for w in breaks.windows(2) {
            let h = (w[1] - w[0]) / PARTS as f64;
            for k in 0..PARTS {
                let (a, b) = (w[0] + h * k as f64, w[0] + h * (k + 1) as f64);
                s += self.arc(a, b);
                table.push((if k + 1 == PARTS { w[1] } else { b }, s));
            }
        }
        table
    }

    /// The parameter at arc length `s` from the start, by Newton's method from the table's
    /// interpolation (`table` from [`Nurbs::arc_table`]).
    pub fn at_length(&self, table: &[(f64, f64)], s: f64) -> f64 {
        let i = table
            .partition_point(|&(_, si)| si <= s)
            .clamp(1, table.len() - 1);
        let ((t0, s0), (t1, s1)) = (table[i - 1], table[i]);
        if s1 <= s0 {
            return t0;
        }
        let mut t = t0 + (t1 - t0) * ((s - s0) / (s1 - s0)).clamp(0.0, 1.0);
        for _ in 0..8 {
            let speed = self.eval(t).1.length();
            if speed <= 0.0 {
                break;
            }
            let step = (self.arc(t0, t) - (s - s0)) / speed;
            t = (t - step).clamp(t0, t1);
            if step.abs() <= 1e-14 * (t1 - t0).abs().max(1e-300) {
                break;
            }
        }
        t
    }

    /// The box of the control points, which holds the curve (its convex-hull property).
    pub fn bounds(&self) -> (DVec2, DVec2) {
        self.points.iter().fold(
            (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
            |(lo, hi), &p| (lo.min(p), hi.max(p)),
        )
    }

    /// The parameters that bound the knot spans inside the valid range, in order.
    pub fn breaks(&self) -> Vec<f64> {
        let (a, b) = self.domain();
        let mut out: Vec<f64> = self
            .knots
            .iter()
            .copied()
            .filter(|&k| k >= a && k <= b)
            .collect();
        out.dedup();
        out
    }
}

/// The cubic through `points` (at least two), as a CAD program draws a spline given by fit
/// points: chord-length parameters ū normalised to [0, 1], those parameters as the inner
/// knots, and the curve's derivatives at its ends given (Piegl and Tiller, *The NURBS Book*,
/// §9.2.2–9.2.3). An end's derivative is its unit tangent times the total chord length, where
/// the drawing gives a tangent, else that of the parabola through the first (last) three
/// points (a straight line through two).
pub fn interpolate(
    points: &[DVec2],
    start: Option<DVec2>,
    end: Option<DVec2>,
) -> Result<Nurbs, NurbsError> {
    let n = points.len();
    if n < 2 {
        return Err(NurbsError::Degree {
            degree: 3,
            points: n,
        });
    }
    let chords: Vec<f64> = points.windows(2).map(|w| w[0].distance(w[1])).collect();
    let total: f64 = chords.iter().sum();
    if let Some(index) = points.iter().position(|p| !p.is_finite()) {
        return Err(NurbsError::Point { index });
    }
    if let Some(i) = chords.iter().position(|&c| c <= 0.0) {
        return Err(NurbsError::Knots(format!(
            "fit points {i} and {} coincide",
            i + 1
        )));
    }
    let mut u = vec![0.0];
    for c in &chords {
        u.push(u.last().copied().unwrap_or(0.0) + c / total);
    }
    u[n - 1] = 1.0;
    let parabola = |i: [usize; 3], at: usize| {
        let (u0, u1, u2) = (u[i[0]], u[i[1]], u[i[2]]);
        let (q0, q1, q2) = (points[i[0]], points[i[1]], points[i[2]]);
        // Derivative at u[at] of the Lagrange parabola through the three points.
        let x = u[at];
        q0 * ((2.0 * x - u1 - u2) / ((u0 - u1) * (u0 - u2)))
            + q1 * ((2.0 * x - u0 - u2) / ((u1 - u0) * (u1 - u2)))
            + q2 * ((2.0 * x - u0 - u1) / ((u2 - u0) * (u2 - u1)))
    };
    let d0 = match start {
        Some(t) => t * total,
        None if n >= 3 => parabola([0, 1, 2], 0),
        None => points[1] - points[0],
    };
    let dn = match end {
        Some(t) => t * total,
        None if n >= 3 => parabola([n - 3, n - 2, n - 1], n - 1),
        None => points[n - 1] - points[n - 2],
    };
    let mut knots = vec![0.0; 4];
    knots.extend_from_slice(&u[1..n - 1]);
    knots.extend_from_slice(&[1.0; 4]);
    let m = n + 2; // control points
                   // The collocation rows are banded (a cubic's point involves four control points), and
                   // B-spline collocation matrices need no pivoting (de Boor): elimination within the band.
    let width = 4;
    let mut rows: Vec<(usize, Vec<f64>, DVec2)> = Vec::with_capacity(m);
    rows.push((0, vec![1.0], points[0]));
    rows.push((0, vec![-1.0, 1.0], d0 * (knots[4] / 3.0)));
    let shape = Nurbs {
        degree: 3,
        knots: knots.clone(),
        points: vec![DVec2::ZERO; m],
        weights: vec![1.0; m],
    };
    for (k, &uk) in u.iter().enumerate().take(n - 1).skip(1) {
        let span = shape.span(uk);
        rows.push((span - 3, shape.basis(span, uk)[0].clone(), points[k]));
    }
    rows.push((m - 2, vec![-1.0, 1.0], dn * ((1.0 - knots[m - 1]) / 3.0)));
    rows.push((m - 1, vec![1.0], points[n - 1]));
    // Dense band storage: row i holds columns i − width … i + width.
    let mut band = vec![vec![0.0; 2 * width + 1]; m];
    let mut rhs: Vec<DVec2> = Vec::with_capacity(m);
    for (i, (first, values, b)) in rows.into_iter().enumerate() {
        for (j, v) in values.into_iter().enumerate() {
            band[i][first + j + width - i] = v;
        }
        rhs.push(b);
    }
    for i in 0..m {
        let pivot = band[i][width];
        if pivot.abs() < 1e-300 {
            return Err(NurbsError::Knots(
                "the fit points give a singular system".into(),
            ));
        }
        for r in i + 1..(i + width + 1).min(m) {
            let factor = band[r][i + width - r] / pivot;
            if factor == 0.0 {
                continue;
            }
            for c in i..(i + width + 1).min(m) {
                band[r][c + width - r] -= factor * band[i][c + width - i];
            }
            let bi = rhs[i];
            rhs[r] -= factor * bi;
        }
    }
    let mut control = vec![DVec2::ZERO; m];
    for i in (0..m).rev() {
        let mut acc = rhs[i];
        for c in i + 1..(i + width + 1).min(m) {
            acc -= band[i][c + width - i] * control[c];
        }
        control[i] = acc / band[i][width];
    }
    Nurbs::new(3, knots, control, vec![])
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::{FRAC_1_SQRT_2, PI};

    /// A quarter circle of radius 2 about the origin as the rational quadratic every CAD
    /// system writes: control points (2,0), (2,2), (0,2), weights 1, 1/√2, 1.
    fn quarter() -> Nurbs {
        Nurbs::new(
            2,
            vec![0.0, 0.0, 0.0, 1.0, 1.0, 1.0],
            vec![
                DVec2::new(2.0, 0.0),
                DVec2::new(2.0, 2.0),
                DVec2::new(0.0, 2.0),
            ],
            vec![1.0, FRAC_1_SQRT_2, 1.0],
        )
        .unwrap()
    }

    #[test]
    fn a_rational_quadratic_quarter_is_a_circle_with_its_curvature() {
        let q = quarter();
        for k in 0..=20 {
            let t = k as f64 / 20.0;
            let (c, d1, d2) = q.eval(t);
            assert!((c.length() - 2.0).abs() < 1e-14, "on the circle at {t}");
            assert!(c.dot(d1).abs() < 1e-12, "tangent ⟂ radius at {t}");
            // Curvature of a circle of radius 2: |c′ × c″| / |c′|³ = 1/2.
            let kappa = d1.perp_dot(d2) / d1.length().powi(3);
            assert!((kappa - 0.5).abs() < 1e-12, "κ {kappa} at {t}");
        }
        assert!((q.length() - PI).abs() < 1e-12, "a quarter of 2π·2");
    }

    #[test]
    fn derivatives_agree_with_differences_of_positions() {
        // A cubic with inner knots and uneven weights.
        let c = Nurbs::new(
            3,
            vec![0.0, 0.0, 0.0, 0.0, 0.4, 1.1, 2.0, 2.0, 2.0, 2.0],
            vec![
                DVec2::new(0.0, 0.0),
                DVec2::new(1.0, 2.0),
                DVec2::new(3.0, 2.5),
                DVec2::new(4.0, -1.0),
                DVec2::new(6.0, 0.5),
                DVec2::new(7.0, 3.0),
            ],
            vec![1.0, 0.7, 1.6, 1.0, 0.9, 1.2],
        )
        .unwrap();
        let h = 1e-5;
        for k in 1..40 {
            let t = 2.0 * k as f64 / 40.0;
            let (p0, d1, d2) = c.eval(t);
            let (pm, _, _) = c.eval(t - h);
            let (pp, _, _) = c.eval(t + h);
            assert!((d1 - (pp - pm) / (2.0 * h)).length() < 1e-6 * (1.0 + d1.length()));
            let second = (pp - 2.0 * p0 + pm) / (h * h);
            assert!((d2 - second).length() < 1e-3 * (1.0 + d2.length()), "{t}");
        }
    }

    #[test]
    fn a_reversed_curve_runs_through_the_same_points_backwards() {
        let q = quarter();
        let r = q.reversed();
        for k in 0..=10 {
            let t = k as f64 / 10.0;
            let (a, da, dda) = q.eval(t);
            let (b, db, ddb) = r.eval(1.0 - t);
            assert!((a - b).length() < 1e-14);
            assert!((da + db).length() < 1e-12);
            assert!((dda - ddb).length() < 1e-12);
        }
    }

    #[test]
    fn malformed_curves_are_refused() {
        let pts = vec![DVec2::ZERO, DVec2::X, DVec2::Y];
        assert!(matches!(
            Nurbs::new(0, vec![0.0, 1.0, 2.0, 3.0], pts.clone(), vec![]),
            Err(NurbsError::Degree { .. })
        ));
        assert!(matches!(
            Nurbs::new(2, vec![0.0, 0.0, 1.0, 1.0], pts.clone(), vec![]),
            Err(NurbsError::KnotCount { .. })
        ));
        assert!(matches!(
            Nurbs::new(2, vec![0.0, 0.0, 0.0, 1.0, 0.5, 1.0], pts.clone(), vec![]),
            Err(NurbsError::Knots(_))
        ));
        assert!(matches!(
            Nurbs::new(
                2,
                vec![0.0, 0.0, 0.0, 1.0, 1.0, 1.0],
                pts.clone(),
                vec![1.0, 0.0, 1.0]
            ),
            Err(NurbsError::Weights(_))
        ));
        assert!(matches!(
            Nurbs::new(
                2,
                vec![0.0, 0.0, 0.0, 1.0, 1.0, 1.0],
                vec![DVec2::ZERO, DVec2::NAN, DVec2::Y],
                vec![]
            ),
            Err(NurbsError::Point { index: 1 })
        ));
    }
}
