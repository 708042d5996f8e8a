"""Overhead camera reader: ``camera.mp4`` -> ground-truth tracks through OpenCV.

The camera gives the ground truth the one-bit trackers are scored against (docs/dataset.md). Agents are found as blobs that differ from a static background and are
linked frame to frame by minimum-cost assignment.

Pipeline
--------
1. **Decode** the frames with ``cv2.VideoCapture`` (FFmpeg) as grey uint8, twice, never
   holding the video: the first pass counts the frames and keeps only what steps 2-4 need
   (each frame's brightness and the ``BG_SAMPLES`` background frames), the second finds the
   blobs frame by frame (step 5). Memory is ``O(BG_SAMPLES * H * W)``, independent of the
   video's length (holding the ``(K, H, W)`` stack cost ``2 K H W`` bytes at its peak); a
   second decode costs less than the copy of the stack did. A file that cannot be opened or
   yields no frame raises :class:`~onebit.core.errors.InputError`; a decode that stops before
   the frame count the container declares keeps the frames so far and adds a ``rejects``
   row. (:func:`decode_frames` still returns the whole stack, for small videos and tests.)
2. **Lighting**: each frame's brightness is ``m_k = median(I_k)`` (on a 4x subsampled grid;
   the agents are a small fraction of the image so the median is the floor's). Frames are
   normalised to a common level, ``J_k = c_k I_k`` with ``c_k = m_ref / m_k`` and
   ``m_ref = median_k m_k``, which removes a global multiplicative lighting drift.
3. **Background** ``B = median_k J_k`` per pixel over up to ``BG_SAMPLES`` frames spread evenly
   over the video (a moving agent covers a pixel in few of them); lower median by
   ``np.partition``.
4. **Foreground**: ``D_k = |J_k - B|`` (computed in 8 bits as ``|I_k - B / c_k| > tau / c_k``);
   threshold ``tau = max(TAU_MIN, TAU_SIGMAS * sigma)`` where ``sigma = 1.4826 * MAD(J_k - B)`` is the robust noise level measured on the background
   samples. ``D_k > tau`` is cleaned by a morphological opening (3x3 ellipse, removes speckle)
   then closing (5x5 ellipse, fills holes).
5. **Blobs**: ``cv2.connectedComponentsWithStats`` (8-connectivity) gives each blob's pixel
   area and centroid ``(u, v)``; blobs smaller than ``min_area_px`` are dropped. By default
   ``min_area_px = max(MIN_AREA_ABS, 0.25 * median area)`` of all blobs of at least
   ``MIN_AREA_ABS`` pixels. Centroids map to world through the pixel->world homography and
   ``t = camera.t0 + k / camera.fps``.
6. **Identity**: see :func:`link_tracks`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import polars as pl

from onebit.core.errors import InputError
from onebit.core.lazy import lazy_module
from onebit.core.site import Camera, Site
from onebit.core.tables import REJECTS, TRUTH, conform, rejects_frame

cv2 = lazy_module("cv2")
_distance = lazy_module("scipy.spatial.distance")
_optimize = lazy_module("scipy.optimize")

#: Frames sampled for the background median (odd, so the median is one sample).
BG_SAMPLES = 41
#: Threshold in robust noise standard deviations, and its floor in grey levels.
TAU_SIGMAS = 6.0
TAU_MIN = 12.0
#: Smallest blob (pixels) ever considered, and the fraction of the median blob area kept.
MIN_AREA_ABS = 6
MIN_AREA_FRACTION = 0.25
#: Default gate as a fraction of the site diagonal (world units per frame).
GATE_FRACTION = 0.05

DETECTIONS = pl.Schema({"frame": pl.Int64, "t": pl.Float64, "x": pl.Float64, "y": pl.Float64, "area": pl.Int64})


@dataclass(frozen=True)
class CameraResult:
    """What :func:`read_camera` found.

    Attributes
    ----------
    truth
        ``onebit.core.tables.TRUTH`` rows, one per tracked blob per frame; targets ``cam1``,
        ``cam2``, ... in track birth order; ``region`` / ``node`` null.
    detections
        Every accepted blob: ``frame`` (Int64), ``t``, ``x``, ``y`` (world), ``area`` (pixels).
    rejects
        ``onebit.core.tables.REJECTS`` rows for frames that could not be decoded.
    frames
        Number of frames decoded.
    """

    truth: pl.DataFrame
    detections: pl.DataFrame
    rejects: pl.DataFrame
    frames: int


def read_camera(
    path: str | Path,
    site: Site,
    *,
    min_area_px: float | None = None,
    gate: float | None = None,
    max_gap: int | None = None,
) -> CameraResult:
    """Read an overhead video and return the agents' tracks in world coordinates.

    Parameters
    ----------
    path
        The video file (any container/codec FFmpeg decodes).
    site
        The site; its ``camera`` gives size, fps, ``t0`` and the pixel->world homography.
    min_area_px
        Smallest blob area kept, in pixels; default derived from the median blob area.
    gate
        Largest distance (world units) a track may move per frame; default
        ``0.05 * site.diagonal``.
    max_gap
        A track unmatched for more than this many frames dies; default ``round(fps)``.

    Returns
    -------
    CameraResult

    Raises
    ------
    InputError
        The file is missing, not a video, has no decodable frame, or its frame size is not
        the site camera's (field ``camera.width`` / ``camera.height``).
    """
    path = Path(path)
    camera = _require_camera(site, path)
    for name, value in (("min_area_px", min_area_px), ("gate", gate), ("max_gap", max_gap)):
        if value is not None and not value > 0:
            raise InputError(f"must be positive, got {value!r}", field=name)
    n, med, samples, idx, rejects = _first_pass(path, camera)
    gains = _gains(med)
    background = _background(samples, gains[idx])
    tau = _threshold(samples, gains[idx], background)
    frame, uv, area = _blobs_pass(path, camera, n, gains, background, tau)
    keep = area >= (default_min_area(area) if min_area_px is None else float(min_area_px))
    frame, uv, area = frame[keep], uv[keep], area[keep]
    xy = camera.pixel_to_world(uv) if len(uv) else np.zeros((0, 2))
    t = camera.t0 + frame / camera.fps
    gate = GATE_FRACTION * site.diagonal if gate is None else float(gate)
    max_gap = max(1, round(camera.fps)) if max_gap is None else int(max_gap)
    track = link_tracks(frame, xy, gate=gate, max_gap=max_gap)
    detections = pl.DataFrame({"frame": frame, "t": t, "x": xy[:, 0], "y": xy[:, 1], "area": area}, schema=DETECTIONS)
    truth = conform(
        detections.with_columns(pl.Series("track", track, pl.Int64))
        .sort("t", "track")
        .with_columns(pl.format("cam{}", pl.col("track") + 1).alias("target")),
        TRUTH,
    )
    return CameraResult(truth=truth, detections=detections, rejects=rejects, frames=n)


# --------------------------------------------------------------------------- decoding


def _require_camera(site: Site, path: Path) -> Camera:
    if site.camera is None:
        raise InputError(f"site {site.name!r} has no [camera]; cannot read the video", file=path, field="camera")
    return site.camera


def accepted_sizes(camera: Camera) -> set[tuple[int, int]]:
    """Frame sizes ``(width, height)`` accepted for ``camera``.

    The camera's own size, and the same rounded down to even numbers: OpenCV's FFmpeg
    writer stores only even sizes and drops an odd trailing column / row, which leaves the
    pixel coordinates of every other pixel unchanged.
    """
    return {(camera.width, camera.height), (camera.width & ~1, camera.height & ~1)}


def _check_size(width: int, height: int, camera: Camera, path: Path) -> None:
    """Raise :class:`InputError` naming ``camera.width`` / ``camera.height`` on a size mismatch."""
    if (width, height) in accepted_sizes(camera):
        return
    field = "camera.width" if width not in {w for w, _ in accepted_sizes(camera)} else "camera.height"
    raise InputError(
        f"video frames are {width}x{height} pixels but the site camera is {camera.width}x{camera.height}",
        file=path,
        field=field,
    )


class _Decode:
    """Grey frames of a video, one at a time (:meth:`frames`); after the iteration ``count``
    is the number decoded and ``problem`` why decoding stopped early (``None`` if it did not).

    Decoding is inherently sequential. If it stops before the frame count the container
    declares (or OpenCV raises mid-stream) the frames decoded so far are kept and the
    problem says where and why.
    """

    def __init__(self, path: Path, camera: Camera) -> None:
        self.path, self.camera = path, camera
        self.count = 0
        self.declared = 0
        self.problem: str | None = None

    def frames(self, limit: int | None = None):
        path = self.path
        if not path.is_file():
            raise InputError("video file not found", file=path)
        cap = cv2.VideoCapture(str(path), cv2.CAP_FFMPEG)
        shape = None
        try:
            if not cap.isOpened():
                raise InputError(
                    "not a readable video: OpenCV/FFmpeg cannot open it (corrupt, truncated or not a video)", file=path
                )
            self.declared = int(cap.get(cv2.CAP_PROP_FRAME_COUNT) or 0)
            while limit is None or self.count < limit:
                try:
                    ok, img = cap.read()
                except cv2.error as exc:
                    self.problem = f"decoding failed: {str(exc).strip().splitlines()[-1]}"
                    break
                if not ok or img is None:
                    break
                if shape is None:
                    _check_size(img.shape[1], img.shape[0], self.camera, path)
                    shape = img.shape[:2]
                elif img.shape[:2] != shape:
                    self.problem = f"frame size changed to {img.shape[1]}x{img.shape[0]}"
                    break
                self.count += 1
                yield cv2.cvtColor(img, cv2.COLOR_BGR2GRAY) if img.ndim == 3 else img
        finally:
            cap.release()
        if self.count == 0:
            raise InputError("video has no decodable frames", file=path)
        if self.problem is None and self.declared > self.count and limit is None:
            self.problem = f"decoding stopped after {self.count} of {self.declared} frames the container declares"

    def rejects(self) -> pl.DataFrame:
        rows = [] if self.problem is None else [(self.path.name, self.count, self.problem, None)]
        return rejects_frame(rows) if rows else pl.DataFrame(schema=REJECTS)


def decode_frames(path: Path, camera: Camera) -> tuple[np.ndarray, pl.DataFrame]:
    """Decode every frame as grey uint8; return the ``(K, H, W)`` stack and ``rejects``
    (memory ``K H W``: :func:`read_camera` streams instead)."""
    dec = _Decode(Path(path), camera)
    frames = list(dec.frames())
    return np.stack(frames), dec.rejects()


def _first_pass(path: Path, camera: Camera):
    """First decode: ``(n, med (n,), samples (s, H, W), idx (s,), rejects)`` -- the frame count,
    each frame's brightness ``m_k`` (:func:`frame_gains`) and the background sample frames
    ``_sample_indices(n)``. The samples are picked from the frame count the container
    declares; when the decoded count differs, a further decode fetches the right ones."""
    dec = _Decode(path, camera)
    want: set[int] = set()
    med: list[float] = []
    kept: dict[int, np.ndarray] = {}
    for k, img in enumerate(dec.frames()):
        if k == 0 and dec.declared > 0:
            want = set(_sample_indices(dec.declared).tolist())
        med.append(_brightness(img))
        if k in want:
            kept[k] = img
    n = dec.count
    idx = _sample_indices(n)
    if any(int(k) not in kept for k in idx):  # the container's count was wrong: fetch the samples
        need = set(idx.tolist())
        kept = {k: img for k, img in enumerate(_Decode(path, camera).frames(limit=n)) if k in need}
    samples = np.stack([kept[int(k)] for k in idx])
    return n, np.asarray(med, dtype=np.float32), samples, idx, dec.rejects()


def _blobs_pass(path: Path, camera: Camera, n: int, gains: np.ndarray, background: np.ndarray, tau: float):
    """Second decode: :func:`find_blobs` frame by frame over the first ``n`` frames."""
    found = [
        _blobs_of(foreground_mask(img, float(g), background, tau))
        for img, g in zip(_Decode(path, camera).frames(limit=n), gains)
    ]
    return _collect_blobs(found)


# --------------------------------------------------------------------------- background


def frame_gains(stack: np.ndarray) -> np.ndarray:
    """Per-frame brightness correction ``m_ref / m_k`` (float32, shape ``(K,)``).

    ``m_k`` is the median grey level of frame ``k`` on a 4x subsampled grid and
    ``m_ref = median_k m_k``.
    """
    return _gains(np.median(stack[:, ::4, ::4].reshape(len(stack), -1), axis=1).astype(np.float32))


def _brightness(frame: np.ndarray) -> float:
    """``m_k``: the median grey level of one frame on a 4x subsampled grid (as :func:`frame_gains`)."""
    return float(np.float32(np.median(frame[::4, ::4].reshape(-1))))


def _gains(med: np.ndarray) -> np.ndarray:
    """``m_ref / m_k`` from the frames' brightness ``med (K,)`` float32."""
    med = np.maximum(np.asarray(med, dtype=np.float32), 1.0)
    return (np.median(med) / med).astype(np.float32)


def _sample_indices(n: int, k: int = BG_SAMPLES) -> np.ndarray:
    """Up to ``k`` frame indices spread evenly over ``0 .. n-1``."""
    return np.unique(np.linspace(0, n - 1, min(n, k)).round().astype(int))


def _lower_median(a: np.ndarray, axis: int | None = None) -> np.ndarray:
    """Lower median ``sort(a)[(n - 1) // 2]`` along ``axis`` by one ``np.partition`` (O(n))."""
    if axis is None:
        a, axis = a.ravel(), 0
    m = (a.shape[axis] - 1) // 2
    return np.take(np.partition(a, m, axis=axis), m, axis=axis)


def background_model(stack: np.ndarray, gains: np.ndarray) -> np.ndarray:
    """Per-pixel (lower) median of the brightness-normalised sample frames, ``B`` (float32, ``(H, W)``)."""
    idx = _sample_indices(len(stack))
    return _background(stack[idx], gains[idx])


def _background(samples: np.ndarray, gains: np.ndarray) -> np.ndarray:
    """:func:`background_model` from the sample frames and their gains."""
    return _lower_median(samples.astype(np.float32) * gains[:, None, None], axis=0)


def noise_threshold(stack: np.ndarray, gains: np.ndarray, background: np.ndarray) -> float:
    """Foreground threshold ``tau = max(TAU_MIN, TAU_SIGMAS * 1.4826 * MAD(J - B))``.

    ``J - B`` is taken over the background samples on a 2x subsampled pixel grid.
    """
    idx = _sample_indices(len(stack))
    return _threshold(stack[idx], gains[idx], background)


def _threshold(samples: np.ndarray, gains: np.ndarray, background: np.ndarray) -> float:
    """:func:`noise_threshold` from the sample frames and their gains."""
    resid = samples[:, ::2, ::2].astype(np.float32) * gains[:, None, None] - background[::2, ::2]
    sigma = 1.4826 * float(_lower_median(np.abs(resid - _lower_median(resid))))
    return max(TAU_MIN, TAU_SIGMAS * sigma)


# --------------------------------------------------------------------------- blobs

_OPEN = np.array(
    [[0, 1, 0], [1, 1, 1], [0, 1, 0]], dtype=np.uint8
)  # cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3))
_CLOSE = np.array(
    [[0, 0, 1, 0, 0], [1, 1, 1, 1, 1], [1, 1, 1, 1, 1], [1, 1, 1, 1, 1], [0, 0, 1, 0, 0]], dtype=np.uint8
)  # cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (5, 5))


def foreground_mask(frame: np.ndarray, gain: float, background: np.ndarray, tau: float) -> np.ndarray:
    """Binary mask ``|c I - B| > tau`` of one frame with brightness correction ``c = gain``.

    Evaluated in 8 bits as the equivalent ``|I - round(B / c)| > tau / c`` with
    ``cv2.convertScaleAbs``, ``cv2.absdiff`` and ``cv2.threshold`` (rounding costs at most
    half a grey level, far below ``tau >= TAU_MIN``).
    """
    scaled = cv2.convertScaleAbs(background, alpha=1.0 / gain)
    _, mask = cv2.threshold(cv2.absdiff(frame, scaled), tau / gain, 255, cv2.THRESH_BINARY)
    return mask


def _blobs_of(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Clean one mask (open, close) and return its blobs' centroids ``(n, 2)`` and areas ``(n,)``."""
    mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, _OPEN)
    mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, _CLOSE)
    _, _, stats, centroids = cv2.connectedComponentsWithStats(mask, connectivity=8)
    return centroids[1:], stats[1:, cv2.CC_STAT_AREA]


def find_blobs(
    stack: np.ndarray, gains: np.ndarray, background: np.ndarray, tau: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """All blobs of at least ``MIN_AREA_ABS`` pixels: frame index, centroid ``(u, v)``, area.

    One OpenCV pass per frame (mask, morphology, connected components); the pixel work is
    inside OpenCV, the loop is over frames only.
    """
    return _collect_blobs([_blobs_of(foreground_mask(img, float(g), background, tau)) for img, g in zip(stack, gains)])


def _collect_blobs(found: list) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-frame ``(centroids, areas)`` -> frame index, centroid, area of the blobs of at least
    ``MIN_AREA_ABS`` pixels."""
    frame = np.repeat(np.arange(len(found), dtype=np.int64), [len(a) for _, a in found])
    uv = np.concatenate([c for c, _ in found]).reshape(-1, 2)
    area = np.concatenate([a for _, a in found]).astype(np.int64)
    keep = area >= MIN_AREA_ABS
    return frame[keep], uv[keep], area[keep]


def default_min_area(area: np.ndarray) -> float:
    """``max(MIN_AREA_ABS, MIN_AREA_FRACTION * median(area))`` (``MIN_AREA_ABS`` if no blob)."""
    if len(area) == 0:
        return float(MIN_AREA_ABS)
    return max(float(MIN_AREA_ABS), MIN_AREA_FRACTION * float(np.median(area)))


# --------------------------------------------------------------------------- identity


def link_tracks(frame: np.ndarray, xy: np.ndarray, *, gate: float, max_gap: int) -> np.ndarray:
    """Track index (0, 1, ... in birth order) of each detection, by frame-to-frame assignment.

    Inherently sequential over frames. For frame ``k`` with detections ``z_1..z_n`` and live
    tracks ``j`` (last seen at frame ``l_j``, position ``p_j``, ``k - l_j <= max_gap``):

    * cost ``C_ij = |z_i - p_j|`` (``scipy.spatial.distance.cdist``);
    * minimum-cost assignment ``scipy.optimize.linear_sum_assignment(C)``;
    * a pair is kept only if ``C_ij <= gate * (k - l_j)`` (gate = largest move per frame);
    * detections left unmatched start new tracks (birth, in detection order);
    * a track unmatched for more than ``max_gap`` frames is dead and never matched again.

    ``frame`` must be sorted ascending.
    """
    n = len(frame)
    track = np.full(n, -1, np.int64)
    last_xy = np.zeros((n, 2))
    last_frame = np.zeros(n, np.int64)
    n_tracks = 0
    starts = np.flatnonzero(np.r_[True, frame[1:] != frame[:-1]]) if n else np.zeros(0, int)
    ends = np.r_[starts[1:], n]
    for s, e in zip(starts, ends):
        k = frame[s]
        live = np.flatnonzero(k - last_frame[:n_tracks] <= max_gap)
        assigned = np.full(e - s, -1, np.int64)
        if live.size:
            cost = _distance.cdist(xy[s:e], last_xy[live])
            rows, cols = _optimize.linear_sum_assignment(cost)
            ok = cost[rows, cols] <= gate * (k - last_frame[live[cols]])
            assigned[rows[ok]] = live[cols[ok]]
        born = np.flatnonzero(assigned < 0)
        assigned[born] = n_tracks + np.arange(born.size)
        n_tracks += born.size
        track[s:e] = assigned
        last_xy[assigned] = xy[s:e]
        last_frame[assigned] = k
    return track


# --------------------------------------------------------------------------- checking against truth


def match_frames(camera_truth: pl.DataFrame, truth: pl.DataFrame, *, period: float | None = None) -> pl.DataFrame:
    """Match camera points to true points, one-to-one per frame.

    Each camera time is joined to the nearest truth time within ``period / 2`` (``period``
    defaults to the median step between distinct truth times). In every joined frame the
    camera points ``c_i`` and true points ``q_j`` are matched by
    ``_optimize.linear_sum_assignment(|c_i - q_j|)``.

    Returns
    -------
    polars.DataFrame
        Columns ``t`` (truth time), ``camera`` (camera target), ``target`` (true target,
        null for a true point left unmatched), ``error`` (world distance, null if unmatched).
        Camera points left unmatched (more detections than targets) have ``target`` null and
        ``camera`` set; true points left unmatched have ``camera`` null.
    """
    times = truth["t"].unique().sort().to_numpy()
    if period is None:
        period = float(np.median(np.diff(times))) if len(times) > 1 else 1.0
    cam_times = pl.DataFrame({"t_cam": camera_truth["t"].unique().sort()})
    joined = cam_times.join_asof(
        pl.DataFrame({"t": times}).with_columns(pl.col("t").alias("t_true")),
        left_on="t_cam",
        right_on="t",
        strategy="nearest",
        tolerance=period / 2,
    ).drop_nulls("t_true")
    cam = camera_truth.join(joined.select("t_cam", "t_true"), left_on="t", right_on="t_cam").sort("t_true", "target")
    tru = truth.join(joined.select("t_true"), left_on="t", right_on="t_true").sort("t", "target")
    cam_t, tru_t = cam["t_true"].to_numpy(), tru["t"].to_numpy()
    cam_xy, tru_xy = cam.select("x", "y").to_numpy(), tru.select("x", "y").to_numpy()
    cam_id, tru_id = cam["target"].to_numpy(), tru["target"].to_numpy()
    frames = joined["t_true"].to_numpy()
    cb, tb = np.searchsorted(cam_t, frames), np.searchsorted(tru_t, frames)
    ce, te = np.searchsorted(cam_t, frames, "right"), np.searchsorted(tru_t, frames, "right")
    out_t, out_c, out_q, out_e = [], [], [], []
    for f, c0, c1, q0, q1 in zip(frames, cb, ce, tb, te):  # one assignment per frame
        cost = _distance.cdist(cam_xy[c0:c1], tru_xy[q0:q1])
        r, c = _optimize.linear_sum_assignment(cost)
        lone_c = np.setdiff1d(np.arange(c1 - c0), r)
        lone_q = np.setdiff1d(np.arange(q1 - q0), c)
        m = len(r) + len(lone_c) + len(lone_q)
        out_t.append(np.full(m, f))
        out_c.append(np.r_[cam_id[c0:c1][r], cam_id[c0:c1][lone_c], np.full(len(lone_q), None)])
        out_q.append(np.r_[tru_id[q0:q1][c], np.full(len(lone_c), None), tru_id[q0:q1][lone_q]])
        out_e.append(np.r_[cost[r, c], np.full(len(lone_c) + len(lone_q), np.nan)])
    if not out_t:
        return pl.DataFrame(schema={"t": pl.Float64, "camera": pl.String, "target": pl.String, "error": pl.Float64})
    return pl.DataFrame(
        {
            "t": np.concatenate(out_t).astype(float),
            "camera": pl.Series(np.concatenate(out_c), dtype=pl.String),
            "target": pl.Series(np.concatenate(out_q), dtype=pl.String),
            "error": np.concatenate(out_e),
        }
    ).with_columns(pl.col("error").fill_nan(None))


def truth_error(
    camera_truth: pl.DataFrame, truth: pl.DataFrame, *, diagonal: float, period: float | None = None
) -> dict[str, float | int]:
    """Localisation error of the camera tracks against the true positions.

    Uses :func:`match_frames` (frames present in both, nearest time within half a frame
    period, one-to-one matching per frame).

    Returns
    -------
    dict
        ``mean`` = mean world distance over matched pairs; ``rel`` = ``mean / diagonal``;
        ``matched`` = number of matched pairs; ``missed`` = true points with no detection;
        ``extra`` = detections with no true point; ``frames`` = frames compared.
    """
    m = match_frames(camera_truth, truth, period=period)
    pairs = m.filter(pl.col("error").is_not_null())
    mean = float(pairs["error"].mean()) if pairs.height else float("nan")
    return {
        "mean": mean,
        "rel": mean / diagonal,
        "matched": pairs.height,
        "missed": m.filter(pl.col("camera").is_null()).height,
        "extra": m.filter(pl.col("target").is_null()).height,
        "frames": m["t"].n_unique(),
    }
