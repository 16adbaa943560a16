//! The groove as the console draws it: the axial section the executed moves cut so far,
//! against the target, the error magnified, with the Δ band; and the measured error of the
//! whole cut at a run's end.
//!
//! The same engine as `whirl log plot --job` ([`crate::judge::measure`]), fed the executed
//! moves of a run and of the runs it resumed, so a stop and a resume show as one cut. The
//! section is taken one pitch wide around where the ring cuts now (the last move's Z), so
//! the operator sees the cut as it grows.

use crate::config::job::Job;
use crate::geometry::linkage::Ring;
use crate::judge::measure::{Motion, SectionPoint, VerifyError};
use crate::judge::svg::{Plot, Series};
use crate::judge::verify::{self, CheckError};
use crate::log::{Event, Record};

use super::registry::Measured;

/// The magnification that draws Δ as about a twentieth of the pitch, as round as
/// `whirl log plot` makes it (1, 2 or 5 × 10ⁿ, at least 1).
fn magnification(delta: f64, pitch: f64) -> f64 {
    let raw = (pitch / 20.0) / delta;
    let decade = 10f64.powf(raw.log10().floor());
    [5.0, 2.0, 1.0]
        .iter()
        .map(|m| m * decade)
        .find(|m| *m <= raw)
        .unwrap_or(decade)
        .max(1.0)
}

/// The cutting moves among `records` (rapids position, they do not cut), and the Z of the
/// last one.
fn motion(records: &[Record]) -> Result<(Motion, Option<f64>), VerifyError> {
    let mut motion = Motion::empty();
    let mut z = None;
    for (i, r) in records.iter().enumerate() {
        if let Event::Executed {
            from,
            to,
            rapid: false,
            ..
        } = &r.event
        {
            motion.push(*from, *to, i + 1)?;
            z = Some(to[1]);
        }
    }
    Ok((motion, z))
}

/// How much more material than Δ a point may have left and still count as cut: more is
/// stock the ring has not reached yet (a cut leaves far less; the guard alarms at Δ).
const UNCUT_DELTAS: f64 = 10.0;

/// The axial section `records`' executed moves cut, against `job`'s target as `ring` (the
/// ring the run's program was planned with) cuts it, with the Δ band (the target moved Δ out
/// and in along its normal, magnified as the error is); `None` before the ring has turned
/// through the work. Mid-run, only what is cut is drawn as machined: the target not yet
/// reached is faded, and the plot keeps the groove's scale (drawn whole, the stock left
/// on it would span hundreds of millimetres, magnified).
pub fn section(job: &Job, ring: Ring, records: &[Record]) -> Result<Option<Plot>, CheckError> {
    let (motion, z) = motion(records)?;
    let Some(z) = z.filter(|_| motion.is_turning()) else {
        return Ok(None);
    };
    let target = verify::target(job, ring)?;
    let pitch = job.groove.lead / f64::from(job.groove.starts);
    let magnify = magnification(job.cut.delta, pitch);
    let points = target.section(&motion, z);
    Ok(Some(plot(&points, job.cut.delta, magnify)))
}

/// The console's section plot of `points`: the target cut so far, the target not yet cut
/// (faded), the machined section where cut, and the Δ band all along.
fn plot(points: &[SectionPoint], delta: f64, magnify: f64) -> Plot {
    let cut = |p: &SectionPoint| p.error_mm <= UNCUT_DELTAS * delta;
    let gap = (f64::NAN, f64::NAN);
    let target: Vec<(f64, f64)> = points.iter().map(|p| (p.z, p.rho)).collect();
    let offset = delta * magnify;
    let mut series = vec![
        Series {
            label: "target, cut".into(),
            colour: "black",
            points: points
                .iter()
                .map(|p| if cut(p) { (p.z, p.rho) } else { gap })
                .collect(),
        },
        Series {
            label: "target, not cut yet".into(),
            colour: "#bbb",
            points: points
                .iter()
                .map(|p| if cut(p) { gap } else { (p.z, p.rho) })
                .collect(),
        },
        Series {
            label: format!("machined (error × {magnify})"),
            colour: "crimson",
            points: points
                .iter()
                .map(|p| if cut(p) { p.machined(magnify) } else { gap })
                .collect(),
        },
        Series {
            label: format!("Δ band (± {delta} mm × {magnify})"),
            colour: "seagreen",
            points: band(&target, offset),
        },
    ];
    // The band's other side: the same legend entry.
    series.push(Series {
        label: String::new(),
        colour: "seagreen",
        points: band(&target, -offset),
    });
    Plot {
        title: format!("axial section at polar angle 0, error magnified {magnify}×"),
        x_label: "z, mm".into(),
        y_label: "radius, mm".into(),
        series,
        equal_scale: true,
    }
}

/// `points` moved `offset` along the polyline's normal (the section's, in its own plane:
/// the surface normal projected into the axial plane is normal to the section curve).
/// Where the polyline jumps (from one start's flank to the next), a point keeps the
/// normal of its nearer neighbour.
fn band(points: &[(f64, f64)], offset: f64) -> Vec<(f64, f64)> {
    let n = points.len();
    (0..n)
        .map(|i| {
            let (a, b) = (points[i.saturating_sub(1)], points[(i + 1).min(n - 1)]);
            let (dz, dr) = (b.0 - a.0, b.1 - a.1);
            let length = dz.hypot(dr);
            if length == 0.0 {
                return points[i];
            }
            (
                points[i].0 - dr / length * offset,
                points[i].1 + dz / length * offset,
            )
        })
        .collect()
}

/// The whole cut measured against `job`'s groove over its formed length, as `whirl verify`
/// measures a program planned with `ring`; an error before the ring has turned through the
/// work.
pub fn measure(job: &Job, ring: Ring, records: &[Record]) -> Result<Measured, CheckError> {
    let (motion, _) = motion(records)?;
    if !motion.is_turning() {
        return Err(VerifyError::NoTurning.into());
    }
    let m = verify::target(job, ring)?.measure(&motion)?;
    let delta = job.cut.delta;
    Ok(Measured {
        max_overcut_mm: m.max_overcut_mm,
        max_undercut_mm: m.max_undercut_mm,
        delta_mm: delta,
        within_delta: m.max_overcut_mm <= delta && m.max_undercut_mm <= delta,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_band_lies_offset_along_the_normal_of_the_section() {
        // A straight flank at 45°: its normal is (−1, 1)/√2.
        let points = [(0.0, 0.0), (1.0, 1.0), (2.0, 2.0)];
        let moved = band(&points, 2f64.sqrt());
        for ((z, r), (mz, mr)) in points.iter().zip(&moved) {
            assert!((mz - (z - 1.0)).abs() < 1e-12 && (mr - (r + 1.0)).abs() < 1e-12);
        }
    }

    #[test]
    fn mid_run_only_the_cut_is_drawn_machined_and_the_band_is_whole() {
        // A floor at radius 16: cut within Δ at z 0 and 1, stock 2 mm proud at z 2 (not
        // reached yet), an overcut of 3Δ at z 3 (a gouge shows, however deep).
        let delta = 0.01;
        let at = |z: f64, error_mm: f64| SectionPoint {
            z,
            rho: 16.0,
            error_mm,
            normal: (0.0, 1.0),
        };
        let points = [
            at(0.0, 0.004),
            at(1.0, -0.002),
            at(2.0, 2.0),
            at(3.0, -0.03),
        ];
        let plot = plot(&points, delta, 20.0);
        let drawn = |k: usize| -> Vec<bool> {
            plot.series[k]
                .points
                .iter()
                .map(|p| p.0.is_finite())
                .collect()
        };
        assert_eq!(drawn(0), [true, true, false, true], "target, cut");
        assert_eq!(drawn(1), [false, false, true, false], "target, not cut yet");
        assert_eq!(drawn(2), [true, true, false, true], "machined");
        assert_eq!(drawn(3), [true; 4], "the band, out");
        assert_eq!(drawn(4), [true; 4], "the band, in");
        // The machined floor: 16 + error × 20.
        assert!((plot.series[2].points[0].1 - 16.08).abs() < 1e-12);
        assert!((plot.series[2].points[3].1 - 15.4).abs() < 1e-12);
        // The band: 16 ± Δ × 20.
        assert!((plot.series[3].points[2].1 - 16.2).abs() < 1e-12);
        assert!((plot.series[4].points[2].1 - 15.8).abs() < 1e-12);
        // Nothing drawn lies beyond the groove's scale: the stock is not.
        let highest = plot
            .series
            .iter()
            .flat_map(|s| &s.points)
            .filter(|p| p.1.is_finite())
            .map(|p| p.1)
            .fold(f64::MIN, f64::max);
        assert!(highest <= 16.2 + 1e-12, "{highest}");
    }

    #[test]
    fn delta_draws_as_at_most_a_twentieth_of_the_pitch() {
        // Pitch 7 mm, Δ 0.01 mm: 35× exactly would be a twentieth; the round one below is 20.
        assert_eq!(magnification(0.01, 7.0), 20.0);
        assert_eq!(magnification(0.001, 2.0), 100.0);
        assert_eq!(magnification(10.0, 1.0), 1.0);
    }

    #[test]
    fn nothing_is_drawn_before_the_ring_has_turned() {
        let job = Job::load(std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/examples/trapezoidal/job.toml"
        )))
        .unwrap();
        let rapid = Record {
            t: 0.0,
            event: Event::Executed {
                line: Some(1),
                times: [0.0, 1.0],
                from: [0.0; 3],
                to: [10.0, 0.0, 0.0],
                rapid: true,
            },
        };
        let (ring, _) = crate::plan::angles::ring(&job).unwrap();
        assert!(section(&job, ring, std::slice::from_ref(&rapid))
            .unwrap()
            .is_none());
        assert!(matches!(
            measure(&job, ring, &[rapid]),
            Err(CheckError::Verify(VerifyError::NoTurning))
        ));
    }
}
