"""Window problems kept between solves: the same rows at other step durations reuse their assembly.

A window's QP depends on its step durations only through the numbers of its matrices
(:class:`~mrfswarm.continuous.formulation.WindowFormulation`: ``P.data = S_P k(T)``), so the
same :class:`~mrfswarm.continuous.formulation.WindowSpec` solved at other durations needs
neither a new formulation nor, in a backend that updates in place, a new setup. That is
what most solves of a window are: the time refinement evaluates the rows of its best point so far
(the accepted QP's at first) at every trial point, and a window's next attempt starts from the rows the last one ended
with. On the forest of the flight-quality bench (time refinement on) 56 of 122 window
solves had the rows of an earlier one; assembly and setup were about 30 % of the solves' time.

The prepared backend is reused only where a backend has no warm start
(``QPCapabilities.warm_start`` false, piqp's interior point): its solve then does not
depend on what it solved before, so an updated solve returns exactly what a fresh one
does (``tests/continuous/test_window_cache.py``), whichever worker process the window's
chunk lands in. Backends with a warm start (osqp) would start from the last solution and
return another point within tolerance: for them only the formulation is kept.
"""

from __future__ import annotations

import dataclasses
import hashlib
import threading
from collections import OrderedDict

import numpy as np
import scipy.sparse as sp

import solvers.qp
from mrfswarm.continuous.formulation import WindowFormulation, WindowSpec
from solvers.qp import Options as QPOptions
from solvers.qp import PreparedQP, Solution

#: Window problems kept per process at most (least recently used dropped first). A window's attempts and its
#: time refinement reuse the last few.
CACHE_SIZE = 32
#: Bytes of assembled formulations kept per process at most (:func:`formulation_bytes`; the prepared backends
#: come on top, three to four times as much). A 10-robot window of the forest is about 1 MB, a 60-robot chunk
#: of a big swarm 2.5 to 7.5 MB: 32 of those cost the 300-robot crossing 1.2 GB per worker process (0.16 GB
#: without) and saved no time; within 16 MB, 0.1 GB more per process. The 30 robots in aisles, time-refined,
#: found 78 of 190 solves here with 16 MB as with 32.
CACHE_BYTES = 16 * 2**20


def spec_key(spec: WindowSpec) -> bytes:
    """A digest of everything ``spec`` holds (two specs with the same digest give the same formulation)."""
    h = hashlib.blake2b(digest_size=20)

    def feed(value: object) -> None:
        if dataclasses.is_dataclass(value) and not isinstance(value, type):
            h.update(type(value).__name__.encode())
            for f in dataclasses.fields(value):
                h.update(f.name.encode())
                feed(getattr(value, f.name))
        elif isinstance(value, np.ndarray):
            arr = np.ascontiguousarray(value)
            h.update(f"{arr.dtype.str}{arr.shape}".encode())
            h.update(arr.tobytes())
        else:  # None, numbers, tuples of numbers
            h.update(repr(value).encode())

    feed(spec)
    return h.digest()


class WindowCache:
    """The last :data:`CACHE_SIZE` window problems: their formulations and, where the backend allows
    (see the module's docstring), their prepared backends."""

    def __init__(self, size: int = CACHE_SIZE, budget: int = CACHE_BYTES) -> None:
        self.size, self.budget = size, budget
        self._items: OrderedDict[tuple, tuple[WindowFormulation, PreparedQP | None, int]] = OrderedDict()
        self._bytes = 0
        self._lock = threading.Lock()  # threads planning at once share the process's cache
        #: Solves that found their problem here (its formulation, at least), and those that did not.
        self.hits = 0
        self.misses = 0

    def clear(self) -> None:
        with self._lock:
            self._items.clear()
            self._bytes = 0

    def solve(self, spec: WindowSpec, durations: np.ndarray, backend: str,
              options: QPOptions) -> tuple[WindowFormulation, Solution]:
        """``spec``'s QP at ``durations`` solved by ``backend``; its formulation with it.

        Raises what :func:`solvers.qp.solve` raises; the formulation is kept then, the
        prepared backend not (a failed solve leaves its iterates where they ended).
        """
        key = (spec_key(spec), backend, repr(options))
        with self._lock:  # taken out while solved: a prepared backend solves one problem at a time
            item = self._items.pop(key, None)
            if item is not None:
                self.hits += 1
                self._bytes -= item[2]
            else:
                self.misses += 1
        form, prepared = (WindowFormulation(spec), None) if item is None else item[:2]
        problem = form.qp(durations)
        try:
            if prepared is not None and prepared.same_pattern(problem):
                prepared.update(problem)
            else:
                prepared = solvers.qp.prepare(problem, backend, options)
            sol = prepared.solve()
        except Exception:
            self._keep(key, form, None)
            raise
        reusable = not solvers.qp.BACKENDS.get(backend).capabilities.warm_start
        self._keep(key, form, prepared if reusable else None)
        return form, sol

    def _keep(self, key: tuple, form: WindowFormulation, prepared: PreparedQP | None) -> None:
        size = formulation_bytes(form)
        with self._lock:
            old = self._items.pop(key, None)  # another thread's solve of the same spec
            if old is not None:
                self._bytes -= old[2]
            if size > self.budget:
                return
            self._items[key] = (form, prepared, size)
            self._bytes += size
            while len(self._items) > self.size or self._bytes > self.budget:
                self._bytes -= self._items.popitem(last=False)[1][2]


def formulation_bytes(form: WindowFormulation) -> int:
    """Bytes of the arrays ``form`` holds (its matrix maps and bounds; its spec not counted)."""

    def size(value: object) -> int:
        if isinstance(value, np.ndarray):
            return value.nbytes
        if isinstance(value, sp.csr_matrix | sp.csc_matrix):
            return value.data.nbytes + value.indices.nbytes + value.indptr.nbytes
        if isinstance(value, (list, tuple)):
            return sum(size(v) for v in value)
        return 0

    return sum(size(v) for v in vars(form).values())


#: The cache of this process (each worker process of a parallel window has its own).
WINDOWS = WindowCache()
