"""The paper's figures, regenerated: one module per figure family, one list of figures.

:data:`FIGURES` is the only list of what ``mrfswarm figs`` draws: the CLI, the tests and
``paper_figs/README.md`` all follow it. Each entry names the files it writes; its
``make(out, quick)`` computes the numbers (through functions of its module that the
tests call without drawing) and writes them. ``quick`` reduces sweeps and sizes;
animations are skipped in quick mode.

Figure modules import matplotlib only inside their drawing functions' helpers
(:mod:`mrfswarm.plots`), so importing this package is cheap.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from mrfswarm.errors import ConfigError

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Figure:
    """One regenerated figure (or set of animations).

    Attributes
    ----------
    name
        What ``--only`` selects (``fig1``, ..., ``fig8``, ``authors``, ``gifs``).
    paper
        The paper figure it reproduces and what it shows.
    files
        The files it writes into the output folder.
    module
        The :mod:`mrfswarm.figures` module with its ``make(out, quick)``.
    animation
        Animations are skipped by ``--quick``.
    """

    name: str
    paper: str
    files: tuple[str, ...]
    module: str
    animation: bool = False

    def _module(self):
        import importlib

        return importlib.import_module(f"{__name__}.{self.module}")

    def make(self, out: Path, quick: bool = False) -> list[Path]:
        """Draw the figure into ``out`` (the module's ``make_<name>``)."""
        return getattr(self._module(), f"make_{self.name}")(Path(out), quick)

    def numbers(self, quick: bool = False) -> dict:
        """The measured numbers behind the figure, JSON-able (the module's ``numbers_<name>``)."""
        fn = getattr(self._module(), f"numbers_{self.name}", None)
        return {} if fn is None else fn(quick)


FIGURES: tuple[Figure, ...] = (
    Figure("fig1", "Fig. 1: five quadrotors flying through an obstacle field (3-D view)",
           ("fig1_flight.png",), "trajectories"),
    Figure("fig2", "Fig. 2a/b: interaction graph (k = 3) of 5 robots and its factor graph",
           ("fig2_interaction_graph.png",), "graphs"),
    Figure("fig3", "Fig. 3a-d: 5 robots, their interaction potential map, obstacle map m_hat, smoothed "
           "obstacle potential",
           ("fig3_potentials.png",), "potentials"),
    Figure("fig4", "Fig. 4: combined potential field (static field + interaction field)",
           ("fig4_combined_field.png",), "potentials"),
    Figure("fig5", "Fig. 5a-e: MRF optimization after 0, 4, 7, 14 steps and the pruned discrete paths",
           ("fig5_mrf_steps.png",), "snapshots"),
    Figure("fig6", "Fig. 6a-h: final discrete, smoothed and receding-horizon trajectories of the four scenarios",
           ("fig6_trajectories.png",), "trajectories"),
    Figure("fig6_seams", "Extra to Fig. 6g: the corridor smoothed with the paper's rest-to-rest seams, ours, and "
           "ours with refined step durations (paths, speeds, makespan, stops, snap)",
           ("fig6_seams.png",), "trajectories"),
    Figure("fig7", "Fig. 7a-c: robot positions over time, swarm size against k_a and k_r, corridor distances",
           ("fig7_robots_size_distances.png",), "studies"),
    Figure("fig8", "Fig. 8a/b: swarm-energy convergence, time per MRF step against N and n",
           ("fig8_convergence_timing.png",), "studies"),
    Figure("authors", "Extra: the authors' own swarm sizes (corridor10, blocks12), discrete and receding horizon",
           ("extra_authors_swarms.png",), "trajectories"),
    Figure("gifs", "Animations of the four scenarios (not in the paper)",
           tuple(f"anim_{s}.gif" for s in ("free5", "free10", "corridor", "blocks")), "trajectories",
           animation=True),
)


def select(only: list[str] | None = None, quick: bool = False) -> list[Figure]:
    """The figures to make: all (without animations when ``quick``) or those named in ``only``.

    Raises
    ------
    ConfigError
        An unknown name (the message lists the known ones).
    """
    names = [f.name for f in FIGURES]
    if only:
        bad = [n for n in only if n not in names]
        if bad:
            raise ConfigError(f"--only {bad[0]!r}: unknown figure; known: {', '.join(names)}")
        chosen = [f for f in FIGURES if f.name in only]
    else:
        chosen = list(FIGURES)
    return [f for f in chosen if not (quick and f.animation)]


def expected_files(quick: bool = False, only: list[str] | None = None) -> list[str]:
    """The file names a run of :func:`make_figures` writes."""
    return [name for f in select(only, quick) for name in f.files]


#: The numbers behind the figures, written next to them by :func:`make_figures`.
MEASURED = "measured.json"


def _compact_json(obj, indent: int = 0) -> str:
    """JSON with one key per line but flat lists (and small tables of scalars) on one line."""
    import json

    pad = "  " * (indent + 1)
    if isinstance(obj, dict) and obj and not all(not isinstance(v, (dict, list)) for v in obj.values()):
        items = [f"{pad}{json.dumps(str(k))}: {_compact_json(v, indent + 1)}" for k, v in obj.items()]
        return "{\n" + ",\n".join(items) + "\n" + "  " * indent + "}"
    if isinstance(obj, list) and any(isinstance(v, dict) and any(isinstance(x, (dict, list)) for x in v.values())
                                     for v in obj):
        items = [f"{pad}{_compact_json(v, indent + 1)}" for v in obj]
        return "[\n" + ",\n".join(items) + "\n" + "  " * indent + "]"
    return json.dumps(obj)


def write_measured(path: Path, measured: dict) -> Path:
    """Write ``measured.json`` atomically, readable by everyone."""
    import os

    from mrfswarm.atomic import atomic_write

    atomic_write(path, lambda p: p.write_text(_compact_json(measured) + "\n"))
    os.chmod(path, 0o644)
    return Path(path)


def make_figures(out: Path, quick: bool = False, only: list[str] | None = None,
                 on_figure: Callable[[Figure, list[Path], float], None] | None = None) -> dict[str, list[Path]]:
    """Make the selected figures into ``out``; returns name -> written files.

    Also writes :data:`MEASURED` (``out/measured.json``): per figure, the numbers behind
    it (entries of figures not made in this run are kept from an earlier run).
    ``on_figure(figure, files, seconds)`` is called after each figure.
    """
    import json

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    written: dict[str, list[Path]] = {}
    measured_path = out / MEASURED
    try:
        measured = json.loads(measured_path.read_text())
    except (OSError, ValueError):
        measured = {}
    for fig in select(only, quick):
        t0 = time.perf_counter()
        files = fig.make(out, quick)
        numbers = fig.numbers(quick)
        dt = time.perf_counter() - t0
        log.info("%s: %s in %.1f s", fig.name, ", ".join(p.name for p in files), dt)
        written[fig.name] = files
        if numbers:
            measured[fig.name] = {"quick": quick, **numbers}
            write_measured(measured_path, measured)
        if on_figure is not None:
            on_figure(fig, files, dt)
    return written
