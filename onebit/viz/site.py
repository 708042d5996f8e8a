"""The static site drawing: boundary, obstacles, beams and regions (logged once, ``static=True``).

Regions are drawn as a translucent outline (:class:`rerun.LineStrips2D`) in the region's
colour plus a labelled :class:`rerun.Points2D` at ``representative_point()`` on the same
entity. Rerun 0.41 has no filled 2D polygon archetype (a triangulated :class:`rerun.Mesh3D`
shows only in 3D views); where a fill matters (I-states) it is an image placed over the site
(:mod:`onebit.viz.istate`). The ``site`` root carries the y-up frame (:mod:`onebit.viz.frame`).
"""

from __future__ import annotations

import numpy as np

from onebit.core.lazy import lazy_module
from onebit.core.region_graph import RegionGraph
from onebit.core.site import Site
from onebit.viz import colors, paths
from onebit.viz._series import rings
from onebit.viz.frame import log_world_frame
from onebit.viz.radii import ui_points

rr = lazy_module("rerun")

#: Line widths in UI points (independent of the site's units).
WALL_WIDTH = ui_points(1.5)
BEAM_WIDTH = ui_points(1.5)
REGION_WIDTH = ui_points(1.0)
LABEL_RADIUS = ui_points(1.0)

#: Region outlines and labels are neutral and dim: the regions' own colours are kept for the
#: occupancy plot, and a colour on the map means an agent (its current region, outlined).
REGION_COLOR = (150, 150, 150, 110)
REGION_LABEL = (170, 170, 170, 255)


def beam_arrow(site: Site, beam_id: str) -> tuple[np.ndarray, np.ndarray]:
    """Origin (the beam midpoint) and vector (towards the forward side) of a beam's arrow."""
    b = site.beam(beam_id)
    p0, p1 = np.asarray(b.p0, float), np.asarray(b.p1, float)
    length = min(0.5 * float(np.hypot(*(p1 - p0))), 0.06 * site.diagonal)
    return (p0 + p1) / 2.0, b.forward_normal * length


def log_site(rec: rr.RecordingStream, site: Site, region_graph: RegionGraph | None = None) -> None:
    """Log ``site`` (and the regions of ``region_graph``) as static geometry.

    Entities: ``site/boundary``, ``site/obstacles/<i>``, ``site/beams/<id>`` (segment and an
    arrow to the forward side labelled with the beam id), ``site/regions/<name>`` and
    ``site/sensors`` (every sensor's dim mark, :func:`log_sensor_marks`). Without a region graph, the site's named
    region points are logged as labelled points.

    Every stage's recording holds the site: its archetypes are built once for a site and
    region graph (the last pair asked for) and logged as they are into each recording.
    """
    log_world_frame(rec, paths.SITE)
    for entity, parts in _site_parts(site, region_graph):
        rec.log(entity, *parts, static=True)


_SITE_PARTS: list = []  # [(site, region_graph, parts)]: the last site drawn


def _site_parts(site: Site, region_graph: RegionGraph | None) -> list[tuple[str, list]]:
    """``(entity, archetypes)`` of :func:`log_site`, built once per site and region graph."""
    if _SITE_PARTS and _SITE_PARTS[0][0] is site and _SITE_PARTS[0][1] is region_graph:
        return _SITE_PARTS[0][2]
    parts = [
        (
            paths.site_boundary(),
            [
                rr.LineStrips2D(
                    rings(site.boundary), radii=WALL_WIDTH, colors=colors.WALL, labels=[site.name], show_labels=False
                )
            ],
        )
    ]
    for i, (poly, name) in enumerate(zip(site.obstacles, site.obstacle_names, strict=True)):
        parts.append(
            (
                paths.site_obstacle(i),
                [
                    rr.LineStrips2D(
                        rings(poly), radii=WALL_WIDTH, colors=colors.OBSTACLE, labels=[name], show_labels=False
                    )
                ],
            )
        )
    for b in site.beams:
        origin, vector = beam_arrow(site, b.id)
        parts.append(
            (
                paths.site_beam(b.id),
                [
                    rr.LineStrips2D(
                        [np.array([b.p0, b.p1], float)], radii=BEAM_WIDTH, colors=colors.BEAM, draw_order=20.0
                    ),
                    rr.Arrows2D(
                        origins=[origin],
                        vectors=[vector],
                        radii=BEAM_WIDTH,
                        colors=colors.BEAM,
                        labels=[b.id],
                        show_labels=True,
                        draw_order=20.0,
                    ),
                ],
            )
        )
    parts += _region_parts(site, region_graph)
    marks = sensor_marks(site)
    if marks:
        parts.append((paths.join(paths.SITE, "sensors"), marks))
    _SITE_PARTS[:] = [(site, region_graph, parts)]
    return parts


def _region_parts(site: Site, region_graph: RegionGraph | None) -> list[tuple[str, list]]:
    """The regions' ``(entity, archetypes)``: the region graph's outlines and labels, else the
    site's named region points."""
    out: list[tuple[str, list]] = []
    if region_graph is not None:
        for name, poly in zip(region_graph.names, region_graph.polygons, strict=True):
            rp = poly.representative_point()
            out.append(
                (
                    paths.site_region(name),
                    [
                        rr.LineStrips2D(rings(poly), radii=REGION_WIDTH, colors=REGION_COLOR, draw_order=5.0),
                        rr.Points2D(
                            [[rp.x, rp.y]],
                            radii=LABEL_RADIUS,
                            colors=REGION_LABEL,
                            labels=[name],
                            show_labels=True,
                            draw_order=6.0,
                        ),
                    ],
                )
            )
    else:
        for spec in site.regions:
            out.append(
                (
                    paths.site_region(spec.name),
                    [
                        rr.Points2D(
                            [spec.point],
                            radii=LABEL_RADIUS,
                            colors=REGION_LABEL,
                            labels=[spec.name],
                            show_labels=True,
                            draw_order=6.0,
                        )
                    ],
                )
            )
    return out


#: Sensor marks: dim, so the map stays readable; the families highlight the sensors that fire.
SENSOR_MARK = (130, 130, 130, 200)


def log_sensor_marks(rec: rr.RecordingStream, site: Site) -> None:
    """Every sensor's dim mark on the one entity ``site/sensors`` (static; the id shows on
    hover): a motion sensor is a short arrow along its heading, a proximity sensor a dot.

    One entity for all sensors, not one per sensor: a static log is a chunk of its own in the
    file, and the site is drawn in every stage's recording.
    """
    parts = sensor_marks(site)
    if parts:
        rec.log(paths.join(paths.SITE, "sensors"), *parts, static=True)


def sensor_marks(site: Site) -> list:
    """The archetypes of :func:`log_sensor_marks` (none for a site without motion or proximity sensors)."""
    length = 0.025 * site.diagonal
    parts = []
    if site.motion_sensors:
        a = np.radians([m.heading for m in site.motion_sensors])
        parts.append(
            rr.Arrows2D(
                origins=[m.position for m in site.motion_sensors],
                vectors=np.c_[np.cos(a), np.sin(a)] * length,
                radii=rr.Radius.ui_points(1.0),
                colors=SENSOR_MARK,
                labels=[m.id for m in site.motion_sensors],
                show_labels=False,
                draw_order=11.0,
            )
        )
    if site.proximity_sensors:
        parts.append(
            rr.Points2D(
                [p.position for p in site.proximity_sensors],
                radii=rr.Radius.ui_points(2.0),
                colors=SENSOR_MARK,
                labels=[p.id for p in site.proximity_sensors],
                show_labels=False,
                draw_order=11.0,
            )
        )
    return parts
