"""Row-wise vector operations compute what numpy's general routines compute, bit for bit:
a step's results must not depend on which of the two a module calls."""

import numpy as np
import pytest

from wrapenv.rowwise import cross, norms


@pytest.mark.parametrize("shape", [(1, 3), (50, 3), (7, 12, 3), (7, 12, 2), (0, 3)])
def test_norms_are_numpys_to_the_bit(shape: tuple[int, ...]) -> None:
    rng = np.random.default_rng(len(shape) + shape[0])
    x = rng.normal(size=shape) * 10.0 ** rng.uniform(-6, 3, size=shape)
    assert np.array_equal(norms(x), np.linalg.norm(x, axis=-1))


def test_norms_of_a_strided_view() -> None:
    x = np.random.default_rng(1).normal(size=(5, 8, 3))
    assert np.array_equal(norms(x[..., :2]), np.linalg.norm(x[..., :2], axis=-1))


def test_norm_of_a_known_vector() -> None:
    assert norms(np.array([[3.0, 4.0, 12.0]])).tolist() == [13.0]


def test_cross_is_numpys_to_the_bit() -> None:
    rng = np.random.default_rng(2)
    a, b = rng.normal(size=(40, 3)), rng.normal(size=(40, 3))
    assert np.array_equal(cross(a, b), np.cross(a, b))


def test_cross_of_the_axes() -> None:
    x, y = np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]])
    assert cross(x, y).tolist() == [[0.0, 0.0, 1.0]]
    assert cross(y, x).tolist() == [[0.0, 0.0, -1.0]]
