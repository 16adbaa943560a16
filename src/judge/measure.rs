//! The profile error of a program against its target groove (kinematics.md, "Error").
//!
//! At a target surface point Q the error is the signed distance from Q to the swept tool:
//! the smallest, over every pose the controller passes through, of (distance from Q to the
//! tip circle − r). Negative is overcut, positive undercut. The motion is the program as a
//! controller executes it: every move a straight line in X, Z and C.
//!
//! Searching every pose for every point would take minutes on a long groove, so the search is
//! seeded. By screw invariance the pose that touches profile point P(u′) turned by θ is the
//! linkage pose of u′ screwed by θ; the poses that come closest to the surface point
//! Q = S(u, θ) are those of the profile positions u′ near u (its own, and its neighbours':
//! near a sharp edge those sit several feeds away in Z). For every such seed the smallest gap
//! is searched on the executed motion itself, over ±[`SEARCH_WINDOW_DEG`] of C around where the
//! motion passes it, in that revolution and the ones either side. Moves that do not turn C
//! (plunges, retracts) are searched whole. A program off by far more than Δ still shows as an
//! error: it may be reported smaller than it is when its poses leave the windows, never within
//! Δ when it is not.
//!
//! A gap also reads no deeper than −r: a tool that went further than r past Q has its tip
//! circle beyond Q, and Q's distance to it no longer says how far (a nose set on the wrong
//! side of a surface, 2r past it, can read as little as 0 where it went straight in, and
//! −r where its tip circle crosses the surface). Such a program is refused all the same; its report names
//! where, not how deep.
//!
//! The target is sampled over every start and the whole formed length, at axial steps of
//! 8/7 of the feed per revolution: the steps walk through every phase of the feed scallop.

use crate::geometry::linkage::{turn, Linkage, Torus};
use crate::geometry::minimise::scan_then_golden;
use crate::geometry::profile::Profile;
use crate::judge::svg::{Plot, Series};
use crate::plan::table::Table;
use crate::program::{Move, Position, Program};
use glam::{DVec2, DVec3};
use serde::Serialize;
use std::f64::consts::TAU;

/// Half-width of the window searched around each seeded turn, degrees.
pub const SEARCH_WINDOW_DEG: f64 = 6.0;
/// Profile positions within this distance of a measured point seed its search, mm.
const SEED_REACH: f64 = 1.0;
/// Profile positions sampled per period.
const PROFILE_SAMPLES: usize = 64;

/// What is measured: the groove and the ring, with the seeds of the search.
#[derive(Debug, Clone)]
pub struct Target {
    profile: Profile,
    linkage: Linkage,
    starts: u32,
    z_range: (f64, f64),
    feed: f64,
    seeds: Vec<Seed>,
}

/// One measured point.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PointError {
    /// The target point, workpiece frame, mm.
    pub at: [f64; 3],
    /// Its profile point (transverse plane, θ = 0), mm.
    pub profile_point: [f64; 2],
    /// Which start (0-based).
    pub start: u32,
    /// Signed error, mm: negative overcut, positive undercut.
    pub error_mm: f64,
}

/// The result over the whole groove.
#[derive(Debug, Clone, Serialize)]
pub struct Measurement {
    /// Largest overcut, mm (≥ 0).
    pub max_overcut_mm: f64,
    /// Largest undercut, mm (≥ 0).
    pub max_undercut_mm: f64,
    /// Where the largest overcut is.
    pub worst_overcut: PointError,
    /// Where the largest undercut is.
    pub worst_undercut: PointError,
    /// Target points measured.
    pub points: usize,
}

/// Why a program cannot be measured.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum VerifyError {
    /// No move turns the workpiece.
    #[error("the program never turns C, so it cannot have cut a helical groove")]
    NoTurning,
    /// C turns both ways.
    #[error(
        "C turns both ways (block {block}); verify measures programs whose workpiece turns \
         one way, as every whirling program does"
    )]
    CNotMonotonic {
        /// Straight index where the direction changes.
        block: usize,
    },
    /// Z goes back and forth while C turns.
    #[error(
        "Z moves both ways while C turns; verify measures programs that feed along the groove \
         one way, as every whirling program does"
    )]
    ZNotMonotonic,
    /// A move from an unknown position.
    #[error("block {block} moves before every axis has been positioned")]
    Unpositioned {
        /// Straight index.
        block: usize,
    },
    /// The linkage has no table for the groove (so no seeds to search from).
    #[error("the ring's poses for this groove cannot be found, so there is nothing to search from: {why}")]
    Seed {
        /// Why.
        why: String,
    },
}

/// A straight move of the executed motion: X, Z in mm, C in radians, at both ends.
#[derive(Debug, Clone, Copy)]
struct Straight {
    from: [f64; 3],
    to: [f64; 3],
}

impl Straight {
    fn at(&self, t: f64) -> [f64; 3] {
        std::array::from_fn(|k| self.from[k] + t * (self.to[k] - self.from[k]))
    }
}

/// The executed motion, split into moves that turn C (one way) and moves that do not.
#[derive(Debug, Clone)]
pub struct Motion {
    /// Turning moves in order of C; `c_dir` tells which way C goes.
    turning: Vec<Straight>,
    /// Moves at a fixed C.
    still: Vec<Straight>,
    c_dir: f64,
    /// Which way Z goes while C turns; 0 until it has moved.
    z_dir: f64,
}

impl Motion {
    /// The motion a controller executes for `program`, from the first fully known position.
    pub fn new(program: &Program) -> Result<Motion, VerifyError> {
        let mut motion = Motion::empty();
        for step in program.steps(Position::UNKNOWN) {
            if !matches!(
                step.action,
                Move::Rapid { .. } | Move::Feed { .. } | Move::Linked { .. }
            ) {
                continue;
            }
            let (Some(fx), Some(fz), Some(fc)) = (step.from.x, step.from.z, step.from.c) else {
                // The first moves position the axes from an unknown start: nothing cuts before
                // the machine's position is known to the program, by the program's own design.
                if step.to.x.is_some() && step.to.z.is_some() && step.to.c.is_some() {
                    continue;
                }
                if !motion.is_empty() {
                    return Err(VerifyError::Unpositioned { block: step.index });
                }
                continue;
            };
            let (Some(tx), Some(tz), Some(tc)) = (step.to.x, step.to.z, step.to.c) else {
                return Err(VerifyError::Unpositioned { block: step.index });
            };
            motion.push([fx, fz, fc], [tx, tz, tc], step.index)?;
        }
        if !motion.is_turning() {
            return Err(VerifyError::NoTurning);
        }
        Ok(motion)
    }

    /// No motion yet, to [`push`](Motion::push) moves onto as they execute.
    pub fn empty() -> Motion {
        Motion {
            turning: Vec::new(),
            still: Vec::new(),
            c_dir: 0.0,
            z_dir: 0.0,
        }
    }

    /// Appends the straight move from `from` to `to` (X, Z in mm, C in degrees); `block`
    /// names it in errors. C must keep turning one way, and Z keep feeding one way while it
    /// does.
    pub fn push(&mut self, from: [f64; 3], to: [f64; 3], block: usize) -> Result<(), VerifyError> {
        let m = Straight {
            from: [from[0], from[1], from[2].to_radians()],
            to: [to[0], to[1], to[2].to_radians()],
        };
        let dc = m.to[2] - m.from[2];
        if dc == 0.0 {
            self.still.push(m);
            return Ok(());
        }
        if self.c_dir == 0.0 {
            self.c_dir = dc.signum();
        } else if dc.signum() != self.c_dir {
            return Err(VerifyError::CNotMonotonic { block });
        }
        let dz = m.to[1] - m.from[1];
        if dz != 0.0 {
            if self.z_dir == 0.0 {
                self.z_dir = dz.signum();
            } else if dz.signum() != self.z_dir {
                return Err(VerifyError::ZNotMonotonic);
            }
        }
        self.turning.push(m);
        Ok(())
    }

    /// No move at all.
    pub fn is_empty(&self) -> bool {
        self.turning.is_empty() && self.still.is_empty()
    }

    /// Some move turns C (only then can a point be measured).
    pub fn is_turning(&self) -> bool {
        !self.turning.is_empty()
    }

    /// Which way Z feeds while C turns (+1, −1; 0 before it has).
    pub fn z_dir(&self) -> f64 {
        self.z_dir
    }

    /// Z where the turning motion is now, if it has begun.
    pub fn z_now(&self) -> Option<f64> {
        self.turning.last().map(|m| m.to[1])
    }

    /// C range of the turning motion, (low, high); `None` before C has turned.
    fn c_range(&self) -> Option<(f64, f64)> {
        let a = self.turning.first()?.from[2];
        let b = self.turning.last()?.to[2];
        Some((a.min(b), a.max(b)))
    }

    /// The pose (X, Z, C) where the turning motion passes C = `c` (clamped to its range).
    fn at_c(&self, c: f64) -> [f64; 3] {
        let key = |m: &Straight| m.to[2] * self.c_dir;
        let i = self
            .turning
            .partition_point(|m| key(m) < c * self.c_dir)
            .min(self.turning.len() - 1);
        let m = &self.turning[i];
        let t = ((c - m.from[2]) / (m.to[2] - m.from[2])).clamp(0.0, 1.0);
        m.at(t)
    }

    /// The C at which the turning motion's Z is nearest `z`: Z moves one way with C (checked
    /// in [`Motion::new`]), so a binary search over the moves finds it.
    fn c_at_z(&self, z: f64) -> f64 {
        let z_dir = self.z_dir;
        let i = self
            .turning
            .partition_point(|m| (m.to[1] - z) * z_dir < 0.0)
            .min(self.turning.len() - 1);
        let m = &self.turning[i];
        let dz = m.to[1] - m.from[1];
        let t = if dz == 0.0 {
            0.0
        } else {
            ((z - m.from[1]) / dz).clamp(0.0, 1.0)
        };
        m.at(t)[2]
    }
}

fn gap(torus: &mut Torus, q: DVec3, pose: [f64; 3]) -> f64 {
    torus.centre = DVec3::new(pose[0], 0.0, pose[1]);
    torus.gap(turn(q, pose[2]))
}

/// A target point: the surface point of profile position `seed` turned by θ (plus its start's
/// turn), at axial position z = p·θ.
struct Probe {
    q: DVec3,
    /// θ plus the start's turn: what turns a seed's C into this point's.
    turn: f64,
    z: f64,
}

/// Where the linkage touches one profile position: the profile point, C and Z of its pose.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Seed {
    pos: DVec2,
    c: f64,
    /// Z of the pose, relative to the axial position of the point it touches.
    pub(crate) z: f64,
}

/// A target point: profile position `k` of a [`Grid`], a start, an axial position.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Sample {
    pub(crate) k: usize,
    pub(crate) start: u32,
    pub(crate) z: f64,
}

/// The measured points: profile positions, the seeds near each, and every sample.
#[derive(Debug, Clone)]
pub(crate) struct Grid {
    positions: Vec<DVec2>,
    /// The seeds of each position's search.
    pub(crate) near: Vec<Vec<Seed>>,
    /// Every point, position by position, start by start, z ascending.
    pub(crate) samples: Vec<Sample>,
}

impl Target {
    /// The groove of `profile` (one period, `starts` starts, lead parameter and ring in
    /// `linkage`) formed over `z_range`, cut at `feed` mm per workpiece revolution (which sets
    /// the axial sampling). Every sample of the linkage table becomes a seed: the table is
    /// dense where X(ψ) bends, so a sharp edge's fan of normals is well covered.
    pub fn new(
        profile: Profile,
        linkage: Linkage,
        starts: u32,
        z_range: (f64, f64),
        feed: f64,
    ) -> Result<Target, VerifyError> {
        let table = Table::build(&profile, &linkage, 1e-4)
            .map_err(|e| VerifyError::Seed { why: e.to_string() })?;
        let seeds = table
            .samples
            .iter()
            .map(|s| Seed {
                pos: s.pos,
                c: s.contact.pose.c,
                z: s.contact.pose.z,
            })
            .collect();
        Ok(Target {
            profile,
            linkage,
            starts,
            z_range,
            feed,
            seeds,
        })
    }

    /// The surface point of profile point `pos`, start `start`, at axial position `z`.
    fn probe(&self, pos: DVec2, start: u32, z: f64) -> Probe {
        let start_turn = TAU / f64::from(self.starts) * f64::from(start);
        let theta = z / self.linkage.p;
        let base = DVec2::from_angle(start_turn).rotate(pos);
        Probe {
            q: turn(DVec3::new(base.x, base.y, 0.0), theta) + DVec3::Z * z,
            turn: theta + start_turn,
            z,
        }
    }

    /// Axial positions measured: steps of 8/7 of the feed over the formed length.
    fn z_samples(&self) -> Vec<f64> {
        let step = self.feed * 8.0 / 7.0;
        let (a, b) = self.z_range;
        let n = ((b - a) / step).floor().max(0.0) as usize;
        (0..=n).map(|k| a + step * k as f64).collect()
    }

    /// The points measured, with the seeds of their searches.
    pub(crate) fn grid(&self) -> Grid {
        let positions: Vec<DVec2> = (0..PROFILE_SAMPLES)
            .map(|k| {
                let u = self.profile.length() * (k as f64 + 0.5) / PROFILE_SAMPLES as f64;
                self.profile.point(u).pos
            })
            .collect();
        let near: Vec<Vec<Seed>> = positions
            .iter()
            .map(|&pos| near_seeds(&self.seeds, pos))
            .collect();
        let zs = self.z_samples();
        let samples = (0..positions.len())
            .flat_map(|k| (0..self.starts).map(move |start| (k, start)))
            .flat_map(|(k, start)| zs.iter().map(move |&z| Sample { k, start, z }))
            .collect();
        Grid {
            positions,
            near,
            samples,
        }
    }

    /// The error at one point of `grid`.
    pub(crate) fn point_error(&self, grid: &Grid, s: Sample, motion: &Motion) -> PointError {
        let pos = grid.positions[s.k];
        let probe = self.probe(pos, s.start, s.z);
        PointError {
            at: probe.q.to_array(),
            profile_point: pos.to_array(),
            start: s.start,
            error_mm: self.error_at(&probe, &grid.near[s.k], motion),
        }
    }

    /// The feed per workpiece revolution, mm.
    pub(crate) fn feed(&self) -> f64 {
        self.feed
    }

    /// Measure `motion` over the whole groove.
    pub fn measure(&self, motion: &Motion) -> Result<Measurement, VerifyError> {
        let grid = self.grid();
        let threads = std::thread::available_parallelism()
            .map_or(1, |n| n.get())
            .min(8);
        let chunk = grid.samples.len().div_ceil(threads).max(1);
        let all: Vec<PointError> = std::thread::scope(|scope| {
            let handles: Vec<_> = grid
                .samples
                .chunks(chunk)
                .map(|part| {
                    let grid = &grid;
                    scope.spawn(move || {
                        part.iter()
                            .map(|&s| self.point_error(grid, s, motion))
                            .collect::<Vec<_>>()
                    })
                })
                .collect();
            handles
                .into_iter()
                .flat_map(|h| h.join().expect("a measuring thread panicked"))
                .collect()
        });
        summarise(&all)
    }

    /// The error at the surface point of profile parameter `u`, start `start` (0-based) and
    /// axial position `z`.
    pub fn error_at_u(&self, motion: &Motion, u: f64, start: u32, z: f64) -> f64 {
        let pos = self.profile.point(u).pos;
        self.error_at(
            &self.probe(pos, start, z),
            &near_seeds(&self.seeds, pos),
            motion,
        )
    }

    fn error_at(&self, probe: &Probe, seeds: &[Seed], motion: &Motion) -> f64 {
        let mut torus = self.linkage.torus(&crate::geometry::linkage::Pose {
            x: 0.0,
            c: 0.0,
            z: 0.0,
        });
        let mut best = f64::INFINITY;
        // Positioning moves alone (C has not turned) cut only where they pass.
        if let Some((c_lo, c_hi)) = motion.c_range() {
            let window = SEARCH_WINDOW_DEG.to_radians();
            // Where the motion passes each seed, in its revolution and the ones either side;
            // windows that overlap are searched once.
            let mut centres: Vec<f64> = Vec::with_capacity(seeds.len() * 3);
            for seed in seeds {
                let seed_c = seed.c - probe.turn;
                let c_near = motion.c_at_z(seed.z + probe.z);
                let k0 = ((c_near - seed_c) / TAU).round();
                for dk in [-1.0, 0.0, 1.0] {
                    centres.push(seed_c + TAU * (k0 + dk));
                }
            }
            centres.sort_by(f64::total_cmp);
            centres.dedup_by(|b, a| *b - *a < window / 2.0);
            for c_mid in centres {
                let (a, b) = ((c_mid - window).max(c_lo), (c_mid + window).min(c_hi));
                if a < b {
                    let v = scan_then_golden(
                        |c| gap(&mut torus, probe.q, motion.at_c(c)),
                        a,
                        b,
                        24,
                        48,
                    );
                    best = best.min(v);
                }
            }
        }
        let reach = self.linkage.ring.radius * self.linkage.ring.installation.sin()
            + self.linkage.ring.nose
            + 1.0;
        for m in &motion.still {
            let (z0, z1) = (m.from[1].min(m.to[1]), m.from[1].max(m.to[1]));
            if probe.q.z < z0 - reach || probe.q.z > z1 + reach {
                continue;
            }
            let along = |t| gap(&mut torus, probe.q, m.at(t));
            best = best.min(scan_then_golden(along, 0.0, 1.0, 40, 48));
        }
        best
    }
}

impl Target {
    /// The axial section (polar angle 0) over one axial pitch centred on `z_centre`, within
    /// the formed length: the target's points in order of z, each with the error measured
    /// there and the direction it is drawn in.
    pub fn section(&self, motion: &Motion, z_centre: f64) -> Vec<SectionPoint> {
        let p = self.linkage.p;
        let period = TAU / f64::from(self.starts);
        let (z_lo, z_hi) = self.z_range;
        let pitch = (period * p.abs()).min(z_hi - z_lo);
        let z_centre = z_centre.clamp(z_lo + pitch / 2.0, z_hi - pitch / 2.0);
        let mut points: Vec<SectionPoint> = Vec::new();
        let n = 400;
        for k in 0..n {
            let point = self
                .profile
                .point(self.profile.length() * k as f64 / n as f64);
            let near = near_seeds(&self.seeds, point.pos);
            for start in 0..self.starts {
                // The turn that brings this copy of the point to polar angle 0, nearest z_centre.
                let phi = point.pos.to_angle() + period * f64::from(start);
                let m = ((z_centre / p + phi) / TAU).round();
                let theta = -phi + TAU * m;
                let z = p * theta;
                if (z - z_centre).abs() > pitch / 2.0 {
                    continue;
                }
                let error_mm = self.error_at(&self.probe(point.pos, start, z), &near, motion);
                let normal = turn(
                    self.profile.normal(&point, p),
                    theta + phi - point.pos.to_angle(),
                );
                let axial = DVec2::new(normal.z, normal.x).normalize_or_zero();
                points.push(SectionPoint {
                    z,
                    rho: point.pos.length(),
                    error_mm,
                    normal: (axial.x, axial.y),
                });
            }
        }
        points.sort_by(|a, b| a.z.total_cmp(&b.z));
        points
    }

    /// [`Target::section`] as a plot: the target, and the machined section drawn as the
    /// target moved by the measured error, magnified `magnify` times, along the surface
    /// normal (undercut outwards, overcut in).
    pub fn section_plot(&self, motion: &Motion, z_centre: f64, magnify: f64) -> Plot {
        let points = self.section(motion, z_centre);
        Plot {
            title: format!("axial section at polar angle 0, error magnified {magnify}×"),
            x_label: "z, mm".into(),
            y_label: "radius, mm".into(),
            series: vec![
                Series {
                    label: "target".into(),
                    colour: "black",
                    points: points.iter().map(|s| (s.z, s.rho)).collect(),
                },
                Series {
                    label: format!("machined (error × {magnify})"),
                    colour: "crimson",
                    points: points.iter().map(|s| s.machined(magnify)).collect(),
                },
            ],
            equal_scale: true,
        }
    }
}

/// One point of an axial section ([`Target::section`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SectionPoint {
    /// Axial position, mm.
    pub z: f64,
    /// The target's radius there, mm.
    pub rho: f64,
    /// The error measured there, mm: positive where material is left (undercut), negative
    /// where too much was cut (overcut).
    pub error_mm: f64,
    /// The surface normal in the axial plane, (z, ρ), unit: the direction an undercut is
    /// drawn in.
    pub normal: (f64, f64),
}

impl SectionPoint {
    /// Where the machined surface is drawn with its error magnified `magnify` times.
    pub fn machined(&self, magnify: f64) -> (f64, f64) {
        let moved = self.error_mm * magnify;
        (
            self.z + self.normal.0 * moved,
            self.rho + self.normal.1 * moved,
        )
    }
}

/// The seeds of the profile positions within [`SEED_REACH`] of `pos`.
fn near_seeds(seeds: &[Seed], pos: DVec2) -> Vec<Seed> {
    seeds
        .iter()
        .filter(|s| (s.pos - pos).length() <= SEED_REACH)
        .copied()
        .collect()
}

fn summarise(all: &[PointError]) -> Result<Measurement, VerifyError> {
    let worst_over = all
        .iter()
        .min_by(|a, b| a.error_mm.total_cmp(&b.error_mm))
        .copied();
    let worst_under = all
        .iter()
        .max_by(|a, b| a.error_mm.total_cmp(&b.error_mm))
        .copied();
    let (Some(o), Some(u)) = (worst_over, worst_under) else {
        return Err(VerifyError::NoTurning);
    };
    Ok(Measurement {
        max_overcut_mm: (-o.error_mm).max(0.0),
        max_undercut_mm: u.error_mm.max(0.0),
        worst_overcut: o,
        worst_undercut: u,
        points: all.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::job::Job;

    /// Positioning moves alone (C standing) cut only where they pass: a point of the groove
    /// they never come near is not reached (infinitely far from the cut), and asking is no
    /// fault even though no turning motion gives a C range to search.
    #[test]
    fn a_motion_that_never_turns_c_reaches_no_point_it_does_not_pass() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/trapezoidal/job.toml");
        let job = Job::load(std::path::Path::new(path)).unwrap();
        let (ring, _) = crate::plan::angles::ring(&job).unwrap();
        let target = crate::judge::verify::target(&job, ring).unwrap();
        let (z_lo, z_hi) = target.z_range;
        // A positioning move along X, a metre beyond the groove's end.
        let z = z_hi + 1000.0;
        let mut motion = Motion::empty();
        motion.push([0.0, z, 0.0], [50.0, z, 0.0], 1).unwrap();
        assert!(!motion.is_turning());
        let error = target.error_at_u(&motion, 0.5, 0, (z_lo + z_hi) / 2.0);
        assert_eq!(error, f64::INFINITY);
    }
}
