"""Path verification (Bobadilla et al., section IV-F-2): Smith-Waterman local alignment.

Given a story ``y_story`` (crossing labels such as ``"a b^-1 c"``) and an observation string
``y`` (the whole sensor word, or one reconstructed agent's string ``y_i``), find substrings
``s1`` of the story and ``s2`` of ``y`` whose similarity is maximum over all pairs of
substrings (the Local Alignment Problem, Gusfield ch. 11, solved by Smith & Waterman [22]).
The story is *plausible* when ``s1`` is the whole story.

Similarity: a match scores ``+match``, a mismatch ``mismatch`` (<= 0) and a gap ``-gap`` per
symbol. The table (i = 1..|story|, j = 1..|y|) is ::

    H[i, j] = max(0, H[i-1, j-1] + s(story_i, y_j), H[i-1, j] - gap, H[i, j-1] - gap)

with ``H[0, :] = H[:, 0] = 0``; the best local score is ``max H``. Row ``i`` is computed in
O(|y|) numpy work: with ``E[j] = max(0, H[i-1, j-1] + s, H[i-1, j] - gap)`` the left-gap
chain is a running maximum, ``H[i, j] = max_{k <= j} (E[k] - gap (j - k))`` =
``cummax(E[k] + gap k)[j] - gap j``. Total O(|story| |y|) time and space (the table is kept
for the traceback, which walks back from the arg-max until a zero cell).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
import polars as pl

_TOKEN = re.compile(r"^[^\s^]+(\^-1)?$")


@dataclass(frozen=True)
class Alignment:
    """Best local alignment of a story against one observation string.

    score : best local similarity ``max H``.
    story_span, observed_span : ``(start, end)`` half-open token ranges of ``s1`` and ``s2``.
    story_aligned, observed_aligned : the aligned rows, ``-`` for a gap.
    plausible : ``s1`` is the whole story (section IV-F-2).
    """

    score: float
    story_span: tuple[int, int]
    observed_span: tuple[int, int]
    story_aligned: tuple[str, ...]
    observed_aligned: tuple[str, ...]
    plausible: bool


def parse_story(story: str | list[str] | tuple[str, ...]) -> list[str]:
    """Crossing labels of a story: ``"a b^-1 c"`` -> ``["a", "b^-1", "c"]`` (also ``b-1``, ``b'``).

    Raises ``ValueError`` naming the bad token.
    """
    toks = story.split() if isinstance(story, str) else [str(s) for s in story]
    out = []
    for tok in toks:
        norm = re.sub(r"(\^?-1|')$", "^-1", tok)
        if not _TOKEN.match(norm):
            raise ValueError(f"story token {tok!r} is not a crossing label (beam or beam^-1)")
        out.append(norm)
    if not out:
        raise ValueError("story is empty")
    return out


def smith_waterman_table(
    story: np.ndarray, observed: np.ndarray, *, match: float = 2.0, mismatch: float = -1.0, gap: float = 1.0
) -> np.ndarray:
    """``(|story| + 1, |y| + 1)`` Smith-Waterman table ``H`` of two integer-coded strings."""
    a = np.asarray(story)
    b = np.asarray(observed)
    n, m = len(a), len(b)
    H = np.zeros((n + 1, m + 1), dtype=np.float64)
    ramp = gap * np.arange(m + 1, dtype=np.float64)
    for i in range(1, n + 1):  # rows are sequential; each row is vectorised over y
        sub = np.where(b == a[i - 1], match, mismatch)
        e = np.zeros(m + 1)
        e[1:] = np.maximum(0.0, np.maximum(H[i - 1, :-1] + sub, H[i - 1, 1:] - gap))
        H[i] = np.maximum.accumulate(e + ramp) - ramp
    return H


def local_alignment(
    story: list[str], observed: list[str], *, match: float = 2.0, mismatch: float = -1.0, gap: float = 1.0
) -> Alignment:
    """Smith-Waterman local alignment of ``story`` against ``observed`` (lists of labels).

    Examples
    --------
    >>> al = local_alignment(["a", "b^-1"], ["c", "a", "b^-1", "d"])
    >>> al.score, al.observed_span, al.plausible
    (4.0, (1, 3), True)
    """
    if match <= 0 or mismatch > 0 or gap <= 0:
        raise ValueError(f"need match > 0, mismatch <= 0, gap > 0; got {match}, {mismatch}, {gap}")
    vocab = {tok: k for k, tok in enumerate(dict.fromkeys([*story, *observed]))}
    a = np.fromiter((vocab[x] for x in story), np.int64, len(story))
    b = np.fromiter((vocab[x] for x in observed), np.int64, len(observed))
    H = smith_waterman_table(a, b, match=match, mismatch=mismatch, gap=gap)
    i, j = np.unravel_index(int(np.argmax(H)), H.shape)
    score = float(H[i, j])
    if score <= 0:
        return Alignment(0.0, (0, 0), (0, 0), (), (), False)
    top: list[str] = []
    bottom: list[str] = []
    end_i, end_j = int(i), int(j)
    eps = 1e-9
    while i > 0 and j > 0 and H[i, j] > eps:  # traceback: O(alignment length)
        h = H[i, j]
        s = match if a[i - 1] == b[j - 1] else mismatch
        if abs(h - (H[i - 1, j - 1] + s)) < eps:
            top.append(story[i - 1])
            bottom.append(observed[j - 1])
            i, j = i - 1, j - 1
        elif abs(h - (H[i - 1, j] - gap)) < eps:
            top.append(story[i - 1])
            bottom.append("-")
            i -= 1
        else:
            top.append("-")
            bottom.append(observed[j - 1])
            j -= 1
    span = (int(i), end_i)
    return Alignment(
        score, span, (int(j), end_j), tuple(reversed(top)), tuple(reversed(bottom)), span == (0, len(story))
    )


def verify_path(
    story: str | list[str],
    assignment: pl.DataFrame,
    *,
    match: float = 2.0,
    mismatch: float = -1.0,
    gap: float = 1.0,
) -> pl.DataFrame:
    """Align a story against the observation string and against every agent's string.

    ``assignment``: one row per crossing in time order with ``t, beam, direction`` and
    ``track`` (null for unexplained crossings) -- the ``beams_assignment`` table.
    Returns one row per target (``"observation"`` first, then each track): ``target, score,
    max_score`` (``match * |story|``), ``story_aligned, observed_aligned`` (space separated,
    ``-`` = gap), ``t_start, t_end`` of the aligned observed crossings, ``plausible``.
    """
    toks = parse_story(story)
    a = assignment.sort("t", maintain_order=True).with_columns(
        label=pl.when(pl.col("direction") > 0).then(pl.col("beam")).otherwise(pl.col("beam") + "^-1")
    )
    targets: list[tuple[str, pl.DataFrame]] = [("observation", a)]
    if "track" in a.columns:
        for (track,), g in a.filter(pl.col("track").is_not_null()).partition_by("track", as_dict=True).items():
            targets.append((str(track), g))
    rows = []
    # one alignment per target string (the observation, then each agent); each is the
    # row-vectorised Smith-Waterman of ``smith_waterman_table``
    for name, g in sorted(targets, key=lambda x: (x[0] != "observation", _natural(x[0]))):
        labels = g["label"].to_list()
        al = local_alignment(toks, labels, match=match, mismatch=mismatch, gap=gap)
        ts = g["t"]
        j0, j1 = al.observed_span
        rows.append(
            {
                "target": name,
                "score": al.score,
                "max_score": match * len(toks),
                "story_aligned": " ".join(al.story_aligned),
                "observed_aligned": " ".join(al.observed_aligned),
                "t_start": ts[j0] if j1 > j0 else None,
                "t_end": ts[j1 - 1] if j1 > j0 else None,
                "plausible": al.plausible,
            }
        )
    schema = {
        "target": pl.String,
        "score": pl.Float64,
        "max_score": pl.Float64,
        "story_aligned": pl.String,
        "observed_aligned": pl.String,
        "t_start": pl.Float64,
        "t_end": pl.Float64,
        "plausible": pl.Boolean,
    }
    return pl.DataFrame(rows, schema=schema)


def _natural(name: str):
    return [int(tok) if tok.isdigit() else tok for tok in re.split(r"(\d+)", name)]
