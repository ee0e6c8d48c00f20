"""One preference-ordered registry per kind of solver.

Each backend module declares a :class:`Backend` record; the package's ``__init__``
builds the one :class:`Registry` of its kind from those records. Dispatch,
``mrfswarm solvers``, tests and benchmarks all iterate that registry, so the list of
names exists exactly once. A record's ``capabilities`` is a typed, frozen dataclass of
its kind (:class:`solvers.qp.QPCapabilities`, :class:`solvers.mrf.MRFCapabilities`);
callers read its fields, never a backend's name.

Backends from outside this package join a registry in two ways, after the built-in ones
in the preference order:

- an installed distribution declares its record under the registry's entry-point group
  (``solvers.qp``, ``solvers.nlp``, ``solvers.mrf``), loaded the first time the
  registry is read, in every process;
- a script calls :meth:`Registry.register`. Processes that a caller starts later do not
  run that script: :func:`added` is what they need to repeat (:func:`restore`), which
  ``mrfswarm``'s process pools and sweeps do.

A record is checked when it joins (its name, its entry, its capabilities' type), so that a
wrong one fails there, naming itself, and not in a solve.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import logging
import multiprocessing
import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from functools import cache
from typing import Any, Generic, TypeVar

from solvers.errors import SolverNotFound

C = TypeVar("C")

log = logging.getLogger(__name__)


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
    distribution
        The distribution whose ``extra`` installs ``requires``; empty: the one that ships
        this package. An entry point's record gets its own distribution's name.
    """

    name: str
    entry: Callable[..., Any]
    capabilities: C
    requires: tuple[str, ...] = ()
    extra: str = ""
    summary: str = ""
    distribution: str = ""

    def is_available(self) -> bool:
        """True when every required module can be found (nothing is imported)."""
        return all(importlib.util.find_spec(m) is not None for m in self.requires)

    @property
    def install_hint(self) -> str:
        """How to install this backend: the pip command of its extra, or ``"included"``."""
        if not self.extra:
            return "included"
        dist = self.distribution or _distribution()
        if dist is None:
            return f"install the {self.extra!r} extra"
        return f'pip install "{dist}[{self.extra}]"'


#: A backend's name: what ``--qp``, ``--nlp`` and ``--mrf`` take and CSV columns carry.
NAME = re.compile(r"[a-z][a-z0-9_]*")

#: The public registries by entry-point group, for :func:`added` and :func:`restore`.
_PUBLIC: dict[str, Registry[Any]] = {}


class Registry(Generic[C]):
    """A preference-ordered mapping of name -> :class:`Backend`: the built-in records, then
    those of the entry-point ``group`` and those given to :meth:`register`.

    Parameters
    ----------
    kind, noun
        What the registry holds, for messages ("QP backend", "MRF method").
    backends
        The built-in records, in preference order.
    capabilities
        The type every record's ``capabilities`` must be (checked as a record joins).
    group
        The entry-point group whose records join when the registry is first read; ``None``
        for none (a test's registry). One registry per group.
    entry_class
        The class every record's ``entry`` must subclass, its ``name`` the record's (QP backends:
        :class:`solvers.qp.PreparedQP`); ``None``: any callable (a function).
    """

    def __init__(self, kind: str, backends: list[Backend[C]], noun: str = "backend", *,
                 capabilities: type[C] | None = None, group: str | None = None,
                 entry_class: type | None = None) -> None:
        self.kind, self.noun = kind, noun  # noun: what the kind calls its entries ("MRF method")
        self.capabilities, self.group, self.entry_class = capabilities, group, entry_class
        self._backends: dict[str, Backend[C]] = {}
        self._builtin: frozenset[str] = frozenset()
        self._broken: dict[str, str] = {}  # entry points that failed to load: name -> why
        self._loaded = group is None
        for b in backends:
            self._add(b)
        self._builtin = frozenset(self._backends)
        if group is not None:
            if group in _PUBLIC:
                raise ValueError(f"a second registry for the entry-point group {group!r}")
            _PUBLIC[group] = self

    def _check(self, b: object) -> Backend[C]:
        """``b`` if it is a record this registry can take, else ValueError naming what is wrong."""
        if not isinstance(b, Backend):
            raise ValueError(f"a {self.kind} {self.noun} must be a solvers.registry.Backend, got {type(b).__name__}")
        if not isinstance(b.name, str) or not NAME.fullmatch(b.name):
            raise ValueError(f"{self.kind} {self.noun} name {b.name!r}: lower-case letters, digits and "
                             "underscores, starting with a letter")
        if not callable(b.entry):
            raise ValueError(f"{self.kind} {self.noun} {b.name!r}: entry {b.entry!r} is not callable")
        if self.entry_class is not None:
            # a function as a QP backend's entry (an NLP backend's is one) failed in every solve, "AttributeError:
            # 'Solution' object has no attribute 'solve'"; a copy of a built-in class under another record name
            # named the original in its solutions and errors
            need = f"{self.entry_class.__module__}.{self.entry_class.__qualname__}"
            if not (isinstance(b.entry, type) and issubclass(b.entry, self.entry_class)):
                raise ValueError(f"{self.kind} {self.noun} {b.name!r}: entry {b.entry!r} is not a subclass of {need}")
            if getattr(b.entry, "name", None) != b.name:
                raise ValueError(f"{self.kind} {self.noun} {b.name!r}: its entry {b.entry.__qualname__} is named "
                                 f"{getattr(b.entry, 'name', None)!r}; subclass it with name = {b.name!r}")
        if self.capabilities is not None and not isinstance(b.capabilities, self.capabilities):
            raise ValueError(f"{self.kind} {self.noun} {b.name!r}: capabilities must be a "
                             f"{self.capabilities.__name__}, got {type(b.capabilities).__name__}")
        if isinstance(b.requires, str) or not all(isinstance(m, str) and m for m in b.requires):
            raise ValueError(f"{self.kind} {self.noun} {b.name!r}: requires must be a tuple of module names, "
                             f"got {b.requires!r}")
        return b

    def _add(self, b: Backend[C]) -> bool:
        """Add ``b``; False if this very record is already there (a worker repeating its parent's)."""
        self._check(b)
        old = self._backends.get(b.name)
        if old == b:
            return False
        if old is not None:
            where = "built in" if b.name in self._builtin else \
                f"registered already, by {old.distribution or 'a register() call'}"
            entry = f"{getattr(old.entry, '__module__', '?')}:{getattr(old.entry, '__qualname__', repr(old.entry))}"
            raise ValueError(f"{self.kind} {self.noun} {b.name!r} is {where} ({entry})")
        self._backends[b.name] = b
        return True

    def register(self, backend: Backend[C]) -> Backend[C]:
        """Add ``backend`` after every record there, in this process; returns it.

        Registering the same record again does nothing. Processes started later (a sweep's
        workers) repeat it from :func:`added`, so its ``entry`` must be importable by
        reference: defined at a module's top level, in a script under
        ``if __name__ == "__main__":``.

        Raises
        ------
        ValueError
            Not a :class:`Backend`, a name that is not lower-case letters, digits and
            underscores, an entry that is not callable, capabilities of another type, or a
            name taken by another record.
        """
        self._load()
        self._add(backend)
        return backend

    def unregister(self, name: str) -> None:
        """Remove the record ``name`` added by :meth:`register` or an entry point.

        Raises
        ------
        ValueError
            ``name`` is built in (dispatch and the tests rely on those) or not registered.
        """
        self._load()
        if name in self._builtin:
            raise ValueError(f"{self.kind} {self.noun} {name!r} is built in; only added ones can be removed")
        if name not in self._backends:
            raise ValueError(f"no added {self.kind} {self.noun} {name!r}")
        del self._backends[name]

    def added(self) -> tuple[Backend[C], ...]:
        """The records that are not built in, in the order they joined."""
        self._load()
        return tuple(b for name, b in self._backends.items() if name not in self._builtin)

    def _load(self) -> None:
        """Add the entry-point group's records, once; one that fails is remembered with why
        (:meth:`get` says it), logged, and skipped."""
        if self._loaded:
            return
        self._loaded = True
        from importlib.metadata import entry_points

        assert self.group is not None
        for ep in sorted(entry_points(group=self.group), key=lambda e: e.name):
            where = f"entry point {ep.name} = {ep.value}" + (f" of {ep.dist.name}" if ep.dist else "")
            try:
                record = self._check(ep.load())
                if record.name != ep.name:
                    raise ValueError(f"the record is named {record.name!r}, not {ep.name!r}")
                if ep.dist is not None and not record.distribution:
                    record = dataclasses.replace(record, distribution=ep.dist.name)
                self._add(record)
            except Exception as e:  # a broken plugin must not take the other backends down
                self._broken[ep.name] = f"{where} failed to load: {type(e).__name__}: {e}"
                # said once: a worker process (a sweep's, a pool's, Dask's) loads the group again, its parent warned
                level = logging.WARNING if multiprocessing.parent_process() is None else logging.INFO
                log.log(level, "%s %s %s", self.kind, self.noun, self._broken[ep.name])

    def __iter__(self) -> Iterator[Backend[C]]:
        self._load()
        return iter(list(self._backends.values()))

    def __len__(self) -> int:
        self._load()
        return len(self._backends)

    def __contains__(self, name: object) -> bool:
        self._load()
        return name in self._backends

    def names(self) -> list[str]:
        """Every registered name, in preference order."""
        self._load()
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
            If ``name`` is unknown, known but not installed, or an entry point that failed
            to load; the message names the installed backends and how to install the
            missing one, or why the entry point failed.
        """
        self._load()
        b = self._backends.get(name)
        if b is not None and b.is_available():
            return b
        installed = ", ".join(self.available()) or "none"
        if name in self._broken:
            raise SolverNotFound(f"{self.kind} {self.noun} {name!r}: {self._broken[name]}; installed: {installed}")
        if b is None:
            raise SolverNotFound(f"unknown {self.kind} {self.noun} {name!r}; installed: {installed}")
        missing = [m for m in b.requires if importlib.util.find_spec(m) is None]
        raise SolverNotFound(
            f"{self.kind} {self.noun} {name!r} is not installed (missing module "
            f"{', '.join(missing)}): {b.install_hint}; installed: {installed}"
        )


def added() -> dict[str, tuple[Backend[Any], ...]]:
    """Every public registry's added records by entry-point group: what a process started
    later needs to :func:`restore` (picklable when their entries are importable)."""
    return {group: reg.added() for group, reg in _PUBLIC.items() if reg.added()}


def restore(records: dict[str, tuple[Backend[Any], ...]]) -> None:
    """Register ``records`` (from :func:`added`, in another process) where they are missing;
    those already there (entry points, a forked parent's) are left as they are."""
    for group, backends in records.items():
        reg = _PUBLIC[group]
        for b in backends:
            if b.name not in reg:
                reg.register(b)
