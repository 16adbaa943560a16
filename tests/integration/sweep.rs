//! Brute force: does the written program, executed as a controller executes it, keep the
//! swept ring within Δ of the target groove?
//!
//! Independent of the planner's own estimates: the program text is parsed back, every linked
//! move is executed as the straight C/X/Z line a controller interpolates, the ring is the
//! torus of kinematics.md written out again here, and the target is the helical surface of the
//! job's profile, sampled over every start and over one feed spacing of axial positions in the
//! middle of the groove. The profile error at a target point is the smallest torus gap over
//! all executed poses (kinematics.md, "Error: what Δ bounds").

use crate::util;
use glam::{DVec2, DVec3};
use std::f64::consts::TAU;
use whirl::config::job::Job;
use whirl::config::machine::MachineProfile;
use whirl::geometry::linkage::Whirling;
use whirl::geometry::profile::Profile;
use whirl::judge::measure::{Motion, Target};
use whirl::post::gcode::parse::read_program;
use whirl::program::{Move, Position, Program};

/// The ring at one executed pose, with the trigonometry of C done once.
#[derive(Clone, Copy)]
struct Pose {
    x: f64,
    z: f64,
    cos_c: f64,
    sin_c: f64,
}

struct Ring {
    radius: f64,
    nose: f64,
    axis: DVec3,
}

impl Ring {
    /// kinematics.md: a_M = (0, k·sin δe, cos δe), δe = sign(p)·δ.
    fn new(job: &Job, installation_deg: f64) -> Ring {
        let k = match job.tool.whirling {
            Whirling::Internal => 1.0,
            Whirling::External | Whirling::Bore => -1.0,
        };
        let de = job.p().signum() * installation_deg.to_radians();
        Ring {
            radius: job.tool.ring_radius,
            nose: job.tool.nose_radius,
            axis: DVec3::new(0.0, k * de.sin(), de.cos()),
        }
    }

    /// Distance from the workpiece point `q` to the tip circle at `pose`, minus r.
    fn gap(&self, q: DVec3, pose: &Pose) -> f64 {
        let qm = DVec3::new(
            pose.cos_c * q.x - pose.sin_c * q.y,
            pose.sin_c * q.x + pose.cos_c * q.y,
            q.z,
        );
        let d = qm - DVec3::new(pose.x, 0.0, pose.z);
        let along = d.dot(self.axis);
        let radial = (d - along * self.axis).length();
        (radial - self.radius).hypot(along) - self.nose
    }
}

/// The executed linked motion as (X, Z, C in radians) endpoints, in one continuous C frame.
fn linked_path(program: &Program) -> Vec<[f64; 3]> {
    let mut out: Vec<[f64; 3]> = Vec::new();
    for step in program.steps(Position::UNKNOWN) {
        if let Move::Linked { .. } = step.action {
            let from = step.from;
            let to = step.to;
            if out.is_empty() {
                out.push([
                    from.x.unwrap(),
                    from.z.unwrap(),
                    from.c.unwrap().to_radians(),
                ]);
            }
            out.push([to.x.unwrap(), to.z.unwrap(), to.c.unwrap().to_radians()]);
        }
    }
    out
}

/// The pose at path parameter `s` (segment index + fraction): the straight line a controller
/// interpolates between two program points.
fn pose_at(path: &[[f64; 3]], s: f64) -> Pose {
    let i = (s.floor() as usize).min(path.len() - 2);
    let t = s - i as f64;
    let lerp = |k: usize| path[i][k] + t * (path[i + 1][k] - path[i][k]);
    let c = lerp(2);
    Pose {
        x: lerp(0),
        z: lerp(1),
        cos_c: c.cos(),
        sin_c: c.sin(),
    }
}

/// Largest overcut (as a positive number) and undercut over the sampled target points, and
/// every point's error with where it is: (profile parameter, start, z, error).
struct Measured {
    overcut: f64,
    undercut: f64,
    points: Vec<(f64, u32, f64, f64)>,
}

fn measure(job: &Job, profile: &Profile, installation_deg: f64, program: &Program) -> Measured {
    let ring = Ring::new(job, installation_deg);
    let path = linked_path(program);
    // Dense samples of the executed motion, at most 0.2° of C apart; every local minimum of
    // the sampled gap is then refined along the continuous path.
    let mut params = Vec::new();
    for i in 0..path.len() - 1 {
        let dc = (path[i + 1][2] - path[i][2]).abs().to_degrees();
        let parts = (dc / 0.2).ceil().max(1.0) as usize;
        params.extend((0..parts).map(|k| i as f64 + k as f64 / parts as f64));
    }
    let poses: Vec<(f64, Pose)> = params.iter().map(|&s| (s, pose_at(&path, s))).collect();
    let p = job.p();
    let period = TAU / f64::from(job.groove.starts);
    // The torus spans R·sin δ + r axially about its centre: poses farther than that (plus Δ)
    // from a point cannot come within Δ of it.
    let reach = ring.radius * installation_deg.to_radians().sin() + ring.nose + job.cut.delta;
    let z_mid = job.groove.z_start + job.groove.length / 2.0;
    let mut m = Measured {
        overcut: 0.0,
        undercut: 0.0,
        points: Vec::new(),
    };
    let us = 40;
    let phases = 6;
    for iu in 0..us {
        let u = profile.length() * (iu as f64 + 0.5) / us as f64;
        let pos: DVec2 = profile.point(u).pos;
        for start in 0..job.groove.starts {
            for k in 0..phases {
                // Axial positions spread over one feed spacing: the scallop's crest is among them.
                let z = z_mid + job.cut.axial_feed * k as f64 / phases as f64;
                let theta = z / p + period * f64::from(start);
                let xy = DVec2::from_angle(theta).rotate(pos);
                let q = DVec3::new(xy.x, xy.y, z);
                let lo = poses.partition_point(|(_, ps)| ps.z < z - reach);
                let hi = poses.partition_point(|(_, ps)| ps.z <= z + reach);
                let gaps: Vec<f64> = poses[lo..hi]
                    .iter()
                    .map(|(_, ps)| ring.gap(q, ps))
                    .collect();
                let coarse = gaps.iter().copied().fold(f64::INFINITY, f64::min);
                let mut best = coarse;
                for j in 1..gaps.len().saturating_sub(1) {
                    if gaps[j] <= gaps[j - 1] && gaps[j] <= gaps[j + 1] && gaps[j] < coarse + 0.05 {
                        let (a, b) = (poses[lo + j - 1].0, poses[lo + j + 1].0);
                        best = best.min(golden(|s| ring.gap(q, &pose_at(&path, s)), a, b));
                    }
                }
                m.overcut = m.overcut.max(-best);
                m.undercut = m.undercut.max(best);
                m.points.push((u, start, z, best));
            }
        }
    }
    m
}

fn golden(f: impl Fn(f64) -> f64, mut a: f64, mut b: f64) -> f64 {
    let g = (5f64.sqrt() - 1.0) / 2.0;
    let (mut x1, mut x2) = (b - g * (b - a), a + g * (b - a));
    let (mut f1, mut f2) = (f(x1), f(x2));
    for _ in 0..40 {
        if f1 < f2 {
            b = x2;
            (x2, f2) = (x1, f1);
            x1 = b - g * (b - a);
            f1 = f(x1);
        } else {
            a = x1;
            (x1, f1) = (x2, f2);
            x2 = a + g * (b - a);
            f2 = f(x2);
        }
    }
    f1.min(f2)
}

/// Plan an example and read its program text back; the plan says the ring it was planned
/// with (the installation angle a job that gives none plans at).
fn planned(name: &str) -> (Job, Profile, Program, whirl::plan::Plan) {
    let job = Job::load(&util::example(name)).unwrap();
    let machine = MachineProfile::builtin_sim().unwrap();
    let plan = whirl::plan::plan(&job, &machine).unwrap();
    let program = read_program(&plan.text, machine.x_diameter()).unwrap();
    let profile = job.profile.clone();
    (job, profile, program, plan)
}

fn assert_within_delta(name: &str) {
    let (job, profile, program, plan) = planned(name);
    let (report, ring) = (&plan.report, plan.ring);
    let m = measure(&job, &profile, report.installation_angle_deg, &program);
    let delta = job.cut.delta;
    eprintln!(
        "{name}: measured overcut {:.5} mm, undercut {:.5} mm; planner's bound {:.5} mm; Δ {delta} mm",
        m.overcut, m.undercut, report.max_error_mm
    );
    assert!(
        m.overcut <= delta,
        "{name}: overcut {} > Δ {delta}",
        m.overcut
    );
    assert!(
        m.undercut <= delta,
        "{name}: undercut {} > Δ {delta}",
        m.undercut
    );
    engine_agrees(&job, ring, &profile, &program, &m);
}

/// `whirl verify`'s engine, with the ring the program was planned with, measures the same
/// error at the same points as the brute force.
fn engine_agrees(
    job: &Job,
    ring: whirl::geometry::linkage::Ring,
    profile: &Profile,
    program: &Program,
    brute: &Measured,
) {
    let linkage = whirl::geometry::linkage::Linkage { p: job.p(), ring };
    let z_range = (job.groove.z_start, job.groove.z_start + job.groove.length);
    let target = Target::new(
        profile.clone(),
        linkage,
        job.groove.starts,
        z_range,
        job.cut.axial_feed,
    )
    .unwrap();
    let motion = Motion::new(program).unwrap();
    let mut worst: f64 = 0.0;
    for &(u, start, z, e) in &brute.points {
        let v = target.error_at_u(&motion, u, start, z);
        worst = worst.max((v - e).abs());
    }
    assert!(worst < 1e-6, "engine and brute force differ by {worst} mm");
}

#[test]
fn double_start_internal_stays_within_delta() {
    assert_within_delta("double-start");
}

#[test]
fn left_hand_external_stays_within_delta() {
    assert_within_delta("left-external");
}

#[test]
fn axial_standard_trapezoidal_stays_within_delta() {
    assert_within_delta("trapezoidal");
}

#[test]
fn trapezoidal_nut_stays_within_delta() {
    assert_within_delta("trapezoidal-nut");
}

#[test]
fn the_brute_force_sees_a_coarse_program() {
    // Drop every other linked move: spans twice as long break the interpolation bound, and the
    // check must see it (it is no use if it passes everything).
    let (job, profile, program, plan) = planned("double-start");
    let mut keep = true;
    let mut moves = Vec::new();
    for action in &program.moves {
        if let Move::Linked { .. } = action {
            keep = !keep;
            if !keep {
                continue;
            }
        }
        moves.push(action.clone());
    }
    let coarse = Program { moves };
    let m = measure(&job, &profile, plan.report.installation_angle_deg, &coarse);
    engine_agrees(&job, plan.ring, &profile, &coarse, &m);
    assert!(
        m.overcut.max(m.undercut) > job.cut.delta,
        "a program with spans twice as long must leave more than Δ: {} / {}",
        m.overcut,
        m.undercut
    );
}
