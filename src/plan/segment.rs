//! Δ-bounded node choice: which cutter locations of the table become program nodes.
//!
//! Between two nodes the controller moves X, Z and C linearly, so X is linear in ψ
//! (kinematics.md, "The path"). The interpolation error of a span is, to first order, the X
//! deviation of the true X(ψ) from that line times |n_M · x̂| at the contact. Nodes are chosen
//! greedily, each span reaching as far along the table as its error allows: for errors that
//! grow with a span's length this gives the fewest spans (the classic interval-cover argument).

use crate::plan::table::{Sample, Table};

/// The nodes of one period, ψ increasing; the last is the first shifted by one period.
#[derive(Debug, Clone)]
pub struct Nodes {
    /// The chosen samples.
    pub nodes: Vec<Sample>,
    /// Largest interpolation error of any span, measured on the table's samples, mm.
    pub max_error: f64,
}

impl Nodes {
    /// Number of linear spans in one period.
    pub fn per_period(&self) -> usize {
        self.nodes.len() - 1
    }
}

/// Interpolation error of the span from sample `i` to sample `j` (exclusive ends).
fn span_error(samples: &[Sample], i: usize, j: usize) -> f64 {
    let (a, b) = (&samples[i].contact, &samples[j].contact);
    let slope = (b.pose.x - a.pose.x) / (b.phase - a.phase);
    samples[i + 1..j]
        .iter()
        .map(|s| {
            let lin = a.pose.x + slope * (s.contact.phase - a.phase);
            (s.contact.pose.x - lin).abs() * s.contact.normal_x
        })
        .fold(0.0, f64::max)
}

/// Choose nodes so that every span's interpolation error stays within `budget` mm.
///
/// The table's own sampling is within its tolerance of the true X(ψ); the caller passes a
/// budget that already leaves room for it.
pub fn choose(table: &Table, budget: f64) -> Nodes {
    let samples = &table.samples;
    let last = samples.len() - 1;
    let mut nodes = vec![samples[0]];
    let mut max_error: f64 = 0.0;
    let mut i = 0;
    while i < last {
        // Reach as far as the error allows; at least one sample further.
        let mut j = i + 1;
        let mut err = 0.0;
        while j < last {
            let e = span_error(samples, i, j + 1);
            if e > budget {
                break;
            }
            j += 1;
            err = e;
        }
        max_error = max_error.max(err);
        nodes.push(samples[j]);
        i = j;
    }
    Nodes { nodes, max_error }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::linkage::{Contact, Pose};
    use glam::DVec2;

    /// A table whose X(ψ) is a parabola X = ψ², with |n·x̂| = 1.
    fn parabola(n: usize) -> Table {
        let samples = (0..=n)
            .map(|k| {
                let psi = k as f64 / n as f64;
                Sample {
                    u: psi,
                    pos: DVec2::ZERO,
                    contact: Contact {
                        pose: Pose {
                            x: psi * psi,
                            c: psi,
                            z: 0.0,
                        },
                        phase: psi,
                        normal_x: 1.0,
                    },
                }
            })
            .collect();
        Table {
            samples,
            period: 1.0,
        }
    }

    #[test]
    fn spans_of_a_parabola_have_the_chord_length_its_curvature_allows() {
        // For X = ψ² a chord of width w deviates by w²/4 at its middle, so a budget e allows
        // spans of width 2√e: ⌈1 / (2√e)⌉ spans over [0, 1].
        for budget in [2e-2, 3e-3, 5e-5] {
            let nodes = choose(&parabola(20_000), budget);
            let expected = (1.0 / (2.0 * f64::sqrt(budget))).ceil() as usize;
            assert_eq!(nodes.per_period(), expected, "budget {budget}");
            assert!(nodes.max_error <= budget);
            for pair in nodes.nodes.windows(2) {
                let w = pair[1].contact.phase - pair[0].contact.phase;
                assert!(w * w / 4.0 <= budget * (1.0 + 1e-9), "{w}");
            }
        }
    }

    #[test]
    fn a_straight_table_needs_one_span() {
        let mut t = parabola(100);
        for s in &mut t.samples {
            s.contact.pose.x = 3.0 - 2.0 * s.contact.phase;
        }
        assert_eq!(choose(&t, 1e-9).per_period(), 1);
    }
}
