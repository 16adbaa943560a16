//! Swept-section benchmarks: seed 000's groove (Dogrusadik, Table 1) by the section method at
//! 0.1 µm, and by the grazing condition.
//!
//! Run with `cargo bench --bench sweep`; the point counts are printed first.

use divan::{black_box, Bencher};
use whirl::papers::grazing::{section_points, ParaboloidCap};
use whirl::papers::helix::Helix;
use whirl::papers::section::{run_paraboloid, top_at, upper_boundary};
use whirl::papers::tool::Paraboloid;

/// Table 1: R = 20 mm, a = −0.05 1/mm, b = 7.2 mm, p = 20 mm.
const TOOL: Paraboloid = Paraboloid { a: -0.05, b: 7.2 };

fn helix() -> Helix {
    Helix::one_turn(20.0, 20.0)
}

fn main() {
    for accuracy in [1e-4, 1e-6] {
        match upper_boundary(&TOOL, &helix(), (-32.0, -8.0), accuracy) {
            Ok(points) => eprintln!(
                "seed 000 section at {accuracy:e} mm: {} points",
                points.len()
            ),
            Err(e) => eprintln!("seed 000 section at {accuracy:e} mm failed: {e}"),
        }
    }
    eprintln!(
        "grazing, 2000 meridian steps: {} points",
        section_points(&ParaboloidCap::from(TOOL), &helix(), 2000).len()
    );
    divan::main();
}

/// The whole groove, x ∈ [−32, −8], within 0.1 µm (the CLI's default).
#[divan::bench]
fn section_seed000_0_1_um(bencher: Bencher) {
    let h = helix();
    bencher.bench(|| upper_boundary(&TOOL, black_box(&h), (-32.0, -8.0), black_box(1e-4)));
}

/// The same within 1 nm.
#[divan::bench]
fn section_seed000_1_nm(bencher: Bencher) {
    let h = helix();
    bencher.bench(|| upper_boundary(&TOOL, black_box(&h), (-32.0, -8.0), black_box(1e-6)));
}

/// The CLI's text, end to end.
#[divan::bench]
fn run_paraboloid_seed000(bencher: Bencher) {
    bencher.bench(|| run_paraboloid(-0.05, 7.2, 20.0, black_box(20.0), 1e-4));
}

/// One evaluation of Y(x): scan, edge bisection, golden section.
#[divan::bench(args = [-31.99, -20.0, -8.05])]
fn top_at_one_x(bencher: Bencher, x: f64) {
    let h = helix();
    bencher.bench(|| top_at(&TOOL, &h, black_box(x)));
}

/// The grazing method over 2000 meridian steps of the cap (closed form per step).
#[divan::bench]
fn grazing_seed000(bencher: Bencher) {
    let h = helix();
    let cap = ParaboloidCap::from(TOOL);
    bencher.bench(|| section_points(&cap, black_box(&h), black_box(2000)));
}
