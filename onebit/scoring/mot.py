"""Standard multi-target tracking metrics of every tracker, as the maintained libraries compute them.

Beside each paper's own metrics (docs/architecture.md, "Scores and reports"):

* MOTA, MOTP, ID switches (CLEAR MOT, Bernardin & Stiefelhagen 2008) and IDF1 (Ristani et al.
  2016) as ``motmetrics`` computes them;
* HOTA, DetA, AssA (Luiten et al. 2021) as ``trackeval`` does (``motmetrics`` 1.4.0 has no HOTA).

Computed over all frames at once (:func:`mot_metrics`: a compiled CLEAR pass, the ID measures
by one assignment, HOTA vectorised; ties between optimal matchings go to the libraries' own
solvers); the libraries' per-frame APIs (:func:`mot_metrics_libraries`) are the test oracle
(``tests/scoring/test_mot_fast.py``; docs/metrics.md, "How the scorer computes").

Frames, objects, hypotheses: every frame is scored
--------------------------------------------------
The frames are **every truth frame** (each distinct ``t`` of the truth), plus each tracker
sample time with no truth frame within half the truth's period (there the truth says nobody is
present, so every track is a false positive). The objects of a frame are the targets with a
truth sample within half the truth's period, at the nearest time
(:func:`~onebit.scoring.association.truth_at`); the hypotheses are the tracks of the
tracker's sample nearest to the frame within half the tracker's own period (its median gap
between sample times: an estimate holds for its slot). A frame with truth and no estimate
therefore counts every present target as a miss -- a tracker silent while people are present
scores MOTA <= 0, never NaN or a score over the few frames it spoke. The beams tracker is
event-driven (a row per crossing, the region held in between), so each agent holds its last
region at every truth frame.

Count error: at every frame ``|#hypotheses - #objects|``; ``count_error`` is its mean over the
frames (people per frame), ``max_tracks`` the most hypotheses at one frame.

Metric gates
------------
Beside its paper's gate, every tracker whose tracks have positions (``x``, ``y``) is scored at
metric gates in world units (``[scores] gates_m``, default ``[1.0]`` metre; the irtracking
authors' protocol is 1.5 m): rows ``mota@1m``, ``idf1@1m``, ``hota@1m``, ``motp@1m``, ...,
the same for every tracker, so trackers of different papers compare. The paper-gate rows keep
their names (``mota``, ``idf1``, ...) and carry their gate in the unit (``fraction @ 1 hops``).

Distance :math:`d` between an object and a hypothesis, by the space the tracks live in:

* ``point``: Euclidean distance, site units;
* ``node``: hops between the true node and the track's node on the sensor graph;
* ``region``: hops between the true region and the track's region on the region graph.

Gate and similarity
-------------------
Every tracker has one gate :math:`\\gamma` (in the paper's unit), declared with it in the
pipeline's stage list (``TrackerEntry.gate``, :mod:`onebit.pipeline.stages`). CLEAR and
the ID measures match an object and a hypothesis only when :math:`d \\le \\gamma`
(``motmetrics`` distance, ``NaN`` beyond the gate). HOTA needs a similarity in
:math:`[0, 1]`:

.. math::

    s = \\max\\big(0,\\; 1 - d / (2\\gamma)\\big),

so the gate sits at :math:`s = 0.5`, the MOT Challenge's IoU threshold (``trackeval``'s CLEAR
default), and HOTA, averaged over :math:`\\alpha = 0.05, 0.10, \\dots, 0.95` as TrackEval
reports it, integrates localisation from :math:`d \\le 0.1\\gamma` to :math:`d \\le 1.9\\gamma`.

.. math::

    \\mathrm{MOTA} = 1 - \\frac{\\sum_f (\\mathrm{FN}_f + \\mathrm{FP}_f + \\mathrm{IDSW}_f)}{\\sum_f \\mathrm{GT}_f},
    \\quad
    \\mathrm{MOTP} = \\frac{\\sum_{f, i} d_{f,i}}{\\sum_f c_f},
    \\quad
    \\mathrm{IDF1} = \\frac{2\\,\\mathrm{IDTP}}{2\\,\\mathrm{IDTP} + \\mathrm{IDFP} + \\mathrm{IDFN}},

.. math::

    \\mathrm{DetA}_\\alpha = \\frac{|\\mathrm{TP}|}{|\\mathrm{TP}| + |\\mathrm{FN}| + |\\mathrm{FP}|},
    \\quad
    \\mathrm{AssA}_\\alpha = \\frac{1}{|\\mathrm{TP}|} \\sum_{c \\in \\mathrm{TP}}
        \\frac{|\\mathrm{TPA}(c)|}{|\\mathrm{TPA}(c)| + |\\mathrm{FNA}(c)| + |\\mathrm{FPA}(c)|},
    \\quad
    \\mathrm{HOTA}_\\alpha = \\sqrt{\\mathrm{DetA}_\\alpha \\mathrm{AssA}_\\alpha}.

These metrics bring their own matchings by definition (per frame for CLEAR, global for IDF1,
alignment-weighted for HOTA); the paper metrics use the one association of
:mod:`onebit.scoring.association`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
import polars as pl

from onebit.core.errors import OnebitError
from onebit.core.lazy import lazy_module
from onebit.core.region_graph import RegionGraph
from onebit.core.site import Site
from onebit.core.units import to_site_units
from onebit.models.graph_hmm.eatg import hop_matrix
from onebit.scoring import mot_kernels
from onebit.scoring.association import truth_at
from onebit.scoring.crossings import truth_regions
from onebit.scoring.findinghumo import truth_nodes

mm = lazy_module("motmetrics")
_trackeval_metrics = lazy_module("trackeval.metrics")

ReportRow = tuple[str, str, float, str]

#: Frame tables of :func:`mot_metrics`.
OBJECTS = pl.Schema({"t": pl.Float64, "target": pl.String})
HYPOTHESES = pl.Schema({"t": pl.Float64, "track": pl.String})
DISTANCES = pl.Schema({"t": pl.Float64, "target": pl.String, "track": pl.String, "distance": pl.Float64})


@dataclass(frozen=True)
class Gate:
    """The MOT gate of one tracker.

    space : where its tracks live: ``point`` (x, y), ``node`` (sensor-graph node) or
        ``region`` (region-graph region).
    size : the gate in ``unit``.
    unit : ``cells`` (the tracker's grid cell), ``R`` (the CLUSTERTRACK sensing radius),
        ``sensing radius`` (the site's median sensor radius), ``hops`` or ``m`` (metres,
        converted to the site's units).
    reason : why this gate, in the paper's terms.
    """

    space: Literal["point", "node", "region"]
    size: float
    unit: Literal["cells", "R", "sensing radius", "hops", "m"]
    reason: str


_METRICS = ("mota", "motp", "idf1", "idp", "idr", "num_switches", "num_misses", "num_false_positives", "num_objects")


# --------------------------------------------------------------------------- the metrics


def similarity(distance: np.ndarray, gate: float) -> np.ndarray:
    """HOTA similarity :math:`s = \\max(0, 1 - d / (2\\gamma))`; 0 where ``distance`` is NaN."""
    s = 1.0 - np.asarray(distance, float) / (2.0 * gate)
    return np.clip(np.nan_to_num(s, nan=0.0), 0.0, 1.0)


@dataclass(frozen=True)
class FrameArrays:
    """The frames as flat arrays: frame ``f`` (time ``t[f]``) has the object ids
    ``oids[o_ptr[f]:o_ptr[f+1]]`` (ascending), the hypothesis ids ``hids[h_ptr[f]:h_ptr[f+1]]``
    (ascending) and their row-major (objects x hypotheses) distances ``d[d_ptr[f]:d_ptr[f+1]]``
    (NaN where no distance is given). Ids are 0-based codes of the sorted target and track
    names (``n_gt_ids``, ``n_tracker_ids`` of them)."""

    t: np.ndarray
    o_ptr: np.ndarray
    oids: np.ndarray
    h_ptr: np.ndarray
    hids: np.ndarray
    d_ptr: np.ndarray
    d: np.ndarray
    n_gt_ids: int
    n_tracker_ids: int

    @property
    def n_frames(self) -> int:
        return len(self.t)

    def pair_index(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """For every entry of ``d``: its object's and its hypothesis' position in ``oids`` and
        ``hids``, and its frame."""
        n_o, n_h = np.diff(self.o_ptr), np.diff(self.h_ptr)
        f = np.repeat(np.arange(self.n_frames), n_o * n_h)
        q = np.arange(len(self.d)) - self.d_ptr[f]
        nh = np.maximum(n_h[f], 1)
        return self.o_ptr[f] + q // nh, self.h_ptr[f] + q % nh, f


def frame_arrays(objects: pl.DataFrame, hypotheses: pl.DataFrame, distances: pl.DataFrame) -> FrameArrays:
    """:class:`FrameArrays` of the frame tables (every distinct ``t`` of either is a frame)."""
    targets = objects["target"].unique().sort()
    tracks = hypotheses["track"].unique().sort()
    o = objects.select("t", "target").unique().join(targets.to_frame().with_row_index("oi"), on="target")
    h = hypotheses.select("t", "track").unique().join(tracks.to_frame().with_row_index("hi"), on="track")
    frames = pl.concat([o["t"], h["t"]]).unique().sort()
    o = o.sort("t", "oi")
    h = h.sort("t", "hi")
    full = (
        o.join(h, on="t")  # every object x hypothesis of a frame
        .join(distances.select("t", "target", "track", "distance"), on=["t", "target", "track"], how="left")
        .sort("t", "oi", "hi")
    )
    fr = frames.to_numpy().astype(float)
    ot, ht = o["t"].to_numpy(), h["t"].to_numpy()
    o_ptr = np.searchsorted(ot, fr, side="left")
    h_ptr = np.searchsorted(ht, fr, side="left")
    o_ptr = np.r_[o_ptr, len(ot)].astype(np.int64)
    h_ptr = np.r_[h_ptr, len(ht)].astype(np.int64)
    d_ptr = np.r_[0, np.cumsum(np.diff(o_ptr) * np.diff(h_ptr))].astype(np.int64)
    return FrameArrays(
        t=fr,
        o_ptr=o_ptr,
        oids=o["oi"].to_numpy().astype(np.int64),
        h_ptr=h_ptr,
        hids=h["hi"].to_numpy().astype(np.int64),
        d_ptr=d_ptr,
        d=full["distance"].fill_null(np.nan).to_numpy().astype(float),
        n_gt_ids=targets.len(),
        n_tracker_ids=tracks.len(),
    )


def frame_blocks(objects: pl.DataFrame, hypotheses: pl.DataFrame, distances: pl.DataFrame):
    """The frames as the libraries take them: per frame the object ids, the hypothesis ids and
    the (objects x hypotheses) distance matrix (NaN where no distance is given).

    Ids are 0-based codes of the sorted target and track names (``trackeval`` wants
    contiguous ids). Returns ``(frames, object_ids, hypothesis_ids, matrices)``.
    """
    fa = frame_arrays(objects, hypotheses, distances)
    n_o, n_h = np.diff(fa.o_ptr), np.diff(fa.h_ptr)
    r = range(fa.n_frames)
    obj_ids = [fa.oids[fa.o_ptr[f] : fa.o_ptr[f + 1]] for f in r]
    hyp_ids = [fa.hids[fa.h_ptr[f] : fa.h_ptr[f + 1]] for f in r]
    mats = [fa.d[fa.d_ptr[f] : fa.d_ptr[f + 1]].reshape(n_o[f], n_h[f]) for f in r]
    return fa.t, obj_ids, hyp_ids, mats


# --------------------------------------------------------------------------- CLEAR MOT


def _clear_frame(
    f: int, fa: FrameArrays, gate: float, last: np.ndarray, counts: np.ndarray, events: np.ndarray
) -> None:
    """One frame of CLEAR MOT exactly as ``motmetrics.MOTAccumulator.update`` does it, with its
    own assignment solver (``motmetrics.lap.linear_sum_assignment``): the frames the kernel
    hands over (a tie between optimal assignments, or too large to enumerate)."""
    oa, ob, ha, hb = fa.o_ptr[f], fa.o_ptr[f + 1], fa.h_ptr[f], fa.h_ptr[f + 1]
    oids, hids = fa.oids[oa:ob], fa.hids[ha:hb]
    no, nh = len(oids), len(hids)
    d = fa.d[fa.d_ptr[f] : fa.d_ptr[f + 1]].reshape(no, nh)
    d = np.where(d <= gate, d, np.nan)
    om, hm = np.zeros(no, bool), np.zeros(nh, bool)
    matches = switches = 0
    ev: list[float] = []
    if no and nh:
        for i in range(no):  # (1) continuing pairs
            if last[oids[i]] < 0:
                continue
            (j,) = np.nonzero(~hm & (hids == last[oids[i]]))
            if len(j) and np.isfinite(d[i, j[0]]):
                om[i] = hm[j[0]] = True
                matches += 1
                ev.append(d[i, j[0]])
        d[om, :] = np.nan
        d[:, hm] = np.nan
        for i, j in zip(*mm.lap.linear_sum_assignment(d)):  # (2) the rest
            if not np.isfinite(d[i, j]):
                continue
            o, h = oids[i], hids[j]
            if last[o] >= 0 and last[o] != h:
                switches += 1
            else:
                matches += 1
            ev.append(d[i, j])
            last[o] = h
            om[i] = hm[j] = True
    misses, fps = no - int(om.sum()), nh - int(hm.sum())
    ev += [0.0] * (misses + fps)
    e = counts[4]
    events[e : e + len(ev)] = ev
    counts += (matches, switches, misses, fps, len(ev))


def clear_counts(fa: FrameArrays, gate: float, *, compiled: bool = True) -> tuple[np.ndarray, float]:
    """CLEAR MOT over all frames (:func:`onebit.scoring.mot_kernels.clear_pass`, motmetrics'
    rule: last frame's matches that are still within the gate are kept, then the fewest
    misses at the least distance): ``([matches, switches, misses, false positives], sum of
    matched distances)``, the sum taken over motmetrics' event column in its order (so MOTP is
    its float). The kernel runs until a frame it cannot decide alone, which :func:`_clear_frame`
    scores with motmetrics' solver, and resumes after it; ``compiled=False`` runs the kernel's
    plain Python (its test oracle)."""
    run = mot_kernels.clear_pass if compiled else mot_kernels.clear_pass.py_func
    last = np.full(max(fa.n_gt_ids, 1), -1, np.int64)
    counts = np.zeros(5, np.int64)
    events = np.zeros(len(fa.oids) + len(fa.hids))
    f = 0
    while f < fa.n_frames:
        f = run(f, fa.o_ptr, fa.oids, fa.h_ptr, fa.hids, fa.d_ptr, fa.d, float(gate), last, counts, events)
        if f < fa.n_frames:
            _clear_frame(f, fa, gate, last, counts, events)
            f += 1
    return counts[:4], float(events[: counts[4]].sum())


# --------------------------------------------------------------------------- ID measures


def id_measures(fa: FrameArrays, gate: float) -> dict[str, float]:
    """IDTP, IDFP, IDFN, IDF1, IDP, IDR (Ristani et al. 2016, as ``motmetrics`` computes them):
    the one-to-one assignment of track ids to truth ids that maximises the frames they are
    matched within the gate (IDTP); IDFN = objects - IDTP, IDFP = hypotheses - IDTP."""
    n_obj, n_hyp = len(fa.oids), len(fa.hids)
    oi, hi, _ = fa.pair_index()
    near = fa.d <= gate
    nt = max(fa.n_tracker_ids, 1)
    tp = np.bincount(fa.oids[oi[near]] * nt + fa.hids[hi[near]], minlength=max(fa.n_gt_ids, 1) * nt)
    tp = tp.reshape(-1, nt)
    idtp = 0.0
    if tp.any():
        r, c = _linear_sum_assignment(tp, maximize=True)
        idtp = float(tp[r, c].sum())
    with np.errstate(divide="ignore", invalid="ignore"):
        return {
            "idtp": idtp,
            "idfp": n_hyp - idtp,
            "idfn": n_obj - idtp,
            "idf1": float(np.divide(2 * idtp, n_obj + n_hyp)),
            "idp": float(np.divide(idtp, n_hyp)),
            "idr": float(np.divide(idtp, n_obj)),
        }


# --------------------------------------------------------------------------- HOTA

#: TrackEval's HOTA localisation thresholds.
ALPHAS = np.arange(0.05, 0.99, 0.05)
_EPS = np.finfo("float").eps


def hota_curves(fa: FrameArrays, gate: float, *, compiled: bool = True) -> dict[str, np.ndarray]:
    """HOTA, DetA, AssA at each of :data:`ALPHAS`, as ``trackeval.metrics.HOTA.eval_sequence``
    computes them, over all frames at once (the same float operations in the same order).

    The global alignment of ids :math:`A(g, k) = P / (n_g + n_k - P)`, with :math:`P` the sum
    over frames of :math:`s_{gk} / (\\sum_{k'} s_{gk'} + \\sum_{g'} s_{g'k} - s_{gk})`; each
    frame's matching maximises :math:`\\sum A \\cdot s`
    (:func:`onebit.scoring.mot_kernels.hota_matches`; ties go to TrackEval's solver, scipy's
    ``linear_sum_assignment``); a matched pair counts at :math:`\\alpha` when
    :math:`s \\ge \\alpha`. ``compiled=False`` runs the matching kernel's plain Python."""
    n = len(ALPHAS)
    n_obj, n_hyp = len(fa.oids), len(fa.hids)
    out = {k: np.zeros(n) for k in ("HOTA", "DetA", "AssA")}
    if n_hyp == 0 or n_obj == 0:
        return out
    ng, nt = fa.n_gt_ids, fa.n_tracker_ids
    s = similarity(fa.d, gate)
    oi, hi, _ = fa.pair_index()
    rows = np.bincount(oi, weights=s, minlength=n_obj)  # per frame and object: sum over its tracks
    cols = np.bincount(hi, weights=s, minlength=n_hyp)  # per frame and track: sum over its objects
    denom = cols[hi] + rows[oi] - s
    iou = np.zeros_like(s)
    ok = denom > 0 + _EPS
    iou[ok] = s[ok] / denom[ok]
    cell = fa.oids[oi] * nt + fa.hids[hi]
    pmc = np.bincount(cell, weights=iou, minlength=ng * nt).reshape(ng, nt)
    gt_count = np.bincount(fa.oids, minlength=ng).astype(float)[:, None]
    tr_count = np.bincount(fa.hids, minlength=nt).astype(float)[None, :]
    align = pmc / (gt_count + tr_count - pmc)
    score = align.ravel()[cell] * s
    pairs = np.empty(min(n_obj, n_hyp), np.int64)
    handed = np.empty(fa.n_frames, np.int64)
    match = mot_kernels.hota_matches if compiled else mot_kernels.hota_matches.py_func
    n_p, n_h = match(fa.o_ptr, fa.h_ptr, fa.d_ptr, score, pairs, handed)
    chosen = [pairs[:n_p]]
    for f in handed[:n_h]:  # ties and large frames: TrackEval's own solver
        no, nh = fa.o_ptr[f + 1] - fa.o_ptr[f], fa.h_ptr[f + 1] - fa.h_ptr[f]
        r, c = _linear_sum_assignment(-score[fa.d_ptr[f] : fa.d_ptr[f + 1]].reshape(no, nh))
        chosen.append(fa.d_ptr[f] + r * nh + c)
    p = np.concatenate(chosen)
    sp, cp = s[p], cell[p]
    for a, alpha in enumerate(ALPHAS):
        hit = sp >= alpha - _EPS
        tp = float(hit.sum())
        mc = np.bincount(cp[hit], minlength=ng * nt).reshape(ng, nt).astype(float)
        ass = mc / np.maximum(1, gt_count + tr_count - mc)
        out["AssA"][a] = np.sum(mc * ass) / np.maximum(1, tp)
        out["DetA"][a] = tp / np.maximum(1, tp + (n_obj - tp) + (n_hyp - tp))
    out["HOTA"] = np.sqrt(out["DetA"] * out["AssA"])
    return out


def _linear_sum_assignment(cost: np.ndarray, maximize: bool = False):
    from scipy.optimize import linear_sum_assignment  # deferred: scipy's import is not free

    return linear_sum_assignment(cost, maximize=maximize)


# --------------------------------------------------------------------------- the metrics


def mot_metrics(
    objects: pl.DataFrame, hypotheses: pl.DataFrame, distances: pl.DataFrame, *, gate: float
) -> dict[str, float]:
    """MOTA, MOTP, IDF1, ID switches (CLEAR MOT and ID measures, as ``motmetrics`` computes them)
    and HOTA, DetA, AssA (as ``trackeval`` does), over all frames at once.

    Parameters
    ----------
    objects : ``(t, target)``, the targets present at each frame (:data:`OBJECTS`).
    hypotheses : ``(t, track)``, the tracks present at each frame (:data:`HYPOTHESES`).
    distances : ``(t, target, track, distance)`` for object-hypothesis pairs of a frame
        (:data:`DISTANCES`); a pair without a row cannot match.
    gate : :math:`\\gamma`, largest distance of a CLEAR / ID match; the HOTA similarity is
        :math:`\\max(0, 1 - d / 2\\gamma)` (module docstring).

    Returns
    -------
    ``mota, motp, idf1, idp, idr, id_switches, misses, false_positives, objects, frames, hota,
    deta, assa``; NaN where undefined (MOTP without a match, MOTA without objects).

    Equal to :func:`mot_metrics_libraries` (the libraries' per-frame APIs, kept as the test
    oracle; ``tests/scoring/test_mot_fast.py``): the sequential CLEAR rule runs compiled
    (:func:`clear_counts`), the ID measures and HOTA are vectorised over frames
    (:func:`id_measures`, :func:`hota_curves`).
    """
    if not gate > 0:
        raise OnebitError(f"mot_metrics: gate={gate!r}; expected a positive distance")
    fa = frame_arrays(objects, hypotheses, distances)
    n_obj = len(fa.oids)
    (matches, switches, misses, fps), dsum = clear_counts(fa, gate)
    ident = id_measures(fa, gate)
    hota = hota_curves(fa, gate)
    detections = matches + switches
    nan = float("nan")
    return {
        "mota": 1.0 - (misses + switches + fps) / n_obj if n_obj else nan,  # undefined without truth
        "motp": dsum / detections if detections else nan,
        "idf1": ident["idf1"] if fa.n_frames else nan,
        "idp": ident["idp"] if fa.n_frames else nan,
        "idr": ident["idr"] if fa.n_frames else nan,
        "id_switches": float(switches),
        "misses": float(misses),
        "false_positives": float(fps),
        "objects": float(n_obj),
        "frames": float(fa.n_frames),
        "hota": float(np.mean(hota["HOTA"])),
        "deta": float(np.mean(hota["DetA"])),
        "assa": float(np.mean(hota["AssA"])),
    }


def mot_metrics_libraries(
    objects: pl.DataFrame, hypotheses: pl.DataFrame, distances: pl.DataFrame, *, gate: float
) -> dict[str, float]:
    """:func:`mot_metrics` through the libraries' own per-frame APIs (``MOTAccumulator.update``,
    TrackEval's per-timestep lists): the oracle of the fast scorer, one Python call per frame."""
    if not gate > 0:
        raise OnebitError(f"mot_metrics: gate={gate!r}; expected a positive distance")
    frames, obj_ids, hyp_ids, mats = frame_blocks(objects, hypotheses, distances)
    acc = mm.MOTAccumulator(auto_id=False)
    sims = []
    for f, (o, h, d) in enumerate(zip(obj_ids, hyp_ids, mats)):  # the libraries' per-frame API
        acc.update(o, h, np.where(d <= gate, d, np.nan), frameid=f)
        sims.append(similarity(d, gate))
    n_obj, n_hyp = sum(len(o) for o in obj_ids), sum(len(h) for h in hyp_ids)
    if len(frames):
        s = mm.metrics.create().compute(acc, metrics=list(_METRICS), name="run", return_dataframe=False)
    else:
        s = dict.fromkeys(_METRICS, 0)
        s.update(mota=np.nan, motp=np.nan, idf1=np.nan, idp=np.nan, idr=np.nan)
    data = {
        "num_timesteps": len(frames),
        "num_gt_ids": objects["target"].n_unique(),
        "num_tracker_ids": hypotheses["track"].n_unique(),
        "num_gt_dets": n_obj,
        "num_tracker_dets": n_hyp,
        "gt_ids": obj_ids,
        "tracker_ids": hyp_ids,
        "similarity_scores": sims,
    }
    hota = _trackeval_metrics.HOTA().eval_sequence(data)
    return {
        "mota": float(s["mota"]) if n_obj else float("nan"),  # 1 - FP / 0: undefined without truth
        "motp": float(s["motp"]),
        "idf1": float(s["idf1"]),
        "idp": float(s["idp"]),
        "idr": float(s["idr"]),
        "id_switches": float(s["num_switches"]),
        "misses": float(s["num_misses"]),
        "false_positives": float(s["num_false_positives"]),
        "objects": float(n_obj),
        "frames": float(len(frames)),
        "hota": float(np.mean(hota["HOTA"])),
        "deta": float(np.mean(hota["DetA"])),
        "assa": float(np.mean(hota["AssA"])),
    }


# --------------------------------------------------------------------------- frames of a tracker


def _period(t: pl.Series) -> float:
    u = t.unique().sort().to_numpy()
    return float(np.median(np.diff(u))) if len(u) > 1 else 1.0


def scoring_frames(truth_t: pl.Series, hyp_t: pl.Series) -> tuple[pl.Series, float, float]:
    """The frames of the module docstring: every truth time, plus each hypothesis time with no
    truth time within half the truth's period. Returns ``(frames, truth_tol, hyp_tol)``: the
    half periods (+1e-9) within which a frame takes the truth's and the tracker's nearest sample."""
    tt = truth_t.unique().sort()
    ht = hyp_t.unique().sort()
    tol_o = (_period(tt) if tt.len() > 1 else _period(ht)) / 2 + 1e-9
    tol_h = (_period(ht) if ht.len() > 1 else _period(tt)) / 2 + 1e-9
    if tt.len() == 0:
        return ht.cast(pl.Float64), tol_o, tol_h
    lone = (
        pl.DataFrame({"t": ht.cast(pl.Float64)})
        .join_asof(
            pl.DataFrame({"t_o": tt.cast(pl.Float64)}),
            left_on="t",
            right_on="t_o",
            strategy="nearest",
            tolerance=tol_o,
            check_sortedness=False,
        )
        .filter(pl.col("t_o").is_null())["t"]
    )
    return pl.concat([tt.cast(pl.Float64), lone]).unique().sort(), tol_o, tol_h


def hypotheses_at(frames: pl.Series, hyp: pl.DataFrame, tolerance: float) -> pl.DataFrame:
    """The rows of ``hyp`` (``t``, ``track``, ...) of the tracker's sample time nearest to each
    frame within ``tolerance``, stamped with the frame's ``t`` (none where it has no sample)."""
    if hyp.height == 0 or frames.len() == 0:
        return hyp.clear()
    ht = hyp.select(pl.col("t").alias("t_h")).unique().sort("t_h")
    pick = (
        pl.DataFrame({"t": frames.cast(pl.Float64)})
        .sort("t")
        .join_asof(ht, left_on="t", right_on="t_h", strategy="nearest", tolerance=tolerance, check_sortedness=False)
        .drop_nulls("t_h")
    )
    return pick.join(hyp.rename({"t": "t_h"}), on="t_h").drop("t_h").select(hyp.columns).sort("t", "track")


def point_frames(tracks: pl.DataFrame, truth: pl.DataFrame) -> tuple[pl.DataFrame, pl.DataFrame, pl.DataFrame]:
    """Objects, hypotheses and Euclidean distances of point tracks at every frame (module
    docstring: :func:`scoring_frames`; ``y`` null = 1D, taken 0)."""
    hyp = tracks.drop_nulls("x").select("t", "track", "x", pl.col("y").fill_null(0.0))
    tru = truth.drop_nulls("x").with_columns(pl.col("y").fill_null(0.0))
    frames, tol_o, tol_h = scoring_frames(tru["t"], hyp["t"])
    obj = truth_at(frames, tru, tolerance=tol_o)
    hyp = hypotheses_at(frames, hyp, tol_h)
    dist = obj.join(hyp, on="t").select(
        "t",
        "target",
        "track",
        distance=((pl.col("x") - pl.col("true_x")) ** 2 + (pl.col("y") - pl.col("true_y")) ** 2).sqrt(),
    )
    return obj.select(list(OBJECTS)), hyp.select(list(HYPOTHESES)), dist


def node_frames(
    tracks: pl.DataFrame, truth: pl.DataFrame, site: Site
) -> tuple[pl.DataFrame, pl.DataFrame, pl.DataFrame]:
    """Objects, hypotheses and hop distances of sensor-graph node tracks at every frame
    (:func:`scoring_frames`; unreachable nodes: no pair)."""
    g = site.sensor_graph
    hops = hop_matrix(g.nodes, g.edges).astype(float)
    hops[hops > len(g.nodes)] = np.nan
    hyp = tracks.drop_nulls("node").select("t", "track", "node")
    tru = truth_nodes(truth, site).drop_nulls("node")
    frames, tol_o, tol_h = scoring_frames(tru["t"], hyp["t"])
    obj = truth_at(frames, tru, tolerance=tol_o, columns=("node",))
    hyp = hypotheses_at(frames, hyp, tol_h)
    return obj.select(list(OBJECTS)), hyp.select(list(HYPOTHESES)), _hop_pairs(obj, hyp, "node", list(g.nodes), hops)


def count_errors(objects: pl.DataFrame, hypotheses: pl.DataFrame) -> pl.DataFrame:
    """Per frame (every frame of either table): ``objects``, ``hypotheses`` and
    ``error = |hypotheses - objects|`` (people)."""
    o = objects.group_by("t").agg(objects=pl.len())
    h = hypotheses.group_by("t").agg(hypotheses=pl.len())
    return (
        o.join(h, on="t", how="full", coalesce=True)
        .with_columns(pl.col("objects").fill_null(0).cast(pl.Int64), pl.col("hypotheses").fill_null(0).cast(pl.Int64))
        .with_columns(error=(pl.col("hypotheses") - pl.col("objects")).abs())
        .sort("t")
    )


def region_frames(
    tracks: pl.DataFrame, truth: pl.DataFrame, rg: RegionGraph
) -> tuple[pl.DataFrame, pl.DataFrame, pl.DataFrame]:
    """Objects, hypotheses and hop distances of region tracks held between their rows.

    Frames = the truth's sample times; each track holds the region of its last row at or
    before the frame (from its first row on).
    """
    tru = truth_regions(truth.select("t", "target", "x", "y"), rg).drop_nulls("region")
    obj = tru.select("t", "target", true_region="region").sort("t")
    names = tracks["track"].unique().sort()
    grid = pl.DataFrame({"t": obj["t"].unique().sort()}).join(names.to_frame(), how="cross").sort("t")
    est = tracks.drop_nulls("region").select("t", "track", "region").sort("t")
    hyp = grid.join_asof(est, on="t", by="track", strategy="backward", check_sortedness=False).drop_nulls("region")
    hops = rg.hop_distance().astype(float)
    hops[hops < 0] = np.nan
    return obj.select(list(OBJECTS)), hyp.select(list(HYPOTHESES)), _hop_pairs(obj, hyp, "region", list(rg.names), hops)


def _hop_pairs(obj: pl.DataFrame, hyp: pl.DataFrame, col: str, names: list[str], hops: np.ndarray) -> pl.DataFrame:
    """``(t, target, track, distance)``: hops between the object's ``true_<col>`` and the hypothesis' ``col``."""
    pairs = obj.join(hyp, on="t")
    code = dict(zip(names, range(len(names))))
    i = pairs[f"true_{col}"].replace_strict(code, default=-1, return_dtype=pl.Int64).to_numpy()
    j = pairs[col].replace_strict(code, default=-1, return_dtype=pl.Int64).to_numpy()
    d = np.where((i >= 0) & (j >= 0), hops[np.maximum(i, 0), np.maximum(j, 0)], np.nan)
    return (
        pairs.select("t", "target", "track")
        .with_columns(distance=pl.Series(d, dtype=pl.Float64).fill_nan(None))
        .drop_nulls("distance")
    )


def sensing_radius(site: Site) -> float | None:
    """Median sensing radius of the site's sensors: a proximity sensor's ``R_o``, a motion
    sensor's ``range`` or the radius of the disc of its field of view's area."""
    r = [p.r_outer for p in site.proximity_sensors]
    for m in site.motion_sensors:
        if m.fov is not None:
            r.append(float(np.sqrt(m.fov.area / np.pi)))
        elif m.range is not None:
            r.append(float(m.range))
    return float(np.median(r)) if r else None


def gate_distance(tracker: str, gate: Gate, tables: dict, site: Site) -> float | None:
    """:math:`\\gamma` in the distance's unit (site units for points, hops otherwise), or
    ``None`` when the unit is unknown (no cell, no R, no sensor)."""
    if gate.unit == "hops":
        return gate.size
    if gate.unit == "m":
        return float(to_site_units(gate.size, "m", site.units))
    if gate.unit == "cells":
        it = tables.get(f"{tracker}_iterations")
        cell = float(it["cell"][0]) if it is not None and it.height and "cell" in it.columns else 1.0
        return gate.size * cell
    if gate.unit == "R":
        params = tables.get(f"{tracker}_params")
        return gate.size * float(params["R"][0]) if params is not None and params.height else None
    radius = sensing_radius(site)
    return gate.size * radius if radius else None


#: Default metric gates (metres) of every positional tracker (``[scores] gates_m``).
METRIC_GATES_M = (1.0,)


def gate_label(size_m: float) -> str:
    """``1m``, ``1.5m``: the suffix of the metric-gate rows (``mota@1.5m``)."""
    return f"{float(size_m):g}m"


def metric_gate_rows(
    tracker: str, tracks: pl.DataFrame, truth: pl.DataFrame, site: Site, gates_m: tuple[float, ...]
) -> list[ReportRow]:
    """MOTA, MOTP, IDF1, ID switches, HOTA, misses and false positives at each metric gate
    (metres, converted to the site's units), every frame scored; ``count_error`` and
    ``max_tracks`` once. Empty when the tracks have rows but none with a position (a tracker
    that answers in nodes or regions only); a tracker with no row at all is scored (all misses)."""
    if not gates_m or "x" not in tracks.columns or (tracks.height and tracks["x"].null_count() == tracks.height):
        return []
    obj, hyp, dist = point_frames(tracks, truth)
    ce = count_errors(obj, hyp)
    rows: list[ReportRow] = [
        (tracker, "count_error", float(ce["error"].mean()) if ce.height else float("nan"), "people/frame"),
        (tracker, "max_tracks", float(ce["hypotheses"].max()) if ce.height else 0.0, "tracks"),
    ]
    for g_m in gates_m:
        g = float(to_site_units(g_m, "m", site.units))
        m = mot_metrics(obj, hyp, dist, gate=g)
        lab = gate_label(g_m)
        rows += [
            (tracker, f"mota@{lab}", m["mota"], "fraction"),
            (tracker, f"idf1@{lab}", m["idf1"], "fraction"),
            (tracker, f"hota@{lab}", m["hota"], "fraction"),
            (tracker, f"motp@{lab}", m["motp"], site.units),
            (tracker, f"id_switches@{lab}", m["id_switches"], "switches"),
            (tracker, f"misses@{lab}", m["misses"], "target-frames"),
            (tracker, f"false_positives@{lab}", m["false_positives"], "track-frames"),
        ]
    return rows


def mot_rows(
    tracker: str,
    gate: Gate | None,
    tables: dict,
    site: Site,
    region_graph: RegionGraph | None,
    *,
    gates_m: tuple[float, ...] = METRIC_GATES_M,
) -> list[ReportRow]:
    """The MOT report rows of one tracker at its paper's gate: ``mota``, ``motp``, ``idf1``,
    ``id_switches``, ``hota``, ``deta``, ``assa`` (unit ``fraction @ <gate> <unit>``),
    ``mot_gate``, ``mot_misses``, ``mot_false_positives``, ``mot_frames``; then, for tracks
    with positions, the metric-gate rows (:func:`metric_gate_rows`). Every frame is scored
    (module docstring). None without truth or without tracks."""
    tracks, truth = tables.get(f"{tracker}_tracks"), tables.get("truth")
    if tracks is None or truth is None or truth.height == 0:
        return []
    metric = metric_gate_rows(tracker, tracks, truth, site, tuple(gates_m))
    if gate is None:
        return metric
    g = gate_distance(tracker, gate, tables, site)
    if g is None or (gate.space == "region" and region_graph is None):
        return metric
    if gate.space == "point":
        obj, hyp, dist = point_frames(tracks, truth)
        unit = site.units
    elif gate.space == "node":
        obj, hyp, dist = node_frames(tracks, truth, site)
        unit = "hops"
    else:
        obj, hyp, dist = region_frames(tracks, truth, region_graph)
        unit = "hops"
    m = mot_metrics(obj, hyp, dist, gate=g)
    frac = f"fraction @ {gate.size:g} {gate.unit}"
    rows = [
        (tracker, "mota", m["mota"], frac),
        (tracker, "motp", m["motp"], unit),
        (tracker, "idf1", m["idf1"], frac),
        (tracker, "id_switches", m["id_switches"], "switches"),
        (tracker, "hota", m["hota"], frac),
        (tracker, "deta", m["deta"], frac),
        (tracker, "assa", m["assa"], frac),
        (tracker, "mot_gate", g, unit),
        (tracker, "mot_misses", m["misses"], "target-frames"),
        (tracker, "mot_false_positives", m["false_positives"], "track-frames"),
        (tracker, "mot_frames", m["frames"], "frames"),
    ]
    if not metric and gate.space != "point":
        ce = count_errors(obj, hyp)
        metric = [
            (tracker, "count_error", float(ce["error"].mean()) if ce.height else float("nan"), "people/frame"),
            (tracker, "max_tracks", float(ce["hypotheses"].max()) if ce.height else 0.0, "tracks"),
        ]
    return rows + metric
