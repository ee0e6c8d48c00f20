"""One preference-ordered registry per kind of solver.

Each backend module declares a :class:`Backend` record; the package's ``__init__``
builds the one :class:`Registry` of its kind from those records. Dispatch,
``mrfswarm solvers``, tests and benchmarks all iterate that registry, so the list of
names exists exactly once. A record's ``capabilities`` is a typed, frozen dataclass of
its kind (:class:`solvers.qp.QPCapabilities`, :class:`solvers.mrf.MRFCapabilities`);
callers read its fields, never a backend's name.
"""

from __future__ import annotations

import importlib.util
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from functools import cache
from typing import Any, Generic, TypeVar

from solvers.errors import SolverNotFound

C = TypeVar("C")


@cache
def _distribution() -> str | None:
    """The installed distribution that ships this package (for install hints), if any.

    Looked up in the installed metadata rather than written here: the numerical layer
    does not name the package that happens to install it.
    """
    from importlib.metadata import packages_distributions

    names = packages_distributions().get(__name__.split(".")[0], [])
    return names[0] if names else None


@dataclass(frozen=True)
class Backend(Generic[C]):
    """A registered solver.

    Parameters
    ----------
    name
        The name users pass (``--qp osqp``, ``method="icm"``).
    entry
        The callable (or class) that does the work; it imports the native package
        itself, so that registering costs nothing.
    capabilities
        What the backend can do, as the typed record of its kind; read by dispatch.
    requires
        Top-level modules that must be importable for the backend to be available.
    extra
        The pip extra that installs ``requires``; empty if always there.
    summary
        One line for ``mrfswarm solvers``.
    """

    name: str
    entry: Callable[..., Any]
    capabilities: C
    requires: tuple[str, ...] = ()
    extra: str = ""
    summary: str = ""

    def is_available(self) -> bool:
        """True when every required module can be found (nothing is imported)."""
        return all(importlib.util.find_spec(m) is not None for m in self.requires)

    @property
    def install_hint(self) -> str:
        """How to install this backend: the pip command of its extra, or ``"included"``."""
        if not self.extra:
            return "included"
        dist = _distribution()
        if dist is None:
            return f"install the {self.extra!r} extra"
        return f'pip install "{dist}[{self.extra}]"'


class Registry(Generic[C]):
    """A preference-ordered, read-only mapping of name -> :class:`Backend`."""

    def __init__(self, kind: str, backends: list[Backend[C]], noun: str = "backend") -> None:
        self.kind, self.noun = kind, noun  # noun: what the kind calls its entries ("MRF method")
        self._backends: dict[str, Backend[C]] = {}
        for b in backends:
            if b.name in self._backends:
                raise ValueError(f"duplicate {kind} {noun} {b.name!r}")
            self._backends[b.name] = b

    def __iter__(self) -> Iterator[Backend[C]]:
        return iter(self._backends.values())

    def __len__(self) -> int:
        return len(self._backends)

    def __contains__(self, name: object) -> bool:
        return name in self._backends

    def names(self) -> list[str]:
        """Every registered name, in preference order."""
        return list(self._backends)

    def available(self, where: Callable[[C], bool] | None = None) -> list[str]:
        """Names of the installed backends, in preference order.

        ``where`` keeps only those whose capabilities satisfy it
        (``BACKENDS.available(lambda c: c.inequalities)``).
        """
        return [b.name for b in self if b.is_available() and (where is None or where(b.capabilities))]

    def get(self, name: str) -> Backend[C]:
        """The installed backend called ``name``.

        Raises
        ------
        SolverNotFound
            If ``name`` is unknown, or known but not installed; the message names the
            installed backends and how to install the missing one.
        """
        b = self._backends.get(name)
        if b is not None and b.is_available():
            return b
        installed = ", ".join(self.available()) or "none"
        if b is None:
            raise SolverNotFound(f"unknown {self.kind} {self.noun} {name!r}; installed: {installed}")
        missing = [m for m in b.requires if importlib.util.find_spec(m) is None]
        raise SolverNotFound(
            f"{self.kind} {self.noun} {name!r} is not installed (missing module "
            f"{', '.join(missing)}): {b.install_hint}; installed: {installed}"
        )
