//! Reading a profile from a CAD drawing of 10 000 entities: the eccentric lobe of
//! `tests/integration/drawings.rs` (the circle of radius 10 mm about (1.5, 0), one start)
//! drawn as 10 000 LINEs, written here with the `dxf` crate's writer; the bytes parsed, the
//! lines chained and the period taken, as a job does when it loads.
//!
//! Run with `cargo bench --bench drawing`; docs/benchmarks.md quotes the figure.

use divan::{black_box, Bencher};
use dxf::entities::{Entity, EntityType, Line};
use dxf::enums::{AcadVersion, Units};
use dxf::{Drawing, Point};
use whirl::geometry::profile::drawing::{self, Options, Section};

fn main() {
    divan::main();
}

/// The drawing's bytes: `n` lines round the circle, in mm.
fn lines(n: usize) -> Vec<u8> {
    let mut d = Drawing::new();
    d.header.version = AcadVersion::R2018;
    d.header.default_drawing_units = Units::Millimeters;
    let at = |k: usize| {
        let t = std::f64::consts::TAU * (k % n) as f64 / n as f64;
        Point::new(1.5 + 10.0 * t.cos(), 10.0 * t.sin(), 0.0)
    };
    for k in 0..n {
        let mut e = Entity::new(EntityType::Line(Line::new(at(k), at(k + 1))));
        e.common.layer = "GROOVE".into();
        d.add_entity(e);
    }
    let mut bytes = Vec::new();
    d.save(&mut bytes).unwrap();
    bytes
}

#[divan::bench(sample_count = 10)]
fn read_10_000_entities(bencher: Bencher) {
    let bytes = lines(10_000);
    let options = Options {
        layer: Some("GROOVE".into()),
        units: None,
        section: Section::Transverse,
        p: 40.0 / std::f64::consts::TAU,
        starts: 1,
        material: whirl::geometry::profile::Material::Inside,
    };
    bencher.bench(|| {
        let parsed = drawing::read(black_box(&bytes)).unwrap();
        drawing::profile(&parsed, &options).unwrap()
    });
}
