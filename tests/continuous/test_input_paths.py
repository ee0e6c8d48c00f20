"""What RecedingHorizon takes as its discrete paths, called from Python as a user's own planner's paths would be
(a library tour): (T + 1, N, d) whole grid cells, and a SmoothingConfig."""

from __future__ import annotations

import numpy as np
import pytest

from mrfswarm import OccupancyGrid, RecedingHorizon
from mrfswarm.config import SmoothingConfig
from mrfswarm.errors import ConfigError, ScenarioError

GRID = OccupancyGrid(np.zeros((10, 5)), resolution=0.5)
PATHS = np.array([[[0, 0], [0, 2]], [[1, 0], [1, 2]], [[2, 0], [2, 2]], [[3, 1], [3, 3]]])


def horizon(paths, cfg: object = None) -> RecedingHorizon:
    return RecedingHorizon(paths, GRID, SmoothingConfig() if cfg is None else cfg, 0.1)


def test_cells_given_as_floats_of_whole_numbers_smooth_as_integers():
    assert horizon(PATHS.astype(float)).run().makespan_s == horizon(PATHS).run().makespan_s


@pytest.mark.parametrize("paths, match", [
    # metres (Result.discrete_paths_world()) were floored to other cells without a word
    (GRID.cell_to_world(PATHS), r"^paths\[1, 0\] = \[0\.5, 0\.0\]: paths are grid cells, whole numbers"),
    (np.where(PATHS == 3, np.nan, PATHS), r"^paths\[3, 0\] = \[nan, 1\.0\]: paths are grid cells"),  # a cast warning
    (PATHS[:, :, 0], r"^paths must have shape \(T \+ 1, N, 2\).*got \(4, 2\)$"),  # an IndexError in the regions
    (PATHS[:0], r"^paths must have shape \(T \+ 1, N, 2\).*got \(0, 2, 2\)$"),  # "argmax of an empty sequence"
    ([["a"]], r"^paths must be \(T \+ 1, N, 2\) grid cells, got \[\['a'\]\]$"),
], ids=["metres", "nan", "no axis of points", "no step", "strings"])
def test_paths_that_are_not_cells_are_refused_naming_them(paths, match):
    with pytest.raises(ScenarioError, match=match):
        horizon(paths)


def test_a_config_that_is_not_the_smoothing_section_is_named():
    with pytest.raises(ConfigError, match=r"^cfg must be a mrfswarm\.config\.SmoothingConfig .*got dict$"):
        horizon(PATHS, {"v_max": 1.0})  # "'dict' object has no attribute 'backend'"
