//! The simulator's Δ guard: the profile error of the motion the simulated controller
//! actually executed, measured with the swept-volume engine while it executes.
//!
//! The target points are those `whirl verify` measures ([`crate::judge::measure`]). A point's
//! error is final once the motion has gone past every pose that could still cut it: the
//! search around a point reaches one workpiece revolution beyond the poses of the profile
//! positions near it, so once the turning motion's Z is more than that (1.25 feeds, with the
//! search window and a margin) past the furthest of those poses, the point is measured, and
//! a point beyond Δ stops the machine at once. What is still open when the program ends is
//! measured then. The alarm so comes within about a revolution and a quarter of the cut that
//! caused it, which is as soon as the error is known: an undercut is only an undercut once
//! nothing more will pass.
//!
//! Rapids are positioning, not cutting: the planner keeps them clear of the work (the
//! lead-in and lead-out), so the guard judges the feed moves. So are moves with the ring
//! clear of the work all round from end to end (`clear_of_the_work` below): CiA 402
//! drives know no rapids, and every cycle they run reaches the guard as a move of its own,
//! among them a resume's re-entry turning C back to the resume line's start with X clear,
//! which cuts nothing. Any other move that turns C the other way, or feeds Z back while C turns,
//! cannot be measured and is itself a breach.

use crate::config::job::Job;
use crate::config::machine::MachineProfile;
use crate::geometry::linkage::{Ring, Whirling};
use crate::judge::measure::{Grid, Motion, PointError, Sample, Target};
use crate::judge::verify::{self, CheckError};
use std::collections::VecDeque;
use whirl_sim::{Breach, ExecutedBlock, Guard, Measured, MoveKind};

/// How far past the furthest seeding pose, in feeds per revolution, the motion must be
/// before a point's error is final: one revolution of search, its ±6° window, and a margin.
const SETTLE_FEEDS: f64 = 1.25;

/// A Δ guard for one job (see the module docs).
#[derive(Debug)]
pub struct DeltaGuard {
    target: Target,
    grid: Grid,
    motion: Motion,
    delta: f64,
    /// X words are diameters: the motion's X is half of them.
    x_diameter: bool,
    /// The ring the groove is cut with, and the work's least and largest radius: where the
    /// ring is clear of the work.
    ring: Ring,
    radii: (f64, f64),
    /// For each profile position of the grid, the lowest and highest Z offset of the poses
    /// that seed its search.
    reach: Vec<(f64, f64)>,
    /// Points not yet final; ordered by when the feed settles them once Z's direction is
    /// known.
    open: VecDeque<Sample>,
    ordered: bool,
    measured: Measured,
    worst_overcut: Option<PointError>,
    worst_undercut: Option<PointError>,
}

impl DeltaGuard {
    /// A guard for `job`'s groove, cut by `ring` (the ring the program was planned with, see
    /// [`verify::target`]), on `machine` (whose X mode says how to read X).
    pub fn new(job: &Job, ring: Ring, machine: &MachineProfile) -> Result<DeltaGuard, CheckError> {
        let target = verify::target(job, ring)?;
        let grid = target.grid();
        let reach = grid
            .near
            .iter()
            .map(|seeds| {
                seeds
                    .iter()
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |r, s| {
                        (r.0.min(s.z), r.1.max(s.z))
                    })
            })
            .collect();
        let open = grid.samples.iter().copied().collect();
        let radii = job.profile.radius_range();
        Ok(DeltaGuard {
            target,
            grid,
            motion: Motion::empty(),
            delta: job.cut.delta,
            x_diameter: machine.x_diameter(),
            ring,
            radii,
            reach,
            open,
            ordered: false,
            measured: Measured {
                delta_mm: job.cut.delta,
                ..Measured::default()
            },
            worst_overcut: None,
            worst_undercut: None,
        })
    }

    /// The target points of the groove: all of them are measured by the program's end.
    pub fn points(&self) -> usize {
        self.grid.samples.len()
    }

    /// The worst overcut and undercut found so far, with where they are.
    pub fn worst(&self) -> (Option<PointError>, Option<PointError>) {
        (self.worst_overcut, self.worst_undercut)
    }

    /// The Z past which the turning motion must be for `s` to be final, in the feed's
    /// direction `dir`.
    fn settles_at(&self, s: &Sample, dir: f64) -> f64 {
        let (lo, hi) = self.reach[s.k];
        let furthest = if dir > 0.0 { hi } else { lo };
        s.z + furthest + dir * SETTLE_FEEDS * self.target.feed()
    }

    /// Measure one point; a breach if it is beyond Δ.
    fn settle(&mut self, s: Sample) -> Result<(), Breach> {
        let e = self.target.point_error(&self.grid, s, &self.motion);
        self.measured.points += 1;
        if -e.error_mm > self.measured.max_overcut_mm {
            self.measured.max_overcut_mm = -e.error_mm;
            self.worst_overcut = Some(e);
        }
        if e.error_mm > self.measured.max_undercut_mm {
            self.measured.max_undercut_mm = e.error_mm;
            self.worst_undercut = Some(e);
        }
        if e.error_mm.abs() <= self.delta {
            return Ok(());
        }
        let [x, y, z] = e.at;
        let [px, py] = e.profile_point;
        Err(Breach {
            message: format!(
                "profile error {:.4} mm {} beyond delta {} mm at X{x:.3} Y{y:.3} Z{z:.3} \
                 (start {}, profile point {px:.3},{py:.3})",
                e.error_mm.abs(),
                if e.error_mm < 0.0 {
                    "overcut"
                } else {
                    "undercut"
                },
                self.delta,
                e.start + 1,
            ),
        })
    }
}

impl Guard for DeltaGuard {
    fn executed(&mut self, block: &ExecutedBlock) -> Result<(), Breach> {
        // Rapids and jogs position the ring; the groove is the program's feeds.
        if matches!(block.kind, MoveKind::Rapid | MoveKind::Jog) {
            return Ok(());
        }
        let scale = if self.x_diameter { 0.5 } else { 1.0 };
        let at = |p: whirl_sim::Position| [p.x * scale, p.z, p.c];
        // X moves along a straight move, so a ring clear at both ends is clear all along;
        // clear of the work's largest radius by Δ more, as that radius is sampled.
        let work = (self.radii.0 - self.delta, self.radii.1 + self.delta);
        let clear = |x: f64| clear_of_the_work(&self.ring, x * scale, work);
        if clear(block.from.x) && clear(block.to.x) {
            return Ok(());
        }
        self.motion
            .push(at(block.from), at(block.to), block.line as usize)
            .map_err(|e| Breach {
                message: format!("the motion of line {} cannot be measured: {e}", block.line),
            })?;
        let dir = self.motion.z_dir();
        if dir == 0.0 {
            return Ok(());
        }
        if !self.ordered {
            let mut open: Vec<Sample> = self.open.drain(..).collect();
            open.sort_by(|a, b| {
                (dir * self.settles_at(a, dir)).total_cmp(&(dir * self.settles_at(b, dir)))
            });
            self.open = open.into();
            self.ordered = true;
        }
        let Some(z_now) = self.motion.z_now() else {
            return Ok(());
        };
        while let Some(&s) = self.open.front() {
            if dir * (z_now - self.settles_at(&s, dir)) <= 0.0 {
                break;
            }
            self.open.pop_front();
            self.settle(s)?;
        }
        Ok(())
    }

    fn program_end(&mut self) -> Result<(), Breach> {
        if self.open.is_empty() {
            return Ok(());
        }
        if !self.motion.is_turning() {
            return Err(Breach {
                message: format!(
                    "the program ended without turning C: none of the groove's {} points \
                     was cut",
                    self.open.len()
                ),
            });
        }
        while let Some(s) = self.open.pop_front() {
            self.settle(s)?;
        }
        Ok(())
    }

    fn measured(&self) -> Measured {
        self.measured
    }
}

/// Whether `ring`, its centre `x` (a radius) off the work's axis, keeps clear of a work
/// whose surface lies between the radii `rho` all round, whatever C and Z are: an internal
/// ring's tip circle, tilted by δ, projects onto the transverse plane as an ellipse whose
/// points are at least R·cos δ from its centre, so at least R·cos δ − |x| from the axis; an
/// external ring's are at most R from its centre, so at least |x| − R from the axis; the
/// insert's nose reaches r further. A bore head's points are at most |x| + R + r from the
/// axis, clear of a nut whose bore is wider. (The planner's clear position is such an X:
/// `plan::clear_x`.)
fn clear_of_the_work(ring: &Ring, x: f64, rho: (f64, f64)) -> bool {
    let (rho_min, rho_max) = rho;
    match ring.whirling {
        Whirling::Internal => ring.radius * ring.installation.cos() - x.abs() - ring.nose > rho_max,
        Whirling::External => x.abs() - ring.radius - ring.nose > rho_max,
        Whirling::Bore => x.abs() + ring.radius + ring.nose < rho_min,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::testing::example;
    use crate::judge::simulator::machine;
    use whirl_sim::{Controller, ControllerOptions, MachineState};

    /// The ring `plan` plans `job` with.
    fn ring(job: &Job) -> Ring {
        crate::plan::angles::ring(job).unwrap().0
    }

    /// Runs `text` on a simulated controller guarded for `job`, feeding lines as its RX
    /// buffer has room; returns everything it printed and the controller.
    fn run(job: &Job, text: &str) -> (String, Controller) {
        let profile = MachineProfile::builtin_sim().unwrap();
        let mut sim = Controller::new(&machine(&profile), ControllerOptions::default()).unwrap();
        sim.set_guard(Box::new(DeltaGuard::new(job, ring(job), &profile).unwrap()));
        let mut out = String::from_utf8(sim.take_output()).unwrap();
        let mut stopped = false;
        for line in text.lines() {
            while sim.rx_free() < line.len() + 1 && sim.state() != MachineState::Alarm {
                sim.advance(0.1).unwrap();
            }
            if sim.state() == MachineState::Alarm {
                stopped = true;
                break;
            }
            sim.receive(format!("{line}\n").as_bytes());
        }
        while !stopped && sim.state() != MachineState::Alarm && !out_has_end(&sim, &out) {
            sim.advance(0.1).unwrap();
            out.push_str(&String::from_utf8(sim.take_output()).unwrap());
        }
        out.push_str(&String::from_utf8(sim.take_output()).unwrap());
        (out, sim)
    }

    fn out_has_end(sim: &Controller, out: &str) -> bool {
        out.contains("[MSG:Pgm End]") && sim.state() == MachineState::Idle
    }

    #[test]
    fn a_planned_program_runs_within_delta_and_every_point_is_measured() {
        let job = example("trapezoidal");
        let profile = MachineProfile::builtin_sim().unwrap();
        let plan = crate::plan::plan(&job, &profile).unwrap();
        let (out, sim) = run(&job, &plan.text);
        assert!(!out.contains("ALARM"), "{out}");
        assert!(out.contains("[MSG:Pgm End]"));
        let m = sim.guard().unwrap().measured();
        let target = verify::target(&job, plan.ring).unwrap();
        assert_eq!(m.points, target.grid().samples.len());
        assert!(m.max_error_mm() <= job.cut.delta, "{m:?}");
        // What the guard measured on the executed motion is what `whirl verify` measures on
        // the program: the same engine, the motion differing by the controller's 32-bit
        // positions, which the planner's rounding share bounds.
        let v = verify::verify(&job, plan.ring, &profile, &plan.text, false).unwrap();
        let held = plan.report.rounding_mm;
        assert!(
            (m.max_overcut_mm - v.max_overcut_mm).abs() <= held,
            "{m:?} {v:?}"
        );
        assert!(
            (m.max_undercut_mm - v.max_undercut_mm).abs() <= held,
            "{m:?} {v:?}"
        );
    }

    #[test]
    fn a_program_that_stops_short_trips_at_its_end_with_the_undercut_it_left() {
        let job = example("trapezoidal");
        let profile = MachineProfile::builtin_sim().unwrap();
        let plan = crate::plan::plan(&job, &profile).unwrap();
        // The lead-in and the first few hundred linked moves, then the retract and the end.
        let mut lines: Vec<&str> = plan.text.lines().take(300).collect();
        lines.extend(["G94", "G0 X0", "M5", "M2"]);
        let (out, sim) = run(&job, &lines.join("\n"));
        let alarm = out.find("ALARM:64").expect("the guard trips");
        assert!(
            out[alarm..].contains("undercut beyond delta 0.01 mm"),
            "{out}"
        );
        // It tripped at the end: every line before M2 was answered ok, M2 error:9.
        let answers: Vec<&str> = out
            .lines()
            .filter(|l| *l == "ok" || l.starts_with("error:"))
            .collect();
        assert_eq!(answers.len(), lines.len());
        assert!(answers[..lines.len() - 1].iter().all(|a| *a == "ok"));
        assert_eq!(answers[lines.len() - 1], "error:9");
        assert!(sim.guard().unwrap().measured().max_undercut_mm > job.cut.delta);
    }

    #[test]
    fn jogs_are_positioning_and_not_measured() {
        // A jog turning C back, which as a feed cannot be measured (below), is not judged:
        // the operator's jogs, like rapids, position the ring.
        let job = example("trapezoidal");
        let profile = MachineProfile::builtin_sim().unwrap();
        let mut sim = Controller::new(&machine(&profile), ControllerOptions::default()).unwrap();
        sim.set_guard(Box::new(
            DeltaGuard::new(&job, ring(&job), &profile).unwrap(),
        ));
        sim.receive(b"$J=G91 X5 C10 F500\n$J=G91 C-5 F500\n");
        for _ in 0..100 {
            sim.advance(0.1).unwrap();
        }
        let out = String::from_utf8(sim.take_output()).unwrap();
        assert!(!out.contains("ALARM"), "{out}");
        assert_eq!((sim.position().x, sim.position().c), (5.0, 5.0));
    }

    #[test]
    fn a_feed_turning_c_back_cannot_be_measured_and_trips() {
        // Tr 40: the work's radius is 20 mm; the ring (R 32, r 0.4, δ 7.8°) centred 15 mm
        // off the axis reaches 31.70 − 0.4 − 15 = 16.3 mm from it, into the work.
        let job = example("trapezoidal");
        let program = "G21 G90 G94\nG1 X15 C10 F500\nG1 X15 C5\nM2";
        let (out, _) = run(&job, program);
        assert!(
            out.contains("[MSG:the motion of line 3 cannot be measured: C turns both ways"),
            "{out}"
        );
    }

    #[test]
    fn a_move_turning_c_back_with_the_ring_clear_of_the_work_is_positioning() {
        // As CiA 402 drives run a resume's re-entry: X out to 0, C back at a feed, X in. At X 0 the ring (R 32, r 0.4, δ 7.8°) stays 31.70 − 0.4 = 31.3 mm from
        // the axis, clear of Tr 40's 20 mm: that move cuts nothing and is not judged.
        let job = example("trapezoidal");
        let profile = MachineProfile::builtin_sim().unwrap();
        let mut sim = Controller::new(&machine(&profile), ControllerOptions::default()).unwrap();
        sim.set_guard(Box::new(
            DeltaGuard::new(&job, ring(&job), &profile).unwrap(),
        ));
        // (Z stands, so that no point of the groove is settled by this motion, which is
        // no whirling: only the direction of C is judged.)
        sim.receive(b"G21 G90 G94\nG1 X15 C10 F500\nG1 X0\nG1 C5\nG1 X15\nG1 C20\n");
        for _ in 0..100 {
            sim.advance(0.1).unwrap();
        }
        let out = String::from_utf8(sim.take_output()).unwrap();
        assert!(!out.contains("ALARM"), "{out}");
        assert_eq!(sim.position().c, 20.0);
    }

    #[test]
    fn the_ring_is_clear_of_the_work_where_no_point_of_it_reaches_the_work() {
        let ring = |whirling, radius: f64, nose: f64, tilt_deg: f64| Ring {
            whirling,
            radius,
            nose,
            installation: tilt_deg.to_radians(),
            edge_half_angle: 0.5,
        };
        // Internal, R 60, r 1.2, untilted, work radius 34: the tips pass 60 − x from the
        // axis, the nose 1.2 nearer, so clear while |x| < 24.8, either side.
        let internal = ring(Whirling::Internal, 60.0, 1.2, 0.0);
        for x in [0.0, 24.7, -24.7] {
            assert!(clear_of_the_work(&internal, x, (30.0, 34.0)), "{x}");
        }
        for x in [24.9, -24.9, 34.0] {
            assert!(!clear_of_the_work(&internal, x, (30.0, 34.0)), "{x}");
        }
        // Tilted by 60°: the tip circle's projection is R·cos 60° = 30 across at its
        // narrowest, so clear while |x| < 30 − 1.2 − 20 = 8.8 of a 20 mm work.
        let tilted = ring(Whirling::Internal, 60.0, 1.2, 60.0);
        assert!(clear_of_the_work(&tilted, 8.7, (16.0, 20.0)));
        assert!(!clear_of_the_work(&tilted, 8.9, (16.0, 20.0)));
        // External, R 45, r 1, work radius 20: clear beyond x = 45 + 1 + 20 = 66.
        let external = ring(Whirling::External, 45.0, 1.0, 20.0);
        assert!(clear_of_the_work(&external, 66.1, (16.0, 20.0)));
        assert!(clear_of_the_work(&external, -66.1, (16.0, 20.0)));
        assert!(!clear_of_the_work(&external, 65.9, (16.0, 20.0)));
        // A bore head, R 12, r 0.8, in a nut whose bore is 16.5 mm in radius: its nose
        // reaches |x| + 12.8 from the axis, clear while |x| < 3.7, either side.
        let bore = ring(Whirling::Bore, 12.0, 0.8, 10.0);
        for x in [0.0, 3.6, -3.6] {
            assert!(clear_of_the_work(&bore, x, (16.5, 20.25)), "{x}");
        }
        for x in [3.8, -3.8, 7.0] {
            assert!(!clear_of_the_work(&bore, x, (16.5, 20.25)), "{x}");
        }
    }
}
