//! `whirl measure` on the trapezoidal example: a measured axial section read, its deviations
//! from the target found, and the tool fitted, for a part cut with the ring radius 0.02 mm
//! and the installation angle 0.3° off the job's (as `tests/integration/measure.rs` cuts
//! it: the engine's section, no noise).
//!
//! Run with `cargo bench --bench measure`; docs/measure.md quotes the figures.

use divan::{black_box, Bencher};
use glam::DVec2;
use std::path::Path;
use whirl::config::job::Job;
use whirl::config::machine::MachineProfile;
use whirl::geometry::linkage::{Linkage, Ring};
use whirl::geometry::profile::surface_normal;
use whirl::judge::fit;
use whirl::judge::measure::Target;
use whirl::judge::section::{self, SectionTarget};

fn main() {
    divan::main();
}

fn job() -> Job {
    Job::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/trapezoidal/job.toml")).unwrap()
}

/// The job's program and the section its part has, cut with the ring off the job's, as a
/// CMM file of `count` points (those clear of the profile's edges).
fn cut(job: &Job, count: usize) -> (fit::Cut, String) {
    let machine = MachineProfile::builtin_sim().unwrap();
    let cut = fit::motion(job, &machine, None).unwrap();
    let ring = cut.ring;
    let real = Ring {
        radius: ring.radius + 0.02,
        installation: ring.installation + 0.3f64.to_radians(),
        ..ring
    };
    let z = (job.groove.z_start, job.groove.z_start + job.groove.length);
    let tool = Target::new(
        job.profile.clone(),
        Linkage {
            p: job.p(),
            ring: real,
        },
        job.groove.starts,
        z,
        job.cut.axial_feed,
    )
    .unwrap();
    let (p, pitch, length) = (job.p(), job.p() * job.period(), job.profile.length());
    let at = |u: f64| job.profile.point(u).pos;
    let edges: Vec<DVec2> = (0..=20_000)
        .map(|k| length * f64::from(k) / 20_000.0)
        .filter(|&u| (at(u + 1e-6) - at(u - 1e-6)).length() < 1e-9)
        .map(at)
        .collect();
    let z_mid = (z.0 + z.1) / 2.0;
    let mut csv = String::from(
        "# section = axial\n# angle_deg = 0\n# units = mm\n# columns = rho, z\n# origin = 0, 0\n",
    );
    for k in 0..count {
        let u = length * (k as f64 + 0.5) / count as f64;
        if edges.iter().any(|e| (at(u) - *e).length() < 0.1) {
            continue;
        }
        let point = job.profile.point(u);
        let phi = point.pos.to_angle();
        let j = ((z_mid + p * phi) / pitch).round();
        let zu = -p * phi + j * pitch;
        let start = (-(j as i64)).rem_euclid(i64::from(job.groove.starts)) as u32;
        let error = tool.error_at_u(&cut.motion, u, start, zu);
        let n = surface_normal(point.pos, point.tangent, p);
        let radial = point.pos.normalize();
        let in_plane = DVec2::new(n.x * radial.x + n.y * radial.y, n.z);
        let q = DVec2::new(point.pos.length(), zu) + in_plane / in_plane.length().powi(2) * error;
        csv.push_str(&format!("{:.4},{:.4}\n", q.x, q.y));
    }
    (cut, csv)
}

/// Reading the file and finding every point's foot and deviation.
#[divan::bench(args = [50, 200, 1000], sample_count = 5)]
fn deviations(bencher: Bencher, points: usize) {
    let job = job();
    let (_, csv) = cut(&job, points);
    bencher.bench(|| {
        let measured = section::read(&csv, &[]).unwrap();
        let target = SectionTarget::new(&job, measured.frame.plane);
        black_box(target.deviations(&measured).unwrap().max_overcut_mm)
    });
}

/// The fit of ring radius, nose radius and installation angle through the engine.
#[divan::bench(args = [50, 200], sample_count = 3)]
fn fit_tool(bencher: Bencher, points: usize) {
    let job = job();
    let (cut, csv) = cut(&job, points);
    let measured = section::read(&csv, &[]).unwrap();
    let d = SectionTarget::new(&job, measured.frame.plane)
        .deviations(&measured)
        .unwrap();
    let once = fit::fit(&job, &cut, &d.points).unwrap();
    eprintln!(
        "{} points: ring radius {:.5} ± {:.5} mm, angle {:.4} ± {:.4}°, {} steps",
        once.points,
        once.ring_radius_mm.fitted,
        once.ring_radius_mm.standard_error,
        once.installation_angle_deg.fitted,
        once.installation_angle_deg.standard_error,
        once.steps
    );
    bencher.bench(|| black_box(fit::fit(&job, &cut, &d.points).unwrap().steps));
}
