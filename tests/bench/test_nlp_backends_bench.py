"""experiments/bench/nlp_backends.py: its receding horizon benchmarks the first windows' NLP and plans on.

Its ``_refine`` override fell behind the receding horizon's (a ``merged`` argument more) and the script stopped with
a TypeError at its first window; a docs tour found it."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parents[2] / "experiments" / "bench"))
from nlp_backends import SETTINGS, Benchmarked  # noqa: E402

from mrfswarm.config import load_config  # noqa: E402
from mrfswarm.pipeline import plan, qp_options  # noqa: E402
from support.repository import EXPERIMENTS  # noqa: E402


def test_the_first_window_is_benchmarked_and_the_flight_planned():
    config = EXPERIMENTS / "free5.toml"
    cfg = load_config(config, ["simulation.enabled=false", "smoothing.time_refinement=true"])
    discrete = plan(load_config(config, ["simulation.enabled=false", "smoothing.enabled=false"]), progress=False)
    rh = Benchmarked(discrete.discrete.paths, discrete.scenario.grid, cfg.smoothing, cfg.scenario.robot_radius,
                     cfg.smoothing.backend, qp_options(cfg), workers=1, windows=1, backends=["slsqp"])
    flight = rh.run()
    assert [(r["setting"], r["backend"]) for r in rh.rows] == [(s, "slsqp") for s in SETTINGS]
    assert len({r["window"] for r in rh.rows}) == 1
    assert all(r["objective"] <= r["f_start"] for r in rh.rows)
    assert flight.certificate.ok
