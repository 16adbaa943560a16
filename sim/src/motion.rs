//! Motion: grbl's look-ahead planner and an executor that runs it in simulated time.
//!
//! The planner is grbl's (`planner.c` of gnea/grbl, kept by grblHAL): a block is a straight
//! move over X, Z and C whose length is the Euclidean norm over all three, millimetres and
//! degrees counted alike. Its speed limit and acceleration are the largest that keep every
//! axis within its max rate and acceleration (`limit_value_by_axis_maximum`); junction
//! speeds come from the junction-deviation model; a backward and a forward pass give each
//! block the fastest entry speed from which the rest of the queue can still stop.
//!
//! The executor replaces grbl's stepper segments with exact kinematics: the head block runs
//! a trapezoid (accelerate, cruise, decelerate into the next block's entry speed) built from
//! the current speed, so it reacts to new blocks, overrides and feed hold the way grbl's
//! segment preparation does. It never exceeds an axis' rate or acceleration, and records
//! each constant-acceleration phase (see [`crate::record`]). Steps, step rates and the
//! stepper's 30–50 ms of segment look-ahead are not modelled.

use std::collections::VecDeque;

use crate::interpreter::{MotionKind, MotionRequest};
use crate::record::{ExecutedBlock, MoveKind, Phase, Position};

/// grbl's `MINIMUM_FEED_RATE`: no block runs slower than 1 unit/min.
const MIN_SPEED: f64 = 1.0 / 60.0;
/// Relative tolerance for "the speed has reached its target" and "the braking point is
/// here", far above rounding and far below anything physical.
const REL_EPS: f64 = 1e-12;

/// The axes' dynamics, in path units (mm or degrees) and seconds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dynamics {
    /// Max rate of X, Z, C, units/s.
    pub max_rate: [f64; 3],
    /// Acceleration of X, Z, C, units/s².
    pub accel: [f64; 3],
    /// grbl's junction deviation (`$11`), units.
    pub junction_deviation: f64,
}

/// The largest scalar whose product with each component of `unit` stays within `limits`
/// (grbl's `limit_value_by_axis_maximum`).
fn axis_limited(limits: [f64; 3], unit: [f64; 3]) -> f64 {
    (0..3)
        .filter(|&i| unit[i] != 0.0)
        .map(|i| limits[i] / unit[i].abs())
        .fold(f64::INFINITY, f64::min)
}

/// Feed-hold state.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Hold {
    /// Not holding.
    None,
    /// Slowing to a stop (`Hold:1`).
    Decelerating,
    /// Stopped; cycle start resumes (`Hold:0`).
    Complete,
}

/// What queued a block.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Tag {
    /// The line's ordinal (see [`ExecutedBlock::line`]).
    pub line: u64,
    /// Its N word.
    pub n: Option<u32>,
}

#[derive(Debug, Clone)]
struct Block {
    start: [f64; 3],
    target: [f64; 3],
    length: f64,
    kind: MotionKind,
    /// Fastest path speed the axes allow, units/s.
    rate_limit: f64,
    /// Path acceleration the axes allow, units/s².
    accel: f64,
    max_junction_sqr: f64,
    /// Planned entry speed squared (for the head: unused, the current speed rules).
    entry_sqr: f64,
    tag: Tag,
}

impl Block {
    fn move_kind(&self) -> MoveKind {
        match self.kind {
            MotionKind::Rapid => MoveKind::Rapid,
            MotionKind::Feed { .. } => MoveKind::Feed,
            MotionKind::InverseTime { .. } => MoveKind::InverseTime,
            MotionKind::Jog { .. } => MoveKind::Jog,
        }
    }

    fn point_at(&self, s: f64) -> [f64; 3] {
        let f = s / self.length;
        [0, 1, 2].map(|i| self.start[i] + (self.target[i] - self.start[i]) * f)
    }
}

/// What stopped a [`Motion::step`] before its time was used.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StepEvent {
    /// The head block reached its target.
    BlockDone,
    /// A feed hold came to rest.
    HoldComplete,
}

/// The result of a [`Motion::step`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepOutcome {
    /// Simulated time used, s.
    pub used: f64,
    /// Why it stopped early, if it did.
    pub event: Option<StepEvent>,
}

/// One constant-acceleration stretch the executor is about to run.
#[derive(Debug, Clone, Copy)]
struct PhasePlan {
    accel: f64,
    duration: f64,
    end_speed: f64,
    ends_block: bool,
}

/// The planner queue and the executing machine.
#[derive(Debug, Clone)]
pub struct Motion {
    dynamics: Dynamics,
    capacity: usize,
    queue: VecDeque<Block>,
    /// Machine position now.
    position: [f64; 3],
    /// Where the last queued block ends (the planner's position).
    plan_end: [f64; 3],
    /// Distance done along the head block, and the path speed.
    s: f64,
    v: f64,
    running: bool,
    hold: Hold,
    /// A motion cancel (jog cancel) is slowing the machine: once it stands, the queue goes.
    cancelling: bool,
    feed_override: f64,
    rapid_override: f64,
    prev_unit: [f64; 3],
    record: Option<ExecutedBlock>,
    done: Vec<ExecutedBlock>,
}

impl Motion {
    /// An empty planner of `capacity` blocks with the machine at rest at `position`.
    pub fn new(dynamics: Dynamics, capacity: usize, position: [f64; 3]) -> Motion {
        Motion {
            dynamics,
            capacity,
            queue: VecDeque::with_capacity(capacity),
            position,
            plan_end: position,
            s: 0.0,
            v: 0.0,
            running: false,
            hold: Hold::None,
            cancelling: false,
            feed_override: 1.0,
            rapid_override: 1.0,
            prev_unit: [0.0; 3],
            record: None,
            done: Vec::new(),
        }
    }

    /// Planner blocks free (the status report's `Bf:` first number).
    pub fn blocks_free(&self) -> usize {
        self.capacity - self.queue.len()
    }

    /// Whether no block is queued.
    pub fn is_empty(&self) -> bool {
        self.queue.is_empty()
    }

    /// Whether a cycle is active (blocks being run, possibly held).
    pub fn is_running(&self) -> bool {
        self.running
    }

    /// Feed-hold state.
    pub fn hold(&self) -> Hold {
        self.hold
    }

    /// Whether the machine is in motion as grbl counts it (a cycle running, or a hold still
    /// slowing down): a soft reset now would lose position on a real machine.
    pub fn is_moving(&self) -> bool {
        self.running && self.hold != Hold::Complete
    }

    /// Machine position now.
    pub fn position(&self) -> [f64; 3] {
        self.position
    }

    /// Path speed now, units/s.
    pub fn speed(&self) -> f64 {
        self.v
    }

    /// The tag of the block being executed (or next to be).
    pub fn head_tag(&self) -> Option<Tag> {
        self.queue.front().map(|b| b.tag)
    }

    /// Blocks executed since the last call, oldest first.
    pub fn take_done(&mut self) -> Vec<ExecutedBlock> {
        std::mem::take(&mut self.done)
    }

    /// Queues a move to `request.target` from the end of the queue; the caller checks for
    /// room first. A move of zero length queues nothing (grbl drops blocks without steps).
    pub fn push(&mut self, request: MotionRequest, tag: Tag) {
        debug_assert!(self.queue.len() < self.capacity);
        let start = self.plan_end;
        let delta = [0, 1, 2].map(|i| request.target[i] - start[i]);
        let length = delta.iter().map(|d| d * d).sum::<f64>().sqrt();
        self.plan_end = request.target;
        if length == 0.0 || !length.is_finite() {
            return;
        }
        let unit = delta.map(|d| d / length);
        let max_junction_sqr = if self.queue.is_empty() {
            0.0
        } else {
            self.junction_speed_sqr(unit)
        };
        self.prev_unit = unit;
        self.queue.push_back(Block {
            start,
            target: request.target,
            length,
            kind: request.kind,
            rate_limit: axis_limited(self.dynamics.max_rate, unit),
            accel: axis_limited(self.dynamics.accel, unit),
            max_junction_sqr,
            entry_sqr: 0.0,
            tag,
        });
        self.replan();
    }

    /// grbl's junction-deviation speed limit between the last queued block and `unit`.
    fn junction_speed_sqr(&self, unit: [f64; 3]) -> f64 {
        let prev = self.prev_unit;
        let cos_theta = -(0..3).map(|i| prev[i] * unit[i]).sum::<f64>();
        if cos_theta > 0.999_999 {
            // A full reversal: stop.
            return 0.0;
        }
        if cos_theta < -0.999_999 {
            // Straight on: no junction limit.
            return f64::INFINITY;
        }
        let mut junction = [0, 1, 2].map(|i| unit[i] - prev[i]);
        let norm = junction.iter().map(|d| d * d).sum::<f64>().sqrt();
        junction = junction.map(|d| d / norm);
        let accel = axis_limited(self.dynamics.accel, junction);
        let sin_half = (0.5 * (1.0 - cos_theta)).sqrt();
        (accel * self.dynamics.junction_deviation * sin_half / (1.0 - sin_half)).max(0.0)
    }

    /// The block's cruise speed under the current overrides, units/s.
    fn nominal(&self, block: &Block) -> f64 {
        let speed = match block.kind {
            MotionKind::Rapid => block.rate_limit * self.rapid_override,
            MotionKind::Feed { per_minute } => {
                (per_minute / 60.0 * self.feed_override).min(block.rate_limit)
            }
            MotionKind::InverseTime { inverse_minutes } => {
                (block.length * inverse_minutes / 60.0 * self.feed_override).min(block.rate_limit)
            }
            MotionKind::Jog { per_minute } => (per_minute / 60.0).min(block.rate_limit),
        };
        speed.max(MIN_SPEED)
    }

    /// Recomputes every planned entry speed: backward from a stop at the end of the queue,
    /// then forward from the head's current state (grbl's `planner_recalculate`, done in
    /// full each time; the queue is short).
    fn replan(&mut self) {
        let n = self.queue.len();
        if n < 2 {
            return;
        }
        let nominals: Vec<f64> = self.queue.iter().map(|b| self.nominal(b)).collect();
        let mut next_entry_sqr = 0.0;
        for i in (1..n).rev() {
            let block = &mut self.queue[i];
            let max_entry = block
                .max_junction_sqr
                .min(nominals[i] * nominals[i])
                .min(nominals[i - 1] * nominals[i - 1]);
            block.entry_sqr = max_entry.min(next_entry_sqr + 2.0 * block.accel * block.length);
            next_entry_sqr = block.entry_sqr;
        }
        let head = &self.queue[0];
        let mut reach = self.v * self.v + 2.0 * head.accel * (head.length - self.s).max(0.0);
        for block in self.queue.iter_mut().skip(1) {
            block.entry_sqr = block.entry_sqr.min(reach);
            reach = block.entry_sqr + 2.0 * block.accel * block.length;
        }
    }

    /// Starts executing the queue (grbl's auto cycle start), unless held.
    pub fn start_cycle(&mut self) {
        if !self.running && self.hold == Hold::None && !self.queue.is_empty() {
            self.running = true;
            self.replan();
        }
    }

    /// Feed hold: slow to a stop at the blocks' acceleration; idle, it holds at once.
    pub fn feed_hold(&mut self) {
        if self.hold != Hold::None {
            return;
        }
        self.hold = if self.running && self.v > 0.0 {
            Hold::Decelerating
        } else {
            Hold::Complete
        };
    }

    /// Cycle start after a completed hold; `false` if there was none to resume (a hold still
    /// slowing down is not resumed, as in grbl).
    pub fn resume(&mut self) -> bool {
        if self.hold != Hold::Complete {
            return false;
        }
        self.hold = Hold::None;
        if !self.queue.is_empty() {
            self.running = true;
            self.replan();
        }
        true
    }

    /// New axis rates, accelerations and junction deviation (setting writes, taken only
    /// while the machine is idle): blocks queued from now on are planned with them.
    pub fn set_dynamics(&mut self, dynamics: Dynamics) {
        self.dynamics = dynamics;
    }

    /// Motion cancel (grblHAL's jog cancel): slow to a stop at the blocks' acceleration, as
    /// a feed hold does, then drop every queued block (`state_await_motion_cancel`). The
    /// block under way is recorded as cut short where the machine stopped. At rest, the
    /// queue goes at once.
    pub fn cancel(&mut self, now: f64) {
        if self.running && self.v > 0.0 && self.hold != Hold::Complete {
            self.cancelling = true;
            self.hold = Hold::Decelerating;
        } else {
            self.abort(now);
        }
    }

    /// New override fractions (1.0 = 100 %) for feeds and rapids.
    pub fn set_overrides(&mut self, feed: f64, rapid: f64) {
        self.feed_override = feed;
        self.rapid_override = rapid;
        self.replan();
    }

    /// Stops dead and empties the queue (soft reset, or the purge after a soft-limit stop);
    /// the block under way is recorded as cut short. Returns whether the machine was in
    /// motion.
    pub fn abort(&mut self, now: f64) -> bool {
        let moving = self.is_moving();
        if let Some(mut record) = self.record.take() {
            record.to = Position::from_array(self.position);
            record.end_time = now;
            record.completed = false;
            self.done.push(record);
        }
        self.queue.clear();
        self.plan_end = self.position;
        self.s = 0.0;
        self.v = 0.0;
        self.running = false;
        self.hold = Hold::None;
        self.cancelling = false;
        moving
    }

    /// Runs the machine for up to `dt` seconds from time `now`, stopping early when a block
    /// completes or a hold comes to rest, so the caller can react at that moment.
    pub fn step(&mut self, dt: f64, now: f64) -> StepOutcome {
        let idle = StepOutcome {
            used: dt,
            event: None,
        };
        if !self.running || self.hold == Hold::Complete || self.queue.is_empty() {
            return idle;
        }
        if self.record.is_none() {
            let head = &self.queue[0];
            self.record = Some(ExecutedBlock {
                line: head.tag.line,
                n: head.tag.n,
                kind: head.move_kind(),
                from: Position::from_array(head.start),
                target: Position::from_array(head.target),
                to: Position::from_array(head.target),
                start_time: now,
                end_time: now,
                completed: false,
                phases: Vec::new(),
            });
        }
        let mut used = 0.0;
        let mut stuck = 0;
        // Each pass either uses time or moves to another phase; the bound only guards
        // against a rounding pathology turning into a hang.
        for _ in 0..64 {
            let head = &self.queue[0];
            let (length, accel) = (head.length, head.accel);
            let rem = (length - self.s).max(0.0);
            if rem <= length * REL_EPS {
                return self.finish_block(now + used, used);
            }
            if self.hold == Hold::Decelerating && self.v <= 0.0 {
                return self.complete_hold(now + used, used);
            }
            let plan = if self.hold == Hold::Decelerating {
                self.hold_phase(rem, accel)
            } else {
                self.run_phase(rem, accel)
            };
            let left = dt - used;
            if left <= 0.0 {
                return StepOutcome { used, event: None };
            }
            let t = plan.duration.min(left);
            let before = (self.s, self.v);
            self.add_phase(now + used, plan.accel);
            self.s += self.v * t + 0.5 * plan.accel * t * t;
            self.v = (self.v + plan.accel * t).max(0.0);
            used += t;
            if t >= plan.duration {
                self.v = plan.end_speed;
                if plan.ends_block {
                    self.s = length;
                }
            }
            self.s = self.s.min(length);
            if (self.s, self.v) == before && t < left {
                // A phase too short to change anything: only rounding is left between here
                // and the block's end (the tolerances above should prevent this).
                stuck += 1;
                if stuck > 4 {
                    self.s = length;
                }
            }
            self.position = self.queue[0].point_at(self.s);
            if self.s >= length {
                return self.finish_block(now + used, used);
            }
            if self.hold == Hold::Decelerating && self.v <= 0.0 {
                return self.complete_hold(now + used, used);
            }
            if used >= dt {
                return StepOutcome { used, event: None };
            }
        }
        StepOutcome { used, event: None }
    }

    /// The next phase of a feed hold: decelerate at the block's rate, to rest or to its end.
    fn hold_phase(&self, rem: f64, accel: f64) -> PhasePlan {
        let v = self.v;
        if v * v / (2.0 * accel) < rem {
            PhasePlan {
                accel: -accel,
                duration: v / accel,
                end_speed: 0.0,
                ends_block: false,
            }
        } else {
            let end_speed = (v * v - 2.0 * accel * rem).max(0.0).sqrt();
            PhasePlan {
                accel: -accel,
                duration: (v - end_speed) / accel,
                end_speed,
                ends_block: true,
            }
        }
    }

    /// The next phase of normal running: brake into the exit speed if the braking point is
    /// reached, else accelerate towards (or slow down to) the nominal speed, else cruise.
    fn run_phase(&mut self, rem: f64, accel: f64) -> PhasePlan {
        let vn = self.nominal(&self.queue[0]);
        let ve = self.queue.get(1).map_or(0.0, |b| b.entry_sqr.sqrt());
        if (self.v - vn).abs() <= vn * REL_EPS {
            self.v = vn;
        }
        let v = self.v;
        let brake = |v: f64| {
            if v > ve {
                (v * v - ve * ve) / (2.0 * accel)
            } else {
                0.0
            }
        };
        // Distances below this are lost in the rounding of the distance done along the
        // block, so the braking point and the block's end are judged to within it.
        let resolution = self.queue[0].length * REL_EPS;
        if v > ve && brake(v) >= rem - resolution {
            return Self::brake_phase(v, ve, rem, accel);
        }
        if v < vn {
            let reach_end_sqr = v * v + 2.0 * accel * rem;
            if ve * ve >= reach_end_sqr && vn * vn >= reach_end_sqr {
                // Accelerating all the way still ends below the exit speed.
                let end_speed = reach_end_sqr.sqrt();
                return PhasePlan {
                    accel,
                    duration: (end_speed - v) / accel,
                    end_speed,
                    ends_block: true,
                };
            }
            let peak = ((reach_end_sqr + ve * ve) / 2.0).sqrt();
            let target = vn.min(peak);
            if target > v {
                return PhasePlan {
                    accel,
                    duration: (target - v) / accel,
                    end_speed: target,
                    ends_block: false,
                };
            }
        }
        if v > vn {
            return PhasePlan {
                accel: -accel,
                duration: (v - vn) / accel,
                end_speed: vn,
                ends_block: false,
            };
        }
        let cruise = rem - brake(v);
        if v <= 0.0 || cruise <= resolution {
            // Rounding left us at the braking point.
            return Self::brake_phase(v, ve, rem, accel);
        }
        PhasePlan {
            accel: 0.0,
            duration: cruise / v,
            end_speed: v,
            ends_block: brake(v) == 0.0,
        }
    }

    /// Braking into the exit speed `ve` at the block's full deceleration. The braking
    /// point was reached, so this lands on `ve` at the block's end up to rounding, which
    /// the end snaps away; always using the same deceleration keeps one phase per ramp.
    /// If the machine is too fast to make `ve` (after an override cut) it carries the
    /// excess into the next block, which slows down itself.
    fn brake_phase(v: f64, ve: f64, rem: f64, accel: f64) -> PhasePlan {
        // At the braking point the speed that remains is the exit speed; computing it as
        // √(v² − 2·a·rem) would turn rounding near zero into µm/s (√1e-11 ≈ 3e-6).
        let needed = (v * v - ve * ve) / (2.0 * rem);
        let end_speed = if needed <= accel * (1.0 + 1e-9) {
            ve.min(v)
        } else {
            (v * v - 2.0 * accel * rem).max(0.0).sqrt()
        };
        PhasePlan {
            accel: -accel,
            duration: (v - end_speed) / accel,
            end_speed,
            ends_block: true,
        }
    }

    /// Appends a phase to the running record, merged with the previous one if it continues
    /// it at the same acceleration.
    fn add_phase(&mut self, start: f64, accel: f64) {
        let Some(record) = self.record.as_mut() else {
            return;
        };
        if record.phases.last().is_some_and(|p| p.accel == accel) {
            return;
        }
        record.phases.push(Phase {
            start,
            distance: self.s,
            speed: self.v,
            accel,
        });
    }

    fn finish_block(&mut self, at: f64, used: f64) -> StepOutcome {
        if let Some(block) = self.queue.pop_front() {
            self.position = block.target;
        }
        if let Some(mut record) = self.record.take() {
            record.to = record.target;
            record.end_time = at;
            record.completed = true;
            self.done.push(record);
        }
        self.s = 0.0;
        if self.queue.is_empty() {
            self.v = 0.0;
            self.running = false;
            if self.hold == Hold::Decelerating {
                self.hold = if self.cancelling {
                    Hold::None
                } else {
                    Hold::Complete
                };
                self.cancelling = false;
            }
        } else {
            self.replan();
        }
        StepOutcome {
            used,
            event: Some(StepEvent::BlockDone),
        }
    }

    fn complete_hold(&mut self, at: f64, used: f64) -> StepOutcome {
        self.v = 0.0;
        if self.cancelling {
            self.abort(at);
            return StepOutcome {
                used,
                event: Some(StepEvent::HoldComplete),
            };
        }
        self.hold = Hold::Complete;
        if let Some(record) = self.record.as_mut() {
            // Standing still until resumed: an explicit phase, so replay does not
            // extrapolate the deceleration.
            record.phases.push(Phase {
                start: at,
                distance: self.s,
                speed: 0.0,
                accel: 0.0,
            });
        }
        StepOutcome {
            used,
            event: Some(StepEvent::HoldComplete),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dynamics() -> Dynamics {
        Dynamics {
            max_rate: [50.0, 50.0, 1200.0],
            accel: [500.0, 500.0, 7200.0],
            junction_deviation: 0.01,
        }
    }

    fn tag(line: u64) -> Tag {
        Tag { line, n: None }
    }

    fn run_until_idle(motion: &mut Motion, dt: f64) -> f64 {
        let mut now = 0.0;
        motion.start_cycle();
        while motion.is_running() {
            now += motion.step(dt, now).used;
            assert!(now < 1e4, "runaway");
        }
        now
    }

    #[test]
    fn a_single_rapid_is_a_trapezoid() {
        // 100 mm of X at 50 mm/s and 500 mm/s²: 0.1 s up and 0.1 s down, 2.5 mm each,
        // 95 mm at 50 mm/s: L/v + v/a = 2.1 s in all.
        let mut motion = Motion::new(dynamics(), 4, [0.0; 3]);
        motion.push(
            MotionRequest {
                target: [100.0, 0.0, 0.0],
                kind: MotionKind::Rapid,
            },
            tag(1),
        );
        let t = run_until_idle(&mut motion, 0.013);
        assert!((t - 2.1).abs() < 1e-9, "{t}");
        let done = motion.take_done();
        assert_eq!(done.len(), 1);
        assert!(done[0].completed);
        assert_eq!(done[0].phases.len(), 3, "{:?}", done[0].phases);
        assert_eq!(motion.position(), [100.0, 0.0, 0.0]);
    }

    #[test]
    fn collinear_blocks_do_not_stop_between() {
        // Ten 10 mm blocks in a line take as long as one 100 mm block.
        let mut motion = Motion::new(dynamics(), 16, [0.0; 3]);
        for i in 1..=10u32 {
            motion.push(
                MotionRequest {
                    target: [10.0 * f64::from(i), 0.0, 0.0],
                    kind: MotionKind::Rapid,
                },
                tag(u64::from(i)),
            );
        }
        let t = run_until_idle(&mut motion, 0.05);
        assert!((t - 2.1).abs() < 1e-9, "{t}");
    }

    #[test]
    fn a_right_angle_slows_to_the_junction_speed() {
        // grbl's junction model: v² = a·δ·sin(θ/2) / (1 − sin(θ/2)); for 90° between X and
        // Z, the junction direction is (−1, 1)/√2, a = 500·√2, sin(θ/2) = √½.
        let mut motion = Motion::new(dynamics(), 4, [0.0; 3]);
        for target in [[50.0, 0.0, 0.0], [50.0, 50.0, 0.0]] {
            motion.push(
                MotionRequest {
                    target,
                    kind: MotionKind::Rapid,
                },
                tag(1),
            );
        }
        run_until_idle(&mut motion, 0.001);
        let done = motion.take_done();
        let s = 0.5_f64.sqrt();
        let expected = (500.0 * 2f64.sqrt() * 0.01 * s / (1.0 - s)).sqrt();
        let exit = done[0].speed_at(done[0].end_time);
        assert!((exit - expected).abs() < 1e-9, "{exit} vs {expected}");
    }
}
