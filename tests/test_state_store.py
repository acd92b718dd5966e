"""Learned-state persistence: atomic replace, round trip, corrupt files rejected in one line."""
from __future__ import annotations

import json
import math
import os

import pytest

from ecu_daemon.io.state_store import StateFileError, load_state, save_state


def test_round_trip_and_no_temp_files_left(tmp_path):
    p = tmp_path / "sub" / "state.json"
    learned = {"version": 1, "yaw_rate_bias_radps": 0.0123, "gnss_delay_s": 0.41, "bad": math.nan}
    save_state(p, learned, saved_at=1.0)
    got = load_state(p)
    assert got == {"version": 1, "yaw_rate_bias_radps": 0.0123, "gnss_delay_s": 0.41}  # NaN dropped
    save_state(p, {"version": 1, "gnss_delay_s": 0.2})
    assert load_state(p) == {"version": 1, "gnss_delay_s": 0.2}
    assert sorted(os.listdir(p.parent)) == ["state.json"]


def test_missing_file_is_not_an_error(tmp_path):
    assert load_state(tmp_path / "nope.json") is None


@pytest.mark.parametrize("content", [b"{not json", b"\xff\xfe", b"[]", b'{"format": "other"}',
                                     json.dumps({"format": "ecu-daemon-state", "version": 99,
                                                 "learned": {}}).encode(), b""])
def test_corrupt_files_raise_one_line_error(tmp_path, content):
    p = tmp_path / "state.json"
    p.write_bytes(content)
    with pytest.raises(StateFileError) as e:
        load_state(p)
    assert "\n" not in str(e.value) and str(p) in str(e.value)


def test_failed_write_keeps_the_old_file(tmp_path):
    p = tmp_path / "state.json"
    save_state(p, {"version": 1, "gnss_delay_s": 0.3})
    with pytest.raises(TypeError):  # not JSON-serialisable: nothing is replaced
        save_state(p, {"version": 1, "x": object()})
    assert load_state(p) == {"version": 1, "gnss_delay_s": 0.3}
    assert sorted(os.listdir(tmp_path)) == ["state.json"]
