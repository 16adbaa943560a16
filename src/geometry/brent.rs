//! Brent's method for a bracketed root, with explicit tolerances.
//!
//! Written here rather than taken from a crate because the linkage solver needs the tolerance
//! on x stated in radians and a hard iteration cap it can report, and a bracket it has already
//! found (it never needs the search the crates add around it).

/// A root of `f` in `[a, b]`, where `f(a)` and `f(b)` have opposite signs (or one is zero),
/// to within `x_tol`; `None` if the bracket is not one or `max_iter` steps did not converge.
pub fn root(
    mut f: impl FnMut(f64) -> f64,
    a: f64,
    b: f64,
    x_tol: f64,
    max_iter: usize,
) -> Option<f64> {
    let (mut a, mut b) = (a, b);
    let (mut fa, mut fb) = (f(a), f(b));
    if fa == 0.0 {
        return Some(a);
    }
    if fb == 0.0 {
        return Some(b);
    }
    if !(fa.is_finite() && fb.is_finite()) || fa.signum() == fb.signum() {
        return None;
    }
    let (mut c, mut fc) = (a, fa);
    let (mut d, mut e) = (b - a, b - a);
    for _ in 0..max_iter {
        if fb.signum() == fc.signum() {
            (c, fc) = (a, fa);
            d = b - a;
            e = d;
        }
        if fc.abs() < fb.abs() {
            (a, b, c) = (b, c, b);
            (fa, fb, fc) = (fb, fc, fb);
        }
        let tol = 2.0 * f64::EPSILON * b.abs() + 0.5 * x_tol;
        let m = 0.5 * (c - b);
        if m.abs() <= tol || fb == 0.0 {
            return Some(b);
        }
        if e.abs() >= tol && fa.abs() > fb.abs() {
            // Inverse quadratic interpolation, or the secant step when only two points differ.
            let s = fb / fa;
            let (mut p, mut q) = if a == c {
                (2.0 * m * s, 1.0 - s)
            } else {
                let (q0, r) = (fa / fc, fb / fc);
                (
                    s * (2.0 * m * q0 * (q0 - r) - (b - a) * (r - 1.0)),
                    (q0 - 1.0) * (r - 1.0) * (s - 1.0),
                )
            };
            if p > 0.0 {
                q = -q;
            } else {
                p = -p;
            }
            if 2.0 * p < (3.0 * m * q - (tol * q).abs()).min((e * q).abs()) {
                e = d;
                d = p / q;
            } else {
                d = m;
                e = m;
            }
        } else {
            d = m;
            e = m;
        }
        (a, fa) = (b, fb);
        b += if d.abs() > tol { d } else { tol.copysign(m) };
        fb = f(b);
    }
    None
}

#[cfg(test)]
mod tests {
    use super::root;

    #[test]
    fn finds_roots_to_the_asked_tolerance() {
        let r = root(|x| x * x - 2.0, 0.0, 2.0, 1e-14, 100).unwrap();
        assert!((r - 2f64.sqrt()).abs() < 1e-14);
        let r = root(f64::cos, 1.0, 2.0, 1e-12, 100).unwrap();
        assert!((r - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        // A flat, nasty one: (x - 1)^5 changes sign only at 1.
        let r = root(|x: f64| (x - 1.0).powi(5), 0.0, 3.0, 1e-10, 200).unwrap();
        assert!((r - 1.0).abs() < 1e-9, "{r}");
    }

    #[test]
    fn refuses_a_bracket_without_a_sign_change_or_with_too_few_steps() {
        assert_eq!(root(|x| x * x + 1.0, -1.0, 1.0, 1e-12, 100), None);
        assert_eq!(root(|_| f64::NAN, -1.0, 1.0, 1e-12, 100), None);
        assert_eq!(root(|x: f64| x.powi(3) - 0.3, 0.0, 1.0, 1e-15, 2), None);
    }
}
