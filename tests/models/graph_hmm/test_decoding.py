"""The decoded run shared by trackers that decode the same thing."""

from __future__ import annotations


def test_trackers_that_decode_the_same_run_share_it_read_only():
    """decode_motion returns the last decoded run again for the same motion table, site and
    decoding fields (hmm2 then findinghumo-flow's default full2), replaying its progress; a
    decoding field that differs decodes anew; the shared arrays cannot be written."""
    import pytest

    from onebit.experiments.findinghumo_diagnose import simulate
    from onebit.models.graph_hmm.decoding import HmmConfig, decode_motion
    from onebit.trackers.findinghumo_flow.stage import FlowConfig

    site, motion, _ = simulate(3)
    inputs = {"motion": motion}
    calls: list = []
    first = decode_motion("full2", inputs, site, HmmConfig(), progress=lambda d, t: calls.append((d, t)))
    again: list = []
    shared = decode_motion("full2", inputs, site, FlowConfig(), progress=lambda d, t: again.append((d, t)))
    assert shared is first and again == calls and len(calls) > 1
    assert decode_motion("full2", {"motion": motion.clone()}, site, FlowConfig()) is not first  # another table
    other = decode_motion("full2", inputs, site, HmmConfig(p_hit=0.8))
    assert other is not first
    assert decode_motion("adaptive", inputs, site, HmmConfig(p_hit=0.8)) is not other
    with pytest.raises(ValueError):
        first.result.paths[0, 0] = 1
    with pytest.raises(ValueError):
        first.active[0, 0] = True
