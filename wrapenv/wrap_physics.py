"""The soft wrap: a tension-only, elastoplastic cable net on the load's outer faces.

The envelope is coupled to the rigid bodies through forces at body-fixed points, summed per body
(force and torque), so Bullet only ever sees external wrenches. Two kinds of element:

* **Rings** (hoops, the web's machine direction): two per layer of bundles, a quarter and three
  quarters up the layer, and one round on the pallet when a band reaches it. A ring is a taut,
  frictionless cable around its layer: it lies on the convex hull of the outer bundles' vertical
  edges at its height, carries one tension all round and pushes only inward, on the hull's
  corners. That is how pretension squeezes a layer, and how a bundle that bulges out of a face
  is held back, while a bundle that moves inward is simply left (the wrap never pulls).
* **Panels** (the web's cross direction and shear): between consecutive rings that sit on
  different bodies (across each layer joint, and from the pallet round to the first layer),
  verticals at the four corners and both diagonals of each face. They carry no pretension: a
  spiral wrap is pulled along the hoop only. This is what resists layers sliding on each other,
  and, through the pallet round, the load sliding on the pallet.

Every element is tension-only and elastoplastic with linear hardening; it tears (and is removed
for the rest of the run) when its force reaches the web's breaking force. Stiffness, strength
and pretension of an element are the material card's per-metre figures times the web layers
over the element's share of height, so layers add up where bands overlap.

The web does not act on a rigid body directly: it presses on shrink-wrapped bottles whose
corners give, and it grips by friction. Each element therefore has the load-side compliance
`CONTACT_STIFFNESS_N_PER_M` at both ends in series with the web. Besides being physical, this
bounds every element's stiffness so the explicit coupling stays stable at the bench's 240 Hz
(Kraft paper's own stiffness, ~10^6 N/m per panel, is not).

While the unit settles the wrap is being applied: rings hold their wrapping tension whatever
the bundles do, as a wrapping machine's web brake does. `freeze()` then fixes the rest lengths:
from there on, the wrap is elastic, yields and tears.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from wrapenv.load import Layout
from wrapenv.wrap import WrapFormat

#: Load-side compliance in series with the web at each end of an element (N/m): a shrink-wrapped
#: PET bundle corner dents 1-2 mm under 100-200 N of wrap force [A]. Scaled by the calibrated
#: stiffness scale together with the web.
CONTACT_STIFFNESS_N_PER_M = 1.0e5
#: Damping of each element as a fraction of critical (for its stiffness and the masses it joins).
DAMPING_RATIO = 0.2
#: Ring heights within a layer of bundles, as fractions of the layer height.
RING_FRACTIONS = (0.25, 0.75)
#: A bundle edge within this distance of its layer's outline is on the outside of the load.
OUTLINE_TOLERANCE_M = 0.005
#: Panel shear stiffness of a wrinkled membrane carried by 45-degree tension strips: K / 4.
SHEAR_FRACTION = 0.25


@dataclass(frozen=True)
class WrapReport:
    """What the wrap went through in one run."""

    torn_at_m: tuple[float, ...]     # heights of the elements that tore (empty: intact)
    peak_utilisation: float          # highest element force / its breaking force
    plastic_strain_max: float        # largest permanent stretch left in an element
    ring_tension_n: tuple[float, ...]  # tension of each ring at the end of the run

    @property
    def torn(self) -> bool:
        return bool(self.torn_at_m)

    def to_json(self) -> dict:
        return {
            "torn": self.torn,
            "torn_at_m": [round(z, 4) for z in self.torn_at_m],
            "peak_utilisation": round(self.peak_utilisation, 4),
            "plastic_strain_max": round(self.plastic_strain_max, 6),
        }


@dataclass
class _Elements:
    """Elastoplastic, tension-only elements with linear hardening; arrays over elements."""

    k_elastic: np.ndarray    # N/m of elongation
    plastic_modulus: np.ndarray  # hardening modulus H, so the post-yield tangent is k_h
    yield_force: np.ndarray
    break_force: np.ndarray
    pretension: np.ndarray
    damping: np.ndarray      # N s/m
    height_m: np.ndarray     # where each element sits, for the report
    length_m: np.ndarray     # material length at freeze, for plastic strain

    def __post_init__(self) -> None:
        n = len(self.k_elastic)
        self.rest = np.zeros(n)
        self.plastic = np.zeros(n)
        self.torn = np.zeros(n, bool)
        self.peak = np.zeros(n)
        self.last = self.pretension.copy()

    def force(self, length: np.ndarray, rate: np.ndarray) -> np.ndarray:
        """Tension for the current lengths (return mapping of 1D plasticity), then tearing."""
        trial = self.k_elastic * (length - self.rest - self.plastic)
        hardening = self.plastic_modulus * self.plastic
        over = trial - (self.yield_force + hardening)
        if over.max(initial=0.0) > 0:  # some element yields (most steps none does)
            flow = np.maximum(over, 0.0) / (self.k_elastic + self.plastic_modulus)
            self.plastic += flow
            trial = trial - self.k_elastic * flow
        elastic = np.maximum(trial, 0.0)
        self.peak = np.maximum(self.peak, np.minimum(elastic / self.break_force, 1.0))
        self.torn |= elastic >= self.break_force
        self.last = np.where(self.torn, 0.0, elastic)
        taut = self.last > 0
        return np.where(taut, np.maximum(self.last + self.damping * rate, 0.0), 0.0)


def _series(*k: np.ndarray | float) -> np.ndarray:
    return np.asarray(1.0 / sum(1.0 / np.asarray(x, float) for x in k))


def _element_set(k_web: np.ndarray, material_strength: tuple[float, float, float],
                 web_metres: np.ndarray, pretension: np.ndarray, mass: np.ndarray,
                 height: np.ndarray, length: np.ndarray, contact_k: float) -> _Elements:
    """Elements from the web's stiffness (k_web, N/m) and the metres of web they stand for.

    `material_strength` is (yield force per metre, break force per metre, hardening ratio).
    """
    yield_per_m, break_per_m, hardening = material_strength
    k_e = _series(k_web, contact_k / 2)
    k_h = _series(np.maximum(k_web * hardening, 1e-9), contact_k / 2)
    plastic_modulus = k_e * k_h / np.maximum(k_e - k_h, 1e-9)
    return _Elements(
        k_elastic=k_e,
        plastic_modulus=plastic_modulus,
        yield_force=yield_per_m * web_metres,
        break_force=break_per_m * web_metres,
        pretension=pretension,
        damping=2 * DAMPING_RATIO * np.sqrt(k_e * mass),
        height_m=height,
        length_m=length,
    )


class WrapNet:
    """The wrap of one load unit, as forces on its bodies.

    Bodies are numbered as the bench's state arrays: 0 the pallet, 1 + k bundle k of the layout.
    """

    def __init__(self, wrap: WrapFormat, layout: Layout,
                 contact_stiffness_n_per_m: float = CONTACT_STIFFNESS_N_PER_M) -> None:
        self.wrap, self.layout = wrap, layout
        self.n_bodies = 1 + len(layout.bundles)
        mass = np.array([layout.pallet_mass_kg] + [b.mass_kg for b in layout.bundles])
        self._node_body: list[int] = []
        self._node_local: list[tuple[float, float, float]] = []
        rings = _ring_specs(wrap, layout)
        self.ring_heights = np.array([r.z for r in rings])
        width = max(len(r.slots) for r in rings) if rings else 0
        self._slots = np.full((len(rings), width), -1)
        corners = []
        for i, ring in enumerate(rings):
            ids = [self._node(b, p) for b, p in ring.slots]
            self._slots[i, :len(ids)] = ids
            corners.append([ids[j] for j in ring.corner_slots])
        self.node_body = np.array(self._node_body, int)
        self.node_local = np.array(self._node_local, float).reshape(-1, 3)
        self._slot_valid = self._slots >= 0
        self._active = self._slot_valid.copy()
        self._hull_links = _neighbours(self._active)
        self._slot_index = np.where(self._slot_valid, self._slots, 0)
        m = wrap.material
        strength = (m.yield_force_n_per_m, m.break_force_n_per_m, m.hardening_ratio)
        k_c = contact_stiffness_n_per_m
        ring_mass = np.array([mass[[b for b, _ in r.slots]].mean() for r in rings])
        perimeter = np.array([r.perimeter_m for r in rings])
        self.rings = _element_set(
            k_web=np.array([m.stiffness_n_per_m * r.web_metres for r in rings]) / perimeter,
            material_strength=strength,
            web_metres=np.array([r.web_metres for r in rings]),
            pretension=np.array([r.tension_n for r in rings]),
            mass=ring_mass, height=self.ring_heights, length=perimeter, contact_k=k_c,
        )
        self.panel_nodes, panel_k, panel_web, panel_h = _panels(wrap, rings, corners,
                                                                self.node_body)
        a, b = (self.panel_nodes.T if len(self.panel_nodes) else (np.zeros(0, int),) * 2)
        ma, mb = mass[self.node_body[a]], mass[self.node_body[b]]
        self.panels = _element_set(
            k_web=panel_k, material_strength=strength, web_metres=panel_web,
            pretension=np.zeros(len(panel_k)), mass=ma * mb / (ma + mb), height=panel_h,
            length=np.ones(len(panel_k)), contact_k=k_c,
        )
        # incidence matrices: sums over elements and nodes become one product each
        n_nodes = len(self.node_body)
        self._incidence = np.zeros((self.n_bodies, n_nodes))
        self._incidence[self.node_body, np.arange(n_nodes)] = 1.0
        # every node is the node of exactly one ring slot: its flat index in (rings x slots)
        flat = self._slots.ravel()
        self._node_slot = np.zeros(n_nodes, int)
        self._node_slot[flat[flat >= 0]] = np.flatnonzero(flat >= 0)
        self._panel_to_node = np.zeros((n_nodes, len(self.panel_nodes)))
        for e, (a, b) in enumerate(self.panel_nodes):
            self._panel_to_node[a, e] += 1.0
            self._panel_to_node[b, e] -= 1.0
        self.frozen = False
        #: While wrapping: the fraction of the wrapping tension laid so far (see `laying`).
        self.laid = 1.0

    def _node(self, body: int, local: tuple[float, float, float]) -> int:
        self._node_body.append(body)
        self._node_local.append(local)
        return len(self._node_body) - 1

    # -- state ----------------------------------------------------------------------------
    def nodes(self, pos: np.ndarray, rot: np.ndarray) -> np.ndarray:
        """World positions (sled frame) of the wrap's nodes, from body positions and rotations."""
        return pos[self.node_body] + np.einsum("nij,nj->ni", rot[self.node_body],
                                               self.node_local)

    def laying(self, fraction: float) -> None:
        """How much of the wrapping tension is on so far (0 to 1). The machine lays the web
        round by round; a full wrap's squeeze switched on at once slams light bundles into
        each other (measured: 6 Kraft layers at 800 N blew up the settle)."""
        self.laid = min(max(fraction, 0.0), 1.0)

    def freeze(self, pos: np.ndarray, rot: np.ndarray) -> None:
        """End of wrapping: rest lengths are fixed so each ring keeps its wrapping tension."""
        p = self.nodes(pos, rot)
        perimeter, *_ = self._ring_geometry(p)
        r = self.rings
        r.rest = perimeter - r.pretension / r.k_elastic
        r.length_m = perimeter.copy()
        length = self._panel_lengths(p)
        self.panels.rest = length.copy()
        self.panels.length_m = length.copy()
        self.frozen = True

    def _panel_lengths(self, p: np.ndarray) -> np.ndarray:
        if not len(self.panel_nodes):
            return np.zeros(0)
        d = p[self.panel_nodes[:, 1]] - p[self.panel_nodes[:, 0]]
        return np.linalg.norm(d, axis=1)

    def _ring_geometry(self, p: np.ndarray) -> tuple[np.ndarray, ...]:
        """Per ring: perimeter of the hull, and per slot its hull neighbours and activity.

        The hull of the last step is the first guess: corners that turned reflex leave it, and
        slots that came out past its edge join it, until nothing changes (usually at once).
        """
        xyz = p[self._slot_index]                       # (R, M, 3)
        rows = np.arange(len(xyz))[:, None]
        active = self._active
        prev, nxt = self._hull_links
        for _ in range(2 * xyz.shape[1]):
            a, c = xyz[rows, prev], xyz[rows, nxt]
            # < 0: the slot is right of its hull edge (a -> c), i.e. outside the hull
            side = ((c[..., 0] - a[..., 0]) * (xyz[..., 1] - a[..., 1])
                    - (c[..., 1] - a[..., 1]) * (xyz[..., 0] - a[..., 0]))
            changed = (active & (side >= 0)) | (~active & self._slot_valid & (side < 0))
            changed &= self._slot_valid
            if not changed.any():
                break
            # drop reflex corners first; add outside slots only when no corner is reflex
            drop = active & changed
            active = active & ~drop if drop.any() else active | changed
            prev, nxt = _neighbours(active)
        self._active, self._hull_links = active, (prev, nxt)
        edge = xyz[rows, nxt] - xyz                     # to the next hull corner
        length = np.where(active, np.linalg.norm(edge, axis=-1), 0.0)
        return length.sum(axis=1), active, prev, nxt, edge, length

    def forces(self, pos: np.ndarray, rot: np.ndarray, vel: np.ndarray,
               omega: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Force and torque (about each body's centre) the wrap applies, (n_bodies, 3) each.

        `pos`, `rot`, `vel`, `omega`: state of every body (pallet first), in the sled frame.
        """
        nb = self.node_body
        arm = np.einsum("nij,nj->ni", rot[nb], self.node_local)
        p = pos[nb] + arm
        v = vel[nb] + _cross(omega[nb], arm)
        f = self._ring_forces(p, v)
        self._panel_forces(p, v, f)
        wrench = self._incidence @ np.hstack([f, _cross(arm, f)])
        return wrench[:, :3], wrench[:, 3:]

    def _ring_forces(self, p: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Forces of the rings on every node (n_nodes, 3)."""
        if not len(self._slots):
            return np.zeros_like(p)
        perimeter, active, prev, nxt, edge, length = self._ring_geometry(p)
        r = self.rings
        unit = edge / np.maximum(length, 1e-12)[..., None]
        rows = np.arange(len(unit))[:, None]
        if self.frozen:
            vs = v[self._slot_index]
            rate = np.where(active, np.einsum("rmk,rmk->rm", vs[rows, nxt] - vs, unit), 0).sum(1)
            tension = r.force(perimeter, rate)
        else:
            tension = np.where(r.torn, 0.0, r.pretension * self.laid)
        # each hull corner is pulled towards both its neighbours
        pull = (unit - unit[rows, prev]) * (tension[:, None, None] * active[..., None])
        return pull.reshape(-1, 3)[self._node_slot]

    def _panel_forces(self, p: np.ndarray, v: np.ndarray, f: np.ndarray) -> None:
        if not self.frozen or not len(self.panel_nodes):
            return
        a, b = self.panel_nodes[:, 0], self.panel_nodes[:, 1]
        d = p[b] - p[a]
        length = np.linalg.norm(d, axis=1)
        unit = d / np.maximum(length, 1e-12)[:, None]
        rate = np.einsum("ek,ek->e", v[b] - v[a], unit)
        tension = self.panels.force(length, rate)
        f += self._panel_to_node @ (unit * tension[:, None])

    def report(self) -> WrapReport:
        torn = np.concatenate([self.rings.height_m[self.rings.torn],
                               self.panels.height_m[self.panels.torn]])
        plastic = np.concatenate([_strain(self.rings), _strain(self.panels)])
        peak = np.concatenate([self.rings.peak, self.panels.peak])
        tension = self.rings.last
        return WrapReport(
            torn_at_m=tuple(sorted({round(float(z), 4) for z in torn})),
            peak_utilisation=float(peak.max()) if len(peak) else 0.0,
            plastic_strain_max=float(plastic.max()) if len(plastic) else 0.0,
            ring_tension_n=tuple(float(t) for t in tension),
        )


def _strain(e: _Elements) -> np.ndarray:
    """Permanent stretch of each element over its length (0 for a degenerate element)."""
    return np.divide(e.plastic, e.length_m, out=np.zeros_like(e.plastic), where=e.length_m > 0)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of (n, 3) arrays (np.cross is slow for small arrays)."""
    return np.stack([a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1],
                     a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
                     a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]], axis=1)


def _neighbours(active: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For every slot of every ring, the previous and next active slot (cyclic)."""
    m = active.shape[1]
    twice = np.concatenate([active, active], axis=1)
    ids = np.arange(2 * m)
    before = np.maximum.accumulate(np.where(twice, ids, -1), axis=1)
    after = np.minimum.accumulate(np.where(twice, ids, 2 * m)[:, ::-1], axis=1)[:, ::-1]
    prev = before[:, m - 1:2 * m - 1] % m
    nxt = np.concatenate([after[:, 1:], np.full((len(active), 1), 2 * m)], axis=1)[:, :m] % m
    return prev, nxt


@dataclass(frozen=True)
class _Ring:
    z: float
    slots: list[tuple[int, tuple[float, float, float]]]  # (body, local point), counter-clockwise
    corner_slots: list[int]   # slots at the outline's corners: -x-y, +x-y, +x+y, -x+y
    rest_xy: list[tuple[float, float]]  # slot positions at rest, sled frame
    perimeter_m: float
    web_metres: float         # layers x height share: metres of web the ring stands for
    tension_n: float          # wrapping tension of those layers


def _ring_specs(wrap: WrapFormat, layout: Layout) -> list[_Ring]:
    """Rings from the bottom up: the pallet round (if a band reaches the pallet), then two per
    layer. A ring exists where some band covers its share of height."""
    px, py, pz = layout.pallet_size_m
    out = []
    if wrap.covers(0.0, pz):
        half = (px / 2, py / 2)
        pts = [(0, (sx * half[0], sy * half[1], 0.0), (sx * half[0], sy * half[1]))
               for sx, sy in _CORNER_SIGNS]
        out.append(_make_ring(wrap, pz / 2, (0.0, pz), pts, list(range(4))))
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
            out.append(_make_ring(wrap, z, share, pts, corners))
    return out


_CORNER_SIGNS = ((-1, -1), (1, -1), (1, 1), (-1, 1))  # counter-clockwise seen from above


def _outline_points(members, z: float) -> tuple[list, list[int]]:
    """Vertical edges of the layer's bundles that lie on the layer's outline, at height z,
    counter-clockwise from the -x-y corner, and which of them are the outline's corners."""
    edges = []
    for k, b in members:
        for sx, sy in _CORNER_SIGNS:
            local = (sx * b.size_m[0] / 2, sy * b.size_m[1] / 2, z - b.centre_m[2])
            world = (b.centre_m[0] + local[0], b.centre_m[1] + local[1])
            edges.append((1 + k, local, world))
    xs = [w[0] for _, _, w in edges]
    ys = [w[1] for _, _, w in edges]
    lo, hi = (min(xs), min(ys)), (max(xs), max(ys))
    tol = OUTLINE_TOLERANCE_M
    outer = [e for e in edges if min(abs(e[2][0] - lo[0]), abs(e[2][0] - hi[0]),
                                     abs(e[2][1] - lo[1]), abs(e[2][1] - hi[1])) <= tol]
    cx, cy = (lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2
    start = math.atan2(lo[1] - cy, lo[0] - cx) - 1e-9
    outer.sort(key=lambda e: (math.atan2(e[2][1] - cy, e[2][0] - cx) - start) % (2 * math.pi))
    corners = []
    for sx, sy in _CORNER_SIGNS:
        target = (lo[0] if sx < 0 else hi[0], lo[1] if sy < 0 else hi[1])
        corners.append(min(range(len(outer)), key=lambda i: math.dist(outer[i][2], target)))
    return outer, corners


def _make_ring(wrap: WrapFormat, z: float, share: tuple[float, float], pts: list,
               corners: list[int]) -> _Ring:
    """A ring through `pts` = (body, local point, world xy at rest), over the height `share`."""
    h = share[1] - share[0]
    xy = np.array([w for _, _, w in pts])
    perimeter = float(np.linalg.norm(np.roll(xy, -1, axis=0) - xy, axis=1).sum())
    return _Ring(
        z=z, slots=[(body, local) for body, local, _ in pts], corner_slots=corners,
        rest_xy=[tuple(w) for w in xy], perimeter_m=perimeter,
        web_metres=wrap.layers_over(*share) * h,
        tension_n=wrap.line_tension_n_per_m(*share) * h,
    )


def _panels(wrap: WrapFormat, rings: list[_Ring], corners: list[list[int]],
            node_body: np.ndarray) -> tuple[np.ndarray, ...]:
    """Corner verticals and face diagonals between consecutive rings on different bodies.

    Returns node pairs (E, 2), web stiffness k_web (N/m), strength width (m of web) and height.
    """
    m = wrap.material
    pairs, k_web, width, height = [], [], [], []
    for i in range(len(rings) - 1):
        lo, hi = rings[i], rings[i + 1]
        if not wrap.covers(lo.z, hi.z):
            continue
        n = wrap.layers_over(lo.z, hi.z)
        h = hi.z - lo.z
        c_lo = [np.array(lo.rest_xy[j]) for j in lo.corner_slots]
        c_hi = [np.array(hi.rest_xy[j]) for j in hi.corner_slots]
        faces = [(np.linalg.norm(c_lo[(c + 1) % 4] - c_lo[c])
                  + np.linalg.norm(c_hi[(c + 1) % 4] - c_hi[c])) / 2 for c in range(4)]
        z = (lo.z + hi.z) / 2
        for c in range(4):
            a, b = corners[i][c], corners[i + 1][c]
            if node_body[a] != node_body[b]:
                trib = (faces[c - 1] + faces[c]) / 2
                length = math.hypot(float(np.linalg.norm(c_hi[c] - c_lo[c])), h)
                pairs.append((a, b))
                k_web.append(m.stiffness_n_per_m * m.cd_ratio * n * trib / length)
                width.append(m.cd_ratio * n * trib)
                height.append(z)
        for c in range(4):
            d = (c + 1) % 4
            for a_c, b_c in ((c, d), (d, c)):
                a, b = corners[i][a_c], corners[i + 1][b_c]
                if node_body[a] == node_body[b]:
                    continue
                run = float(np.linalg.norm(c_hi[b_c] - c_lo[a_c]))
                cos = run / math.hypot(run, h)
                pairs.append((a, b))
                k_web.append(SHEAR_FRACTION * m.stiffness_n_per_m * n * faces[c] / (h * cos**2))
                width.append(n * faces[c] / (2 * cos))
                height.append(z)
    return (np.array(pairs, int).reshape(-1, 2), np.array(k_web), np.array(width),
            np.array(height))
