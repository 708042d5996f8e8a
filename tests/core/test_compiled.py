"""A kernel may call a kernel of another module (which calls one of its own), whichever of the two
modules compiles first."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

CALLEE = """
from onebit.core.compiled import kernel

@kernel
def _double(x):
    return x + x

@kernel
def twice(x):
    return _double(x)
"""

CALLER = """
from onebit.core.compiled import kernel
from {callee} import twice

@kernel
def twice_plus_one(x):
    return twice(x) + 1.0
"""


@pytest.mark.parametrize("callee_first", [True, False])
def test_a_kernel_calls_a_kernel_imported_from_another_module(tmp_path, callee_first):
    callee = f"callee_{int(callee_first)}"
    (tmp_path / f"{callee}.py").write_text(CALLEE)
    (tmp_path / f"caller_{int(callee_first)}.py").write_text(CALLER.format(callee=callee))
    first = f"{callee}.twice(3.0) == 6.0" if callee_first else "True"
    code = textwrap.dedent(
        f"""
        import sys
        sys.path.insert(0, {str(tmp_path)!r})
        import {callee}, caller_{int(callee_first)} as caller
        assert {first}
        assert caller.twice_plus_one(3.0) == 7.0
        assert {callee}.twice(2.0) == 4.0
        print("ok")
        """
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr[-2000:]
