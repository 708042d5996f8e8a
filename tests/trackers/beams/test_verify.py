"""Path verification (section IV-F-2): Smith-Waterman against brute force, API and CLI."""

from __future__ import annotations

import functools

import numpy as np
import polars as pl
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit.cli import main
from onebit.trackers.beams.verify import local_alignment, parse_story, smith_waterman_table, verify_path

MATCH, MISMATCH, GAP = 2.0, -1.0, 1.0


def _global(a: tuple, b: tuple, match: float, mismatch: float, gap: float) -> float:
    """Best global alignment score of a and b, by exhaustive recursion over the last column."""

    @functools.cache
    def g(i: int, j: int) -> float:
        if i == 0:
            return -gap * j
        if j == 0:
            return -gap * i
        return max(
            g(i - 1, j - 1) + (match if a[i - 1] == b[j - 1] else mismatch),
            g(i - 1, j) - gap,
            g(i, j - 1) - gap,
        )

    return g(len(a), len(b))


def _brute_local(a, b, match=MATCH, mismatch=MISMATCH, gap=GAP) -> float:
    """Local alignment by definition: the best global score over all pairs of substrings."""
    best = 0.0
    for i0 in range(len(a)):
        for i1 in range(i0 + 1, len(a) + 1):
            for j0 in range(len(b)):
                for j1 in range(j0 + 1, len(b) + 1):
                    best = max(best, _global(tuple(a[i0:i1]), tuple(b[j0:j1]), match, mismatch, gap))
    return best


def _aligned_score(top, bottom, match=MATCH, mismatch=MISMATCH, gap=GAP) -> float:
    return sum(-gap if x == "-" or y == "-" else (match if x == y else mismatch) for x, y in zip(top, bottom))


labels = st.lists(st.sampled_from(["a", "a^-1", "b", "b^-1", "c"]), min_size=1, max_size=6)


@settings(max_examples=200, deadline=None)
@given(labels, labels, st.sampled_from([(2.0, -1.0, 1.0), (1.0, -1.0, 2.0), (3.0, 0.0, 1.0)]))
def test_smith_waterman_matches_brute_force(story, observed, scores):
    match, mismatch, gap = scores
    al = local_alignment(story, observed, match=match, mismatch=mismatch, gap=gap)
    assert al.score == pytest.approx(_brute_local(story, observed, match, mismatch, gap))
    if al.score > 0:
        # the traceback's aligned rows are the substrings it reports and reproduce the score
        assert [x for x in al.story_aligned if x != "-"] == story[al.story_span[0] : al.story_span[1]]
        assert [x for x in al.observed_aligned if x != "-"] == observed[al.observed_span[0] : al.observed_span[1]]
        assert _aligned_score(al.story_aligned, al.observed_aligned, match, mismatch, gap) == pytest.approx(al.score)
        assert al.plausible == (al.story_span == (0, len(story)))


@settings(max_examples=60, deadline=None)
@given(labels, labels, labels)
def test_a_story_inside_the_string_is_plausible(prefix, story, suffix):
    al = local_alignment(story, prefix + story + suffix)
    assert al.plausible and al.score == MATCH * len(story)


def test_table_rows_are_vectorised_recurrence():
    a = np.array([0, 1, 2])
    b = np.array([2, 0, 1, 1, 2])
    H = smith_waterman_table(a, b)
    ref = np.zeros_like(H)
    for i in range(1, 4):
        for j in range(1, 6):
            s = MATCH if a[i - 1] == b[j - 1] else MISMATCH
            ref[i, j] = max(0, ref[i - 1, j - 1] + s, ref[i - 1, j] - GAP, ref[i, j - 1] - GAP)
    assert np.array_equal(H, ref)


def test_parse_story():
    assert parse_story("a b^-1 c'") == ["a", "b^-1", "c^-1"]
    assert parse_story(" d-1  e ") == ["d^-1", "e"]
    with pytest.raises(ValueError, match="empty"):
        parse_story("  ")
    with pytest.raises(ValueError, match="'\\^x'"):
        parse_story("a ^x")


def _assignment() -> pl.DataFrame:
    # paper Fig. 1: g^-1 a^-1 d^-1 e^-1 b b^-1 c^-1 c e f with the paper's three agents
    word = "g^-1 a^-1 d^-1 e^-1 b b^-1 c^-1 c e f".split()
    who = ["agent1", "agent2", "agent1", "agent3", "agent2", "agent3", "agent1", "agent3", "agent2", "agent2"]
    return pl.DataFrame(
        {
            "t": [float(i) for i in range(len(word))],
            "beam": [w[0] for w in word],
            "direction": pl.Series([-1 if w.endswith("^-1") else 1 for w in word], dtype=pl.Int8),
            "track": who,
        }
    )


def test_verify_path_against_observation_and_agents():
    res = verify_path("a^-1 b e f", _assignment())
    assert res["target"].to_list() == ["observation", "agent1", "agent2", "agent3"]
    row = {r["target"]: r for r in res.iter_rows(named=True)}
    assert row["agent2"]["plausible"] and row["agent2"]["score"] == row["agent2"]["max_score"] == 8.0
    assert row["agent2"]["observed_aligned"] == "a^-1 b e f"
    # in the observation string the story is interleaved with 5 crossings of the others: with a gap
    # penalty of 1 the best local alignment is only "e f" (4 > 8 - 5 + ...); cheaper gaps accept it
    assert not row["observation"]["plausible"] and row["observation"]["score"] == 4.0
    cheap = verify_path("a^-1 b e f", _assignment(), gap=0.5).row(0, named=True)
    assert cheap["plausible"] and cheap["score"] == 8.0 - 5 * 0.5
    assert cheap["story_aligned"] == "a^-1 - - b - - - e f"
    assert cheap["observed_aligned"] == "a^-1 d^-1 e^-1 b b^-1 c^-1 c e f"
    assert (cheap["t_start"], cheap["t_end"]) == (1.0, 9.0)
    assert not row["agent1"]["plausible"] and not row["agent3"]["plausible"]
    # a story no agent followed
    res = verify_path("g f^-1 a", _assignment())
    assert not res["plausible"].any()


def test_verify_path_cli(tmp_path, capsys):
    (tmp_path / "tables").mkdir()
    _assignment().write_parquet(tmp_path / "tables" / "beams_assignment.parquet")
    assert main(["verify-path", str(tmp_path), "--story", "e^-1 b^-1 c"]) == 0
    out = capsys.readouterr().out
    assert "plausible against the observation string: yes" in out and "agent3" in out
    assert main(["verify-path", str(tmp_path), "--story", "g a"]) == 1
    assert main(["verify-path", str(tmp_path), "--story", "a ^"]) == 2
    assert "story token" in capsys.readouterr().err
    assert main(["verify-path", str(tmp_path / "none"), "--story", "a"]) == 2
    assert "beams_assignment" in capsys.readouterr().err
