"""The soft wrap: a tension-only, elastoplastic cable net on the load's outer faces.

The envelope is coupled to the rigid bodies through forces at body-fixed points, summed per body
(force and torque), so Bullet only ever sees external wrenches. Two kinds of element, laid out
by wrapenv/wrap_geometry.py:

* **Rings** (hoops, the web's machine direction): two per layer of bundles, a quarter and three
  quarters up the layer, and one round on the pallet when a band reaches it. A ring is a taut
  cable around its layer: it lies on the convex hull of the outer bundles' vertical edges at its
  height, carries one tension all round (the web slides round the edges) and pushes only inward,
  on the hull's corners. That is how pretension squeezes a layer, and how a bundle that bulges
  out of a face is held back, while a bundle that moves inward is simply left.
* **Panels** (the web's cross direction and shear): between consecutive rings that sit on
  different bodies, verticals at the four corners and both diagonals of each face. They carry no
  pretension: a spiral wrap is pulled along the hoop only. They resist layers sliding on each
  other and, through the pallet round, the load sliding on the pallet.

Every element is tension-only and elastoplastic with linear hardening; stiffness, strength and
pretension are the material card's per-metre figures times the web layers over the element's
share of height. What limits a wrap, beyond that law (docs/materials.md, section 5):

* **The load's give.** The web presses on the products' vertical edges, which dent: each element
  has the load-side compliance of the edges it bears on in series with the web (the bundle card's
  corner stiffness times the edge height; the pallet's block is far stiffer). It is physical, and
  it bounds every element's stiffness so the explicit coupling stays stable at 240 Hz.
* **Edges.** Where a ring's web turns round an edge it also bends to a curvature κ: its outer
  fibre carries t κ / (2 + t κ) more strain, so that place tears at a lower tension
  (`bend_factor`). κ is the edge's 1/r for a web wrapped fully round it (t / (2r + t)), less for
  a small turn under tension, which the web's bending stiffness spreads (`bend_curvature`).
* **Layers that slide.** Paper does not cling: only the layer touching the load is gripped by it;
  the layers outside it take a panel's load through friction on the layer beneath, pressed by
  the rings' push on the corners, so their share is capped. Film layers cling and act as one.
* **The seam.** The tail of the last revolution is glued or clamped; it holds the tension of the
  outermost layer less what friction on the turn beneath takes off (capstan). If it lets go,
  the rings it closes go slack (`opened`).

While the unit settles the wrap is being applied: rings hold their wrapping tension whatever
the bundles do, as a wrapping machine's web brake does. `freeze()` then fixes the rest lengths:
from there on, the wrap is elastic, yields, tears and may open.
"""

from __future__ import annotations

import math

import numpy as np

from wrapenv.load import Layout
from wrapenv.rowwise import cross, norms
from wrapenv.wrap import WrapFormat
from wrapenv.wrap_elements import Elements, bend_curvature, bend_factor, element_set, series
from wrapenv.wrap_geometry import (
    corner_positions_m,
    hull_neighbours,
    panel_specs,
    ring_give,
    ring_specs,
    seam_rings,
)
from wrapenv.wrap_report import WrapReport, places_of

#: The pallet's corners under the wrap, N/m per m of edge [A] (docs/materials.md section 5,
#: B3): a wooden block, stiffer than a PET bundle's edge; 1e7 made the heaviest program of the
#: search space blow up on a two-bundle unit at 0.3 g (bodies overlapping 41 mm), 1e6 is
#: stable on it from 0.3 to 1.0 g.
PALLET_CORNER_STIFFNESS_N_PER_M2 = 1.0e6
#: Radius of the pallet's vertical edges: a sawn block, lightly rounded [A] (B3).
PALLET_EDGE_RADIUS_M = 0.005


class WrapNet:
    """The wrap of one load unit, as forces on its bodies.

    Bodies are numbered as the bench's state arrays (wrapenv.scene: the pallet, then the bundles).
    """

    def __init__(self, wrap: WrapFormat, layout: Layout) -> None:
        self.wrap, self.layout = wrap, layout
        self.n_bodies = 1 + len(layout.bundles)
        mass = np.array([layout.pallet_mass_kg] + [b.mass_kg for b in layout.bundles])
        #: Per body: how stiff its vertical edges are under the wrap, and how round.
        self.corner_stiffness_n_per_m2 = np.array([PALLET_CORNER_STIFFNESS_N_PER_M2]
                                         + [b.corner_stiffness_n_per_m2 for b in layout.bundles])
        radius = np.array([PALLET_EDGE_RADIUS_M] + [b.edge_radius_m for b in layout.bundles])
        self._node_body: list[int] = []
        self._node_local: list[tuple[float, float, float]] = []
        self.ring_specs = rings = ring_specs(wrap, layout)
        self.ring_heights = np.array([r.z_m for r in rings])
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
        self._slot_index = np.where(self._slot_valid, self._slots, 0)
        # constant per step, so made once: row indices, and weights and counts for the centres
        self._rows = np.arange(len(rings))[:, None]
        self._slot_weight = self._slot_valid[..., None].astype(float)
        self._slot_count = np.maximum(self._slot_valid.sum(1), 1)[:, None]
        self._ring_web_m = np.maximum(np.array([r.web_m for r in rings]), 1e-9)
        bodies = self.node_body[self._slot_index] if len(self.node_body) else self._slot_index
        #: Per ring slot: the radius of the edge there.
        self.slot_radius = radius[bodies]
        #: Per ring slot: how much less tension the web bore there (bending round the edge)
        #: when the ring's tension peaked.
        self.ring_edge = np.ones(self._slots.shape)
        self.rings = self._ring_elements(mass)
        self.outline_s_m = corner_positions_m(layout)
        self.panel_spec = panel_specs(wrap, rings, corners, self.node_body, self.outline_s_m)
        self.panels = self._panel_elements(mass)
        self._incidences()
        self._seam_setup()
        self.frozen = False
        #: While wrapping: the fraction of the wrapping tension laid so far (see `laying`).
        self.laid = 1.0

    @property
    def panel_nodes(self) -> np.ndarray:
        """(E, 2) node pairs of the panels, lower ring's node first."""
        return self.panel_spec.nodes

    def _node(self, body: int, local: tuple[float, float, float]) -> int:
        self._node_body.append(body)
        self._node_local.append(local)
        return len(self._node_body) - 1

    # -- building ------------------------------------------------------------------------
    def _ring_elements(self, mass: np.ndarray) -> Elements:
        rings, m = self.ring_specs, self.wrap.material
        strength = (m.yield_force_n_per_m, m.break_force_n_per_m, m.hardening_ratio)
        perimeter = np.array([r.perimeter_m for r in rings])
        return element_set(
            k_web_n_per_m=np.array([m.stiffness_n_per_m * r.web_m for r in rings]) / perimeter,
            material_strength=strength,
            web_m=np.array([r.web_m for r in rings]),
            pretension_n=np.array([r.tension_n for r in rings]),
            mass_kg=np.array([mass[[b for b, _ in r.slots]].mean() for r in rings]),
            height_m=self.ring_heights, length_m=perimeter,
            give_n_per_m=np.array([ring_give(r, self.corner_stiffness_n_per_m2) for r in rings]),
            damping_ratio=m.damping_ratio,
        )

    def _panel_elements(self, mass: np.ndarray) -> Elements:
        """The panels, all layers of a panel in one element behind the give of its two ends.
        For paper, `_paper_law` then limits what the layers outside the one touching the load
        take (stored here: the law of all layers stuck, and the tangent once they slip)."""
        spec, m = self.panel_spec, self.wrap.material
        a, b = spec.nodes.T
        share = np.array([r.height_m for r in self.ring_specs])
        k_end = [self.corner_stiffness_n_per_m2[self.node_body[n]] * share[spec.rings[:, j]]
                 for j, n in enumerate((a, b))]
        give = series(*k_end) if len(a) else np.zeros(0)
        ma, mb = mass[self.node_body[a]], mass[self.node_body[b]]
        panels = element_set(
            k_web_n_per_m=spec.k_web_n_per_m,
            material_strength=(m.yield_force_n_per_m, m.break_force_n_per_m, m.hardening_ratio),
            web_m=spec.web_m, pretension_n=np.zeros_like(spec.k_web_n_per_m),
            mass_kg=ma * mb / (ma + mb), height_m=spec.height_m,
            length_m=np.ones_like(spec.k_web_n_per_m), give_n_per_m=give,
            damping_ratio=m.damping_ratio)
        n = spec.layers
        #: Panels whose outer layers slide on the one beneath (paper, more than one layer).
        self.sliding = np.flatnonzero((n > 1.0 + 1e-9) & (not m.clings))
        k = self.sliding
        slipped = series(spec.k_web_n_per_m[k] / n[k], give[k])   # only the layer against the load
        self._stuck = (panels.yield_force_n[k].copy(), panels.break_force_n[k].copy(),
                       panels.plastic_modulus_n_per_m[k].copy(),
                       panels.k_elastic_n_per_m[k] * slipped
                       / np.maximum(panels.k_elastic_n_per_m[k] - slipped, 1e-9))
        return panels

    def _incidences(self) -> None:
        """Incidence matrices: sums over slots, elements and nodes become one product each."""
        n_nodes = len(self.node_body)
        self._incidence = np.zeros((self.n_bodies, n_nodes))
        self._incidence[self.node_body, np.arange(n_nodes)] = 1.0
        # every node is the node of exactly one ring slot: its flat index in (rings x slots)
        flat = self._slots.ravel()
        self._node_slot = np.zeros(n_nodes, int)
        self._node_slot[flat[flat >= 0]] = np.flatnonzero(flat >= 0)
        nodes = self.panel_spec.nodes
        self._panel_to_node = np.zeros((n_nodes, len(nodes)))
        for e, (a, b) in enumerate(nodes):
            self._panel_to_node[a, e] += 1.0
            self._panel_to_node[b, e] -= 1.0
        # what presses a node's outer layers onto the layer beneath: its ring's push on that
        # corner, the outer layers' share of it, split among the sliding panels ending there
        layers = np.array([r.layers for r in self.ring_specs])
        node_ring = np.zeros(n_nodes, int)
        node_ring[flat[flat >= 0]] = np.flatnonzero(flat >= 0) // max(self._slots.shape[1], 1)
        ends = nodes[self.sliding].ravel()
        sharing = np.maximum(np.bincount(ends, minlength=n_nodes), 1)
        self._outer_press = np.clip(1.0 - 1.0 / np.maximum(layers, 1.0), 0, 1)[node_ring] / sharing
        self._push = np.zeros(n_nodes)

    def _seam_setup(self) -> None:
        """The rings the tail closes, the share of their tension it holds (one layer's, less
        what friction on a full turn beneath takes off: capstan e^(-2 pi mu)) and its strength."""
        m, rings = self.wrap.material, self.ring_specs
        self.seam = np.array(seam_rings(self.wrap, rings), int)
        layers = np.array([rings[i].layers for i in self.seam])
        lap = np.clip(layers - 1.0, 0.0, 1.0)
        self._seam_share = np.exp(-2 * math.pi * m.interlayer_mu * lap) / np.maximum(layers, 1)
        self._seam_bears = m.seam_holds_n_per_m * np.array([rings[i].height_m for i in self.seam])
        self.seam_peak, self.seam_peak_force, self.seam_peak_t = 0.0, 0.0, math.nan

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
        r.rest_m = perimeter - r.pretension_n / r.k_elastic_n_per_m
        r.length_m = perimeter.copy()
        length = self._panel_lengths(p)
        self.panels.rest_m = length.copy()
        self.panels.length_m = length.copy()
        self.frozen = True

    def next_level(self) -> None:
        """Carry the wrap into the next level of the same unit: its rest lengths, plastic
        stretch, tears and an opened seam stay as they are; the peaks start again, since the
        report is per level."""
        for e in (self.rings, self.panels):
            e.peak[:], e.peak_force_n[:], e.peak_t_s[:], e.rising[:] = 0.0, 0.0, np.nan, False
        self.ring_edge[:] = 1.0
        self.seam_peak, self.seam_peak_force, self.seam_peak_t = 0.0, 0.0, math.nan

    def _panel_lengths(self, p: np.ndarray) -> np.ndarray:
        nodes = self.panel_spec.nodes
        if not len(nodes):
            return np.zeros(0)
        return norms(p[nodes[:, 1]] - p[nodes[:, 0]])

    def _ring_geometry(self, p: np.ndarray) -> tuple[np.ndarray, ...]:
        """Per ring: perimeter of the hull, and per slot its hull neighbours and activity.

        Slots are taken in the order of their angle round the ring's centre (bundles pressed
        together can swap the order they had at rest, which would cross the hull). The hull
        of the last step is the first guess: corners that turned reflex leave it, and slots
        that came out past its edge join it, until nothing changes (usually at once).
        """
        xyz = p[self._slot_index]                       # (R, M, 3), rest order
        rows, valid = self._rows, self._slot_valid
        centre = (xyz * self._slot_weight).sum(1) / self._slot_count
        angle = np.where(valid, np.arctan2(xyz[..., 1] - centre[:, None, 1],
                                           xyz[..., 0] - centre[:, None, 0]), np.inf)
        order = np.argsort(angle, axis=1, kind="stable")
        s_xyz, s_valid, active = xyz[rows, order], valid[rows, order], self._active[rows, order]
        for _ in range(2 * xyz.shape[1]):
            prev, nxt = hull_neighbours(active)
            a, c = s_xyz[rows, prev], s_xyz[rows, nxt]
            # < 0: the slot is right of its hull edge (a -> c), i.e. outside the hull
            side = ((c[..., 0] - a[..., 0]) * (s_xyz[..., 1] - a[..., 1])
                    - (c[..., 1] - a[..., 1]) * (s_xyz[..., 0] - a[..., 0]))
            changed = ((active & (side >= 0)) | (~active & s_valid & (side < 0))) & s_valid
            if not changed.any():
                break  # prev and nxt are this hull's
            # drop reflex corners first; add outside slots only when no corner is reflex
            drop = active & changed
            active = active & ~drop if drop.any() else active | changed
        else:
            prev, nxt = hull_neighbours(active)
        back = np.argsort(order, axis=1)                # sorted position of each rest slot
        active = active[rows, back]
        prev, nxt = order[rows, prev][rows, back], order[rows, nxt][rows, back]
        self._active = active
        edge = xyz[rows, nxt] - xyz                     # to the next hull corner
        length = np.where(active, norms(edge), 0.0)
        return length.sum(axis=1), active, prev, nxt, edge, length

    def forces(self, pos: np.ndarray, rot: np.ndarray, vel: np.ndarray,
               omega: np.ndarray, t_s: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Force and torque (about each body's centre) the wrap applies, (n_bodies, 3) each.

        `pos`, `rot`, `vel`, `omega`: state of every body (pallet first), in the sled frame;
        `t_s`: time from the pulse's start, for when each place peaks (None: not timed).
        """
        nb = self.node_body
        arm = np.einsum("nij,nj->ni", rot[nb], self.node_local)
        p = pos[nb] + arm
        v = vel[nb] + cross(omega[nb], arm)
        f = np.zeros_like(p)
        self._ring_forces(p, v, f, t_s)
        self._panel_forces(p, v, f, t_s)
        wrench = self._incidence @ np.hstack([f, cross(arm, f)])
        return wrench[:, :3], wrench[:, 3:]

    def _ring_forces(self, p: np.ndarray, v: np.ndarray, f: np.ndarray,
                     t_s: float | None) -> None:
        if not len(self._slots):
            return
        perimeter, active, prev, nxt, edge, length = self._ring_geometry(p)
        r = self.rings
        unit = edge / np.maximum(length, 1e-12)[..., None]
        rows = self._rows
        turn = unit - unit[rows, prev]                  # 2 sin(angle / 2) towards the inside
        if self.frozen:
            edge = self._edge_factors(turn, active)
            vs = v[self._slot_index]
            rate = np.where(active, np.einsum("rmk,rmk->rm", vs[rows, nxt] - vs, unit), 0).sum(1)
            tension = r.force(perimeter, rate, edge.max(axis=1, initial=1.0), t_s)
            self.ring_edge[r.rising] = edge[r.rising]
            tension = self._seam_step(tension, t_s)
        else:
            tension = np.where(r.torn | r.opened, 0.0, r.pretension_n * self.laid)
        # each hull corner is pulled towards both its neighbours
        pull = (turn * (tension[:, None, None] * active[..., None])).reshape(-1, 3)[
            self._node_slot]
        self._push = norms(pull)
        f += pull

    def _edge_factors(self, turn: np.ndarray, active: np.ndarray) -> np.ndarray:
        """Per ring slot, how much less tension the web bears where it turns round that edge
        (1 where it does not touch): the bending of its outer fibre, sharper the more it turns
        and the tighter it is pulled (`bend_curvature`), at the last step's tension."""
        m, r = self.wrap.material, self.rings
        angle = 2 * np.arcsin(np.clip(norms(turn[..., :2]) / 2, 0, 1))
        per_layer = r.last_n / self._ring_web_m
        kappa = bend_curvature(m, self.slot_radius, angle, per_layer[:, None])
        t = m.layer_thickness_m
        return np.where(active, bend_factor(m, t * kappa / (2 + t * kappa)), 1.0)

    def _seam_step(self, tension: np.ndarray, t_s: float | None) -> np.ndarray:
        """The tail's load this step; if it reaches the seam's strength, the rings it closes
        let go for the rest of the run."""
        if not len(self.seam) or self.rings.opened.any():
            return tension
        held = tension[self.seam] * self._seam_share
        utilisation = held / self._seam_bears
        k = int(np.argmax(utilisation))
        if utilisation[k] > self.seam_peak:
            self.seam_peak, self.seam_peak_force = min(float(utilisation[k]), 1.0), float(held[k])
            self.seam_peak_t = math.nan if t_s is None else t_s
        if utilisation[k] >= 1.0:
            self.rings.opened[self.seam] = True
            self.rings.last_n[self.seam] = 0.0
            tension = np.where(self.rings.opened, 0.0, tension)
        return tension

    def _panel_forces(self, p: np.ndarray, v: np.ndarray, f: np.ndarray,
                      t_s: float | None) -> None:
        nodes = self.panel_spec.nodes
        if not self.frozen or not len(nodes):
            return
        a, b = nodes[:, 0], nodes[:, 1]
        d = p[b] - p[a]
        length = norms(d)
        unit = d / np.maximum(length, 1e-12)[:, None]
        rate = np.einsum("ek,ek->e", v[b] - v[a], unit)
        if len(self.sliding):
            self._paper_law()
        tension = self.panels.force(length, rate, t_s=t_s)
        f += self._panel_to_node @ (unit * tension[:, None])

    def _paper_law(self) -> None:
        """Paper's layers do not cling: a panel's layers outside the one touching the load take
        their share only through friction on the layer beneath, where the rings press them on
        the corners; the panel's vertical part needs that friction (the corners' edges push its
        horizontal part through every layer). Up to that grip C the layers act together; past
        it they slip (permanently, as plastic stretch) and the inner layer takes the rest, so
        the panel bears one layer's breaking force plus C (all layers' at most)."""
        k, n = self.sliding, self.panel_spec.layers[self.sliding]
        stuck_yield, stuck_break, stuck_h, slip_h = self._stuck
        press = self._push * self._outer_press
        ends = self.panel_spec.nodes[k]
        normal = np.minimum(press[ends[:, 0]], press[ends[:, 1]])
        rise = np.maximum(self.panel_spec.rise[k], 1e-6)
        outer = (n - 1.0) / n
        grip = np.minimum(self.wrap.material.interlayer_mu * normal / rise, stuck_yield * outer)
        slips = grip / outer < stuck_yield
        p = self.panels
        p.yield_force_n[k] = np.minimum(stuck_yield, grip / outer)
        p.break_force_n[k] = np.minimum(stuck_break / n + grip, stuck_break)
        p.plastic_modulus_n_per_m[k] = np.where(slips, slip_h, stuck_h)

    def report(self) -> WrapReport:
        r, inner = self.rings, self.panels
        torn = np.concatenate([r.height_m[r.torn], inner.height_m[inner.torn]])
        plastic = np.concatenate([_strain(r), _strain(inner)])
        places = places_of(self)
        return WrapReport(
            torn_at_m=tuple(sorted({round(float(z), 4) for z in torn})),
            peak_utilisation=max((p.utilisation for p in places), default=0.0),
            plastic_strain_max=float(plastic.max()) if len(plastic) else 0.0,
            opened_at_m=tuple(round(float(z), 4) for z in r.height_m[r.opened]),
            places=places,
        )


def _strain(e: Elements) -> np.ndarray:
    """Permanent stretch of each element over its length (0 for a degenerate element)."""
    return np.divide(e.plastic_m, e.length_m, out=np.zeros_like(e.plastic_m), where=e.length_m > 0)

