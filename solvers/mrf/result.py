"""The one result type and the one options object of every MRF method."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Options:
    """Settings shared by every method; a method ignores what does not apply to it.

    Parameters
    ----------
    max_iter
        Cap on sweeps (ICM, Gibbs, lazy flipper) or message-passing iterations (BP, TRW-S).
    tol
        Stop when an iteration lowers the energy (or moves the bound) by less than this.
        For the single-site moves of ICM (and the lazy flipper's flips) it is the least
        decrease of E that a move must bring to be made: ties keep the current labels.
    seed
        Seed of any randomness (Gibbs sampling, tie breaking).
    time_limit
        Seconds; ``None`` for no limit.
    """

    max_iter: int = 100
    tol: float = 1e-9
    seed: int = 0
    time_limit: float | None = None

    def __post_init__(self) -> None:
        if self.max_iter < 1:
            raise ValueError(f"max_iter must be >= 1, got {self.max_iter}")
        if not self.tol >= 0:
            raise ValueError(f"tol must be >= 0, got {self.tol}")
        if self.time_limit is not None and not self.time_limit > 0:
            raise ValueError(f"time_limit must be positive, got {self.time_limit}")


@dataclass(frozen=True)
class MRFResult:
    """What every method returns.

    Attributes
    ----------
    labels
        (N,) the labelling, feasible (repaired if the method's raw output was not).
    energy
        E(labels).
    energy_trace
        Energy after each iteration (for methods that have one; at least the final).
    iterations
        Iterations (sweeps) the method ran.
    time_s
        Wall time of the method, repair included.
    method
        The registry name.
    lower_bound
        A lower bound on the optimum when the method provides one (TRW-S, exact).
    repaired
        Nodes sent back to their initial label because the raw output broke a conflict.
    stats
        Method-specific numbers (e.g. accepted moves, messages, temperature).
    """

    labels: np.ndarray
    energy: float
    energy_trace: np.ndarray
    iterations: int
    time_s: float
    method: str
    lower_bound: float | None = None
    repaired: int = 0
    stats: dict = field(default_factory=dict)
