"""What the wrap went through in one run: the most loaded places and the whole map.

A *place* is a part of the envelope a wrapping engineer can point at: a ring's face or corner
at a height, a corner vertical or a face's diagonals between two rings, the tail's seam. Its
utilisation is the highest force it carried over the run divided by what that place bears
before it tears (or, for the seam, lets go), the bending round the load's edge included: 1
means it tore.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from wrapenv.wrap_geometry import CORNER_NAMES, FACE_NAMES

if TYPE_CHECKING:
    from wrapenv.wrap_physics import WrapNet

#: How many places `WrapReport.critical` keeps, most loaded first.
CRITICAL_COUNT = 5


@dataclass(frozen=True)
class Place:
    """One place of the envelope and what it bore. `s0_m`..`s1_m` is its span round the load's
    outline (wrapenv.wrap_geometry; a corner has s0 = s1), `z0_m`..`z1_m` its height span (a
    ring has z0 = z1 = its height)."""

    element: str          # "ring" | "vertical" | "diagonals" | "seam"
    where: str            # "corner -x-y" | "face +x" | ... | "seam"
    height_m: float
    utilisation: float    # peak force / what the place bears, edge concentration included
    force_n: float        # the peak force
    t_s: float | None     # when it peaked, from the pulse's start (None: not timed)
    s0_m: float
    s1_m: float
    z0_m: float
    z1_m: float
    torn: bool = False
    opened: bool = False  # the seam let go and the rings it closes went slack

    def to_json(self) -> dict:
        out: dict = {"height_m": round(self.height_m, 4), "where": self.where,
                     "utilisation": round(self.utilisation, 4),
                     "t_s": None if self.t_s is None else round(self.t_s, 4),
                     "element": self.element, "force_n": round(self.force_n, 2)}
        if self.torn:
            out["torn"] = True
        if self.opened:
            out["opened"] = True
        return out


@dataclass(frozen=True)
class WrapReport:
    """What the wrap went through in one run."""

    torn_at_m: tuple[float, ...]     # heights of the elements that tore (empty: intact)
    peak_utilisation: float          # highest utilisation of any place
    plastic_strain_max: float        # largest permanent stretch left in an element
    #: Heights of the rings whose seam let go (empty: the tail held).
    opened_at_m: tuple[float, ...] = ()
    #: Every place of the envelope (the tension map's data), bottom up.
    places: tuple[Place, ...] = ()

    @property
    def torn(self) -> bool:
        return bool(self.torn_at_m)

    @property
    def opened(self) -> bool:
        return bool(self.opened_at_m)

    @property
    def critical(self) -> tuple[Place, ...]:
        """The most loaded places, most loaded first (ties: the lower place first)."""
        ranked = sorted(self.places, key=lambda p: (-p.utilisation, p.height_m, p.where))
        return tuple(ranked[:CRITICAL_COUNT])

    def to_json(self) -> dict:
        return {
            "torn": self.torn,
            "torn_at_m": [round(z, 4) for z in self.torn_at_m],
            "opened": self.opened,
            "opened_at_m": [round(z, 4) for z in self.opened_at_m],
            "peak_utilisation": round(self.peak_utilisation, 4),
            "plastic_strain_max": round(self.plastic_strain_max, 6),
            "critical": [p.to_json() for p in self.critical],
        }


def _timed(t: float) -> float | None:
    """A peak's time for the report (NaN, never timed, is None)."""
    return None if math.isnan(t) else float(t)


def places_of(net: WrapNet) -> tuple[Place, ...]:
    """Every place of a net after a run: each ring's four corners and four faces, each pair of
    rings' corner verticals and face diagonals, and the seam."""
    return (*_ring_places(net), *_panel_places(net), *_seam_places(net))


def _ring_places(net: WrapNet) -> list[Place]:
    """A ring carries one tension; where its web turned round an edge at its peak, that place
    bore less (the bending there), so a ring's corners are usually its most loaded places."""
    r, s = net.rings, net.outline_s_m
    out = []
    for i, spec in enumerate(net.ring_specs):
        force, bears = float(r.peak_force_n[i]), float(r.break_force_n[i])
        for f in range(4):
            corner = spec.corner_slots[f]
            face = [j for j, where in enumerate(spec.places) if where == FACE_NAMES[f]]
            spots = (([corner], CORNER_NAMES[f], (s[f], s[f])),
                     (face, FACE_NAMES[f], (s[f], s[f + 1])))
            for slots, where, span in spots:
                edge = max((float(net.ring_edge[i, j]) for j in slots), default=1.0)
                use = min(force * edge / bears, 1.0)
                out.append(Place("ring", where, spec.z_m, use, force, _timed(r.peak_t_s[i]),
                                 *span, spec.z_m, spec.z_m,
                                 torn=bool(r.torn[i]) and use >= 1.0 - 1e-9,
                                 opened=bool(r.opened[i])))
    return out


def _panel_places(net: WrapNet) -> list[Place]:
    """Per pair of rings: a vertical at each corner and the two diagonals of each face as
    one place, the more loaded diagonal speaking."""
    spec, inner = net.panel_spec, net.panels
    use, force, when = inner.peak, inner.peak_force_n, inner.peak_t_s
    groups: dict[tuple[int, int, str], list[int]] = {}
    for e, where in enumerate(spec.where):
        lo, hi = (int(k) for k in spec.rings[e])
        groups.setdefault((lo, hi, where), []).append(e)
    out = []
    for (lo, hi, where), members in groups.items():
        e = max(members, key=lambda k: float(use[k]))
        s0, s1 = (float(x) for x in spec.s_m[e])
        z0, z1 = float(net.ring_heights[lo]), float(net.ring_heights[hi])
        element = "vertical" if where.startswith("corner") else "diagonals"
        out.append(Place(element, where, float(spec.height_m[e]), float(use[e]),
                         float(force[e]), _timed(float(when[e])), s0, s1, z0, z1,
                         torn=bool(np.any(inner.torn[members]))))
    return out


def _seam_places(net: WrapNet) -> list[Place]:
    """The tail's joint, across the whole perimeter at the rings it closes."""
    if not len(net.seam):
        return []
    z = net.ring_heights[net.seam]
    return [Place("seam", "seam", float(z.mean()), net.seam_peak, net.seam_peak_force,
                  _timed(net.seam_peak_t), 0.0, net.outline_s_m[-1], float(z.min()),
                  float(z.max()), opened=bool(net.rings.opened[net.seam].any()))]
