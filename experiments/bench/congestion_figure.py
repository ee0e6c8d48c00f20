"""The 200-robot clutter case (flight_quality.py, big200) with and without the congested goal field.

Writes ``--out`` (default ``docs/figures/congestion_big200.png``, the figure the README shows): the swarm at
steps 60, 120 and 180 of its
discrete plan, with ``goal_potential.congestion = 0`` (the static geodesic field) above and
the default below. Discrete stage only (about half a minute per plan).

    python experiments/bench/congestion_figure.py [--out figure.png]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "figures" / "congestion_big200.png",
                    help="the PNG to write (default: the README's figure)")
    args = ap.parse_args()
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    from flight_quality import case_config

    from mrfswarm.config import CONGESTION, apply_overrides, from_dict
    from mrfswarm.pipeline import plan

    data, base = case_config("big200")
    runs = []
    for label, extra in [("goal_potential.congestion = 0 (static field)", ["goal_potential.congestion=0"]),
                         (f"default (congestion = {CONGESTION:g})", [])]:
        cfg = from_dict(apply_overrides(data, ["smoothing.enabled=false", "simulation.enabled=false", *extra]), base)
        r = plan(cfg, progress=False)
        at = sum(bool(o.at_goal) for o in r.robots())
        print(f"{label}: {r.discrete.n_steps} steps, {r.discrete.stop_reason}, {at} of {r.scenario.n_robots} at the goal")
        runs.append((label, r))
    fig, axs = plt.subplots(2, 3, figsize=(12, 9))
    for row, (label, r) in enumerate(runs):
        P, grid = r.discrete.paths, r.scenario.grid
        for col, t in enumerate((60, 120, 180)):
            ax = axs[row, col]
            t = min(t, len(P) - 1)
            ax.imshow(grid.occupied.T, origin="lower", cmap="Greys", interpolation="nearest")
            ax.plot(P[t, :, 0], P[t, :, 1], ".", color="tab:red", ms=3)
            ax.plot(*np.asarray(r.scenario.goal)[:2], "*", color="tab:green", ms=14)
            ax.set_title(f"{label}\nstep {t}", fontsize=9)
            ax.set_xticks([])
            ax.set_yticks([])
    fig.suptitle("200 robots, 128 x 128 cells, 15 % obstacles: the static field sends every robot through the same "
                 "gaps", fontsize=10)
    fig.tight_layout(h_pad=2.0)
    out = args.out
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=80)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
