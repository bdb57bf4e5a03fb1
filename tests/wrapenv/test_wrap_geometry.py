"""Where the wrap's rings run (wrapenv/wrap_geometry.py): round the convex hull of a layer, so
every bundle the web touches is held, whatever the layout."""

from __future__ import annotations

import numpy as np
import pytest

from wrapenv.load import LoadUnit
from wrapenv.wrap import WrapFormat
from wrapenv.wrap_geometry import ring_specs


def test_a_staggered_bundle_on_the_hull_but_off_the_bounding_box_is_on_the_ring():
    """Bundles at (-0.4, -0.25), (0.2, -0.15), (0.4, 0.25): the middle one's -y face lies
    0.1 m inside the layer's bounding box, yet its +x-y corner (0.34, -0.245) sticks out of the
    line from the first bundle's (-0.26, -0.345) to the third's (0.54, 0.155): the web bends
    round it."""
    unit = LoadUnit.from_dict({
        "pallet": {"preset": "EUR"}, "bundle": {"preset": "PET6x1.5L"},
        "stack": {"layers": 1, "pattern": "explicit",
                  "positions": [[-0.4, -0.25], [0.2, -0.15], [0.4, 0.25]]}})
    layout = unit.layout()
    wrap = WrapFormat.from_dict({"material": "kraft", "web_width_m": 0.5, "band": [
        {"from_m": 0.0, "to_m": 0.474, "layers": 1, "tension_n": 250.0}]},
        load_height_m=layout.load_height_m)
    ring = ring_specs(wrap, layout)[1]        # the layer's lower ring (ring 0 is the pallet's)
    assert sorted({body for body, _ in ring.slots}) == [1, 2, 3]
    assert any(np.allclose(xy, (0.34, -0.245)) for xy in ring.rest_xy)
    # without it the web would run straight from (-0.26, -0.345) to (0.54, 0.155), at x = 0.34
    # through y = -0.345 + 0.6 / 0.8 x 0.5 = 0.030: 0.275 m inside that corner
    a, b = np.array((-0.26, -0.345)), np.array((0.54, 0.155))
    assert a[1] + (0.34 - a[0]) / (b[0] - a[0]) * (b[1] - a[1]) == pytest.approx(0.030)
