"""Synthetic overhead camera: render ground-truth positions into ``camera.mp4``.

The video is what :func:`onebit.readers.camera.read_camera` reads back, so the simulators
can ship a camera stream whose ground truth is known exactly.

Image model
-----------
For frame ``k`` at time ``t_k = camera.t0 + k / camera.fps`` the grey level of pixel
``(u, v)`` is

.. math::

    I_k(u, v) = \\operatorname{clip}_{[0, 255]}\\Big( g(t_k)\\,\\big[(1 - c_k)\\,B(u, v)
                + c_k\\, s_{a_k}\\big] + n_k(u, v) \\Big)

where

* ``B`` is the static scene: a light floor (``FLOOR`` grey) with a fixed, smoothed texture
  noise, and the site's obstacle polygons filled darker (``OBSTACLE`` grey);
* ``c_k(u, v) = max_a clip((r - d_a(u, v)) / p + 1/2, 0, 1)`` is the anti-aliased coverage of
  the agent discs: ``d_a`` is the world distance from the pixel's world point (through the
  pixel->world homography) to agent ``a``, ``r`` the disc radius in world units and ``p`` the
  world size of one pixel at the image centre; ``a_k`` is the agent covering the pixel most;
* ``s_a`` is the agent's own dark shade (agents differ slightly so they can be told apart);
* ``g(t) = 1 + 0.06 sin(2 pi t / 60)`` is a slow global lighting drift;
* ``n_k ~ N(0, 3^2)`` is per-frame sensor noise, drawn from ``numpy.random.default_rng(seed)``.

Codec
-----
Frames are written with ``cv2.VideoWriter`` (FFmpeg backend, fourcc ``mp4v``, i.e. MPEG-4
Part 2 in an MP4 container), which OpenCV 5.0 headless both writes and reads back (lossy:
mean absolute error about 1-5 grey levels). H.264/HEVC/AV1 encoders are not available in the
headless wheel. OpenCV's FFmpeg writer stores only even frame sizes, so an odd camera width or
height loses its last column / row (see :func:`encoded_size`). The file is written to a
temporary name in the same folder and renamed over ``path`` (atomic).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import polars as pl

from onebit.core.errors import InputError, OnebitError
from onebit.core.lazy import lazy_module
from onebit.core.site import Camera, Site
from onebit.core.writers import atomic_path

cv2 = lazy_module("cv2")

#: Grey level of the floor.
FLOOR = 200.0
#: Standard deviation (grey levels) of the fixed floor texture.
TEXTURE_SIGMA = 3.0
#: Grey level of obstacles.
OBSTACLE = 110.0
#: Darkest agent shade; agent ``i`` gets ``AGENT_SHADE + AGENT_SHADE_STEP * (i % 5)``.
AGENT_SHADE = 35.0
AGENT_SHADE_STEP = 12.0
#: Per-frame Gaussian noise (grey levels).
NOISE_SIGMA = 3.0
#: Lighting drift: amplitude and period (seconds).
LIGHT_AMPLITUDE = 0.06
LIGHT_PERIOD = 60.0
#: Four-character code of the codec.
FOURCC = "mp4v"


def render_overhead_video(path: str | Path, site: Site, truth: pl.DataFrame, *, seed: int, radius: float) -> int:
    """Render ``truth`` as an overhead video of ``site`` and write it to ``path``.

    Parameters
    ----------
    path
        Output ``.mp4`` file; written atomically (temporary file + ``os.replace``).
    site
        The site; its ``camera`` gives the image size, frame rate, ``t0`` and homography.
    truth
        Columns ``t`` (seconds), ``target``, ``x``, ``y`` (world units), sampled at the frame
        times ``t_k = t0 + k / fps``; frame ``k = round((t - t0) * fps)``. A target may be
        absent from some frames. Frames run from ``k = 0`` to the largest ``k`` in ``truth``.
    seed
        Seed of ``numpy.random.default_rng`` for the floor texture and the per-frame noise.
    radius
        Agent disc radius in world units.

    Returns
    -------
    int
        Number of frames written.

    Steps
    -----
    1. Precompute the world point of every pixel ``(u, v)`` and the static background ``B``.
    2. Group truth rows by frame index ``k`` (sort + ``searchsorted``).
    3. Per frame (inherently sequential, one encoder call each): coverage of all agent discs
       at once as an ``(n_agents, H, W)`` array, composite, lighting gain, noise, encode.
    """
    path = Path(path)
    camera = _require_camera(site, path)
    if radius <= 0:
        raise InputError(f"agent radius must be positive, got {radius!r}", field="radius")
    k, xy, agent = _truth_frames(truth, camera)
    rng = np.random.default_rng(seed)
    world = _pixel_world_grid(camera)
    background = _background(site, camera, rng)
    shades = AGENT_SHADE + AGENT_SHADE_STEP * (np.arange(int(agent.max()) + 1) % 5)
    soft = _pixel_size(camera)
    n_frames = int(k[-1]) + 1
    width, height = encoded_size(camera)
    bounds = np.searchsorted(k, np.arange(n_frames + 1))
    with _atomic_writer(path, camera) as writer:
        for f in range(n_frames):
            sl = slice(bounds[f], bounds[f + 1])
            img = _composite(background, world, xy[sl], shades[agent[sl]], radius, soft)
            img *= _lighting_gain(camera.t0 + f / camera.fps)
            img += rng.standard_normal(img.shape, dtype=np.float32) * NOISE_SIGMA
            grey = np.clip(img[:height, :width] + 0.5, 0, 255).astype(np.uint8)
            writer.write(cv2.cvtColor(grey, cv2.COLOR_GRAY2BGR))
    return n_frames


def encoded_size(camera: Camera) -> tuple[int, int]:
    """Frame size ``(width, height)`` actually stored in the video: each rounded down to even.

    OpenCV's FFmpeg writer (every codec tried: mp4v, FFV1, MJPG, VP9, PNG) stores frames of
    even width and height and drops an odd trailing column / row; the renderer crops the same
    way explicitly, and the reader accepts this size (pixel coordinates are unchanged).
    """
    return camera.width & ~1, camera.height & ~1


def _require_camera(site: Site, path: Path) -> Camera:
    """The site's camera, or an :class:`InputError` if the site has none."""
    if site.camera is None:
        raise InputError(f"site {site.name!r} has no [camera]; cannot render", file=path, field="camera")
    return site.camera


def _truth_frames(truth: pl.DataFrame, camera: Camera) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Frame index, world position and agent index of each truth row, sorted by frame.

    ``k = round((t - t0) * fps)``; agents are numbered by their sorted target names.
    """
    missing = {"t", "target", "x", "y"} - set(truth.columns)
    if missing:
        raise InputError(f"truth lacks columns {sorted(missing)}", field="truth")
    if truth.height == 0:
        raise InputError("truth has no rows; nothing to render", field="truth")
    df = truth.select(
        ((pl.col("t").cast(pl.Float64) - camera.t0) * camera.fps).round().cast(pl.Int64).alias("k"),
        pl.col("x").cast(pl.Float64),
        pl.col("y").cast(pl.Float64),
        pl.col("target").cast(pl.String).rank("dense").cast(pl.Int64).sub(1).alias("agent"),
    ).sort("k", "agent")
    if df["k"].min() < 0:
        raise InputError(f"truth has rows before the camera start t0={camera.t0}", field="t")
    return df["k"].to_numpy(), df.select("x", "y").to_numpy(), df["agent"].to_numpy()


def _pixel_world_grid(camera: Camera) -> np.ndarray:
    """World point of every pixel centre, shape ``(H, W, 2)``, float32.

    Pixel ``(u, v)`` (column, row) maps to ``H @ (u, v, 1)`` divided by its third component.
    """
    v, u = np.mgrid[0 : camera.height, 0 : camera.width]
    uv = np.stack([u.ravel(), v.ravel()], axis=1).astype(float)
    return camera.pixel_to_world(uv).reshape(camera.height, camera.width, 2).astype(np.float32)


def _pixel_size(camera: Camera) -> float:
    """World size of one pixel at the image centre: ``sqrt(|det J|)`` of the homography Jacobian."""
    c = np.array([camera.width / 2, camera.height / 2])
    w = camera.pixel_to_world(np.array([c, c + [1, 0], c + [0, 1]]))
    jac = np.column_stack([w[1] - w[0], w[2] - w[0]])
    return float(np.sqrt(abs(np.linalg.det(jac))))


def _background(site: Site, camera: Camera, rng: np.random.Generator) -> np.ndarray:
    """Static scene ``B``: textured floor with obstacles filled at ``OBSTACLE`` grey (float32).

    The texture is white noise blurred by a Gaussian of sigma 1.5 px and rescaled to standard
    deviation ``TEXTURE_SIGMA``, added to both floor and obstacles.
    """
    noise = rng.standard_normal((camera.height, camera.width), dtype=np.float32)
    texture = cv2.GaussianBlur(noise, (0, 0), 1.5)
    texture *= TEXTURE_SIGMA / max(float(texture.std()), 1e-6)
    base = np.full((camera.height, camera.width), FLOOR, np.float32)
    shift = 4  # sub-pixel vertex precision: coordinates in 1/16 px
    polys = [
        np.round(camera.world_to_pixel_xy(np.asarray(ob.exterior.coords)) * (1 << shift)).astype(np.int32)
        for ob in site.obstacles
    ]
    if polys:
        cv2.fillPoly(base, polys, OBSTACLE, lineType=cv2.LINE_AA, shift=shift)
    return base + texture


def _composite(
    background: np.ndarray, world: np.ndarray, centres: np.ndarray, shades: np.ndarray, radius: float, soft: float
) -> np.ndarray:
    """Draw the agent discs over ``background`` (returns a new float32 image).

    Coverage of agent ``a`` at pixel ``p``: ``c_a = clip((r - |w(p) - x_a|) / soft + 1/2, 0, 1)``;
    each pixel takes the agent of largest coverage, ``I = (1 - c) B + c s_a``.
    """
    img = background.copy()
    if len(centres) == 0:
        return img
    xy = centres.astype(np.float32)
    dx = world[None, :, :, 0] - xy[:, 0, None, None]
    dy = world[None, :, :, 1] - xy[:, 1, None, None]
    d = np.sqrt(dx * dx + dy * dy)  # not ``(...) ** 2).sum(axis=-1)``: numpy reduces a length-2 axis slowly
    cov = np.clip((radius - d) / soft + 0.5, 0.0, 1.0)
    best = cov.argmax(axis=0)
    c = np.take_along_axis(cov, best[None], axis=0)[0]
    shade = shades.astype(np.float32)[best]
    img += c * (shade - img)
    return img


def _lighting_gain(t: float) -> float:
    """Global brightness factor ``g(t) = 1 + 0.06 sin(2 pi t / 60)``."""
    return 1.0 + LIGHT_AMPLITUDE * float(np.sin(2.0 * np.pi * t / LIGHT_PERIOD))


@contextlib.contextmanager
def _atomic_writer(path: Path, camera: Camera) -> Iterator[cv2.VideoWriter]:
    """A ``cv2.VideoWriter`` on a temporary file next to ``path``, renamed over it on success
    (:func:`onebit.core.writers.atomic_path`; the temp name keeps the extension OpenCV needs)."""
    with atomic_path(path, suffix=f".tmp{path.suffix or '.mp4'}") as tmp:
        width, height = encoded_size(camera)
        writer = cv2.VideoWriter(
            str(tmp), cv2.CAP_FFMPEG, cv2.VideoWriter_fourcc(*FOURCC), float(camera.fps), (width, height)
        )
        if not writer.isOpened():
            raise OnebitError(f"{path}: OpenCV cannot open a '{FOURCC}' video writer")
        try:
            yield writer
        finally:
            writer.release()
