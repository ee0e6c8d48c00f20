"""One preference-ordered registry per kind of solver.

Each backend module declares a :class:`Backend` record; the package's ``__init__``
builds the one :class:`Registry` of its kind from those records. Dispatch,
``mrfswarm solvers``, tests and benchmarks all iterate that registry, so the list of
names exists exactly once.
"""

from __future__ import annotations

import importlib.util
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

from solvers.errors import SolverNotFound


@dataclass(frozen=True)
class Backend:
    """A registered solver.

    Parameters
    ----------
    name
        The name users pass (``--qp osqp``, ``method="icm"``).
    entry
        The callable (or class) that does the work; it imports the native package
        itself, so that registering costs nothing.
    requires
        Top-level modules that must be importable for the backend to be available.
    extra
        The pip extra of ``mrfswarm`` that installs ``requires``; empty if always there.
    summary
        One line for ``mrfswarm solvers``.
    capabilities
        Free-form flags (``"inequalities"``, ``"lower_bound"``, ...), read by callers
        that need a capability.
    """

    name: str
    entry: Callable[..., Any]
    requires: tuple[str, ...] = ()
    extra: str = ""
    summary: str = ""
    capabilities: frozenset[str] = field(default_factory=frozenset)

    def is_available(self) -> bool:
        """True when every required module can be found (nothing is imported)."""
        return all(importlib.util.find_spec(m) is not None for m in self.requires)

    @property
    def install_hint(self) -> str:
        """The command that installs this backend."""
        if not self.extra:
            return "included"
        return f'pip install "mrfswarm[{self.extra}]"'


class Registry:
    """A preference-ordered, read-only mapping of name -> :class:`Backend`."""

    def __init__(self, kind: str, backends: list[Backend]) -> None:
        self.kind = kind
        self._backends: dict[str, Backend] = {}
        for b in backends:
            if b.name in self._backends:
                raise ValueError(f"duplicate {kind} backend {b.name!r}")
            self._backends[b.name] = b

    def __iter__(self) -> Iterator[Backend]:
        return iter(self._backends.values())

    def __len__(self) -> int:
        return len(self._backends)

    def __contains__(self, name: object) -> bool:
        return name in self._backends

    def names(self) -> list[str]:
        """Every registered name, in preference order."""
        return list(self._backends)

    def available(self) -> list[str]:
        """Names of the installed backends, in preference order."""
        return [b.name for b in self if b.is_available()]

    def get(self, name: str) -> Backend:
        """The installed backend called ``name``.

        Raises
        ------
        SolverNotFound
            If ``name`` is unknown, or known but not installed; the message names the
            installed backends and the pip extra to install.
        """
        installed = ", ".join(self.available()) or "none"
        b = self._backends.get(name)
        if b is None:
            raise SolverNotFound(
                f"unknown {self.kind} backend {name!r}; installed: {installed}"
            )
        if not b.is_available():
            missing = [m for m in b.requires if importlib.util.find_spec(m) is None]
            raise SolverNotFound(
                f"{self.kind} backend {name!r} is not installed (missing module "
                f"{', '.join(missing)}): {b.install_hint}; installed: {installed}"
            )
        return b
