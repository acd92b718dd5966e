"""Learned-state persistence: atomic replace, round trip, corrupt files rejected in one line."""
from __future__ import annotations

import errno
import json
import math
import os
import subprocess
import sys

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


def test_unserialisable_state_is_refused_before_any_file_is_touched(tmp_path):
    p = tmp_path / "state.json"
    save_state(p, {"version": 1, "gnss_delay_s": 0.3})
    with pytest.raises(TypeError):
        save_state(p, {"version": 1, "x": object()})
    assert load_state(p) == {"version": 1, "gnss_delay_s": 0.3}
    assert sorted(os.listdir(tmp_path)) == ["state.json"]


#: In a child process whose file-size limit (RLIMIT_FSIZE) is below the new document, so the write
#: itself fails (EFBIG, as a full disk would with ENOSPC) after the temporary file was created.
FAILING_WRITER = """
import resource, signal, sys
from ecu_daemon.io.state_store import save_state
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # get the error, not the signal
resource.setrlimit(resource.RLIMIT_FSIZE, (4096, resource.getrlimit(resource.RLIMIT_FSIZE)[1]))
try:
    save_state(sys.argv[1], {"version": 1, "gnss_delay_s": 0.4, "padding": "x" * 100000})
except OSError as e:
    print(f"OSError {e.errno}")
"""


def test_failed_write_keeps_the_old_file_and_leaves_no_temporary(tmp_path):
    p = tmp_path / "state.json"
    save_state(p, {"version": 1, "gnss_delay_s": 0.3})
    r = subprocess.run([sys.executable, "-c", FAILING_WRITER, str(p)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == f"OSError {errno.EFBIG}"  # raised to the caller, who logs one line
    assert load_state(p) == {"version": 1, "gnss_delay_s": 0.3}  # the old file, whole
    assert sorted(os.listdir(tmp_path)) == ["state.json"]  # the half-written temporary removed
