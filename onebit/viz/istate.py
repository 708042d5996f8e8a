"""Rerun logging of O'Kane I-states and active tracking.

An I-state is a union of elements; each element is a product of n regions (one target in
each). Entities (all through ``send_columns``, one call per entity):

* ``<tracker>/istate/fill`` -- every element's regions **filled**, one colour per element slot
  blended onto the map background, as one image per stage placed under the site drawing
  (Rerun's 2D views have no filled polygon and draw images opaque; a PNG of flat colours
  costs a few kB per stage);
* ``<tracker>/istate/<element>/<k>`` -- region ``k`` of element slot ``element`` at every
  stage, **outlined** in the slot's colour; a stage where the slot is unused holds no strips;
* ``<tracker>/sensing/<sensor>`` -- static sensing regions, dim; ``<tracker>/detections`` the
  regions reading 1 at each stage, bright red;
* ``<tracker>/elements`` (count) and ``<tracker>/area`` (site units squared) -- Scalars, one
  plot each (and ``<tracker>/P`` for active tracking);
* ``<tracker>/tracks/<track>`` -- the point summary used for scoring (:mod:`onebit.viz.tracks`);
* active tracking: ``<tracker>/trackers/<j>`` points, ``.../sensing`` the 9 squares,
  ``.../destination``; ``<tracker>/links`` communication links; ``truth/<target>``.
"""

from __future__ import annotations

import numpy as np
import polars as pl
import shapely

from onebit.core.lazy import lazy_module
from onebit.viz import colors, paths
from onebit.viz._series import rings, strips_array
from onebit.viz.families import GENERIC, Look
from onebit.viz.frame import log_world_frame
from onebit.viz.radii import ui_points
from onebit.viz.tracks import log_point_tracks
from onebit.viz.truth import log_truth

rr = lazy_module("rerun")
cv2 = lazy_module("cv2")

#: Element slot colours: the palette's strong colours, grey and brown last.
_ELEMENT_ORDER = (0, 1, 2, 3, 4, 6, 8, 9, 5, 7)
#: Opacity of one element's fill (overlapping elements add up).
FILL_ALPHA = 0.25
#: Long side of the fill image in pixels.
FILL_PIXELS = 360
OUTLINE_WIDTH = ui_points(1.5)
SENSING = (150, 150, 150, 90)


def element_color(e: int, *, alpha: int = 255) -> tuple[int, int, int, int]:
    """Colour of element slot ``e``: distinct for the first ten slots."""
    r, g, b = (int(c) for c in colors.PALETTE[_ELEMENT_ORDER[e % len(_ELEMENT_ORDER)]])
    return (r, g, b, int(alpha))


def _strips_per_stage(geoms: np.ndarray):
    """The rings of one geometry per stage (``None`` = absent) as one ``LineStrip2D`` Arrow
    array and the number of strips per stage (for ``.partition``)."""
    strips, counts = [], []
    for g in geoms:
        rs = [] if g is None or g.is_empty else rings(g)
        strips.extend(rs)
        counts.append(len(rs))
    points = np.concatenate(strips) if strips else np.zeros((0, 2))
    return strips_array(points, [len(r) for r in strips]), counts


def _series(
    rec: rr.RecordingStream, entity: str, name: str, color, t: np.ndarray, values: np.ndarray, *, step: bool = True
) -> None:
    mode = rr.components.InterpolationMode.StepAfter if step else None
    rec.log(entity, rr.SeriesLines(colors=color, names=[name], widths=[2.0], interpolation_mode=mode), static=True)
    rec.send_columns(
        entity, indexes=[paths.time_column(t)], columns=rr.Scalars.columns(scalars=np.asarray(values, float))
    )


class FillRaster:
    """The pixel grid of the fill image: ``cell`` world units per pixel from ``(x0, y0)``;
    pixel row ``r`` covers ``y0 + r * cell`` (rows grow with y, the frame flips them on screen)."""

    def __init__(self, bounds: tuple[float, float, float, float], *, pixels: int = FILL_PIXELS) -> None:
        minx, miny, maxx, maxy = bounds
        span = max(maxx - minx, maxy - miny, 1e-9)
        self.cell = span / pixels
        self.x0, self.y0 = float(minx), float(miny)
        self.width = max(1, int(np.ceil((maxx - minx) / self.cell)))
        self.height = max(1, int(np.ceil((maxy - miny) / self.cell)))

    def transform(self) -> rr.Transform3D:
        return rr.Transform3D(translation=[self.x0, self.y0, 0.0], scale=[self.cell, self.cell, 1.0])

    def mask(self, geom) -> np.ndarray:
        """``(height, width)`` uint8 mask of a polygon (holes cut out) or multipolygon."""
        m = np.zeros((self.height, self.width), np.uint8)
        for g in getattr(geom, "geoms", [geom]):
            if g.geom_type != "Polygon" or g.is_empty:
                continue
            ext = self._pixels(np.asarray(g.exterior.coords)[:, :2])
            cv2.fillPoly(m, [ext], 1, lineType=cv2.LINE_8, shift=4)
            for ring in g.interiors:
                cv2.fillPoly(m, [self._pixels(np.asarray(ring.coords)[:, :2])], 0, lineType=cv2.LINE_8, shift=4)
        return m

    def _pixels(self, xy: np.ndarray) -> np.ndarray:
        return np.round((xy - [self.x0, self.y0]) / self.cell * 16.0).astype(np.int32)  # shift = 4


def _png(rgb: np.ndarray) -> bytes:
    ok, png = cv2.imencode(".png", np.ascontiguousarray(rgb[..., ::-1]))
    if not ok:  # pragma: no cover - OpenCV always encodes a valid array
        raise RuntimeError("OpenCV could not encode an I-state fill image")
    return png.tobytes()


def fill_images(grid: np.ndarray, raster: FillRaster, *, background=colors.MAP_BACKGROUND, keys=None) -> list[bytes]:
    """One RGB PNG per stage of ``grid`` (``(E, n, K)`` geometries or ``None``): every region of
    every element filled in the element's colour at :data:`FILL_ALPHA` over ``background`` and
    over each other (a region inside another of the product shows brighter); pixels of no
    element are the background.

    A pixel's colour depends only on which regions cover it, in drawing order, so the image is
    drawn as a label per pixel (which regions so far) and a small table of label colours,
    blended as :func:`onebit._testing.oracles.fill_images_reference` blends each pixel (equal images, tested): per
    region one mask and one table lookup, no float image. ``keys`` (one hashable per stage,
    e.g. the stage's region WKBs) reuses the PNG of an earlier stage with the same key: an
    unobserved I-state that has filled the free space stays the same for many stages.
    """
    E, _, K = grid.shape
    bg = np.asarray(background[:3], np.float32)
    elem = [np.asarray(element_color(e)[:3], np.float32) for e in range(E)]
    done: dict = {}
    out = []
    for s in range(K):
        key = keys[s] if keys is not None else None
        if key is not None and key in done:
            out.append(done[key])
            continue
        label = np.zeros((raster.height, raster.width), np.int32)  # 0 = background
        table = [bg]
        for e in range(E):
            for g in grid[e, :, s]:
                if g is None or g.is_empty:
                    continue
                m = raster.mask(g).astype(bool)
                under = label[m]
                present = np.flatnonzero(np.bincount(under, minlength=len(table)))
                remap = np.arange(len(table), dtype=np.int32)
                remap[present] = len(table) + np.arange(len(present), dtype=np.int32)
                table += [elem[e] * FILL_ALPHA + table[i] * (1 - FILL_ALPHA) for i in present]
                label[m] = remap[under]
        lut = np.stack(table).round().clip(0, 255).astype(np.uint8)
        png = _png(lut[label])
        if key is not None:
            done[key] = png
        out.append(png)
    return out


def _region_grid(regions: pl.DataFrame, K: int) -> np.ndarray:
    n = int(regions["k"].max()) + 1
    E = int(regions["element"].max()) + 1
    grid = np.full((E, n, K), None, dtype=object)
    geoms = shapely.from_wkb(regions["wkb"].to_numpy())
    grid[regions["element"].to_numpy(), regions["k"].to_numpy(), regions["stage"].to_numpy()] = geoms
    return grid


def _stage_keys(regions: pl.DataFrame, K: int) -> list:
    """One key per stage: its (element, k, WKB) triples, equal for stages with the same regions."""
    keys: list = [()] * K
    g = regions.sort(["stage", "element", "k"]).group_by("stage", maintain_order=True).agg("element", "k", "wkb")
    for stage, e, k, w in g.iter_rows():
        keys[stage] = tuple(zip(e, k, w))
    return keys


def log_istate_regions(
    rec: rr.RecordingStream, tracker: str, regions: pl.DataFrame, times: np.ndarray, *, bounds=None, fill: bool = True
) -> None:
    """Every (element slot, k) of the ``regions`` table (t, stage, element, k, wkb) over ``times``:
    outlines per slot and region, and (``fill``) one fill image per stage over ``bounds``
    (minx, miny, maxx, maxy; default: the regions' own bounds)."""
    if regions.height == 0:
        return
    log_world_frame(rec, paths.tracker_root(tracker))
    K = len(times)
    grid = _region_grid(regions, K)
    E, n, _ = grid.shape
    tc = paths.time_column(times)
    for e in range(E):
        col = element_color(e, alpha=230)
        for k in range(n):
            strips, counts = _strips_per_stage(grid[e, k])
            ent = paths.istate(tracker, str(e), k)
            rec.log(
                ent,
                rr.LineStrips2D.from_fields(
                    colors=[col], radii=OUTLINE_WIDTH, labels=[f"element {e + 1}"], show_labels=False, draw_order=15.0
                ),
                static=True,
            )
            rec.send_columns(ent, indexes=[tc], columns=rr.LineStrips2D.columns(strips=strips).partition(counts))
    if not fill:
        return
    if bounds is None:
        bounds = shapely.union_all([g for g in grid.ravel() if g is not None]).bounds
    raster = FillRaster(bounds)
    ent = paths.join(paths.tracker_root(tracker), "istate", "fill")
    rec.log(ent, raster.transform(), static=True)
    rec.log(ent, rr.EncodedImage.from_fields(media_type="image/png", draw_order=-5.0), static=True)
    rec.send_columns(
        ent, indexes=[tc], columns=rr.EncodedImage.columns(blob=fill_images(grid, raster, keys=_stage_keys(regions, K)))
    )


def log_istate_run(
    rec: rr.RecordingStream,
    tracker: str,
    regions: pl.DataFrame,
    summary: pl.DataFrame,
    *,
    site=None,
    sensing: dict | None = None,
    detections: pl.DataFrame | None = None,
) -> None:
    """The ``istate`` stage: I-state regions (filled and outlined), sensing regions, detections,
    element count and area."""
    root = paths.tracker_root(tracker)
    log_world_frame(rec, root)
    for sid, g in (sensing or {}).items():
        rec.log(
            paths.join(root, "sensing", paths.part(sid)),
            rr.LineStrips2D(
                rings(g), colors=[SENSING], radii=rr.Radius.ui_points(1.0), labels=[str(sid)], show_labels=False
            ),
            static=True,
        )
    if summary.height == 0:
        return
    times = summary["t"].to_numpy()
    bounds = site.boundary.bounds if site is not None else None
    log_istate_regions(rec, tracker, regions, times, bounds=bounds)
    _series(
        rec,
        paths.join(root, "elements"),
        "elements in the I-state",
        (255, 235, 130),
        times,
        summary["elements"].to_numpy(),
    )
    _series(rec, paths.join(root, "area"), "area of the I-state", (120, 200, 255), times, summary["area"].to_numpy())
    if detections is not None and detections.height and sensing:
        d = detections.sort("stage", maintain_order=True)
        strips = [s for sid in d["sensor"] for s in rings(sensing[sid])]
        per = [len(rings(sensing[sid])) for sid in d["sensor"]]
        lens = np.zeros(len(times), dtype=np.int64)
        np.add.at(lens, d["stage"].to_numpy(), per)
        ent = paths.join(root, "detections")
        rec.log(
            ent,
            rr.LineStrips2D.from_fields(colors=[colors.FIRING], radii=rr.Radius.ui_points(2.5), draw_order=18.0),
            static=True,
        )
        rec.send_columns(
            ent, indexes=[paths.time_column(times)], columns=rr.LineStrips2D.columns(strips=strips).partition(lens)
        )


def log_active_tracking(
    rec: rr.RecordingStream,
    tracker: str,
    *,
    times: np.ndarray,
    targets: np.ndarray,
    trackers: np.ndarray,
    destinations: np.ndarray,
    sensing: np.ndarray,
    links: list[np.ndarray],
    elements: np.ndarray,
    performance: np.ndarray,
    regions: pl.DataFrame | None = None,
    free_space=None,
) -> None:
    """An active-tracking simulation (section VII).

    ``targets (K, n, 2)``, ``trackers (K, m, 2)``, ``destinations (K, m, 2)`` (each tracker's
    own destination), ``sensing (K, m)`` geometries (the tracker's sensing squares),
    ``links`` one ``(L, 2, 2)`` array of segments per stage, ``elements (K, m)``, ``P (K,)``,
    ``regions`` the I-state regions of tracker 0 (``istate`` schema).
    """
    tc = paths.time_column(times)
    root = paths.tracker_root(tracker)
    log_world_frame(rec, root)
    if free_space is not None:
        log_world_frame(rec, paths.SITE)
        rec.log(
            paths.join(paths.SITE, "free_space"), rr.LineStrips2D(rings(free_space), colors=[colors.WALL]), static=True
        )
    K, n = targets.shape[:2]
    truth = pl.DataFrame(
        {
            "t": np.repeat(times, n),
            "target": [f"target{i + 1}" for i in range(n)] * K,
            "x": targets[:, :, 0].ravel(),
            "y": targets[:, :, 1].ravel(),
        }
    )
    log_truth(rec, truth, diagonal=None)
    for j in range(trackers.shape[1]):
        base = paths.join(root, "trackers", paths.part(j))
        col = colors.color_of(f"tracker{j}")
        rec.log(
            base,
            rr.Points2D.from_fields(
                colors=[col], radii=rr.Radius.ui_points(6.0), labels=[f"tracker {j + 1}"], show_labels=True
            ),
            static=True,
        )
        rec.send_columns(base, indexes=[tc], columns=rr.Points2D.columns(positions=trackers[:, j]))
        rec.log(
            paths.join(base, "destination"),
            rr.Points2D.from_fields(colors=[col], radii=rr.Radius.ui_points(3.0)),
            static=True,
        )
        rec.send_columns(
            paths.join(base, "destination"), indexes=[tc], columns=rr.Points2D.columns(positions=destinations[:, j])
        )
        strips, counts = _strips_per_stage(sensing[:, j])
        rec.log(paths.join(base, "sensing"), rr.LineStrips2D.from_fields(colors=[col]), static=True)
        rec.send_columns(
            paths.join(base, "sensing"), indexes=[tc], columns=rr.LineStrips2D.columns(strips=strips).partition(counts)
        )
        _series(rec, paths.join(root, "elements", paths.part(j)), f"tracker {j + 1}", col, times, elements[:, j])
    lens = [len(seg) for seg in links]
    strips = [s for seg in links for s in seg]
    rec.log(paths.join(root, "links"), rr.LineStrips2D.from_fields(colors=[(0, 160, 255, 255)]), static=True)
    rec.send_columns(
        paths.join(root, "links"), indexes=[tc], columns=rr.LineStrips2D.columns(strips=strips).partition(lens)
    )
    _series(rec, paths.join(root, "P"), "P (Eq. 1)", (255, 160, 40), times, performance, step=False)
    if regions is not None:
        log_istate_regions(rec, tracker, regions, times)


def log_run(
    rec: rr.RecordingStream, tracker: str, out: dict, *, site, region_graph, config, tables: dict, look: Look = GENERIC
) -> None:
    """Everything the I-state filter produced: regions (filled and outlined), sensing regions,
    detections, element count and area, and the point summary."""
    log_istate_run(
        rec,
        tracker,
        out["regions"],
        out["summary"],
        site=site,
        sensing=out["artifacts"]["sensing"],
        detections=out["detections"],
    )
    log_point_tracks(rec, tracker, out["tracks"], rgb=look.rgb)
