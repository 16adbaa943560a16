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
//! At the corner between moves i and i+1 let ω_b = min(ω_i, ω_{i+1}) and
//! a = min(a_C,i, a_C,i+1). Over the blend the first move decelerates from ω_b to rest over
//! what is left of it while the second accelerates from rest, each at a (in C). With the
//! blend lasting T = ω_b/a and t from its start, the first move has r(t) = (a/2)(T − t)² of C
//! still to go and the second has made p(t) = (a/2)·t². The machine is at
//! `corner − s_i·r + s_{i+1}·p` in X, Z and at C = C_corner − r + p. Before C reaches the corner
//! (p < r) the programmed polyline at that C is on move i, at `corner − s_i·(r − p)`, so the
//! machine is `(s_{i+1} − s_i)·p` off it; after, on move i+1, `(s_{i+1} − s_i)·r` off. The
//! largest is where C passes the corner, p = r, at t = T/2, where p = a·T²/8 = ω_b²/(8a):
//!
//! ```text
//! deviation ≈ ω_b² / (8·a) · |s_{i+1} − s_i|      (mm, X/Z distance at the same C)
//! ```
//!
//! and the blend reaches r(0) = p(T) = ω_b²/(2a) degrees of C into each move. The model
//! assumes one blend at a time: each move's two blends must not meet, which
//! ω_b²/(2a) ≤ |ΔC|/2 for both moves of every corner ensures. (That is also the cap
//! `tpComputeBlendVelocity` puts on a parabolic blend's speed in the `tp.c` sources read,
//! `sqrt(target · maxaccel/2)` of each move, which in C is sqrt(a_C,i · |ΔC_i|): in a capped
//! program it does not bind.)
//!
//! The lead checked it against LinuxCNC 2.9's own samples over 1490 corners of the
//! double-start example: measured/predicted had median 1.011 and max 1.052 (predicted max
//! 3.12 µm, measured 3.19 µm). [`MARGIN`] covers that excess.
//!
//! # The cap
//!
//! [`cap_linked_feeds`] lengthens the `minutes` of linked moves so that at every corner
//! between two of them `MARGIN · deviation ≤ share` and neither blend reaches past the middle
//! of a move. A move's rate enters only through ω_b, the smaller of its two neighbours'
//! rates at each of its corners, and a_C,i does not depend on it; so slowing a move never
//! raises any corner's deviation or reach, and capping each move at the least rate its two
//! corners allow, in one pass, meets every corner.

use super::{Move, Program};
use crate::config::machine::{Axis, MachineProfile};

/// Safety factor on the predicted deviation: the cap holds `MARGIN · deviation ≤ share`.
///
/// The largest measured/predicted ratio over the lead's 1490 LinuxCNC corners was 1.052;
/// 1.1 is that rounded up, leaving some 5 % for corners the sample did not see.
pub const MARGIN: f64 = 1.1;

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
    /// ω_b = min(ω_i, ω_{i+1}), °/s.
    pub blend_rate: f64,
    /// a = min(a_C,i, a_C,i+1), °/s².
    pub accel: f64,
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
            blend_rate: first.rate().min(second.rate()),
            accel: first.c_accel(accels).min(second.c_accel(accels)),
            kink: (x2 - x1).hypot(z2 - z1),
            shorter_deg: first.dc.abs().min(second.dc.abs()),
        })
    }

    /// The predicted corner cut: ω_b²/(8a) · |s_{i+1} − s_i|, mm (X/Z distance from the
    /// programmed polyline at the same C).
    pub fn deviation(&self) -> f64 {
        self.blend_rate * self.blend_rate / (8.0 * self.accel) * self.kink
    }

    /// How far the blend reaches into each move: ω_b²/(2a), degrees of C.
    pub fn reach_deg(&self) -> f64 {
        self.blend_rate * self.blend_rate / (2.0 * self.accel)
    }

    /// Whether the blend reaches past the middle of either move (where the blend at the
    /// move's other end may begin).
    pub fn overlaps(&self) -> bool {
        self.reach_deg() > self.shorter_deg / 2.0
    }

    /// The fastest blend rate, °/s, at which `MARGIN · deviation ≤ share` and the blend does
    /// not overlap: min(sqrt(8·a·share / (MARGIN·|Δs|)), sqrt(a·min|ΔC|)).
    pub fn rate_cap(&self, share: f64) -> f64 {
        let within = if self.kink > 0.0 {
            (8.0 * self.accel * share / (MARGIN * self.kink)).sqrt()
        } else {
            f64::INFINITY
        };
        within.min((self.accel * self.shorter_deg).sqrt())
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
}

/// The corners between linked moves of `program`, in order. Two linked moves meet at a
/// corner when no other motion comes between them: comments and spindle commands do not
/// separate them (that errs on the side of a blend), a rapid or a feed move does. A linked
/// move whose start is not fully known (the program's first positioning) meets nothing.
pub fn corners(program: &Program, accels: Accels) -> Vec<CornerAt> {
    let mut corners = Vec::new();
    let mut previous: Option<(usize, Segment)> = None;
    for step in program.steps(super::Position::UNKNOWN) {
        let Move::Linked { minutes, .. } = *step.action else {
            if step.action.target().is_some() {
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
            });
        }
        previous = segment.map(|s| (step.index, s));
    }
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
/// (`MARGIN · deviation ≤ share`) and reaches at most halfway into either move.
///
/// Each move's rate is capped at the least [`Corner::rate_cap`] of its (up to) two corners;
/// only `minutes` of linked moves changes, and only ever grows. A program whose corners are
/// already within is left exactly as it was. `share` (mm) must be above zero.
pub fn cap_linked_feeds(program: &mut Program, accels: Accels, share: f64) -> Capped {
    assert!(
        share > 0.0 && share.is_finite(),
        "blend share {share} mm is not above zero"
    );
    let found = corners(program, accels);
    let mut cap = vec![f64::INFINITY; program.moves.len()];
    for at in &found {
        if let Some(corner) = at.corner {
            let limit = corner.rate_cap(share);
            cap[at.first] = cap[at.first].min(limit);
            cap[at.second] = cap[at.second].min(limit);
        }
    }
    let turns: Vec<Option<f64>> = {
        // Each linked move's |ΔC|.
        let mut dc = vec![None; program.moves.len()];
        for step in program.steps(super::Position::UNKNOWN) {
            if let (Move::Linked { .. }, Some(a), Some(b)) = (step.action, step.from.c, step.to.c) {
                dc[step.index] = Some((b - a).abs());
            }
        }
        dc
    };
    let mut capped = Capped {
        corners: found.len(),
        unmodelled: found.iter().filter(|at| at.corner.is_none()).count(),
        ..Capped::default()
    };
    for (index, action) in program.moves.iter_mut().enumerate() {
        let (Move::Linked { minutes, .. }, Some(dc)) = (action, turns[index]) else {
            continue;
        };
        let limit = cap[index];
        if dc / (*minutes * 60.0) > limit {
            let longer = dc / (limit * (1.0 - CAP_SLACK)) / 60.0;
            if longer > *minutes {
                capped.added_s += (longer - *minutes) * 60.0;
                *minutes = longer;
                capped.slowed += 1;
            }
        }
    }
    capped.max_deviation_mm = corners(program, accels)
        .iter()
        .filter_map(|at| at.corner.map(|c| c.deviation()))
        .fold(0.0, f64::max);
    capped
}

#[cfg(test)]
mod tests;
