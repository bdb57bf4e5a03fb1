"""Procedural textures of the bench's objects for synthetic recordings, all drawn from a seed.

A tracker needs what real footage has: a printed label every bundle shares (template matching),
fine detail that differs from bundle to bundle (optical flow), wood grain on the pallet, a deck with
bolts, a static wall behind. Textures are RGB uint8 images of an object's front face (the face the
camera sees, -y) at `px_per_m` texture pixels per metre, row 0 at the top of the face.
"""

from __future__ import annotations

import string

import cv2
import numpy as np

#: Quiet zone round a printed marker, as a fraction of its side (one ArUco cell of a 4x4 code).
QUIET_ZONE = 1 / 6


def _smooth_noise(rng: np.random.Generator, shape: tuple[int, int], cell_px: tuple[float, float]
                  ) -> np.ndarray:
    """Noise in [-1, 1] with features about `cell_px` (columns, rows) large."""
    h, w = shape
    small = rng.standard_normal((max(2, round(h / cell_px[1])), max(2, round(w / cell_px[0]))))
    big = cv2.resize(small.astype(np.float32), (w, h), interpolation=cv2.INTER_CUBIC)
    return np.clip(big / 2.5, -1, 1)


def _shade(image: np.ndarray, factor: np.ndarray) -> np.ndarray:
    return np.clip(image.astype(np.float32) * factor[..., None], 0, 255).astype(np.uint8)


def _size(size_m: tuple[float, float], px_per_m: float) -> tuple[int, int]:
    """(width, height) in texture pixels of a face (x, z) metres."""
    return max(2, round(size_m[0] * px_per_m)), max(2, round(size_m[1] * px_per_m))


def _rgb(values: np.ndarray) -> tuple[int, int, int]:
    """A colour for cv2's drawing functions (plain ints)."""
    r, g, b = (int(v) for v in values)
    return r, g, b


def brand_name(rng: np.random.Generator) -> str:
    letters = rng.choice(list(string.ascii_uppercase), 5)
    return "".join(letters)


def _label_strip(rng: np.random.Generator, width: int, height: int, s: float, name: str,
                 colour: tuple[int, int, int], accent: tuple[int, int, int]) -> np.ndarray:
    """One bottle's label unrolled (its whole circumference, `width` px): brand, logo, small
    print and a barcode. A bottle shows part of it, so neighbouring bottles look different."""
    strip = np.full((height, width, 3), colour, np.uint8)
    radius = max(2, round(0.22 * height))
    cv2.circle(strip, (width // 6, height // 3), radius, accent, -1, cv2.LINE_AA)
    cv2.circle(strip, (width // 6, height // 3), max(1, radius // 2), colour, -1, cv2.LINE_AA)
    cv2.putText(strip, name, (width // 3, round(0.45 * height)), cv2.FONT_HERSHEY_DUPLEX,
                0.012 * height / s, (255, 255, 255), max(1, round(1.5 * s)), cv2.LINE_AA)
    for line in range(3):  # small print
        y = round((0.62 + 0.1 * line) * height)
        for x in range(width // 3, width - round(4 * s), max(2, round(3 * s))):
            if rng.random() < 0.7:
                cv2.line(strip, (x, y), (x + max(1, round(2 * s)), y), (230, 230, 230), 1)
    bar = max(1, round(1.2 * s))
    for x in range(round(4 * s), width // 4, bar):  # barcode on white
        cv2.line(strip, (x, round(0.62 * height)), (x, height - 2), (250, 250, 250), bar)
        if rng.random() < 0.5:
            cv2.line(strip, (x, round(0.66 * height)), (x, height - 4), (15, 15, 15), 1)
    return strip


def label_design(size_m: tuple[float, float], px_per_m: float, seed: int) -> np.ndarray:
    """The front of a shrink-wrapped bundle as printed: bottles through clear film, caps, and a
    brand label on each bottle, each turned its own way. Every bundle of a load shows this same
    design (one product, packed by one machine)."""
    rng = np.random.default_rng([seed, 1])
    w, h = _size(size_m, px_per_m)
    s = px_per_m / 1000  # texture pixels per millimetre
    liquid = _rgb(np.array([150, 190, 215]) + rng.integers(-25, 25, 3))
    colour = _rgb(rng.integers(20, 170, 3))
    accent = _rgb(255 - np.array(colour))
    image = np.full((h, w, 3), (235, 240, 245), np.uint8)
    bottles = max(1, round(size_m[0] / 0.095))
    pitch = w / bottles
    top, bottom = round(0.45 * h), round(0.72 * h)
    strip = _label_strip(rng, round(3 * pitch), bottom - top, s, brand_name(rng), colour, accent)
    for i in range(bottles):
        x0, x1 = round(i * pitch + 2 * s), round((i + 1) * pitch - 2 * s)
        xm, neck = (x0 + x1) // 2, round(0.22 * h)
        cv2.rectangle(image, (x0, neck), (x1, h - 1), liquid, -1)
        cv2.ellipse(image, (xm, neck), ((x1 - x0) // 2, round(0.08 * h)), 0, 180, 360, liquid, -1)
        cap = max(2, round(0.15 * (x1 - x0)))
        cv2.rectangle(image, (xm - cap, round(0.04 * h)), (xm + cap, round(0.1 * h)), accent, -1)
        turn = int(rng.integers(0, strip.shape[1] - (x1 - x0)))
        image[top:bottom, x0:x1] = strip[:, turn:turn + x1 - x0]
    grain = _smooth_noise(rng, (h, w), (3 * s, 3 * s))
    return _shade(image, 1 + 0.06 * grain)


def bundle_texture(design: np.ndarray, seed: int, index: int) -> np.ndarray:
    """One bundle's front: the shared design under its own film (streaks of gloss, wrinkles)."""
    rng = np.random.default_rng([seed, 2, index])
    h, w = design.shape[:2]
    wrinkles = _smooth_noise(rng, (h, w), (w / 25, h / 6))
    image = _shade(design, 1 + 0.08 * wrinkles).astype(np.float32)
    gloss = np.zeros((h, w), np.float32)
    for _ in range(rng.integers(2, 5)):
        x = rng.uniform(0, w)
        dx = rng.uniform(-0.3, 0.3) * h
        cv2.line(gloss, (round(x), 0), (round(x + dx), h - 1), 1.0, max(1, round(w / 60)),
                 cv2.LINE_AA)
    gloss = cv2.GaussianBlur(gloss, (0, 0), max(1.0, w / 150)) * rng.uniform(0.15, 0.35)
    image = image * (1 - gloss[..., None]) + 255 * gloss[..., None]
    return np.clip(image, 0, 255).astype(np.uint8)


def pallet_texture(size_m: tuple[float, float], px_per_m: float, seed: int) -> np.ndarray:
    """The side of a block pallet: deck board on top, bottom board below, three blocks with
    fork openings (dark) between them, wood grain and a stamp on the blocks."""
    rng = np.random.default_rng([seed, 3])
    w, h = _size(size_m, px_per_m)
    s = px_per_m / 1000
    wood = np.array([200, 160, 120], np.float32)  # light pine
    grain = _smooth_noise(rng, (h, w), (60 * s, 1.5 * s)) + 0.5 * _smooth_noise(
        rng, (h, w), (8 * s, 0.8 * s))
    image = wood * (1 + 0.12 * grain)[..., None]
    board = round(0.022 * px_per_m)
    block_w = round(0.145 * px_per_m)
    starts = [0, (w - block_w) // 2, w - block_w]
    for a, b in zip(starts[:-1], starts[1:], strict=True):
        image[board:h - board, a + block_w:b] = (35, 25, 18)  # fork openings, in shadow
    chips = 1 + 0.18 * rng.standard_normal((h, w)).astype(np.float32)  # pressed-chip blocks
    for x in starts:
        image[board:h - board, x:x + block_w] *= chips[board:h - board, x:x + block_w, None]
    image = np.clip(image, 0, 255).astype(np.uint8)
    for y in (board, h - board):  # board edges
        cv2.line(image, (0, y), (w - 1, y), (70, 50, 35), max(1, round(1.5 * s)))
    cv2.putText(image, "EPAL", (starts[1] + round(block_w * 0.12), h // 2 + round(8 * s)),
                cv2.FONT_HERSHEY_SIMPLEX, 0.02 * block_w / 6, (60, 40, 30), max(1, round(2 * s)),
                cv2.LINE_AA)
    return image


def deck_texture(size_m: tuple[float, float], px_per_m: float, seed: int) -> np.ndarray:
    """The sled deck's side: brushed steel, bolts every 0.25 m, a hazard stripe at the bottom."""
    rng = np.random.default_rng([seed, 4])
    w, h = _size(size_m, px_per_m)
    s = px_per_m / 1000
    brushed = _smooth_noise(rng, (h, w), (80 * s, 1.0 * s))
    image = np.clip(150 * (1 + 0.1 * brushed), 0, 255).astype(np.uint8)
    image = np.repeat(image[..., None], 3, axis=2)
    stripe = round(0.15 * h)
    period = max(2, round(40 * s))
    diagonal = (np.arange(w) + np.arange(h - stripe, h)[:, None]) // period % 2 == 0
    image[h - stripe:] = np.where(diagonal[..., None], (230, 190, 30), (30, 30, 30))
    for x in np.arange(0.125, size_m[0], 0.25):
        cv2.circle(image, (round(x * px_per_m), round(0.2 * h)), max(1, round(6 * s)),
                   (60, 60, 65), -1, cv2.LINE_AA)
    return image


def wall_texture(width: int, height: int, seed: int) -> np.ndarray:
    """The hall behind the bench (static): painted wall with blotches and block joints."""
    rng = np.random.default_rng([seed, 5])
    blotch = _smooth_noise(rng, (height, width), (width / 12, height / 8))
    fine = _smooth_noise(rng, (height, width), (3.0, 3.0))
    image = np.full((height, width, 3), (205, 200, 190), np.float32)
    image *= (1 + 0.06 * blotch + 0.03 * fine)[..., None]
    block = max(8, width // 24)
    for y in range(0, height, block // 2):  # joints of the wall's blocks
        cv2.line(image, (0, y), (width - 1, y), (185, 180, 172), 1)
    return np.clip(image, 0, 255).astype(np.uint8)


def marker_image(dictionary: cv2.aruco.Dictionary, marker_id: int, side_px: int) -> np.ndarray:
    """An ArUco marker (RGB) `side_px` across, with its white quiet zone round it (so the image
    is side_px * (1 + 2 QUIET_ZONE) across)."""
    code = cv2.aruco.generateImageMarker(dictionary, marker_id, side_px)
    quiet = round(side_px * QUIET_ZONE)
    padded = cv2.copyMakeBorder(code, quiet, quiet, quiet, quiet, cv2.BORDER_CONSTANT, value=255)
    return cv2.cvtColor(padded, cv2.COLOR_GRAY2RGB)
