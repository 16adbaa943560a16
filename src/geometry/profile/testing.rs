//! Shapes shared by the unit tests.

use super::points::{profile, Row, Section};
use super::Profile;
use std::f64::consts::TAU;

/// The three-lobe groove ρ(φ) = 30 − 5·cos 3φ of tests/data/linkage-vectors.csv,
/// 24 points of one period, for lead `lead` (right hand).
pub fn lobe(lead: f64) -> Profile {
    let rows: Vec<Row> = (0..24)
        .map(|k| {
            let phi = TAU / 3.0 * k as f64 / 24.0;
            let rho = 30.0 - 5.0 * (3.0 * phi).cos();
            Row {
                line: k + 1,
                a: rho * phi.cos(),
                b: rho * phi.sin(),
            }
        })
        .collect();
    profile(&rows, Section::Transverse, false, lead / TAU, 3).expect("a valid profile")
}
