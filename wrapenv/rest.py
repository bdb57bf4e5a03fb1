"""Rest under a steady load: when a level may end, and which steps cannot change anything.

A unit at rest relative to the sled, every bundle flat on one of its faces, while the sled's
acceleration stays constant and below what could make any body slide or tip on its own
(`quiet_accel_mps2`), is in stable static equilibrium: contact and friction forces balance
gravity, the steady inertial field and the wrap, whose forces depend only on the poses, which
do not change; and no slow instability can be under way (a box just past its tipping level
starts to tip imperceptibly, a leaning one may slide down, so neither counts). Nothing can
change until the load does: the next change of acceleration, for the bench pulse the stop that
ends the constant, gentle deceleration after the dwell (most of a level's time). A run may
therefore record the resting state for the steps in between without simulating them and go on
from the change, whose effect (the deceleration let go at the stop) it simulates as always.
Left out is the solver's creep of a resting stack, which a run taken step by step shows as
jitter-driven drift of a squeezed stack (tests/wrapenv/test_bench_skip.py bounds what it
changes). A push is a load of its own: nothing is skipped while it acts.
"""

from __future__ import annotations

import math

import numpy as np

from wrapenv.load import Layout
from wrapenv.profile import G
from wrapenv.scene import BUNDLES

#: A bundle with none of its axes this close to vertical leans on something, where no tipping
#: or friction level holds; a box lying flat on any face stands at least as firmly as upright.
FLAT_RAD = math.radians(2.0)


def quiet_accel_mps2(layout: Layout) -> float:
    """The sled acceleration below which no body of the unit could start to slide or tip on
    its own: g times the lowest static friction coefficient of a pair that bears a body, and the
    lowest width-to-height ratio of a bundle with everything above it (a column tips as one),
    or of the whole load on its pallet."""
    f = layout.friction
    top = layout.load_height_m
    ratios = [min(b.size_m[:2]) / (top - (b.centre_m[2] - b.size_m[2] / 2))
              for b in layout.bundles]
    ratios.append(min(layout.pallet_size_m[:2]) / top)
    mu = [f.sled_pallet.static, f.pallet_bundle.static]
    if any(b.layer > 1 for b in layout.bundles):
        mu.append(f.bundle_bundle.static)
    return G * min(*mu, *ratios)


class Rest:
    """Follows rest through a run: since which step the bodies have stayed where they were,
    under the same load.

    `accel` is the sled's acceleration at every step; `push_until` (if given) the step at
    which a push on a bundle ends, another change of load.
    """

    def __init__(self, layout: Layout, accel: np.ndarray, drift_m: float,
                 push_until: int | None = None) -> None:
        self.accel, self.drift_m = accel, drift_m
        changes = {0, len(accel)} | set((np.flatnonzero(np.diff(accel) != 0) + 1).tolist())
        if push_until is not None:
            changes.add(push_until)
        #: Steps at which the load changes (0 first, and a sentinel past the end).
        self.changes = np.array(sorted(changes))
        self.push_until = push_until or 0
        self.quiet_mps2 = quiet_accel_mps2(layout)
        self.since: int | None = None  # first step of the current rest under a steady load
        self.pose = (np.empty(0), np.empty(0))  # poses at `since`

    def observe(self, step: int, pos: np.ndarray, rot: np.ndarray) -> int:
        """Take the poses at `step`; returns the first step of the rest they continue."""
        at = np.searchsorted(self.changes, step, "right")
        if self.since is not None and (self.since < self.changes[at - 1] or self._moved(pos, rot)):
            self.since = None
        if self.since is None:
            self.since, self.pose = step, (pos, rot)
        return self.since

    def unchanged_until(self, step: int, rot: np.ndarray, end: int) -> int:
        """For a unit at rest at `step` (`rot`: the state arrays' rotations), the last step up to
        which nothing can change, `end` at the latest: the step before the next change of
        load if this load is quiet and every bundle lies flat on a face, else `step` itself."""
        flat = bool(np.all(np.abs(rot[BUNDLES, 2, :]).max(axis=1) > math.cos(FLAT_RAD)))
        if not (abs(self.accel[step]) < self.quiet_mps2 and flat and step >= self.push_until):
            return step
        change = int(self.changes[np.searchsorted(self.changes, step, "right")])
        return min(change - 1, end)

    def quiet_between(self, start: int, stop: int) -> bool:
        """Whether every acceleration from `start` to `stop` is quiet."""
        return bool(np.abs(self.accel[start:stop]).max(initial=0.0) < self.quiet_mps2)

    def _moved(self, pos: np.ndarray, rot: np.ndarray) -> bool:
        """Whether a body left where it was when the rest began: by more than `drift_m`, or
        turned by ten times that in radians per metre (a bundle's edge moves about as far). A
        squeezed stack jitters at a few mm/s on the spot; what counts is where the bodies go,
        not how they shake."""
        ref_pos, ref_rot = self.pose
        return bool(np.abs(pos - ref_pos).max() > self.drift_m
                    or np.abs(rot - ref_rot).max() > 10 * self.drift_m)
