"""The world frame of the map views: x to the right, **y up**, in the site's units.

Rerun's 2D views put y down (image convention); site coordinates have y up (a camera
homography maps pixel rows to decreasing y). Every root that holds map geometry (``site``,
``truth``, ``sensors``, ``camera``, ``correct`` and each tracker's root) carries one static
``Transform3D`` that mirrors y, so the map reads as the site plan does, while hovering still
shows world coordinates and labels stay upright. Logging it again is harmless (static).
"""

from __future__ import annotations

import functools

from onebit.core.lazy import lazy_module

rr = lazy_module("rerun")


#: The world frame: y points up (a flip of the image-like y of site coordinates).
Y_UP_SCALE = (1.0, -1.0, 1.0)


def log_world_frame(rec: rr.RecordingStream, root: str) -> None:
    """Put the map geometry under ``root`` (one path part, e.g. ``"truth"``) in the y-up frame."""
    rec.log(root.split("/")[0], _world_frame(), static=True)


@functools.cache
def _world_frame() -> rr.Transform3D:
    """The y-up transform, built once (an archetype is logged as it is, into any recording)."""
    return rr.Transform3D(scale=list(Y_UP_SCALE))
