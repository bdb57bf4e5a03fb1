"""Farnebäck's flow reduced to a patch's rigid motion: its signs, the texture weights, and the
robust pass that keeps pixels moving otherwise (a neighbour entering the box) from pulling it."""

import cv2
import numpy as np

from calibration.vision.flow import RigidFlow, texture_weights, warp_to_reference
from tests.calibration.vision.vision_frames import moved, texture

CENTRE = (200.3, 150.6)
SIZE = (110, 130)


def test_rigid_flow_sign_conventions() -> None:
    image = texture(300, 400)
    ref_centre = (55.0, 65.0)
    ref = warp_to_reference(image, CENTRE, 0.0, ref_centre, SIZE)
    flow = RigidFlow(ref, ref_centre)
    cur = warp_to_reference(moved(image, CENTRE, 0.4, 0.2, 0.01, noise=0.0), CENTRE, 0.0,
                            ref_centre, SIZE)
    m = flow.measure(cur)
    assert abs(m.du - 0.4) < 0.05 and abs(m.dv - 0.2) < 0.05 and abs(m.dtheta - 0.01) < 1e-3


def test_texture_weights_are_zero_within_the_border_on_every_side() -> None:
    """Farnebäck's window reaches outside the patch there; border 0 keeps every pixel."""
    patch = texture(40, 50, seed=4)
    weights = texture_weights(patch, border=6)
    inside = weights[6:-6, 6:-6]
    assert (inside > 0).mean() > 0.9
    assert not weights[:6].any() and not weights[-6:].any()
    assert not weights[:, :6].any() and not weights[:, -6:].any()
    assert (texture_weights(patch, border=0) > 0).mean() > 0.9


def test_a_strip_moving_otherwise_does_not_pull_the_motion() -> None:
    """The patch moves (0.3, -0.2) px but its right 16 px (15 %) show texture moved
    (2.3, 1.8), as a neighbour sliding into the box would: the robust pass stays within 0.08 px
    of the patch's motion, where the texture-weighted fit alone is pulled 0.15 px or more."""
    image = texture(300, 400, seed=5)
    centre, ref_centre = (200.0, 150.0), (54.5, 64.5)
    ref = warp_to_reference(image, centre, 0.0, ref_centre, SIZE)
    flow = RigidFlow(ref, ref_centre)
    cur = warp_to_reference(moved(image, centre, 0.3, -0.2, noise=0.0), centre, 0.0,
                            ref_centre, SIZE)
    other = warp_to_reference(moved(image, centre, 2.3, 1.8, noise=0.0), centre, 0.0,
                              ref_centre, SIZE)
    cur[:, -16:] = other[:, -16:]
    m = flow.measure(cur)
    assert abs(m.du - 0.3) < 0.08 and abs(m.dv + 0.2) < 0.08
    field = cv2.calcOpticalFlowFarneback(ref, cur, np.zeros((*ref.shape, 2), np.float32),
                                         *flow.farneback)
    plain = flow._fit(field[..., 0], field[..., 1], flow.weights)
    assert abs(plain.du - 0.3) > 0.15 and abs(plain.dv + 0.2) > 0.15
