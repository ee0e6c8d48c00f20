"""experiments/navigation.py: its variants set what their names say."""

from __future__ import annotations

import csv

from experiments import navigation
from mrfswarm.config import load_config
from support.repository import EXPERIMENTS, ROOT

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


def test_the_figure_names_the_variants_its_example_panels_draw(monkeypatch, tmp_path):
    """Panels (d)-(g) draw the ``euclidean`` and ``default`` variants; the first keeps the default's rules, so
    its title may not say "paper" (the paper's rules throughout are the ``paper`` variant). They said
    "Euclidean (paper)"."""
    from mrfswarm import plots

    titles = []
    save = plots.save_figure

    def keep_titles(fig, path, *args, **kwargs):
        titles.extend(ax.get_title() for ax in fig.axes)
        return save(fig, path, *args, **kwargs)

    monkeypatch.setattr(plots, "save_figure", keep_titles)
    rows = navigation.read_rows(ROOT / "paper_figs" / "navigation.csv")
    navigation.figure(rows, {}, tmp_path / "navigation.png")
    drawn = [t for t in titles if any(f" {name}, " in t for name, _, _ in navigation.EXAMPLES)]
    assert len(drawn) == 2 * len(navigation.EXAMPLES)
    euclidean = [t for t in drawn if "Euclidean" in t]
    assert len(euclidean) == len(navigation.EXAMPLES)
    for t in euclidean:
        assert "paper" not in t and "default rules" in t, t
    assert (tmp_path / "navigation.png").stat().st_size > 0


def test_read_rows_gives_back_the_rows_the_study_writes(tmp_path):
    row = {"variant": "euclidean", "method": "icm", "map": "trap_01", "kind": "trap", "seed": 1, "n_robots": 20,
           "start_seed": 0, "success": False, "at_goal": 4, "cohesive": True, "steps_to_goal": "", "mrf_steps": 61,
           "stop_reason": "stalled", "trapped": 16, "stalled": 0, "separated": 0, "min_separation_m": 1.0,
           "max_nearest_neighbour_m": 2.236, "planning_s": 0.5, "field_s": 0.01, "goal_region_m": 5.4}
    with open(tmp_path / "navigation.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=navigation.COLUMNS)
        w.writeheader()
        w.writerows([row, {**row, "success": True, "steps_to_goal": 38}])
    assert navigation.read_rows(tmp_path / "navigation.csv") == [row, {**row, "success": True, "steps_to_goal": 38}]
