"""The first frame: which objects are followed, what they are called and where they start.

The sled and the pallet are placed from the layout (the sled from its markers when they are
seen); the bundles of the row facing the camera are found by template matching (NCC + NMS) and
each match is named after the nearest layout position (`L{layer}C{column}R1`), so names are the
load's and a match far from every position (a neighbour's label, the wall) is ignored.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from calibration.vision.detection import Detection, find_template
from calibration.vision.markers import baseline_scale, centre_px, scale_warning
from calibration.vision.roi import ROI_MARGIN_M, PixelMap, predict_roi, unit_extent_m
from calibration.vision.tracking import Frame
from wrapenv.config import InputError
from wrapenv.load import Layout
from wrapenv.scene import SLED_DECK_M

#: A template match must score this much (TM_CCOEFF_NORMED) to count as a bundle.
MATCH_THRESHOLD = 0.6
#: Inset of an object's tracked box from its outline, so no neighbour is in its reference patch.
INSET_M = 0.012
#: A match farther than this fraction of the bundle's size from every layout position is ignored.
MATCH_RADIUS = 0.35
#: Smallest side of a tracked box (px): fewer pixels hold too little texture to follow.
MIN_BOX_PX = 8


@dataclass(frozen=True)
class TrackedObject:
    """An object to follow: its name, its centre in frame 0 and its box (px)."""

    name: str
    centre_px: tuple[float, float]
    size_px: tuple[int, int]


@dataclass(frozen=True)
class View:
    """The test at rest as the camera shows it: the load, the pixel mapping, the image size and
    the sled's x in frame 0 according to the profile."""

    layout: Layout
    pixmap: PixelMap
    frame_size: tuple[int, int]
    sled_x0_m: float


def box_size(width_px: float, height_px: float) -> tuple[int, int]:
    """A tracked box's whole-pixel size, at least `MIN_BOX_PX` a side."""
    return max(int(round(width_px)), MIN_BOX_PX), max(int(round(height_px)), MIN_BOX_PX)


def sled_and_pallet(view: View, sled_x0_m: float) -> list[TrackedObject]:
    """The sled's deck face (centred on `sled_x0_m`) and the pallet, boxes inset from their
    outlines."""
    s, inset = view.pixmap.px_per_m, 2 * INSET_M
    px, _, pz = view.layout.pallet_size_m
    u, v = view.pixmap.to_px(sled_x0_m, -SLED_DECK_M / 2)
    pu, pv = view.pixmap.to_px(view.sled_x0_m, pz / 2)
    return [TrackedObject("sled", (float(u), float(v)),
                          box_size(s * (px + 0.2), s * (SLED_DECK_M - inset))),
            TrackedObject("pallet", (float(pu), float(pv)),
                          box_size(s * (px - inset), s * (pz - inset)))]


def sled_marker_centre(view: View, found: dict[int, np.ndarray],
                       sled_offsets_m: dict[int, tuple[float, float]],
                       warnings: list[str]) -> tuple[float, float] | None:
    """The sled's centre (x, z) in frame 0 from its markers (`found`: ArUco's corners by id),
    None when none is seen (the sled then starts where the profile puts it); the distance
    between two of them checks setup.toml's scale (it needs no marker size), and a warning says
    when it cannot. The sled runs level on its rails: its markers' centres less their offsets,
    with no rotation estimated (one small marker's own angle, a few degrees off, would move the
    centre 0.7 m away by centimetres)."""
    seen = {i: (found[i], offset) for i, offset in sled_offsets_m.items() if i in found}
    if not seen:
        warnings.append("sled markers not found in frame 0: the sled starts where profile.csv "
                        "puts it and setup.toml's camera.px_per_m is not cross-checked")
        return None
    if len(seen) == 1:
        warnings.append(f"only one sled marker ({next(iter(seen))}) seen in frame 0: "
                        "setup.toml's camera.px_per_m is not cross-checked")
    scale = scale_warning(baseline_scale(found, sled_offsets_m), view.pixmap.px_per_m)
    if scale:
        warnings.append(scale)
    x, z = np.mean([np.subtract(view.pixmap.to_world(*centre_px(corners)), offset)
                    for corners, offset in seen.values()], axis=0)
    return float(x), float(z)


def front_row(layout: Layout) -> dict[str, tuple[float, float, float, float]]:
    """Name -> (x, z, length, height) in the sled frame of the bundles facing the camera (R1)."""
    return {b.name: (b.centre_m[0], b.centre_m[2], b.size_m[0], b.size_m[2])
            for b in layout.bundles if b.name.endswith("R1")}


def bundles(view: View, matches: list[Detection] | None,
            warnings: list[str]) -> list[TrackedObject]:
    """Front-row bundles named after the nearest layout position, each at its best match; a
    position no match comes near (or every position, with no template: `matches` None) starts
    from the layout, with a warning when there were matches to use."""
    s, inset = view.pixmap.px_per_m, 2 * INSET_M
    objects, unmatched = [], []
    for name, (bx, bz, length, height) in front_row(view.layout).items():
        u, v = view.pixmap.to_px(bx + view.sled_x0_m, bz)
        radius = MATCH_RADIUS * s * min(length, height)
        near = [d for d in matches or [] if math.hypot(d.u - u, d.v - v) < radius]
        if near:
            best = max(near, key=lambda d: d.score)
            u, v = best.u, best.v
        elif matches is not None:
            unmatched.append(name)
            warnings.append(f"{name}: no template match near its layout position in frame 0; "
                            "started from the layout")
        objects.append(TrackedObject(name, (float(u), float(v)),
                                     box_size(s * (length - inset), s * (height - inset))))
    if matches is not None:
        warnings.extend(_missing_layers(view.layout, unmatched))
    return objects


def _missing_layers(layout: Layout, unmatched: list[str]) -> list[str]:
    """A warning for each layer none of whose front bundles matched while a layer below did:
    load.toml most likely describes another unit than the one filmed (phantom bundles are
    then followed over the background)."""
    row = front_row(layout)
    front = [b for b in layout.bundles if b.name in row]
    layers = sorted({b.layer for b in front})
    empty = {k for k in layers if all(b.name in unmatched for b in front if b.layer == k)}
    matched_below = [k for k in sorted(empty) if any(j < k for j in set(layers) - empty)]
    return [f"layer {k}: none of its bundles matches the template in frame 0, though a layer "
            f"below does: does load.toml (stack.layers = {max(layers)}, bundle.height_m = "
            f"{layout.bundles[0].size_m[2]:g}) describe the unit filmed?" for k in matched_below]


def match_template(view: View, first: Frame, path: Path) -> list[Detection]:
    """Matches of the template image at `path` in frame 0, inside the unit's region of
    interest, in full-frame pixels; none is bad input."""
    template = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if template is None:
        raise InputError(str(path), "", "cannot read the template image")
    box = predict_roi(view.pixmap, unit_extent_m(view.layout), view.sled_x0_m, view.frame_size,
                      ROI_MARGIN_M)
    roi = first.gray[box.y0 - first.y0:box.y1 - first.y0, box.x0 - first.x0:box.x1 - first.x0]
    found = find_template(roi, template, MATCH_THRESHOLD)
    if not found:
        raise InputError(str(path), "", f"no match scoring >= {MATCH_THRESHOLD} in the first "
                         "frame's region of interest: is it a bundle's front face at the "
                         "recording's scale?")
    return [Detection(d.u + box.x0, d.v + box.y0, d.score, d.width, d.height) for d in found]
