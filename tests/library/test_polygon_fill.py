"""The polygon fill of the detection scenes (``cvkit.data._scenes._inside_polygon``) evaluates
each edge only on the rows it crosses when the samples are the usual grid (``y`` an ascending
column, ``x`` a row); that shortcut must give exactly the even-odd rule on every sample."""
import numpy as np
import pytest

from cvkit.data._common import samples
from cvkit.data._scenes import _inside_polygon


def _plain_even_odd(vertices, x, y):
    """The even-odd rule on every sample, written directly."""
    x, y = np.broadcast_arrays(x, y)
    hit = np.zeros(x.shape, dtype=bool)
    for (x0, y0), (x1, y1) in zip(vertices, np.roll(vertices, -1, axis=0)):
        if y0 != y1:
            hit ^= ((y0 > y) != (y1 > y)) & (x < x0 + (y - y0) * (x1 - x0) / (y1 - y0))
    return hit


@pytest.mark.parametrize("seed", range(12))
def test_the_row_shortcut_fills_exactly_as_the_even_odd_rule(seed):
    rng = np.random.default_rng(seed)
    rows, cols = rng.integers(8, 40, 2)
    n = int(rng.integers(3, 9))
    vertices = np.column_stack([rng.uniform(-3, cols + 3, n), rng.uniform(-3, rows + 3, n)])
    if seed % 3 == 0:  # vertices on sample rows and a horizontal edge
        vertices = np.round(vertices)  # on the rows of the centre samples
        vertices[1, 1] = vertices[0, 1]
    x, y = samples(int(rows), int(cols), 3)
    inside = _inside_polygon(vertices)
    fast = inside(x, y)
    general = inside(*np.broadcast_arrays(x, y))  # full grids: the shortcut does not apply
    assert fast.any() and not fast.all() or seed % 3 == 0
    np.testing.assert_array_equal(fast, _plain_even_odd(vertices, x, y))
    np.testing.assert_array_equal(general, fast)
