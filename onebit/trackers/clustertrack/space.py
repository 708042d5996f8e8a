"""The sequence of feasible spaces {F[t]} that CLUSTERTRACK samples from, in 1-D or 2-D.

:class:`FeasibleSpace` holds, per instant, what the algorithm and Appendix B need: the size
S_F(t), a uniform sampler, the component of a point, the lower bound on the target count
and the per-component bounds. It can be *restricted* (F[t_o] replaced by one component c_o)
and *reversed* in time without recomputing anything (Appendix B).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from onebit.trackers.clustertrack.counting import snapshot_bounds_1d, snapshot_bounds_2d
from onebit.trackers.clustertrack.feasible import (
    Feasible1D,
    Raster,
    SensorArray,
    disk_masks,
    feasible_1d,
    feasible_raster,
    make_raster,
    raster_components,
    sample_cell_centres,
    sample_intervals,
)


@dataclass(frozen=True)
class FeasibleSpace:
    """F[t] for instants ``order`` (indices into the original instants).

    ``dim`` is 1 or 2; positions are ``(..., dim)`` arrays. ``only`` maps an original
    instant to the single component F is restricted to there (Appendix B).
    """

    dim: int
    times: np.ndarray  # (T,) seconds of the original instants
    sizes_all: np.ndarray  # (T,) S_F of the original instants
    bounds_all: np.ndarray  # (T,) lower bound on the count
    comp_bounds_all: tuple  # T arrays: lower bound per component
    f1d: tuple = ()  # T Feasible1D (1-D)
    raster: Raster | None = None  # 2-D
    masks: np.ndarray | None = None  # (T, cells) bool F (2-D)
    labels: np.ndarray | None = None  # (T, cells) component labels, 0 outside (2-D)
    order: np.ndarray = field(default=None)  # (T',) original instant of each step
    only: tuple = ()  # ((t, c), ...)
    minimal_targets: tuple = ()  # T arrays: positions of a minimal target set (1-D, Theorem 4)
    cells: tuple = ()  # T arrays: the F cells of each instant (2-D), so sampling costs |F|, not the grid
    cell_xy: tuple = ()  # T arrays (|F|, 2): their centres
    reading: np.ndarray | None = None  # (T,) index of each instant's distinct reading (F is shared within one)

    # ----------------------------------------------------------------- construction

    @classmethod
    def build(
        cls, on: np.ndarray, times: np.ndarray, sensors: SensorArray, boundary, *, dim: int, cell: float
    ) -> FeasibleSpace:
        """From readings ``on (T, n)`` (sensor order of ``sensors``) at ``times (T,)``.

        F, its components and their bounds are a function of the readings alone, so they are
        computed once per *distinct* reading (a sensor array repeats a handful of patterns
        over a long log: 22 in 10^6 rows of the simulated line) and shared by the instants
        that have it -- the same values, in time and work bounded by the distinct patterns,
        not the log's length."""
        on = np.asarray(on, dtype=bool)
        T = on.shape[0]
        if T:
            uniq, inv = np.unique(on, axis=0, return_inverse=True)
            inv = inv.reshape(-1)
        else:
            uniq, inv = on, np.zeros(0, dtype=np.int64)
        if dim == 1:
            minx, _, maxx, _ = boundary.bounds
            x = sensors.xy[:, 0]
            # per distinct reading: F is a different number of intervals each time (each call is
            # vectorised over sensors); Theorem 4's greedy is sequential in its picks
            fu = [feasible_1d(x, row, sensors.r_inner, sensors.r_outer, minx, maxx) for row in uniq]
            bu = [snapshot_bounds_1d(f) for f in fu]
            fs = tuple(fu[k] for k in inv)
            b = [bu[k] for k in inv]
            return cls(
                1,
                np.asarray(times, float),
                np.array([f.size for f in fs]),
                np.array([x[0] for x in b], dtype=np.int64),
                tuple(x[1] for x in b),
                f1d=fs,
                order=np.arange(T),
                minimal_targets=tuple(x[2] for x in b),
                reading=inv,
            )
        raster = make_raster(boundary, cell)
        outer = disk_masks(raster, sensors.xy, sensors.r_outer, closed=True)
        inner = disk_masks(raster, sensors.xy, sensors.r_inner, closed=False)
        masks_u = feasible_raster(uniq, outer, inner, raster.inside)
        labels_u = np.zeros(masks_u.shape, dtype=np.int64)
        bounds, cb = [], []
        # Per distinct reading: one OpenCV labelling (~30 us) and the bounds vectorised over
        # on-sensors x cells. Stacking them into one image and one (reading, sensor) x cells
        # pass was measured 10x slower (re-numbering the labels and gathering a label row per
        # pair cost more than the calls), so the loop stays.
        for k in range(uniq.shape[0]):
            n, lab = raster_components(masks_u[k], raster)
            labels_u[k] = lab
            lb, per = snapshot_bounds_2d(lab, n, np.flatnonzero(uniq[k]), outer)
            bounds.append(lb)
            cb.append(per)
        cells_u = [np.flatnonzero(m) for m in masks_u]
        xy_u = [raster.centres_of(c) for c in cells_u]
        return cls(
            2,
            np.asarray(times, float),
            (masks_u.sum(axis=1) * raster.cell**2)[inv],
            np.array(bounds, dtype=np.int64)[inv] if T else np.zeros(0, dtype=np.int64),
            tuple(cb[k] for k in inv),
            raster=raster,
            masks=masks_u[inv],
            labels=labels_u[inv],
            order=np.arange(T),
            cells=tuple(cells_u[k] for k in inv),
            cell_xy=tuple(xy_u[k] for k in inv),
            reading=inv,
        )

    # ----------------------------------------------------------------- views

    @property
    def T(self) -> int:
        return int(self.order.size)

    def restricted(self, t: int, c: int) -> FeasibleSpace:
        """F with F[t] (original instant) replaced by its component ``c``."""
        return replace(self, only=tuple(x for x in self.only if x[0] != t) + ((int(t), int(c)),))

    def reversed(self) -> FeasibleSpace:
        return replace(self, order=self.order[::-1].copy())

    def _only(self, t: int) -> int | None:
        for tt, c in self.only:
            if tt == t:
                return c
        return None

    # ----------------------------------------------------------------- per step

    def size(self, step: int) -> float:
        """S_F at ``step`` (with a restriction applied)."""
        t = int(self.order[step])
        c = self._only(t)
        if c is None:
            return float(self.sizes_all[t])
        if self.dim == 1:
            iv = self.f1d[t].components[c]
            return float(iv[1] - iv[0])
        return float(np.count_nonzero(self.labels[t] == c + 1) * self.raster.cell**2)

    def sample(self, step: int, n: int, rng: np.random.Generator, *, compiled: bool = False) -> np.ndarray:
        """``(n, dim)`` points uniform on F at ``step`` (``compiled``: the mapping of the draws
        compiled, same points)."""
        t = int(self.order[step])
        c = self._only(t)
        if self.dim == 1:
            iv = self.f1d[t].components
            if c is not None:
                iv = iv[c : c + 1]
            return sample_intervals(iv, n, rng, compiled=compiled)[:, None]
        xy = self.cell_xy[t]
        if c is not None:
            xy = xy[self.labels[t][self.cells[t]] == c + 1]
        return sample_cell_centres(xy, self.raster.cell, n, rng, compiled=compiled)

    def component_of(self, t: int, pts: np.ndarray) -> np.ndarray:
        """Component index (0-based) of points ``(m, dim)`` at original instant ``t``; -1 outside F.

        In 2-D a point just outside F (a track between rasterised components) takes the
        component of its nearest F cell within one cell.
        """
        pts = np.asarray(pts, float).reshape(-1, self.dim)
        if self.dim == 1:
            return self.f1d[t].component_of(pts[:, 0])
        r = self.raster
        j = np.floor((pts[:, 0] - r.x0) / r.cell).astype(np.int64)
        i = np.floor((pts[:, 1] - r.y0) / r.cell).astype(np.int64)
        lab = self.labels[t].reshape(r.height, r.width)
        best = np.full(len(pts), -1, dtype=np.int64)
        for di, dj in ((0, 0), (0, 1), (1, 0), (0, -1), (-1, 0), (1, 1), (1, -1), (-1, 1), (-1, -1)):
            ii, jj = i + di, j + dj
            ok = (ii >= 0) & (ii < r.height) & (jj >= 0) & (jj < r.width)
            val = np.where(ok, lab[np.clip(ii, 0, r.height - 1), np.clip(jj, 0, r.width - 1)], 0) - 1
            best = np.where(best < 0, val, best)
        return best

    def components_of(self, tracks: np.ndarray) -> np.ndarray:
        """``(N, T)`` component index (0-based, -1 outside F) of every track ``(N, T, dim)`` at
        every original instant: :meth:`component_of` for all instants at once (2-D: one
        vectorised lookup over tracks x instants; 1-D: one interval search per instant)."""
        N, T = tracks.shape[0], self.sizes_all.size
        out = np.full((N, T), -1, dtype=np.int64)
        if N == 0 or T == 0:
            return out
        if self.dim == 1:
            if self.reading is None:
                for t in range(T):  # a different set of intervals per instant
                    out[:, t] = self.f1d[t].component_of(tracks[:, t, 0])
                return out
            # one lookup per distinct reading, over every instant that has it
            order = np.argsort(self.reading, kind="stable")
            starts = np.flatnonzero(np.r_[True, np.diff(self.reading[order]) != 0])
            for ts in np.split(order, starts[1:]):
                out[:, ts] = self.f1d[ts[0]].component_of(tracks[:, ts, 0])
            return out
        r = self.raster
        j = np.floor((tracks[..., 0] - r.x0) / r.cell).astype(np.int64)
        i = np.floor((tracks[..., 1] - r.y0) / r.cell).astype(np.int64)
        lab = self.labels.reshape(T, r.height, r.width)
        tt = np.broadcast_to(np.arange(T)[None, :], (N, T))
        for di, dj in ((0, 0), (0, 1), (1, 0), (0, -1), (-1, 0), (1, 1), (1, -1), (-1, 1), (-1, -1)):
            ii, jj = i + di, j + dj
            ok = (ii >= 0) & (ii < r.height) & (jj >= 0) & (jj < r.width)
            val = np.where(ok, lab[tt, np.clip(ii, 0, r.height - 1), np.clip(jj, 0, r.width - 1)], 0) - 1
            out = np.where(out < 0, val, out)
        return out

    @property
    def max_lower_bound(self) -> int:
        return int(self.bounds_all.max()) if self.bounds_all.size else 0

    def f_at(self, t: int) -> Feasible1D:
        return self.f1d[t]
