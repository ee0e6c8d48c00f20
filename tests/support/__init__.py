"""Helpers shared by several test modules (references and inputs, not tests).

- :mod:`support.fields`: static fields of random maps;
- :mod:`support.final_checks_reference`: the whole-flight checks before the piece stack;
- :mod:`support.qp_reference`: QPs with known optima;
- :mod:`support.repository`: where the repository's files are (root, experiments, test data);
- :mod:`support.swarms`: random swarms on random maps;
- :mod:`support.trajectories`: random waypoints and the min-snap references.

Fixtures live in ``tests/conftest.py``.
"""
