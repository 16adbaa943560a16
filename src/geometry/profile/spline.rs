//! Cubic splines through profile points, parametric by chord length.
//!
//! Points are complex numbers `x + iy`, which turns the rotational periodicity of a groove
//! section into a scalar: a transverse profile of one period closes onto its first point turned
//! by the period angle `T`, i.e. `P[i + n] = e^{iT} · P[i]`, and so do the spline's second
//! derivatives. The spline equations have real coefficients, so the whole system stays a
//! (complex) cyclic tridiagonal one, solved exactly with Sherman–Morrison in O(n).
//!
//! End conditions: none are needed. Every groove section is periodic (axial-section points
//! are turned into transverse ones first, and half periods are mirrored into full ones), so
//! the spline is C² everywhere, across the seam between periods included.

use num_complex::Complex64;

/// A C²-continuous cubic spline, one cubic per chord, parametrised by cumulative chord length.
#[derive(Debug, Clone)]
pub struct Spline {
    /// Knot points, `n + 1` of them for `n` spans.
    points: Vec<Complex64>,
    /// Second derivatives at the knots (with respect to the chord-length parameter).
    second: Vec<Complex64>,
    /// Cumulative chord length at each knot; `knots[0] = 0`.
    knots: Vec<f64>,
}

/// Value and first two derivatives of a spline at a parameter.
#[derive(Debug, Clone, Copy)]
pub struct SplinePoint {
    /// Position.
    pub p: Complex64,
    /// First derivative with respect to the chord-length parameter.
    pub d1: Complex64,
    /// Second derivative.
    pub d2: Complex64,
}

impl Spline {
    /// The periodic spline through `points`, closing from the last point onto the first one
    /// turned by `period` radians about the origin. Needs at least 3 distinct points.
    pub fn periodic(points: &[Complex64], period: f64) -> Spline {
        let n = points.len();
        assert!(n >= 3, "a periodic spline needs at least 3 points");
        let turn = Complex64::from_polar(1.0, period);
        let h: Vec<f64> = (0..n)
            .map(|i| {
                let next = if i + 1 == n {
                    points[0] * turn
                } else {
                    points[i + 1]
                };
                (next - points[i]).norm()
            })
            .collect();
        Spline::periodic_on(points, &h, period)
    }

    /// The periodic spline through `points` at knots `h` apart (the last knot `h[n − 1]`
    /// before the first one turned by `period`), rather than at their chord lengths.
    pub(super) fn periodic_on(points: &[Complex64], h: &[f64], period: f64) -> Spline {
        let n = points.len();
        assert!(n >= 3, "a periodic spline needs at least 3 points");
        let turn = Complex64::from_polar(1.0, period);
        let at = |i: usize| {
            if i == n {
                points[0] * turn
            } else {
                points[i]
            }
        };
        let slope: Vec<Complex64> = (0..n).map(|i| (at(i + 1) - at(i)) / h[i]).collect();
        // Row i: h[i-1] M[i-1] + 2 (h[i-1] + h[i]) M[i] + h[i] M[i+1] = 6 (slope[i] - slope[i-1]),
        // with M[-1] = M[n-1] / turn and M[n] = M[0] * turn; slope[-1] = slope[n-1] / turn.
        let prev = |i: usize| (i + n - 1) % n;
        let lower: Vec<Complex64> = (0..n).map(|i| h[prev(i)].into()).collect();
        let diag: Vec<Complex64> = (0..n).map(|i| (2.0 * (h[prev(i)] + h[i])).into()).collect();
        let upper: Vec<Complex64> = (0..n).map(|i| h[i].into()).collect();
        let rhs: Vec<Complex64> = (0..n)
            .map(|i| {
                let before = if i == 0 {
                    slope[n - 1] / turn
                } else {
                    slope[i - 1]
                };
                6.0 * (slope[i] - before)
            })
            .collect();
        // Corner coefficients of the cyclic system.
        let top_right = lower[0] / turn; // row 0, column n-1
        let bottom_left = upper[n - 1] * turn; // row n-1, column 0
        let mut second = solve_cyclic(&lower, &diag, &upper, top_right, bottom_left, &rhs);
        second.push(second[0] * turn);
        let mut pts = points.to_vec();
        pts.push(at(n));
        Spline::from_parts(pts, second, h)
    }

    /// The periodic spline with `values` at knots `h` apart and second derivatives `second`
    /// there, closing onto the first knot turned by `period` radians: a smoothing fit's
    /// ([`super::smoothing`]), whose values and second derivatives satisfy the spline's
    /// equations by construction.
    pub(super) fn periodic_with(
        values: &[Complex64],
        second: &[Complex64],
        h: &[f64],
        period: f64,
    ) -> Spline {
        let turn = Complex64::from_polar(1.0, period);
        let mut points = values.to_vec();
        points.push(values[0] * turn);
        let mut second = second.to_vec();
        second.push(second[0] * turn);
        Spline::from_parts(points, second, h)
    }

    fn from_parts(points: Vec<Complex64>, second: Vec<Complex64>, h: &[f64]) -> Spline {
        let mut knots = Vec::with_capacity(h.len() + 1);
        knots.push(0.0);
        for step in h {
            knots.push(knots.last().copied().unwrap_or(0.0) + step);
        }
        Spline {
            points,
            second,
            knots,
        }
    }

    /// Total parameter length (the sum of the chords).
    pub fn length(&self) -> f64 {
        self.knots.last().copied().unwrap_or(0.0)
    }

    /// Parameter values of the knots.
    pub fn knots(&self) -> &[f64] {
        &self.knots
    }

    /// Position and derivatives at parameter `s`, clamped to `[0, length]`.
    pub fn eval(&self, s: f64) -> SplinePoint {
        let s = s.clamp(0.0, self.length());
        let i = match self.knots.partition_point(|&k| k <= s) {
            0 => 0,
            k => (k - 1).min(self.knots.len() - 2),
        };
        let h = self.knots[i + 1] - self.knots[i];
        let (a, b) = (self.knots[i + 1] - s, s - self.knots[i]);
        let (m0, m1) = (self.second[i], self.second[i + 1]);
        let (p0, p1) = (self.points[i], self.points[i + 1]);
        let p = m0 * (a * a * a / (6.0 * h))
            + m1 * (b * b * b / (6.0 * h))
            + (p0 / h - m0 * (h / 6.0)) * a
            + (p1 / h - m1 * (h / 6.0)) * b;
        let d1 = -m0 * (a * a / (2.0 * h)) + m1 * (b * b / (2.0 * h)) + (p1 - p0) / h
            - (m1 - m0) * (h / 6.0);
        let d2 = m0 * (a / h) + m1 * (b / h);
        SplinePoint { p, d1, d2 }
    }
}

/// Thomas algorithm for a tridiagonal system (`lower[0]` and `upper[last]` are ignored).
fn solve_tridiagonal(
    lower: &[Complex64],
    diag: &[Complex64],
    upper: &[Complex64],
    rhs: &[Complex64],
) -> Vec<Complex64> {
    let n = diag.len();
    let mut c = vec![Complex64::new(0.0, 0.0); n];
    let mut d = vec![Complex64::new(0.0, 0.0); n];
    c[0] = upper[0] / diag[0];
    d[0] = rhs[0] / diag[0];
    for i in 1..n {
        let m = diag[i] - lower[i] * c[i - 1];
        c[i] = upper[i] / m;
        d[i] = (rhs[i] - lower[i] * d[i - 1]) / m;
    }
    for i in (0..n - 1).rev() {
        let next = d[i + 1];
        d[i] -= c[i] * next;
    }
    d
}

/// Cyclic tridiagonal solve by Sherman–Morrison: the corners `top_right` (row 0, last column)
/// and `bottom_left` (last row, column 0) are a rank-one update of a plain tridiagonal matrix.
fn solve_cyclic(
    lower: &[Complex64],
    diag: &[Complex64],
    upper: &[Complex64],
    top_right: Complex64,
    bottom_left: Complex64,
    rhs: &[Complex64],
) -> Vec<Complex64> {
    let n = diag.len();
    let gamma = -diag[0];
    let mut b = diag.to_vec();
    b[0] -= gamma;
    b[n - 1] -= bottom_left * top_right / gamma;
    let y = solve_tridiagonal(lower, &b, upper, rhs);
    let mut u = vec![Complex64::new(0.0, 0.0); n];
    u[0] = gamma;
    u[n - 1] = bottom_left;
    let z = solve_tridiagonal(lower, &b, upper, &u);
    let v_last = top_right / gamma;
    let factor = (y[0] + v_last * y[n - 1]) / (1.0 + z[0] + v_last * z[n - 1]);
    y.iter().zip(&z).map(|(y, z)| y - factor * z).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::{PI, TAU};

    fn circle(n: usize, radius: f64, span: f64) -> Vec<Complex64> {
        (0..n)
            .map(|i| Complex64::from_polar(radius, span * i as f64 / n as f64))
            .collect()
    }

    #[test]
    fn periodic_spline_hits_its_knots_and_closes_by_the_period_rotation() {
        let period = TAU / 3.0;
        let pts: Vec<Complex64> = (0..7)
            .map(|i| {
                let phi = period * i as f64 / 7.0;
                Complex64::from_polar(30.0 - 5.0 * (3.0 * phi).cos(), phi)
            })
            .collect();
        let s = Spline::periodic(&pts, period);
        for (k, p) in s.knots().iter().zip(&pts) {
            assert!((s.eval(*k).p - p).norm() < 1e-12);
        }
        let turn = Complex64::from_polar(1.0, period);
        let (start, end) = (s.eval(0.0), s.eval(s.length()));
        assert!((end.p - start.p * turn).norm() < 1e-12);
        assert!(
            (end.d1 - start.d1 * turn).norm() < 1e-12,
            "C1 across the seam"
        );
        assert!(
            (end.d2 - start.d2 * turn).norm() < 1e-12,
            "C2 across the seam"
        );
    }

    #[test]
    fn periodic_spline_of_a_sampled_circle_stays_on_the_circle() {
        // 24 points on a full circle of radius 10: a cubic spline deviates by O(h^4 / R^3).
        let s = Spline::periodic(&circle(24, 10.0, TAU), TAU);
        let worst = (0..1000)
            .map(|i| (s.eval(s.length() * i as f64 / 1000.0).p.norm() - 10.0).abs())
            .fold(0.0, f64::max);
        let h = 2.0 * 10.0 * (PI / 24.0).sin();
        assert!(worst < h.powi(4) / 10.0_f64.powi(3), "{worst}");
    }

    #[test]
    fn rotated_periodicity_matches_the_full_closed_spline() {
        // A three-fold symmetric curve given by one third of its points with period 2π/3
        // is the same curve as the ordinary closed spline through all the points.
        let full: Vec<Complex64> = (0..18)
            .map(|i| {
                let phi = TAU * i as f64 / 18.0;
                Complex64::from_polar(20.0 + 3.0 * (3.0 * phi).sin(), phi)
            })
            .collect();
        let closed = Spline::periodic(&full, TAU);
        let third = Spline::periodic(&full[..6], TAU / 3.0);
        for i in 0..=60 {
            let s = third.length() * i as f64 / 60.0;
            assert!((closed.eval(s).p - third.eval(s).p).norm() < 1e-10);
        }
    }
}
