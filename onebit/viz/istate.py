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
from onebit.core.wkb import geometries
from onebit.viz import colors, paths
from onebit.viz._series import blobs_array, gather_ranges, rings, strips_array
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
#: Rows of one ``send_columns`` call of the region outlines and fill images (memory stays
#: bounded on long runs: a day of stages sends ~50 000 rows of ~200-point outlines per slot).
SEND_ROWS = 4096
#: Regions of a stage up to which :func:`fill_images` codes a pixel by the set of regions over
#: it (a bit each; the code table has 2^16 entries at most), beyond by renumbered labels.
FILL_BITS = 16
OUTLINE_WIDTH = ui_points(1.5)
SENSING = (150, 150, 150, 90)


def element_color(e: int, *, alpha: int = 255) -> tuple[int, int, int, int]:
    """Colour of element slot ``e``: distinct for the first ten slots."""
    r, g, b = (int(c) for c in colors.PALETTE[_ELEMENT_ORDER[e % len(_ELEMENT_ORDER)]])
    return (r, g, b, int(alpha))


def _strips_per_stage(geoms: np.ndarray):
    """The rings of one geometry per stage (``None`` = absent) as one ``LineStrip2D`` Arrow
    array and the number of strips per stage (for ``.partition``): :func:`polygon_rings` when
    every geometry is a polygon or a multipolygon, else ring by ring
    (:func:`_strips_per_stage_reference`, its test oracle)."""
    geoms = np.asarray(geoms, dtype=object).reshape(-1)
    ids = np.fromiter(map(id, geoms), dtype=np.int64, count=geoms.size)
    _, first, inv = np.unique(ids, return_index=True, return_inverse=True)  # a region recurs over stages
    flat = polygon_rings(geoms[first])
    if flat is None:
        return _strips_per_stage_reference(geoms)
    points, lengths, counts = flat  # of each distinct geometry once, gathered per stage below
    inv = inv.reshape(-1)
    ring0 = np.cumsum(counts) - counts  # first ring of each distinct geometry
    rings_of = gather_ranges(ring0[inv], counts[inv])  # the rings of every stage, in order
    point0 = np.cumsum(lengths) - lengths
    pts = points[gather_ranges(point0[rings_of], lengths[rings_of])]
    return strips_array(pts, lengths[rings_of]), counts[inv].tolist()


def polygon_rings(geoms: np.ndarray):
    """``(points (m, 2), ring lengths (r,), rings per geometry (g,))`` of an object array of
    polygons and multipolygons (``None`` or empty: no ring), in :func:`~onebit.viz._series.rings`'
    order (each part's exterior, then its holes), with shapely's array functions and no Python
    work per ring; ``None`` when a geometry of another type is present."""
    geoms = np.asarray(geoms, dtype=object).reshape(-1)
    live = ~shapely.is_missing(geoms)
    live[live] = ~shapely.is_empty(geoms[live])
    idx = np.flatnonzero(live)
    if idx.size and not np.isin(shapely.get_type_id(geoms[idx]), (3, 6)).all():  # Polygon, MultiPolygon
        return None
    parts, owner = shapely.get_parts(geoms[idx], return_index=True)
    rings, part = shapely.get_rings(parts, return_index=True)
    points, ring = shapely.get_coordinates(rings, return_index=True)
    lengths = np.bincount(ring, minlength=len(rings)).astype(np.int64)
    counts = np.zeros(geoms.size, dtype=np.int64)
    np.add.at(counts, idx[owner[part]], 1)
    return points.reshape(-1, 2).astype(np.float32), lengths, counts


def _strips_per_stage_reference(geoms: np.ndarray):
    """:func:`_strips_per_stage` geometry by geometry and ring by ring (any geometry type)."""
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

    def window(self, geom):
        """``((r0, r1, c0, c1), m)``: :meth:`mask` of ``geom`` cut to the pixel rows ``r0:r1`` and
        columns ``c0:c1`` around it (its bounding box and a pixel more each side, within the
        image); every pixel of the whole mask outside the window is 0. ``None`` when ``geom``
        covers no pixel of the image. The polygon is filled on the window with its fixed-point
        coordinates moved by whole pixels, which OpenCV's scan conversion does not change (test:
        equal to the whole mask cut to the window)."""
        parts = [
            g for g in getattr(geom, "geoms", [geom]) if g is not None and g.geom_type == "Polygon" and not g.is_empty
        ]
        if not parts:
            return None
        exts = [self._pixels(np.asarray(g.exterior.coords)[:, :2]) for g in parts]
        lo = np.min([e.min(axis=0) for e in exts], axis=0) // 16 - 1  # (x, y) pixels
        hi = np.max([e.max(axis=0) for e in exts], axis=0) // 16 + 2
        c0, r0 = max(int(lo[0]), 0), max(int(lo[1]), 0)
        c1, r1 = min(int(hi[0]), self.width), min(int(hi[1]), self.height)
        if c1 <= c0 or r1 <= r0:
            return None
        m = np.zeros((r1 - r0, c1 - c0), np.uint8)
        shift = np.array([c0 * 16, r0 * 16], np.int32)
        for g, ext in zip(parts, exts):
            cv2.fillPoly(m, [ext - shift], 1, lineType=cv2.LINE_8, shift=4)
            for ring in g.interiors:
                cv2.fillPoly(m, [self._pixels(np.asarray(ring.coords)[:, :2]) - shift], 0, lineType=cv2.LINE_8, shift=4)
        return (r0, r1, c0, c1), m

    def _pixels(self, xy: np.ndarray) -> np.ndarray:
        return np.round((xy - [self.x0, self.y0]) / self.cell * 16.0).astype(np.int32)  # shift = 4


def _png(rgb: np.ndarray) -> bytes:
    return _png_bgr(np.ascontiguousarray(rgb[..., ::-1]))


def _png_bgr(bgr: np.ndarray) -> bytes:
    ok, png = cv2.imencode(".png", bgr)
    if not ok:  # pragma: no cover - OpenCV always encodes a valid array
        raise RuntimeError("OpenCV could not encode an I-state fill image")
    return png.tobytes()


def fill_images(
    grid: np.ndarray,
    raster: FillRaster,
    *,
    background=colors.MAP_BACKGROUND,
    keys=None,
    cache: dict | None = None,
    max_bits: int = FILL_BITS,
) -> list[bytes]:
    """One RGB PNG per stage of ``grid`` (``(E, n, K)`` geometries or ``None``): every region of
    every element filled in the element's colour at :data:`FILL_ALPHA` over ``background`` and
    over each other (a region inside another of the product shows brighter); pixels of no
    element are the background.

    A pixel's colour depends only on which regions cover it, in drawing order, so the image is
    drawn as a code per pixel and a small table of code colours, blended as
    :func:`onebit._testing.oracles.fill_images_reference` blends each pixel (equal images,
    tested), no float image. With at most ``max_bits`` regions in the stage the code is the
    set of regions covering the pixel, one bit each (``code |= mask << j`` on each region's
    window); the colours are blended for the codes present only. With more, the code is a
    label renumbered region by region (per region one gather and one scatter of its pixels).
    ``keys`` (one hashable per stage, e.g. the stage's region WKBs) reuses the PNG of an earlier
    stage with the same key: an unobserved I-state that has filled the free space stays the
    same for many stages; ``cache`` (key -> PNG) keeps them across calls.
    """
    E, _, K = grid.shape
    bg = np.asarray(background[:3], np.float32)
    elem = [np.asarray(element_color(e)[:3], np.float32) for e in range(E)]
    done: dict = cache if cache is not None else {}
    out = []
    for s in range(K):
        key = keys[s] if keys is not None else None
        if key is not None and key in done:
            out.append(done[key])
            continue
        wins = []  # (element, window) of each region drawn, in drawing order
        for e in range(E):
            for g in grid[e, :, s]:
                if g is None or g.is_empty:
                    continue
                win = raster.window(g)  # the region's own pixels only, not the whole image
                if win is not None:
                    wins.append((e, win))
        draw = _codes_by_bits if len(wins) <= max_bits else _codes_by_labels
        code, table = draw(wins, raster, bg, elem)
        bgr = np.ascontiguousarray(table.round().clip(0, 255).astype(np.uint8)[:, ::-1])
        png = _png_bgr(np.take(bgr, code, axis=0))  # the image in OpenCV's channel order, one gather
        if key is not None:
            done[key] = png
        out.append(png)
    return out


def _codes_by_bits(wins, raster: FillRaster, bg: np.ndarray, elem: list) -> tuple[np.ndarray, np.ndarray]:
    """``(code (h, w), colours (codes, 3))``: bit ``j`` of a pixel's code set when region ``j``
    covers it; the colour of a code blends the elements of its bits in order over ``bg``
    (for the codes present in the image only)."""
    bits = np.zeros((raster.height, raster.width), np.int32)
    for j, (_, ((r0, r1, c0, c1), m)) in enumerate(wins):
        bits[r0:r1, c0:c1] |= m.astype(np.int32) << j
    present = np.flatnonzero(np.bincount(bits.reshape(-1), minlength=1))
    col = np.repeat(bg[None, :], present.size, axis=0)
    for j, (e, _) in enumerate(wins):  # in drawing order, as each pixel is blended
        on = ((present >> j) & 1).astype(bool)
        col[on] = elem[e] * FILL_ALPHA + col[on] * (1 - FILL_ALPHA)
    index = np.zeros(int(present[-1]) + 1, np.int32)
    index[present] = np.arange(present.size, dtype=np.int32)
    return index[bits], col


def _codes_by_labels(wins, raster: FillRaster, bg: np.ndarray, elem: list) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_codes_by_bits` for any number of regions: a label per pixel (which regions so
    far), renumbered region by region, and the table of the labels' colours."""
    label = np.zeros((raster.height, raster.width), np.int32)  # 0 = background
    table = bg[None, :]  # (labels, 3) colours
    for e, ((r0, r1, c0, c1), m) in wins:
        sub = label[r0:r1, c0:c1]
        m = m.astype(bool)
        under = sub[m]
        present = np.flatnonzero(np.bincount(under, minlength=len(table)))
        remap = np.arange(len(table), dtype=np.int32)
        remap[present] = len(table) + np.arange(len(present), dtype=np.int32)
        table = np.concatenate([table, elem[e] * FILL_ALPHA + table[present] * (1 - FILL_ALPHA)])
        sub[m] = remap[under]
    return label, table


def _region_grid(regions: pl.DataFrame, K: int, geoms: np.ndarray | None = None) -> np.ndarray:
    """``(E, n, K)`` object array of the regions by element slot, region and stage (``None``
    where absent); rows with the same WKB hold the same geometry object (parsed once), or
    ``geoms`` holds each row's geometry already (the tracker's, rows with the same region
    sharing an object)."""
    n = int(regions["k"].max()) + 1
    E = int(regions["element"].max()) + 1
    grid = np.full((E, n, K), None, dtype=object)
    if geoms is None or len(geoms) != regions.height:
        geoms = geometries(regions["wkb"])
    grid[regions["element"].to_numpy(), regions["k"].to_numpy(), regions["stage"].to_numpy()] = geoms
    return grid


def _stage_keys(grid: np.ndarray) -> list:
    """One key per stage of ``grid`` (:func:`_region_grid`): the geometry objects of its slots,
    equal for stages with the same regions (the grid's rows with the same WKB share one object)."""
    E, n, K = grid.shape
    ids = np.fromiter(map(id, grid.reshape(-1)), dtype=np.int64, count=grid.size).reshape(E * n, K)
    return [row.tobytes() for row in ids.T]  # ``None`` has one id of its own


def changed(keys) -> np.ndarray:
    """Indices of the stages whose key differs from the stage before (the first always):
    the only rows a recording needs, since the viewer shows at every time the latest row at or
    before it."""
    return np.asarray([s for s in range(len(keys)) if s == 0 or keys[s] != keys[s - 1]], dtype=np.int64)


def log_istate_regions(
    rec: rr.RecordingStream,
    tracker: str,
    regions: pl.DataFrame,
    times: np.ndarray,
    *,
    bounds=None,
    fill: bool = True,
    geoms: np.ndarray | None = None,
) -> None:
    """Every (element slot, k) of the ``regions`` table (t, stage, element, k, wkb) over ``times``:
    outlines per slot and region, and (``fill``) one fill image per stage over ``bounds``
    (minx, miny, maxx, maxy; default: the regions' own bounds).

    Each entity gets a row only at the stages where what it shows changes (the first stage
    always; a slot that empties gets a row with no strips): the viewer shows at every time the
    latest row at or before it, so it shows what a row per stage showed. An I-state holds
    still between readings -- a day of a home: 86 389 stages, 10 600 changes of the fill.
    ``geoms``: each row's geometry, when the caller has them (:func:`_region_grid`)."""
    if regions.height == 0:
        return
    log_world_frame(rec, paths.tracker_root(tracker))
    K = len(times)
    grid = _region_grid(regions, K, geoms)
    E, n, _ = grid.shape
    times = np.asarray(times)
    for e in range(E):
        col = element_color(e, alpha=230)
        for k in range(n):
            ids = np.fromiter(map(id, grid[e, k]), dtype=np.int64, count=K)
            at = np.flatnonzero(np.r_[True, ids[1:] != ids[:-1]])  # the slot's region changes
            ent = paths.istate(tracker, str(e), k)
            rec.log(
                ent,
                rr.LineStrips2D.from_fields(
                    colors=[col], radii=OUTLINE_WIDTH, labels=[f"element {e + 1}"], show_labels=False, draw_order=15.0
                ),
                static=True,
            )
            for part in np.array_split(at, max(1, -(-at.size // SEND_ROWS))):  # bounded batches
                strips, counts = _strips_per_stage(grid[e, k, part])
                rec.send_columns(
                    ent,
                    indexes=[paths.time_column(times[part])],
                    columns=rr.LineStrips2D.columns(strips=strips).partition(counts),
                )
    if not fill:
        return
    if bounds is None:
        bounds = shapely.union_all([g for g in grid.ravel() if g is not None]).bounds
    raster = FillRaster(bounds)
    ent = paths.join(paths.tracker_root(tracker), "istate", "fill")
    keys = _stage_keys(grid)
    at = changed(keys)
    rec.log(ent, raster.transform(), static=True)
    rec.log(ent, rr.EncodedImage.from_fields(media_type="image/png", draw_order=-5.0), static=True)
    drawn: dict = {}  # PNGs by stage key, across the batches
    for part in np.array_split(at, max(1, -(-at.size // SEND_ROWS))):
        blobs = fill_images(grid[:, :, part], raster, keys=[keys[s] for s in part], cache=drawn)
        # the previous batch written before this one is queued (at most two batches of images in
        # memory), while this one was drawn: the writer's encoding overlaps the drawing
        rec.flush()
        rec.send_columns(
            ent, indexes=[paths.time_column(times[part])], columns=rr.EncodedImage.columns(blob=blobs_array(blobs))
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
    geoms: np.ndarray | None = None,
) -> None:
    """The ``istate`` stage: I-state regions (filled and outlined), sensing regions, detections,
    element count and area (``geoms``: the regions' geometries row by row, if known)."""
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
    log_istate_regions(rec, tracker, regions, times, bounds=bounds, geoms=geoms)
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
        log_detections(rec, root, detections, sensing, times)


def log_detections(rec: rr.RecordingStream, root: str, detections: pl.DataFrame, sensing: dict, times) -> None:
    """``<root>/detections``: the sensing regions (``sensing``: sensor -> geometry) of the
    ``detections`` (stage, sensor) of each stage, outlined bright red; a row only at the stages
    whose set of detected sensors differs from the stage before (the first always), a stage with
    none an empty row -- the viewer shows at every time what a row per stage showed. Each
    sensor's rings are taken once (:func:`_strips_per_stage`) and gathered per row."""
    d = detections.sort("stage", maintain_order=True)
    ids = list(sensing)
    code = d["sensor"].replace_strict({s: i for i, s in enumerate(ids)}, return_dtype=pl.Int64).to_numpy()
    stage = d["stage"].to_numpy()
    K = len(times)
    at = _changed_sets(stage, code, K)
    shapes = np.array([sensing[s] for s in ids] + [None], dtype=object)[:-1]
    ent = paths.join(root, "detections")
    rec.log(
        ent,
        rr.LineStrips2D.from_fields(colors=[colors.FIRING], radii=rr.Radius.ui_points(2.5), draw_order=18.0),
        static=True,
    )
    for part in np.array_split(at, max(1, -(-at.size // SEND_ROWS))):  # bounded batches
        lo, hi = np.searchsorted(stage, part[0], "left"), np.searchsorted(stage, part[-1], "right")
        rows = lo + np.flatnonzero(np.isin(stage[lo:hi], part))  # the detections of this batch's stages
        strips, per = _strips_per_stage(shapes[code[rows]])
        lens = np.zeros(len(part), dtype=np.int64)
        np.add.at(lens, np.searchsorted(part, stage[rows]), np.asarray(per, dtype=np.int64))
        rec.send_columns(
            ent,
            indexes=[paths.time_column(np.asarray(times)[part])],
            columns=rr.LineStrips2D.columns(strips=strips).partition(lens),
        )


def _changed_sets(stage: np.ndarray, code: np.ndarray, K: int) -> np.ndarray:
    """The stages ``0..K-1`` whose sequence of ``code`` (rows sorted by ``stage``) differs from
    the stage before's (the first always): equal counts and equal codes position by position."""
    cnt = np.bincount(stage, minlength=K)
    same = np.r_[False, cnt[1:] == cnt[:-1]]
    j = np.flatnonzero(same[stage])  # a row of a stage with as many rows as the stage before
    differs = code[j] != code[j - cnt[stage[j]]]  # its counterpart there: as many rows back
    same[stage[j[differs]]] = False
    return np.flatnonzero(~same)


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
        geoms=out["artifacts"].get("region_geometries"),
    )
    log_point_tracks(rec, tracker, out["tracks"], rgb=look.rgb)
