//! One-dimensional minimisation: golden-section search, and a scan that finds the basin first.
//!
//! The sweep computations minimise gaps along a parameter (a pose's turn, a helix angle) where
//! the function is smooth and unimodal near its minimum but may have other basins further out.

/// Golden-section search for a minimum of `f` on `[a, b]`, `steps` steps (each shrinks the
/// bracket by 0.618): returns the best point found and its value.
pub fn golden(mut f: impl FnMut(f64) -> f64, mut a: f64, mut b: f64, steps: usize) -> (f64, f64) {
    let g = (5f64.sqrt() - 1.0) / 2.0;
    let (mut x1, mut x2) = (b - g * (b - a), a + g * (b - a));
    let (mut f1, mut f2) = (f(x1), f(x2));
    for _ in 0..steps {
        if f1 < f2 {
            b = x2;
            (x2, f2) = (x1, f1);
            x1 = b - g * (b - a);
            f1 = f(x1);
        } else {
            a = x1;
            (x1, f1) = (x2, f2);
            x2 = a + g * (b - a);
            f2 = f(x2);
        }
    }
    if f1 < f2 {
        (x1, f1)
    } else {
        (x2, f2)
    }
}

/// The minimum of `f` over `[a, b]`: `scan` even steps find the best basin, then `steps`
/// golden-section steps refine it within one scan step either side. The scan must be fine
/// enough that the basin of the minimum is wider than a step.
pub fn scan_then_golden(
    mut f: impl FnMut(f64) -> f64,
    a: f64,
    b: f64,
    scan: usize,
    steps: usize,
) -> f64 {
    let step = (b - a) / scan.max(1) as f64;
    let (mut best_x, mut best) = (a, f64::INFINITY);
    for k in 0..=scan.max(1) {
        let x = a + step * k as f64;
        let v = f(x);
        if v < best {
            (best_x, best) = (x, v);
        }
    }
    let lo = (best_x - step).max(a);
    let hi = (best_x + step).min(b);
    best.min(golden(f, lo, hi, steps).1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn golden_finds_a_parabola_s_vertex() {
        let (x, v) = golden(|x| (x - 0.3).powi(2) + 1.0, -2.0, 5.0, 60);
        assert!((x - 0.3).abs() < 1e-7 && (v - 1.0).abs() < 1e-12);
    }

    #[test]
    fn the_scan_picks_the_deeper_of_two_basins() {
        // cos(3x) on [0, 4]: minima near π/3 and π, both −1; tilted by −0.01x the one near π
        // is deeper by 0.0209. The tilt moves each minimum by about 0.001 in x, changing its
        // value by under 1e-5.
        let f = |x: f64| (3.0 * x).cos() - 0.01 * x;
        let v = scan_then_golden(f, 0.0, 4.0, 40, 60);
        let pi = std::f64::consts::PI;
        assert!((v - (-1.0 - 0.01 * pi)).abs() < 1e-5, "{v}");
        assert!(v < -1.0 - 0.01 * pi / 3.0 - 0.02, "the deeper basin: {v}");
    }
}
