//! Δ-bounded node choice: where the program's nodes go in one period.
//!
//! Between two nodes the controller moves X, Z and C linearly, so X is linear in ψ
//! (kinematics.md, "The path"), and an X error δX at a contact moves the surface by
//! `n_x·δX` to first order, n the outward normal there in the machine frame (negative:
//! overcut). The nodes need not lie on the table: the
//! polyline is a *best approximation* of X(ψ), free to pass on either side of it, within a
//! corridor around the table that each sample's rooms set ([`Rooms`]): how deep the polyline may
//! cut there and how much it may leave. An interpolating polyline puts a span's whole error on
//! one side; one that may leave the table splits it over both, and spans grow by up to √2 for
//! the same error.
//!
//! The fewest spans through the corridor: each span reaches as far along the table as some line
//! through the corridor allows, starting from any point the previous span can end at (the
//! window of Imai and Iri's piecewise-linear approximation). The lines a span may take form a
//! convex polygon in the plane of (start value, slope), cut down by two half-planes per
//! sample; the span ends where the next sample would leave it empty. Their number fixed, the
//! breakpoints are then balanced (`balanced`): a controller that takes a block a scan or a
//! cycle runs a move shorter than that slower than planned, and reaching as far as each span
//! can leaves the period's slack to a sliver at its end. A backward pass then picks each vertex
//! in the middle of what the span after it allows. The pattern is periodic: it starts and ends
//! at the same X, chosen among a few values across the first sample's corridor for the fewest
//! spans, and of those, the longest shortest span.

use crate::config::job::Job;
use crate::geometry::linkage::{turn, Linkage, Pose};
use crate::plan::budget::{self, Budget};
use crate::plan::path::{Node, PathSpec};
use crate::plan::scallop::Scallops;
use crate::plan::table::Table;
use glam::{DVec2, DVec3};
use serde::Serialize;
use std::f64::consts::TAU;

/// The nodes of one period, ψ increasing; the last is the first shifted by one period.
#[derive(Debug, Clone, PartialEq)]
pub struct Nodes {
    /// The pattern.
    pub nodes: Vec<Node>,
    /// Largest overcut of the polyline against the table at its samples, to first order, mm.
    pub overcut: f64,
    /// Largest undercut, likewise, mm.
    pub undercut: f64,
}

impl Nodes {
    /// The pattern `nodes` over `table`, with its largest errors against it.
    fn new(table: &Table, nodes: Vec<Node>) -> Nodes {
        let mut out = Nodes {
            nodes,
            overcut: 0.0,
            undercut: 0.0,
        };
        let errors = out.errors(table);
        out.overcut = errors.iter().map(|e| -e).fold(0.0, f64::max);
        out.undercut = errors.iter().copied().fold(0.0, f64::max);
        out
    }

    /// Number of linear spans in one period.
    pub fn per_period(&self) -> usize {
        self.nodes.len() - 1
    }

    /// The normal error of the polyline at every table sample, to first order, mm (negative:
    /// overcut): `n_x·(X_polyline(ψ) − X(ψ))`.
    pub fn errors(&self, table: &Table) -> Vec<f64> {
        let mut k = 0;
        table
            .samples
            .iter()
            .map(|s| {
                let psi = s.contact.phase;
                while k + 2 < self.nodes.len() && self.nodes[k + 1].phase <= psi {
                    k += 1;
                }
                let (a, b) = (self.nodes[k], self.nodes[k + 1]);
                let x = a.x + (psi - a.phase) / (b.phase - a.phase) * (b.x - a.x);
                s.normal.x * (x - s.contact.pose.x)
            })
            .collect()
    }
}

/// What the sweep engine measured of the program a choice of nodes makes.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Measured {
    /// Largest overcut, mm (≥ 0).
    pub overcut_mm: f64,
    /// Largest undercut, mm (≥ 0): what a pass left where it touches, with the scallop to the
    /// next pass and the insert cusp at that profile point.
    pub undercut_mm: f64,
    /// Target points measured.
    pub points: usize,
    /// Node choices planned and measured up to this one, this one included.
    pub rounds: usize,
}

/// A choice of nodes and the profile error it is held to.
#[derive(Debug, Clone, PartialEq)]
pub struct Choice {
    /// The nodes.
    pub nodes: Nodes,
    /// The profile error the program is held to, mm: the budget's bound, or what was measured
    /// plus what the measurement cannot see.
    pub max_error: f64,
    /// The measurement, when the nodes were measured.
    pub measured: Option<Measured>,
}

/// Why no nodes could be chosen.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct NodeError(pub String);

/// What a choice of nodes works from: the table, the budget and the rooms they leave, and the
/// path the nodes will make.
#[derive(Debug, Clone, Copy)]
pub struct Problem<'a> {
    /// The job.
    pub job: &'a Job,
    /// The linkage (lead and ring).
    pub linkage: &'a Linkage,
    /// The cutter-location table of one period.
    pub table: &'a Table,
    /// How Δ is shared.
    pub budget: &'a Budget,
    /// The feed scallop along the profile.
    pub scallops: &'a Scallops,
    /// How far the table's polyline may be from the true X(ψ), as a normal error, mm.
    pub table_accuracy: f64,
    /// The rounding of the numbers the controller moves to, written and held: of X and of Z
    /// each, and of C as the distance it turns the groove along its screw (|p| per radian),
    /// mm. Their sum, counting X and Z once each, is the budget's `rounding`; at a contact
    /// whose normal is n they move the surface by at most
    /// `rounding[0]·(|n_x| + |n_z|) + rounding[1]·|n_z|` (a turn δc of C acts as an axial shift
    /// p·δc).
    pub rounding: [f64; 2],
    /// The whole groove's path, but for its nodes.
    pub spec: &'a PathSpec,
}

impl Problem<'_> {
    /// The ring along one pass of this job's path.
    pub fn pass(&self) -> Pass<'_> {
        Pass::new(self.linkage, self.spec.feed)
    }

    /// The insert cusp at every table sample, mm.
    pub fn cusps(&self) -> Vec<f64> {
        let cut = &self.job.cut;
        let turn = budget::insert_turn(self.job.tool.inserts, cut.workpiece_rpm, cut.ring_rpm);
        self.table
            .samples
            .iter()
            .map(|s| budget::cusp_at(s.pos.length(), self.linkage, turn))
            .collect()
    }

    /// The rounding at every sample, mm (see [`Problem::rounding`]).
    pub fn roundings(&self) -> Vec<f64> {
        let [linear, angular] = self.rounding;
        self.table
            .samples
            .iter()
            .map(|s| linear * (s.normal.x.abs() + s.normal.z.abs()) + angular * s.normal.z.abs())
            .collect()
    }

    /// The rooms the budget leaves interpolation at every sample: Δ less what adds to an
    /// overcut there (blending, the profile's fit, that sample's rounding, the table's
    /// accuracy), and less what
    /// adds to an undercut there (also its scallop, its cusp and the concave stretches).
    pub fn rooms(&self) -> Rooms {
        let b = self.budget;
        let (cusps, roundings) = (self.cusps(), self.roundings());
        let over = |i: usize| b.delta - b.blend - b.fit - roundings[i] - self.table_accuracy;
        Rooms {
            overcut: (0..cusps.len()).map(over).collect(),
            undercut: (0..cusps.len())
                .map(|i| over(i) - b.concave - self.scallops.near(i) - cusps[i])
                .collect(),
        }
    }

    /// The bound the budget puts on the program of `nodes`: at every sample, the
    /// interpolation error there plus what adds to it there, each side.
    pub fn bound(&self, nodes: &Nodes) -> f64 {
        let b = self.budget;
        let (cusps, roundings) = (self.cusps(), self.roundings());
        nodes
            .errors(self.table)
            .iter()
            .enumerate()
            .map(|(i, e)| {
                let common = self.table_accuracy + b.blend + b.fit + roundings[i];
                let under = e + self.scallops.near(i) + cusps[i] + b.concave;
                (common - e).max(common + under)
            })
            .fold(0.0, f64::max)
    }
}

/// How a planner chooses its nodes.
pub trait NodeChoice {
    /// The nodes for `problem`.
    fn choose(&self, problem: &Problem) -> Result<Choice, NodeError>;
}

/// The nodes the error budget alone allows: its rooms at every sample, its bound. Plain
/// geometry, what `plan::plan` uses; the judge's measured choice starts from it.
#[derive(Debug, Clone, Copy, Default)]
pub struct Estimated;

impl NodeChoice for Estimated {
    fn choose(&self, problem: &Problem) -> Result<Choice, NodeError> {
        let nodes = approximate(problem.table, &problem.rooms(), &problem.pass());
        Ok(Choice {
            max_error: problem.bound(&nodes),
            nodes,
            measured: None,
        })
    }
}

/// How far interpolation may err at every table sample, as normal errors, mm (≥ 0).
#[derive(Debug, Clone, PartialEq)]
pub struct Rooms {
    /// How deep the polyline may cut.
    pub overcut: Vec<f64>,
    /// How much it may leave.
    pub undercut: Vec<f64>,
}

impl Rooms {
    /// The rooms with the overcut side scaled by `overcut` and the undercut side by `undercut`.
    pub fn scaled(&self, overcut: f64, undercut: f64) -> Rooms {
        Rooms {
            overcut: self.overcut.iter().map(|r| r * overcut).collect(),
            undercut: self.undercut.iter().map(|r| r * undercut).collect(),
        }
    }
}

/// Where in the first sample's corridor the pattern may start and end (0 its low edge, 1 its
/// high), middle first: of equally short patterns, the one nearest the middle.
const CLOSURES: [f64; 5] = [0.5, 0.3, 0.7, 0.1, 0.9];
/// Slack on each side of a constraint, mm: keeps a corridor that closes to a point feasible in
/// floating point.
const SLACK: f64 = 1e-12;

/// One pass of the ring over its groove, as the node choice sees it.
#[derive(Debug, Clone, Copy)]
pub struct Pass<'a> {
    /// The linkage (lead and ring).
    pub linkage: &'a Linkage,
    /// dZ/dψ along the path, mm/rad: Z = Z₀ + f·C/2π and ψ = C + Z/p give f·p/(2πp + f).
    pub drift: f64,
}

impl Pass<'_> {
    /// The pass of `linkage` at `feed` mm per workpiece revolution.
    pub fn new(linkage: &Linkage, feed: f64) -> Pass<'_> {
        let p = linkage.p;
        Pass {
            linkage,
            drift: feed * p / (TAU * p + feed),
        }
    }

    /// How far sample `j`'s pose may move in X, `(below, above)` at most, before it cuts a
    /// profile point beside its own on the same pass deeper than that point's overcut room:
    /// `gap + slope·δ ≥ −room` at every sample k whose gap to the pose is within reach, the
    /// gap and its slope in X measured on the torus. The scan runs out from j both ways,
    /// round the period, until the gap exceeds anything the pose's X error could undo.
    fn held_by_neighbours(
        &self,
        table: &Table,
        rooms: &Rooms,
        j: usize,
        (mut below, mut above): (f64, f64),
    ) -> (f64, f64) {
        let samples = &table.samples;
        let last = samples.len() as i64 - 1;
        let s = &samples[j];
        let over_max = rooms.overcut.iter().fold(0.0, |a: f64, &b| a.max(b));
        let reach = below.max(above) + over_max;
        for dir in [-1, 1] {
            for step in 1..last {
                // Sample k along the unwrapped table: sample i, m periods on.
                let k = j as i64 + dir * step;
                let (m, i) = (k.div_euclid(last), k.rem_euclid(last) as usize);
                let turned = m as f64 * table.period;
                let at = DVec2::from_angle(turned).rotate(samples[i].pos);
                // Sample j's pose on the pass that touches sample k.
                let psi_k = samples[i].contact.phase + turned;
                let z = samples[i].contact.pose.z + self.drift * (s.contact.phase - psi_k);
                let pose = Pose {
                    x: s.contact.pose.x,
                    c: s.contact.phase - z / self.linkage.p,
                    z,
                };
                let (gap, slope) = self.gap_and_slope(DVec3::new(at.x, at.y, 0.0), &pose);
                if gap > reach {
                    break;
                }
                let room = rooms.overcut[i].max(0.0) + gap.max(0.0);
                if slope < 0.0 {
                    above = above.min(room / -slope);
                } else if slope > 0.0 {
                    below = below.min(room / slope);
                }
            }
        }
        (below, above)
    }

    /// The gap between the surface point `q` (workpiece frame) and the ring at `pose`, and
    /// how fast it changes with the pose's X (−x̂ along the unit vector from the nearest point
    /// of the tip circle to the point).
    fn gap_and_slope(&self, q: DVec3, pose: &Pose) -> (f64, f64) {
        let torus = self.linkage.torus(pose);
        let d = turn(q, pose.c) - torus.centre;
        let along = d.dot(torus.axis);
        let radial = d - along * torus.axis;
        let w = d - radial.normalize_or_zero() * torus.radius;
        let len = w.length();
        let slope = if len > 0.0 { -w.x / len } else { 0.0 };
        (len - torus.nose, slope)
    }
}

/// The corridor of X around the table: at sample i, X may lie in `[lo[i], hi[i]]`.
struct Corridor {
    psi: Vec<f64>,
    /// The table's X at each sample, which a span's lines are taken relative to, mm.
    x: Vec<f64>,
    lo: Vec<f64>,
    hi: Vec<f64>,
    /// Larger than the slope of any line that stays in the corridor, mm/rad.
    slope: f64,
}

impl Corridor {
    /// X within the rooms at every sample. To first order an X error δ at sample i's pose
    /// moves the surface there by `n_x·δ`; where that barely sees X (|n_x| small),
    /// the second-order term of a sideways shift s of the torus, about s²/(2r) for nose
    /// radius r, is held to a tenth of the room by keeping |s| ≤ √(room·r/5).
    ///
    /// An overcut is also what a pose cuts at the profile points *beside* its own: the error
    /// at a point is the least gap over every pose that passes it, and where the ring fits the
    /// groove closely (a root fillet barely larger than the nose) a pose reaches its
    /// neighbours with little gap to spare, and more of its X error when their normals see X
    /// more than its own does. So each pose is also held by its neighbours on the same pass:
    /// `gap + slope·δ ≥ −overcut room` there, the gap and its slope in X measured on the
    /// torus, out to where the gap exceeds anything δ could undo.
    fn new(table: &Table, rooms: &Rooms, pass: &Pass) -> Corridor {
        let nose = pass.linkage.ring.nose;
        let samples = &table.samples;
        let n = samples.len();
        let last = n - 1;
        let (mut lo, mut hi) = (Vec::with_capacity(n), Vec::with_capacity(n));
        for (j, s) in samples.iter().enumerate() {
            let (over, under) = (rooms.overcut[j].max(0.0), rooms.undercut[j].max(0.0));
            let effect = s.normal.x.abs();
            let cap = |room: f64| {
                let first = if effect > 0.0 {
                    room / effect
                } else {
                    f64::INFINITY
                };
                first.min((room * nose / 5.0).sqrt())
            };
            // n_x < 0: a larger X cuts deeper.
            let (mut below, mut above) = if s.normal.x < 0.0 {
                (cap(under), cap(over))
            } else {
                (cap(over), cap(under))
            };
            if j < last {
                (below, above) = pass.held_by_neighbours(table, rooms, j, (below, above));
            }
            lo.push(s.contact.pose.x - below);
            hi.push(s.contact.pose.x + above);
        }
        // The last sample is the first one period on: the same corridor.
        lo[last] = lo[0];
        hi[last] = hi[0];
        let psi: Vec<f64> = samples.iter().map(|s| s.contact.phase).collect();
        let x = samples.iter().map(|s| s.contact.pose.x).collect();
        let slope = (1..n)
            .map(|i| {
                let d = psi[i] - psi[i - 1];
                ((hi[i] - lo[i - 1]).abs().max((lo[i] - hi[i - 1]).abs())) / d
            })
            .fold(1.0, f64::max)
            * 2.0;
        Corridor {
            psi,
            x,
            lo,
            hi,
            slope,
        }
    }

    /// The same corridor taken backwards: the samples in reverse order, ψ negated.
    fn reversed(&self) -> Corridor {
        let back = |v: &[f64]| v.iter().rev().copied().collect::<Vec<f64>>();
        Corridor {
            psi: self.psi.iter().rev().map(|p| -p).collect(),
            x: back(&self.x),
            lo: back(&self.lo),
            hi: back(&self.hi),
            slope: self.slope,
        }
    }
}

/// A convex polygon in the plane of (start value relative to the span's table X, slope).
#[derive(Debug, Clone, Default)]
struct Polygon(Vec<[f64; 2]>);

impl Polygon {
    /// Start values in `[lo, hi]`, slopes within ±`slope`.
    fn rect(lo: f64, hi: f64, slope: f64) -> Polygon {
        Polygon(vec![[lo, -slope], [hi, -slope], [hi, slope], [lo, slope]])
    }

    /// The part of `self` where x + d·s ≤ c (or ≥ c with `above`), into `out`.
    fn clip(&self, d: f64, c: f64, above: bool, out: &mut Polygon) {
        out.0.clear();
        let sign = if above { -1.0 } else { 1.0 };
        let f = |v: &[f64; 2]| sign * (v[0] + d * v[1] - c);
        let n = self.0.len();
        for k in 0..n {
            let (p, q) = (self.0[k], self.0[(k + 1) % n]);
            let (fp, fq) = (f(&p), f(&q));
            if fp <= 0.0 {
                out.0.push(p);
            }
            if (fp < 0.0 && fq > 0.0) || (fp > 0.0 && fq < 0.0) {
                let t = fp / (fp - fq);
                out.0
                    .push([p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])]);
            }
        }
    }

    /// The part where `lo ≤ x + d·s ≤ hi`, into `out` (`tmp` is scratch).
    fn band(&self, d: f64, lo: f64, hi: f64, tmp: &mut Polygon, out: &mut Polygon) {
        self.clip(d, hi, false, tmp);
        tmp.clip(d, lo, true, out);
    }

    /// The middle of the start values x of the lines whose x + d·s is `end`.
    fn start_ending_at(&self, d: f64, end: f64) -> f64 {
        let (mut tmp, mut on) = (Polygon::default(), Polygon::default());
        self.band(d, end - SLACK, end + SLACK, &mut tmp, &mut on);
        if on.0.is_empty() {
            // Only rounding can leave none, `end` being within the range of x + d·s: the
            // line that ends nearest.
            let off = |v: &[f64; 2]| (v[0] + d * v[1] - end).abs();
            return self
                .0
                .iter()
                .min_by(|p, q| off(p).total_cmp(&off(q)))
                .map_or(end, |v| v[0]);
        }
        let (a, b) = on.range(0.0);
        (a + b) / 2.0
    }

    /// The range of x + d·s over the polygon.
    fn range(&self, d: f64) -> (f64, f64) {
        self.0
            .iter()
            .map(|v| v[0] + d * v[1])
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), y| {
                (a.min(y), b.max(y))
            })
    }
}

/// One span of the forward pass: from sample `a` to sample `b`, and the lines it may take.
struct Span {
    a: usize,
    b: usize,
    lines: Polygon,
}

/// Spans through the corridor from `start` at the first sample to `start` at the last, each
/// reaching as far as it can but no further than `stop(k, a)` for the k-th span (from 0)
/// starting at sample `a`. With no stop short of the last sample, the fewest spans.
fn spans(c: &Corridor, start: f64, stop: impl Fn(usize, usize) -> usize) -> Vec<Span> {
    let last = c.psi.len() - 1;
    // The pattern closes: it ends where it starts.
    let bounds = |i: usize| {
        if i == last || i == 0 {
            (start - SLACK, start + SLACK)
        } else {
            (c.lo[i] - SLACK, c.hi[i] + SLACK)
        }
    };
    let mut out = Vec::new();
    let (mut a, mut window) = (0, bounds(0));
    let (mut tmp, mut next) = (Polygon::default(), Polygon::default());
    while a < last {
        let xa = c.x[a];
        let end = stop(out.len(), a).min(last);
        let mut lines = Polygon::rect(window.0 - xa, window.1 - xa, c.slope);
        let mut b = a;
        while b < end {
            let (lo, hi) = bounds(b + 1);
            lines.band(
                c.psi[b + 1] - c.psi[a],
                lo - xa,
                hi - xa,
                &mut tmp,
                &mut next,
            );
            if next.0.is_empty() {
                break;
            }
            std::mem::swap(&mut lines, &mut next);
            b += 1;
        }
        // One sample further is always reachable: the slopes allowed reach from anywhere in
        // the corridor to anywhere in the next sample's.
        assert!(
            b > a,
            "a span through the corridor reaches no further sample"
        );
        let (lo, hi) = lines.range(c.psi[b] - c.psi[a]);
        window = (lo + xa, hi + xa);
        out.push(Span { a, b, lines });
        a = b;
    }
    out
}

/// The fewest spans at `start` ([`spans`]) with their breakpoints balanced: no span shorter
/// than it need be. `None` where balancing does not keep their number.
///
/// Each span reaching as far as it can puts the slack of the whole period into the last
/// span, which may end up a sliver (left-external on the PLC: 5.1 ms among spans of 30 to
/// 60). Taken backwards from the end, the same greedy reach gives how early each breakpoint
/// may lie and still leave the rest of the period to the spans after it; taken forwards it
/// gives how late. Between the two, each span here ends as near as it can to an even share of
/// what is left of the period (ψ runs at a steady rate, so that is an even share of the time),
/// and no earlier than the spans after it need.
fn balanced(c: &Corridor, start: f64, count: usize) -> Option<Vec<Span>> {
    let last = c.psi.len() - 1;
    let back = spans(&c.reversed(), start, |_, _| usize::MAX);
    if back.len() != count {
        return None;
    }
    // The earliest end of the k-th span: where the backward spans, count − 1 − k of them from
    // the end, reach back to; the last sample for the last span (or any past it, where the
    // spans come to more than `count` after all).
    let earliest = |k: usize| match count.checked_sub(k + 2) {
        Some(j) => last - back[j].b,
        None => last,
    };
    let chosen = spans(c, start, |k, a| {
        let left = count.saturating_sub(k).max(1);
        let share = c.psi[a] + (c.psi[last] - c.psi[a]) / left as f64;
        let even = c.psi.partition_point(|&psi| psi < share);
        even.max(earliest(k))
    });
    (chosen.len() == count).then_some(chosen)
}

/// The best approximation of the table's X(ψ) within `rooms` by the fewest spans (see the
/// module's comment), for the ring along `pass`, its breakpoints balanced.
pub fn approximate(table: &Table, rooms: &Rooms, pass: &Pass) -> Nodes {
    let c = Corridor::new(table, rooms, pass);
    let (lo, hi) = (c.lo[0], c.hi[0]);
    let greedy: Vec<(f64, Vec<Span>)> = CLOSURES
        .iter()
        .map(|t| lo + (hi - lo) * t)
        .map(|v| (v, spans(&c, v, |_, _| usize::MAX)))
        .collect();
    let fewest = greedy
        .iter()
        .map(|(_, s)| s.len())
        .min()
        .expect("at least one start");
    // Of the closures with the fewest spans, the one whose shortest balanced span is longest;
    // the first unbalanced if none balances.
    let shortest = |s: &[Span]| {
        s.iter()
            .map(|span| c.psi[span.b] - c.psi[span.a])
            .fold(f64::INFINITY, f64::min)
    };
    let (start, best) = greedy
        .iter()
        .filter(|(_, s)| s.len() == fewest)
        .filter_map(|&(v, _)| balanced(&c, v, fewest).map(|s| (v, s)))
        .max_by(|(_, a), (_, b)| shortest(a).total_cmp(&shortest(b)))
        .unwrap_or_else(|| {
            greedy
                .into_iter()
                .find(|(_, s)| s.len() == fewest)
                .expect("a start with the fewest spans")
        });
    // Backwards: each vertex in the middle of the start values the span allows, given where
    // it ends.
    let mut xs = vec![start; best.len() + 1];
    for (k, span) in best.iter().enumerate().rev() {
        let xa = c.x[span.a];
        let d = c.psi[span.b] - c.psi[span.a];
        xs[k] = xa + span.lines.start_ending_at(d, xs[k + 1] - xa);
    }
    xs[0] = start;
    let mut nodes: Vec<Node> = best
        .iter()
        .zip(&xs)
        .map(|(span, &x)| Node {
            phase: c.psi[span.a],
            x,
        })
        .collect();
    nodes.push(Node {
        phase: c.psi[c.psi.len() - 1],
        x: start,
    });
    Nodes::new(table, nodes)
}

/// The planner's node choice before the best approximation, kept for the tests that compare
/// against it: nodes on the table, each span reaching as far as its interpolation error
/// `|ΔX|·|n_x|` at the samples allows within `tolerance`.
#[cfg(test)]
pub(crate) fn interpolating(table: &Table, tolerance: f64) -> Nodes {
    let samples = &table.samples;
    let error = |i: usize, j: usize| {
        let (a, b) = (&samples[i].contact, &samples[j].contact);
        let slope = (b.pose.x - a.pose.x) / (b.phase - a.phase);
        samples[i + 1..j]
            .iter()
            .map(|s| {
                let line = a.pose.x + slope * (s.contact.phase - a.phase);
                (s.contact.pose.x - line).abs() * s.contact.normal_x
            })
            .fold(0.0, f64::max)
    };
    let node = |i: usize| Node {
        phase: samples[i].contact.phase,
        x: samples[i].contact.pose.x,
    };
    let last = samples.len() - 1;
    let (mut i, mut nodes) = (0, vec![node(0)]);
    while i < last {
        let mut j = i + 1;
        while j < last && error(i, j + 1) <= tolerance {
            j += 1;
        }
        nodes.push(node(j));
        i = j;
    }
    Nodes::new(table, nodes)
}

/// The planner's choice before the best approximation: [`interpolating`] nodes within what
/// the budget left interpolation where every share peaks at once, less the table's accuracy,
/// and the bound the sum of every share.
#[cfg(test)]
pub(crate) struct Interpolating;

#[cfg(test)]
impl NodeChoice for Interpolating {
    fn choose(&self, problem: &Problem) -> Result<Choice, NodeError> {
        let b = problem.budget;
        let tolerance = b.interpolation - problem.table_accuracy;
        let nodes = interpolating(problem.table, tolerance);
        let interpolation = nodes.overcut.max(nodes.undercut);
        Ok(Choice {
            max_error: interpolation + problem.table_accuracy + b.delta - b.interpolation,
            nodes,
            measured: None,
        })
    }
}

/// A node choice that also counts the spans [`Interpolating`] needs, then chooses as `C` does.
#[cfg(test)]
pub(crate) struct AgainstInterpolation<C> {
    /// The choice made.
    pub choice: C,
    /// The interpolating planner's spans per period.
    pub interpolating: std::cell::Cell<usize>,
}

#[cfg(test)]
impl<C: NodeChoice> NodeChoice for AgainstInterpolation<C> {
    fn choose(&self, problem: &Problem) -> Result<Choice, NodeError> {
        let before = Interpolating.choose(problem)?;
        self.interpolating.set(before.nodes.per_period());
        self.choice.choose(problem)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::linkage::{Contact, Ring, Whirling};
    use crate::plan::table::Sample;

    /// A table whose X(ψ) is `x(ψ)` over [0, 1] (one period), with n_x `effect`.
    fn table(n: usize, effect: f64, x: impl Fn(f64) -> f64) -> Table {
        let samples = (0..=n)
            .map(|k| {
                let psi = k as f64 / n as f64;
                Sample {
                    u: psi,
                    pos: DVec2::ZERO,
                    contact: Contact {
                        pose: Pose {
                            x: x(psi),
                            c: psi,
                            z: 0.0,
                        },
                        phase: psi,
                        normal_x: effect.abs(),
                    },
                    normal: DVec3::new(effect, 0.0, 0.0),
                }
            })
            .collect();
        Table {
            samples,
            period: 1.0,
        }
    }

    fn rooms(n: usize, over: f64, under: f64) -> Rooms {
        Rooms {
            overcut: vec![over; n + 1],
            undercut: vec![under; n + 1],
        }
    }

    /// A ring far from the tables' made-up profile points (all at the origin), so that no
    /// pose reaches a neighbour's point, with a 1 mm nose.
    fn far_ring() -> Linkage {
        Linkage {
            p: 1.0,
            ring: Ring {
                whirling: Whirling::Internal,
                radius: 1000.0,
                nose: 1.0,
                installation: 0.0,
                edge_half_angle: std::f64::consts::FRAC_PI_2,
            },
        }
    }

    #[test]
    fn spans_of_a_periodic_parabola_split_their_error_over_both_sides() {
        // X = 4·ψ(1 − ψ) (zero at both ends, so it closes), curvature 8: a chord of width w
        // deviates from it by w², so a band of total height h = over + under allows spans of
        // width √h when the vertices may leave the curve, against √under for an interpolating
        // polyline that must keep the whole error on one side.
        let n = 20_000;
        for (over, under) in [(2e-3, 2e-3), (1e-3, 3e-3), (5e-5, 5e-5)] {
            let t = table(n, -1.0, |p| 4.0 * p * (1.0 - p));
            let nodes = approximate(&t, &rooms(n, over, under), &Pass::new(&far_ring(), 0.0));
            let best = (1.0 / (over + under).sqrt()).ceil() as usize;
            let interpolating = (1.0 / under.sqrt()).ceil() as usize;
            // Closing the pattern at one X may cost one span more than the free optimum.
            assert!(
                nodes.per_period() <= best + 1,
                "{over}/{under}: {} spans, {best} at best",
                nodes.per_period()
            );
            assert!(nodes.per_period() < interpolating, "{over}/{under}");
            assert!(nodes.overcut <= over + 1e-9, "{}", nodes.overcut);
            assert!(nodes.undercut <= under + 1e-9, "{}", nodes.undercut);
            // Between the samples too: the polyline against the true curve.
            for pair in nodes.nodes.windows(2) {
                for k in 1..10 {
                    let psi = pair[0].phase + (pair[1].phase - pair[0].phase) * k as f64 / 10.0;
                    let x = pair[0].x + (pair[1].x - pair[0].x) * k as f64 / 10.0;
                    let e = -(x - 4.0 * psi * (1.0 - psi));
                    let slack = 1e-6; // the samples are 5·10⁻⁵ apart in ψ
                    assert!(e >= -over - slack && e <= under + slack, "{psi}: {e}");
                }
            }
        }
    }

    #[test]
    fn on_a_uniform_corridor_no_span_is_shorter_than_half_the_mean() {
        // X = 4ψ(1 − ψ) has the same curvature everywhere, so every span can reach the same
        // width, √h for a band of height h: 1/√h = 10.1 takes 11 spans. Reaching as far as
        // each can leaves the last a tenth of the others' width; balanced, they share the
        // period evenly, and none is shorter than half the mean.
        let n = 20_000;
        let h = 1.0 / (10.1f64 * 10.1);
        let t = table(n, -1.0, |p| 4.0 * p * (1.0 - p));
        let r = rooms(n, h / 2.0, h / 2.0);
        let ring = far_ring();
        let pass = Pass::new(&ring, 0.0);
        let nodes = approximate(&t, &r, &pass);
        assert_eq!(nodes.per_period(), 11);
        let mean = 1.0 / nodes.per_period() as f64;
        let widths: Vec<f64> = nodes
            .nodes
            .windows(2)
            .map(|w| w[1].phase - w[0].phase)
            .collect();
        assert!(
            widths.iter().all(|&w| w >= mean / 2.0),
            "{widths:?} against a mean of {mean}"
        );
        // The greedy reach alone, at the start chosen: a sliver.
        let c = Corridor::new(&t, &r, &pass);
        let greedy = spans(&c, nodes.nodes[0].x, |_, _| usize::MAX);
        assert_eq!(greedy.len(), 11);
        let narrowest = greedy
            .iter()
            .map(|s| c.psi[s.b] - c.psi[s.a])
            .fold(f64::INFINITY, f64::min);
        assert!(narrowest < mean / 2.0, "{narrowest}");
    }

    #[test]
    fn the_sign_of_the_normal_along_x_decides_which_side_is_overcut() {
        // X = 4ψ(1 − ψ) bulges upwards. With no room to overcut, the polyline must stay where
        // it leaves material: below the curve where a larger X cuts deeper (n_x < 0,
        // internal whirling), above it where a larger X leaves more (external whirling).
        let n = 4000;
        for effect in [-1.0, 1.0] {
            let t = table(n, effect, |p| 4.0 * p * (1.0 - p));
            let nodes = approximate(&t, &rooms(n, 0.0, 1e-3), &Pass::new(&far_ring(), 0.0));
            assert!(nodes.overcut <= 1e-9, "{effect}: {}", nodes.overcut);
            assert!(nodes.undercut > 0.5e-3, "{effect}: {}", nodes.undercut);
            for node in &nodes.nodes {
                let x = 4.0 * node.phase * (1.0 - node.phase);
                assert!(effect * (node.x - x) >= -1e-9, "{effect}: {node:?}");
            }
        }
    }

    #[test]
    fn a_straight_table_needs_one_span() {
        let n = 100;
        let t = table(n, -1.0, |_| 3.0);
        let nodes = approximate(&t, &rooms(n, 1e-9, 1e-9), &Pass::new(&far_ring(), 0.0));
        assert_eq!(nodes.per_period(), 1);
    }

    #[test]
    fn where_x_barely_shows_the_second_order_term_holds_it() {
        // n_x = 0: to first order any X would do, but a sideways shift s of the torus costs
        // about s²/(2r); the corridor keeps s within √(room·r/5).
        let n = 1000;
        let x = |p: f64| (4.0 * TAU * p).sin();
        let t = table(n, 0.0, x);
        let nose: f64 = 1.0;
        let nodes = approximate(&t, &rooms(n, 1e-3, 1e-3), &Pass::new(&far_ring(), 0.0));
        let cap = (1e-3 * nose / 5.0).sqrt();
        for node in &nodes.nodes {
            assert!((node.x - x(node.phase)).abs() <= cap + 1e-9, "{node:?}");
        }
        assert!(nodes.per_period() > 4);
    }
}
