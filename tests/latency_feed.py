"""The wheels-and-GNSS feed loop of the latency identification's synthetic tests (test_latency.py's
``run``, test_latency_clean_late.py's ``noisy_wheels``), written once."""
from __future__ import annotations

from ecu_daemon.estimator.history import AUX_WHEEL, StepHistory


def feed_wheels(est, speed, delay_s: float, seconds: float, every: int, rng, gnss_noise: float = 0.0,
                wheel_scale: float = 1.0, wheel_noise: float = 0.0):
    """Feed ``est`` (a LatencyEstimator) a speed profile: the wheels read ``wheel_scale * speed(t)``
    at every step (plus ``wheel_noise``, a new draw per stored sample), and every ``every`` steps the
    GNSS reports ``speed(t - delay_s)`` (plus ``gnss_noise``) received just before step k + 1, valid
    at step k + 1 - d (a delay of d steps). Noise is drawn from ``rng`` in the order the samples come
    (no draw for a noise that is 0). Returns ``est``."""
    dt = est.dt
    hist = StepHistory(est.max_steps + 20)
    hist.reset(0)
    d = round(delay_s / dt)
    for k in range(int(seconds / dt)):
        wheel = wheel_scale * speed(k * dt)
        if wheel_noise:
            wheel = wheel + wheel_noise * rng.normal()
        hist.aux[hist.slot(k), AUX_WHEEL] = wheel
        hist.last = k
        if k % every == 0 and k > d:
            est.observe(k + 1, speed((k + 1 - d) * dt) + gnss_noise * rng.normal(), hist)
    return est
