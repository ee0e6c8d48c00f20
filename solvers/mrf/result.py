"""The one result type and the one options object of every MRF method."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from solvers.errors import InvalidOptions
from solvers.options import check_fields


@dataclass(frozen=True)
class Options:
    """Settings shared by every method; a method ignores what does not apply to it.

    Parameters
    ----------
    max_iter
        Cap on sweeps (ICM, Gibbs; also each ICM descent of the lazy flipper and of
        ``polish``), rounds of joint moves (lazy flipper) or message-passing iterations
        (BP, TRW-S).
    tol
        ICM and the lazy flipper: the least decrease of E that a move must bring to be
        made (ties keep the current labels; the descent stops when a sweep moves
        nothing). BP: stop when no message changes by more than this. TRW-S: stop when
        an iteration raises the bound by at most ``tol * max(1, |bound|)`` or the best
        energy is within ``tol`` of it.
    seed
        Seed of any randomness (Gibbs sampling, tie breaking).
    time_limit
        Seconds; ``None`` for no limit.
    temperature
        ``gibbs``: initial temperature T_0; ``None`` sets it from the problem (the
        median, over nodes, of the standard deviation of the local energy over the
        feasible labels at ``initial``).
    schedule
        ``gibbs``: ``"geometric"`` (T_k = T_0 * cooling**k, k = 0, 1, ... sweeps) or
        ``"log"`` (T_k = T_0 / log(k + 2), Geman & Geman's logarithmic schedule).
    cooling
        ``gibbs``: factor of the geometric schedule, in (0, 1).
    damping
        ``bp``: weight of the old message in each update, in [0, 1) (0: undamped).
    conflict_penalty
        ``bp``, ``trws``: finite cost added to forbidden label pairs of conflicting nodes
        inside message passing (hard constraints as messages would need inf - inf).
        ``None`` picks one larger than any single node's possible change of local
        energy; 0 ignores conflicts while passing messages (decoding still respects them).
    max_flip
        ``lazy_flipper``: the largest number of nodes changed jointly in one move, >= 1.
    polish
        ``bp``, ``trws``, ``gibbs``: finish with ICM from the method's labelling.
    """

    max_iter: int = 100
    tol: float = 1e-9
    seed: int = 0
    time_limit: float | None = None
    temperature: float | None = None
    schedule: str = "geometric"
    cooling: float = 0.9
    damping: float = 0.5
    conflict_penalty: float | None = None
    max_flip: int = 2
    polish: bool = False

    def __post_init__(self) -> None:
        check_fields(self)
        if self.max_iter < 1:
            raise InvalidOptions(f"max_iter must be >= 1, got {self.max_iter}")
        if not 0 <= self.tol < float("inf"):  # inf: no move was ever enough for ICM or the lazy flipper (a library tour)
            raise InvalidOptions(f"tol must be finite and >= 0, got {self.tol}")
        if self.seed < 0:
            raise InvalidOptions(f"seed must be >= 0, got {self.seed}")
        if self.time_limit is not None and not self.time_limit > 0:
            raise InvalidOptions(f"time_limit must be positive, got {self.time_limit}")
        if self.temperature is not None and not (0 < self.temperature < float("inf")):
            raise InvalidOptions(f"temperature must be positive and finite, got {self.temperature}")
        if self.schedule not in ("geometric", "log"):
            raise InvalidOptions(f"schedule must be 'geometric' or 'log', got {self.schedule!r}")
        if not 0 < self.cooling < 1:
            raise InvalidOptions(f"cooling must be in (0, 1), got {self.cooling}")
        if not 0 <= self.damping < 1:
            raise InvalidOptions(f"damping must be in [0, 1), got {self.damping}")
        if self.conflict_penalty is not None and not (0 <= self.conflict_penalty < float("inf")):
            raise InvalidOptions(f"conflict_penalty must be finite and >= 0, got {self.conflict_penalty}")
        if self.max_flip < 1:
            raise InvalidOptions(f"max_flip must be >= 1, got {self.max_flip}")


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
