"""The space of wrapping programs a search or a policy chooses from.

A program (wrapenv.program) mixes whole numbers of wraps with continuous settings. The space
names each parameter and its range. A search works on the values themselves (the wraps are
integer variables, for pycma's integer handling); a policy acts in [-1, 1]^9, which `decode`
maps linearly onto the ranges, rounding the wraps.

    index  parameter              range
    0      bottom_wraps           1 .. 6 revolutions parked low, the web's lower edge
                                  `ONTO_PALLET_M` below the pallet's top (whole)
    1      top_wraps              1 .. 6 revolutions parked high (whole)
    2      reinforcement_wraps    0 .. 4 revolutions parked at index 4's height (whole; 0: none)
    3      up_overlap             0 .. 0.75 of the web: a spiral of 1 to 4 layers (from what the
                                  carriage can rise a revolution, `min_overlap`)
    4      reinforcement_from_m   the bottom wraps' height .. load top - web width: where the
                                  reinforcement's web starts
    5-8    tension of the bottom, middle (spiral), top and reinforcement wraps: 5 % .. 50 % of
           one layer's yield force (machines keep about half the limit for the corners, P4)

Fixed for every program of the space: at least one bottom wrap, its web a few cm onto the pallet
(`ONTO_PALLET_M`: over the deck, clear of the fork entries, which forks would tear the web at
before the unit reaches the bench). It ties the pallet to the load and holds the web's head: the
machine's clamp lets the head go after the first revolution, and paper does not cling, so only a
revolution laid over the head keeps the web anchored (without it a search found 0.7 of a
revolution "holding" a 323 kg unit, the web never closing round it). At least one top wrap,
whose web ends `TOP_OVERHANG_M` above the load and folds over: with a bottom and a top wrap the
web closes round the load at every height (a spiral lays at least one layer where its helix is
complete, and its ends lie under the parked wraps), so no part of the load is held by part of a
turn, which the bench would average round the load (`wrapenv.program`) although it presses on
some faces only. No spiral down (a higher overlap lays the same layers in one pass); the web
(its card and width) and the machine's speeds, which are the space's `Web`: a named card on the
0.5 m web and the default machine, or those of a WRAP.toml (`Web.from_toml`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from wrapenv.load import Layout
from wrapenv.material import Material
from wrapenv.program import TOP_OVERHANG_M, Program, Reinforcement, top_from_m
from wrapenv.wrap import Web, WrapFormat

MAX_WRAPS = 6
#: A program's first revolution is parked: it holds the web's head; with a top wrap too, the
#: web closes round the load at every height (see the module docstring).
MIN_BOTTOM_WRAPS = 1
MIN_TOP_WRAPS = 1
MAX_REINFORCEMENT_WRAPS = 4
MAX_OVERLAP = 0.75
#: The bottom wraps' web reaches this far down onto the pallet [A]: "a few cm onto the pallet"
#: (docs/materials.md [30]); on a EUR pallet its deck, 22 mm boards on 22 mm cross boards
#: ([40]), above the fork entries (the top 44 mm of its 144).
ONTO_PALLET_M = 0.044
#: A program is given as an operator types it into a machine's panel: tensions in whole
#: newtons, overlaps in whole percent, carriage heights in millimetres (decimal places kept).
TENSION_DECIMALS, OVERLAP_DECIMALS, HEIGHT_DECIMALS = 0, 2, 3
#: Tension range as a fraction of one layer's yield force over the web width. Machines set the
#: tension at about half the limit because corners cause tension peaks (docs/materials.md, P4):
#: Kraft 80-800 N, LLDPE 9-94 N on a 0.5 m web (measured here: Kraft at 90 % tore on the bench).
TENSION_FRACTIONS = (0.05, 0.5)
NAMES = ("bottom_wraps", "top_wraps", "reinforcement_wraps", "up_overlap",
         "reinforcement_from_m", "bottom_tension_n", "middle_tension_n", "top_tension_n",
         "reinforcement_tension_n")
INTEGER_INDICES = (0, 1, 2)
TENSION_INDICES = (5, 6, 7, 8)
N_PARAMS = len(NAMES)


@dataclass(frozen=True)
class ProgramSpace:
    """Programs for one load unit and one web (a card, its width, the machine), as vectors of
    `NAMES` values."""

    web: Web
    load_height_m: float
    #: The bottom wraps' web's lower edge (`bottom_from_m`, see `for_layout`).
    bottom_from_m: float

    @classmethod
    def for_layout(cls, layout: Layout, web: Web | str) -> ProgramSpace:
        """The space of a unit for a web, or for a named card on the default web. The bottom
        wraps' web starts `ONTO_PALLET_M` below the pallet's top, or lower where the top wraps'
        web (`TOP_OVERHANG_M` above the load) does: on a unit lower than the web is wide, both
        are parked at one height and the carriage never travels down."""
        w = Web.named(web) if isinstance(web, str) else web
        h = layout.load_height_m
        onto_pallet_m = max(0.0, layout.pallet_size_m[2] - ONTO_PALLET_M)
        return cls(w, h, round(min(onto_pallet_m, top_from_m(h, w.width_m)), HEIGHT_DECIMALS))

    @property
    def material(self) -> Material:
        return self.web.material

    @property
    def material_key(self) -> str:
        return self.web.material_key

    @property
    def web_width_m(self) -> float:
        return self.web.width_m

    @property
    def tension_range_n(self) -> tuple[float, float]:
        limit = self.material.yield_force_n_per_m * self.web_width_m
        return TENSION_FRACTIONS[0] * limit, TENSION_FRACTIONS[1] * limit

    @property
    def min_overlap(self) -> float:
        """The least overlap the machine lays: at its rpm the carriage rises at most
        `Machine.most_rise_m` a revolution (`wrapenv.program.as_laid`); whole percent, rounded
        up."""
        m = self.web.machine
        least = math.ceil(100.0 * (1.0 - m.most_rise_m(m.rpm) / self.web_width_m) - 1e-9) / 100.0
        return min(max(0.0, least), MAX_OVERLAP)

    @property
    def low(self) -> np.ndarray:
        t0, _ = self.tension_range_n
        return np.array([MIN_BOTTOM_WRAPS, MIN_TOP_WRAPS, 0, self.min_overlap,
                         self.bottom_from_m, t0, t0, t0, t0])

    @property
    def high(self) -> np.ndarray:
        _, t1 = self.tension_range_n
        reach = max(self.bottom_from_m, self.load_height_m - self.web_width_m)
        return np.array([MAX_WRAPS, MAX_WRAPS, MAX_REINFORCEMENT_WRAPS, MAX_OVERLAP, reach,
                         t1, t1, t1, t1])

    def program(self, values: np.ndarray) -> Program:
        """The program of a vector of values (clipped to the ranges, rounded to what a machine's
        panel takes: whole wraps and newtons, whole percent of overlap, millimetres)."""
        v = np.clip(_finite(values), self.low, self.high)
        wraps = [int(round(float(x))) for x in v[list(INTEGER_INDICES)]]
        tension = [round(float(x), TENSION_DECIMALS) for x in v[list(TENSION_INDICES)]]
        reinforcement = (Reinforcement(round(float(v[4]), HEIGHT_DECIMALS), wraps[2], tension[3]),
                         ) if wraps[2] else ()
        return Program(
            bottom_wraps=wraps[0], bottom_from_m=self.bottom_from_m, bottom_tension_n=tension[0],
            up_overlap=round(float(v[3]), OVERLAP_DECIMALS), middle_tension_n=tension[1],
            top_wraps=wraps[1], top_overhang_m=TOP_OVERHANG_M,
            top_tension_n=tension[2], reinforcements=reinforcement,
            prestretch=self.material.prestretch,  # film: the panel's setting, written out
        )

    def wrap(self, values: np.ndarray) -> WrapFormat:
        """The wrap a vector of values lays on this unit."""
        return self.laid(self.program(values))

    def laid(self, program: Program) -> WrapFormat:
        return WrapFormat.from_program(self.material, self.web_width_m, program,
                                       self.load_height_m, self.material_key, self.web.machine)

    def decode(self, action: np.ndarray) -> WrapFormat:
        """The wrap of a policy's action in [-1, 1]^9 (clipped; NaN raises `ValueError`)."""
        a = np.clip(_finite(action), -1.0, 1.0)
        return self.wrap(self.low + (a + 1.0) / 2.0 * (self.high - self.low))

    def values(self, program: Program) -> np.ndarray:
        """The vector of a program of this space (a search's starting point)."""
        r = program.reinforcements[0] if program.reinforcements else None
        t0, _ = self.tension_range_n
        return np.array([program.bottom_wraps, program.top_wraps, r.wraps if r else 0,
                         program.up_overlap, r.from_m if r else 0.0,
                         program.bottom_tension_n, program.middle_tension_n,
                         program.top_tension_n, r.tension_n if r else t0], float)

    def machine_default(self) -> Program:
        """What a wrapper does out of the box: 3 bottom wraps (from the space's bottom height), a
        spiral up at 50 % overlap, 3 top wraps, every tension at half the web's yield force."""
        half = self.material.yield_force_n_per_m * self.web_width_m / 2
        return Program(bottom_wraps=3, bottom_from_m=self.bottom_from_m, bottom_tension_n=half,
                       up_overlap=0.5,
                       middle_tension_n=half, top_wraps=3, top_overhang_m=TOP_OVERHANG_M,
                       top_tension_n=half)

    def reference_mass_kg(self, layout: Layout) -> float:
        """Web of the machine's default program on this unit: what material is measured by."""
        return self.laid(self.machine_default()).material_used_on(layout).mass_kg


def _finite(vector: np.ndarray) -> np.ndarray:
    v = np.asarray(vector, dtype=float)
    if v.shape != (N_PARAMS,):
        raise ValueError(f"a program vector has {N_PARAMS} values in one row, got shape "
                         f"{v.shape}")
    if not np.all(np.isfinite(v)):
        raise ValueError(f"a program vector must be finite, got {v.tolist()}")
    return v
