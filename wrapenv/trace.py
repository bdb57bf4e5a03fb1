"""What one simulated bench run records: poses of the pallet and of every bundle over time."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wrapenv.wrap_physics import WrapReport


@dataclass(frozen=True)
class Trace:
    """Poses in the sled frame, sampled from the start of the pulse (t = 0) until rest.

    The first sample is the reference state the displacements during the level are measured
    from (the stack as it rests on the still sled when the pulse starts). In a cumulative
    sequence (one unit through several levels) `origin_m` holds where the bundles stood when the
    unit was first put on the sled, for the displacements since then.
    """

    level_g: float
    load_height_m: float
    names: tuple[str, ...]
    bottom_z_m: np.ndarray      # (n,) height of each bundle's underside at rest
    t_s: np.ndarray             # (T,)
    sled_accel_mps2: np.ndarray  # (T,)
    pallet_pos_m: np.ndarray    # (T, 3)
    pallet_rot: np.ndarray      # (T, 3, 3) rotation matrices
    bundle_pos_m: np.ndarray    # (T, n, 3)
    bundle_rot: np.ndarray      # (T, n, 3, 3)
    valid: bool = True
    invalid_reason: str = ""
    wrap: WrapReport | None = None  # None: the unit was not wrapped
    #: Why the run stopped before rest, its verdict already decided failed ("": it ran to rest):
    #: `SimSettings.stop_when_decided`, or a body gone over the edge of the sled's deck.
    #: The figures of such a trace are those at the stop, not the permanent ones.
    stopped_early: str = ""
    #: Why the run ended with a body still moving ("": it ended at rest or stopped early): its
    #: permanent figures are those of its last poses, which may not be where it would rest.
    not_at_rest: str = ""
    #: Why the level is invalid if the solver failed ("": it did not): bodies left inside each
    #: other past the limit, or a blow-up; in a wrapped unit, a squeeze its iterations did not
    #: solve.
    unsolved: str = ""
    #: (n,) the layer of each bundle (1 at the bottom); None: all in one layer.
    layers: np.ndarray | None = None
    #: (n, 3) bundle centres in the pallet's frame when the unit was first put on the sled
    #: (None: at this level's first sample, a fresh unit).
    origin_m: np.ndarray | None = None

    def bundle_displacement_m(self) -> np.ndarray:
        """(T, n) horizontal displacement of each bundle centre in the pallet's frame."""
        rel = in_pallet_frame(self.pallet_pos_m, self.pallet_rot, self.bundle_pos_m)
        return np.linalg.norm((rel - rel[0])[..., :2], axis=-1)

    def permanent_total_m(self) -> np.ndarray:
        """(n,) horizontal displacement of each bundle centre in the pallet's frame from where
        it stood when the unit was first put on the sled to where it rests at the end."""
        moved = self._in_pallet(-1) - self.origin()
        return np.linalg.norm(moved[:, :2], axis=1)

    def layer_shift_m(self) -> float:
        """The largest horizontal shift of a layer relative to the layer below it (layer 1
        relative to the pallet) since the unit was first put on the sled: per layer, the
        displacement of the mean of its bundle centres in the pallet's frame, less the lower
        layer's."""
        moved = (self._in_pallet(-1) - self.origin())[:, :2]
        layers = self.layers if self.layers is not None else np.ones(len(moved), int)
        below = np.zeros(2)  # the pallet does not move in its own frame
        largest = 0.0
        for layer in np.unique(layers):
            mean = moved[layers == layer].mean(axis=0)
            largest = max(largest, float(np.linalg.norm(mean - below)))
            below = mean
        return largest

    def _in_pallet(self, i: int) -> np.ndarray:
        """(n, 3) bundle centres in the pallet's frame at sample i."""
        return in_pallet_frame(self.pallet_pos_m[i], self.pallet_rot[i], self.bundle_pos_m[i])

    def moved_before_m(self) -> float:
        """How far the bundle that had moved most stood, when this level began, from where
        the unit was put on the sled (0: a first level): what a later level of a cumulative
        sequence adds to its own displacements before the permanent limit judges them."""
        moved = (self._in_pallet(0) - self.origin())[:, :2]
        return float(np.linalg.norm(moved, axis=1).max(initial=0.0))

    def origin(self) -> np.ndarray:
        """(n, 3) bundle centres in the pallet's frame when the unit was first put on the sled."""
        return self.origin_m if self.origin_m is not None else self._in_pallet(0)

    def pallet_slip_m(self) -> float:
        """Permanent horizontal displacement of the pallet on the sled."""
        return float(np.linalg.norm(self.pallet_pos_m[-1, :2] - self.pallet_pos_m[0, :2]))

    def dropped_m(self) -> np.ndarray:
        """(n,) how far each bundle centre ends below where it stood when the unit was first
        put on the sled, in the pallet's frame."""
        return self.origin()[:, 2] - self._in_pallet(-1)[:, 2]

    def tilt_rad(self) -> np.ndarray:
        """(n,) final tilt of each bundle: angle between its vertical axis and the world's."""
        return np.arccos(np.clip(self.bundle_rot[-1, :, 2, 2], -1.0, 1.0))


def in_pallet_frame(pallet_pos_m: np.ndarray, pallet_rot: np.ndarray,
                    bundle_pos_m: np.ndarray) -> np.ndarray:
    """Bundle centres (..., n, 3) in the pallet's frame, for one sample or a whole trace
    (leading axes of `pallet_pos_m` (..., 3) and `pallet_rot` (..., 3, 3))."""
    return np.einsum("...ba,...nb->...na", pallet_rot, bundle_pos_m - pallet_pos_m[..., None, :])
