"""experiments/bench/smooth_time.py: its CLI timings run every variant more than once (each repeat writes the
same output file: it stopped at the second, since ``mrfswarm smooth`` refuses an existing --out)."""

from __future__ import annotations

import sys

import numpy as np

from support.repository import EXPERIMENTS

sys.path.insert(0, str(EXPERIMENTS / "bench"))
from smooth_time import cli_times  # noqa: E402


def test_cli_times_repeat_every_variant():
    W = np.array([[0.0, 0.0], [1.0, 0.5], [2.0, 0.0]])
    times = cli_times(W, 2.0, 4.0, reps=2)
    assert set(times) == {"plain", "refine+limits", "refine+toppra"} and all(t > 0 for t in times.values())
