//! LinuxCNC's blends between linked moves: how far they cut a corner, and the cap on the feed
//! of linked moves that keeps them within the controller's share of Δ.
//!
//! # Why `G64 P` does not bound them
//!
//! LinuxCNC (2.9, `src/emc/tp/tp.c`) rounds a corner between two straight moves with a
//! circular blend arc whose size `G64 P` bounds, but `tpCheckBlendArcType` refuses the arc
//! when either move turns a rotary axis (`tcRotaryMotionCheck`), and the corner is then
//! blended *parabolically*: the next move starts while the previous one is still
//! decelerating, and the two motions add. `tpComputeBlendVelocity` limits the speed of a
//! parabolic blend by P only through the angle between the two moves' XYZ directions, and a
//! whirling program's consecutive linked moves are nearly parallel in X/Z while they turn
//! sharply in X against C: P bounds nothing there. The lead measured it on a simulated
//! LinuxCNC 2.9: over 1500 lines of the double-start example, with `G64 P0.001 Q0`, corners
//! cut by up to 3.19 µm (X, Z at the same C), and `P0.0001` gave the same path.
//!
//! # The model
//!
//! For move i of a run of linked (G93) moves, each turning C: ΔX_i, ΔZ_i (mm, X a radius),
//! ΔC_i (degrees), duration T_i (its `minutes` · 60, s); its C rate ω_i = |ΔC_i|/T_i (°/s); its
//! slope s_i = (ΔX_i/ΔC_i, ΔZ_i/ΔC_i) (mm/°); and the C acceleration LinuxCNC gives it,
//!
//! ```text
//! a_C,i = ½ · min(a_C, a_X·|ΔC_i|/|ΔX_i|, a_Z·|ΔC_i|/|ΔZ_i|)
//! ```
//!
//! (axis accelerations of the machine profile, X and Z in mm/s², C in °/s²; a term whose
//! denominator is zero is absent). The minimum is `getStraightAcceleration` of
//! `src/emc/task/emccanon.cc`: a straight move gets the path acceleration at which its most
//! limiting axis is at its limit, which in C is the minimum above. The ½ is
//! `tpGetScaledAccel` of `tp.c`: a move that blends parabolically with a neighbour gets half
//! its acceleration, so that the two together stay within the limits.
//!
//! At the corner between moves i and i+1 take both moves at the rate ω_b = max(ω_i, ω_{i+1})
//! and, to begin with, the acceleration a = min(a_C,i, a_C,i+1) (see "Which rate" and "Two
//! accelerations" below). Over the blend the first move decelerates from ω_b to rest over
//! what is left of it while the second accelerates from rest. With the blend lasting
//! T = ω_b/a and t from its start, the first move has r(t) = (a/2)(T − t)² of C still to go
//! and the second has made p(t) = (a/2)·t². The machine is at `corner − s_i·r + s_{i+1}·p` in
//! X, Z and at C = C_corner − r + p. Before C reaches the corner (p < r) the programmed
//! polyline at that C is on move i, at `corner − s_i·(r − p)`, so the machine is
//! `(s_{i+1} − s_i)·p` off it; after, on move i+1, `(s_{i+1} − s_i)·r` off. The largest is
//! where C passes the corner, p = r, at t = T/2, where p = a·T²/8 = ω_b²/(8a):
//!
//! ```text
//! deviation ≈ ω_b² / (8·a) · |s_{i+1} − s_i|      (mm, X/Z distance at the same C)
//! ```
//!
//! and the blend reaches r(0) = p(T) = ω_b²/(2a) degrees of C into each move. The model
//! assumes one blend at a time: each move's two blends must not meet, which
//! ω_b²/(2a) ≤ |ΔC|/2 for both moves of every corner ensures (LinuxCNC, too, shortens a
//! blend that would not fit its moves: `t_max_reachable` in `tpComputeBlendVelocity`).
//!
//! The lead checked it against LinuxCNC 2.9's own samples over 1490 corners of the
//! double-start example at the job's rate: measured/predicted had median 1.011 and max 1.052
//! (predicted max 3.12 µm, measured 3.19 µm).
//!
//! # Which rate
//!
//! The lead's model took the slower rate, ω_b = min(ω_i, ω_{i+1}); on that program every move
//! turned C at the job's rate, so the two agree. Once capped, neighbours differ, and LinuxCNC
//! gives each move a blend speed of its own (`tpComputeBlendVelocity` returns `v_blend_this`
//! and `v_blend_next`, each move's own requested speed unless the blend is cut short), so the
//! faster move sets the corner: on the capped double-start program the slower rate
//! under-predicted such corners by up to 1.62× (0.89 µm measured, 0.55 µm predicted).
//!
//! # Two accelerations
//!
//! Where the second move gets the larger acceleration, it gains on the first: the first
//! still has r(t) = (a_C,i/2)(T − t)² to go, T = ω_b/a_C,i, while the second has made
//! p(t) = (a_C,i+1/2)·t², and they meet at
//!
//! ```text
//! p = ω_b² · a_C,i+1 / (2 · a_C,i · (√a_C,i + √a_C,i+1)²)
//! ```
//!
//! which is ω_b²/(8·a_C,i) times 4x²/(1 + x)², x = √(a_C,i+1/a_C,i) (as long as the second
//! has not reached ω_b by then, x ≤ 1.618; beyond, it overstates). [`Corner::deviation`]
//! takes the larger of this and ω_b²/(8a). On the trapezoidal example's flank-to-root corners
//! (a_C,i+1 = 1.44·a_C,i) ω_b²/(8a) alone under-predicted by 1.31×.
//!
//! # Measured
//!
//! Every example planned with the cap and run on LinuxCNC 2.9 (`whirl dry-run --controller
//! linuxcnc`, 1 ms samples; every run within Δ), corners predicted at 0.3 µm or more: within a
//! run of linked moves, measured/predicted at most 1.091 (double-start, 32 330 corners), 1.103
//! (left-external, 75 981), 1.099 (trapezoidal, 25 500) and 1.091 (ball-screw, 67 642),
//! median 0.76 to 1.0; the largest corner measured 0.96 µm on the 1 µm share.
//!
//! The corner into the last move of a run, where the machine stops (before the retract),
//! measured 1.27 to 1.49 times the prediction over two rounds of these runs, for a reason not
//! pinned down; [`STOP_MARGIN`] holds it (0.57 to 0.86 µm measured). Not modelled: the corner
//! from the plunge (a G94 feed of X alone) into the first linked move, which LinuxCNC blends
//! too, X still v²/(2a) short of the plunge depth when C starts (1.0 to 1.7 µm measured); it
//! lies in the run-in, outside the formed length.
//!
//! # The cap
//!
//! [`cap_linked_feeds`] lengthens the `minutes` of linked moves so that at every corner
//! between two of them `margin · deviation ≤ share` and neither blend reaches past the middle
//! of a move: both moves of a corner within the fastest rate the corner allows. The planner
//! caps the corners of the program as posted ([`cap_linked_feeds_as_posted`]): the written
//! decimals move each vertex by up to the rounding share, and the slopes either side with
//! it. A move's rate enters only through ω_b at each of its two corners, and a_C,i does not
//! depend on it; so slowing a move never raises any corner's deviation or reach, and capping
//! each move at the least rate its two corners allow, in one pass, meets every corner. It is
//! also the least slowing that does: with ω_b the faster rate, every corner needs both of its
//! moves within its limit.

use super::{Move, Program};
use crate::config::machine::{Axis, MachineProfile};

/// Safety factor on the predicted deviation within a run of linked moves: the cap holds
/// `MARGIN · deviation ≤ share`.
///
/// The largest measured/predicted ratio on LinuxCNC 2.9 was 1.052 over the lead's 1490
/// corners at the job's rate and 1.103 over some 200 000 corners of the four examples capped
/// (see "Measured"); 1.15 leaves some 4 % above that for corners those samples did not see.
pub const MARGIN: f64 = 1.15;

/// The margin of the corner into the last linked move of a run, after which the machine
/// stops: measured up to 1.49 times the prediction (see "Measured"); 1.6 leaves some 7 %.
/// One corner a run: it costs next to nothing.
pub const STOP_MARGIN: f64 = 1.6;

/// The cap aims this far below a corner's limit, relative, so that the rate computed back
/// from the lengthened `minutes` is not above it by a rounding.
const CAP_SLACK: f64 = 1e-12;

/// The axis accelerations the model uses: X and Z in mm/s² (X a radius), C in °/s².
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Accels {
    /// X, mm/s².
    pub x: f64,
    /// Z, mm/s².
    pub z: f64,
    /// C, °/s².
    pub c: f64,
}

impl Accels {
    /// The accelerations of a machine profile's axes.
    pub fn of(machine: &MachineProfile) -> Accels {
        Accels {
            x: machine.accel(Axis::X),
            z: machine.accel(Axis::Z),
            c: machine.accel(Axis::C),
        }
    }
}

/// One linked move as the model sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Segment {
    /// ΔX, mm (radius).
    pub dx: f64,
    /// ΔZ, mm.
    pub dz: f64,
    /// ΔC, degrees.
    pub dc: f64,
    /// Duration, s.
    pub seconds: f64,
}

impl Segment {
    /// Its C rate ω = |ΔC|/T, °/s.
    pub fn rate(&self) -> f64 {
        self.dc.abs() / self.seconds
    }

    /// Its slope (ΔX/ΔC, ΔZ/ΔC), mm/°.
    pub fn slope(&self) -> [f64; 2] {
        [self.dx / self.dc, self.dz / self.dc]
    }

    /// The C acceleration LinuxCNC gives it when it blends parabolically, °/s²:
    /// ½ · min(a_C, a_X·|ΔC|/|ΔX|, a_Z·|ΔC|/|ΔZ|), a term with a zero denominator absent.
    pub fn c_accel(&self, accels: Accels) -> f64 {
        let dc = self.dc.abs();
        let mut a = accels.c;
        for (d, axis) in [(self.dx.abs(), accels.x), (self.dz.abs(), accels.z)] {
            if d > 0.0 {
                a = a.min(axis * dc / d);
            }
        }
        0.5 * a
    }
}

/// The corner between two consecutive linked moves, as the model sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Corner {
    /// ω_b = max(ω_i, ω_{i+1}), °/s: each move blends at its own rate, and the faster sets
    /// the corner.
    pub blend_rate: f64,
    /// a_C,i, the first move's C acceleration, °/s².
    pub accel_first: f64,
    /// a_C,i+1, the second move's, °/s².
    pub accel_second: f64,
    /// |s_{i+1} − s_i|, mm/°.
    pub kink: f64,
    /// The shorter |ΔC| of the two moves, degrees.
    pub shorter_deg: f64,
}

impl Corner {
    /// The corner from `first` into `second`; `None` when the model does not apply: a move
    /// that does not turn C (or takes no time) has no slope in C.
    pub fn between(first: &Segment, second: &Segment, accels: Accels) -> Option<Corner> {
        let modelled = |s: &Segment| s.dc != 0.0 && s.seconds > 0.0 && s.seconds.is_finite();
        if !(modelled(first) && modelled(second)) {
            return None;
        }
        let ([x1, z1], [x2, z2]) = (first.slope(), second.slope());
        Some(Corner {
            blend_rate: first.rate().max(second.rate()),
            accel_first: first.c_accel(accels),
            accel_second: second.c_accel(accels),
            kink: (x2 - x1).hypot(z2 - z1),
            shorter_deg: first.dc.abs().min(second.dc.abs()),
        })
    }

    /// a = min(a_C,i, a_C,i+1), °/s².
    pub fn accel(&self) -> f64 {
        self.accel_first.min(self.accel_second)
    }

    /// How deep into C the blend is where C passes the corner, per (°/s)² of ω_b:
    /// max(1/(8a), a_C,i+1 / (2·a_C,i·(√a_C,i + √a_C,i+1)²)), s²/°.
    fn depth_per_rate2(&self) -> f64 {
        let (a1, a2) = (self.accel_first, self.accel_second);
        let own = a2 / (2.0 * a1 * (a1.sqrt() + a2.sqrt()).powi(2));
        (1.0 / (8.0 * self.accel())).max(own)
    }

    /// The predicted corner cut, mm (X/Z distance from the programmed polyline at the same
    /// C): ω_b²/(8a) · |s_{i+1} − s_i|, or, where the second move accelerates faster than
    /// the first decelerates, ω_b²·a_C,i+1 / (2·a_C,i·(√a_C,i + √a_C,i+1)²) · |s_{i+1} − s_i|
    /// (see "Two accelerations" in the module's documentation).
    pub fn deviation(&self) -> f64 {
        self.blend_rate * self.blend_rate * self.depth_per_rate2() * self.kink
    }

    /// How far the blend reaches into each move: ω_b²/(2a), degrees of C.
    pub fn reach_deg(&self) -> f64 {
        self.blend_rate * self.blend_rate / (2.0 * self.accel())
    }

    /// Whether the blend reaches past the middle of either move (where the blend at the
    /// move's other end may begin).
    pub fn overlaps(&self) -> bool {
        self.reach_deg() > self.shorter_deg / 2.0
    }

    /// The fastest blend rate, °/s, at which `margin · deviation ≤ share` and the blend does
    /// not overlap.
    pub fn rate_cap(&self, share: f64, margin: f64) -> f64 {
        let within = if self.kink > 0.0 {
            (share / (margin * self.kink * self.depth_per_rate2())).sqrt()
        } else {
            f64::INFINITY
        };
        within.min((self.accel() * self.shorter_deg).sqrt())
    }
}

/// A corner of a program: the indices in [`Program::moves`] of the two linked moves that
/// meet there, and the corner when the model applies.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CornerAt {
    /// The move into the corner.
    pub first: usize,
    /// The move out of it.
    pub second: usize,
    /// The corner; `None` when the model does not apply ([`Corner::between`]).
    pub corner: Option<Corner>,
    /// Whether the move out of it is the last of its run of linked moves: the machine stops
    /// at its end (a rapid, a feed or the program's end follows). Such corners are held with
    /// [`STOP_MARGIN`].
    pub into_stop: bool,
}

impl CornerAt {
    /// The margin the cap holds this corner's predicted deviation to.
    pub fn margin(&self) -> f64 {
        if self.into_stop {
            STOP_MARGIN
        } else {
            MARGIN
        }
    }
}

/// The corners between linked moves of `program`, in order. Two linked moves meet at a
/// corner when no other motion comes between them: comments and spindle commands do not
/// separate them (that errs on the side of a blend), a rapid or a feed move does. A linked
/// move whose start is not fully known (the program's first positioning) meets nothing.
pub fn corners(program: &Program, accels: Accels) -> Vec<CornerAt> {
    let mut corners: Vec<CornerAt> = Vec::new();
    let mut previous: Option<(usize, Segment)> = None;
    // Marks the last corner found as leading into a stop, if it leads into `index`.
    let stop = |corners: &mut Vec<CornerAt>, previous: Option<(usize, Segment)>| {
        if let (Some(last), Some((index, _))) = (corners.last_mut(), previous) {
            if last.second == index {
                last.into_stop = true;
            }
        }
    };
    for step in program.steps(super::Position::UNKNOWN) {
        let Move::Linked { minutes, .. } = *step.action else {
            if step.action.target().is_some() {
                stop(&mut corners, previous);
                previous = None;
            }
            continue;
        };
        let segment = match (step.from.x, step.from.z, step.from.c, step.to) {
            (Some(x0), Some(z0), Some(c0), to) => Some(Segment {
                dx: to.x.unwrap_or(x0) - x0,
                dz: to.z.unwrap_or(z0) - z0,
                dc: to.c.unwrap_or(c0) - c0,
                seconds: minutes * 60.0,
            }),
            _ => None,
        };
        if let (Some((first, before)), Some(this)) = (previous, segment) {
            corners.push(CornerAt {
                first,
                second: step.index,
                corner: Corner::between(&before, &this, accels),
                into_stop: false,
            });
        }
        previous = segment.map(|s| (step.index, s));
    }
    stop(&mut corners, previous);
    corners
}

/// What [`cap_linked_feeds`] did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Capped {
    /// Corners between linked moves.
    pub corners: usize,
    /// Of those, the ones the model does not apply to (a move that does not turn C); left
    /// alone. The planner writes none.
    pub unmodelled: usize,
    /// Linked moves slowed.
    pub slowed: usize,
    /// The largest predicted deviation over all corners after the cap, mm.
    pub max_deviation_mm: f64,
    /// Time the slowing added, s.
    pub added_s: f64,
}

/// Slows the linked moves of `program` so that at every corner between two of them
/// LinuxCNC's parabolic blend stays within `share` with [`MARGIN`]
/// (`MARGIN · deviation ≤ share`; [`STOP_MARGIN`] at the corner into a run's last move) and
/// reaches at most halfway into either move; the corners are those of `program` itself. See [`cap_linked_feeds_as_posted`].
pub fn cap_linked_feeds(program: &mut Program, accels: Accels, share: f64) -> Capped {
    let geometry = program.clone();
    cap_linked_feeds_as_posted(program, &geometry, accels, share)
}

/// [`cap_linked_feeds`] with the corners of `posted`: the program as the controller reads
/// it, its positions rounded to the decimals written (LinuxCNC blends the corners of the
/// polyline it is given, and rounding moves a vertex by up to the rounding share, which
/// changes the slopes either side). `posted` holds the same linked moves in the same order
/// (its durations do not matter); when it does not, `program`'s own corners are used.
///
/// Each move's rate is capped at the least [`Corner::rate_cap`] of its (up to) two corners;
/// only `minutes` of linked moves changes, and only ever grows. A program whose corners are
/// already within is left exactly as it was. `share` (mm) must be above zero.
pub fn cap_linked_feeds_as_posted(
    program: &mut Program,
    posted: &Program,
    accels: Accels,
    share: f64,
) -> Capped {
    assert!(
        share > 0.0 && share.is_finite(),
        "blend share {share} mm is not above zero"
    );
    let linked = |p: &Program| -> Vec<usize> {
        p.moves
            .iter()
            .enumerate()
            .filter(|(_, m)| matches!(m, Move::Linked { .. }))
            .map(|(index, _)| index)
            .collect()
    };
    let ours = linked(program);
    let own;
    let geometry = if linked(posted).len() == ours.len() {
        posted
    } else {
        own = program.clone();
        &own
    };
    // The geometry's linked moves, in order, are ours: (index there, index here).
    let pairs: Vec<(usize, usize)> = linked(geometry).into_iter().zip(ours).collect();
    let found = corners(geometry, accels);
    let mut cap = vec![f64::INFINITY; geometry.moves.len()];
    for at in &found {
        if let Some(corner) = at.corner {
            let limit = corner.rate_cap(share, at.margin());
            cap[at.first] = cap[at.first].min(limit);
            cap[at.second] = cap[at.second].min(limit);
        }
    }
    // Each linked move's |ΔC| as the controller reads it.
    let mut turn = vec![None; geometry.moves.len()];
    for step in geometry.steps(super::Position::UNKNOWN) {
        if let (Move::Linked { .. }, Some(a), Some(b)) = (step.action, step.from.c, step.to.c) {
            turn[step.index] = Some((b - a).abs());
        }
    }
    let mut capped = Capped {
        corners: found.len(),
        unmodelled: found.iter().filter(|at| at.corner.is_none()).count(),
        ..Capped::default()
    };
    let mut timed = geometry.clone();
    for &(there, here) in &pairs {
        let (Move::Linked { minutes, .. }, Some(dc)) = (&mut program.moves[here], turn[there])
        else {
            continue;
        };
        let limit = cap[there];
        if dc / (*minutes * 60.0) > limit {
            let longer = dc / (limit * (1.0 - CAP_SLACK)) / 60.0;
            if longer > *minutes {
                capped.added_s += (longer - *minutes) * 60.0;
                *minutes = longer;
                capped.slowed += 1;
            }
        }
        if let Move::Linked { minutes: t, .. } = &mut timed.moves[there] {
            *t = *minutes;
        }
    }
    capped.max_deviation_mm = corners(&timed, accels)
        .iter()
        .filter_map(|at| at.corner.map(|c| c.deviation()))
        .fold(0.0, f64::max);
    capped
}

#[cfg(test)]
mod tests;
