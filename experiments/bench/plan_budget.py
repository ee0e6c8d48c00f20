"""Where a flight's time goes against its lower bound: the discrete plan, then the flight of it.

Per case of the flight-quality bench (``flight_quality.py``'s maps) and variant, with the working tree:

- ``x_bound``: makespan over the lower bound (:mod:`mrfswarm.flight_quality`);
- ``steps``, ``min_steps``: the plan's MRF steps, and the fewest moves the robot farthest from its final
  cell needs to reach it (the same graph as the bound; a diagonal counts one): no plan between those cells
  has fewer steps;
- ``detour``: the discrete path of the robot that sets the bound over its shortest free path;
- ``s_step``: the flight's median seconds per step, against ``s_diag``, the plan's longest move (a diagonal
  cell with the default ``mrf.order``) at v_max (with
  regions that let a step cut corners a step can be a little shorter);
- the moves the robots choose outside the goal region, per robot-step: ``best`` the move that lowers its
  free-path distance to the goal most, ``wait``, and the others: ``taken`` (another robot moves into that
  best cell in the same step), ``occupied`` (another robot stands in it) and ``free`` (it is free
  throughout: the robot's energy, its label set or the step's conflicts chose another).

    python experiments/bench/plan_budget.py [--cases clutter40,open50] [--variants default,refined] [--set KEY=VALUE]

The diagnosis behind docs/flight_quality.md's "Not yet reached" (seventh session of 2026-11-28):
clutter40's refined steps fly near v_max, and its plan takes 67 steps where 56 would do.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from csv_table import text_table, write_csv  # noqa: E402
from flight_quality import RESULTS, VARIANTS, case_config  # noqa: E402

COLUMNS = ["case", "variant", "x_bound", "steps", "min_steps", "detour", "s_step", "s_diag", "best", "wait",
           "taken", "occupied", "free"]
#: Goal distance (m) under which a robot counts as in the goal region for the move census (its moves there
#: pack the swarm, not bring it nearer).
NEAR_GOAL_CELLS = 3


def move_census(paths: np.ndarray, free: np.ndarray, distance: np.ndarray, near: float,
                order: int = 2) -> dict[str, int]:
    """Counts of the robots' moves (see the module docstring) over the robot-steps that start farther than
    ``near`` (metres) from the goal along free paths (``distance``, metres; inf where unreachable); moves of
    ``mrf.order`` ``order``."""
    from mrfswarm.discrete.motion import moves_clear, stencil

    off = stencil(order, free.ndim)  # the plan's moves, stay first
    counts = dict.fromkeys(["best", "wait", "taken", "occupied", "free"], 0)
    for t in range(len(paths) - 1):
        cur, nxt = paths[t], paths[t + 1]
        cand = cur[:, None, :] + off[None]  # (N, S, d)
        inside = np.all((cand >= 0) & (cand < np.array(free.shape)), axis=2)
        clipped = np.clip(cand, 0, np.array(free.shape) - 1)
        ok = inside & moves_clear(free, cur, np.broadcast_to(np.arange(len(off)), cand.shape[:2]), order)
        d = np.where(ok, distance[tuple(np.moveaxis(clipped, 2, 0))], np.inf)
        best = np.argmin(d, axis=1)
        here = distance[tuple(cur.T)]
        stands = {tuple(c) for c in cur}
        enters = {tuple(b) for a, b in zip(cur, nxt) if not np.array_equal(a, b)}
        for i in np.flatnonzero(here > near):
            if np.array_equal(nxt[i], cur[i]):
                counts["wait"] += 1
            elif distance[tuple(nxt[i])] <= d[i, best[i]] + 1e-9:
                counts["best"] += 1
            else:
                cell = tuple(cand[i, best[i]])
                counts["taken" if cell in enters else "occupied" if cell in stands else "free"] += 1
    return counts


def row(case: str, variant: str, overrides: list[str]) -> dict:
    from mrfswarm.config import apply_overrides, from_dict
    from mrfswarm.flight_quality import free_move_counts, free_path_lengths
    from mrfswarm.pipeline import plan

    data, base = case_config(case)
    cfg = from_dict(apply_overrides(data, ["simulation.enabled=false", *VARIANTS[variant], *overrides]), base)
    r = plan(cfg, progress=False)
    scn, paths, c = r.scenario, r.discrete.paths, r.smoothed()
    free, res = scn.grid.free, scn.grid.resolution
    q = r.flight_quality()
    assert q is not None
    k = q["bound_robot"]
    shortest = free_path_lengths(free, paths[:1, k], paths[-1:, k], res)[0]
    flown = float(np.linalg.norm(np.diff(paths[:, k], axis=0), axis=1).sum()) * res
    order = cfg.mrf.order
    census = move_census(paths, free, scn.distances.path, NEAR_GOAL_CELLS * res, order) \
        if scn.distances is not None else dict.fromkeys(["best", "wait", "taken", "occupied", "free"])
    return {"case": case, "variant": variant, "x_bound": round(q["makespan_over_bound"], 3),
            "steps": r.discrete.n_steps, "min_steps": int(free_move_counts(free, paths[0], paths[-1]).max()),
            "detour": round(flown / shortest, 3) if shortest > 0 else None,
            "s_step": round(float(np.median(np.diff(c.knot_times))), 3),
            "s_diag": round(float(np.sqrt(min(order, free.ndim)) * res / cfg.smoothing.v_max), 3), **census}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", default="clutter40,open50,aisles30,forest")
    ap.add_argument("--variants", default="default,refined")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--out", type=Path, default=RESULTS / "plan_budget.csv")
    args = ap.parse_args()
    rows = [row(case, variant, args.set) for case in args.cases.split(",") for variant in args.variants.split(",")]
    print(text_table(rows, COLUMNS))
    write_csv(args.out, rows, COLUMNS)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
