//! A drawing's entities as curves of the section: lines, arcs and NURBS, in mm, in the
//! section's own frame (transverse `(x, y)`; axial `(ρ, z)`, the drawing's Y and X swapped).

use super::super::nurbs::Nurbs;
use super::{DrawingError, EntityRef, Section, JOIN};
use dxf::entities::{Entity, EntityType};
use dxf::Drawing;
use glam::DVec2;
use std::f64::consts::{PI, TAU};

/// A curve of the section.
#[derive(Debug, Clone)]
pub(super) enum Shape {
    /// A straight line.
    Line {
        /// Start.
        from: DVec2,
        /// End.
        to: DVec2,
    },
    /// A circular arc: centre, radius, start angle, signed sweep (radians, positive
    /// counter-clockwise in the section's frame).
    Arc {
        /// Centre.
        centre: DVec2,
        /// Radius.
        radius: f64,
        /// Start angle.
        start: f64,
        /// Signed sweep.
        sweep: f64,
    },
    /// A NURBS curve.
    Nurbs(Nurbs),
}

/// One curve and the entity it was drawn as.
#[derive(Debug, Clone)]
pub(super) struct Curve {
    /// The curve.
    pub shape: Shape,
    /// Its entity.
    pub entity: EntityRef,
}

impl Shape {
    /// The point at `f` ∈ [0, 1] of the way along the curve's parameter.
    pub fn at(&self, f: f64) -> DVec2 {
        match self {
            Shape::Line { from, to } => from.lerp(*to, f),
            Shape::Arc {
                centre,
                radius,
                start,
                sweep,
            } => *centre + *radius * DVec2::from_angle(start + f * sweep),
            Shape::Nurbs(curve) => {
                let (a, b) = curve.domain();
                curve.eval(a + f * (b - a)).0
            }
        }
    }

    /// The same curve traversed the other way.
    pub fn reversed(&self) -> Shape {
        match self {
            Shape::Line { from, to } => Shape::Line {
                from: *to,
                to: *from,
            },
            Shape::Arc {
                centre,
                radius,
                start,
                sweep,
            } => Shape::Arc {
                centre: *centre,
                radius: *radius,
                start: start + sweep,
                sweep: -sweep,
            },
            Shape::Nurbs(curve) => Shape::Nurbs(curve.reversed()),
        }
    }

    /// How many samples show the curve's course: 2 for a line, more for curves.
    pub fn samples(&self) -> usize {
        match self {
            Shape::Line { .. } => 1,
            Shape::Arc { sweep, .. } => 8 + (sweep.abs() * 16.0) as usize,
            Shape::Nurbs(curve) => 16 * curve.breaks().len().max(2),
        }
    }

    /// The distance from `q` to the curve, and the point where it is reached.
    pub fn distance(&self, q: DVec2) -> (f64, DVec2) {
        match self {
            Shape::Line { from, to } => {
                let d = *to - *from;
                let f = ((q - *from).dot(d) / d.length_squared()).clamp(0.0, 1.0);
                let at = from.lerp(*to, f);
                (q.distance(at), at)
            }
            Shape::Arc {
                centre,
                start,
                sweep,
                ..
            } => {
                // The foot on the circle if it lies within the sweep, else the nearer end.
                let travelled = ((q - *centre).to_angle() - start) * sweep.signum();
                let f = travelled.rem_euclid(TAU) / sweep.abs();
                let at = if f <= 1.0 {
                    self.at(f)
                } else if q.distance(self.at(0.0)) < q.distance(self.at(1.0)) {
                    self.at(0.0)
                } else {
                    self.at(1.0)
                };
                (q.distance(at), at)
            }
            Shape::Nurbs(curve) => {
                // The curve lies in its control points' hull: far from their box, far from it.
                let (lo, hi) = curve.bounds();
                let outside = (lo - q).max(q - hi).max(DVec2::ZERO).length();
                if outside > JOIN {
                    return (outside, q.clamp(lo, hi));
                }
                // Nearest of fine samples, then Newton on the foot-point condition
                // (C − q)·C′ = 0 along the fraction of the way.
                let n = self.samples() * 8;
                let mut best = (f64::INFINITY, 0.0);
                for k in 0..=n {
                    let f = k as f64 / n as f64;
                    let d = q.distance(self.at(f));
                    if d < best.0 {
                        best = (d, f);
                    }
                }
                let mut f = best.1;
                let h = 1e-7;
                for _ in 0..20 {
                    let g = |f: f64| {
                        let f0 = (f - h).max(0.0);
                        let f1 = (f + h).min(1.0);
                        (self.at(f) - q).dot((self.at(f1) - self.at(f0)) / (f1 - f0))
                    };
                    let (g0, g1) = (
                        g(f),
                        (g((f + h).min(1.0)) - g((f - h).max(0.0))) / (2.0 * h),
                    );
                    if g1.abs() < 1e-300 {
                        break;
                    }
                    let next = (f - g0 / g1).clamp(0.0, 1.0);
                    if (next - f).abs() < 1e-15 {
                        break;
                    }
                    f = next;
                }
                let at = self.at(f);
                (q.distance(at), at)
            }
        }
    }
}

/// The curves of the drawing's model space on `layer` (every layer when `None`), scaled by
/// `scale` (mm per drawing unit) into `section`'s frame.
pub(super) fn curves(
    drawing: &Drawing,
    layer: Option<&str>,
    scale: f64,
    section: Section,
) -> Result<Vec<Curve>, DrawingError> {
    let mut layers: Vec<String> = Vec::new();
    let mut out = Vec::new();
    for entity in drawing.entities() {
        if entity.common.is_in_paper_space {
            continue;
        }
        if !layers.contains(&entity.common.layer) {
            layers.push(entity.common.layer.clone());
        }
        if layer.is_some_and(|l| l != entity.common.layer) {
            continue;
        }
        for mut curve in of_entity(entity)? {
            curve.shape = frame(curve.shape, scale, section);
            check_length(&curve)?;
            out.push(curve);
        }
    }
    if out.is_empty() {
        layers.sort();
        return Err(DrawingError::NoEntity {
            layer: layer.map(str::to_owned),
            layers,
        });
    }
    Ok(out)
}

/// Refuse a curve with no length: a draughtsman's stray click, which has no direction to
/// chain by.
fn check_length(curve: &Curve) -> Result<(), DrawingError> {
    let why = match &curve.shape {
        Shape::Line { from, to } if from.distance(*to) <= JOIN => {
            Some(format!("its ends coincide at ({}, {})", from.x, from.y))
        }
        Shape::Arc { radius, sweep, .. } if radius * sweep.abs() <= JOIN => {
            Some(format!("radius {radius} mm, sweep {}°", sweep.to_degrees()))
        }
        Shape::Nurbs(n) if n.length() <= JOIN => Some("its control points coincide".into()),
        _ => None,
    };
    match why {
        Some(why) => Err(DrawingError::Degenerate {
            entity: curve.entity.clone(),
            why,
        }),
        None => Ok(()),
    }
}

/// A curve in drawing units and the drawing's X/Y, into mm and the section's frame.
fn frame(shape: Shape, scale: f64, section: Section) -> Shape {
    let axial = section == Section::Axial;
    let map = |p: DVec2| {
        let p = p * scale;
        if axial {
            DVec2::new(p.y, p.x)
        } else {
            p
        }
    };
    match shape {
        Shape::Line { from, to } => Shape::Line {
            from: map(from),
            to: map(to),
        },
        // Swapping the axes mirrors angles about 45°: θ → π/2 − θ, and reverses the sense.
        Shape::Arc {
            centre,
            radius,
            start,
            sweep,
        } => Shape::Arc {
            centre: map(centre),
            radius: radius * scale,
            start: if axial { PI / 2.0 - start } else { start },
            sweep: if axial { -sweep } else { sweep },
        },
        Shape::Nurbs(curve) => Shape::Nurbs(curve.map(map)),
    }
}

/// The entity's DXF type name, for a message.
fn kind(entity: &Entity) -> String {
    match &entity.specific {
        EntityType::Line(_) => "LINE".into(),
        EntityType::Arc(_) => "ARC".into(),
        EntityType::Circle(_) => "CIRCLE".into(),
        EntityType::LwPolyline(_) => "LWPOLYLINE".into(),
        EntityType::Polyline(_) => "POLYLINE".into(),
        EntityType::Spline(_) => "SPLINE".into(),
        other => {
            let debug = format!("{other:?}");
            debug
                .split(|c: char| !c.is_alphanumeric())
                .next()
                .unwrap_or("entity")
                .to_uppercase()
        }
    }
}

fn reference(entity: &Entity, segment: Option<usize>) -> EntityRef {
    EntityRef {
        kind: kind(entity),
        handle: entity.common.handle.0,
        layer: entity.common.layer.clone(),
        segment,
    }
}

fn xy(p: &dxf::Point) -> DVec2 {
    DVec2::new(p.x, p.y)
}

/// The curves one entity draws.
fn of_entity(entity: &Entity) -> Result<Vec<Curve>, DrawingError> {
    let unsupported = |why: &str| DrawingError::Unsupported {
        entity: reference(entity, None),
        why: why.to_owned(),
    };
    let flat = |normal: &dxf::Vector| {
        if normal.x.abs() > 1e-12 || normal.y.abs() > 1e-12 || normal.z <= 0.0 {
            Err(unsupported(
                "drawn in a plane other than the drawing's XY plane (its extrusion direction \
                 is not +Z): draw the section in the XY plane",
            ))
        } else {
            Ok(())
        }
    };
    let one = |shape: Shape| {
        Ok(vec![Curve {
            shape,
            entity: reference(entity, None),
        }])
    };
    match &entity.specific {
        EntityType::Line(line) => {
            flat(&line.extrusion_direction)?;
            one(Shape::Line {
                from: xy(&line.p1),
                to: xy(&line.p2),
            })
        }
        EntityType::Arc(arc) => {
            flat(&arc.normal)?;
            let start = arc.start_angle.to_radians();
            let mut sweep = (arc.end_angle - arc.start_angle)
                .rem_euclid(360.0)
                .to_radians();
            if sweep == 0.0 {
                sweep = TAU;
            }
            one(Shape::Arc {
                centre: xy(&arc.center),
                radius: arc.radius,
                start,
                sweep,
            })
        }
        EntityType::Circle(circle) => {
            flat(&circle.normal)?;
            one(Shape::Arc {
                centre: xy(&circle.center),
                radius: circle.radius,
                start: 0.0,
                sweep: TAU,
            })
        }
        EntityType::LwPolyline(poly) => {
            flat(&poly.extrusion_direction)?;
            let vertices: Vec<(DVec2, f64)> = poly
                .vertices
                .iter()
                .map(|v| (DVec2::new(v.x, v.y), v.bulge))
                .collect();
            Ok(polyline(entity, &vertices, poly.is_closed()))
        }
        EntityType::Polyline(poly) => {
            flat(&poly.normal)?;
            if poly.is_3d_polyline() || poly.is_3d_polygon_mesh() || poly.is_polyface_mesh() {
                return Err(unsupported(
                    "a 3D polyline or mesh, not a curve of the section: draw a 2D polyline",
                ));
            }
            if poly.curve_fit_vertices_added() || poly.spline_fit_vertices_added() {
                return Err(unsupported(
                    "a curve-fit or spline-fit polyline, whose curve is the CAD program's \
                     approximation: draw its curve as a SPLINE",
                ));
            }
            let vertices: Vec<(DVec2, f64)> = poly
                .vertices()
                .map(|v| (xy(&v.location), v.bulge))
                .collect();
            Ok(polyline(entity, &vertices, poly.is_closed()))
        }
        EntityType::Spline(spline) => {
            flat(&spline.normal)?;
            let curve = if spline.control_points.is_empty() {
                if spline.fit_points.len() < 2 {
                    return Err(unsupported("a spline with neither control nor fit points"));
                }
                fit_points(spline)
            } else {
                let weights = if spline.weight_values.iter().all(|&w| w == 1.0) {
                    vec![]
                } else {
                    spline.weight_values.clone()
                };
                Nurbs::new(
                    usize::try_from(spline.degree_of_curve).unwrap_or(0),
                    spline.knot_values.clone(),
                    spline.control_points.iter().map(xy).collect(),
                    weights,
                )
            };
            let curve = curve.map_err(|e| unsupported(&format!("not a valid NURBS: {e}")))?;
            one(Shape::Nurbs(curve))
        }
        _ => Err(unsupported(
            "not a curve of a section (give the profile's LINE, ARC, CIRCLE, LWPOLYLINE, \
             POLYLINE and SPLINE entities a layer of their own and name it: layer = \"…\")",
        )),
    }
}

/// A polyline's segments: straight where the bulge is 0, else a circular arc of sweep
/// 4·atan(bulge) (counter-clockwise for a positive bulge).
fn polyline(entity: &Entity, vertices: &[(DVec2, f64)], closed: bool) -> Vec<Curve> {
    let n = vertices.len();
    let segments = if closed { n } else { n.saturating_sub(1) };
    (0..segments)
        .map(|i| {
            let (from, bulge) = vertices[i];
            let to = vertices[(i + 1) % n].0;
            let shape = if bulge == 0.0 {
                Shape::Line { from, to }
            } else {
                let sweep = 4.0 * bulge.atan();
                let chord = to - from;
                let radius = chord.length() / (2.0 * (sweep / 2.0).sin().abs());
                // The centre lies off the chord's middle, on its left for a counter-clockwise
                // arc of less than a half turn: at distance r·cos(sweep/2) along the normal.
                let middle = (from + to) / 2.0;
                let normal = chord.perp().normalize_or_zero();
                let centre = middle + normal * (radius * (sweep / 2.0).cos() * sweep.signum());
                Shape::Arc {
                    centre,
                    radius,
                    start: (from - centre).to_angle(),
                    sweep,
                }
            };
            Curve {
                shape,
                entity: reference(entity, Some(i + 1)),
            }
        })
        .collect()
}

/// A spline given by fit points only: the cubic through them with chord-length parameters
/// and knots averaged from them (Piegl and Tiller §9.2.1), its end tangents the drawing's
/// where it gives them, else those of the parabola through the first (last) three points.
fn fit_points(spline: &dxf::entities::Spline) -> Result<Nurbs, super::super::nurbs::NurbsError> {
    let points: Vec<DVec2> = spline.fit_points.iter().map(xy).collect();
    super::super::nurbs::interpolate(
        &points,
        tangent(&spline.start_tangent),
        tangent(&spline.end_tangent),
    )
}

fn tangent(p: &dxf::Point) -> Option<DVec2> {
    let t = xy(p);
    (t.length() > 0.0).then(|| t.normalize())
}
