"""Per-pair static and kinetic friction on top of Bullet's single, multiplied coefficient.

Bullet gives each body one friction coefficient and uses the product of the two bodies' values
for a contact, with no separate static and kinetic values. The load file instead gives a static
and a kinetic coefficient per contact pair (sled-pallet, pallet-bundle, bundle-bundle). This
module keeps, for every resting contact (a body on what supports it), whether it sticks or
slides, and solves for body coefficients m whose products m_i * m_j equal the wanted pair value:
a linear least-squares problem in log m. Resting contacts form a tree for columnar stacks, so
they are met exactly; side contacts between neighbours in a layer are met as well as the
remaining freedom allows. The solve is a fixed matrix times a vector, precomputed once.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from threadpoolctl import threadpool_limits

from wrapenv.load import Friction, FrictionPair, Layout
from wrapenv.scene import PALLET_NAME, SLED, BenchScene

#: A sticking contact starts to slide above this relative speed, and a sliding one sticks again
#: below `STICK_SPEED_MPS` (hysteresis keeps solver jitter from toggling the state).
SLIP_SPEED_MPS = 2e-3
STICK_SPEED_MPS = 1e-3
#: The same for a wrapped unit. The wrap squeezes each layer shut, and Bullet's solver leaves a
#: squeezed stack jittering at a few mm/s; with the finer thresholds the contact states then
#: flip every step, and each flip (a contact rebuilt) feeds the jitter (measured: a wrapped
#: 3-layer unit never came to rest). Costs ~4 % of a free slide, which a wrap does not allow.
WRAPPED_SLIP_SPEED_MPS = 1e-2
WRAPPED_STICK_SPEED_MPS = 5e-3
#: Neighbours in a layer closer than this (face to face) are treated as side contacts.
SIDE_CONTACT_GAP_M = 0.01


@dataclass(frozen=True)
class Contact:
    body: int     # the body resting on (or beside) `other`
    other: int
    pair: FrictionPair
    offset_m: tuple[float, float, float]  # from `body`'s centre to the contact, body frame


class StickSlip:
    """Contact states and the body coefficients that realise them.

    Bodies are the scene's bodies with a coefficient of their own, by world index
    (`BenchScene.parts`): the sled, the pallet and the bundles.
    """

    def __init__(self, scene: BenchScene | Layout, slip_speed_mps: float = SLIP_SPEED_MPS,
                 stick_speed_mps: float = STICK_SPEED_MPS) -> None:
        self.scene = scene if isinstance(scene, BenchScene) else BenchScene(scene)
        self.slip_speed_mps, self.stick_speed_mps = slip_speed_mps, stick_speed_mps
        self.n_bodies = self.scene.n_parts
        self.resting = _resting_contacts(self.scene)
        side = _side_contacts(self.scene)
        a_rest = _incidence(self.resting, self.n_bodies)
        a_side = _incidence(side, self.n_bodies)
        self._p_rest, self._p_side = _projections(a_rest, a_side)
        self._b_side = np.log([c.pair.static for c in side]) if side else np.zeros(0)
        self._static = np.log([c.pair.static for c in self.resting])
        self._kinetic = np.log([c.pair.kinetic for c in self.resting])
        self.sliding = np.zeros(len(self.resting), dtype=bool)
        self._i = np.array([c.body for c in self.resting])
        self._j = np.array([c.other for c in self.resting])
        self._offset = np.array([c.offset_m for c in self.resting])
        # full state arrays for `update_moving`: the sled's row stays at rest at its origin
        self._moving = self.scene.moving
        self._full = (np.zeros((self.n_bodies, 3)), np.repeat(np.eye(3)[None], self.n_bodies, 0),
                      np.zeros((self.n_bodies, 3)), np.zeros((self.n_bodies, 3)))

    def sliding_bodies(self) -> set[int]:
        """Bodies touching a contact that slides now."""
        return self._bodies(self.sliding)

    def _bodies(self, contacts: np.ndarray) -> set[int]:
        """The bodies touching the resting contacts a boolean mask selects."""
        return set(self._i[contacts].tolist()) | set(self._j[contacts].tolist())

    def coefficients(self) -> np.ndarray:
        """Body coefficients (n_bodies,) for the current contact states."""
        b_rest = np.where(self.sliding, self._kinetic, self._static)
        return np.exp(self._p_rest @ b_rest + self._p_side @ self._b_side)

    def stick_all(self) -> list[int]:
        """Every contact sticks (the bodies were stopped). Returns the bodies of the contacts
        that were sliding, as `update` does."""
        changed = self.sliding
        self.sliding = np.zeros_like(changed)
        return sorted(self._bodies(changed))

    def update(self, pos: np.ndarray, rot: np.ndarray, vel: np.ndarray,
               omega: np.ndarray) -> list[int]:
        """Update contact states from body states (all bodies, sled included, sled frame).

        `rot` holds rotation matrices (n, 3, 3). Returns the bodies of the contacts that changed
        state (empty when none did).
        """
        i, j = self._i, self._j
        r_i = np.einsum("nab,nb->na", rot[i], self._offset)  # contact point from i's centre
        r_j = pos[i] + r_i - pos[j]                           # and from j's
        v = (vel[i, :2] + _horizontal_cross(omega[i], r_i)
             - vel[j, :2] - _horizontal_cross(omega[j], r_j))
        rel = np.sqrt(np.einsum("nk,nk->n", v, v))
        new = np.where(self.sliding, rel > self.stick_speed_mps, rel > self.slip_speed_mps)
        changed = new != self.sliding
        if not changed.any():  # most steps: no set built for nothing
            return []
        self.sliding = new
        return sorted(self._bodies(changed))

    def update_moving(self, pos: np.ndarray, rot: np.ndarray, vel: np.ndarray,
                      omega: np.ndarray) -> list[int]:
        """`update` from the state arrays of the moving bodies (`BenchScene.moving`), the sled
        at rest at the origin of its own frame."""
        for full, moving in zip(self._full, (pos, rot, vel, omega), strict=True):
            full[self._moving] = moving
        return self.update(*self._full)


def _horizontal_cross(w: np.ndarray, r: np.ndarray) -> np.ndarray:
    """x and y of the row-wise cross products w x r (n, 2): all a contact's sliding needs
    (np.cross is slow on small arrays)."""
    out = np.empty((len(w), 2))
    out[:, 0] = w[:, 1] * r[:, 2] - w[:, 2] * r[:, 1]
    out[:, 1] = w[:, 2] * r[:, 0] - w[:, 0] * r[:, 2]
    return out


def _incidence(contacts: list[Contact], n: int) -> np.ndarray:
    a = np.zeros((len(contacts), n))
    for row, c in enumerate(contacts):
        a[row, c.body] += 1.0
        a[row, c.other] += 1.0
    return a


def _resting_contacts(scene: BenchScene) -> list[Contact]:
    layout = scene.layout
    f: Friction = layout.friction
    pallet_h = layout.pallet_size_m[2]
    pallet = scene.index(PALLET_NAME)
    out = [Contact(pallet, scene.index(SLED), f.sled_pallet, (0.0, 0.0, -pallet_h / 2))]
    bundles = [scene.index(b.name) for b in layout.bundles]
    for k, (b, below) in enumerate(zip(layout.bundles, layout.supports(), strict=True)):
        bottom = (0.0, 0.0, -b.size_m[2] / 2)
        if b.layer == 1:
            out.append(Contact(bundles[k], pallet, f.pallet_bundle, bottom))
        out.extend(Contact(bundles[k], bundles[j], f.bundle_bundle, bottom) for j in below)
    return out


def _side_contacts(scene: BenchScene) -> list[Contact]:
    layout = scene.layout
    out = []
    bundles = layout.bundles
    for a in range(len(bundles)):
        for b in range(a + 1, len(bundles)):
            p, q = bundles[a], bundles[b]
            if p.layer != q.layer:
                continue
            gaps = [abs(p.centre_m[k] - q.centre_m[k]) - (p.size_m[k] + q.size_m[k]) / 2
                    for k in (0, 1)]
            # face to face: touching (small gap) along one axis, overlapping along the other
            if (gaps[0] < SIDE_CONTACT_GAP_M and gaps[1] < 0) or (
                gaps[1] < SIDE_CONTACT_GAP_M and gaps[0] < 0
            ):
                out.append(Contact(scene.index(p.name), scene.index(q.name),
                                   layout.friction.bundle_bundle, (0.0, 0.0, 0.0)))
    return out


def _projections(a_rest: np.ndarray, a_side: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """P_rest, P_side with log m = P_rest @ b_rest + P_side @ b_side: meet the resting contacts
    in least squares, then use the null space left over to meet the side contacts (a ridge
    keeps it well posed). On one BLAS thread: a threaded SVD rounds differently with the number
    of cores, and a last-bit change of one coefficient changes a whole run. Processors still
    round it differently (OpenBLAS's AVX-512 kernels against its AVX2 ones): the world rounds
    the coefficients it is given (`wrapenv.bullet.FRICTION_DECIMALS`)."""
    with threadpool_limits(limits=1, user_api="blas"):
        pinv = np.linalg.pinv(a_rest)
        _, s, vt = np.linalg.svd(a_rest)
        rank = int(np.sum(s > 1e-9))
        null = vt[rank:].T
        if not (null.shape[1] and a_side.shape[0]):
            return pinv, np.zeros((a_rest.shape[1], a_side.shape[0]))
        an = a_side @ null
        z = np.linalg.solve(an.T @ an + 1e-6 * np.eye(an.shape[1]), an.T)
        return pinv - null @ z @ a_side @ pinv, null @ z
