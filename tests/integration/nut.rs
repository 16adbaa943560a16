//! Internal grooves (nuts): the trapezoidal nut example, cut by a bore head, measured against
//! ISO 2904's internal thread (docs/kinematics.md, "Internal grooves").

use crate::util;
use whirl::config::job::Job;
use whirl::config::machine::MachineProfile;
use whirl::judge::measure::Motion;
use whirl::judge::verify;
use whirl::post::gcode::parse::read_program;
use whirl::program::{Move, Program};

/// The nut example planned for the simulator, with its program read back as a controller
/// reads it.
fn planned() -> (Job, whirl::plan::Plan, Program) {
    let job = Job::load(&util::example("trapezoidal-nut")).unwrap();
    let machine = MachineProfile::builtin_sim().unwrap();
    let plan = whirl::plan::plan(&job, &machine).unwrap();
    let program = read_program(&plan.text, machine.x_diameter()).unwrap();
    (job, plan, program)
}

/// The least-squares slope dz/dρ of the points `(z, ρ)`.
fn slope(points: &[(f64, f64)]) -> f64 {
    let n = points.len() as f64;
    let (mz, mr) = points
        .iter()
        .fold((0.0, 0.0), |(a, b), &(z, r)| (a + z / n, b + r / n));
    let (num, den) = points.iter().fold((0.0, 0.0), |(a, b), &(z, r)| {
        (a + (r - mr) * (z - mz), b + (r - mr) * (r - mr))
    });
    num / den
}

#[test]
fn a_nut_cut_by_its_program_has_the_internal_threads_depth_and_flanks() {
    // ISO 2904, Tr 40x7 internal thread: a_c = 0.5 mm (P 6 to 12), D1 = d − P = 33 mm,
    // D4 = d + 2·a_c = 41 mm, H4 = h3 = 0.5·P + a_c = 4 mm; flanks at 15° to the radial line
    // (30° included).
    let (d1, d4, h4) = (33.0, 41.0, 4.0);
    let (job, plan, program) = planned();
    let delta = job.cut.delta;
    let target = verify::target(&job, plan.ring).unwrap();
    let motion = Motion::new(&program).unwrap();
    let m = target.measure(&motion).unwrap();
    assert!(
        m.max_overcut_mm <= delta && m.max_undercut_mm <= delta,
        "{m:?}"
    );
    // The machined axial section mid-groove: each target point moved by its measured error
    // along the surface normal.
    // Centred on a groove's root mid-length, so that the pitch drawn holds one whole groove.
    let on_the_root = |rho: f64| rho > d4 / 2.0 - 1e-6;
    let z_mid = job.groove.z_start + job.groove.length / 2.0;
    let root_z = target
        .section(&motion, z_mid)
        .iter()
        .find(|s| on_the_root(s.rho))
        .map(|s| s.z)
        .unwrap();
    let section = target.section(&motion, root_z);
    let machined: Vec<((f64, f64), f64)> =
        section.iter().map(|s| (s.machined(1.0), s.rho)).collect();
    let radius = |pick: fn(f64, f64) -> f64, start: f64| {
        machined.iter().map(|&((_, rho), _)| rho).fold(start, pick)
    };
    let (bore, root) = (radius(f64::min, f64::INFINITY), radius(f64::max, 0.0));
    // Each machined point lies within Δ of the standard's surface.
    assert!((2.0 * bore - d1).abs() <= 2.0 * delta, "D1 {}", 2.0 * bore);
    assert!((2.0 * root - d4).abs() <= 2.0 * delta, "D4 {}", 2.0 * root);
    assert!(
        (root - bore - h4).abs() <= 2.0 * delta,
        "H4 {}",
        root - bore
    );
    // The flanks: the points between 17 and 20 mm of radius, clear of the bore edges and of
    // the 0.5 mm root fillets (centred at 20 mm), either side of the groove's middle (the
    // middle of the root flat).
    let on_root: Vec<f64> = machined
        .iter()
        .filter(|&&(_, target_rho)| on_the_root(target_rho))
        .map(|&((z, _), _)| z)
        .collect();
    let middle = on_root.iter().sum::<f64>() / on_root.len() as f64;
    let flank = |side: f64| -> Vec<(f64, f64)> {
        machined
            .iter()
            .filter(|&&((z, _), target_rho)| {
                (17.0..20.0).contains(&target_rho) && (z - middle) * side > 0.0
            })
            .map(|&(at, _)| at)
            .collect()
    };
    for side in [-1.0, 1.0] {
        let points = flank(side);
        assert!(points.len() > 20, "{} flank points", points.len());
        let angle = slope(&points).abs().atan().to_degrees();
        // Every point lies within Δ of the 15° flank, so a line through them over its radial
        // span L tilts from it by at most atan(2Δ / L).
        let span = points.iter().map(|p| p.1).fold(0.0, f64::max)
            - points.iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
        let bound = (2.0 * delta / span).atan().to_degrees();
        assert!(
            (angle - 15.0).abs() <= bound,
            "flank {side}: {angle}° (bound ±{bound}°)"
        );
        // The groove widens towards the bore: z moves away from the middle as ρ falls.
        assert!(
            slope(&points) * side < 0.0,
            "flank {side} leans the wrong way"
        );
    }
}

#[test]
fn a_nose_on_the_wrong_side_of_a_nut_is_measured_as_gouging() {
    // The nose centre placed on the wall's side of the surface (N = M − r·n) puts the head
    // 2r further out where the normal is radial. Shifting the ring by s along x moves the tip
    // circle by s·n_x across a surface point it touched at r: the gap there becomes
    // |r − s·n_x| − r, deepest, −r, where s·n_x = r, the tip circle through the surface.
    // With s = 2r that is where n_x = 1/2, in the root fillets (n_x runs from sin 15° on the
    // flanks to 1 on the root flat): an overcut of r there.
    let (job, plan, program) = planned();
    let (nose, delta) = (job.tool.nose_radius, job.cut.delta);
    let moves = program
        .moves
        .iter()
        .map(|m| match *m {
            Move::Linked { x, z, c, minutes } => Move::Linked {
                x: x + 2.0 * nose,
                z,
                c,
                minutes,
            },
            ref other => other.clone(),
        })
        .collect();
    let wrong = Program { moves };
    let target = verify::target(&job, plan.ring).unwrap();
    let m = target.measure(&Motion::new(&wrong).unwrap()).unwrap();
    assert!(
        (m.max_overcut_mm - nose).abs() <= delta,
        "overcut {} mm, r = {nose} mm",
        m.max_overcut_mm,
    );
    // The fillets' centres lie at 20 mm, their 0.5 mm arcs out to the root at 20.5 mm.
    let worst = m.worst_overcut.profile_point;
    let rho = worst[0].hypot(worst[1]);
    assert!(
        rho > 20.0 && rho < 20.5,
        "deepest at ρ {rho}, not in a root fillet"
    );
}

#[test]
fn the_nut_program_starts_centred_in_the_bore_and_stays_inside_it() {
    // The clear position of a bore head is the bore's axis (X 0), and the head, R + r from
    // its centre, reaches at most X + R + r from the axis: it must stay within the root
    // radius D4/2 = 20.5 mm plus Δ, and X must stay between the bore contact, D1/2 − r − R,
    // and the root contact, D4/2 − r − R (kinematics.md, "Internal grooves").
    let (job, _, program) = planned();
    let (big_r, r, delta) = (job.tool.ring_radius, job.tool.nose_radius, job.cut.delta);
    let first_x = program.moves.iter().find_map(|m| match *m {
        Move::Rapid { x: Some(x), .. } => Some(x),
        _ => None,
    });
    assert_eq!(first_x, Some(0.0));
    for m in &program.moves {
        if let Move::Linked { x, .. } = *m {
            assert!(x + big_r + r <= 20.5 + delta, "X {x} cuts past the root");
            // Round the bore edges the nose rolls just below the bore contact's X.
            assert!(x >= 16.5 - r - big_r - r, "X {x} is past the bore contact");
        }
    }
}
