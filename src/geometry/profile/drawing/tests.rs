//! The drawing reader on drawings made here with the `dxf` crate's writer and read back from
//! their bytes. The integration tests (`tests/integration/drawings.rs`) read drawings that
//! ezdxf, an independent writer, makes.

use super::*;
use crate::geometry::profile::standard::{AxialPiece, IsoTrapezoidal};
use crate::geometry::profile::Piece;
use dxf::entities::{Arc, Entity, EntityType, Line, LwPolyline, Text};
use dxf::enums::{AcadVersion, Units as DxfUnits};
use dxf::{LwPolylineVertex, Point};
use std::f64::consts::{PI, TAU};

/// A drawing in mm of the given entities, on layer `GROOVE` unless they name another, as
/// bytes and read back.
fn drawing(entities: Vec<EntityType>, units: DxfUnits) -> Drawing {
    let mut d = Drawing::new();
    d.header.version = AcadVersion::R2018;
    d.header.default_drawing_units = units;
    for specific in entities {
        let mut e = Entity::new(specific);
        e.common.layer = "GROOVE".into();
        d.add_entity(e);
    }
    let mut bytes = Vec::new();
    d.save(&mut bytes).unwrap();
    read(&bytes).unwrap()
}

fn line(a: (f64, f64), b: (f64, f64)) -> EntityType {
    EntityType::Line(Line::new(
        Point::new(a.0, a.1, 0.0),
        Point::new(b.0, b.1, 0.0),
    ))
}

fn options(section: Section, p: f64, starts: u32) -> Options {
    Options {
        layer: Some("GROOVE".into()),
        units: None,
        section,
        p,
        starts,
        material: Material::Inside,
    }
}

/// A transverse groove of two starts (period π): a crest arc of radius 10 about the axis from
/// 0° to 150°, a straight flank down to radius 8 at 165°, and back up to 180° (the next
/// crest's start).
fn v_groove() -> Vec<EntityType> {
    let at = |r: f64, deg: f64| {
        let a = deg.to_radians();
        (r * a.cos(), r * a.sin())
    };
    vec![
        EntityType::Arc(Arc::new(Point::origin(), 10.0, 0.0, 150.0)),
        line(at(10.0, 150.0), at(8.0, 165.0)),
        line(at(8.0, 165.0), at(10.0, 180.0)),
    ]
}

#[test]
fn a_transverse_outline_of_one_period_keeps_its_arc_and_lines() {
    let d = drawing(v_groove(), DxfUnits::Millimeters);
    let profile = profile(&d, &options(Section::Transverse, 2.0, 2)).unwrap();
    assert_eq!(profile.period(), PI);
    assert!(profile
        .pieces
        .iter()
        .any(|p| matches!(p, Piece::Arc { radius, .. } if (radius - 10.0).abs() < 1e-12)));
    // Every point lies on the drawn outline: on the crest circle up to 150°, on the flanks
    // beyond (their polar equation: the line through two points).
    let mut last = f64::NEG_INFINITY;
    for k in 0..=1000 {
        let q = profile.point(profile.length() * k as f64 / 1000.0).pos;
        let a = q.to_angle().rem_euclid(TAU).to_degrees();
        let a = if a > 359.0 { a - 360.0 } else { a };
        assert!(a >= last - 1e-9, "polar angle increases: {a} after {last}");
        last = a;
        if a <= 150.0 {
            assert!((q.length() - 10.0).abs() < 1e-12, "{q} on the crest");
        }
    }
    // The deepest point is the flanks' corner at 8 mm, which the range's samples find to
    // within their spacing.
    let (lo, hi) = profile.radius_range();
    assert!(
        (lo - 8.0).abs() < 1e-2 && (hi - 10.0).abs() < 1e-9,
        "{lo} {hi}"
    );
}

/// ISO 2904 Tr 40×7 drawn as an axial section, one pitch: its pieces as a polyline along X.
fn trapezoid_pieces() -> Vec<AxialPiece> {
    IsoTrapezoidal::new(40.0, None, None)
        .unwrap()
        .pieces(7.0)
        .unwrap()
}

/// The polyline's vertices (X = z, Y = ρ) of the standard's pieces.
fn trapezoid_vertices(pieces: &[AxialPiece]) -> Vec<(f64, f64)> {
    let mut v: Vec<(f64, f64)> = pieces.iter().map(|p| (p.start().y, p.start().x)).collect();
    let end = pieces[pieces.len() - 1].end();
    v.push((end.y, end.x));
    v
}

fn lwpolyline(vertices: &[(f64, f64)], closed: bool) -> EntityType {
    let mut poly = LwPolyline {
        vertices: vertices
            .iter()
            .map(|&(x, y)| LwPolylineVertex {
                x,
                y,
                ..Default::default()
            })
            .collect(),
        ..Default::default()
    };
    poly.set_is_closed(closed);
    EntityType::LwPolyline(poly)
}

fn assert_same(a: &Profile, b: &Profile) {
    assert!(
        (a.length() - b.length()).abs() < 1e-9,
        "{} {}",
        a.length(),
        b.length()
    );
    for k in 0..=2000 {
        let u = a.length() * k as f64 / 2000.0;
        let (pa, da, _) = a.derivatives(u);
        let (pb, db, _) = b.derivatives(u);
        assert!((pa - pb).length() < 1e-9, "at u {u}: {pa} vs {pb}");
        assert!((da - db).length() < 1e-9, "at u {u}: {da} vs {db}");
    }
}

#[test]
fn an_axial_drawing_of_a_standard_form_is_that_standard_in_either_hand() {
    let pieces = trapezoid_pieces();
    let d = drawing(
        vec![lwpolyline(&trapezoid_vertices(&pieces), false)],
        DxfUnits::Millimeters,
    );
    for p in [7.0 / TAU, -7.0 / TAU] {
        let drawn = profile(&d, &options(Section::Axial, p, 1)).unwrap();
        assert_same(&drawn, &Profile::from_axial(pieces.clone(), p, TAU));
    }
}

#[test]
fn a_closed_outline_of_a_whole_thread_form_gives_its_groove_over_one_period() {
    // Three pitches of Tr 40×7 from z = −10.5 to 10.5, down to the axis at both ends, and
    // back along it: a machinist's half-section of the screw.
    let pieces = trapezoid_pieces();
    let one = trapezoid_vertices(&pieces);
    let mut v = vec![(-10.5, 0.0)];
    for k in -1..=1 {
        for &(z, rho) in &one[..one.len() - 1] {
            v.push((z + 7.0 * f64::from(k), rho));
        }
    }
    v.push((10.5, 20.0));
    v.push((10.5, 0.0));
    let d = drawing(vec![lwpolyline(&v, true)], DxfUnits::Millimeters);
    let p = 7.0 / TAU;
    let drawn = profile(&d, &options(Section::Axial, p, 1)).unwrap();
    // The period starts at a crest point: the profile is the standard's, shifted along z by
    // whole crests, so it runs through the same radii; compare ρ against the standard at
    // the same axial position.
    let standard = Profile::from_axial(pieces, p, TAU);
    assert!((drawn.length() - standard.length()).abs() < 1e-9);
    let rho_at = |prof: &Profile, z: f64| {
        // ρ where the polar angle is −z/p: scan.
        let n = 20_000;
        (0..=n)
            .map(|k| prof.point(prof.length() * k as f64 / n as f64).pos)
            .min_by(|a, b| {
                let da = -(a.to_angle() - (-z / p)).cos();
                let db = -(b.to_angle() - (-z / p)).cos();
                da.total_cmp(&db)
            })
            .unwrap()
            .length()
    };
    for z in [-3.0, -1.7, -0.4, 0.0, 0.9, 2.2, 3.1] {
        let (a, b) = (rho_at(&drawn, z), rho_at(&standard, z));
        assert!((a - b).abs() < 1e-3, "ρ at z {z}: {a} vs {b}");
    }
}

#[test]
fn inches_are_scaled_to_mm_and_a_job_can_override_the_units() {
    let pieces = trapezoid_pieces();
    let inch: Vec<(f64, f64)> = trapezoid_vertices(&pieces)
        .into_iter()
        .map(|(x, y)| (x / 25.4, y / 25.4))
        .collect();
    let p = 7.0 / TAU;
    let standard = Profile::from_axial(pieces, p, TAU);
    let d = drawing(vec![lwpolyline(&inch, false)], DxfUnits::Inches);
    assert_same(
        &profile(&d, &options(Section::Axial, p, 1)).unwrap(),
        &standard,
    );
    let unitless = drawing(vec![lwpolyline(&inch, false)], DxfUnits::Unitless);
    assert_eq!(
        profile(&unitless, &options(Section::Axial, p, 1)).unwrap_err(),
        DrawingError::NoUnits
    );
    let mut told = options(Section::Axial, p, 1);
    told.units = Some(Units::named("inch").unwrap());
    assert_same(&profile(&unitless, &told).unwrap(), &standard);
    let km = drawing(vec![lwpolyline(&inch, false)], DxfUnits::Kilometers);
    assert_eq!(
        profile(&km, &options(Section::Axial, p, 1)).unwrap_err(),
        DrawingError::WrongUnits { code: 7 }
    );
    assert!(
        matches!(Units::named("furlong"), Err(DrawingError::UnknownUnits(u)) if u == "furlong")
    );
}

fn refusal(entities: Vec<EntityType>) -> DrawingError {
    let d = drawing(entities, DxfUnits::Millimeters);
    profile(&d, &options(Section::Transverse, 2.0, 2)).unwrap_err()
}

#[test]
fn a_gap_names_both_entities_and_the_distance() {
    let mut g = v_groove();
    // The second flank starts 0.01 mm beside the first one's end, in X.
    let a = 165f64.to_radians();
    g[2] = line((a.cos() * 8.0 + 0.01, a.sin() * 8.0), (-10.0, 0.0));
    let e = refusal(g);
    let DrawingError::Gap { a, b, distance, .. } = &e else {
        panic!("{e}")
    };
    assert!((distance - 0.01).abs() < 1e-9, "{e}");
    assert!(
        a.kind == "LINE" && b.kind == "LINE" && a.handle != b.handle,
        "{e}"
    );
    assert!(e.to_string().contains("on layer \"GROOVE\""), "{e}");
}

#[test]
fn an_overlap_names_both_entities() {
    let mut g = v_groove();
    // A stray line from where the crest arc meets the first flank: three entities at a point.
    let a = 150f64.to_radians();
    g.push(line((10.0 * a.cos(), 10.0 * a.sin()), (0.0, 0.0)));
    assert!(matches!(refusal(g), DrawingError::Overlap { distance, .. } if distance == 0.0));
    // Two collinear lines lying partly on each other: the first runs 0.5 mm onto the second.
    let at = |r: f64, deg: f64| {
        let a = f64::to_radians(deg);
        (r * a.cos(), r * a.sin())
    };
    let mut g = v_groove();
    let (p, q) = (at(10.0, 150.0), at(8.0, 165.0));
    let mid = ((p.0 + q.0) / 2.0, (p.1 + q.1) / 2.0);
    g[1] = line(p, mid);
    g.push(line(
        (mid.0 - (q.0 - p.0) * 0.1, mid.1 - (q.1 - p.1) * 0.1),
        q,
    ));
    let e = refusal(g);
    assert!(matches!(e, DrawingError::Overlap { .. }), "{e}");
    assert!(e.to_string().contains("LINE #"), "{e}");
}

#[test]
fn an_outline_that_is_not_one_period_is_refused() {
    // Open: the last flank ends at radius 9, not at the crest.
    let mut g = v_groove();
    let at = |r: f64, deg: f64| {
        let a = f64::to_radians(deg);
        (r * a.cos(), r * a.sin())
    };
    g[2] = line(at(8.0, 165.0), at(9.0, 180.0));
    assert!(matches!(refusal(g), DrawingError::Open { .. }));
    // One and a half periods at the crest radius: the crest arc drawn on to 240°.
    let mut g = v_groove();
    g.push(EntityType::Arc(Arc::new(
        Point::origin(),
        10.0,
        180.0,
        270.0,
    )));
    let e = refusal(g);
    assert!(
        matches!(e, DrawingError::NotOnePeriod { span, .. } if (span - 1.5 * PI).abs() < 1e-9),
        "{e}"
    );
}

#[test]
fn an_outline_that_turns_back_is_refused_naming_the_entity() {
    // The second flank goes back to 160° before the crest: a zig-zag.
    let at = |r: f64, deg: f64| {
        let a = f64::to_radians(deg);
        (r * a.cos(), r * a.sin())
    };
    let mut g = v_groove();
    g[2] = line(at(8.0, 165.0), at(9.0, 160.0));
    g.push(line(at(9.0, 160.0), at(10.0, 180.0)));
    let e = refusal(g);
    assert!(
        matches!(&e, DrawingError::Backwards { entity, .. } if entity.kind == "LINE"),
        "{e}"
    );
}

#[test]
fn no_entity_on_the_layer_and_entities_of_other_kinds_are_refused() {
    let d = drawing(v_groove(), DxfUnits::Millimeters);
    let mut o = options(Section::Transverse, 2.0, 2);
    o.layer = Some("PROFILE".into());
    let e = profile(&d, &o).unwrap_err();
    assert_eq!(
        e,
        DrawingError::NoEntity {
            layer: Some("PROFILE".into()),
            layers: vec!["GROOVE".into()],
        }
    );
    let mut g = v_groove();
    g.push(EntityType::Text(Text::default()));
    let e = refusal(g);
    assert!(
        matches!(&e, DrawingError::Unsupported { entity, .. } if entity.kind == "TEXT"),
        "{e}"
    );
}

#[test]
fn a_line_of_no_length_and_a_file_that_is_not_dxf_are_refused() {
    let mut g = v_groove();
    g.push(line((3.0, 3.0), (3.0, 3.0)));
    assert!(matches!(refusal(g), DrawingError::Degenerate { .. }));
    assert!(matches!(read(b"not a drawing"), Err(DrawingError::Read(_))));
}
