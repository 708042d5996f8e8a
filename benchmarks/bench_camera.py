"""Camera reader speed, side by side with a plain OpenCV peer in the same process.

For ``N`` in (100, 300, 1000) frames a lab-site video (two agents, see
:func:`lab_truth`) is rendered once with :func:`render_overhead_video`, then decoded and
processed by

* **ours**: :func:`onebit.readers.camera.read_camera` (decode, lighting normalisation,
  median background, threshold, morphology, connected components, homography, assignment
  tracking);
* **peer**: decode + ``cv2.createBackgroundSubtractorMOG2`` + ``connectedComponentsWithStats``
  per frame, no tracking and no world coordinates.

Both include decoding. Printed: frames per second of each and the ratio ``ours / peer``
(above 1 means ours is faster). Run with ``python -m benchmarks.bench_camera``.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import cv2
import numpy as np
import polars as pl

from onebit.core.site import Site
from onebit.datasets.builtin import builtin_site
from onebit.datasets.camera_render import render_overhead_video
from onebit.readers.camera import read_camera, truth_error

SIZES = (100, 300, 1000)
RADIUS = 0.15


def lab_truth(site: Site, n_frames: int) -> pl.DataFrame:
    """Two agents: one walking along the top corridor, one circling in the right-hand room."""
    cam = site.camera
    t = cam.t0 + np.arange(n_frames) / cam.fps
    phase = 2 * np.pi * t / 8.0
    a = pl.DataFrame(
        {"t": t, "target": "a", "x": 0.5 + 4.5 * np.abs((t / 10.0) % 2.0 - 1.0), "y": np.full_like(t, 3.5)}
    )
    b = pl.DataFrame({"t": t, "target": "b", "x": 4.6 + 0.6 * np.cos(phase), "y": 1.2 + 0.6 * np.sin(phase)})
    return pl.concat([a, b]).sort("t", "target")


def peer(path: Path) -> int:
    """MOG2 background subtraction + connected components over every frame; returns blob count."""
    cap = cv2.VideoCapture(str(path), cv2.CAP_FFMPEG)
    mog = cv2.createBackgroundSubtractorMOG2(detectShadows=False)
    blobs = 0
    while True:
        ok, img = cap.read()
        if not ok:
            break
        mask = mog.apply(cv2.cvtColor(img, cv2.COLOR_BGR2GRAY))
        n, _, _, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
        blobs += n - 1
    cap.release()
    return blobs


def _best_of(fn, repeats: int) -> tuple[float, object]:
    """Smallest wall time of ``repeats`` calls and the last result."""
    best, out = float("inf"), None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def main() -> None:
    site = builtin_site("lab")
    print(f"camera reader vs MOG2 peer, lab site {site.camera.width}x{site.camera.height} @ {site.camera.fps:g} fps")
    print(f"{'frames':>7} {'ours fps':>10} {'peer fps':>10} {'ours/peer':>10} {'rel error':>10} {'tracks':>7}")
    with tempfile.TemporaryDirectory() as tmp:
        for n in SIZES:
            path = Path(tmp) / f"lab_{n}.mp4"
            truth = lab_truth(site, n)
            render_overhead_video(path, site, truth, seed=0, radius=RADIUS)
            repeats = 3 if n <= 300 else 1
            t_ours, res = _best_of(lambda: read_camera(path, site), repeats)
            t_peer, _ = _best_of(lambda: peer(path), repeats)
            err = truth_error(res.truth, truth, diagonal=site.diagonal)
            ours_fps, peer_fps = res.frames / t_ours, res.frames / t_peer
            print(
                f"{n:>7} {ours_fps:>10.0f} {peer_fps:>10.0f} {ours_fps / peer_fps:>10.2f} "
                f"{err['rel']:>10.2e} {res.truth['target'].n_unique():>7}"
            )


if __name__ == "__main__":
    main()
