"""Radii in UI points (independent of zoom), without importing rerun at module import time.

Rerun stores a radius in UI points as a negative number (``rr.Radius.ui_points`` returns
``-abs(r)`` as float32); the views' module-level constants use :func:`ui_points` so that
importing onebit does not import rerun (``tests/test_startup.py``).
"""

from __future__ import annotations

import numpy as np


def ui_points(radius: float) -> np.float32:
    """``radius`` in UI points, as ``rr.Radius.ui_points(radius)`` encodes it."""
    return -np.abs(np.float32(radius))
