//! The bridge's CANopen master for three CiA 402 drives (X, Z, C), as a state machine over
//! frames and time: [`Session::receive`] takes the bus's frames, [`Session::poll`] is told
//! the time and returns the frames to send, [`Session::events`] says what happened. No
//! port, no clock: the transport moves the frames and calls `poll` at least once a cycle.
//!
//! # Phases
//!
//! 1. **Boot-up.** Wait [`SessionConfig::boot_wait`] for every node's boot-up message. A
//!    node that booted before the bridge listened (before the adapter's channel opened)
//!    never sends another, so the missing ones get NMT reset communication, which makes
//!    them boot again, and one more wait; a node still silent stops the job.
//! 2. **Configuration**, by expedited SDO, the three nodes in parallel, each node's writes
//!    in order: device type 1000h read (CiA 402 is 0192h in its low word: anything else is
//!    not a drive this master knows how to run), producer heartbeat 1017h, modes of
//!    operation 6060h = 8 (cyclic synchronous position) or 7 (interpolated position; see
//!    [`SessionConfig::operation`]), following error window 6065h, interpolation time
//!    period 60C2h (the cycle, which the drives lock to), then RPDO1 = controlword 6040h +
//!    the mode's set-point (target position 607Ah, or in interpolated position mode the
//!    interpolation data record's first entry, 60C1h sub-index 1) and TPDO1 = statusword
//!    6041h + position actual 6064h, both every SYNC, by CiA 301's mapping procedure
//!    ([`cia301::pdo_mapping`]). Heartbeat supervision of a node starts when its 1017h
//!    write is confirmed. Where the profile gives the drives' data sheets
//!    (`connection.drives.eds`), [`SessionConfig::for_drives`] has checked every one of
//!    these objects against them ([`objects_used`]) before any of this is sent.
//! 3. **Start and enable.** NMT start to each node, and the cycle starts: every period,
//!    each drive's RPDO1 and then one SYNC. The first SYNC only asks for the TPDOs; from
//!    each drive's first TPDO on, its target is its actual position (CiA 402: in CSP a
//!    drive follows 607Ah the moment it is enabled, in interpolated position mode 60C1h
//!    the moment ip mode is active), which must be within
//!    [`SessionConfig::start_tolerance`] of the set-points' start, and the controlword
//!    walks it to Operation enabled with a [`PowerSequencer`], one transition a cycle:
//!    0x06, 0x07, 0x0F. In interpolated position mode one step follows: once a drive
//!    shows Operation enabled, its controlword also sets bit 4, enable ip mode (0x1F).
//! 4. **Run.** Once all three show Operation enabled and follow their targets (statusword
//!    bit 12: in CSP "drive follows the command value", in interpolated position mode "ip
//!    mode active"), each cycle carries the next set-point's three targets, then the SYNC
//!    that makes the drives take them together. In interpolated position mode a drive
//!    whose bit 12 drops while it runs stops the job ([`StopReason::IpModeInactive`]): it
//!    no longer takes its set-points. Spindle [`Mark`](crate::post::setpoints::Mark)s are
//!    reported as [`Event::Spindle`] when due.
//! 5. **Settle and disable.** After the last set-point the final targets are held until
//!    every actual position is within [`SessionConfig::settle_window`], then the drives
//!    are walked to Switch on disabled, and the cycle ends.
//!
//! # Stopping
//!
//! A lost heartbeat, an emergency message, a drive leaving Operation enabled or NMT
//! Operational, an SDO failure, a timeout of any phase, or [`Session::stop`] stops the
//! job: [`Event::Stopped`] says why, once (the first reason wins). If the cycle was
//! running, it goes on for the stop: each drive in Operation enabled is sent quick stop
//! (0x02), held there until its position stands still, then disable voltage (0x00)
//! (neither with bit 4: in interpolated position mode ip mode ends with the first),
//! until every drive still heard from shows Switch on disabled or Fault in a TPDO received
//! after the stop, or [`SessionConfig::disable_timeout`] passes; [`Event::Halted`] then
//! names the drives not confirmed. Faults are not reset: a faulted drive stays faulted for
//! someone to look at.
//!
//! [`Session::stop_held`] is the gentle stop, for an interrupted bridge: [`Event::Stopped`]
//! at once, then the hold's ramp brings the set-points to a stand on the path, and once
//! every drive stands within [`SessionConfig::settle_window`] of its held target, the
//! drives are walked to Switch on disabled as at the job's end (no quick stop) and the
//! session ends [`Phase::Stopped`] after [`Event::Halted`]. The wait for the stand is
//! limited to the hold ramp plus [`SessionConfig::settle_timeout`] (the machine's stop time
//! and a margin); past it the drives get the quick stop above, [`StopReason::NoStand`]
//! saying why (any stop during a gentle one does the same, with a second
//! [`Event::Stopped`]: the first reason is the job's). With
//! [`SessionConfig::stall_timeout`], a job whose set-points move on while no drive's TPDO
//! shows anything new (position or statusword) for that long is stopped the same way,
//! [`StopReason::Stalled`]; the set-points standing (the caller's hold, a spin-up) is no
//! stall.
//!
//! # Where the drives are
//!
//! A drive reports its position actual value (6064h) in every TPDO. A set-point is known
//! reached once the three positions, reported together, are each within the settle window
//! of it, or of the targets the path stands at between set-points (a hold): the drives
//! were there. The search runs over the last set-points sent, newest first, so the count
//! only grows. A drive lagging its targets by more than the window while it moves is seen
//! reaching the path only where it stands (a hold, the end): the count then stays behind,
//! never ahead. [`Session::resume_move`] says it in the program's moves: the first not
//! known to have run to its end.
//!
//! # The cycle
//!
//! Set-points are computed before the first SYNC ([`crate::post::setpoints`]), so a cycle only
//! reads the next one and the cycle never waits for the planner. `poll` sends exactly one
//! SYNC when the cycle's time has come, however often it is called. A poll later than
//! a whole period still sends one cycle (never a burst to catch up, which would hand the
//! drives set-points faster than the path allows), reports [`Event::Late`], and the
//! schedule restarts from then: the path slows down, it does not jump.

mod config;
mod events;
mod objects;
mod script;
#[cfg(test)]
mod tests;

use std::collections::VecDeque;
use std::time::Duration;

use super::cia301::{
    self, cob, decode_emcy, decode_heartbeat, Cob, NmtCommand, NmtState, NodeId, PdoNumber,
    SdoClient, SdoDone,
};
use super::cia402::{
    interpolation_time_period, object, Command, PowerSequencer, PowerState, Statusword, Target,
};
use super::frame::{CanFrame, CanId};
use crate::config::machine::Axis;
use crate::post::setpoints::{to_wire, unwrap_near, SetPoints};
use script::{configuration, Op};

pub use config::{Operation, SessionConfig, SessionError};
pub use events::{emcy_meaning, DriveStatus, Event, StopReason};
pub use objects::objects_used;

/// Where the session is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// Waiting for boot-up messages.
    Booting,
    /// Writing the drives' objects by SDO.
    Configuring,
    /// NMT started; walking the drives to Operation enabled.
    Enabling,
    /// Sending set-points.
    Running,
    /// Holding the final targets until the drives get there.
    Settling,
    /// Walking the drives to Switch on disabled after the job.
    Disabling,
    /// The job ran to its end and the drives are disabled.
    Finished,
    /// Quick-stopping and disabling the drives after a stop.
    Stopping,
    /// Stopped; see [`Event::Stopped`].
    Stopped,
}

/// The session's view of one drive.
#[derive(Debug, Clone)]
struct Drive {
    axis: Axis,
    sdo: SdoClient,
    ops: VecDeque<Op>,
    booted: bool,
    /// Heartbeat supervision: lost if not heard from by then.
    heartbeat_due: Option<Duration>,
    lost: bool,
    statusword: Option<u16>,
    actual: Option<i64>,
    /// The last TPDO showed the same position as the one before.
    still: bool,
    /// A TPDO arrived since the stop or the disable began.
    fresh: bool,
    target: Option<i64>,
    sequencer: PowerSequencer,
}

impl Drive {
    fn state(&self) -> Option<PowerState> {
        self.statusword
            .and_then(|w| PowerState::from_statusword(w).ok())
    }
}

/// The master; see the module docs.
#[derive(Debug, Clone)]
pub struct Session {
    config: SessionConfig,
    setpoints: SetPoints,
    phase: Phase,
    /// The current phase's deadline (boot wait, timeouts).
    deadline: Option<Duration>,
    reset_sent: bool,
    drives: [Drive; 3],
    next_sync: Duration,
    syncs: u64,
    /// Set-points passed: the whole part of `position`.
    sent: usize,
    /// Where along the set-points the path is, in cycles: `k` is set-point `k` (1-based)
    /// reached, between two whole numbers the straight move between them.
    position: f64,
    /// The path's speed, set-points a cycle: the feed override running (1 at 100 %), 0
    /// held.
    speed: f64,
    /// The feed override, as set-points a cycle: the speed the path runs at, unheld.
    feed: f64,
    /// The last step was on a feed move (not a rapid nor the spin-up wait).
    on_feed: bool,
    /// A feed override asked whose speed the path has not reached yet, percent.
    feed_asked: Option<u16>,
    /// A resume whose speed the path has not reached yet.
    resuming: bool,
    /// The caller asked for a hold (and no resume since).
    held: bool,
    /// A gentle stop ([`Session::stop_held`]) is under way: the job ends stopped.
    interrupted: bool,
    /// While a gentle stop waits for the drives to stand: until when.
    stand_by: Option<Duration>,
    /// Set-points the drives are known to have reached (see "Where the drives are").
    reached: usize,
    /// When a drive last reported something new, or the set-points stood: the stall's
    /// clock.
    progressed: Duration,
    /// The set-points where one straight move ends and the next begins (1-based, as
    /// `position` counts): no step crosses one, so the drives turn the polyline's corners
    /// whatever the path's speed.
    junctions: Vec<usize>,
    next_mark: usize,
    outbox: Vec<CanFrame>,
    events: Vec<Event>,
}

/// How many set-points back from the last sent the drives' positions are looked for (see
/// "Where the drives are"): the TPDOs of a cycle may reach the session several cycles late
/// (eight in the transport's lockstep), and a drive lags its target by a cycle or two.
const REACHED_LOOKBACK: usize = 32;

fn frame(id: u16, data: &[u8]) -> CanFrame {
    CanFrame::standard(id, data).expect("CANopen frames are 11-bit and at most 8 bytes")
}

impl Session {
    /// A session that will run `setpoints` on the drives `config` names.
    pub fn new(config: SessionConfig, setpoints: SetPoints) -> Result<Session, SessionError> {
        let invalid = |name, reason: String| Err(SessionError::Config { name, reason });
        let [x, z, c] = config.nodes;
        if x == z || z == c || x == c {
            return invalid("nodes", format!("{x}, {z}, {c} are not three nodes"));
        }
        if config.heartbeat_ms == 0 {
            return invalid("heartbeat_ms", "0 switches the heartbeat off".into());
        }
        let period = Duration::from_millis(config.heartbeat_ms.into());
        if config.heartbeat_timeout <= period {
            return invalid(
                "heartbeat_timeout",
                format!(
                    "{:?} is not longer than the producer's {period:?}",
                    config.heartbeat_timeout
                ),
            );
        }
        let Some(cycle) = interpolation_time_period(setpoints.period) else {
            return invalid(
                "setpoints.period",
                format!(
                    "{:?} is not a cycle 60C2h holds (value ≤ 255 × 10^index s, whole µs)",
                    setpoints.period
                ),
            );
        };
        let drives = std::array::from_fn(|k| {
            let node = config.nodes[k];
            Drive {
                axis: Axis::ALL[k],
                sdo: SdoClient::new(node, config.sdo_timeout),
                ops: configuration(node, &config, cycle),
                booted: false,
                heartbeat_due: None,
                lost: false,
                statusword: None,
                actual: None,
                still: false,
                fresh: false,
                target: None,
                sequencer: PowerSequencer::new(Target::OperationEnabled),
            }
        });
        let period = setpoints.period.as_secs_f64();
        let junctions = setpoints
            .moves
            .iter()
            .map(|m| ((m.start + m.duration) / period).round() as usize)
            .collect();
        Ok(Session {
            config,
            junctions,
            setpoints,
            phase: Phase::Booting,
            deadline: None,
            reset_sent: false,
            drives,
            next_sync: Duration::ZERO,
            syncs: 0,
            sent: 0,
            position: 0.0,
            speed: 1.0,
            feed: 1.0,
            on_feed: false,
            feed_asked: None,
            resuming: false,
            held: false,
            interrupted: false,
            stand_by: None,
            reached: 0,
            progressed: Duration::ZERO,
            next_mark: 0,
            outbox: Vec::new(),
            events: Vec::new(),
        })
    }

    /// Where the session is.
    pub fn phase(&self) -> Phase {
        self.phase
    }

    /// Set-points sent, and their number.
    pub fn progress(&self) -> (usize, usize) {
        (self.sent, self.setpoints.points.len())
    }

    /// The drives as last seen, X, Z, C.
    pub fn drives(&self) -> [DriveStatus; 3] {
        std::array::from_fn(|k| {
            let d = &self.drives[k];
            DriveStatus {
                node: self.config.nodes[k],
                statusword: d.statusword,
                actual: d.actual,
                target: d.target,
            }
        })
    }

    /// What happened since the last call.
    pub fn events(&mut self) -> Vec<Event> {
        std::mem::take(&mut self.events)
    }

    /// Stops the job (an operator's abort): as any stop, see the module docs.
    pub fn stop(&mut self, now: Duration) {
        self.halt(StopReason::Requested, now);
    }

    /// Holds the job: the set-points slow along the path to a stand over
    /// [`SessionConfig::hold_ramp`], and the drives then hold their targets on the path,
    /// enabled and supervised. Before the set-points start, they start held.
    pub fn hold(&mut self) {
        self.held = true;
    }

    /// Resumes after a hold: the set-points come back up to speed over the same ramp. A
    /// gentle stop under way is not undone.
    pub fn resume(&mut self) {
        if !self.interrupted {
            self.resuming |= self.held;
            self.held = false;
        }
    }

    /// Feed override: the set-points' clock runs at `percent` of the programmed feed (the
    /// bridge makes the set-points, so the override is its own interpolation's: a cycle
    /// advances the path by `percent`/100 set-points), reached over the hold ramp's slope
    /// and announced by [`Event::FeedOverride`] once reached. The caller checks the cap.
    pub fn feed_override(&mut self, percent: u16) {
        self.feed = f64::from(percent) / 100.0;
        self.feed_asked = Some(percent);
    }

    /// Stops the job gently for `reason` (see the module docs, "Stopping"): the path held
    /// to a stand, then the drives disabled as at the job's end. Before the set-points
    /// start nothing moves along the path, and it is [`Session::stop`]'s stop; after the
    /// last set-point the drives settle at the path's end and the job finishes, with
    /// nothing left to resume.
    pub fn stop_held(&mut self, reason: StopReason, now: Duration) {
        let total = self.setpoints.points.len();
        match self.phase {
            Phase::Running if self.interrupted || self.sent >= total => {}
            Phase::Running => {
                self.events.push(Event::Stopped { reason });
                self.interrupted = true;
                self.held = true;
                self.stand_by = Some(now + self.config.hold_ramp + self.config.settle_timeout);
            }
            Phase::Booting | Phase::Configuring | Phase::Enabling => self.halt(reason, now),
            _ => {}
        }
    }

    /// The index in the program of the first move the drives are not known to have run
    /// to its end (see the module docs, "Where the drives are"): the move of the last
    /// set-point known reached, or the one after it if that set-point is its end; 0 if
    /// none is known reached.
    pub fn resume_move(&self) -> usize {
        let k = self.reached;
        if k == 0 {
            return 0;
        }
        let i = self.junctions.partition_point(|&j| j < k);
        match self.setpoints.moves.get(i) {
            Some(m) if self.junctions[i] == k => m.index + 1,
            Some(m) => m.index,
            None => self.setpoints.moves.last().map_or(0, |m| m.index + 1),
        }
    }

    /// The change of speed in one cycle on the hold ramp.
    fn ramp_step(&self) -> f64 {
        let cycles = self.config.hold_ramp.as_secs_f64() / self.setpoints.period.as_secs_f64();
        1.0 / cycles.max(1.0)
    }

    /// The set-points' path at `position` (in cycles, as the session counts it): between
    /// two set-points, the straight move from one to the other, to the nearest count.
    fn path_at(&self, position: f64) -> [i64; 3] {
        let points = &self.setpoints.points;
        let whole = position.floor() as usize;
        let before = match whole {
            0 => self.setpoints.start,
            k => points[k - 1],
        };
        let fraction = position - whole as f64;
        match points.get(whole) {
            Some(after) if fraction > 0.0 => std::array::from_fn(|i| {
                before[i] + ((after[i] - before[i]) as f64 * fraction).round() as i64
            }),
            _ => before,
        }
    }

    /// Which of the three a node is.
    fn slot(&self, node: NodeId) -> Option<usize> {
        self.config.nodes.iter().position(|n| *n == node)
    }

    fn reason_for(&self, k: usize) -> (NodeId, Axis) {
        (self.config.nodes[k], self.drives[k].axis)
    }

    /// Whether the cycle runs.
    fn cyclic(&self) -> bool {
        matches!(
            self.phase,
            Phase::Enabling | Phase::Running | Phase::Settling | Phase::Disabling | Phase::Stopping
        )
    }

    /// Stops the job for `reason` (the first reason stands).
    fn halt(&mut self, reason: StopReason, now: Duration) {
        if matches!(
            self.phase,
            Phase::Stopping | Phase::Stopped | Phase::Finished
        ) {
            return;
        }
        self.events.push(Event::Stopped { reason });
        if self.cyclic() {
            self.phase = Phase::Stopping;
            self.deadline = Some(now + self.config.disable_timeout);
            self.drives.iter_mut().for_each(|d| d.fresh = false);
        } else {
            // Nothing was enabled: there is nothing to stop.
            self.phase = Phase::Stopped;
            self.events.push(Event::Halted {
                unconfirmed: Vec::new(),
            });
        }
    }

    /// A frame from the bus, received at `now`.
    pub fn receive(&mut self, frame: &CanFrame, now: Duration) {
        let CanId::Standard(id) = frame.id() else {
            return;
        };
        if frame.is_remote() {
            return;
        }
        let cob = Cob::classify(id);
        let (node, k) = match cob {
            Cob::Heartbeat(node)
            | Cob::Emcy(node)
            | Cob::SdoResponse(node)
            | Cob::Tpdo(_, node) => match self.slot(node) {
                Some(k) => (node, k),
                None => return,
            },
            _ => return,
        };
        match cob {
            Cob::Heartbeat(_) => self.heartbeat(k, frame, now),
            Cob::Emcy(_) => {
                let Ok(emcy) = decode_emcy(frame) else {
                    return;
                };
                self.events.push(Event::Emergency(emcy));
                if !emcy.is_reset() {
                    let axis = self.drives[k].axis;
                    let reason = StopReason::Emergency {
                        node,
                        axis,
                        code: emcy.code,
                        meaning: emcy_meaning(&emcy),
                    };
                    self.halt(reason, now);
                }
            }
            Cob::SdoResponse(_) => {
                let done = self.drives[k].sdo.receive(frame);
                while let Some(frame) = self.drives[k].sdo.transmit() {
                    self.outbox.push(frame);
                }
                match done {
                    Some(Ok(done)) => self.configured(k, done, now),
                    Some(Err(error)) => self.halt(StopReason::Sdo(error), now),
                    None => {}
                }
            }
            Cob::Tpdo(pdo, _) if pdo.get() == 1 => self.tpdo(k, frame.data(), now),
            _ => {}
        }
    }

    fn heartbeat(&mut self, k: usize, frame: &CanFrame, now: Duration) {
        // A malformed heartbeat is not one: it does not keep the node alive.
        let Ok(beat) = decode_heartbeat(frame) else {
            return;
        };
        let (node, axis) = self.reason_for(k);
        if beat.state == NmtState::BootUp {
            if self.phase == Phase::Booting {
                if !self.drives[k].booted {
                    self.drives[k].booted = true;
                    self.events.push(Event::BootUp { node });
                }
            } else {
                self.halt(StopReason::Rebooted { node, axis }, now);
            }
            return;
        }
        let drive = &mut self.drives[k];
        if drive.heartbeat_due.is_some() {
            drive.heartbeat_due = Some(now + self.config.heartbeat_timeout);
        }
        let running = matches!(
            self.phase,
            Phase::Running | Phase::Settling | Phase::Disabling
        );
        if running && beat.state != NmtState::Operational {
            let reason = StopReason::NotOperational {
                node,
                axis,
                state: beat.state,
            };
            self.halt(reason, now);
        }
    }

    /// An SDO transfer of drive `k` succeeded.
    fn configured(&mut self, k: usize, done: SdoDone, now: Duration) {
        let (node, axis) = self.reason_for(k);
        match done {
            SdoDone::Uploaded { index, data, .. } if index == object::DEVICE_TYPE => {
                let mut bytes = [0; 4];
                bytes[..data.len()].copy_from_slice(&data);
                let device_type = u32::from_le_bytes(bytes);
                if device_type & 0xFFFF != 0x0192 {
                    let reason = StopReason::DeviceType {
                        node,
                        axis,
                        device_type,
                    };
                    self.halt(reason, now);
                }
            }
            SdoDone::Downloaded { index, .. } if index == object::PRODUCER_HEARTBEAT => {
                // The drive restarts its period on this write: supervise from now.
                self.drives[k].heartbeat_due = Some(now + self.config.heartbeat_timeout);
            }
            _ => {}
        }
        if self.phase == Phase::Configuring
            && self.drives[k].ops.is_empty()
            && !self.drives[k].sdo.is_busy()
        {
            self.events.push(Event::Configured { node });
        }
    }

    fn tpdo(&mut self, k: usize, data: &[u8], now: Duration) {
        let (node, axis) = self.reason_for(k);
        if data.len() < 6 {
            let len = data.len();
            return self.halt(StopReason::Tpdo { node, axis, len }, now);
        }
        let statusword = u16::from_le_bytes([data[0], data[1]]);
        let wire = i32::from_le_bytes([data[2], data[3], data[4], data[5]]);
        let start = self.setpoints.start[k];
        let drive = &mut self.drives[k];
        let near = drive.target.or(drive.actual).unwrap_or(start);
        let actual = unwrap_near(wire, near);
        drive.still = drive.actual == Some(actual);
        let news = !drive.still || drive.statusword != Some(statusword);
        drive.actual = Some(actual);
        drive.statusword = Some(statusword);
        drive.fresh = true;
        if news {
            self.progressed = now;
        }
        let state = match PowerState::from_statusword(statusword) {
            Ok(state) => state,
            Err(_) if self.phase == Phase::Stopping => return,
            Err(_) => {
                return self.halt(
                    StopReason::Statusword {
                        node,
                        axis,
                        statusword,
                    },
                    now,
                )
            }
        };
        match self.phase {
            Phase::Enabling if drive.target.is_none() => {
                let tolerance = self.config.start_tolerance;
                if actual.abs_diff(start) > u64::from(tolerance) {
                    let reason = StopReason::StartMismatch {
                        node,
                        axis,
                        actual,
                        start,
                        tolerance,
                    };
                    return self.halt(reason, now);
                }
                drive.target = Some(actual);
            }
            Phase::Running | Phase::Settling => match state {
                PowerState::OperationEnabled
                    if self.config.operation == Operation::InterpolatedPosition
                        && !Statusword(statusword).ip_mode_active() =>
                {
                    self.halt(
                        StopReason::IpModeInactive {
                            node,
                            axis,
                            statusword,
                        },
                        now,
                    );
                }
                PowerState::OperationEnabled => {}
                PowerState::Fault | PowerState::FaultReactionActive => {
                    self.halt(
                        StopReason::Fault {
                            node,
                            axis,
                            statusword,
                        },
                        now,
                    );
                }
                state => self.halt(StopReason::LeftOperation { node, axis, state }, now),
            },
            _ => {}
        }
        self.track_reached();
    }

    /// Counts the set-points the drives are known to have reached, from the positions they
    /// last reported (see the module docs, "Where the drives are").
    fn track_reached(&mut self) {
        let window = u64::from(self.config.settle_window);
        let (Some(x), Some(z), Some(c)) = (
            self.drives[0].actual,
            self.drives[1].actual,
            self.drives[2].actual,
        ) else {
            return;
        };
        let at = |point: [i64; 3]| {
            [x, z, c]
                .iter()
                .zip(point)
                .all(|(a, p)| a.abs_diff(p) <= window)
        };
        let targets = self.drives.each_ref().map(|d| d.target);
        if let [Some(x), Some(z), Some(c)] = targets {
            if at([x, z, c]) {
                self.reached = self.reached.max(self.sent);
                return;
            }
        }
        let low = self.reached.max(self.sent.saturating_sub(REACHED_LOOKBACK));
        if let Some(k) = (low + 1..=self.sent)
            .rev()
            .find(|&k| at(self.setpoints.points[k - 1]))
        {
            self.reached = k;
        }
    }

    /// Tells the session the time; returns the frames to send now, in order.
    pub fn poll(&mut self, now: Duration) -> Vec<CanFrame> {
        let mut out = std::mem::take(&mut self.outbox);
        self.supervise(now);
        match self.phase {
            Phase::Booting => self.boot(now, &mut out),
            Phase::Configuring => self.configure(now, &mut out),
            _ => {}
        }
        if self.cyclic() && now >= self.next_sync {
            self.cycle(now, &mut out);
        }
        out
    }

    /// Heartbeat consumer: a node not heard from in time is lost.
    fn supervise(&mut self, now: Duration) {
        if matches!(
            self.phase,
            Phase::Finished | Phase::Stopped | Phase::Booting
        ) {
            return;
        }
        for k in 0..3 {
            let drive = &mut self.drives[k];
            if drive.lost || drive.heartbeat_due.is_none_or(|due| now <= due) {
                continue;
            }
            drive.lost = true;
            let (node, axis) = self.reason_for(k);
            let timeout = self.config.heartbeat_timeout;
            self.halt(
                StopReason::HeartbeatLost {
                    node,
                    axis,
                    timeout,
                },
                now,
            );
        }
    }

    fn boot(&mut self, now: Duration, out: &mut Vec<CanFrame>) {
        let deadline = *self.deadline.get_or_insert(now + self.config.boot_wait);
        if self.drives.iter().all(|d| d.booted) {
            self.phase = Phase::Configuring;
            self.deadline = None;
            return self.configure(now, out);
        }
        if now < deadline {
            return;
        }
        let missing: Vec<usize> = (0..3).filter(|&k| !self.drives[k].booted).collect();
        if self.reset_sent {
            let (node, axis) = self.reason_for(missing[0]);
            return self.halt(StopReason::NoBootUp { node, axis }, now);
        }
        let nodes: Vec<NodeId> = missing.iter().map(|&k| self.config.nodes[k]).collect();
        for node in &nodes {
            out.push(NmtCommand::ResetCommunication.frame(Some(*node)));
        }
        self.events.push(Event::ResetCommunication { nodes });
        self.reset_sent = true;
        self.deadline = Some(now + self.config.boot_wait);
    }

    fn configure(&mut self, now: Duration, out: &mut Vec<CanFrame>) {
        for k in 0..3 {
            if let Some(error) = self.drives[k].sdo.poll(now) {
                out.extend(std::iter::from_fn(|| self.drives[k].sdo.transmit()));
                return self.halt(StopReason::Sdo(error), now);
            }
            let drive = &mut self.drives[k];
            if !drive.sdo.is_busy() {
                let started = match drive.ops.pop_front() {
                    Some(Op::CheckDeviceType) => drive.sdo.upload(object::DEVICE_TYPE, 0, now),
                    Some(Op::Write(w)) => drive.sdo.download(w.index, w.sub, &w.data, now),
                    None => Ok(()),
                };
                // One transfer at a time, of 1-4 bytes: the client cannot refuse these.
                started.expect("an idle client takes an expedited transfer");
            }
            out.extend(std::iter::from_fn(|| self.drives[k].sdo.transmit()));
        }
        if self.phase != Phase::Configuring {
            return;
        }
        if self
            .drives
            .iter()
            .all(|d| d.ops.is_empty() && !d.sdo.is_busy())
        {
            for node in self.config.nodes {
                out.push(NmtCommand::Start.frame(Some(node)));
            }
            self.events.push(Event::Started);
            self.phase = Phase::Enabling;
            self.deadline = Some(now + self.config.enable_timeout);
            self.next_sync = now;
        }
    }

    /// One cycle: RPDOs, then SYNC.
    fn cycle(&mut self, now: Duration, out: &mut Vec<CanFrame>) {
        let period = self.setpoints.period;
        let late_by = now - self.next_sync;
        let late = late_by >= period;
        self.next_sync = if late {
            now + period
        } else {
            self.next_sync + period
        };
        let words = match self.phase {
            Phase::Enabling => self.enabling(now),
            Phase::Running => self.running(now),
            Phase::Settling => self.settling(now),
            Phase::Disabling => self.disabling(now),
            Phase::Stopping => self.stopping(now),
            _ => None,
        };
        // A phase may have ended the cycle (or moved on to another that sends).
        let Some(words) = words else {
            return;
        };
        if late {
            self.events.push(Event::Late {
                sync: self.syncs + 1,
                late_by,
            });
        }
        for (k, word) in words.into_iter().enumerate() {
            let (Some(word), Some(target)) = (word, self.drives[k].target) else {
                continue;
            };
            let mut data = word.to_le_bytes().to_vec();
            data.extend_from_slice(&to_wire(target).to_le_bytes());
            let pdo = PdoNumber::new(1).expect("PDO 1");
            out.push(frame(cob::rpdo(pdo, self.config.nodes[k]), &data));
        }
        out.push(cia301::sync_frame());
        self.syncs += 1;
    }

    /// Controlwords of the walk to Operation enabled (and in interpolated position mode
    /// on to ip mode active), or on to running.
    fn enabling(&mut self, now: Duration) -> Option<[Option<u16>; 3]> {
        let operation = self.config.operation;
        let following = |d: &Drive| d.statusword.is_some_and(|w| operation.follows(w));
        if self.drives.iter().all(following) {
            self.events.push(Event::Enabled { syncs: self.syncs });
            self.phase = Phase::Running;
            self.deadline = None;
            self.progressed = now;
            if self.held {
                // Held before the set-points start: they start standing.
                self.speed = 0.0;
                self.events.push(Event::Held { sent: 0 });
            }
            return self.running(now);
        }
        if self.deadline.is_some_and(|d| now >= d) {
            let k = (0..3).find(|&k| !following(&self.drives[k])).unwrap_or(0);
            let (node, axis) = self.reason_for(k);
            let state = match self.drives[k].statusword {
                None => "no TPDO seen".to_string(),
                Some(w) => match PowerState::from_statusword(w) {
                    Ok(PowerState::OperationEnabled)
                        if operation == Operation::InterpolatedPosition =>
                    {
                        format!(
                            "OperationEnabled (statusword 0x{w:04X}) without ip mode active \
                             (bit 12)"
                        )
                    }
                    Ok(state) => format!("{state:?} (statusword 0x{w:04X})"),
                    Err(e) => e.to_string(),
                },
            };
            let timeout = self.config.enable_timeout;
            self.halt(
                StopReason::EnableTimeout {
                    node,
                    axis,
                    state,
                    timeout,
                },
                now,
            );
            return self.stopping(now);
        }
        let mut words = [None; 3];
        for (k, word) in words.iter_mut().enumerate() {
            let drive = &mut self.drives[k];
            let (Some(statusword), Some(_)) = (drive.statusword, drive.target) else {
                continue;
            };
            // The TPDO was checked when it arrived: a statusword that decodes.
            *word = drive.sequencer.controlword(statusword).ok();
            // Enable ip mode once Operation enabled shows, not before (the sequencer
            // then sends enable operation, 0x0F).
            if drive.state() == Some(PowerState::OperationEnabled) {
                *word = word.map(|w| w | operation.running_bits());
            }
        }
        Some(words)
    }

    /// The spindle marks due once `sent` set-points are out.
    fn due_marks(&mut self) {
        let marks = &self.setpoints.marks;
        while self.next_mark < marks.len() && marks[self.next_mark].cycle <= self.sent {
            let mark = marks[self.next_mark];
            self.events.push(Event::Spindle {
                block: mark.index,
                rpm: mark.spindle,
            });
            self.next_mark += 1;
        }
    }

    /// The next set-point: one a cycle at speed; on a hold or a resume, the path's speed
    /// ramps down to a stand or back up, and the target lies on the path in between,
    /// never past the end of the straight move it is on.
    fn running(&mut self, now: Duration) -> Option<[Option<u16>; 3]> {
        self.due_marks();
        let total = self.setpoints.points.len();
        if self.sent >= total {
            self.phase = Phase::Settling;
            self.deadline = Some(now + self.config.settle_timeout);
            return self.settling(now);
        }
        if let Some(deadline) = self.stand_by {
            let off = self.off_target();
            if self.speed == 0.0 && off.is_none() {
                self.stand_by = None;
                return self.disable(now);
            }
            if now >= deadline {
                let (node, axis) = self.reason_for(off.unwrap_or(0));
                let reason = StopReason::NoStand {
                    node,
                    axis,
                    window: self.config.settle_window,
                    waited: self.config.hold_ramp + self.config.settle_timeout,
                };
                self.halt(reason, now);
                return self.stopping(now);
            }
        }
        if let Some(limit) = self.config.stall_timeout {
            if !self.held && now.saturating_sub(self.progressed) >= limit {
                self.stop_held(StopReason::Stalled { waited: limit }, now);
            }
        }
        // The straight move the next step is on, and how fast a feed override may run it:
        // a feed move never so fast that an axis exceeds its max rate, a rapid or the
        // spin-up wait at its own speed whatever the override. Entering a move with less
        // room, the speed drops to it at once, as at any junction; and between a feed move
        // and a rapid or the wait, each starts at its own speed (unless a hold or a resume
        // ramps it), as their speeds along the path differ there anyway.
        let next = self
            .junctions
            .partition_point(|&j| j as f64 <= self.position);
        let (room, feed) = self
            .setpoints
            .moves
            .get(next)
            .map_or((1.0, false), |m| (m.speedup, m.feed));
        if feed != self.on_feed && !self.held && !self.resuming && self.speed > 0.0 {
            self.speed = if feed { self.feed.min(room) } else { 1.0 };
        }
        self.on_feed = feed;
        self.speed = self.speed.min(room);
        let step = self.ramp_step();
        let was = self.speed;
        let target = match (self.held, feed) {
            (true, _) => 0.0,
            (false, true) => self.feed.min(room),
            (false, false) => 1.0,
        };
        self.speed = if self.speed > target {
            (self.speed - step).max(target)
        } else {
            (self.speed + step).min(target)
        };
        if self.speed == 0.0 && was > 0.0 {
            self.events.push(Event::Held { sent: self.sent });
        }
        if !self.held && self.speed == target {
            if self.resuming && was < target {
                self.events.push(Event::Resumed);
            }
            self.resuming = false;
            if let Some(percent) = self.feed_asked.take() {
                self.events.push(Event::FeedOverride { percent });
            }
        }
        // Up to the next junction at most: the step stays on one straight move.
        let junction = self.junctions.get(next).map_or(total, |&j| j.min(total));
        self.position = (self.position + self.speed).min(junction as f64);
        let point = self.path_at(self.position);
        if self
            .drives
            .iter()
            .zip(point)
            .all(|(d, p)| d.target == Some(p))
        {
            // The set-points stand (a hold, a spin-up): no drive has anywhere new to go.
            self.progressed = now;
        }
        for (drive, target) in self.drives.iter_mut().zip(point) {
            drive.target = Some(target);
        }
        self.sent = self.position.floor() as usize;
        Some([Some(self.run_word()); 3])
    }

    /// The controlword while the set-points run: enable operation, with enable ip mode
    /// in interpolated position mode.
    fn run_word(&self) -> u16 {
        Command::EnableOperation.word() | self.config.operation.running_bits()
    }

    fn settling(&mut self, now: Duration) -> Option<[Option<u16>; 3]> {
        let end = self.setpoints.end();
        let window = u64::from(self.config.settle_window);
        let off = (0..3).find(|&k| {
            self.drives[k]
                .actual
                .is_none_or(|a| a.abs_diff(end[k]) > window)
        });
        let Some(k) = off else {
            self.events.push(Event::Settled);
            return self.disable(now);
        };
        if self.deadline.is_some_and(|d| now >= d) {
            let (node, axis) = self.reason_for(k);
            let reason = StopReason::NotSettled {
                node,
                axis,
                actual: self.drives[k].actual.unwrap_or(self.setpoints.start[k]),
                target: end[k],
                window: self.config.settle_window,
                timeout: self.config.settle_timeout,
            };
            self.halt(reason, now);
            return self.stopping(now);
        }
        Some([Some(self.run_word()); 3])
    }

    /// The first drive not within the settle window of its target, if any.
    fn off_target(&self) -> Option<usize> {
        let window = u64::from(self.config.settle_window);
        (0..3).find(|&k| match (self.drives[k].actual, self.drives[k].target) {
            (Some(actual), Some(target)) => actual.abs_diff(target) > window,
            _ => true,
        })
    }

    /// The walk to Switch on disabled begins, at the job's end or a gentle stop's.
    fn disable(&mut self, now: Duration) -> Option<[Option<u16>; 3]> {
        self.phase = Phase::Disabling;
        self.deadline = Some(now + self.config.disable_timeout);
        for drive in &mut self.drives {
            drive.sequencer.set_target(Target::SwitchOnDisabled);
            drive.fresh = false;
        }
        self.disabling(now)
    }

    fn disabling(&mut self, now: Duration) -> Option<[Option<u16>; 3]> {
        let disabled = |d: &Drive| d.fresh && d.state() == Some(PowerState::SwitchOnDisabled);
        if self.drives.iter().all(disabled) {
            self.deadline = None;
            if self.interrupted {
                self.phase = Phase::Stopped;
                self.events.push(Event::Halted {
                    unconfirmed: Vec::new(),
                });
            } else {
                self.events.push(Event::Finished);
                self.phase = Phase::Finished;
            }
            return None;
        }
        if self.deadline.is_some_and(|d| now >= d) {
            let k = (0..3).find(|&k| !disabled(&self.drives[k])).unwrap_or(0);
            let (node, axis) = self.reason_for(k);
            let timeout = self.config.disable_timeout;
            // Disabling is what a stop does too: there is no more to try.
            self.events.push(Event::Stopped {
                reason: StopReason::NotDisabled {
                    node,
                    axis,
                    timeout,
                },
            });
            self.phase = Phase::Stopped;
            self.events.push(Event::Halted {
                unconfirmed: vec![node],
            });
            return None;
        }
        let mut words = [None; 3];
        for (k, word) in words.iter_mut().enumerate() {
            let drive = &mut self.drives[k];
            *word = drive
                .statusword
                .and_then(|w| drive.sequencer.controlword(w).ok());
        }
        Some(words)
    }

    fn stopping(&mut self, now: Duration) -> Option<[Option<u16>; 3]> {
        let safe = |d: &Drive| {
            d.fresh
                && matches!(
                    d.state(),
                    Some(
                        PowerState::SwitchOnDisabled
                            | PowerState::Fault
                            | PowerState::NotReadyToSwitchOn
                    )
                )
        };
        let done = self.drives.iter().all(|d| d.lost || safe(d));
        if done || self.deadline.is_some_and(|d| now >= d) {
            let unconfirmed = (0..3)
                .filter(|&k| !safe(&self.drives[k]))
                .map(|k| self.config.nodes[k])
                .collect();
            self.phase = Phase::Stopped;
            self.events.push(Event::Halted { unconfirmed });
            return None;
        }
        let words = self.drives.each_ref().map(|d| match d.state() {
            Some(PowerState::OperationEnabled) => Some(Command::QuickStop.word()),
            // Stopping on the quick stop ramp: hold it until the drive stands still.
            Some(PowerState::QuickStopActive) if !(d.fresh && d.still) => {
                Some(Command::QuickStop.word())
            }
            Some(PowerState::Fault | PowerState::FaultReactionActive) | None => None,
            Some(_) => Some(Command::DisableVoltage.word()),
        });
        Some(words)
    }
}
