"""``merge_waits`` old against new on the free-space crossing: seconds, merges, and whether the paths are the same.

Inputs: the crossing of ``scale.py`` (N robots around (50, 100) crossing a free
300 x 200 m map) for each N, planned once by the working tree with ``mrf.merge_waits =
false`` and saved to ``--inputs`` (reused when there): the paths ``merge_waits`` is given
at the end of the discrete stage, and the flight model the pipeline passes it.

Then, in this one process, ``merge_waits`` of git revision ``--baseline`` (the module
file alone, loaded beside the working tree's: both use the working tree's
``motion`` and ``geometry``) and of the working tree each merge those paths, with the
flight model and without (every safe merge), alternately, the best of ``--repeat``. The
table gives old and new seconds, the speed-up, the merges, and ``same``: the paths equal
element for element and the same number of merges (a difference is an error).

    python experiments/bench/merge_waits_speed.py [--sizes 300,1000] [--baseline 5f9ffa7] [--repeat 2]
        [--inputs DIR] [--out experiments/bench/results/merge_waits_speed.csv]
"""

from __future__ import annotations

import argparse
import importlib.util
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from baseline_code import ROOT
from csv_table import text_table, write_csv
from scale import overrides

RESULTS = Path(__file__).parent / "results"
MODULE = "mrfswarm/discrete/merge_waits.py"


def make_inputs(n: int, path: Path) -> None:
    """Plan the crossing for ``n`` robots without merging and save the paths and the flight model."""
    import mrfswarm
    from mrfswarm.pipeline import plan

    cfg = mrfswarm.load_config(None, [*overrides(n), "mrf.merge_waits=false"])
    r = plan(cfg, progress=False)
    flight = r.scenario.discrete_problem().flight
    model = [] if flight is None else [flight.resolution, flight.v_max, flight.acceleration, flight.drift]
    np.savez(path, paths=r.discrete.paths, downwash=cfg.scenario.downwash, flight=np.array(model, dtype=float))


def old_module(ref: str, into: Path):
    """The module ``merge_waits`` at git revision ``ref``, imported from a file under ``into``."""
    text = subprocess.run(["git", "-C", str(ROOT), "show", f"{ref}:{MODULE}"], capture_output=True, text=True,
                          check=True).stdout
    path = into / "merge_waits_old.py"
    path.write_text(text)
    spec = importlib.util.spec_from_file_location("merge_waits_old", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", default="300,1000")
    ap.add_argument("--baseline", default="5f9ffa7", help="git revision of the old merge_waits")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--inputs", type=Path, default=None, help="folder of the planned paths (default: a temporary one)")
    ap.add_argument("--out", type=Path, default=RESULTS / "merge_waits_speed.csv")
    args = ap.parse_args()

    from mrfswarm.continuous.time_grid import FlightModel
    from mrfswarm.discrete import merge_waits as new

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        old = old_module(args.baseline, Path(tmp))
        inputs = args.inputs or Path(tmp)
        inputs.mkdir(parents=True, exist_ok=True)
        for n in (int(v) for v in args.sizes.split(",")):
            path = inputs / f"merge_waits_cross{n}.npz"
            if not path.exists():
                make_inputs(n, path)
            data = np.load(path)
            model = FlightModel(*data["flight"]) if len(data["flight"]) else None
            for flight in (model, None):
                times: dict[str, list[float]] = {"old": [], "new": []}
                out = {}
                for _ in range(args.repeat):
                    for name, module in (("old", old), ("new", new)):
                        t0 = time.perf_counter()
                        out[name] = module.merge_waits(data["paths"], float(data["downwash"]), flight)
                        times[name].append(time.perf_counter() - t0)
                same = out["old"][1] == out["new"][1] and np.array_equal(out["old"][0], out["new"][0])
                rows.append({"N": n, "steps": len(data["paths"]) - 1, "flight": "model" if flight else "none",
                             "merges": out["new"][1], "old_s": round(min(times["old"]), 2),
                             "new_s": round(min(times["new"]), 2),
                             "speedup": round(min(times["old"]) / min(times["new"]), 1), "same": same})
    print(text_table(rows))
    write_csv(args.out, rows)
    print(f"wrote {args.out}")
    if not all(r["same"] for r in rows):
        raise SystemExit("the new merge_waits changed a result")


if __name__ == "__main__":
    main()
