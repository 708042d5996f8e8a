"""``read_file`` (a log's bytes read into memory advised for huge pages) against ``Path.read_bytes``."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from onebit.readers import filebytes
from onebit.readers.filebytes import read_file


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(body=st.binary(max_size=3000), limit=st.sampled_from([0, 1, 100, filebytes.HUGE_READ_BYTES]))
def test_read_file_gives_the_files_bytes(tmp_path, monkeypatch, body, limit):
    """Any content, read the advised way (the size from which it is used lowered) or plainly."""
    monkeypatch.setattr(filebytes, "HUGE_READ_BYTES", limit)
    path = tmp_path / "log.csv"
    path.write_bytes(body)
    got = read_file(path)
    assert type(got) is bytes and got == body


def test_a_large_file_read_advised_is_its_bytes(tmp_path):
    """A file past the size and several huge pages long (a start and an end off the 2 MiB grid)."""
    body = os.urandom(3 * (1 << 21) + 12345)
    path = tmp_path / "big.csv"
    path.write_bytes(body)
    assert filebytes._C is not None or not os.uname().sysname == "Linux"
    assert read_file(path) == body
    assert read_file(str(path)) == body


@pytest.mark.parametrize("told", [-7, +7])
def test_a_file_that_changes_size_while_read_is_read_again(tmp_path, monkeypatch, told):
    """When the size the file had at ``fstat`` is not what is read, the plain read's bytes."""
    monkeypatch.setattr(filebytes, "HUGE_READ_BYTES", 1)
    body = b"t,sensor,value\n" + b"1.5,p1,1\n" * 50
    path = tmp_path / "motion.csv"
    path.write_bytes(body)
    real = os.fstat

    class Stat:
        def __init__(self, st):
            self.st_size = st.st_size + told

    monkeypatch.setattr(filebytes.os, "fstat", lambda fd: Stat(real(fd)))
    assert read_file(path) == body


def test_without_the_c_functions_it_is_read_bytes(tmp_path, monkeypatch):
    monkeypatch.setattr(filebytes, "_C", None)
    path = tmp_path / "beams.csv"
    path.write_bytes(b"t,beam,pair,blocked\n1,a,a,1\n")
    assert read_file(path) == path.read_bytes()


def test_errors_are_read_bytes_errors(tmp_path):
    with pytest.raises(IsADirectoryError):
        read_file(tmp_path)
    with pytest.raises(FileNotFoundError):
        read_file(tmp_path / "missing.csv")
    with pytest.raises(FileNotFoundError):
        Path(tmp_path / "missing.csv").read_bytes()
