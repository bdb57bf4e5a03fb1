"""The bench described once: every body by name, with its box, pose, mass, friction and colour.

The bench (`wrapenv.bench`), the renderer (`wrapenv.render`) and synthetic recordings
(`calibration.filming`, `calibration.synth`) build their worlds from one `BenchScene`, so the
sled's deck, the stopper's offset and the colours exist in one place. Bodies are named:
"sled", "stopper", "pallet" and the bundles' names (`L{layer}C{col}R{row}`, `wrapenv.load`).

Two numberings follow from the scene, and only this module says how they relate:
- world indices, the order in which bodies are added to a Bullet world (`BenchScene.index`):
  the sled, the pallet, the bundles in layout order, then the stopper if there is one;
- state indices, the rows of the state arrays of the moving bodies (positions, rotations,
  velocities: `Trace`, `WrapNet`, `Rest`): the pallet (`PALLET`), then the bundles (`BUNDLES`)
  in layout order; `BenchScene.moving` gives each row's world index.
A body that takes the friction coefficient of another (the stopper bar is part of the sled)
names it in `Body.friction_of`; every other body has a coefficient of its own, and those bodies
come first in world order, so a coefficient array (`wrapenv.friction.StickSlip`) is indexed
by world index and `BenchScene.parts` maps every body to its coefficient.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wrapenv.load import Layout

SLED_MARGIN_M = 2.0          # sled deck beyond the pallet on every side
SLED_DECK_M = 0.1            # thickness of the sled deck (its top is z = 0)
STOPPER_SIZE_M = (0.05, 0.08)  # pallet stopper bar: thickness along x, height
#: A bundle starts this far per layer above where it stands stacked (`Body.start_centre_m`).
START_LIFT_M = 1e-4

SLED, STOPPER, PALLET_NAME = "sled", "stopper", "pallet"
#: State arrays hold the pallet's row, then the bundles' rows in layout order.
PALLET = 0
BUNDLES = slice(1, None)


def bundle_row(k: int) -> int:
    """Row of the layout's bundle k in the state arrays."""
    return int(BUNDLES.start) + k

SLED_RGBA = (0.35, 0.35, 0.4, 1.0)
STOPPER_RGBA = (0.2, 0.2, 0.2, 1.0)
PALLET_RGBA = (0.76, 0.6, 0.4, 1.0)
#: Two blues in a checkerboard (column + layer): side by side, one colour would merge the fronts
#: of a row of bundles into one block.
BUNDLE_RGBA = ((0.2, 0.45, 0.8, 1.0), (0.33, 0.6, 0.92, 1.0))


@dataclass(frozen=True)
class Body:
    """One box of the bench, upright, as the unit stands stacked before a test."""

    name: str
    size_m: tuple[float, float, float]
    centre_m: tuple[float, float, float]
    mass_kg: float  # 0: static (the sled and its stopper move with the sled's frame)
    #: The body whose friction coefficient this one takes (itself, or the sled for the stopper).
    friction_of: str
    rgba: tuple[float, float, float, float]
    layer: int = 0  # a bundle's layer (1 = bottom); 0 for the others

    @property
    def moving(self) -> bool:
        return self.mass_kg > 0

    @property
    def start_centre_m(self) -> tuple[float, float, float]:
        """Where a simulation adds the body: a bundle a hair (0.1 mm per layer) above the layer
        below, so nothing starts overlapping; settling closes the gap."""
        x, y, z = self.centre_m
        return x, y, z + START_LIFT_M * self.layer


class BenchScene:
    """The bodies of a layout on the bench, in world order, and the maps between numberings."""

    def __init__(self, layout: Layout) -> None:
        self.layout = layout
        self.bodies: tuple[Body, ...] = tuple(_bodies(layout))
        self._index = {b.name: i for i, b in enumerate(self.bodies)}
        if len(self._index) != len(self.bodies):
            raise ValueError("two bodies of the bench share a name")
        #: World index of each state row (pallet, then bundles).
        self.moving = np.array([i for i, b in enumerate(self.bodies) if b.moving], dtype=int)
        #: For each body, the world index of the body whose friction coefficient it takes.
        self.parts = np.array([self._index[b.friction_of] for b in self.bodies], dtype=int)
        #: How many bodies have a friction coefficient of their own (they come first).
        self.n_parts = int(np.sum(self.parts == np.arange(len(self.bodies))))
        assert np.all(self.parts < self.n_parts), "bodies with own friction come first"
        self._state = {self.bodies[w].name: s for s, w in enumerate(self.moving.tolist())}

    def index(self, name: str) -> int:
        """World index of the body called `name`."""
        try:
            return self._index[name]
        except KeyError:
            raise ValueError(f"the bench has no body {name!r}") from None

    def state_index(self, name: str) -> int:
        """Row of the moving body `name` in the state arrays."""
        try:
            return self._state[name]
        except KeyError:
            raise ValueError(f"the bench has no moving body {name!r}") from None

    def body(self, name: str) -> Body:
        return self.bodies[self.index(name)]


def _bodies(layout: Layout) -> list[Body]:
    """Sled deck, pallet, bundles and stopper, in world order."""
    px, py, pz = layout.pallet_size_m
    deck = (px + 2 * SLED_MARGIN_M, py + 2 * SLED_MARGIN_M, SLED_DECK_M)
    out = [Body(SLED, deck, (0.0, 0.0, -SLED_DECK_M / 2), 0.0, SLED, SLED_RGBA),
           Body(PALLET_NAME, (px, py, pz), (0.0, 0.0, pz / 2), layout.pallet_mass_kg,
                PALLET_NAME, PALLET_RGBA)]
    columns: dict[int, list[float]] = {}
    for b in layout.bundles:
        columns.setdefault(b.layer, []).append(round(b.centre_m[0], 4))
    for b in layout.bundles:
        column = sorted(set(columns[b.layer])).index(round(b.centre_m[0], 4))
        out.append(Body(b.name, b.size_m, b.centre_m, b.mass_kg, b.name,
                        BUNDLE_RGBA[(column + b.layer) % 2], b.layer))
    if layout.pallet_stopper:
        t, h = STOPPER_SIZE_M
        out.append(Body(STOPPER, (t, py, h), (-px / 2 - t / 2, 0.0, h / 2), 0.0,
                        SLED, STOPPER_RGBA))
    return out
