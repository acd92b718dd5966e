"""The compiled candump line formatting (``_candump.lines``) against the Python f-strings it
replaces, and ``CandumpWriter.write_steps`` against ``write_payloads`` step by step."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ecu_daemon import canlog
from ecu_daemon.canlog import CandumpWriter

_candump = pytest.importorskip("ecu_daemon._candump", reason="the optional C extension is not built")

CHANNELS = st.sampled_from(["can0", "vcan1", "x"])
PAYLOAD = st.one_of(st.binary(max_size=64), st.binary(max_size=64).map(bytearray))
FRAMES = st.lists(st.tuples(st.integers(0, 0x7FF), PAYLOAD), max_size=4)
TIMES = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.floats(0, 2e9), st.just(-0.0))


def _reference(channel, steps):
    return "".join(CandumpWriter._lines_reference(channel, t, frames) for t, frames in steps)


@settings(max_examples=400, deadline=None)
@given(CHANNELS, st.lists(st.tuples(TIMES, FRAMES), max_size=6))
def test_compiled_lines_are_the_python_lines(channel, steps):
    assert _candump.lines(channel, steps) == _reference(channel, steps)


@pytest.mark.parametrize("steps", [
    [(np.float64(1.0), [(1, b"\x01")])],  # not an exact float: its own formatting is not C's business
    [(1.0, [(0x800, b"\x01")])],  # a 29-bit id
    [(1.0, [(-1, b"")])],
    [(1.0, [(1 << 70, b"")])],
    [(1.0, [(1, memoryview(b"\x01"))])],
    [(1.0, [(1, bytes(65))])],
    [(1.0, [(1, b"\x01", 0)])],
    [(1.0, ((1, b"\x01"),))],
    [[1.0, [(1, b"\x01")]]],
])
def test_anything_else_goes_back_to_python(steps):
    assert _candump.lines("can0", steps) is NotImplemented


def test_a_channel_name_that_is_not_printable_goes_back_to_python():
    assert _candump.lines("can 0", [(1.0, [(1, b"")])]) is NotImplemented


@pytest.mark.parametrize("compiled", [True, False])
def test_write_steps_writes_what_write_payloads_writes(tmp_path, monkeypatch, compiled):
    if not compiled:
        monkeypatch.setattr(canlog, "_candump_lines", None)
    steps = [(1200.006 * k, [(0x100 + k, bytearray([k] * 8)), (0x7FF, b"")][: k % 3]) for k in range(50)]
    steps.append((np.float64(1500.5), [(0x200, b"\xaa\xbb")]))  # one odd item: the whole batch in Python
    with CandumpWriter(tmp_path / "a.log") as w:
        for t, frames in steps:
            w.write_payloads(t, frames)
    with CandumpWriter(tmp_path / "b.log") as w:
        w.write_steps(steps[:-1])
        w.write_steps(steps[-1:])
        n = w.frames
    assert (tmp_path / "a.log").read_bytes() == (tmp_path / "b.log").read_bytes()
    assert n == sum(len(f) for _, f in steps)
