"""The I-state fill images: the label-table drawing equals the per-pixel blend, stage by stage."""

from __future__ import annotations

import numpy as np
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit._testing.oracles import fill_images_reference
from onebit.viz.istate import FillRaster, fill_images


def _box(x0, y0, w, h):
    return shapely.box(x0, y0, x0 + w, y0 + h)


@st.composite
def grids(draw):
    E, n, K = draw(st.integers(1, 3)), draw(st.integers(1, 3)), draw(st.integers(1, 4))
    grid = np.full((E, n, K), None, dtype=object)
    for e in range(E):
        for k in range(n):
            for s in range(K):
                if draw(st.booleans()):
                    x, y = draw(st.floats(0, 8)), draw(st.floats(0, 6))
                    w, h = draw(st.floats(0.5, 6)), draw(st.floats(0.5, 5))
                    g = _box(x, y, w, h)
                    if draw(st.booleans()):  # a region with a hole
                        g = g.difference(_box(x + w / 4, y + h / 4, w / 2, h / 2))
                    grid[e, k, s] = g
    return grid


@settings(max_examples=25, deadline=None)
@given(grids())
def test_label_table_drawing_equals_the_per_pixel_blend(grid):
    raster = FillRaster((0.0, 0.0, 14.0, 11.0), pixels=60)
    assert fill_images(grid, raster) == fill_images_reference(grid, raster)


def test_stages_with_the_same_key_share_the_image():
    a, b = _box(0, 0, 4, 3), _box(2, 1, 5, 5)
    grid = np.array([[[a, b, a]]], dtype=object)
    raster = FillRaster((0.0, 0.0, 8.0, 8.0), pixels=40)
    images = fill_images(grid, raster, keys=["A", "B", "A"])
    assert images == fill_images_reference(grid, raster)
    assert images[0] is images[2] and images[0] != images[1]
