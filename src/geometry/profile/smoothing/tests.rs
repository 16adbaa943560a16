use super::*;
use std::f64::consts::PI;

/// The double-start's curve, ρ = 30 − 4 cos 2φ: its point, first and second derivative in
/// φ, and its curvature `(ρ² + 2ρ′² − ρρ″) / (ρ² + ρ′²)^{3/2}` (a polar curve's).
fn lobes(phi: f64) -> (Complex64, f64) {
    let (r, r1, r2) = (
        30.0 - 4.0 * (2.0 * phi).cos(),
        8.0 * (2.0 * phi).sin(),
        16.0 * (2.0 * phi).cos(),
    );
    let kappa = (r * r + 2.0 * r1 * r1 - r * r2) / (r * r + r1 * r1).powf(1.5);
    (Complex64::from_polar(r, phi), kappa)
}

/// `n` points over one period (π) of [`lobes`], each coordinate moved by `scatter(k)`.
fn sampled(n: usize, mut scatter: impl FnMut(usize, Complex64) -> Complex64) -> Vec<Complex64> {
    (0..n)
        .map(|k| scatter(k, lobes(PI * k as f64 / n as f64).0))
        .collect()
}

/// Rounded to `decimals`, and the band that rounding allows (half the last decimal in each
/// coordinate).
fn rounded(n: usize, decimals: i32) -> (Vec<Complex64>, f64) {
    let scale = 10f64.powi(decimals);
    let round =
        |_, z: Complex64| Complex64::new((z.re * scale).round(), (z.im * scale).round()) / scale;
    (sampled(n, round), (0.5 / scale) * 2f64.sqrt())
}

/// The distance from `q` to the curve [`lobes`]: the nearest of its points near `q`'s polar
/// angle, by golden-section search (the distance has one minimum that close).
fn off_curve(q: Complex64) -> f64 {
    let dist = |phi: f64| (lobes(phi).0 - q).norm();
    let (mut a, mut b) = (q.arg() - 0.01, q.arg() + 0.01);
    let g = (5f64.sqrt() - 1.0) / 2.0;
    for _ in 0..100 {
        let (c, d) = (b - g * (b - a), a + g * (b - a));
        if dist(c) < dist(d) {
            b = d;
        } else {
            a = c;
        }
    }
    dist((a + b) / 2.0)
}

/// The curvature of a fitted spline at its parameter `s`.
fn curvature(spline: &Spline, s: f64) -> f64 {
    let e = spline.eval(s);
    (e.d1.conj() * e.d2).im / e.d1.norm().powi(3)
}

#[test]
fn the_fit_keeps_within_every_points_band_and_so_within_twice_it_of_the_curve() {
    let (points, band) = rounded(2000, 4);
    let fit = fit(&points, &vec![band; points.len()], Spread::Rounding, PI);
    assert!(fit.deviation <= band, "{} > {band}", fit.deviation);
    for (knot, point) in fit.spline.knots().iter().zip(&points) {
        let at = fit.spline.eval(*knot).p;
        assert!((at - point).norm() <= band * (1.0 + 1e-9));
        // Each rounded point is within the band of the curve, the fit within it of the point.
        assert!(off_curve(at) <= 2.0 * band, "{}", off_curve(at));
    }
}

#[test]
fn the_fit_bends_as_the_curve_does_where_the_interpolation_follows_the_rounding() {
    // 2000 points at 4 decimals: 0.05 µm of rounding over a spacing of 50 µm.
    let (points, band) = rounded(2000, 4);
    let fitted = fit(&points, &vec![band; points.len()], Spread::Rounding, PI).spline;
    let through = Spline::periodic(&points, PI);
    let worst = |spline: &Spline| {
        spline
            .knots()
            .iter()
            .map(|&s| (curvature(spline, s) - lobes(spline.eval(s).p.arg()).1).abs())
            .fold(0.0, f64::max)
    };
    // The curve's curvature lies between 1/26 and 1/22 per mm (at its lobes).
    let most = lobes(0.0).1.abs().max(lobes(PI / 2.0).1.abs());
    assert!(worst(&fitted) < 0.01 * most, "{} of {most}", worst(&fitted));
    // What the smoothing is for: through the points, the rounding shows in the curvature.
    assert!(
        worst(&through) > 0.1 * most,
        "{} of {most}",
        worst(&through)
    );
}

#[test]
fn the_fit_is_continuous_in_slope_at_every_knot() {
    let (points, band) = rounded(500, 3);
    let spline = fit(&points, &vec![band; points.len()], Spread::Rounding, PI).spline;
    let knots = spline.knots();
    for pair in knots.windows(3) {
        let (k, eps) = (pair[1], 1e-7 * (pair[2] - pair[0]));
        let (before, after) = (spline.eval(k - eps), spline.eval(k + eps));
        let jump = (after.d1 - before.d1).norm();
        // Within what the second derivative turns the slope by over 2·eps.
        assert!(jump <= 4.0 * eps * before.d2.norm().max(after.d2.norm()) + 1e-12);
    }
}

#[test]
fn half_a_turn_with_its_turn_fits_as_the_whole_closed_curve_does() {
    // The same data as one period of a two-start groove (closing onto itself turned by π,
    // the complex corners) and as the whole closed curve (turn 1): one objective, one fit.
    let (half, band) = rounded(400, 3);
    let whole: Vec<Complex64> = half
        .iter()
        .chain(&half.iter().map(|z| -z).collect::<Vec<_>>())
        .copied()
        .collect();
    let by_half = fit(&half, &vec![band; half.len()], Spread::Rounding, PI);
    let by_whole = fit(&whole, &vec![band; whole.len()], Spread::Rounding, 2.0 * PI);
    for (k, knot) in by_half.spline.knots().iter().enumerate() {
        let (a, b) = (
            by_half.spline.eval(*knot).p,
            by_whole.spline.eval(by_whole.spline.knots()[k]).p,
        );
        // The two searches stop within LAMBDA_FACTOR of the same λ, not at the same λ.
        assert!((a - b).norm() < 0.05 * band, "knot {k}: {a} {b}");
    }
}

#[test]
fn measured_scatter_within_its_stated_tolerance_is_smoothed_away() {
    // ±2 µm of scatter, radial, from a fixed sequence (a linear congruential generator).
    let tolerance = 0.002;
    let mut state = 12345u64;
    let mut noise = Vec::new();
    for _ in 0..4000 {
        // Knuth's MMIX multiplier and increment.
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        noise.push(((state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0) * tolerance);
    }
    let points = sampled(4000, |k, z| z * (1.0 + noise[k] / z.norm()));
    let fit = fit(&points, &vec![tolerance; points.len()], Spread::Scatter, PI);
    assert!(fit.deviation <= tolerance, "{}", fit.deviation);
    let knots = fit.spline.knots();
    for &s in knots {
        assert!(off_curve(fit.spline.eval(s).p) <= 2.0 * tolerance);
    }
    // Through the points, the scatter bends the curve by up to 8·2 µm over (20 µm)²: 40 per
    // mm. The fit bends as the curve does to within a twentieth of what a nose of 1 mm
    // radius (a small one for whirling) bends: noise nowhere looks like a corner to cut.
    for &s in knots {
        let wrong = (curvature(&fit.spline, s) - lobes(fit.spline.eval(s).p.arg()).1).abs();
        assert!(wrong < 0.05, "{wrong} per mm at {s}");
    }
}

#[test]
fn exact_points_and_very_few_are_interpolated() {
    let points = sampled(50, |_, z| z);
    let exact = fit(&points, &vec![0.0; 50], Spread::Rounding, PI);
    let few = fit(
        &points[..MIN_POINTS - 1],
        &[0.001; MIN_POINTS - 1],
        Spread::Rounding,
        PI,
    );
    for (fitted, given) in [(&exact, &points[..]), (&few, &points[..MIN_POINTS - 1])] {
        assert_eq!(fitted.deviation, 0.0);
        for (knot, point) in fitted.spline.knots().iter().zip(given) {
            assert!((fitted.spline.eval(*knot).p - point).norm() < 1e-12);
        }
    }
}

#[test]
fn the_cyclic_solve_inverts_its_matrix() {
    // A small system with complex corners, checked by multiplying back.
    let n = 9;
    let mut m = Pentadiagonal::zero(n);
    for i in 0..n {
        m.add(i, i, (10.0 + i as f64).into());
        m.add(
            i,
            (i + 1) % n,
            Complex64::new(1.0 + 0.1 * i as f64, 0.0)
                * if i + 1 == n {
                    Complex64::from_polar(1.0, 0.7)
                } else {
                    1.0.into()
                },
        );
        m.add(
            i,
            (i + 2) % n,
            Complex64::new(0.5, 0.0)
                * if i + 2 >= n {
                    Complex64::from_polar(1.0, 0.7)
                } else {
                    1.0.into()
                },
        );
    }
    let full = |i: usize, j: usize| -> Complex64 {
        let (a, b, conj) = if i <= j { (i, j, false) } else { (j, i, true) };
        let v = match b - a {
            0 => m.diag[a].into(),
            1 => m.first[a].into(),
            2 => m.second[a].into(),
            _ if a < 2 && b >= n - 2 => m.corner[a][b + 2 - n],
            _ => Complex64::new(0.0, 0.0),
        };
        if conj {
            v.conj()
        } else {
            v
        }
    };
    let rhs: Vec<Complex64> = (0..n)
        .map(|i| Complex64::new(i as f64, 1.0 - i as f64))
        .collect();
    let x = m.factor().solve(&rhs);
    for (i, wanted) in rhs.iter().enumerate() {
        let back: Complex64 = (0..n).map(|j| full(i, j) * x[j]).sum();
        assert!((back - wanted).norm() < 1e-12, "row {i}");
    }
}
