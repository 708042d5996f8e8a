"""Camera pointing (Schiff & Goldberg, section VII-C): pan, tilt and zoom that frame the prism.

For a camera at ``C = (cx, cy, cz)`` and the intruder's bounding prism (width ``w``, depth
``d``, height ``h``) standing on the floor at the estimate ``(x, y)``:

* **pan / tilt** -- spherical coordinates of the prism centre ``P = (x, y, h/2)`` seen from
  ``C``: ``pan = atan2(Py - Cy, Px - Cx)``, ``tilt = atan2(Pz - Cz, |P - C|_xy)`` (degrees;
  pan counter-clockwise from +x, tilt positive upwards).
* **zoom** -- the 8 prism corners are projected on the image plane orthogonal to the viewing
  direction ``f = (P - C) / |P - C|`` (pin-hole: ``(v . r / v . f, v . u / v . f)`` with ``r``
  = ``f x z`` normalised and ``u = r x f``); the zoom is the largest magnification at which the
  projection still fits the field of view::

      zoom = min( tan(fov_h / 2) / max|x_img|,  tan(fov_v / 2) / max|y_img| )

  with ``fov_h`` the horizontal field of view at zoom 1 and ``tan(fov_v/2) = tan(fov_h/2) /
  aspect``. The camera's own zoom range is not modelled (the value is not clipped).
"""

from __future__ import annotations

import numpy as np


def pan_tilt_zoom(
    est: np.ndarray,
    camera: tuple[float, float, float],
    *,
    width: float,
    depth: float,
    height: float,
    fov_deg: float = 60.0,
    aspect: float = 4.0 / 3.0,
) -> np.ndarray:
    """``(T, 3)`` pan (deg), tilt (deg), zoom for estimates ``est`` ``(T, 2)``; vectorised over T."""
    est = np.asarray(est, float).reshape(-1, 2)
    C = np.asarray(camera, float)
    P = np.c_[est, np.full(len(est), height / 2)]
    d = P - C
    pan = np.degrees(np.arctan2(d[:, 1], d[:, 0]))
    tilt = np.degrees(np.arctan2(d[:, 2], np.hypot(d[:, 0], d[:, 1])))
    f = d / np.linalg.norm(d, axis=1, keepdims=True)
    r = np.cross(f, [0.0, 0.0, 1.0])
    rn = np.linalg.norm(r, axis=1, keepdims=True)
    r = np.where(rn > 1e-9, r / np.maximum(rn, 1e-12), [1.0, 0.0, 0.0])  # looking straight down: any right
    u = np.cross(r, f)
    corners = (
        P[:, None, :]
        + (
            np.array(
                [[a * width / 2, b * depth / 2, c * height / 2] for a in (-1, 1) for b in (-1, 1) for c in (-1, 1)]
            )
        )[None]
    )  # (T, 8, 3)
    v = corners - C
    z = np.einsum("tkc,tc->tk", v, f)
    xi = np.abs(np.einsum("tkc,tc->tk", v, r) / z).max(axis=1)
    yi = np.abs(np.einsum("tkc,tc->tk", v, u) / z).max(axis=1)
    th = np.tan(np.radians(fov_deg) / 2)
    tv = th / aspect
    zoom = np.minimum(th / np.maximum(xi, 1e-12), tv / np.maximum(yi, 1e-12))
    return np.c_[pan, tilt, zoom]
