//! Planner benchmarks: node solves per second, planning whole grooves (one of 100 mm) as
//! `whirl plan` does and on the budget's estimate alone, and planning from dense profile
//! points (up to a million).
//!
//! Run with `cargo bench --bench planner`; docs/benchmarks.md quotes the figures.

use divan::{black_box, Bencher};
use glam::DVec2;
use std::f64::consts::{PI, TAU};
use whirl::config::machine::MachineProfile;
use whirl::geometry::linkage::{Linkage, Ring, Whirling};
use whirl::geometry::profile::points::{self, Section};
use whirl::geometry::profile::ProfilePoint;

mod common;
use common::example;

fn main() {
    divan::main();
}

/// 1000 points of the reference groove ρ(φ) = 30 − 5·cos 3φ (tests/data/linkage-vectors.csv).
fn lobe_points() -> Vec<ProfilePoint> {
    (0..1000)
        .map(|k| {
            let phi = TAU / 3.0 * k as f64 / 1000.0;
            let rho = 30.0 - 5.0 * (3.0 * phi).cos();
            let drho = 15.0 * (3.0 * phi).sin();
            let tangent = (DVec2::from_angle(phi) * drho + DVec2::from_angle(phi + PI / 2.0) * rho)
                .normalize();
            ProfilePoint {
                u: phi,
                pos: DVec2::from_angle(phi) * rho,
                tangent,
            }
        })
        .collect()
}

/// One linkage solve (kinematics.md: bracket near C₀, Brent), internal whirling.
#[divan::bench(counter = divan::counter::ItemsCount::new(1000usize))]
fn node_solves(bencher: Bencher) {
    let points = lobe_points();
    let linkage = Linkage {
        p: 60.0 / TAU,
        ring: Ring {
            whirling: Whirling::Internal,
            radius: 50.0,
            nose: 1.0,
            installation: 20f64.to_radians(),
            edge_half_angle: PI / 2.0,
        },
    };
    bencher.bench(|| {
        for p in &points {
            black_box(linkage.solve(black_box(p)).ok());
        }
    });
}

/// Every example job, planned whole as `whirl plan` plans it but for the file writes: nodes
/// chosen, measured by the sweep engine on a stretch of the program and chosen again
/// (`whirl::judge::refine`); `ball-screw` is a 100 mm groove at Δ = 5 µm.
#[divan::bench(args = ["double-start", "left-external", "trapezoidal", "ball-screw"], sample_count = 10)]
fn plan_example(bencher: Bencher, name: &str) {
    let job = example(name);
    let machine = MachineProfile::builtin_sim().unwrap();
    bencher.bench(|| {
        black_box(
            whirl::judge::refine::plan(&job, &machine)
                .unwrap()
                .report
                .segments,
        )
    });
}

/// `whirl plan` of the jobs that leave the installation angle to the planner, given the angle
/// the planner chooses (the middle of the window): the node choice and its measurement
/// without the window's search.
#[divan::bench(args = ["double-start", "ball-screw"], sample_count = 10)]
fn plan_at_given_angle(bencher: Bencher, name: &str) {
    let mut job = example(name);
    job.tool.installation_angle_deg = Some(whirl::plan::angles::windows(&job).unwrap().best().1);
    let machine = MachineProfile::builtin_sim().unwrap();
    bencher.bench(|| {
        black_box(
            whirl::judge::refine::plan(&job, &machine)
                .unwrap()
                .report
                .segments,
        )
    });
}

/// The same jobs planned without the engine, on the error budget's estimate alone
/// (`whirl::plan::plan`, the library's engine-free planner): what the measurement costs.
#[divan::bench(args = ["double-start", "left-external", "trapezoidal", "ball-screw"], sample_count = 10)]
fn plan_estimated(bencher: Bencher, name: &str) {
    let job = example(name);
    let machine = MachineProfile::builtin_sim().unwrap();
    bencher.bench(|| black_box(whirl::plan::plan(&job, &machine).unwrap().report.segments));
}

/// `n` points over half a period of the double-start groove, ρ = 30 − 4·cos 2φ for
/// 0 ≤ φ ≤ 90°, written to 10 decimals as a CAD export would, as the text of a points file.
fn half_period_csv(n: usize) -> String {
    let mut csv = String::from("x,y\n");
    for k in 0..n {
        let phi = PI / 2.0 * k as f64 / (n - 1) as f64;
        let rho = 30.0 - 4.0 * (2.0 * phi).cos();
        csv.push_str(&format!(
            "{:.10},{:.10}\n",
            rho * phi.cos(),
            rho * phi.sin()
        ));
    }
    csv
}

/// The double-start job (Δ = 5 µm, 24 mm of groove) from a points file of `n` points, mirrored
/// as its own profile is: reading the text, validating the points (outliers included), the
/// spline fit and the whole plan, as `whirl plan` does but for the file reads and writes.
#[divan::bench(args = [10_000, 100_000, 1_000_000], sample_count = 5)]
fn dense_profile(bencher: Bencher, n: usize) {
    plan_from_points(bencher, &half_period_csv(n), true);
}

/// The double-start job planned from the points file `csv` (a half period to mirror, or a
/// whole one), the text read and the points fitted in every round.
fn plan_from_points(bencher: Bencher, csv: &str, mirror: bool) {
    let job = example("double-start");
    let machine = MachineProfile::builtin_sim().unwrap();
    bencher.bench(|| {
        let rows = points::read_csv(black_box(csv)).unwrap();
        let mut job = job.clone();
        job.profile = points::profile(&rows, Section::Transverse, mirror, job.p(), 2).unwrap();
        black_box(
            whirl::judge::refine::plan(&job, &machine)
                .unwrap()
                .report
                .segments,
        )
    });
}

/// `n` points over one whole period of the double-start groove at 4 decimals, as a CAD
/// export at its default precision writes them, as the text of a points file.
fn period_csv_4(n: usize) -> String {
    let mut csv = String::from("x,y\n");
    for k in 0..n {
        let phi = PI * k as f64 / n as f64;
        let rho = 30.0 - 4.0 * (2.0 * phi).cos();
        csv.push_str(&format!("{:.4},{:.4}\n", rho * phi.cos(), rho * phi.sin()));
    }
    csv
}

/// Reading `n` points written to 4 decimals and fitting the profile within their rounding
/// (`geometry::profile::smoothing`), validation included: the profile alone.
#[divan::bench(args = [2_000, 200_000], sample_count = 5)]
fn fit_rounded_points(bencher: Bencher, n: usize) {
    let csv = period_csv_4(n);
    let job = example("double-start");
    bencher.bench(|| {
        let rows = points::read_csv(black_box(&csv)).unwrap();
        black_box(points::profile(&rows, Section::Transverse, false, job.p(), 2).unwrap())
    });
}

/// The same points read, fitted and the double-start job planned from them, as `whirl plan`
/// does but for the file reads and writes (issue 23: 200 000 points under 5 s).
#[divan::bench(args = [2_000, 200_000], sample_count = 3)]
fn plan_rounded_points(bencher: Bencher, n: usize) {
    plan_from_points(bencher, &period_csv_4(n), false);
}
