//! The groove's axial section sampled from its transverse profile: what `whirl profile` draws
//! and writes as an axial points file that whirl reads back as the same groove.
//!
//! kinematics.md's rule read backwards: the transverse point at radius `r` and polar angle `φ`
//! is, on the helical surface, the axial point `(ρ, z) = (r, −p·φ)` of the half-plane at polar
//! angle 0. One period of the profile (`2π / starts`) is one axial pitch (`lead / starts`).
//!
//! The samples are even in the profile's parameter, with three more at halving distances
//! next to every join of pieces (a crest edge, a root corner, a fillet's tangent point) and
//! every knot of a spline: a spline fitted through the samples bends round a corner within
//! the spans beside it, so finer spans there keep it close to the corner.

use super::{Piece, Profile};
use glam::DVec2;

/// How many extra samples each side of a join, at 1/2, 1/4, 1/8 of the even spacing.
const REFINE: u32 = 3;

/// The axial section of one pitch, as sampled.
#[derive(Debug, Clone, PartialEq)]
pub struct AxialSection {
    /// `(ρ, z)` points, mm, in increasing `z`; the last is the first one pitch further on.
    pub points: Vec<DVec2>,
    /// The even spacing of the samples in the profile's parameter (mm of the axial section
    /// for a standard form, of the transverse chords for points).
    pub spacing: f64,
    /// The smallest spacing, next to the joins, in the same parameter.
    pub finest: f64,
}

impl AxialSection {
    /// The axial pitch the section spans, mm.
    pub fn pitch(&self) -> f64 {
        match (self.points.first(), self.points.last()) {
            (Some(a), Some(b)) => b.y - a.y,
            _ => 0.0,
        }
    }
}

impl Profile {
    /// The axial section at polar angle 0 over one axial pitch, for lead parameter `p`, with
    /// at least `at_least` points spaced evenly along the transverse profile (besides the
    /// finer ones next to its joins).
    pub fn axial_section(&self, p: f64, at_least: usize) -> AxialSection {
        let length = self.length();
        let smooth: f64 = self
            .pieces
            .iter()
            .filter(|piece| !matches!(piece, Piece::Corner { .. }))
            .map(Piece::length)
            .sum();
        let spacing = smooth / at_least.max(1) as f64;
        let mut params = Vec::with_capacity(at_least + 8 * self.pieces.len());
        let mut joins = Vec::new();
        for (piece, window) in self.pieces.iter().zip(self.offsets.windows(2)) {
            let (start, end) = (window[0], window[1]);
            match piece {
                // The corner's point is the end of the piece before and the start of the
                // one after: both are sampled already.
                Piece::Corner { .. } => continue,
                Piece::Spline(spline) => joins.extend(spline.knots().iter().map(|k| start + k)),
                Piece::Axial { .. }
                | Piece::Line { .. }
                | Piece::Arc { .. }
                | Piece::Nurbs { .. } => {}
            }
            joins.extend([start, end]);
            let n = ((end - start) / spacing).ceil().max(1.0) as usize;
            params.extend((0..=n).map(|k| start + (end - start) * k as f64 / n as f64));
        }
        let finest = spacing / f64::from(1 << REFINE);
        for &join in &joins {
            for j in 1..=REFINE {
                let d = spacing / f64::from(1 << j);
                params.extend([join - d, join + d]);
            }
        }
        params.retain(|u| (0.0..=length).contains(u));
        params.sort_by(f64::total_cmp);
        let mut points: Vec<DVec2> = Vec::with_capacity(params.len());
        let mut last_angle: Option<f64> = None;
        for u in params {
            let pos = self.point(u).pos;
            // The polar angle unwrapped along the profile, where it increases.
            let mut angle = pos.to_angle();
            if let Some(prev) = last_angle {
                angle += (prev - angle + std::f64::consts::PI).div_euclid(std::f64::consts::TAU)
                    * std::f64::consts::TAU;
            }
            let axial = DVec2::new(pos.length(), -p * angle);
            // Joins sampled twice, a corner's two ends: one point each.
            if points.last().is_some_and(|q| q.distance(axial) < 1e-9) {
                continue;
            }
            last_angle = Some(angle);
            points.push(axial);
        }
        if p > 0.0 {
            points.reverse();
        }
        AxialSection {
            points,
            spacing,
            finest,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::profile::standard::{IsoTrapezoidal, StandardProfile};
    use std::f64::consts::TAU;

    /// Tr 40x7, one start, right hand: ISO 2904's basic profile, sharp root corners.
    fn tr_40x7(p_sign: f64) -> (Profile, f64) {
        let form = StandardProfile::IsoTrapezoidal(IsoTrapezoidal::new(40.0, None, None).unwrap());
        let p = p_sign * 7.0 / TAU;
        (Profile::from_axial(form.pieces(7.0).unwrap(), p, TAU), p)
    }

    #[test]
    fn the_tr_40x7_section_is_iso_2904_s_profile_over_one_pitch() {
        for sign in [1.0, -1.0] {
            let (profile, p) = tr_40x7(sign);
            let section = profile.axial_section(p, 1000);
            let pts = &section.points;
            assert!(pts.len() >= 1000, "{} points", pts.len());
            assert!(pts.windows(2).all(|w| w[1].y > w[0].y), "z increases");
            // ISO 2904, P = 7: z spans the pitch; d = 40 is the crest, h3 = 0.5·P + a_c =
            // 3.5 + 0.5 = 4 mm the depth (d3 = 32).
            assert!((section.pitch() - 7.0).abs() < 1e-9, "{}", section.pitch());
            let (lo, hi) = pts.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), q| {
                (lo.min(q.x), hi.max(q.x))
            });
            assert!(
                (hi - 20.0).abs() < 1e-9 && (lo - 16.0).abs() < 1e-9,
                "{lo} {hi}"
            );
            // The flanks, between crest and root, lean 15° from the radial direction (ISO
            // 2901's 30° thread angle): on each, z changes by tan 15° per mm of ρ.
            let flank: Vec<&DVec2> = pts.iter().filter(|q| q.x > 16.5 && q.x < 19.5).collect();
            assert!(flank.len() > 20, "points on the flanks");
            for w in flank.windows(2) {
                let (dr, dz) = (w[1].x - w[0].x, w[1].y - w[0].y);
                if dz.abs() > 1e-3 {
                    continue; // from one flank across the groove to the other
                }
                let lean = (dz / dr).abs().atan().to_degrees();
                assert!((lean - 15.0).abs() < 1e-6, "flank at {lean}°");
            }
        }
    }

    #[test]
    fn joins_are_sampled_finer_and_once() {
        let (profile, p) = tr_40x7(1.0);
        let section = profile.axial_section(p, 1000);
        assert!((section.finest - section.spacing / 8.0).abs() < 1e-15);
        // Every corner of the section is a sample: the crest edges at ρ = 20, the root
        // corners at ρ = 16, on the flanks' lines.
        for rho in [16.0, 20.0] {
            let corners = section
                .points
                .windows(3)
                .filter(|w| {
                    (w[1].x - rho).abs() < 1e-9
                        && ((w[0].x - rho).abs() > 1e-9 || (w[2].x - rho).abs() > 1e-9)
                })
                .count();
            assert_eq!(corners, 2, "two corners at ρ = {rho}");
        }
        let closest = section
            .points
            .windows(2)
            .map(|w| w[0].distance(w[1]))
            .fold(f64::INFINITY, f64::min);
        assert!(closest > 1e-6, "no point twice: {closest}");
    }
}
