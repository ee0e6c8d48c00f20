"""experiments/bench/mrf_step.py prints, beside the times, what its docstring says it prints for reference: each
step's energy decrease, ours and the plain baseline's, and whether both moved the robots to the same cells (it said
"the baseline's energy is printed for reference" and printed times only)."""

from __future__ import annotations

import csv
import sys

import pytest

from support.repository import EXPERIMENTS

sys.path.insert(0, str(EXPERIMENTS / "bench"))
import mrf_step  # noqa: E402
import mrf_step_3d  # noqa: E402

from solvers import mrf as mrf_solvers  # noqa: E402


def test_the_table_gives_both_energy_decreases_and_whether_the_cells_agree(tmp_path, monkeypatch, capsys):
    out = tmp_path / "mrf_step.csv"
    monkeypatch.setattr(sys, "argv", ["mrf_step.py", "--sizes", "5", "--orders", "2", "--steps", "2",
                                      "--out", str(out)])
    mrf_step.main()
    lines = capsys.readouterr().out.splitlines()
    assert lines[1].split()[-4:] == ["dE", "base", "dE", "same"]
    row = next(csv.DictReader(open(out, newline="")))
    # 5 robots: both steps alike, each lowering the energy by the same amount
    assert row["same_cells"] == "2/2"
    assert float(row["energy_drop"]) > 0
    assert abs(float(row["energy_drop"]) - float(row["baseline_energy_drop"])) < 1e-9
    assert lines[2].split()[-3:] == [f"{float(row['energy_drop']):.4g}"] * 2 + ["2/2"]


@pytest.mark.parametrize("script, argv", [(mrf_step, ["--method", "icn"]), (mrf_step, ["--methods", "icm,icn"]),
                                          (mrf_step_3d, ["--method", "icn"])], ids=["method", "methods", "3d"])
def test_an_unknown_method_is_one_line_naming_it_and_the_installed_ones(script, argv, tmp_path, monkeypatch):
    """A tour's '--method icn' ended in a SolverNotFound traceback from inside the timing loop."""
    prog = f"{script.__name__}.py"
    monkeypatch.setattr(sys, "argv", [prog, *argv, "--sizes", "5", "--out", str(tmp_path / "x.csv")])
    with pytest.raises(SystemExit) as e:
        script.main()
    flag = argv[0]
    assert str(e.value) == (f"{prog}: error: {flag}: unknown MRF method 'icn'; "
                            f"installed: {', '.join(mrf_solvers.METHODS.available())}")
    assert not (tmp_path / "x.csv").exists()
