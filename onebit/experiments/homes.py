"""``onebit experiment homes OUT --data HOUSE --learn A-B --decode C-D[,E-F...]``: how many are
home, and who, in an ARAS house over days (docs/homes.md).

The house folder (``DAY_N.txt`` and ``README``, :mod:`onebit.datasets.aras`) is imported twice
over: the labelled days ``--learn`` (default the first half of the days found) into
``OUT/datasets/learn``, and each range of ``--decode`` (default the second half) into
``OUT/datasets/days-C-D``. From the labelled days ``onebit learn residents`` learns two profiles
(``OUT/profiles/sensor``: per sensor, and ``OUT/profiles/hour``: with the time-of-day clock,
24 bins) and the home's count model (``count_profile.csv``). Each decoded range is then run
(``residents``, no recordings) three times: unlearned (``days-C-D``), and with each profile
(``days-C-D-sensor``, ``days-C-D-hour``: the residents profile and the count profile copied
in). One row per decoded range and method:

``days, method, count_error, count_accuracy, occupancy_accuracy, identity_accuracy, events``

methods: ``count-unlearned`` / ``count-learned`` (the ``occupancy`` stage), the count baselines
``count-commonest`` and ``count-recent-60min``; ``who-unlearned``, ``who-known``, ``who-known-hour``
(the ``residents`` tracker), and the identity baselines ``busier``, ``habits-sensor``,
``habits-sensor-hour`` (:mod:`onebit.scoring.identity`). Written to ``OUT/results.csv``.
Decode the labelled days too (``--decode 1-7,8-15``) to see the model on the days it learned
from beside days it did not.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import polars as pl

from onebit.core.errors import InputError
from onebit.core.writers import write_csv
from onebit.datasets.aras import day_files, import_aras, parse_days
from onebit.pipeline.learn import learn_counts, learn_residents, write_profile
from onebit.pipeline.runner import run_pipeline
from onebit.trackers.residents.known import Clock

RESULTS = pl.Schema(
    {
        "days": pl.String,
        "method": pl.String,
        "count_error": pl.Float64,
        "count_accuracy": pl.Float64,
        "occupancy_accuracy": pl.Float64,
        "identity_accuracy": pl.Float64,
        "events": pl.Float64,
    }
)

#: report stage -> method, per run variant
_COUNT = {"occupancy": "count", "count-commonest": "count-commonest", "count-recent-60min": "count-recent-60min"}


def _ranges(text: str | None) -> list[tuple[int, int]]:
    return [parse_days(x) for x in text.split(",") if x.strip()] if text else []


def run(
    out: Path,
    *,
    data: str | None = None,
    learn: str | None = None,
    decode: str | None = None,
    echo=print,
    **_ignored,
) -> Path:
    """The study (module docstring); returns ``OUT``."""
    if data is None:
        raise InputError("experiment homes needs --data HOUSE_FOLDER (an ARAS house: DAY_N.txt and README)")
    house = Path(data)
    files = day_files(house)
    if not files:
        raise InputError("no DAY_N.txt files in the house folder", file=house)
    days = sorted(files)
    half = days[len(days) // 2 - 1] if len(days) > 1 else days[0]
    lrn = parse_days(learn) if learn else (days[0], half)
    decs = _ranges(decode) or [(half + 1, days[-1])]
    out = Path(out)
    ds = out / "datasets"
    echo(f"homes: learn days {lrn[0]}-{lrn[1]}, decode {', '.join(f'{a}-{b}' for a, b in decs)}")
    import_aras(house, ds / "learn", days=lrn)
    counts = learn_counts([ds / "learn"])
    profiles = {}
    for name, clock in (("sensor", None), ("hour", Clock("day", 24))):
        p = out / "profiles" / name
        write_profile(learn_residents([ds / "learn"], clock=clock), p / "residents_profile.csv")
        if counts is not None:
            write_csv(counts, p / "count_profile.csv")
        profiles[name] = p
    rows = []
    for a, b in decs:
        tag = f"{a}-{b}"
        base = ds / f"days-{tag}"
        import_aras(house, base, days=(a, b))
        variants = {"unlearned": base}
        for name, p in profiles.items():
            v = ds / f"days-{tag}-{name}"
            if v.exists():
                shutil.rmtree(v)
            shutil.copytree(base, v)
            for f in p.iterdir():
                shutil.copy(f, v / f.name)
            variants[name] = v
        for variant, path in variants.items():
            res = run_pipeline(path, out / "runs" / path.name, trackers=("residents",), rrd=False)
            rows += _rows(tag, variant, res.report)
        echo(f"homes: days {tag} done")
    table = pl.DataFrame(rows, schema=RESULTS, orient="row").unique(
        ["days", "method"], keep="first", maintain_order=True
    )
    write_csv(table, out / "results.csv")
    echo(str(table))
    return out


def _rows(days: str, variant: str, report: pl.DataFrame) -> list[tuple]:
    """This run's rows of the results table (module docstring)."""
    get = {(s, m): v for s, m, v in report.select("stage", "metric", "value").iter_rows()}
    out = []
    learned = "unlearned" if variant == "unlearned" else "learned"
    for stage, method in _COUNT.items():
        if (stage, "count_error") not in get:
            continue
        name = f"{method}-{learned}" if stage == "occupancy" else method
        if stage == "occupancy" and variant == "hour":
            continue  # the same count model as "sensor"
        out.append(
            (
                days,
                name,
                get[(stage, "count_error")],
                get[(stage, "count_accuracy")],
                get[(stage, "occupancy_accuracy")],
                None,
                None,
            )
        )
    who = {"unlearned": "who-unlearned", "sensor": "who-known", "hour": "who-known-hour"}[variant]
    ident = [("residents", who), ("identity-busier", "busier")]
    if variant != "unlearned":
        ident.append(("identity-habits", "habits-sensor" if variant == "sensor" else "habits-sensor-hour"))
    for stage, name in ident:
        if (stage, "identity_accuracy") in get:
            out.append(
                (days, name, None, None, None, get[(stage, "identity_accuracy")], get[(stage, "identity_events")])
            )
    return out
