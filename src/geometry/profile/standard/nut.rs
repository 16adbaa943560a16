//! Internal threads (nuts): a standard's external section turned into its nut's.
//!
//! ISO 2901's trapezoidal design profile is built on a basic profile that is symmetric about
//! the pitch line: there, thread and groove are each P/2 wide, and the flanks make the same
//! angle either side of it. The nut's groove is where the screw's thread lies, so its axial
//! section is the screw's groove reflected about the pitch radius, `ρ ↦ d₂ − ρ` with
//! `d₂ = d − P/2`: the screw's crest (d/2) becomes the nut's bore, `D₁/2 = d/2 − P/2`, and
//! the screw's root (`d/2 − h₃`, `h₃ = P/2 + a_c`) the nut's major radius,
//! `D₄/2 = d/2 + a_c`, with `H₄ = h₃` (ISO 2904's internal-thread dimensions). The root
//! fillets (ISO's `R₂ ≤ a_c` on both) carry over; the crest (bore) edges stay sharp, as the
//! bore is drilled beforehand. The result keeps the module's conventions (one pitch, ordered
//! by increasing z, the groove centred at z = 0) with the groove now running *outward* from
//! the bore at both ends of the period (kinematics.md, "Internal grooves").

use super::AxialPiece;
use glam::DVec2;
use std::f64::consts::PI;

/// The pieces of `external` (a screw's groove section) reflected about the radius
/// `pitch_diameter / 2`: each point `(ρ, z)` becomes `(d₂ − ρ, z)`. An arc keeps its radius
/// and its direction of travel in z; its angles, measured from +ρ, become `π − angle`.
pub fn reflected(external: Vec<AxialPiece>, pitch_diameter: f64) -> Vec<AxialPiece> {
    let flip = |q: DVec2| DVec2::new(pitch_diameter - q.x, q.y);
    external
        .into_iter()
        .map(|piece| match piece {
            AxialPiece::Line { from, to } => AxialPiece::Line {
                from: flip(from),
                to: flip(to),
            },
            AxialPiece::Arc {
                centre,
                radius,
                start,
                end,
            } => AxialPiece::Arc {
                centre: flip(centre),
                radius,
                start: PI - start,
                end: PI - end,
            },
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::profile::standard::IsoTrapezoidal;

    /// ρ of the section at axial position z, from its line pieces (the flanks and flats).
    fn rho_at(pieces: &[AxialPiece], z: f64) -> f64 {
        pieces
            .iter()
            .find_map(|piece| {
                let (a, b) = (piece.start(), piece.end());
                let (lo, hi) = (a.y.min(b.y), a.y.max(b.y));
                (matches!(piece, AxialPiece::Line { .. }) && lo <= z && z <= hi && hi > lo)
                    .then(|| a.x + (b.x - a.x) * (z - a.y) / (b.y - a.y))
            })
            .unwrap()
    }

    #[test]
    fn the_tr_40x7_nut_has_iso_2904s_bore_major_diameter_depth_and_flanks() {
        // ISO 2904, Tr 40x7: a_c = 0.5 (P 6 to 12), D1 = d − P = 33, D4 = d + 2a_c = 41,
        // H4 = 0.5P + a_c = 4, d2 = D2 = d − 0.5P = 36.5; flanks at 15° to the radial line;
        // at the pitch diameter the nut's groove is P/2 wide.
        let (d, pitch) = (40.0, 7.0);
        let screw = IsoTrapezoidal::new(d, None, None).unwrap();
        let nut = reflected(
            crate::geometry::profile::standard::StandardProfile::IsoTrapezoidal(screw)
                .pieces(pitch)
                .unwrap(),
            d - pitch / 2.0,
        );
        let (first, last) = (nut[0].start(), nut.last().unwrap().end());
        assert!((first - DVec2::new(16.5, -3.5)).length() < 1e-12, "{first}");
        assert!((last - DVec2::new(16.5, 3.5)).length() < 1e-12, "{last}");
        assert!(
            (rho_at(&nut, 0.0) - 20.5).abs() < 1e-12,
            "D4/2 at the groove's middle"
        );
        let depth = rho_at(&nut, 0.0) - rho_at(&nut, -3.5);
        assert!((depth - 4.0).abs() < 1e-12, "H4 {depth}");
        // The groove is P/2 wide at the pitch radius 18.25: the flank crosses it at z = ±P/4.
        let flank = nut
            .iter()
            .find(|p| {
                let (a, b) = (p.start(), p.end());
                a.x < b.x && a.y < 0.0
            })
            .unwrap();
        let (a, b) = (flank.start(), flank.end());
        let z_at_pitch = a.y + (b.y - a.y) * (18.25 - a.x) / (b.x - a.x);
        assert!((z_at_pitch + 1.75).abs() < 1e-12, "{z_at_pitch}");
        let angle = ((b.y - a.y) / (b.x - a.x)).atan().to_degrees();
        assert!(
            (angle - 15.0).abs() < 1e-12,
            "flank at {angle}° to the radial line"
        );
        for w in nut.windows(2) {
            assert!((w[0].end() - w[1].start()).length() < 1e-12, "continuous");
        }
    }

    #[test]
    fn a_root_fillet_stays_tangent_and_inside_the_groove() {
        // R2 ≤ a_c = 0.5: a 0.5 mm fillet joins the flank and the nut's root flat at 20.5 mm
        // tangentially, its centre 0.5 mm nearer the bore than the root.
        let screw = IsoTrapezoidal::new(40.0, Some(0.5), None).unwrap();
        let nut = reflected(
            crate::geometry::profile::standard::StandardProfile::IsoTrapezoidal(screw)
                .pieces(7.0)
                .unwrap(),
            36.5,
        );
        let arcs: Vec<_> = nut
            .iter()
            .filter_map(|p| match *p {
                AxialPiece::Arc { centre, radius, .. } => Some((centre, radius)),
                _ => None,
            })
            .collect();
        assert_eq!(arcs.len(), 2);
        for (centre, radius) in arcs {
            assert!((centre.x - 20.0).abs() < 1e-12 && (radius - 0.5).abs() < 1e-12);
        }
        for (i, w) in nut.windows(2).enumerate() {
            let (_, t_out, _) = w[0].eval(w[0].length());
            let (_, t_in, _) = w[1].eval(0.0);
            let turn = t_out.angle_to(t_in).abs();
            // Only the bore edges (into and out of the bore flat) are corners.
            assert!(
                turn < 1e-12 || i == 0 || i + 2 == nut.len(),
                "join {i} turns {turn}"
            );
        }
    }
}
