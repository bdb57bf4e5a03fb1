"""What of a tracked test the bench can predict, as one vector a fit compares.

Per observed body two paths, both in metres and relative to the first frame:
- its slip: the bottom centre of the body against the top centre of what it rests on (the
  pallet against the sled, a first-layer bundle against the pallet, a bundle against the
  bundles below it that are seen), rotations included, so a column that tips does not slip;
- its turn: how far its rotation moves that contact point, (h / 2) x angle.
Slips isolate one contact pair each (the source paper compares the load with the sled, the
first layer with the pallet, the second with the first), so an error in one pair does not
leak into the paths of every body above it.

A body's path is predictable only while the body stands on what it stood on: each body's
window ends at the first frame where its centre has slid past the edge of its support, it has
turned past the angle at which it tips over (atan(length / height)), it has dropped by more than
`FALL_M`, or its support's window has ended; and every window ends `AFTER_STOP_S` after the
sled stopped (what follows is the unit at rest, or a fallen body rolling). Windows are read off
the recording and applied to the replay alike. Within them, slips and turns are clipped at those
same limits: a replay in which a body falls off counts as "past the edge", not as metres of
error, so one body that falls in one run and not in another cannot dominate a loss.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np

from wrapenv.load import Layout

#: A body whose centre dropped more than this has lost its support (fallen, or falling).
FALL_M = 0.02
#: Windows end this long after the sled stopped.
AFTER_STOP_S = 0.25
#: Standard deviation of a tracked position (the tracker's accuracy on the issue's recordings).
TRACK_NOISE_M = 0.002

#: object -> (frame times (n,), x and z displacement relative to the sled and angle (n, 3))
States = Mapping[str, tuple[np.ndarray, np.ndarray]]


@dataclass(frozen=True)
class Body:
    """What the features need to know of one observed body."""

    length_m: float     # along x
    height_m: float
    #: the observed bodies it rests on, with their heights; () for the pallet (on the sled)
    supports: tuple[tuple[str, float], ...]
    #: how far it can slip backwards (-x) and forwards before its centre passes the edge of
    #: what it rests on (`bodies`)
    room_m: tuple[float, float]
    #: how far a slip counts, backwards and forwards, once a recording has shown how far it
    #: went (`reach`); its room until then
    reach_m: tuple[float, float] | None = None

    @property
    def pair(self) -> str:
        """The contact pair its slip isolates (`wrapenv.load.PAIRS`)."""
        if not self.supports:
            return "sled_pallet"
        return "pallet_bundle" if self.supports[0][0] == "pallet" else "bundle_bundle"

    @property
    def tip_rad(self) -> float:
        """The angle at which its centre passes over its bottom edge."""
        return math.atan2(self.length_m, self.height_m)

    def clipped(self, slip: np.ndarray) -> np.ndarray:
        """A slip clipped at its reach: beyond it a run has come to another outcome."""
        back, ahead = self.reach_m or self.room_m
        return np.clip(slip, -back, ahead)

    def off(self, slip: np.ndarray) -> np.ndarray:
        """Per frame, whether its centre has passed its support's edge."""
        return (slip < -self.room_m[0]) | (slip > self.room_m[1])


def bodies(layout: Layout, observed: set[str]) -> dict[str, Body]:
    """The observed bodies of a layout that can be compared: the pallet, and bundles whose
    support is observed (a bundle of an upper layer whose supports are all hidden is not).
    A bundle's room to slip is measured to the outer edges of what it rests on (the seen
    bundles below, or the pallet): a one-layer unit's inner rows can slide far on the pallet,
    where only its back row runs off it. The pallet is followed for half its length on the
    sled (whose deck the recording does not show)."""
    out = {}
    px, _, pz = layout.pallet_size_m
    if "pallet" in observed:
        out["pallet"] = Body(px, pz, (), (px / 2, px / 2))
    extents = {"pallet": (0.0, px)} | {b.name: (b.centre_m[0], b.size_m[0])
                                       for b in layout.bundles}
    for b, below in zip(layout.bundles, layout.supports(), strict=True):
        if b.name not in observed:
            continue
        under = ((("pallet", pz),) if b.layer == 1 else
                 tuple((layout.bundles[j].name, layout.bundles[j].size_m[2]) for j in below))
        seen = tuple((n, h) for n, h in under if n in observed)
        if seen:
            out[b.name] = Body(b.size_m[0], b.size_m[2], seen,
                               _room(b.centre_m[0], [extents[n] for n, _ in seen]))
    return out


def _room(x_m: float, supports: list[tuple[float, float]]) -> tuple[float, float]:
    """Backwards and forwards, how far a centre at x can slip before it passes the outer edge
    of its supports (centre, length), which a slip is taken against (`slips`)."""
    back = x_m - min(c - length / 2 for c, length in supports)
    ahead = max(c + length / 2 for c, length in supports) - x_m
    return max(back, 0.0), max(ahead, 0.0)


def _edge_x(t: np.ndarray, path: tuple[np.ndarray, np.ndarray], height_m: float,
            side: int) -> np.ndarray:
    """x of a body's bottom (side -1) or top (+1) centre at times t."""
    ts, xza = path
    x = xza[:, 0] - side * height_m / 2 * np.sin(xza[:, 2])
    return np.interp(t, ts, x)


def slips(states: States, body_map: Mapping[str, Body]) -> dict[str, np.ndarray]:
    """Each body's slip across its contact (metres, zero at its first frame)."""
    out = {}
    for name, body in body_map.items():
        t = states[name][0]
        bottom = _edge_x(t, states[name], body.height_m, -1)
        if body.supports:
            tops = [_edge_x(t, states[s], h, +1) for s, h in body.supports]
            slip = bottom - np.mean(tops, axis=0)
        else:
            slip = bottom          # the pallet: its states are relative to the sled already
        out[name] = slip - slip[0]
    return out


def on_pallet(states: States, body_map: Mapping[str, Body]) -> dict[str, np.ndarray]:
    """Each bundle's displacement on the pallet (metres, zero at its first frame): its slip,
    clipped at its support's edge, plus what its supports moved on the pallet (their mean).
    The distance EUMOS 40509 judges a load by, where a slip is what one friction pair decides:
    the same slide of a top layer can be its own on a bottom layer that held, or part of one
    on a bottom layer that slid first."""
    slip = slips(states, body_map)
    out: dict[str, np.ndarray] = {}
    for name in sorted(body_map, key=lambda n: (n != "pallet", n)):   # supports first
        body = body_map[name]
        if not body.supports:
            continue
        t = states[name][0]
        own = body.clipped(slip[name])
        below = [np.interp(t, states[s][0], out[s]) for s, _ in body.supports if s in out]
        out[name] = own + np.mean(below, axis=0) if below else own
    return out


def _off_and_turned(xza: np.ndarray, slip: np.ndarray, body: Body
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Per frame: whether the body has slid past its support's edge or dropped, and whether
    it has turned past its tipping angle."""
    off = body.off(slip) | (xza[:, 1] - xza[0, 1] < -FALL_M)
    return off, np.abs(xza[:, 2] - xza[0, 2]) > body.tip_rad


def windows(states: States, body_map: Mapping[str, Body], sled_stop_s: float
            ) -> dict[str, int]:
    """How many leading frames of each body's path the bench can predict (see the module
    docstring); read off the recording."""
    slip = slips(states, body_map)
    end_s: dict[str, float] = {}
    # supports first: the pallet, then layer by layer
    for name in sorted(body_map, key=lambda n: (n != "pallet", n)):
        body = body_map[name]
        t, xza = states[name]
        off, turned = _off_and_turned(xza, slip[name], body)
        lost = off | turned | (t > sled_stop_s + AFTER_STOP_S)
        end = float(t[np.argmax(lost)]) if lost.any() else math.inf
        end_s[name] = min([end] + [end_s.get(s, math.inf) for s, _ in body.supports])
    return {name: int(np.sum(states[name][0] < end_s[name])) for name in body_map}


def reach(states: States, body_map: Mapping[str, Body], frames: Mapping[str, int]
          ) -> dict[str, Body]:
    """The bodies with how far a slip counts, read off a recording: up to half a body's length
    beyond what the recording showed, within its room. A replay that slides farther has come
    to another outcome (a bundle that runs off in one run and not in another), not metres more
    of error: a bottom layer at its onset on the pallet, still in one recording and sliding
    0.3 m in some replays, would otherwise decide a fit by which replays those are."""
    slip = slips(states, body_map)
    out = {}
    for name, body in body_map.items():
        shown = slip[name][:frames[name]] if frames[name] else np.zeros(1)
        back = min(body.room_m[0], max(0.0, -float(shown.min())) + body.length_m / 2)
        ahead = min(body.room_m[1], max(0.0, float(shown.max())) + body.length_m / 2)
        out[name] = replace(body, reach_m=(back, ahead))
    return out


def toppled(states: States, body_map: Mapping[str, Body]) -> bool:
    """Whether some bundle turned past its tipping angle while it still stood on its support
    (before it slid past the support's edge or dropped): a column toppled, rather than a
    bundle tumbling as it fell off."""
    slip = slips(states, body_map)
    for name, body in body_map.items():
        if not body.supports:
            continue
        off, turned = _off_and_turned(states[name][1], slip[name], body)
        if turned.any() and (not off.any() or np.argmax(turned) < np.argmax(off)):
            return True
    return False


def vector(states: States, body_map: Mapping[str, Body], frames: Mapping[str, int]
           ) -> np.ndarray:
    """The features of one run: per body (sorted by name) its clipped slip, then its clipped
    turn, over its window."""
    slip = slips(states, body_map)
    parts = []
    for name in sorted(frames):
        body, k = body_map[name], frames[name]
        angle = states[name][1][:k, 2] - states[name][1][0, 2]
        parts.append(body.clipped(slip[name][:k]))
        parts.append(body.height_m / 2 * np.clip(angle, -body.tip_rad, body.tip_rad))
    return np.concatenate(parts) if parts else np.zeros(0)



def spans(frames: Mapping[str, int]) -> dict[str, np.ndarray]:
    """Per body the indices of its features (its slip's, then its turn's) in `vector`."""
    out, start = {}, 0
    for name in sorted(frames):
        out[name] = np.arange(start, start + 2 * frames[name])
        start += 2 * frames[name]
    return out
