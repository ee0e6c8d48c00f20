"""What an MRF method promises: one typed record per method, read by callers and tests."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, kw_only=True)
class MRFCapabilities:
    """The promises of an MRF method; every method states each one.

    Attributes
    ----------
    optimal
        Returns a global minimum (exhaustive: tiny problems only).
    lower_bound
        Reports a lower bound on the minimum (``MRFResult.lower_bound``).
    exact_on_trees
        Optimal when the edges and conflicts form a forest.
    monotone
        Never returns a labelling with a higher energy than ``mrf.initial``.
    stochastic
        Its result depends on ``Options.seed``.
    """

    optimal: bool
    lower_bound: bool
    exact_on_trees: bool
    monotone: bool
    stochastic: bool

    def flags(self) -> list[str]:
        """The names of the promises the method makes, for listings."""
        return [name for name, on in vars(self).items() if on]
