"""Pixels <-> world metres and the region of interest predicted from the sled profile.

The camera is fixed while the load rides the sled metres across the image, so the paper's trick
is to predict where the unit is from the measured sled position instead of searching the frame:
everything on the sled is displaced by px_per_m * (sled x(t) - sled x(t0)) pixels along u.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wrapenv.load import Layout
from wrapenv.scene import SLED_DECK_M

#: Margin of the region of interest around the unit: bundles slide and tip within it.
ROI_MARGIN_M = 0.25


@dataclass(frozen=True)
class PixelMap:
    """CONTRACTS.md's orthographic camera: u = u0 + s x, v = v0 - s z."""

    px_per_m: float
    u0: float
    v0: float

    def to_px(self, x_m: np.ndarray | float, z_m: np.ndarray | float) -> tuple:
        return self.u0 + self.px_per_m * np.asarray(x_m), self.v0 - self.px_per_m * np.asarray(z_m)

    def to_world(self, u: np.ndarray | float, v: np.ndarray | float) -> tuple:
        return (np.asarray(u) - self.u0) / self.px_per_m, (self.v0 - np.asarray(v)) / self.px_per_m


@dataclass(frozen=True)
class Box:
    """An axis-aligned pixel rectangle, integer corners, [x0, x1) x [y0, y1)."""

    x0: int
    y0: int
    x1: int
    y1: int

    @property
    def width(self) -> int:
        return self.x1 - self.x0

    @property
    def height(self) -> int:
        return self.y1 - self.y0

    @property
    def empty(self) -> bool:
        return self.width <= 0 or self.height <= 0

    def clip(self, width: int, height: int) -> Box:
        return Box(max(self.x0, 0), max(self.y0, 0), min(self.x1, width), min(self.y1, height))

    def grow(self, px: int) -> Box:
        return Box(self.x0 - px, self.y0 - px, self.x1 + px, self.y1 + px)

    def shift(self, du: float) -> Box:
        d = int(round(du))
        return Box(self.x0 + d, self.y0, self.x1 + d, self.y1)

    @classmethod
    def around(cls, u: float, v: float, width: float, height: float) -> Box:
        """The box of a (width x height) rectangle centred on (u, v), rounded outwards."""
        return cls(int(np.floor(u - width / 2)), int(np.floor(v - height / 2)),
                   int(np.ceil(u + width / 2)) + 1, int(np.ceil(v + height / 2)) + 1)


def unit_extent_m(layout: Layout, extra_x_m: tuple[float, ...] = ()
                  ) -> tuple[float, float, float, float]:
    """(x_min, x_max, z_min, z_max) in the sled frame of the unit at rest plus the deck's face
    (as far along it as `extra_x_m`, e.g. to the sled's markers)."""
    px, _, pz = layout.pallet_size_m
    xs = [-px / 2, px / 2, *extra_x_m] + [b.centre_m[0] + s * b.size_m[0] / 2
                                          for b in layout.bundles for s in (-1, 1)]
    return min(xs), max(xs), -SLED_DECK_M, max(pz, layout.load_height_m)


def predict_roi(pixmap: PixelMap, extent_m: tuple[float, float, float, float], sled_x_m: float,
                frame_size: tuple[int, int], margin_m: float) -> Box:
    """Where the unit is in a frame, `margin_m` around it, clipped; `extent_m` is
    `unit_extent_m`'s (computed once per recording, not per frame)."""
    x0, x1, z0, z1 = extent_m
    u0, v1 = pixmap.to_px(x0 + sled_x_m - margin_m, z0 - margin_m)
    u1, v0 = pixmap.to_px(x1 + sled_x_m + margin_m, z1 + margin_m)
    box = Box(int(np.floor(u0)), int(np.floor(v0)), int(np.ceil(u1)) + 1, int(np.ceil(v1)) + 1)
    return box.clip(*frame_size)
