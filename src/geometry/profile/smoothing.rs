//! The smoothing fit of points known only to within a band: rounded to the decimals they are
//! written to, or measured to a tolerance the job states.
//!
//! A spline through every point follows their rounding too: dense points at four decimals
//! zig-zag by a tenth of a micrometre over spacings not much longer, which bends the curve
//! far tighter than the groove and than any insert's nose. The fit here is a cubic spline
//! with knots at the points (closing as `f(u + L) = T·f(u)`, `T` the period's turn, as in
//! [`super::spline`]) whose value at each knot lies within `e_k` of its point, and which
//! bends as little as that allows (the steps below say in what sense). It is never further
//! from a point than the point may lie from the true curve, so never more than twice that
//! from the true curve there.
//!
//! With `γ` the second derivatives at the knots, `R` (so that `∫ |f″|² = γᴴRγ`) and `D` (the
//! spline's condition `D·g = R·γ` on its values `g`) the cyclic tridiagonal matrices of
//! [`Spline::periodic`]'s system divided by six, the spline nearest to data `y` for a
//! weight λ (Reinsch, 1967: least `Σ |g_k − y_k|² / e_k² + λ·γᴴRγ`) solves
//! `(R + λ·D·W·D) γ = D·y`, `g = y − λ·W·D·γ`, `W = diag(e_k²)`: a Hermitian, cyclic
//! pentadiagonal system. Its band is real and is factored as `L·diag·Lᵀ`; the corners the
//! period's wrap adds (complex, through `T`) are a rank-four correction (Woodbury). So
//! each solve is O(n).
//!
//! The fit is found in up to three steps:
//! 1. the largest λ whose Reinsch spline through the points keeps within every band, by
//!    bisecting log λ (λ = 0 interpolates, and always does). For rounded points this is the
//!    fit: rounding is small against the curve's own bending, and this λ smooths it away
//!    (the tests measure the curvature against the true curve's).
//! 2. Measured points scatter at random across their band, and a few at its edge hold
//!    step 1's λ down while the rest still zig-zag. Their reference is the Reinsch spline
//!    whose misfit spreads as the band says the points do (mean square a third of the
//!    band's, as for scatter spread evenly), and it is brought within the bands by the
//!    least-energy correction (ADMM: the correction's Reinsch spline through the points
//!    moved so far, each then put back into its disc, until the two agree; one factored
//!    matrix for all rounds).
//! 3. Step 2's curve may still stand out of a band by a hair: the fit is the point on the
//!    way from step 1's curve to step 2's that is furthest along and within every band (a
//!    mix of two splines on the same knots is one).
//!
//! The knots are the chord lengths of the points: along the curve, a point's scatter
//! cancels from one chord to the next.

use super::spline::Spline;
use num_complex::Complex64;

/// Fewer points than this are interpolated, not smoothed: on fewer, the cyclic system's
/// corners would overlap its band, and so few points carry no scatter worth smoothing.
pub const MIN_POINTS: usize = 8;

/// How closely the largest λ is found: the last λ within the bands is within this factor
/// of the first beyond them.
const LAMBDA_FACTOR: f64 = 1.02;

/// The most rounds of step 2 (module docs).
const MAX_ROUNDS: usize = 2000;

/// Step 2 has converged when no value stands out of its disc, nor moved in the last round,
/// by more than this share of its band.
const CONVERGED: f64 = 1e-3;

/// How points spread about the true curve within their bands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Spread {
    /// Rounded to the decimals they are written to: a smooth curve's rounding, which the
    /// largest λ within the bands smooths away (step 1 of the module docs).
    Rounding,
    /// Measured, to a tolerance the job states: scatter at random across the band, which
    /// takes steps 2 and 3 (a few points at their band's edge hold step 1's λ down).
    Scatter,
}

/// The smoothing fit of a period of points.
#[derive(Debug, Clone)]
pub struct Fit {
    /// The fitted curve.
    pub spline: Spline,
    /// Its largest distance from a point, mm.
    pub deviation: f64,
    /// The index of the point where it is reached.
    pub worst: usize,
}

/// The smoothest periodic spline within `band[k]` of every `points[k]`, closing from the
/// last point onto the first turned by `period` radians; see the module docs. Points with
/// no band (exact ones) and fewer than [`MIN_POINTS`] are interpolated.
pub fn fit(points: &[Complex64], band: &[f64], spread: Spread, period: f64) -> Fit {
    assert_eq!(points.len(), band.len(), "a band for every point");
    let n = points.len();
    let turn = Complex64::from_polar(1.0, period);
    if n < MIN_POINTS || band.iter().any(|&e| e <= 0.0) {
        return Fit {
            spline: Spline::periodic(points, period),
            deviation: 0.0,
            worst: 0,
        };
    }
    let h = chords(points, turn);
    let system = System::new(band, turn, &h);
    let (within_all, inside) = largest_lambda(&system, points);
    let (values, second) = match spread {
        Spread::Rounding => (inside.values, inside.second),
        Spread::Scatter => {
            let lambda = scatter_lambda(&system, points, within_all);
            let reference = system.factor(lambda).fit(points);
            let off: Vec<Complex64> = points
                .iter()
                .zip(&reference.values)
                .map(|(p, g)| p - g)
                .collect();
            let correction = correct(&system, &off, lambda);
            let corrected = Curve {
                values: add(&reference.values, &correction.values),
                second: add(&reference.second, &correction.second),
            };
            furthest_within(points, band, &inside, &corrected)
        }
    };
    let (deviation, worst) = deviation(points, &values);
    Fit {
        spline: Spline::periodic_with(&values, &second, &h, period),
        deviation,
        worst,
    }
}

/// The chord lengths between consecutive points, the last one closing onto the first turned.
fn chords(points: &[Complex64], turn: Complex64) -> Vec<f64> {
    let n = points.len();
    (0..n)
        .map(|k| {
            let next = if k + 1 == n {
                points[0] * turn
            } else {
                points[k + 1]
            };
            (next - points[k]).norm()
        })
        .collect()
}

/// The largest distance between `points` and the fitted `values`, and where.
fn deviation(points: &[Complex64], values: &[Complex64]) -> (f64, usize) {
    points
        .iter()
        .zip(values)
        .map(|(p, g)| (p - g).norm())
        .enumerate()
        .map(|(k, d)| (d, k))
        .fold((0.0, 0), |a, b| if b.0 > a.0 { b } else { a })
}

/// Whether every value is within its point's band.
fn within(points: &[Complex64], band: &[f64], values: &[Complex64]) -> bool {
    values
        .iter()
        .zip(points)
        .zip(band)
        .all(|((g, p), e)| (g - p).norm() <= *e)
}

/// A spline on the system's knots: its values and second derivatives there.
#[derive(Debug, Clone)]
struct Curve {
    values: Vec<Complex64>,
    second: Vec<Complex64>,
}

/// Step 1 (module docs): the largest λ found whose Reinsch spline through `points` keeps
/// within the bands, and that spline (λ = 0 and the interpolation if none larger does).
fn largest_lambda(system: &System, points: &[Complex64]) -> (f64, Curve) {
    let fits = |lambda: f64| {
        let curve = system.factor(lambda).fit(points);
        let inside = within(points, system.band, &curve.values);
        (curve, inside)
    };
    let mut lo = (0.0, fits(0.0).0);
    let mut hi = f64::INFINITY;
    // Bracket it from the natural scale, where the two terms weigh alike (λ·e²/h² ≈ h):
    // up while within, down while not.
    let mut lambda = median(system.h).powi(3) / median(system.band).powi(2);
    for _ in 0..40 {
        let (curve, inside) = fits(lambda);
        if inside {
            lo = (lambda, curve);
            if hi.is_finite() {
                break;
            }
            lambda *= 100.0;
        } else {
            hi = lambda;
            if lo.0 > 0.0 {
                break;
            }
            lambda /= 100.0;
        }
    }
    if lo.0 > 0.0 && hi.is_finite() {
        while hi / lo.0 > LAMBDA_FACTOR {
            let mid = (hi * lo.0).sqrt();
            let (curve, inside) = fits(mid);
            if inside {
                lo = (mid, curve);
            } else {
                hi = mid;
            }
        }
    }
    lo
}

/// The λ at or above `from` whose Reinsch spline through `points` scatters about them as
/// the bands say the points scatter about the true curve: the mean of `(|g_k − P_k|/e_k)²`
/// a third, as for scatter spread evenly across the band (rounding is, and so is the
/// reading of an instrument specified to ±e). The deviation grows with λ.
fn scatter_lambda(system: &System, points: &[Complex64], from: f64) -> f64 {
    let scatter = |lambda: f64| {
        let curve = system.factor(lambda).fit(points);
        let sum: f64 = (0..points.len())
            .map(|k| ((curve.values[k] - points[k]).norm() / system.band[k]).powi(2))
            .sum();
        sum / points.len() as f64
    };
    const EVEN: f64 = 1.0 / 3.0;
    if from <= 0.0 || scatter(from) >= EVEN {
        return from;
    }
    let (mut lo, mut hi) = (from, from * 100.0);
    for _ in 0..40 {
        if scatter(hi) >= EVEN {
            break;
        }
        lo = hi;
        hi *= 100.0;
    }
    while hi / lo > LAMBDA_FACTOR {
        let mid = (hi * lo).sqrt();
        if scatter(mid) < EVEN {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

fn add(a: &[Complex64], b: &[Complex64]) -> Vec<Complex64> {
    a.iter().zip(b).map(|(a, b)| a + b).collect()
}

/// Step 2 (module docs): the least-energy correction `c` with every `reference + c` in its
/// point's disc, by ADMM on `c = z`, `z` in the discs (centred on `off`, the points less
/// the reference), each round's correction the Reinsch spline at `lambda` through `z − u`
/// (`u` the scaled multipliers).
fn correct(system: &System, off: &[Complex64], lambda: f64) -> Curve {
    let band = system.band;
    let solver = system.factor(lambda);
    let zero = Complex64::new(0.0, 0.0);
    let mut z = vec![zero; off.len()];
    let mut u = vec![zero; off.len()];
    let mut curve = solver.fit(&z);
    for _ in 0..MAX_ROUNDS {
        let data: Vec<Complex64> = z.iter().zip(&u).map(|(z, u)| z - u).collect();
        curve = solver.fit(&data);
        let mut settled = true;
        for k in 0..off.len() {
            let wanted = curve.values[k] + u[k];
            let from = wanted - off[k];
            let inside = if from.norm() > band[k] {
                off[k] + from * (band[k] / from.norm())
            } else {
                wanted
            };
            let stands_out = (curve.values[k] - inside).norm();
            let moved = (inside - z[k]).norm();
            settled &= stands_out.max(moved) <= CONVERGED * band[k];
            u[k] = wanted - inside;
            z[k] = inside;
        }
        if settled {
            break;
        }
    }
    curve
}

/// Step 3 (module docs): the mix `(1 − t)·from + t·to` of largest `t` in [0, 1] within every
/// band, `from` being within them.
fn furthest_within(
    points: &[Complex64],
    band: &[f64],
    from: &Curve,
    to: &Curve,
) -> (Vec<Complex64>, Vec<Complex64>) {
    // |a + t·b| ≤ e with |a| ≤ e holds from t = 0 to the larger root of the quadratic.
    let t = (0..points.len())
        .map(|k| {
            let (a, b) = (from.values[k] - points[k], to.values[k] - from.values[k]);
            let (bb, ab) = (b.norm_sqr(), (a.conj() * b).re);
            if bb == 0.0 {
                return 1.0;
            }
            let room = (ab * ab - bb * (a.norm_sqr() - band[k] * band[k])).max(0.0);
            (-ab + room.sqrt()) / bb
        })
        .fold(1.0, f64::min)
        .max(0.0)
        // The root to a hair inside: the mix's own rounding must not carry it out.
        * (1.0 - 1e-9);
    let mix = |a: &[Complex64], b: &[Complex64]| -> Vec<Complex64> {
        a.iter()
            .zip(b)
            .map(|(a, b)| a * (1.0 - t) + b * t)
            .collect()
    };
    (mix(&from.values, &to.values), mix(&from.second, &to.second))
}

fn median(values: &[f64]) -> f64 {
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    sorted[sorted.len() / 2]
}

/// The Reinsch spline's equations on given knots.
struct System<'a> {
    /// Each point's band, mm.
    band: &'a [f64],
    /// The knots' spacing.
    h: &'a [f64],
    turn: Complex64,
}

impl<'a> System<'a> {
    fn new(band: &'a [f64], turn: Complex64, h: &'a [f64]) -> Self {
        System { band, h, turn }
    }

    /// Row `k` of `D`: its three columns (`k − 1`, `k`, `k + 1`, cyclic) and entries.
    fn d_row(&self, k: usize) -> [(usize, Complex64); 3] {
        let n = self.h.len();
        let (prev, next) = ((k + n - 1) % n, (k + 1) % n);
        let one = Complex64::new(1.0, 0.0);
        let before = if k == 0 { self.turn.conj() } else { one } / self.h[prev];
        let after = if k + 1 == n { self.turn } else { one } / self.h[k];
        let own = -(1.0 / self.h[prev] + 1.0 / self.h[k]);
        [(prev, before), (k, own.into()), (next, after)]
    }

    fn apply_d(&self, x: &[Complex64]) -> Vec<Complex64> {
        (0..x.len())
            .map(|k| self.d_row(k).iter().map(|&(j, d)| d * x[j]).sum())
            .collect()
    }

    /// The system at `lambda`, factored.
    fn factor(&self, lambda: f64) -> Reinsch<'_> {
        let n = self.h.len();
        let mut matrix = Pentadiagonal::zero(n);
        for k in 0..n {
            let (prev, next) = ((k + n - 1) % n, (k + 1) % n);
            matrix.add(k, k, ((self.h[prev] + self.h[k]) / 3.0).into());
            let wrap = if k + 1 == n {
                self.turn
            } else {
                Complex64::new(1.0, 0.0)
            };
            matrix.add(k, next, wrap * (self.h[k] / 6.0));
            let weight = lambda * self.band[k] * self.band[k];
            let row = self.d_row(k);
            for (a, &(i, di)) in row.iter().enumerate() {
                for &(j, dj) in &row[a..] {
                    matrix.add(i, j, di.conj() * dj * weight);
                }
            }
        }
        Reinsch {
            system: self,
            lambda,
            solver: matrix.factor(),
        }
    }
}

/// The Reinsch spline at one λ, its matrix factored.
struct Reinsch<'a> {
    system: &'a System<'a>,
    lambda: f64,
    solver: Solver,
}

impl Reinsch<'_> {
    /// The spline nearest to `data` at this λ.
    fn fit(&self, data: &[Complex64]) -> Curve {
        let system = self.system;
        let second = self.solver.solve(&system.apply_d(data));
        let d_second = system.apply_d(&second);
        let values = (0..data.len())
            .map(|k| data[k] - d_second[k] * (self.lambda * system.band[k] * system.band[k]))
            .collect();
        Curve { values, second }
    }
}

/// A Hermitian cyclic pentadiagonal matrix: its real band (diagonal and the two above it)
/// and the complex corner block the wrap adds, rows 0 and 1 by columns `n − 2` and `n − 1`.
struct Pentadiagonal {
    diag: Vec<f64>,
    first: Vec<f64>,
    second: Vec<f64>,
    corner: [[Complex64; 2]; 2],
}

impl Pentadiagonal {
    fn zero(n: usize) -> Self {
        Pentadiagonal {
            diag: vec![0.0; n],
            first: vec![0.0; n],
            second: vec![0.0; n],
            corner: [[Complex64::new(0.0, 0.0); 2]; 2],
        }
    }

    /// Adds `v` at (`i`, `j`) and its conjugate at (`j`, `i`) (`v` once, real, on the
    /// diagonal). Within the band the entries are real: only the wrap brings in the turn.
    fn add(&mut self, i: usize, j: usize, v: Complex64) {
        let (i, j, v) = if i <= j { (i, j, v) } else { (j, i, v.conj()) };
        let n = self.diag.len();
        match j - i {
            0 => self.diag[i] += v.re,
            1 => self.first[i] += v.re,
            2 => self.second[i] += v.re,
            _ => {
                debug_assert!(i < 2 && j >= n - 2, "({i}, {j}) is neither band nor corner");
                self.corner[i][j + 2 - n] += v;
            }
        }
    }

    /// The matrix ready to solve with: the band's `L·diag·Lᵀ`, and for the corners
    /// (Woodbury: `A = B + P·E·Pᵀ`, `P` picking rows and columns 0, 1, n − 2, n − 1) the
    /// band's solutions `Z = B⁻¹·P` and the 4×4 matrix `I + E·Pᵀ·Z`.
    fn factor(&self) -> Solver {
        let n = self.diag.len();
        let band = Factored::new(self);
        let at = [0, 1, n - 2, n - 1];
        let zero = Complex64::new(0.0, 0.0);
        let mut e = [[zero; 4]; 4];
        for (a, row) in self.corner.iter().enumerate() {
            for (b, &v) in row.iter().enumerate() {
                e[a][b + 2] = v;
                e[b + 2][a] = v.conj();
            }
        }
        let z: Vec<Vec<Complex64>> = at
            .iter()
            .map(|&col| {
                let mut unit = vec![zero; n];
                unit[col] = Complex64::new(1.0, 0.0);
                band.solve(unit)
            })
            .collect();
        let mut s = [[zero; 4]; 4];
        for a in 0..4 {
            for b in 0..4 {
                s[a][b] = if a == b { 1.0.into() } else { zero };
                for c in 0..4 {
                    s[a][b] += e[a][c] * z[b][at[c]];
                }
            }
        }
        Solver { band, at, e, z, s }
    }
}

/// A [`Pentadiagonal`] factored ([`Pentadiagonal::factor`]).
struct Solver {
    band: Factored,
    at: [usize; 4],
    e: [[Complex64; 4]; 4],
    z: Vec<Vec<Complex64>>,
    s: [[Complex64; 4]; 4],
}

impl Solver {
    /// `x` with `A·x = rhs`: `x = B⁻¹·rhs − Z·(I + E·Pᵀ·Z)⁻¹·E·Pᵀ·B⁻¹·rhs`.
    fn solve(&self, rhs: &[Complex64]) -> Vec<Complex64> {
        let x0 = self.band.solve(rhs.to_vec());
        let mut t = [Complex64::new(0.0, 0.0); 4];
        for (a, ta) in t.iter_mut().enumerate() {
            *ta = (0..4).map(|c| self.e[a][c] * x0[self.at[c]]).sum();
        }
        let w = solve4(self.s, t);
        x0.iter()
            .enumerate()
            .map(|(i, x)| x - (0..4).map(|b| self.z[b][i] * w[b]).sum::<Complex64>())
            .collect()
    }
}

/// A real symmetric positive definite pentadiagonal band as `L·diag·Lᵀ`, `L` unit lower
/// triangular with two subdiagonals.
struct Factored {
    d: Vec<f64>,
    l1: Vec<f64>,
    l2: Vec<f64>,
}

impl Factored {
    fn new(m: &Pentadiagonal) -> Self {
        let n = m.diag.len();
        let (mut d, mut l1, mut l2) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        for i in 0..n {
            let mut di = m.diag[i];
            if i >= 1 {
                di -= l1[i - 1] * l1[i - 1] * d[i - 1];
            }
            if i >= 2 {
                di -= l2[i - 2] * l2[i - 2] * d[i - 2];
            }
            d[i] = di;
            if i + 1 < n {
                let mut b = m.first[i];
                if i >= 1 {
                    b -= l2[i - 1] * l1[i - 1] * d[i - 1];
                }
                l1[i] = b / di;
            }
            if i + 2 < n {
                l2[i] = m.second[i] / di;
            }
        }
        Factored { d, l1, l2 }
    }

    fn solve(&self, mut x: Vec<Complex64>) -> Vec<Complex64> {
        let n = x.len();
        for i in 1..n {
            let mut xi = x[i] - x[i - 1] * self.l1[i - 1];
            if i >= 2 {
                xi -= x[i - 2] * self.l2[i - 2];
            }
            x[i] = xi;
        }
        for (xi, d) in x.iter_mut().zip(&self.d) {
            *xi /= *d;
        }
        for i in (0..n.saturating_sub(1)).rev() {
            let mut xi = x[i] - x[i + 1] * self.l1[i];
            if i + 2 < n {
                xi -= x[i + 2] * self.l2[i];
            }
            x[i] = xi;
        }
        x
    }
}

/// `w` with `s · w = t`: Gaussian elimination with partial pivoting.
fn solve4(mut s: [[Complex64; 4]; 4], mut t: [Complex64; 4]) -> [Complex64; 4] {
    for col in 0..4 {
        let pivot = (col..4)
            .max_by(|&a, &b| s[a][col].norm().total_cmp(&s[b][col].norm()))
            .unwrap_or(col);
        s.swap(col, pivot);
        t.swap(col, pivot);
        let (above, below) = s.split_at_mut(col + 1);
        let pivot_row = above[col];
        for (offset, row) in below.iter_mut().enumerate() {
            let factor = row[col] / pivot_row[col];
            for (v, p) in row.iter_mut().zip(&pivot_row).skip(col) {
                *v -= factor * p;
            }
            let pivot_t = t[col];
            t[col + 1 + offset] -= factor * pivot_t;
        }
    }
    let mut w = [Complex64::new(0.0, 0.0); 4];
    for row in (0..4).rev() {
        let known: Complex64 = (row + 1..4).map(|k| s[row][k] * w[k]).sum();
        w[row] = (t[row] - known) / s[row][row];
    }
    w
}

#[cfg(test)]
mod tests;
