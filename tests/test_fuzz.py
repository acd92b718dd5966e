"""Hypothesis fuzzing, a short run (``tools/bench_fuzz.py`` runs >= 1e5 inputs of each target)."""
from __future__ import annotations

from hypothesis import HealthCheck, given, settings

from fuzzing import can_frames, check_config, check_frame, check_gz, config_docs, gz_inputs

FAST = settings(deadline=None, database=None, suppress_health_check=[HealthCheck.too_slow])


@settings(FAST, max_examples=150)
@given(config_docs)
def test_a_config_that_passes_validation_builds_and_runs_an_estimator(doc):
    check_config(doc)


@settings(FAST, max_examples=400)
@given(can_frames())
def test_the_decoder_never_raises_on_random_frames_dlcs_and_fd_lengths(frame):
    check_frame(frame)


@settings(FAST, max_examples=100)
@given(gz_inputs())
def test_a_damaged_compressed_log_is_a_one_line_error(data):
    check_gz(data)
