"""A spiral wrapper's program and the web it really lays.

A spiral (rotary-arm or turntable) wrapper lays a web of fixed width round the load while its
carriage moves up and down. Its program runs in order: bottom wraps with the carriage parked low,
a spiral up at some overlap (stopping for reinforcement wraps at chosen heights), top wraps
parked high with the web's upper edge above the load, and maybe a spiral back down. Every
revolution lays a full web width; nothing narrower exists but a rope of film.

A program becomes `Pass`es (what the carriage does: parked or travelling, for how many turns, at
which web tension). Passes give the two things the rest of the product needs:

* the **layer map** the physics uses, as `Band`s: a parked pass lays its turns over one web
  width; a travelling pass lays a helix whose layers, averaged round the load, rise linearly
  over one web width, hold ``web / rise`` layers (an overlap of 50 % gives two) and fall again;
  web above the load's top folds over its edge (material, but no hoop);
* the **material used** (every revolution's length round the pallet below its top and round the
  load's outline above it, a travelling turn's rise included, times the web width) and the
  **cycle time** (turns at the turntable's speed, travel at the carriage's).

Heights are from the sled surface (the underside of the pallet is z = 0). The web's position is
given by its lower edge, as a machine's carriage height is.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

#: Lengths and turn counts below this are rounding, not web.
_FLAT = 1e-9


@dataclass(frozen=True)
class Band:
    """A height range wrapped with `layers` layers of web, each pulled at `tension_n`.

    `layers_to`, when given, is the layer count at `to_m`: the count then varies linearly from
    `layers` at `from_m` (the ends of a spiral, where the helix starts or stops). Counts are
    averaged round the load, so a program's bands may hold fractions of a layer.
    """

    from_m: float
    to_m: float
    layers: float
    tension_n: float
    layers_to: float | None = None

    @property
    def height_m(self) -> float:
        return self.to_m - self.from_m

    def layers_at(self, z: float) -> float:
        """Layer count at height z (the band covers [from_m, to_m))."""
        if not self.from_m <= z < self.to_m:
            return 0.0
        end = self.layers if self.layers_to is None else self.layers_to
        return self.layers + (end - self.layers) * (z - self.from_m) / self.height_m

    def layer_metres(self, z0: float, z1: float) -> float:
        """Metres of web (layers x height) this band lays inside [z0, z1]."""
        a, b = max(self.from_m, z0), min(self.to_m, z1)
        if b <= a:
            return 0.0
        end = self.layers if self.layers_to is None else self.layers_to
        slope = (end - self.layers) / self.height_m
        mean = self.layers + slope * ((a + b) / 2 - self.from_m)
        return mean * (b - a)

    def clipped(self, top_m: float) -> Band | None:
        """The part of the band below `top_m` (None if nothing is left)."""
        if self.from_m >= top_m:
            return None
        if self.to_m <= top_m:
            return self
        end = self.layers_at(top_m) if self.layers_to is not None else None
        return Band(self.from_m, top_m, self.layers, self.tension_n, end)


@dataclass(frozen=True)
class Reinforcement:
    """Extra revolutions with the carriage parked at a height (e.g. across a layer joint)."""

    from_m: float  # the web's lower edge
    wraps: int
    tension_n: float


@dataclass(frozen=True)
class Machine:
    """What the wrapper can do; defaults in docs/materials.md, section 4."""

    rpm: float = 12.0                 # turntable or arm speed, revolutions per minute [A]
    carriage_speed_mps: float = 0.1   # fastest carriage travel (6 m/min) [A]
    handling_s: float = 15.0          # pallet in and out, cut and seal the tail [A]
    #: The rotation's start from rest to its speed, and its stop: on a linear ramp each costs
    #: half its time against turning at speed throughout [A].
    ramp_s: float = 3.0

    def most_rise_m(self, rpm: float) -> float:
        """The most the carriage rises in one revolution at `rpm`."""
        return self.carriage_speed_mps * 60.0 / rpm


#: The top wraps' web reaches this far above the load and folds over its edge [A]: enough to
#: tie the top layer's corners without laying web into the air (a program's default).
TOP_OVERHANG_M = 0.05


def top_from_m(load_height_m: float, web_width_m: float,
               overhang_m: float = TOP_OVERHANG_M) -> float:
    """Where top wraps are laid (the web's lower edge): its upper edge `overhang_m` above the
    load, or the pallet's deck if the web is wider than that."""
    return max(0.0, load_height_m + overhang_m - web_width_m)


@dataclass(frozen=True, kw_only=True)
class Program:
    """A wrapping program as an operator enters it (CONTRACTS.md, WRAP.toml's [program]), in
    the order the machine runs it."""

    bottom_wraps: int
    bottom_from_m: float = 0.0
    bottom_tension_n: float
    up_overlap: float
    middle_tension_n: float
    top_wraps: int
    top_overhang_m: float = TOP_OVERHANG_M
    top_tension_n: float
    down_overlap: float | None = None
    rpm: float | None = None
    #: Film only: the bottom wraps are gathered into a rope (`ROPE_HEIGHT_M` tall).
    roping: bool = False
    #: Film only: pre-stretch as a fraction (2.5 = 250 %); None: the material card's own.
    prestretch: float | None = None
    reinforcements: tuple[Reinforcement, ...] = ()

    def top_from_m(self, web_width_m: float, load_height_m: float) -> float:
        """Where the top wraps are laid (the web's lower edge): its upper edge
        `top_overhang_m` above the load."""
        return top_from_m(load_height_m, web_width_m, self.top_overhang_m)

    def passes(self, web_width_m: float, load_height_m: float) -> tuple[Pass, ...]:
        """What the carriage does, in the order the machine runs the program."""
        w, b0 = web_width_m, self.bottom_from_m
        top = self.top_from_m(w, load_height_m)
        up = w * (1.0 - self.up_overlap)
        rope = ROPE_HEIGHT_M if self.roping else None
        out = [Pass("bottom", b0, b0, float(self.bottom_wraps), self.bottom_tension_n, rope)]
        here = b0
        for r in sorted(self.reinforcements, key=lambda r: r.from_m):
            out.append(_travel(here, r.from_m, up, self.middle_tension_n))
            out.append(Pass("reinforcement", r.from_m, r.from_m, float(r.wraps), r.tension_n))
            here = r.from_m
        out.append(_travel(here, top, up, self.middle_tension_n))
        out.append(Pass("top", top, top, float(self.top_wraps), self.top_tension_n))
        if self.down_overlap is not None:
            down = w * (1.0 - self.down_overlap)
            out.append(_travel(top, b0, down, self.middle_tension_n))
        return tuple(p for p in out if p.turns > _FLAT)


#: Height of the rope a film's bottom wraps are gathered into [A]: a 500 mm web rolled into a
#: cord of a few centimetres (Lantech's roping places it above the pallet's fork entries).
ROPE_HEIGHT_M = 0.03


@dataclass(frozen=True)
class Pass:
    """The carriage parked (`start_m == end_m`) or travelling for `turns` revolutions.

    `start_m` and `end_m` are the web's lower edge when the pass starts and ends; `rope_m`, when
    given, is the height of the rope the web is gathered into (film roping) instead of its width.
    """

    zone: str  # "bottom" | "spiral up" | "reinforcement" | "top" | "spiral down" | "band"
    start_m: float
    end_m: float
    turns: float
    tension_n: float
    rope_m: float | None = None

    @property
    def travel_m(self) -> float:
        return abs(self.end_m - self.start_m)

    @property
    def rise_m(self) -> float:
        """Carriage travel per revolution (0 when parked)."""
        return self.travel_m / self.turns if self.turns > 0 else 0.0

    def bands(self, web_width_m: float) -> tuple[Band, ...]:
        """The layers this pass lays, averaged round the load (see the module docstring)."""
        if self.travel_m == 0.0:
            height = self.rope_m if self.rope_m is not None else web_width_m
            layers = self.turns * web_width_m / height
            return (Band(self.start_m, self.start_m + height, layers, self.tension_n),)
        s0, s1 = sorted((self.start_m, self.end_m))
        a = min(self.travel_m, web_width_m)  # the ramps' length
        peak = a / self.rise_m               # layers where the helix is complete
        pieces = [Band(s0, s0 + a, 0.0, self.tension_n, peak)]
        if s1 + web_width_m - a > s0 + a + _FLAT:
            pieces.append(Band(s0 + a, s1 + web_width_m - a, peak, self.tension_n))
        pieces.append(Band(s1 + web_width_m - a, s1 + web_width_m, peak, self.tension_n, 0.0))
        return tuple(pieces)


def _travel(start_m: float, end_m: float, rise_m: float, tension_n: float) -> Pass:
    """A spiral from one carriage height to another, moving `rise_m` per revolution, up or
    down as the heights lie (a reinforcement may lie above the top wraps' height)."""
    zone = "spiral up" if end_m >= start_m else "spiral down"
    return Pass(zone, start_m, end_m, abs(end_m - start_m) / rise_m, tension_n)


def as_laid(passes: tuple[Pass, ...], rpm: float, machine: Machine) -> tuple[Pass, ...]:
    """The passes as the machine lays them at `rpm`. The turntable does not wait for the
    carriage: a spiral asking a rise per revolution the carriage cannot travel in one revolution
    turns more often, each turn rising what the carriage can, and lays that much more web."""
    most = machine.most_rise_m(rpm)
    return tuple(replace(p, turns=p.travel_m / most) if p.rise_m > most + _FLAT else p
                 for p in passes)


def layer_map(passes: tuple[Pass, ...], web_width_m: float, load_height_m: float
              ) -> tuple[Band, ...]:
    """The bands the passes lay on the load (web above its top folds over: no band there)."""
    out = []
    for p in passes:
        for band in p.bands(web_width_m):
            kept = band.clipped(load_height_m)
            if kept is not None and kept.height_m > _FLAT:
                out.append(kept)
    return tuple(out)


def band_passes(bands: tuple[Band, ...], web_width_m: float) -> tuple[Pass, ...]:
    """How a machine would lay a band form: every layer of a band takes full-width revolutions
    parked one web width apart from its lower edge, as many as its height needs."""
    out = []
    for b in sorted(bands, key=lambda b: (b.from_m, b.to_m)):
        stacks = max(1, math.ceil(b.height_m / web_width_m - 1e-9))
        for k in range(stacks):
            z = b.from_m + k * web_width_m
            out.append(Pass("band", z, z, float(math.ceil(b.layers - 1e-9)), b.tension_n))
    return tuple(out)


@dataclass(frozen=True)
class Outline:
    """Perimeters a revolution goes round: the pallet's below its top, the load's above."""

    pallet_top_m: float
    pallet_perimeter_m: float
    load_perimeter_m: float

    def web_area_m2(self, z0: float, z1: float) -> float:
        """Area of one revolution's web covering heights [z0, z1]: ∫ perimeter dz."""
        below = max(0.0, min(z1, self.pallet_top_m) - z0)
        above = max(0.0, z1 - max(z0, self.pallet_top_m))
        return below * self.pallet_perimeter_m + above * self.load_perimeter_m


def pass_area_m2(p: Pass, web_width_m: float, outline: Outline) -> float:
    """Web laid by one pass: each revolution's length times the web width.

    A rope is a full web gathered up: it goes round the perimeter at the rope's height. A
    travelling revolution is a helix, longer than the perimeter by sqrt(1 + (rise/perimeter)^2).
    """
    if p.turns <= 0:
        return 0.0
    if p.travel_m == 0.0:
        h = p.rope_m if p.rope_m is not None else web_width_m
        return p.turns * outline.web_area_m2(p.start_m, p.start_m + h) * web_width_m / h
    s0, s1 = sorted((p.start_m, p.end_m))
    # The area per turn, A(e) = area of one web whose lower edge is at e, is linear in e between
    # the heights where the web's edges cross the pallet's top: integrate piece by piece.
    cuts = sorted({s0, s1, *(c for c in (outline.pallet_top_m - web_width_m,
                                         outline.pallet_top_m) if s0 < c < s1)})
    total = 0.0
    for a, b in zip(cuts, cuts[1:], strict=False):
        area = (outline.web_area_m2(a, a + web_width_m)
                + outline.web_area_m2(b, b + web_width_m)) / 2
        perimeter = area / web_width_m
        helix = math.sqrt(1.0 + (p.rise_m / perimeter) ** 2)
        total += area * helix * (b - a)
    return total / p.rise_m


def cycle_time_s(passes: tuple[Pass, ...], home_m: float, rpm: float, machine: Machine) -> float:
    """Time from one pallet to the next: the passes (turns at `rpm`, a spiral no faster than
    the carriage can travel) in one rotation that starts and stops once (`ramp_s`), the
    carriage's return home at full speed, which runs while the wrapped pallet leaves and the
    next arrives (`handling_s`)."""
    revolution_s, speed = 60.0 / rpm, machine.carriage_speed_mps
    wrapping = sum(max(p.turns * revolution_s, p.travel_m / speed) for p in passes)
    wrapping += machine.ramp_s if passes else 0.0
    # between passes that do not join (a band form's stacks) the carriage moves at full speed
    wrapping += sum(abs(b.start_m - a.end_m) for a, b in zip(passes, passes[1:], strict=False)
                    ) / speed
    end = passes[-1].end_m if passes else home_m
    back = abs(end - home_m) / machine.carriage_speed_mps
    return wrapping + max(back, machine.handling_s)
