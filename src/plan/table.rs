//! The cutter-location table of one period: X(ψ), densely sampled and checked.
//!
//! By screw invariance (kinematics.md) every profile point has one X and one phase ψ, and the
//! whole groove's path follows from X(ψ) over one period. This module samples the profile,
//! solves the linkage at every sample, and refines until the polyline through the samples is
//! within `tolerance` of the true X(ψ) (as a normal error), so that segment selection can work
//! on samples alone. Along the way it finds what makes a profile unwhirlable: a point with no
//! pose, ψ turning back, or X jumping (the ring meeting the groove on another branch).

use crate::geometry::linkage::{turn, Contact, Linkage, LinkageError};
use crate::geometry::profile::Profile;
use glam::{DVec2, DVec3};
use std::f64::consts::TAU;

/// One solved profile sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Profile parameter.
    pub u: f64,
    /// Profile point (transverse plane), mm.
    pub pos: DVec2,
    /// The pose and its phase (unwrapped along the profile).
    pub contact: Contact,
    /// The outward unit normal at the contact in the machine frame (turned by the pose's C):
    /// to first order an error δ of the ring's X moves the surface there by `normal.x·δ`, one of
    /// its Z by `normal.z·δ` (kinematics.md: negative is overcut). The ring moving by +x̂
    /// changes a surface point's gap by the outward normal along that shift: internal
    /// whirling, which cuts on the −X side, cuts deeper with a larger X (normal.x < 0), and
    /// so does a bore head, which cuts a nut on the +X side where the normal points to the
    /// axis; external whirling leaves more (normal.x > 0).
    pub normal: DVec3,
}

/// The cutter-location table of one period, ordered by increasing phase ψ.
#[derive(Debug, Clone)]
pub struct Table {
    /// Samples, ψ strictly increasing; the last is the first shifted by one period.
    pub samples: Vec<Sample>,
    /// Polar period 2π / starts.
    pub period: f64,
}

/// Why no table could be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TableError {
    /// A profile point has no pose.
    #[error("profile point ({x:.4}, {y:.4}) (polar angle {angle_deg:.3}°): {error}")]
    Linkage {
        /// Transverse x of the point.
        x: f64,
        /// Transverse y of the point.
        y: f64,
        /// Its polar angle, degrees.
        angle_deg: f64,
        /// Why.
        error: LinkageError,
    },
    /// The phase turns back along the profile: the ring meets the groove on another branch.
    #[error(
        "interference near profile point ({x:.4}, {y:.4}) (polar angle {angle_deg:.3}°): the \
         phase ψ turns back there, so the ring would cut this stretch from another branch \
         (a flank or a neighbouring thread)"
    )]
    PhaseTurnsBack {
        /// Transverse x.
        x: f64,
        /// Transverse y.
        y: f64,
        /// Polar angle, degrees.
        angle_deg: f64,
    },
    /// X jumps between neighbouring profile points.
    #[error(
        "interference near profile point ({x:.4}, {y:.4}) (polar angle {angle_deg:.3}°): X jumps \
         by {jump:.4} mm between neighbouring profile points, so the ring meets the groove on \
         another branch"
    )]
    XJumps {
        /// Transverse x.
        x: f64,
        /// Transverse y.
        y: f64,
        /// Polar angle, degrees.
        angle_deg: f64,
        /// Size of the jump, mm.
        jump: f64,
    },
}

/// Samples per mm of profile to start from, and the largest phase step kept between samples.
const START_PER_MM: f64 = 2.0;
const MAX_PHASE_STEP: f64 = 0.5 * std::f64::consts::PI / 180.0;
/// Below this parameter step a change that will not shrink is a jump, not a slope.
const MIN_STEP: f64 = 1e-9;

impl Table {
    /// Sample `profile`, solve `linkage` at every sample and refine until the sample polyline
    /// is within `tolerance` mm (normal error) of X(ψ) and no phase step exceeds half a degree.
    pub fn build(
        profile: &Profile,
        linkage: &Linkage,
        tolerance: f64,
    ) -> Result<Table, TableError> {
        Self::sample(profile, linkage, tolerance, false)
    }

    /// [`build`](Self::build), stopping at the first sample where ψ turns back: the same table
    /// where `build` gives one, and an error wherever `build` gives one, though where ψ turns
    /// back before `build`'s own refusal the error names that sample instead. A refused angle
    /// costs the installation-angle search (`crate::plan::angles`) what the table cost up to
    /// the turn, not the refinement of every fold down to its last sample.
    pub fn probe(
        profile: &Profile,
        linkage: &Linkage,
        tolerance: f64,
    ) -> Result<Table, TableError> {
        Self::sample(profile, linkage, tolerance, true)
    }

    /// The table, `build`'s or, with `stop_at_turn`, `probe`'s.
    fn sample(
        profile: &Profile,
        linkage: &Linkage,
        tolerance: f64,
        stop_at_turn: bool,
    ) -> Result<Table, TableError> {
        let solve = |u: f64| -> Result<Sample, TableError> {
            let point = profile.point(u);
            linkage
                .solve(&point)
                .map(|contact| Sample {
                    u,
                    pos: point.pos,
                    contact,
                    normal: turn(profile.normal(&point, linkage.p), contact.pose.c),
                })
                .map_err(|error| TableError::Linkage {
                    x: point.pos.x,
                    y: point.pos.y,
                    angle_deg: point.pos.to_angle().to_degrees(),
                    error,
                })
        };
        // Start: every piece boundary and an even spread inside each piece.
        let mut us = Vec::new();
        for pair in profile.breaks().windows(2) {
            let (a, b) = (pair[0], pair[1]);
            let parts = ((b - a) * START_PER_MM).ceil().max(4.0) as usize;
            us.extend((0..parts).map(|k| a + (b - a) * k as f64 / parts as f64));
        }
        us.push(profile.length());
        let mut done: Vec<Sample> = Vec::with_capacity(us.len() * 4);
        let mut pending: Vec<Sample> = if stop_at_turn {
            let mut turns = Turns::new(profile.period());
            let mut solved = Vec::with_capacity(us.len());
            for &u in &us {
                let sample = solve(u)?;
                if let Some(last) = solved.last() {
                    if turns.sure_after(last, &sample) {
                        return Err(turned_back(&sample));
                    }
                }
                solved.push(sample);
            }
            solved.reverse();
            solved
        } else {
            us.iter()
                .rev()
                .map(|&u| solve(u))
                .collect::<Result<_, _>>()?
        };
        // Depth-first refinement: `pending` is a stack with the next sample on top.
        let mut first = pending.pop().expect("at least one sample");
        first.contact.phase = first.contact.phase.rem_euclid(TAU);
        done.push(first);
        while let Some(mut next) = pending.pop() {
            let prev = *done.last().expect("started with one sample");
            unwrap_near(&mut next, prev.contact.phase);
            let du = next.u - prev.u;
            let mid = solve(prev.u + du / 2.0).map(|mut m| {
                unwrap_near(&mut m, prev.contact.phase);
                m
            })?;
            let dev = chord_deviation(&prev, &next, &mid);
            let step = (next.contact.phase - prev.contact.phase).abs();
            if (dev > tolerance || step > MAX_PHASE_STEP) && du > MIN_STEP {
                pending.push(next);
                pending.push(mid);
                continue;
            }
            // Refinement that stopped only because the step is tiny found a discontinuity.
            let jump = (next.contact.pose.x - prev.contact.pose.x).abs();
            if du <= MIN_STEP && (jump > tolerance || step > MAX_PHASE_STEP) {
                return Err(TableError::XJumps {
                    x: mid.pos.x,
                    y: mid.pos.y,
                    angle_deg: mid.pos.to_angle().to_degrees(),
                    jump,
                });
            }
            // ψ must run one way (`check_monotonic`): a step against an earlier one, or none,
            // refuses the table whatever comes after.
            if stop_at_turn {
                let step = next.contact.phase - prev.contact.phase;
                let before = done
                    .len()
                    .checked_sub(2)
                    .map(|i| prev.contact.phase - done[i].contact.phase);
                if step == 0.0 || before.is_some_and(|b| b * step <= 0.0) {
                    return Err(turned_back(&next));
                }
            }
            done.push(next);
        }
        let period = profile.period();
        check_monotonic(&done, period)?;
        if done[done.len() - 1].contact.phase < done[0].contact.phase {
            done.reverse();
        }
        Ok(Table {
            samples: done,
            period,
        })
    }

    /// X at phase `psi` (any period), by linear interpolation between samples.
    pub fn x_at(&self, psi: f64) -> f64 {
        let first = self.samples[0].contact.phase;
        let local = first + (psi - first).rem_euclid(self.period);
        let i = self
            .samples
            .partition_point(|s| s.contact.phase <= local)
            .clamp(1, self.samples.len() - 1);
        let (a, b) = (&self.samples[i - 1].contact, &self.samples[i].contact);
        let t = (local - a.phase) / (b.phase - a.phase);
        a.pose.x + t * (b.pose.x - a.pose.x)
    }

    /// The range of Z over the period's poses (the contact sits at Z − Z_u on the workpiece).
    pub fn z_range(&self) -> (f64, f64) {
        self.samples
            .iter()
            .map(|s| s.contact.pose.z)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), z| {
                (lo.min(z), hi.max(z))
            })
    }
}

/// Shift `sample`'s phase by whole turns to lie within half a turn of `near`.
fn unwrap_near(sample: &mut Sample, near: f64) {
    let phase = &mut sample.contact.phase;
    *phase = near + (*phase - near + TAU / 2.0).rem_euclid(TAU) - TAU / 2.0;
}

/// Normal deviation of the middle sample from the straight line X(ψ) between its neighbours.
pub fn chord_deviation(a: &Sample, b: &Sample, mid: &Sample) -> f64 {
    let (pa, pb, pm) = (a.contact.phase, b.contact.phase, mid.contact.phase);
    if (pb - pa).abs() < 1e-300 {
        return (mid.contact.pose.x - a.contact.pose.x).abs() * mid.contact.normal_x;
    }
    let lin = a.contact.pose.x + (pm - pa) / (pb - pa) * (b.contact.pose.x - a.contact.pose.x);
    (mid.contact.pose.x - lin).abs() * mid.contact.normal_x
}

/// Whether ψ turns back, as far as the samples the refinement starts from show it, taken in
/// order along the profile.
///
/// Refinement only adds samples between these, so were the table to pass, ψ would run one
/// way from each to the next, over one period in all: by Δ, all of one sign. Each Δ is known
/// here only up to whole turns, as the difference w taken within ±π. Where the period is at
/// most π (two starts or more), |Δ| < π, so w = Δ: two w of opposite signs, or a zero one,
/// show the turn. With one start a single span may take more than half the period, and its
/// w then has the other sign; two such spans cannot both (they would pass a whole turn), so
/// only two w against each sign show it.
struct Turns {
    /// Spans a passing table may have against its direction: 0, or 1 with one start.
    allowed: usize,
    /// Spans seen with w ≤ 0, and with w ≥ 0.
    not_up: usize,
    not_down: usize,
}

impl Turns {
    fn new(period: f64) -> Turns {
        Turns {
            allowed: usize::from(period > std::f64::consts::PI),
            not_up: 0,
            not_down: 0,
        }
    }

    /// Counts the span from `a` to `b`; whether the table is now sure to be refused.
    fn sure_after(&mut self, a: &Sample, b: &Sample) -> bool {
        let d = b.contact.phase - a.contact.phase;
        let w = d - TAU * (d / TAU).round();
        self.not_up += usize::from(w <= 0.0);
        self.not_down += usize::from(w >= 0.0);
        self.not_up > self.allowed && self.not_down > self.allowed
    }
}

/// The refusal of a table whose phase turns back at `s`.
fn turned_back(s: &Sample) -> TableError {
    TableError::PhaseTurnsBack {
        x: s.pos.x,
        y: s.pos.y,
        angle_deg: s.pos.to_angle().to_degrees(),
    }
}

/// ψ must run one way over the whole period and cover exactly one period.
fn check_monotonic(samples: &[Sample], period: f64) -> Result<(), TableError> {
    let total = samples[samples.len() - 1].contact.phase - samples[0].contact.phase;
    let dir = total.signum();
    for pair in samples.windows(2) {
        if (pair[1].contact.phase - pair[0].contact.phase) * dir <= 0.0 {
            return Err(turned_back(&pair[1]));
        }
    }
    if (total.abs() - period).abs() > 1e-6 {
        // The phase wound a different amount than one period: somewhere it ran off the branch.
        return Err(turned_back(&samples[samples.len() / 2]));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::linkage::{Ring, Whirling};
    use crate::geometry::profile::testing::lobe;
    use std::f64::consts::PI;

    fn linkage(radius: f64, delta_deg: f64, lead: f64) -> Linkage {
        Linkage {
            p: lead / TAU,
            ring: Ring {
                whirling: Whirling::Internal,
                radius,
                nose: 1.0,
                installation: delta_deg.to_radians(),
                edge_half_angle: PI / 2.0,
            },
        }
    }

    #[test]
    fn the_reference_groove_gives_a_periodic_table_within_tolerance() {
        let profile = lobe(60.0);
        let l = linkage(50.0, 20.0, 60.0);
        let t = Table::build(&profile, &l, 1e-4).unwrap();
        let (first, last) = (
            &t.samples[0].contact,
            &t.samples[t.samples.len() - 1].contact,
        );
        assert!(
            (last.phase - first.phase - TAU / 3.0).abs() < 1e-9,
            "one period of ψ"
        );
        assert!((last.pose.x - first.pose.x).abs() < 1e-9, "X repeats");
        // Between samples the polyline is within the tolerance of X(ψ): probe the middles.
        for pair in t.samples.windows(2) {
            let mid_u = (pair[0].u + pair[1].u) / 2.0;
            let mut mid = l.solve(&profile.point(mid_u)).unwrap();
            let near = pair[0].contact.phase;
            mid.phase = near + (mid.phase - near + PI).rem_euclid(TAU) - PI;
            let m = Sample {
                u: mid_u,
                pos: profile.point(mid_u).pos,
                contact: mid,
                normal: DVec3::ZERO,
            };
            assert!(chord_deviation(&pair[0], &pair[1], &m) <= 1e-4 * 1.5);
        }
    }

    #[test]
    fn the_normal_at_a_contact_is_how_its_gap_changes_with_x() {
        // Moving the ring by δ along X moves a surface point's gap by n_x·δ, n the outward
        // normal at the contact in the machine frame: negative for internal whirling, which
        // cuts on the −X side (a larger X cuts deeper), positive for external.
        let profile = lobe(60.0);
        for (whirling, radius) in [(Whirling::Internal, 50.0), (Whirling::External, 45.0)] {
            let mut l = linkage(radius, 20.0, 60.0);
            l.ring.whirling = whirling;
            let t = Table::build(&profile, &l, 1e-4).unwrap();
            for s in t.samples.iter().step_by(7) {
                let q = DVec3::new(s.pos.x, s.pos.y, 0.0);
                let h = 1e-6;
                let gap = |dx: f64| {
                    let mut pose = s.contact.pose;
                    pose.x += dx;
                    l.gap(q, &pose)
                };
                let slope = (gap(h) - gap(-h)) / (2.0 * h);
                assert!(
                    (slope - s.normal.x).abs() < 1e-6,
                    "{whirling:?}: {slope} {s:?}"
                );
                assert!((s.normal.length() - 1.0).abs() < 1e-12);
                assert!((s.normal.x.abs() - s.contact.normal_x).abs() < 1e-12);
                let cuts_deeper = s.normal.x < 0.0;
                assert_eq!(cuts_deeper, whirling == Whirling::Internal, "{s:?}");
            }
        }
    }

    #[test]
    fn a_flat_ring_gouging_a_concave_root_is_refused_as_phase_turning_back() {
        // δ = 0: the ring lies in the transverse plane, its tip arc bending towards the axis,
        // while the lobe's root (ρ = 25 at φ = 0) is concave, bending away: any tangency at
        // the root gouges its sides, and the phase turns back there.
        let e = Table::build(&lobe(60.0), &linkage(40.0, 0.0, 60.0), 1e-4).unwrap_err();
        let TableError::PhaseTurnsBack { x, y, .. } = e else {
            panic!("{e}")
        };
        assert!(
            DVec2::new(x, y).to_angle().abs() < 1f64.to_radians(),
            "at the root: {e}"
        );
    }

    #[test]
    fn a_branch_switch_is_refused_as_x_jumping() {
        // A ring barely larger than the work, tilted 20°, meets the lobe on two branches.
        let e = Table::build(&lobe(60.0), &linkage(36.5, 20.0, 60.0), 1e-4).unwrap_err();
        assert!(
            matches!(e, TableError::XJumps { jump, .. } if jump > 1e-4),
            "{e}"
        );
        assert!(e.to_string().contains("another branch"));
    }

    #[test]
    fn the_probe_builds_where_build_does_and_refuses_where_it_refuses() {
        // Across the angles, rings and leads of the refusals above (ψ turning back, a branch
        // switch, out of reach) and of tables that build; and on a one-start groove, where a
        // single span of the start samples may take more than half the period.
        let one_start = {
            let rows: Vec<crate::geometry::profile::points::Row> = (0..48)
                .map(|k| {
                    let phi = TAU * f64::from(k) / 48.0;
                    let rho = 20.0 - 2.0 * phi.cos();
                    crate::geometry::profile::points::Row {
                        line: k as usize + 1,
                        a: rho * phi.cos(),
                        b: rho * phi.sin(),
                    }
                })
                .collect();
            crate::geometry::profile::points::profile(
                &rows,
                crate::geometry::profile::points::Section::Transverse,
                false,
                10.0 / TAU,
                1,
            )
            .unwrap()
        };
        let cases = [
            (lobe(60.0), 60.0, 40.0),
            (lobe(60.0), 60.0, 50.0),
            (lobe(60.0), 60.0, 36.5),
            (lobe(5.0), 5.0, 10.0),
            (one_start, 10.0, 40.0),
        ];
        let (mut built, mut refused) = (0, 0);
        for (profile, lead, radius) in &cases {
            for step in 0..=24 {
                let l = linkage(*radius, 2.5 * f64::from(step), *lead);
                let probe = Table::probe(profile, &l, 1e-4);
                match Table::build(profile, &l, 1e-4) {
                    Ok(table) => {
                        built += 1;
                        assert_eq!(
                            probe.unwrap().samples,
                            table.samples,
                            "{lead} {radius} {step}"
                        );
                    }
                    Err(e) => {
                        refused += 1;
                        assert!(probe.is_err(), "{lead} {radius} {step}: {e}");
                    }
                }
            }
        }
        assert!(
            built > 10 && refused > 10,
            "{built} built, {refused} refused"
        );
    }

    #[test]
    fn a_point_without_pose_is_named() {
        // A 10 mm ring on a 25–35 mm work, tilted 20° on a 5 mm lead, runs out of reach.
        let e = Table::build(&lobe(5.0), &linkage(10.0, 20.0, 5.0), 1e-4).unwrap_err();
        let TableError::Linkage { error, .. } = &e else {
            panic!("{e}")
        };
        assert!(matches!(error, LinkageError::OutOfReach { .. }), "{e}");
        assert!(e.to_string().contains("profile point ("), "{e}");
    }
}
