"""A backend added the way a user adds one (``Registry.register``), importable by reference in a spawned worker."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

from solvers.mrf import METHODS, MRFResult, Options, PairwiseMRF, icm
from solvers.registry import Backend


def icm_twin(mrf: PairwiseMRF, options: Options) -> MRFResult:
    """ICM under another name: a real method, so that a plan with it equals one with ``icm``."""
    return icm.minimize(mrf, options)


TWIN = Backend(name="icm_twin", entry=icm_twin, capabilities=icm.BACKEND.capabilities, summary="ICM, added")


@contextlib.contextmanager
def registered() -> Iterator[Backend]:
    """``TWIN`` in ``solvers.mrf.METHODS`` for the block."""
    METHODS.register(TWIN)
    try:
        yield TWIN
    finally:
        METHODS.unregister(TWIN.name)
