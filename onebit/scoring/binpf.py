"""Scoring of ``binpf``: the people count per frame against the truth (the MOT metrics are
added for every tracker by :mod:`onebit.scoring.mot`)."""

from __future__ import annotations

import numpy as np
import polars as pl

from onebit.core.site import Site

NAME = "binpf"


def true_counts(frame_t: np.ndarray, truth: pl.DataFrame) -> np.ndarray:
    """Targets with a truth sample within half a frame period of each frame time ``(T,)``."""
    if frame_t.size == 0:
        return np.zeros(0, dtype=np.int64)
    half = 0.5 * (float(np.median(np.diff(frame_t))) if frame_t.size > 1 else 1.0)
    tt = truth["t"].to_numpy()
    k = np.searchsorted(frame_t, tt)
    lo = np.clip(k - 1, 0, frame_t.size - 1)
    hi = np.clip(k, 0, frame_t.size - 1)
    near = np.where(np.abs(frame_t[lo] - tt) <= np.abs(frame_t[hi] - tt), lo, hi)
    ok = np.abs(frame_t[near] - tt) <= half + 1e-9
    pairs = pl.DataFrame({"f": near[ok], "target": truth["target"].to_numpy()[ok]}).unique()
    return np.bincount(pairs["f"].to_numpy(), minlength=frame_t.size).astype(np.int64)


def score(tracker: str, tables: dict, site: Site, region_graph=None) -> tuple[list[tuple[str, str, float, str]], dict]:
    """Report rows ``filter_count_error`` (mean over *every* frame of the filter, a frame with
    people and no track included, of |reported tracks - people present|; the MOT scorer's
    ``count_error`` is the same over the truth frames, :mod:`onebit.scoring.mot`), ``count_bias`` (mean of the signed
    difference), ``count_expected_error`` (same with the filter's expected count
    :math:`\\sum_i r_i`), and without truth ``tracks``, ``births``, ``merges``, ``max_reported``."""
    frames = tables.get(f"{NAME}_frames")
    tracks = tables.get(f"{NAME}_tracks")
    if frames is None or tracks is None:
        return [], {}
    rows = [
        (NAME, "tracks", float(tracks["track"].n_unique()), "tracks"),
        (NAME, "births", float(frames["births"].sum()), "tracks"),
        (NAME, "merges", float(frames["merges"].sum()), "tracks"),
        (NAME, "max_reported", float(frames["reported"].max() or 0), "tracks"),
    ]
    truth = tables.get("truth")
    if truth is None or truth.height == 0 or frames.height == 0:
        return rows, {}
    n = true_counts(frames["t"].to_numpy(), truth)
    rep = frames["reported"].to_numpy()
    rows += [
        (NAME, "filter_count_error", float(np.abs(rep - n).mean()), "people/frame"),
        (NAME, "count_bias", float((rep - n).mean()), "people/frame"),
        (NAME, "count_expected_error", float(np.abs(frames["count"].to_numpy() - n).mean()), "people/frame"),
    ]
    return rows, {
        f"{NAME}_counts": pl.DataFrame({"t": frames["t"], "true": n, "reported": rep, "expected": frames["count"]})
    }
