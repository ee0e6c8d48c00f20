"""The window loop switches limit rows on per face of the limit polytope and part of a piece, in the plane as in
space."""

import numpy as np

from mrfswarm.config import SmoothingConfig
from mrfswarm.continuous import RecedingHorizon
from mrfswarm.continuous.formulation import LIMIT_PARTS, limit_polytope
from mrfswarm.maps import OccupancyGrid


def test_a_straight_run_switches_on_the_faces_and_parts_it_presses_only():
    """Three robots cruise 12 cells along x: their velocity presses the two faces of the limit polygon either side
    of x (its vertex: a run along the grid flies at the limit itself, not 0.924 of it); the rows of the faces
    and of the parts of a piece that no control point crosses stay off (all four faces and parts came on
    together before: 2-3 x the rows in big windows), and the flight keeps every derivative within its limit
    all the same."""
    cells = np.array([[2, 2], [2, 5], [2, 8]])
    paths = np.array([cells + [k, 0] for k in range(13)])
    grid = OccupancyGrid.from_occupied(np.zeros((16, 11), bool))
    cfg = SmoothingConfig()
    rh = RecedingHorizon(paths, grid, cfg, 0.25, workers=1)
    plan = rh.run()
    assert plan.certificate.ok
    faces, inner = limit_polytope(2)
    on = rh.limit_rows  # (T, N, 3, faces, parts)
    assert on.shape[-2:] == (len(faces), LIMIT_PARTS)
    assert on[:, :, 0, 0].any() and on[:, :, 0, -1].any()  # velocity: the faces at +-11.25 degrees from x
    some = on.any(axis=(-1, -2))  # (step, robot, order) with any row on
    assert some.any() and on.sum() < len(faces) * LIMIT_PARTS * some.sum()  # fewer than every face and part
    face = on.any(axis=-1)
    assert face.sum() < len(faces) * some.sum()  # not every face
    assert on.sum() < LIMIT_PARTS * face.sum()  # not every part of a face
    t = np.linspace(0.0, plan.makespan_s, 4001)
    for tr in plan.trajectories:  # within the limits (the certificate checks the control points; here sampled once more)
        for r, lim in zip((1, 2, 3), (cfg.v_max, cfg.a_max, cfg.j_max)):
            assert np.linalg.norm(tr.derivative(r)(t), axis=-1).max() <= lim * (1 + 1e-6)
    assert np.linalg.norm(plan.trajectories[0].derivative(1)(t), axis=-1).max() > 0.99 * cfg.v_max  # at the limit
