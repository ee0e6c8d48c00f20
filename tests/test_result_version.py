"""result.json says which code made it and the congestion weight in force (a scale tour: runs that straddled a change
of the default could not be told apart, the config's unset congestion being null)."""

import re
import subprocess

import mrfswarm
from mrfswarm.config import CONGESTION, load_config
from mrfswarm.pipeline import code_version, plan
from support.repository import EXPERIMENTS, ROOT


def test_result_json_names_the_code_and_the_congestion_in_force():
    r = plan(load_config(EXPERIMENTS / "corridor.toml", ["smoothing.enabled=false", "simulation.enabled=false",
                                                          'goal_potential.distance="geodesic"']), progress=False)
    s = r.summary()
    assert s["config"]["goal_potential"]["congestion"] is None and s["congestion_weight"] == CONGESTION
    assert s["version"]["mrfswarm"] == mrfswarm.__version__
    commit = s["version"]["commit"]
    if (ROOT / ".git").exists():
        head = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True, text=True).stdout
        assert re.fullmatch(r"[0-9a-f]{40}(\+dirty)?", commit) and commit.startswith(head.strip())
    else:
        assert commit is None
    assert code_version() is code_version()  # asked once per process
