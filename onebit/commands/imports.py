"""``onebit import casas|aras|irtracking|trajectories``: dataset folders from the field's own recordings.

Every option's default is the importer's own (its signature, or :class:`TrajectoryFormat`'s
fields), so ``--help`` shows the value the importer uses."""

from __future__ import annotations

from onebit.commands.options import default_of
from onebit.datasets.aras import import_aras, parse_days
from onebit.datasets.importers import import_casas, import_trajectories
from onebit.datasets.irtracking import DEFAULT_TARGETS, import_irtracking
from onebit.readers.trajectories import TIME_UNITS, TrajectoryFormat


def _cmd_import_aras(args) -> int:
    """``onebit import aras HOUSE DATASET``."""
    res = import_aras(args.house, args.dataset, days=parse_days(args.days))
    c = res.counts
    print(
        f"imported {args.house} -> {args.dataset}: {c['days']} days, {c['lines']} lines, {c['motion_csv']} level changes "
        f"of {c['person_sensors']} person sensors in motion.csv, {c['other_csv']} in other.csv, "
        f"{c['truth_events']} resident-labelled events, {c['rejected']} rejected lines, {c['short_days']} short days; "
        "see import.toml"
    )
    return 0


def _cmd_import_casas(args) -> int:
    """``onebit import casas LOG DATASET``."""
    doors = tuple(d.strip() for d in args.doors.split(",") if d.strip()) if args.doors else ()
    res = import_casas(
        args.log,
        args.dataset,
        layout=args.layout,
        targets=args.targets,
        doors=doors,
        window_s=args.window,
        min_count=args.min_count,
        min_share=args.min_share,
        spacing_m=args.spacing,
        hold_s=args.hold,
        hold_samples=args.hold_samples,
        scale=args.scale,
        rooms=args.rooms,
        graph_radius=args.graph_radius,
        count=args.count,
    )
    c = res.counts
    print(
        f"imported {args.log} -> {args.dataset}: {c['events']} events ({c['motion_csv']} motion/contact in motion.csv, "
        f"{c['lost_off_repaired']} lost OFFs repaired, {c['other_csv']} others in other.csv, {c['annotations']} annotated, "
        f"{c['truth_events']} resident-labelled in truth_events.csv), {c['rejected']} rejected lines, "
        f"{c['reordered']} out of order (sorted); {c['sensors']} sensors, {c['edges']} edges "
        f"({res.info['graph']['source']} graph, positions: {res.info['layout']['positions']}); see import.toml"
    )
    return 0


def _cmd_import_irtracking(args) -> int:
    """``onebit import irtracking SEQ DATASET``."""
    res = import_irtracking(
        args.readings,
        args.dataset,
        truth=args.truth,
        coordinates=args.coordinates,
        period=args.period,
        radius=args.radius,
        r_inner=args.r_inner,
        targets=args.targets,
        name=args.name,
    )
    c = res.info["counts"]
    truth = f", truth.csv ({c['truth_rows']} positions of {c['truth_targets']} people)" if "truth_rows" in c else ""
    print(
        f"imported {args.readings} -> {args.dataset}: site.toml ({c['sensors']} sensors), frames.csv ({c['frames']} frames, "
        f"{c['active_readings']} active readings){truth}; {c['rejected']} rejected{' (rejects.csv)' if c['rejected'] else ''}; "
        "see import.toml"
    )
    return 0


def _cmd_import_trajectories(args) -> int:
    """``onebit import trajectories FILE DATASET``."""
    fmt = TrajectoryFormat(
        delimiter={"tab": "\t", "space": " "}.get(args.delimiter, args.delimiter),
        time=args.time_column,
        track=args.track_column,
        x=args.x_column,
        y=args.y_column,
        time_unit=args.time_unit,
        scale=args.scale,
        offset=(args.offset_x, args.offset_y),
        flip_x=args.flip_x,
        flip_y=args.flip_y,
        swap_xy=args.swap_xy,
        join=tuple(tuple(i.strip() for i in j.split(",")) for j in args.join or []),
    )
    res = import_trajectories(args.file, args.dataset, fmt)
    c = res.counts
    print(
        f"imported {args.file} -> {args.dataset}/truth.csv: {c['positions']} positions of {c['tracks']} tracks, "
        f"{c['rejected']} rejected rows{' (truth_rejects.csv)' if c['rejected'] else ''}; see truth_import.toml"
    )
    return 0


def add_import_commands(sub) -> None:
    """``import casas|aras|irtracking|trajectories``."""
    im = sub.add_parser("import", help="make a dataset folder from the field's own recordings (CASAS, trajectories)")
    isub = im.add_subparsers(dest="import_command", required=True)
    _add_casas(isub)
    _add_aras(isub)
    _add_irtracking(isub)
    _add_trajectories(isub)


def _add_casas(isub) -> None:
    ic = isub.add_parser(
        "casas",
        help="a CASAS smart-home log (.txt, or pymrt events.csv) -> motion.csv, truth_events.csv, other.csv, annotations.csv, site.toml",
    )
    ic.add_argument("log")
    ic.add_argument("dataset")
    ic.add_argument(
        "--layout",
        help="layout.toml (positions, edges), or a floor plan sensors.json / sensors.csv / pymrt site.json "
        "(pixels or normalised, with --scale; edges from geometry); without it the graph is learned from the log",
    )
    ic.add_argument(
        "--rooms", default=None, help="floor plan rooms (JSON: rectangles or polygons, in the plan's coordinates)"
    )
    ic.add_argument(
        "--scale",
        type=float,
        default=None,
        help="floor plan: metres per pixel (or per plan width for normalised coordinates)",
    )
    ic.add_argument(
        "--graph-radius",
        type=float,
        default=None,
        help="floor plan graph: link sensors within this many metres "
        "(default: the smallest distance that keeps the graph connected)",
    )
    ic.add_argument("--targets", type=int, default=None, help="the most residents present at once (site.toml targets)")
    ic.add_argument(
        "--count",
        type=int,
        default=None,
        help="the people in throughout, when known and constant (a one-resident session): written as "
        "truth_count.csv, so every people count is scored per minute",
    )
    _add_casas_graph_options(ic)
    ic.add_argument(
        "--doors", default=None, help="comma-separated contact ids that are doors to the outside (entry/exit nodes)"
    )
    ic.add_argument(
        "--hold",
        type=float,
        default=default_of(import_casas, "hold_s"),
        help="lost OFF repair: hold time (s) of a sensor with too few on-durations (default %(default)g)",
    )
    ic.add_argument(
        "--hold-samples",
        type=int,
        default=default_of(import_casas, "hold_samples"),
        help="lost OFF repair: on-durations a sensor needs for its own (median) hold time (default %(default)s)",
    )
    ic.set_defaults(func=_cmd_import_casas)


def _add_casas_graph_options(ic) -> None:
    """The learned graph's rule and the force layout (:func:`import_casas`'s defaults)."""
    ic.add_argument(
        "--window",
        type=float,
        default=default_of(import_casas, "window_s"),
        help="learned graph: s between two sensors' ON for a transition (default %(default)g)",
    )
    ic.add_argument(
        "--min-count",
        type=int,
        default=default_of(import_casas, "min_count"),
        help="learned graph: transitions an edge needs (default %(default)s)",
    )
    ic.add_argument(
        "--min-share",
        type=float,
        default=default_of(import_casas, "min_share"),
        help="learned graph: share of the less busy sensor's transitions (default %(default)g)",
    )
    ic.add_argument(
        "--spacing",
        type=float,
        default=default_of(import_casas, "spacing_m"),
        help="force layout: edge length (m) (default %(default)g)",
    )


def _add_aras(isub) -> None:
    ia = isub.add_parser(
        "aras",
        help="an ARAS house folder (DAY_N.txt, README) -> motion.csv, truth_count.csv, annotations.csv, "
        "truth_events.csv, site.toml (docs/homes.md)",
    )
    ia.add_argument("house", help="the house folder: DAY_1.txt ... and the README naming the sensor columns")
    ia.add_argument("dataset")
    ia.add_argument("--days", default=None, help="days to import, A-B (default: every day file found)")
    ia.set_defaults(func=_cmd_import_aras)


def _add_irtracking(isub) -> None:
    ir = isub.add_parser(
        "irtracking",
        help="Milan et al.'s ceiling IR array (SEQ.txt or SEQ.xml detections) -> site.toml, frames.csv, truth.csv",
    )
    ir.add_argument("readings", help="SEQ.txt (one line of 50 channels per frame) or SEQ.xml (CVML detections)")
    ir.add_argument("dataset")
    ir.add_argument("--truth", default=None, help="SEQ_gt.xml (CVML, pixels x 25 = mm) -> truth.csv")
    ir.add_argument(
        "--coordinates",
        default=None,
        help="getSensorCoordinates.m (default: next to the readings or up to two folders above)",
    )
    ir.add_argument(
        "--period",
        type=float,
        default=default_of(import_irtracking, "period"),
        help="seconds between frames (default %(default)g: 2 Hz)",
    )
    ir.add_argument(
        "--radius",
        type=float,
        default=default_of(import_irtracking, "radius"),
        help="footprint radius of a sensor, m (default %(default)g)",
    )
    ir.add_argument("--r-inner", type=float, default=None, help="radius a reading 0 clears, m (default: --radius)")
    ir.add_argument(
        "--targets",
        type=int,
        default=None,
        help=f"most people present at once (default {DEFAULT_TARGETS}, the recordings' most)",
    )
    ir.add_argument("--name", default=None, help="site name (default: the readings' file name)")
    ir.set_defaults(func=_cmd_import_irtracking)


def _add_trajectories(isub) -> None:
    it = isub.add_parser("trajectories", help="a people-counter / indoor-positioning export -> truth.csv")
    it.add_argument("file")
    it.add_argument("dataset")
    it.add_argument(
        "--delimiter", default=None, help="',', ';', 'tab', '|' or 'space' (default: sniffed from the header)"
    )
    it.add_argument("--time-column", default=None, help="default: t, time, timestamp, ts, ...")
    it.add_argument("--track-column", default=None, help="default: track, id, track_id, person_id, ...")
    it.add_argument("--x-column", default=None)
    it.add_argument("--y-column", default=None)
    it.add_argument("--time-unit", default=TrajectoryFormat.time_unit, choices=TIME_UNITS)
    it.add_argument(
        "--scale",
        type=float,
        default=TrajectoryFormat.scale,
        help="x, y times this (0.001: mm -> m; default %(default)g)",
    )
    offset_x, offset_y = TrajectoryFormat.offset
    it.add_argument("--offset-x", type=float, default=offset_x, help="added to x after scaling")
    it.add_argument("--offset-y", type=float, default=offset_y, help="added to y after scaling")
    it.add_argument("--flip-x", action="store_true", help="negate x (before the offset)")
    it.add_argument("--flip-y", action="store_true", help="negate y (before the offset)")
    it.add_argument("--swap-xy", action="store_true", help="swap the x and y columns")
    it.add_argument("--join", action="append", metavar="A,B", help="track ids that are one person (repeatable)")
    it.set_defaults(func=_cmd_import_trajectories)
