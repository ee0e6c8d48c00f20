"""experiments/navigation.py: its variants set what their names say."""

from __future__ import annotations

from experiments import navigation
from mrfswarm.config import load_config
from support.repository import EXPERIMENTS

#: The rules the paper's scenario configs set back (README, "Configs"), as (section, key).
RULES = [("goal_potential", "distance"), ("goal_potential", "congestion_weight"), ("obstacle_potential", "gamma"),
         *(("mrf", k) for k in ("trim_backward", "contested", "follow", "arrival", "merge_waits", "drop_loops",
                                "straighten", "escalation", "progress"))]


def test_the_paper_variant_sets_every_rule_the_paper_configs_set():
    overrides, method = navigation.ICM_VARIANTS["paper"]
    study = load_config(EXPERIMENTS / "maps" / "rooms_01.toml", list(overrides))
    paper = load_config(EXPERIMENTS / "corridor.toml")
    assert method == "icm"
    for section, key in RULES:
        assert getattr(getattr(study, section), key) == getattr(getattr(paper, section), key), f"{section}.{key}"
