"""``onebit config show [STAGE]``: every parameter of every ``run.toml`` section, as TOML a user
can paste into ``run.toml`` -- each value its default, each doc, unit and allowed range a comment
above it. The sections are the stages of the declared pipeline that take a config
(:func:`onebit.pipeline.stages.stages`), the parameters their declarations
(:func:`onebit.core.params.describe`); ``docs/parameters.md`` is made from the same
(``tools/params_md.py``)."""

from __future__ import annotations

import dataclasses
import inspect
import json
import math
import re
import textwrap
from typing import Any

from onebit.core.errors import ConfigError
from onebit.core.params import ParamInfo, describe
from onebit.pipeline.stages import stages

#: Width of the comment lines.
WIDTH = 100


def config_sections(stage_list: list | None = None) -> dict[str, type]:
    """``{section: config class}`` for every stage of ``stage_list`` (the declared pipeline by
    default) that reads a ``run.toml`` section."""
    if stage_list is None:
        stage_list = stages()
    return {st.name: st.config for st in stage_list if st.config is not None}


def toml_value(v: Any) -> str:
    """``v`` written as a TOML value (a bool, number, string, array or inline table)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)  # a TOML basic string
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        if not v:
            return "{}"
        keys = (k if re.fullmatch(r"[A-Za-z0-9_-]+", k) else json.dumps(k) for k in v)
        return "{ " + ", ".join(f"{k} = {toml_value(x)}" for k, x in zip(keys, v.values(), strict=True)) + " }"
    raise TypeError(f"no TOML form for {v!r}")


def plain(text: str) -> str:
    """``text`` without reStructuredText markup: ``:func:`~a.b.c``` -> ``c``, ````x```` -> ``x``."""
    text = re.sub(r":\w+:`~[^`]*?\.?([^.`]+)`", r"\1", text)
    text = re.sub(r":\w+:`([^`]+)`", r"\1", text)
    return text.replace("``", "")


def summary(cls: type) -> str:
    """The first paragraph of a config class's docstring, on one line, without markup."""
    doc = inspect.getdoc(cls) or ""
    return plain(" ".join(doc.split("\n\n")[0].split()))


def facts(p: ParamInfo) -> str:
    """The kind, unit and allowed values of a parameter: ``float, m, [0.0, 1000000.0]``."""
    parts = [p.kind]
    if p.unit:
        parts.append(p.unit)
    if p.allowed():
        parts.append(p.allowed())
    if p.optional:
        parts.append("may be unset")
    return ", ".join(parts)


def _comment(text: str) -> list[str]:
    return textwrap.wrap(text, WIDTH - 2, initial_indent="# ", subsequent_indent="# ", break_on_hyphens=False)


def section_toml(name: str, cls: type) -> str:
    """One ``[name]`` section: the class summary, then per parameter its doc and facts as
    comments and ``name = default`` (a parameter unset by default is a commented ``# name =``)."""
    head = f"[{name}]" if re.fullmatch(r"[A-Za-z0-9_-]+", name) else f"[{json.dumps(name)}]"
    lines = [head, *_comment(summary(cls))]
    for p in describe(cls):
        lines += ["", *_comment(p.doc.rstrip(".") + "."), *_comment(f"({facts(p)})")]
        if p.default is None or p.default is dataclasses.MISSING:
            lines.append(f"# {p.name} =")
        else:
            lines.append(f"{p.name} = {toml_value(p.default)}")
    return "\n".join(lines) + "\n"


def show(stage: str | None = None, stage_list: list | None = None) -> str:
    """The TOML of one stage's section (``stage``) or of every section (of ``stage_list``, by
    default the declared pipeline)."""
    sections = config_sections(stage_list)
    if stage is not None:
        if stage not in sections:
            raise ConfigError(f"config show: no stage {stage!r} takes a config; stages with one: {sorted(sections)}")
        sections = {stage: sections[stage]}
    head = "# run.toml: every parameter with its default (onebit config show); keep the lines you change\n"
    return head + "\n" + "\n\n".join(section_toml(n, c) for n, c in sections.items())


def _cmd_config_show(args) -> int:
    print(show(args.stage), end="")
    return 0


def add_config_command(sub) -> None:
    """``onebit config show [STAGE]`` on the subcommands ``sub`` of the ``onebit`` parser."""
    cf = sub.add_parser("config", help="the run.toml parameters: defaults, bounds, units, docs")
    csub = cf.add_subparsers(dest="config_command", required=True)
    cs = csub.add_parser("show", help="print every parameter of every run.toml section (or of STAGE) as TOML")
    cs.add_argument("stage", nargs="?", default=None, help="one stage's section (e.g. binpf, motion, scores)")
    cs.set_defaults(func=_cmd_config_show)


def _cell(text: str) -> str:
    return " ".join(text.split()).replace("|", "\\|")


def reference_markdown() -> str:
    """``docs/parameters.md``: one table per ``run.toml`` section (parameter, default, allowed
    values, unit, doc), from the same declarations as :func:`show`."""
    lines = [
        "<!-- generated by `python tools/params_md.py` from the config declarations (onebit.core.params): "
        "edit those -->",
        "",
        "# Parameters",
        "",
        "Every section of `run.toml` and every parameter in it, with its default, the values it accepts",
        "and its unit. A value outside them stops the run with an error naming the section and the field.",
        "Lengths, speeds and areas are in metres (`m`, `m/s`, `m^2`) whatever the site's `units`: they are",
        "converted once to the site's units before a stage runs. A parameter *unset* by default is left",
        "out of `run.toml` to keep its default behaviour.",
        "",
        "`onebit config show [STAGE]` prints the same as TOML to paste into `run.toml`",
        "([commands](commands.md), [the dataset folder](dataset.md)).",
        "",
    ]
    for name, cls in config_sections().items():
        lines += [f"## `[{name}]`", "", summary(cls), ""]
        rows = [["parameter", "default", "allowed", "unit", "meaning"], ["---"] * 5]
        for p in describe(cls):
            default = "unset" if p.default is None else f"`{toml_value(p.default)}`"
            allowed = p.allowed() or p.kind
            rows.append([f"`{p.name}`", default, allowed, p.unit or "", plain(p.doc)])
        lines += ["| " + " | ".join(_cell(c) for c in row) + " |" for row in rows]
        lines.append("")
    return "\n".join(lines).rstrip() + "\n"
