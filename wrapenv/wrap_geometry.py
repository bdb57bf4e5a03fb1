"""Where the soft wrap's elements lie: rings and panels on a laid-out unit, at rest.

Plain geometry and bookkeeping, no forces (those are wrapenv/wrap_physics.py): which bundle
edges a ring goes round, which corners a panel joins, how many web layers and how much web
each element stands for, which place of the envelope it is ("corner -x-y", "face +x") and where
that place lies on the envelope unrolled (position round the perimeter, height).

The perimeter position `s` runs round the load's outline seen from above, counter-clockwise
from the -x-y corner: face -y, corner +x-y, face +x, corner +x+y, face +y, corner -x+y, face -x.
Every ring is mapped onto that one outline (face by face), so the pallet round and the layers
line up in a tension map although their perimeters differ.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from wrapenv.load import BundlePlacement, Layout
from wrapenv.material import Material
from wrapenv.rowwise import norms
from wrapenv.scene import bundle_row
from wrapenv.wrap import WrapFormat

#: Ring heights within a layer of bundles, as fractions of the layer height.
RING_FRACTIONS = (0.25, 0.75)
#: A bundle edge within this distance of its layer's outline is on the outside of the load.
OUTLINE_TOLERANCE_M = 0.005

_CORNER_SIGNS = ((-1, -1), (1, -1), (1, 1), (-1, 1))  # counter-clockwise seen from above
#: Names of the outline's corners and of the face that follows each, counter-clockwise.
CORNER_NAMES = ("corner -x-y", "corner +x-y", "corner +x+y", "corner -x+y")
FACE_NAMES = ("face -y", "face +x", "face +y", "face -x")
#: A point of a ring: (body's state row, the point in the body's frame, its world xy at rest).
OutlinePoint = tuple[int, tuple[float, float, float], tuple[float, float]]


@dataclass(frozen=True)
class Ring:
    """One hoop of web at height `z_m`, standing for the web over the heights `share_m`."""

    z_m: float
    share_m: tuple[float, float]
    slots: list[tuple[int, tuple[float, float, float]]]  # (body, local point), counter-clockwise
    corner_slots: list[int]   # slots at the outline's corners: -x-y, +x-y, +x+y, -x+y
    rest_xy: list[tuple[float, float]]  # slot positions at rest, sled frame
    perimeter_m: float
    layers: float             # web layers over the share (averaged round the load)
    web_m: float              # layers x height share: metres of web the ring stands for
    tension_n: float          # wrapping tension of those layers
    #: Per slot: the place it is (a corner or the face it lies on) and its position round the
    #: outline, `s`.
    places: list[str]
    s_m: list[float]

    @property
    def height_m(self) -> float:
        return self.share_m[1] - self.share_m[0]


@dataclass(frozen=True)
class Panels:
    """Corner verticals and face diagonals between consecutive rings, as arrays over panels."""

    nodes: np.ndarray        # (E, 2) node pairs (lower ring's node first)
    k_web_n_per_m: np.ndarray   # web stiffness of all the layers
    web_m: np.ndarray        # metres of web, for strength: layers x width the panel stands for
    layers: np.ndarray       # web layers between the two rings
    rings: np.ndarray        # (E, 2) indices of the lower and upper ring
    rise: np.ndarray         # vertical part of the panel's direction at rest (1: vertical)
    height_m: np.ndarray     # mid height, for the report
    where: list[str]         # "corner -x-y" for a vertical, "face +x" for a diagonal
    s_m: np.ndarray          # (E, 2) span round the outline (a vertical: one point)


def ring_specs(wrap: WrapFormat, layout: Layout) -> list[Ring]:
    """Rings from the bottom up: the pallet round (if a band reaches the pallet), then two per
    layer. A ring exists where some band covers its share of height."""
    px, py, pz = layout.pallet_size_m
    outline = layout.outline_m
    out = []
    if wrap.covers(0.0, pz):
        half = (px / 2, py / 2)
        pts = [(0, (sx * half[0], sy * half[1], 0.0), (sx * half[0], sy * half[1]))
               for sx, sy in _CORNER_SIGNS]
        out.append(_make_ring(wrap, pz / 2, (0.0, pz), pts, list(range(4)), outline))
    for layer in sorted({b.layer for b in layout.bundles}):
        members = [(k, b) for k, b in enumerate(layout.bundles) if b.layer == layer]
        bottom = min(b.centre_m[2] - b.size_m[2] / 2 for _, b in members)
        top = max(b.centre_m[2] + b.size_m[2] / 2 for _, b in members)
        h = top - bottom
        for i, frac in enumerate(RING_FRACTIONS):
            share = (bottom + h * (RING_FRACTIONS[i - 1] + frac) / 2 if i else bottom,
                     bottom + h * (frac + RING_FRACTIONS[i + 1]) / 2
                     if i + 1 < len(RING_FRACTIONS) else top)
            if not wrap.covers(*share):
                continue
            z = bottom + frac * h
            pts, corners = _outline_points(members, z)
            out.append(_make_ring(wrap, z, share, pts, corners, outline))
    return out


def corner_positions_m(layout: Layout) -> tuple[float, ...]:
    """Where the outline's four corners lie round the perimeter, and the perimeter itself."""
    lx, ly = layout.outline_m
    return (0.0, lx, lx + ly, 2 * lx + ly, 2 * (lx + ly))


def _outline_points(members: list[tuple[int, BundlePlacement]], z: float
                    ) -> tuple[list[OutlinePoint], list[int]]:
    """Vertical edges of the layer's bundles that lie on the layer's outline (its convex hull,
    where the web runs), at height z, counter-clockwise from the -x-y corner, and which of them
    are the outline's corners."""
    edges: list[OutlinePoint] = []
    for k, b in members:
        for sx, sy in _CORNER_SIGNS:
            local = (sx * b.size_m[0] / 2, sy * b.size_m[1] / 2, z - b.centre_m[2])
            world = (b.centre_m[0] + local[0], b.centre_m[1] + local[1])
            edges.append((bundle_row(k), local, world))
    xs = [w[0] for _, _, w in edges]
    ys = [w[1] for _, _, w in edges]
    lo, hi = (min(xs), min(ys)), (max(xs), max(ys))
    hull = _convex_hull([w for _, _, w in edges])
    distance = _distances_to_polygon([w for _, _, w in edges], hull)
    outer = [e for e, d in zip(edges, distance, strict=True) if d <= OUTLINE_TOLERANCE_M]
    cx, cy = (lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2
    start = math.atan2(lo[1] - cy, lo[0] - cx) - 1e-9
    outer.sort(key=lambda e: (math.atan2(e[2][1] - cy, e[2][0] - cx) - start) % (2 * math.pi))
    corners = []
    for sx, sy in _CORNER_SIGNS:
        target = (lo[0] if sx < 0 else hi[0], lo[1] if sy < 0 else hi[1])
        corners.append(min(range(len(outer)), key=lambda i: math.dist(outer[i][2], target)))
    return outer, corners


def _convex_hull(points: list[tuple[float, float]]) -> np.ndarray:
    """The convex hull's vertices, counter-clockwise (Andrew's monotone chain)."""
    pts = sorted(set(points))

    def half(seq: list[tuple[float, float]]) -> list[tuple[float, float]]:
        out: list[tuple[float, float]] = []
        for p in seq:
            while len(out) >= 2 and ((out[-1][0] - out[-2][0]) * (p[1] - out[-2][1])
                                     - (out[-1][1] - out[-2][1]) * (p[0] - out[-2][0])) <= 0:
                out.pop()
            out.append(p)
        return out[:-1]

    return np.array(half(pts) + half(pts[::-1]))


def _distances_to_polygon(points: list[tuple[float, float]], polygon: np.ndarray
                          ) -> np.ndarray:
    """Distance from each point to the nearest side of a closed polygon."""
    a, b = polygon, np.roll(polygon, -1, axis=0)
    ab, ap = b - a, np.asarray(points)[:, None, :] - a          # (sides, 2), (points, sides, 2)
    t = np.clip(np.einsum("kij,ij->ki", ap, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab),
                                                              1e-18), 0.0, 1.0)
    return np.min(norms(ap - t[..., None] * ab), axis=1)


def _make_ring(wrap: WrapFormat, z: float, share: tuple[float, float], pts: list[OutlinePoint],
               corners: list[int], outline: tuple[float, float]) -> Ring:
    """A ring through `pts` = (body, local point, world xy at rest), over the height `share`."""
    h = share[1] - share[0]
    xy = np.array([w for _, _, w in pts])
    perimeter = float(np.linalg.norm(np.roll(xy, -1, axis=0) - xy, axis=1).sum())
    places, s = _slot_places(xy, corners, outline)
    layers = wrap.layers_over(*share)
    return Ring(
        z_m=z, share_m=share, slots=[(body, local) for body, local, _ in pts],
        corner_slots=corners, rest_xy=[tuple(w) for w in xy], perimeter_m=perimeter,
        layers=layers, web_m=layers * h,
        tension_n=wrap.line_tension_n_per_m(*share) * h, places=places, s_m=s,
    )


def _slot_places(xy: np.ndarray, corners: list[int], outline: tuple[float, float]
                 ) -> tuple[list[str], list[float]]:
    """Each slot's place (one of the four corners, else the face it lies on) and its position
    round the load's outline (the ring's own face, scaled onto the outline's face)."""
    lengths = (outline[0], outline[1], outline[0], outline[1])
    starts = np.concatenate([[0.0], np.cumsum(lengths)])
    places, s = [""] * len(xy), [0.0] * len(xy)
    for f in range(4):
        a, b = corners[f], corners[(f + 1) % 4]
        places[a], s[a] = CORNER_NAMES[f], float(starts[f])
        run = [(a + j) % len(xy) for j in range(1, (b - a) % len(xy))]
        span = float(np.linalg.norm(xy[b] - xy[a])) or 1.0
        for j in run:
            along = float(np.dot(xy[j] - xy[a], xy[b] - xy[a])) / span
            places[j] = FACE_NAMES[f]
            s[j] = float(starts[f] + lengths[f] * min(max(along / span, 0.0), 1.0))
    return places, s


class _Panel(NamedTuple):
    """One row of `Panels`."""

    nodes: tuple[int, int]
    k_web_n_per_m: float
    web_m: float
    layers: float
    rings: tuple[int, int]
    rise: float
    height_m: float
    where: str
    s_m: tuple[float, float]


class _Between:
    """Two consecutive rings (`i` and the one above) and what their panels share: the web's
    layers, the height, the corners at rest and the faces' widths."""

    def __init__(self, i: int, lo: Ring, hi: Ring, layers: float, corners: list[list[int]],
                 node_body: np.ndarray) -> None:
        self.i, self.n, self.h = i, layers, hi.z_m - lo.z_m
        self.z = (lo.z_m + hi.z_m) / 2
        self.corners_lo, self.corners_hi = corners[i], corners[i + 1]
        self.node_body = node_body
        self.c_lo = [np.array(lo.rest_xy[j]) for j in lo.corner_slots]
        self.c_hi = [np.array(hi.rest_xy[j]) for j in hi.corner_slots]
        self.faces = [float(np.linalg.norm(self.c_lo[(c + 1) % 4] - self.c_lo[c])
                            + np.linalg.norm(self.c_hi[(c + 1) % 4] - self.c_hi[c])) / 2
                      for c in range(4)]


def _verticals(r: _Between, m: Material, outline: tuple[float, ...]) -> list[_Panel]:
    """The corner verticals between different bodies: the web stretched across its width
    (its cross direction, `cd_ratio`) over the half faces either side of the corner."""
    rows = []
    for c in range(4):
        a, b = r.corners_lo[c], r.corners_hi[c]
        if r.node_body[a] != r.node_body[b]:
            trib = (r.faces[c - 1] + r.faces[c]) / 2
            length = math.hypot(float(np.linalg.norm(r.c_hi[c] - r.c_lo[c])), r.h)
            rows.append(_Panel((a, b), m.stiffness_n_per_m * m.cd_ratio * r.n * trib / length,
                               m.cd_ratio * r.n * trib, r.n, (r.i, r.i + 1), r.h / length,
                               r.z, CORNER_NAMES[c], (outline[c], outline[c])))
    return rows


def _diagonals(r: _Between, m: Material, outline: tuple[float, ...]) -> list[_Panel]:
    """The face diagonals between different bodies, both ways across each face: the web's
    shear."""
    rows = []
    for c in range(4):
        d = (c + 1) % 4
        for a_c, b_c in ((c, d), (d, c)):
            a, b = r.corners_lo[a_c], r.corners_hi[b_c]
            if r.node_body[a] == r.node_body[b]:
                continue
            run = float(np.linalg.norm(r.c_hi[b_c] - r.c_lo[a_c]))
            cos = run / math.hypot(run, r.h)
            rows.append(_Panel((a, b), m.shear_ratio * m.stiffness_n_per_m * r.n * r.faces[c]
                               / (r.h * cos**2), r.n * r.faces[c] / (2 * cos), r.n,
                               (r.i, r.i + 1), r.h / math.hypot(run, r.h), r.z, FACE_NAMES[c],
                               (outline[c], outline[c + 1])))
    return rows


def panel_specs(wrap: WrapFormat, rings: list[Ring], corners: list[list[int]],
                node_body: np.ndarray, outline: tuple[float, ...]) -> Panels:
    """Corner verticals and face diagonals between consecutive rings on different bodies.

    `corners[i]` are ring i's node ids at the outline's corners; `outline` the corner
    positions round the perimeter (`corner_positions_m`).
    """
    rows: list[_Panel] = []
    for i in range(len(rings) - 1):
        lo, hi = rings[i], rings[i + 1]
        if wrap.covers(lo.z_m, hi.z_m):
            between = _Between(i, lo, hi, wrap.layers_over(lo.z_m, hi.z_m), corners, node_body)
            rows += _verticals(between, wrap.material, outline)
            rows += _diagonals(between, wrap.material, outline)
    cols = list(zip(*rows, strict=True)) if rows else [()] * len(_Panel._fields)
    return Panels(
        nodes=np.array(cols[0], int).reshape(-1, 2), k_web_n_per_m=np.array(cols[1], float),
        web_m=np.array(cols[2], float), layers=np.array(cols[3], float),
        rings=np.array(cols[4], int).reshape(-1, 2), rise=np.array(cols[5], float),
        height_m=np.array(cols[6], float), where=list(cols[7]),
        s_m=np.array(cols[8], float).reshape(-1, 2),
    )


def seam_rings(wrap: WrapFormat, rings: list[Ring]) -> list[int]:
    """The rings the wrap's tail closes: those under the web of the machine's last revolution
    (the tail is glued or clamped there; elsewhere the web runs on). Nearest ring if none."""
    if not rings or not wrap.passes:
        return []
    last = wrap.passes[-1]
    height = last.rope_m if last.rope_m is not None else wrap.web_width_m
    lo = last.end_m
    inside = [i for i, r in enumerate(rings) if lo <= r.z_m < lo + height]
    if inside:
        return inside
    middle = lo + height / 2
    return [min(range(len(rings)), key=lambda i: abs(rings[i].z_m - middle))]


def ring_give(ring: Ring, corner_stiffness_n_per_m2: np.ndarray) -> float:
    """A ring's load-side stiffness (tension per metre of perimeter): each edge it turns round
    by an angle a dents under 2 T sin(a/2), which shortens the perimeter by 2 sin(a/2) times
    the dent, so the edges add 4 sin²(a/2) / k_edge of compliance each."""
    xy = np.array(ring.rest_xy)
    into, out = xy - np.roll(xy, 1, axis=0), np.roll(xy, -1, axis=0) - xy
    turn = np.arctan2(into[:, 0] * out[:, 1] - into[:, 1] * out[:, 0],
                      np.einsum("ij,ij->i", into, out))
    k_edge = corner_stiffness_n_per_m2[[body for body, _ in ring.slots]] * ring.height_m
    compliance = float(np.sum(4 * np.sin(turn / 2) ** 2 / k_edge))
    return 1.0 / compliance if compliance > 0 else math.inf


def hull_neighbours(active: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For every slot of every ring, the previous and next active slot (cyclic)."""
    m = active.shape[1]
    twice = np.concatenate([active, active], axis=1)
    ids = np.arange(2 * m)
    before = np.maximum.accumulate(np.where(twice, ids, -1), axis=1)
    after = np.minimum.accumulate(np.where(twice, ids, 2 * m)[:, ::-1], axis=1)[:, ::-1]
    prev = before[:, m - 1:2 * m - 1] % m
    nxt = np.concatenate([after[:, 1:], np.full((len(active), 1), 2 * m)], axis=1)[:, :m] % m
    return prev, nxt
