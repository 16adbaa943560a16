#!/usr/bin/env python3
"""Groove drawings as a shop's CAD hands them over, written by ezdxf (an independent DXF
writer), for whirl's drawing reader (tests/integration/drawings.rs).

Usage: dxf_drawings.py OUT_DIR

Writes into OUT_DIR, and prints a JSON manifest on stdout:
- "good": drawings of two grooves in every entity kind, in R12 and R2018 forms (R12 has no
  LWPOLYLINE nor SPLINE: POLYLINE with bulges there), each with the reference it must plan
  like:
  * "eccentric": a transverse section, the circle of radius 10 mm about (1.5, 0), one start
    (an eccentric lobe); its reference is "eccentric.csv", 3600 points of the same circle at
    10 decimals, polar angle increasing from (11.5, 0);
  * "trapezoid": a closed outline of a whole ISO 2904 Tr 40x14 (P7) thread form, two starts,
    root fillet 0.5 mm, drawn as an axial half-section (z along X, radius along Y) over three
    pitches down to the axis; its reference is whirl's standard = "trapezoidal".
  The trapezoid's geometry is computed here from ISO 2904's formulas: basic height
  H1 = P/2, crest clearance a_c = 0.5 mm for P 6..12 (so h3 = P/2 + a_c), 30 deg included
  flank angle, the groove P/2 wide on the pitch line d2 = d - P/2, fillets tangent to the
  flank and the root flat.
- "bad": malformed drawings, each with the refusal expected and the handles it must name.
"""

import json
import math
import os
import sys

import ezdxf

OUT = sys.argv[1]
LAYER = "GROOVE"
manifest = {"good": [], "bad": [], "nut": []}


def new(version, insunits=4):
    """A drawing with the GROOVE layer; $INSUNITS where the version has it."""
    doc = ezdxf.new(version)
    doc.layers.add(LAYER)
    if version != "R12" and insunits is not None:
        doc.header["$INSUNITS"] = insunits
    return doc


def attribs():
    return {"layer": LAYER}


def save(doc, name):
    doc.saveas(os.path.join(OUT, name))


# --- the eccentric circle ---------------------------------------------------------------

CX, CY, R = 1.5, 0.0, 10.0


def eccentric_points(n=3600):
    rows = ["x,y"]
    for k in range(n):
        t = 2.0 * math.pi * k / n
        rows.append("%.10f,%.10f" % (CX + R * math.cos(t), CY + R * math.sin(t)))
    with open(os.path.join(OUT, "eccentric.csv"), "w") as f:
        f.write("\n".join(rows) + "\n")


def eccentric(version, kind):
    doc = new(version)
    msp = doc.modelspace()
    if kind == "CIRCLE":
        msp.add_circle((CX, CY), R, dxfattribs=attribs())
    elif kind == "ARC":
        msp.add_arc((CX, CY), R, 0.0, 180.0, dxfattribs=attribs())
        msp.add_arc((CX, CY), R, 180.0, 360.0, dxfattribs=attribs())
    elif kind == "LWPOLYLINE":
        # Two half circles: bulge tan(180/4) = 1.
        msp.add_lwpolyline(
            [(CX + R, CY, 0, 0, 1.0), (CX - R, CY, 0, 0, 1.0)],
            format="xyseb",
            close=True,
            dxfattribs=attribs(),
        )
    elif kind == "POLYLINE":
        poly = msp.add_polyline2d([], dxfattribs=attribs())
        poly.append_vertex((CX + R, CY), dxfattribs={"bulge": 1.0})
        poly.append_vertex((CX - R, CY), dxfattribs={"bulge": 1.0})
        poly.close(True)
    elif kind == "SPLINE":
        # The circle as the rational quadratic NURBS of nine control points (the square's
        # corners weighted 1/sqrt 2), as CAD programs write a circle.
        w = math.sqrt(0.5)
        square = [(1, 0), (1, 1), (0, 1), (-1, 1), (-1, 0), (-1, -1), (0, -1), (1, -1), (1, 0)]
        points = [(CX + R * x, CY + R * y) for x, y in square]
        weights = [1, w, 1, w, 1, w, 1, w, 1]
        knots = [0, 0, 0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1, 1, 1]
        msp.add_rational_spline(points, weights, degree=2, knots=knots, dxfattribs=attribs())
    name = "eccentric-%s-%s.dxf" % (kind.lower(), version)
    save(doc, name)
    manifest["good"].append(
        {"file": name, "kind": kind, "version": version, "groove": "eccentric"}
    )


# --- the trapezoidal thread form --------------------------------------------------------

D, P, AC, RR, BETA = 40.0, 7.0, 0.5, 0.5, math.radians(15.0)
PITCHES = 3


def trapezoid_period(z0):
    """One pitch of the form from the crest at z0 to the crest at z0 + P, as a list of
    ("line", a, b) and ("arc", centre, r, start_deg, end_deg, a, b) in drawing X/Y =
    (z, rho), the groove centred at z0 + P/2."""
    crest = D / 2.0
    root = crest - (P / 2.0 + AC)
    d2 = D - P / 2.0
    half = lambda rho: P / 4.0 + (rho - d2 / 2.0) * math.tan(BETA)  # groove half-width
    zc = z0 + P / 2.0
    # Fillet: centre at rho = root + RR, tangent to the flank; the flank's inward normal
    # makes the centre lie RR from it.
    # Left flank line: z = zc - half(rho); its distance from (z, rho):
    # (z - (zc - half(rho))) * cos(BETA).
    rho_f = root + RR
    z_left = zc - half(rho_f) + RR / math.cos(BETA)
    z_right = zc + half(rho_f) - RR / math.cos(BETA)
    # Tangent points: on the root flat below the centre; on the flank along its normal.
    # The left flank runs down along (sin b, -cos b); its normal towards it from the centre
    # is (-cos b, -sin b), at 195 deg; the right flank's, mirrored, at -15 deg.
    n_left = (-math.cos(BETA), -math.sin(BETA))
    t_left_flank = (z_left + RR * n_left[0], rho_f + RR * n_left[1])
    t_left_root = (z_left, root)
    t_right_root = (z_right, root)
    t_right_flank = (z_right + RR * math.cos(BETA), rho_f - RR * math.sin(BETA))
    a_left = 360.0 + math.degrees(math.atan2(n_left[1], n_left[0]))  # 195 deg
    a_right = math.degrees(math.atan2(-math.sin(BETA), math.cos(BETA)))  # -15 deg
    return [
        ("line", (z0, crest), (zc - half(crest), crest)),
        ("line", (zc - half(crest), crest), t_left_flank),
        # Counter-clockwise in X/Y from the flank's tangent point (195 deg) down to the root
        # (270 deg).
        ("arc", (z_left, rho_f), RR, a_left, 270.0, t_left_flank, t_left_root),
        ("line", t_left_root, t_right_root),
        ("arc", (z_right, rho_f), RR, 270.0, 360.0 + a_right, t_right_root, t_right_flank),
        ("line", t_right_flank, (zc + half(crest), crest)),
        ("line", (zc + half(crest), crest), (z0 + P, crest)),
    ]


def trapezoid_outline():
    """The closed half-section: PITCHES periods from z = -P/2 (grooves centred on whole
    pitches, as the standard's), down to the axis, back along it."""
    items = []
    start = -P / 2.0
    for k in range(PITCHES):
        items.extend(trapezoid_period(start + P * k))
    end = start + P * PITCHES
    items.append(("line", (end, D / 2.0), (end, 0.0)))
    items.append(("line", (end, 0.0), (start, 0.0)))
    items.append(("line", (start, 0.0), (start, D / 2.0)))
    return items


def bulge(item):
    """The bulge of the segment an item is, from its start: tan(sweep / 4)."""
    if item[0] == "line":
        return 0.0
    sweep = item[4] - item[3]
    return math.tan(math.radians(sweep) / 4.0)


def draw(msp, items, kind, turn=1.0):
    """A closed outline of items as LINEs and ARCs, one LWPOLYLINE or one POLYLINE; `turn`
    -1 where the arcs run clockwise along the outline (their bulges negative)."""
    if kind == "LINE":
        # Lines and arcs, as separate entities.
        for it in items:
            if it[0] == "line":
                msp.add_line(it[1], it[2], dxfattribs=attribs())
            else:
                msp.add_arc(it[1], it[2], it[3], it[4], dxfattribs=attribs())
    elif kind == "LWPOLYLINE":
        msp.add_lwpolyline(
            [(it[1 if it[0] == "line" else 5][0], it[1 if it[0] == "line" else 5][1], 0, 0,
              turn * bulge(it)) for it in items],
            format="xyseb",
            close=True,
            dxfattribs=attribs(),
        )
    elif kind == "POLYLINE":
        poly = msp.add_polyline2d([], dxfattribs=attribs())
        for it in items:
            start = it[1] if it[0] == "line" else it[5]
            poly.append_vertex(start, dxfattribs={"bulge": turn * bulge(it)})
        poly.close(True)


def trapezoid(version, kind):
    doc = new(version)
    draw(doc.modelspace(), trapezoid_outline(), kind)
    name = "trapezoid-%s-%s.dxf" % (kind.lower(), version)
    save(doc, name)
    manifest["good"].append(
        {"file": name, "kind": kind, "version": version, "groove": "trapezoid"}
    )


NUT_OUTER = 30.0


def mirrored(item):
    """An item reflected about the pitch line rho = d2/2 (ISO 2904's nut is the screw's
    section mirrored there): the arc's turn reverses, so DXF's counter-clockwise arc runs
    between the mirrored end and start angles."""
    about = (D - P / 2.0) / 2.0
    m = lambda pt: (pt[0], 2.0 * about - pt[1])
    if item[0] == "line":
        return ("line", m(item[1]), m(item[2]))
    return ("arc", m(item[1]), item[2], -item[4] % 360.0, -item[3] % 360.0, m(item[5]), m(item[6]))


def nut_outline():
    """The closed half-section of the Tr 40x7 nut: PITCHES periods along the bore, out to
    the nut's outer radius and back."""
    items = []
    start = -P / 2.0
    for k in range(PITCHES):
        items.extend(mirrored(it) for it in trapezoid_period(start + P * k))
    end = start + P * PITCHES
    bore = items[0][1][1]
    items.append(("line", (end, bore), (end, NUT_OUTER)))
    items.append(("line", (end, NUT_OUTER), (start, NUT_OUTER)))
    items.append(("line", (start, NUT_OUTER), (start, bore)))
    return items


def nut(kind):
    doc = new("R2018")
    # The mirrored arcs run clockwise along the outline.
    draw(doc.modelspace(), nut_outline(), kind, turn=-1.0)
    name = "nut-%s.dxf" % kind.lower()
    save(doc, name)
    manifest["nut"].append({"file": name, "kind": kind})


# --- malformed drawings -------------------------------------------------------------------
# A transverse groove of two starts (period 180 deg): a crest arc of radius 10 about the axis
# from 0 to 150 deg, a flank down to radius 8 at 165 deg, and back up to 180 deg.


def polar(r, deg):
    return (r * math.cos(math.radians(deg)), r * math.sin(math.radians(deg)))


def bad(name, expect, handles, build, version="R2018", insunits=4, layer=None):
    doc = new(version, insunits)
    msp = doc.modelspace()
    named = build(msp)
    save(doc, name)
    manifest["bad"].append(
        {
            "file": name,
            "expect": expect,
            "handles": [e.dxf.handle for e in named] if handles else [],
            "layer": layer,
        }
    )


def v_groove(msp, last_end=None, first_start=None):
    arc = msp.add_arc((0, 0), 10.0, 0.0, 150.0, dxfattribs=attribs())
    one = msp.add_line(polar(10, 150), polar(8, 165), dxfattribs=attribs())
    two = msp.add_line(first_start or polar(8, 165), last_end or polar(10, 180),
                       dxfattribs=attribs())
    return arc, one, two


def gap(msp):
    a, one, two = v_groove(msp, first_start=(polar(8, 165)[0] + 0.01, polar(8, 165)[1]))
    return [one, two]


def overlap(msp):
    arc, one, two = v_groove(msp)
    # A second arc on the crest from 100 to 170 deg: it runs past the first's end.
    extra = msp.add_arc((0, 0), 10.0, 100.0, 170.0, dxfattribs=attribs())
    return [extra]


def open_outline(msp):
    arc, one, two = v_groove(msp, last_end=polar(9, 180))
    return [arc, two]


def not_one_period(msp):
    arc, one, two = v_groove(msp)
    more = msp.add_arc((0, 0), 10.0, 180.0, 270.0, dxfattribs=attribs())
    return [arc, more]


def self_crossing(msp):
    # The flanks cross: the second runs back to 160 deg, then a line goes on to the crest.
    arc, one, two = v_groove(msp, last_end=polar(9, 160))
    back = msp.add_line(polar(9, 160), polar(10, 180), dxfattribs=attribs())
    return [two]


def unsupported(msp):
    v_groove(msp)
    text = msp.add_text("Tr 40x7", dxfattribs=attribs())
    return [text]


def on_another_layer(msp):
    for e in v_groove(msp):
        e.dxf.layer = "CONSTRUCTION"
    return []


def good_v(msp):
    return list(v_groove(msp))


def write_all():
    eccentric_points()
    for kind in ["LINE", "LWPOLYLINE"]:
        nut(kind)
    for kind in ["CIRCLE", "ARC", "LWPOLYLINE", "POLYLINE", "SPLINE"]:
        eccentric("R2018", kind)
    for kind in ["CIRCLE", "ARC", "POLYLINE"]:
        eccentric("R12", kind)
    for kind in ["LINE", "LWPOLYLINE", "POLYLINE"]:
        trapezoid("R2018", kind)
    for kind in ["LINE", "POLYLINE"]:
        trapezoid("R12", kind)
    bad("gap.dxf", "gap", True, gap)
    bad("overlap.dxf", "overlap", True, overlap)
    bad("open.dxf", "open outline", True, open_outline)
    bad("period.dxf", "not one period", True, not_one_period)
    bad("crossing.dxf", "turns back", True, self_crossing)
    bad("text.dxf", "TEXT", True, unsupported)
    bad("layer.dxf", "no entity on layer", False, on_another_layer)
    bad("unitless.dxf", "no units", False, good_v, insunits=0)
    bad("kilometres.dxf", "$INSUNITS = 7", False, good_v, insunits=7)
    bad("r12.dxf", "no units", False, good_v, version="R12")
    print(json.dumps(manifest))


write_all()
