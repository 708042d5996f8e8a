"""``onebit verify-path OUT --story "a b^-1 c"``: a story's plausibility against a beams run."""

from __future__ import annotations

from pathlib import Path

import polars as pl

from onebit.commands.options import default_of
from onebit.core.config import load_toml
from onebit.core.errors import ConfigError, InputError, OnebitError
from onebit.core.site import load_site
from onebit.pipeline.report import check_run_folder
from onebit.trackers.beams.verify import parse_story, verify_path


def verify_run(out: str | Path, story: str, **scores: float) -> pl.DataFrame:
    """:func:`verify_path` on the ``beams_assignment`` table of a finished run folder ``out``.

    A story label naming a beam the run's site does not have is a ``ValueError`` naming it
    and the beams there are (when the site can be found from the run's ``run.toml``)."""
    if Path(out).is_dir():
        check_run_folder(out)  # refuses a folder an interrupted run left INCOMPLETE
    path = Path(out) / "tables" / "beams_assignment.parquet"
    if not path.exists():
        raise InputError("no beams_assignment table: run the beams tracker first (onebit run)", file=path)
    beams = _run_beams(Path(out))
    unknown = sorted({tok.removesuffix("^-1") for tok in parse_story(story)} - set(beams)) if beams else []
    if unknown:
        raise ValueError(
            f"label(s) {', '.join(map(repr, unknown))} name no beam of the run; its beams are {', '.join(beams)}"
        )
    return verify_path(story, pl.read_parquet(path), **scores)


def _run_beams(out: Path) -> list[str]:
    """The beam ids of the run's site (its ``run.toml`` names the dataset), or ``[]`` if unknown."""
    try:
        dataset = Path(str(load_toml(out / "run.toml", error=InputError).get("dataset", "")))
        return list(load_site(dataset / "site.toml").beam_ids)
    except (OnebitError, OSError):
        return []


def _cmd_verify_path(args) -> int:
    """``onebit verify-path OUT --story "a b^-1 c"``: print the alignments; exit 0 when the
    story is plausible against the observation string, 1 when it is not."""
    try:
        res = verify_run(args.out, args.story, match=args.match, mismatch=args.mismatch, gap=args.gap)
    except ValueError as exc:
        raise ConfigError(f"--story: {exc}") from None
    with pl.Config(tbl_rows=-1, tbl_cols=-1, fmt_str_lengths=80, tbl_hide_dataframe_shape=True):
        print(f"story {' '.join(parse_story(args.story))!r} against the run {args.out}")
        print(res)
    obs = res.filter(pl.col("target") == "observation")
    ok = bool(obs["plausible"][0]) if obs.height else False
    plausible_agents = res.filter((pl.col("target") != "observation") & pl.col("plausible"))["target"].to_list()
    print(
        f"plausible against the observation string: {'yes' if ok else 'no'}; "
        f"agents whose reconstructed path contains it: {', '.join(plausible_agents) or 'none'}"
    )
    return 0 if ok else 1


def add_verify_path_command(sub) -> None:
    """``verify-path``: a story's plausibility against a beams run."""
    vp = sub.add_parser("verify-path", help="is a story (crossing labels) plausible? Smith-Waterman vs a beams run")
    vp.add_argument("out", help="run folder of a finished 'onebit run' with the beams tracker")
    vp.add_argument("--story", required=True, help='crossing labels, e.g. "a b^-1 c"')
    for flag, help in (
        ("match", "score of a matching label"),
        ("mismatch", "score of a mismatching label (<= 0)"),
        ("gap", "penalty of a gap (> 0)"),
    ):
        vp.add_argument(
            f"--{flag}", type=float, default=default_of(verify_path, flag), help=f"{help} (default %(default)g)"
        )
    vp.set_defaults(func=_cmd_verify_path)
