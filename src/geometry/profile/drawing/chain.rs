//! Chaining a drawing's curves end to end into one outline, and taking one period of the
//! groove from it.
//!
//! Ends are matched through a grid of cells, so that a drawing of ten thousand entities is
//! chained in linear time. Each end must meet exactly one other end within [`JOIN`]: none is a
//! free end (an outline's end, or a gap, or an end that runs onto another entity: an
//! overlap), more than one is an overlap (three entities meeting, or one drawn twice).

use super::super::standard::AxialPiece;
use super::super::{Material, Piece, Profile};
use super::entities::{Curve, Shape};
use super::{DrawingError, Options, Section, JOIN};
use glam::DVec2;
use std::collections::HashMap;

/// The curves of one outline, in order, each oriented along it.
#[derive(Debug)]
pub(super) struct Outline {
    curves: Vec<Curve>,
    closed: bool,
}

/// Grid cell of an end: cells of 1 µm, so that ends within [`JOIN`] lie in the same or a
/// neighbouring cell.
fn cell(p: DVec2) -> (i64, i64) {
    ((p.x / 1e-3).floor() as i64, (p.y / 1e-3).floor() as i64)
}

fn ends_of(shape: &Shape) -> [DVec2; 2] {
    [shape.at(0.0), shape.at(1.0)]
}

/// Chain the curves into one outline.
pub(super) fn chain(curves: Vec<Curve>, section: Section) -> Result<Outline, DrawingError> {
    // End k is end k % 2 of curve k / 2.
    let ends: Vec<DVec2> = curves.iter().flat_map(|c| ends_of(&c.shape)).collect();
    let mut grid: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
    for (k, &p) in ends.iter().enumerate() {
        grid.entry(cell(p)).or_default().push(k);
    }
    let near = |k: usize| -> Vec<usize> {
        let (cx, cy) = cell(ends[k]);
        let mut found = Vec::new();
        for dx in -1..=1 {
            for dy in -1..=1 {
                for &j in grid.get(&(cx + dx, cy + dy)).into_iter().flatten() {
                    if j != k && ends[j].distance(ends[k]) <= JOIN {
                        found.push(j);
                    }
                }
            }
        }
        found
    };
    // The end each end meets, if any.
    let mut link: Vec<Option<usize>> = vec![None; ends.len()];
    for k in 0..ends.len() {
        let found = near(k);
        match found.as_slice() {
            [] => {}
            [j] => link[k] = Some(*j),
            [j, l, ..] => {
                // Three ends at one point: name two entities other than this one's, or this
                // one and the other if one of them is this curve's own other end.
                let other = if j / 2 == k / 2 { *l } else { *j };
                return Err(DrawingError::Overlap {
                    a: curves[k / 2].entity.clone(),
                    b: curves[other / 2].entity.clone(),
                    at: unframe(ends[k], section),
                    distance: 0.0,
                });
            }
        }
    }
    // A free end that lies on another curve runs onto it.
    for k in (0..ends.len()).filter(|&k| link[k].is_none()) {
        for (i, other) in curves.iter().enumerate() {
            if i == k / 2 {
                continue;
            }
            let (d, at) = other.shape.distance(ends[k]);
            if d <= JOIN {
                let [a, b] = ends_of(&other.shape);
                return Err(DrawingError::Overlap {
                    a: curves[k / 2].entity.clone(),
                    b: other.entity.clone(),
                    at: unframe(at, section),
                    distance: a.distance(at).min(b.distance(at)),
                });
            }
        }
    }
    // Walk the chains.
    let mut seen = vec![false; curves.len()];
    let mut chains: Vec<(Vec<(usize, bool)>, bool)> = Vec::new();
    for first in 0..curves.len() {
        if seen[first] {
            continue;
        }
        // Go back from `first` to a free end (or round a closed loop to `first` again).
        let mut start_end = 2 * first;
        let mut closed = false;
        loop {
            match link[start_end] {
                None => break,
                Some(j) => {
                    let next_start = j ^ 1;
                    if next_start / 2 == first {
                        closed = true;
                        break;
                    }
                    start_end = next_start;
                }
            }
        }
        // Walk forward from `start_end`: each curve is entered at one end, left at the other.
        let mut order = Vec::new();
        let mut entered = start_end;
        loop {
            let i = entered / 2;
            if seen[i] {
                break;
            }
            seen[i] = true;
            order.push((i, entered % 2 == 1));
            match link[entered ^ 1] {
                Some(j) => entered = j,
                None => break,
            }
        }
        chains.push((order, closed));
    }
    if chains.len() > 1 {
        return Err(gap(&curves, &chains, &ends, &link, section));
    }
    let (order, closed) = chains.pop().unwrap_or_default();
    let mut curves: Vec<Option<Curve>> = curves.into_iter().map(Some).collect();
    let curves = order
        .into_iter()
        .filter_map(|(i, reversed)| {
            curves[i].take().map(|mut c| {
                if reversed {
                    c.shape = c.shape.reversed();
                }
                c
            })
        })
        .collect();
    Ok(Outline { curves, closed })
}

/// The gap between two chains: the closest pair of free ends of different chains (or of any
/// ends, where the chains are closed loops).
fn gap(
    curves: &[Curve],
    chains: &[(Vec<(usize, bool)>, bool)],
    ends: &[DVec2],
    link: &[Option<usize>],
    section: Section,
) -> DrawingError {
    let mut chain_of = vec![0; curves.len()];
    for (c, (order, _)) in chains.iter().enumerate() {
        for &(i, _) in order {
            chain_of[i] = c;
        }
    }
    let free: Vec<usize> = (0..ends.len()).filter(|&k| link[k].is_none()).collect();
    let candidates: Vec<usize> = if free.len() >= 2 {
        free
    } else {
        (0..ends.len()).collect()
    };
    let mut best = (f64::INFINITY, 0, 0);
    for (n, &k) in candidates.iter().enumerate() {
        for &j in &candidates[n + 1..] {
            if chain_of[k / 2] != chain_of[j / 2] {
                let d = ends[k].distance(ends[j]);
                if d < best.0 {
                    best = (d, k, j);
                }
            }
        }
    }
    let (distance, k, j) = best;
    DrawingError::Gap {
        a: curves[k / 2].entity.clone(),
        b: curves[j / 2].entity.clone(),
        at: unframe(ends[k], section),
        distance,
    }
}

/// The phase of a section point: polar angle (transverse) or z (axial).
fn phase(p: DVec2, section: Section) -> f64 {
    match section {
        Section::Transverse => p.y.atan2(p.x),
        Section::Axial => p.y,
    }
}

/// Distance from the screw axis.
fn radius(p: DVec2, section: Section) -> f64 {
    match section {
        Section::Transverse => p.length(),
        Section::Axial => p.x,
    }
}

/// `p` moved on by `periods` periods.
fn shifted(p: DVec2, periods: f64, section: Section) -> DVec2 {
    match section {
        Section::Transverse => DVec2::from_angle(periods).rotate(p),
        Section::Axial => p + DVec2::new(0.0, periods),
    }
}

/// The change of phase along a curve (unwrapped through its samples), or the point where it
/// decreases by more than the tolerance.
fn advance(curve: &Curve, section: Section) -> Result<f64, DVec2> {
    let n = curve.shape.samples();
    let mut last = curve.shape.at(0.0);
    let mut total = 0.0;
    for k in 1..=n {
        let p = curve.shape.at(k as f64 / n as f64);
        let mut step = phase(p, section) - phase(last, section);
        if section == Section::Transverse {
            step = (step + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                - std::f64::consts::PI;
        }
        // A decrease beyond a nanometre of arc at the point's radius.
        let scale = match section {
            Section::Transverse => radius(p, section).max(JOIN),
            Section::Axial => 1.0,
        };
        if step * scale < -JOIN * 1e-3 {
            return Err(p);
        }
        total += step;
        last = p;
    }
    Ok(total)
}

/// One period of the groove from the outline, its curves in order of increasing phase.
pub(super) fn one_period(
    outline: Outline,
    section: Section,
    period: f64,
    material: Material,
) -> Result<Vec<Curve>, DrawingError> {
    let Outline { mut curves, closed } = outline;
    let total_reversed = {
        let total: f64 = curves.iter().map(|c| signed_advance(c, section)).sum();
        total < 0.0
    };
    if !closed {
        if total_reversed {
            curves.reverse();
            for c in &mut curves {
                c.shape = c.shape.reversed();
            }
        }
        let mut span = 0.0;
        for c in &curves {
            span += advance(c, section).map_err(|at| backwards(c, at, section))?;
        }
        let first = &curves[0];
        let last = &curves[curves.len() - 1];
        let start = first.shape.at(0.0);
        let end = last.shape.at(1.0);
        let distance = end.distance(shifted(start, period, section));
        if distance > JOIN {
            let same_radius = (radius(end, section) - radius(start, section)).abs() <= JOIN;
            return Err(if same_radius {
                DrawingError::NotOnePeriod {
                    first: first.entity.clone(),
                    last: last.entity.clone(),
                    span,
                    period,
                    section,
                    closed: false,
                }
            } else {
                DrawingError::Open {
                    first: first.entity.clone(),
                    last: last.entity.clone(),
                    start: unframe(start, section),
                    end: unframe(end, section),
                    distance,
                    section,
                }
            });
        }
        return Ok(curves);
    }
    // A closed outline: walk one period from a crest point, the way the phase increases.
    // A screw's crest is its outermost radius; a nut's (its bore) its innermost.
    let n = curves.len();
    let sign = material.sign();
    let crest = sign
        * curves
            .iter()
            .map(|c| sign * radius(c.shape.at(0.0), section))
            .fold(f64::NEG_INFINITY, f64::max);
    // In order of phase, so that the period taken does not depend on where the drawing's
    // outline happens to start: the crest point with the least z, or polar angle from 0.
    let mut candidates: Vec<usize> = (0..n)
        .filter(|&i| (radius(curves[i].shape.at(0.0), section) - crest).abs() <= JOIN)
        .collect();
    let key = |i: &usize| {
        let ph = phase(curves[*i].shape.at(0.0), section);
        match section {
            Section::Transverse => ph.rem_euclid(std::f64::consts::TAU),
            Section::Axial => ph,
        }
    };
    candidates.sort_by(|a, b| key(a).total_cmp(&key(b)));
    let mut first_error = None;
    for &k in &candidates {
        for forward in [true, false] {
            let walk: Vec<Curve> = (0..n)
                .map(|step| {
                    if forward {
                        curves[(k + step) % n].clone()
                    } else {
                        let mut c = curves[(k + n - 1 - step) % n].clone();
                        c.shape = c.shape.reversed();
                        c
                    }
                })
                .collect();
            // The first curve that moves the phase must move it forwards.
            match walk_period(&walk, section, period) {
                Ok(taken) => return Ok(taken),
                Err(e) => {
                    if first_error.is_none() {
                        first_error = Some(e);
                    }
                }
            }
        }
    }
    Err(first_error.unwrap_or_else(|| DrawingError::NotOnePeriod {
        first: curves[0].entity.clone(),
        last: curves[n - 1].entity.clone(),
        span: 0.0,
        period,
        section,
        closed: true,
    }))
}

/// The phase change along a curve from its start to its end, unwrapped, whatever its course.
fn signed_advance(curve: &Curve, section: Section) -> f64 {
    let n = curve.shape.samples();
    let mut total = 0.0;
    let mut last = curve.shape.at(0.0);
    for k in 1..=n {
        let p = curve.shape.at(k as f64 / n as f64);
        let mut step = phase(p, section) - phase(last, section);
        if section == Section::Transverse {
            step = (step + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                - std::f64::consts::PI;
        }
        total += step;
        last = p;
    }
    total
}

/// The curves from the start of `walk` to where the phase has advanced by one period,
/// if that is an end of a curve, the phase never decreasing on the way.
fn walk_period(walk: &[Curve], section: Section, period: f64) -> Result<Vec<Curve>, DrawingError> {
    let start = walk[0].shape.at(0.0);
    let target = shifted(start, period, section);
    let mut span = 0.0;
    // Skip a walk whose first move is backwards: it is the other direction's.
    if signed_advance(&walk[0], section) < 0.0 {
        return Err(DrawingError::Backwards {
            entity: walk[0].entity.clone(),
            at: unframe(walk[0].shape.at(0.0), section),
            section,
        });
    }
    for (i, c) in walk.iter().enumerate() {
        span += advance(c, section).map_err(|at| backwards(c, at, section))?;
        let end = c.shape.at(1.0);
        if end.distance(target) <= JOIN {
            return Ok(walk[..=i].to_vec());
        }
        if span > period + JOIN {
            break;
        }
    }
    Err(DrawingError::NotOnePeriod {
        first: walk[0].entity.clone(),
        last: walk[walk.len() - 1].entity.clone(),
        span,
        period,
        section,
        closed: true,
    })
}

fn backwards(curve: &Curve, at: DVec2, section: Section) -> DrawingError {
    DrawingError::Backwards {
        entity: curve.entity.clone(),
        at: unframe(at, section),
        section,
    }
}

/// A section point back in the drawing's X/Y, for a message.
fn unframe(p: DVec2, section: Section) -> DVec2 {
    match section {
        Section::Transverse => p,
        Section::Axial => DVec2::new(p.y, p.x),
    }
}

/// The profile's pieces from one period of curves in order of increasing phase.
pub(super) fn pieces(curves: Vec<Curve>, options: &Options) -> Profile {
    let polar_period = std::f64::consts::TAU / f64::from(options.starts);
    let p = options.p;
    let smooth: Vec<Piece> = match options.section {
        Section::Transverse => curves
            .into_iter()
            .map(|c| match c.shape {
                Shape::Line { from, to } => Piece::Line { from, to },
                Shape::Arc {
                    centre,
                    radius,
                    start,
                    sweep,
                } => Piece::Arc {
                    centre,
                    radius,
                    start,
                    sweep,
                },
                Shape::Nurbs(curve) => Piece::nurbs(curve, None),
            })
            .collect(),
        Section::Axial => {
            // The polar angle −z/p increases with z for p < 0 only: for p > 0 the period is
            // traversed from its end, each piece backwards (as `Profile::from_axial` does).
            let reversed = p > 0.0;
            let mut ordered = curves;
            if reversed {
                ordered.reverse();
            }
            ordered
                .into_iter()
                .map(|c| {
                    let axial = |piece| Piece::Axial { piece, p, reversed };
                    match c.shape {
                        Shape::Line { from, to } => axial(AxialPiece::Line { from, to }),
                        Shape::Arc {
                            centre,
                            radius,
                            start,
                            sweep,
                        } => axial(AxialPiece::Arc {
                            centre,
                            radius,
                            start,
                            end: start + sweep,
                        }),
                        Shape::Nurbs(curve) => {
                            Piece::nurbs(if reversed { curve.reversed() } else { curve }, Some(p))
                        }
                    }
                })
                .collect()
        }
    };
    Profile::joined(smooth, polar_period, options.material)
}
