"""The trial studies on the serial executor and a local process pool give equal tables (the
executors themselves, the seed sweeps and Ray: test_executors.py)."""

from __future__ import annotations

import pytest

#: (study, trials) small enough for a test; each study's own `quick` grid otherwise (the studies
#: fixture, tests/experiments/conftest.py)
STUDIES = (("okane", 1), ("singh", 1), ("schiff", 1))
#: none on Ray here: the seed sweep on Ray (test_executors.py) starts the Ray of the session
RAY_STUDIES = ()


@pytest.mark.parametrize("name", [s for s, _ in STUDIES])
def test_serial_and_local_pool_give_equal_tables(equal_tables, name):
    equal_tables(name)
