"""Extra pipeline stages contributed by sensor kinds and trackers.

Each module in :data:`STAGE_MODULES` defines ``STAGES: list[Stage]`` (see
:mod:`onebit.pipeline.runner`). They run after the built-in reader stages (crossings,
truth, camera) and before the tracker stages, in the order listed here: reader stages for
motion and proximity logs, and pre-tracker stages such as the beams error correction.
"""

from __future__ import annotations

import importlib

STAGE_MODULES: tuple[str, ...] = (
    "onebit.pipeline.stages_motion",
    "onebit.pipeline.stages_correct",
    "onebit.pipeline.stages_proximity",
)


def extra_stages() -> list:
    out = []
    for mod in STAGE_MODULES:
        out.extend(importlib.import_module(mod).STAGES)
    return out
