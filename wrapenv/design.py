"""The space of wrap formats a search or a policy chooses from, as a vector in [-1, 1]^8.

A wrapping machine's program has three zones (paper, section 3): a bottom zone that ties the load
to the pallet, a middle zone, and a top zone that closes the envelope. The vector holds, in this
order:

    0-2  layers of the bottom, middle and top band      -> 0 .. max_layers (rounded; the bottom
                                                           band, the anchor, has at least one)
    3    top of the bottom band                          -> pallet top + 0.05 m .. 45 % of the load
    4    bottom of the top band                          -> 55 % of the load .. top - 0.05 m
    5-7  web tension of the bottom, middle and top band -> 5 % .. 50 % of the web's yield force

The bottom band always starts at the sled surface (it wraps the pallet: the anchor) and the top
band always reaches the top of the load. Out-of-range values are clipped; NaN is an error.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from wrapenv.config import InputError
from wrapenv.load import Layout
from wrapenv.wrap import MATERIALS, Band, Material, WrapFormat

N_PARAMS = 8
WEB_WIDTH_M = 0.5
MAX_LAYERS = 6
#: Tension range as a fraction of one layer's yield force over the web width. Machines set the
#: tension at about half the limit because corners cause tension peaks (docs/materials.md, P4):
#: Kraft 80-800 N, LLDPE 9-94 N on a 0.5 m web (measured here: Kraft at 90 % tore on the bench).
TENSION_FRACTIONS = (0.05, 0.5)
BAND_MARGIN_M = 0.05
#: The reference a format's material is measured against: this many layers over the whole
#: height of the load (round the pallet below its top, round the load's outline above it).
REFERENCE_LAYERS = 3


@dataclass(frozen=True)
class FormatSpace:
    """Maps vectors in [-1, 1]^8 to wrap formats for one load unit and one material."""

    material_key: str
    load_height_m: float
    pallet_top_m: float
    max_layers: int = MAX_LAYERS
    web_width_m: float = WEB_WIDTH_M

    @classmethod
    def for_layout(cls, layout: Layout, material_key: str, **kwargs) -> FormatSpace:
        if material_key not in MATERIALS:
            raise InputError("arguments", "--material",
                             f"must be one of {', '.join(map(repr, MATERIALS))} "
                             f"(got {material_key!r})")
        return cls(material_key, layout.load_height_m, layout.pallet_size_m[2], **kwargs)

    @property
    def material(self) -> Material:
        return MATERIALS[self.material_key]

    @property
    def tension_range_n(self) -> tuple[float, float]:
        limit = self.material.yield_force_n_per_m * self.web_width_m
        return TENSION_FRACTIONS[0] * limit, TENSION_FRACTIONS[1] * limit

    def reference_mass_kg(self, layout: Layout) -> float:
        """Material of `REFERENCE_LAYERS` layers over the whole height of this unit."""
        full = WrapFormat(self.material, self.web_width_m,
                          (Band(0.0, layout.load_height_m, REFERENCE_LAYERS, 1.0),),
                          self.material_key)
        return full.material_used_on(layout).mass_kg

    def _bounds(self) -> tuple[tuple[float, float], tuple[float, float]]:
        h = self.load_height_m
        low = (self.pallet_top_m + BAND_MARGIN_M, max(0.45 * h, self.pallet_top_m + 0.1))
        high = (min(0.55 * h, h - 0.1), h - BAND_MARGIN_M)
        return low, high

    def decode(self, action: np.ndarray) -> WrapFormat:
        """The wrap format of a vector (clipped to [-1, 1]; NaN raises `ValueError`)."""
        a = np.asarray(action, dtype=float).reshape(-1)
        if a.shape != (N_PARAMS,):
            raise ValueError(f"a wrap format vector has {N_PARAMS} values, got {a.shape[0]}")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"a wrap format vector must be finite, got {a.tolist()}")
        u = (np.clip(a, -1.0, 1.0) + 1.0) / 2.0          # 0 .. 1
        layers = [round(float(x) * self.max_layers) for x in u[:3]]
        layers[0] = max(layers[0], 1)
        (lo0, lo1), (hi0, hi1) = self._bounds()
        bottom_top = lo0 + u[3] * (lo1 - lo0)
        top_bottom = hi0 + u[4] * (hi1 - hi0)
        t0, t1 = self.tension_range_n
        tension = [t0 + float(x) * (t1 - t0) for x in u[5:]]
        h = self.load_height_m
        spans = ((0.0, bottom_top), (bottom_top, top_bottom), (top_bottom, h))
        bands = tuple(Band(round(float(a_), 4), round(float(b_), 4), n, round(t, 1))
                      for (a_, b_), n, t in zip(spans, layers, tension, strict=True) if n > 0)
        return WrapFormat(self.material, self.web_width_m, bands, self.material_key)

    def encode(self, wrap: WrapFormat) -> np.ndarray:
        """A vector that decodes to (nearly) this three-band format: a search's starting point."""
        bottom, *rest = sorted(wrap.bands, key=lambda b: b.from_m)
        top = rest[-1] if rest and rest[-1].to_m >= self.load_height_m - 1e-6 else None
        middle = rest[0] if rest and rest[0] is not top else None
        (lo0, lo1), (hi0, hi1) = self._bounds()
        t0, t1 = self.tension_range_n
        u = [
            bottom.layers / self.max_layers,
            (middle.layers if middle else 0) / self.max_layers,
            (top.layers if top else 0) / self.max_layers,
            _frac(bottom.to_m, lo0, lo1),
            _frac(top.from_m if top else hi1, hi0, hi1),
            *(_frac(b.tension_n, t0, t1) for b in (bottom, middle or bottom, top or bottom)),
        ]
        return np.clip(2 * np.array(u) - 1, -1, 1)


def _frac(x: float, lo: float, hi: float) -> float:
    return 0.5 if math.isclose(hi, lo) else (x - lo) / (hi - lo)
