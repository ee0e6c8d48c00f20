"""Parameter sweeps: one config, a grid of overrides, every point planned, one table.

A sweep runs :func:`mrfswarm.pipeline.plan` once per point of a grid (the Cartesian
product of the values given per config key, row-major in the order the keys are given),
optionally once per seed, in local processes (:class:`concurrent.futures.ProcessPoolExecutor`)
or on a Dask distributed cluster. Every point's config is built and validated before
anything runs, so a typo fails at once. Each point's ``result.json`` is written as the
point finishes, under ``OUT/points/<index>_<key=value slug>/``; ``OUT/sweep.csv`` and
``OUT/sweep.json`` hold one row per point (per seed). A point that fails with an error
of the toolkit (:class:`~mrfswarm.errors.SolversError`, the root of the domain's and the
numerical layer's) is a row whose ``error`` column holds the message; any other
exception is a bug and stops the sweep.

Rows are computed in the workers and written by the caller, so a remote cluster needs
``mrfswarm`` installed and the config's map files readable, not a shared output folder
(except with ``figures=True``: the figures are written by the workers).
"""

from __future__ import annotations

import contextlib
import itertools
import logging
import math
import numbers
import os
import re
import shutil
import sys
import threading
import time
import uuid
import warnings
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import solvers.registry
from mrfswarm.config import Config, current_key, load_config, parse_override
from mrfswarm.errors import (
    ConfigError,
    DeprecatedKeyWarning,
    MrfswarmError,
    PlanError,
    PlanWarning,
    SolversError,
    UnusedSettingWarning,
)
from mrfswarm.pools import check_shippable, process_pool

#: The file that makes a folder a sweep's (what ``--overwrite`` may replace).
SWEEP_MARKER = "sweep.json"
#: The toolkit's warnings a point hands to the sweep's process, which says each text once.
_HANDED = (UnusedSettingWarning, DeprecatedKeyWarning)
#: The loggers whose warnings a point hands to the sweep's process, which says each text once, naming the point: the
#: numerical layer's (a QP backend's "reduced accuracy") and the maps' (a box reaching past its cells). A spawned
#: worker printed them bare, once per worker process, with no point named (a tour's osqp sweep of 3 points on 2
#: workers: two unprefixed lines; a blocks sweep of 3 points: each of its 3 boxes' lines 3 times, bare).
_HANDED_LOGS = ("solvers", "mrfswarm.maps")

log = logging.getLogger(__name__)

# summary keys that hold a list or a table when they are not None: never a column as such (flight_quality's scalars
# are columns under their own names; a discrete-only point's None made an empty column of it)
_STRUCTURED = {"goal", "simulation", "limits", "achieved", "flight_quality"}
# summary keys holding a table (or None) whose scalars are columns <key>_<name>: the limits asked and reached, the
# certificate, the sampled check, the Crazyflie memory, the windows the QP backend failed to solve; None (the check
# off, no smoothing) leaves them empty
_PREFIXED = ("limits", "achieved", "certificate", "sampled_check", "piece_limit", "crazyflie", "solve_failures")


def is_timing_column(name: str) -> bool:
    """Whether a table column holds a measured time (it differs between runs of the same sweep)."""
    return name == "wall_s" or (name.startswith(("mrf_step_time_", "time_")) and name.endswith("_s"))


class SchedulerError(MrfswarmError, RuntimeError):
    """The Dask scheduler cannot be reached, or Dask is not installed."""


@dataclass
class SweepResult:
    """What a sweep produced.

    Attributes
    ----------
    rows
        One dict per run, in the order of the points (and of the seeds within a point):
        ``point``, the grid values, ``seed`` (with seeds), the scalars of
        ``result.json``, ``swarm_energy_final``, ``mrf_step_time_<stage>_s``, ``wall_s`` and ``error``.
    csv_path
        ``out_dir / "sweep.csv"``.
    out_dir
        The output folder.
    columns
        The CSV header (the union of the rows' keys, in a stable order).
    grid
        The grid swept (key -> values).
    """

    rows: list[dict]
    csv_path: Path
    out_dir: Path
    columns: list[str] = field(default_factory=list)
    grid: dict[str, list] = field(default_factory=dict)

    @property
    def json_path(self) -> Path:
        return self.out_dir / SWEEP_MARKER

    @property
    def failed(self) -> list[dict]:
        """The rows of the points that failed."""
        return [r for r in self.rows if r.get("error") is not None]


@dataclass(frozen=True)
class _Task:
    """One run, as shipped to a worker (a validated config, not a path: no file needed there)."""

    config: Config
    seed: int | None
    point_dir: str
    figures: bool
    #: the backends the sweep's process registered (``solvers.registry.added``), which a spawned or Dask worker
    #: repeats: a script's ``register`` did not reach them ("unknown MRF method" in every row)
    backends: dict[str, tuple[solvers.registry.Backend[Any], ...]] = field(default_factory=dict)


# --- the grid ------------------------------------------------------------------------------


def parse_grid(items: Iterable[str]) -> dict[str, list]:
    """Parse ``--grid KEY=V1,V2,...`` items into ``{key: [values]}``.

    Each value is read as ``--set`` reads one: a TOML literal (integer, float, boolean,
    quoted string, array, inline table), or a bare string when it is not one. Values are
    split at the commas that are not inside brackets, braces or quotes, so
    ``scenario.goal=[35,15],[30,20]`` gives two points.

    Raises
    ------
    ConfigError
        An item without ``=``, an empty key, an empty value list or value, a key given twice.
    """
    grid: dict[str, list] = {}
    for item in items:
        if "=" not in item:
            raise ConfigError(f"--grid {item!r}: expected KEY=V1,V2,...")
        key, raw = (s.strip() for s in item.split("=", 1))
        if not key or not all(key.split(".")):
            raise ConfigError(f"--grid {item!r}: empty key")
        if key in grid:
            raise ConfigError(f"--grid {item!r}: {key} is given twice")
        if not raw:
            raise ConfigError(f"--grid {item!r}: empty value list")
        parts = _split_values(raw)
        if any(not p for p in parts):
            raise ConfigError(f"--grid {item!r}: empty value in the list")
        grid[key] = [parse_override(f"{key}={p}")[1] for p in parts]
    return grid


def _split_values(raw: str) -> list[str]:
    """Split at top-level commas (outside ``[]``, ``{}`` and quoted strings)."""
    parts, buf, depth, quote = [], [], 0, ""
    i = 0
    while i < len(raw):
        ch = raw[i]
        if quote:
            if ch == "\\" and quote == '"' and i + 1 < len(raw):
                buf.append(raw[i:i + 2])
                i += 2
                continue
            if ch == quote:
                quote = ""
        elif ch in "\"'":
            quote = ch
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
        elif ch == "," and depth == 0:
            parts.append("".join(buf).strip())
            buf = []
            i += 1
            continue
        buf.append(ch)
        i += 1
    parts.append("".join(buf).strip())
    return parts


def toml_literal(value: Any) -> str:
    """``value`` written as a TOML literal, so ``--set`` reads back exactly ``value``.

    Raises
    ------
    ConfigError
        A value TOML cannot express (``None``, an object).
    """
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, numbers.Integral):
        return str(int(value))
    if isinstance(value, numbers.Real):
        v = float(value)
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(value, str):
        return _toml_string(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_literal(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{_toml_string(str(k))} = {toml_literal(v)}" for k, v in value.items()) + " }"
    raise ConfigError(f"grid value {value!r} cannot be written in TOML")


def _toml_string(s: str) -> str:
    """A TOML basic string: quotes, backslashes and control characters (with DEL) escaped."""
    out = []
    for ch in s:
        if ch in '"\\':
            out.append("\\" + ch)
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04x}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def grid_points(grid: Mapping[str, Sequence]) -> list[dict[str, Any]]:
    """The Cartesian product of ``grid``, row-major in the order of its keys (last key fastest).

    Raises
    ------
    ConfigError
        No key, or a key with no values.
    """
    if not grid:
        raise ConfigError("a sweep needs at least one --grid KEY=V1,V2,...")
    for key, values in grid.items():
        if isinstance(values, (str, bytes)) or not isinstance(values, Sequence):
            raise ConfigError(f"grid {key}: expected a list of values, got {values!r}")
        if len(values) == 0:
            raise ConfigError(f"grid {key}: empty value list")
    keys = list(grid)
    return [dict(zip(keys, combo)) for combo in itertools.product(*(grid[k] for k in keys))]


def current_grid(grid: Mapping[str, Sequence]) -> dict[str, Sequence]:
    """``grid`` with renamed config keys under their current names (:func:`~mrfswarm.config.current_key`).

    Raises
    ------
    ConfigError
        A key given under both its old and its current name.
    """
    out: dict[str, Sequence] = {}
    for key, values in grid.items():
        new = current_key(key)
        if new in out:
            raise ConfigError(f"grid {key}: {new} is given twice (under its old name too)")
        out[new] = values
    return out


def _slug(values: dict[str, Any], seed: int | None, limit: int = 60) -> str:
    """``k_a=8_k_r=2`` from the last part of each key (a list's items joined by ``x``: ``goal=4x3``, not
    ``goal=-4-3``, which read as negative numbers); only filename-safe characters."""

    def text(v: Any) -> str:
        return "x".join(text(e) for e in v) if isinstance(v, (list, tuple)) else _cell(v)

    parts = [f"{k.rsplit('.', 1)[-1]}={text(v)}" for k, v in values.items()]
    s = re.sub(r"[^A-Za-z0-9_.=+-]+", "-", "_".join(parts)).strip("-")[:limit]
    return s if seed is None else f"{s}_seed={seed}"


# --- one point -----------------------------------------------------------------------------


def _run_point(task: _Task) -> dict:
    """Plan one point in a worker; return ``{"summary", "error", "wall_s", "config", "warnings"}``.

    An error of the toolkit (:class:`~mrfswarm.errors.SolversError`, the root of every
    one) is the point's result (its message, and what a :class:`PlanError` carries);
    anything else propagates: it is a bug. The toolkit's own warnings (a setting the point leaves unused) are
    ``warnings``, ``(category, text)`` pairs the sweep's process says (:func:`_say`), and the numerical layer's
    logged warnings (:data:`_HANDED_LOGS`) and the plan's own (:class:`~mrfswarm.errors.PlanWarning`: windows flown
    as their witness, robots short of the goal) are ``logged``, texts it says naming the point (:func:`_tell`), in a
    process's main thread; a Dask worker's threads say them where they are (:func:`warnings.catch_warnings` is not
    for threads, nor a logger's handlers).
    """
    handed: list[tuple[type[Warning], str]] = []
    logged: list[str] = []
    if threading.current_thread() is not threading.main_thread():
        return _plan_point(task) | {"warnings": handed, "logged": logged}
    with _handing(handed, logged), _logging_into(logged):
        out = _plan_point(task)
    return out | {"warnings": handed, "logged": logged}


def _plan_point(task: _Task) -> dict:
    from mrfswarm.pipeline import plan

    solvers.registry.restore(task.backends)
    t0 = time.perf_counter()
    summary, error, result = None, None, None
    try:
        result = plan(task.config, seed=task.seed, progress=False)
    except SolversError as e:
        error = str(e).splitlines()[0] if str(e) else type(e).__name__
        result = e.result if isinstance(e, PlanError) else None
    wall = time.perf_counter() - t0
    if result is not None:
        summary = result.summary()
        if task.figures:
            from mrfswarm.outputs import write_outputs

            write_outputs(result, Path(task.point_dir), overwrite=True)  # the sweep's own point folder
    return {"summary": summary, "error": error, "wall_s": wall, "config": task.config.to_dict()}


@contextlib.contextmanager
def _handing(handed: list[tuple[type[Warning], str]], logged: list[str] | None = None) -> Iterator[None]:
    """Collect the block's warnings of the toolkit (:data:`_HANDED`) into ``handed`` as ``(category, text)``, and
    (given ``logged``) its :class:`PlanWarning` texts into ``logged`` (said naming the point, as a logged warning: what a point's plan
    warns of is that point's); show any other as it would have been shown. A worker process printed them in Python's
    format (file, line, source line), once per worker, and the sweep's own process said again what building the
    points had said."""
    records: list[warnings.WarningMessage] = []
    try:
        with warnings.catch_warnings(record=True) as caught:
            for category in (*_HANDED, PlanWarning):
                warnings.filterwarnings("always", category=category)
            records = caught
            yield
    finally:
        for w in records:
            if issubclass(w.category, _HANDED):
                handed.append((w.category, str(w.message)))
            elif logged is not None and issubclass(w.category, PlanWarning):
                logged.append(str(w.message))
            else:
                warnings.showwarning(w.message, w.category, w.filename, w.lineno, w.file, w.line)


class _Into(logging.Handler):
    """A handler that keeps the text of each warning (and worse) logged in this process in a list; passes anything
    else on to the root logger's handlers, as the logger's propagation would have (``--verbose``'s progress), and so
    a process forked while it is on (the window chunks' workers), whose list no one reads."""

    def __init__(self, into: list[str]) -> None:
        super().__init__()
        self.into, self.pid = into, os.getpid()

    def emit(self, record: logging.LogRecord) -> None:
        if record.levelno >= logging.WARNING and os.getpid() == self.pid:
            self.into.append(record.getMessage())
        else:
            logging.getLogger().handle(record)


@contextlib.contextmanager
def _logging_into(logged: list[str]) -> Iterator[None]:
    """Collect the block's warnings of the loggers :data:`_HANDED_LOGS` into ``logged`` (texts), instead of letting
    them reach the root logger's handlers (in a spawned worker, Python's last resort: a bare line)."""
    loggers = [logging.getLogger(name) for name in _HANDED_LOGS]
    handler = _Into(logged)
    before = [lg.propagate for lg in loggers]
    for lg in loggers:
        lg.addHandler(handler)
        lg.propagate = False
    try:
        yield
    finally:
        for lg, propagate in zip(loggers, before):
            lg.removeHandler(handler)
            lg.propagate = propagate


def _point_name(p: int, values: Mapping[str, Any], seed: int | None = None) -> str:
    """``sweep point 1 (interaction.k_a=14, seed 3)``: how the sweep's lines name a point."""
    where = ", ".join([f"{k}={_cell(v)}" for k, v in values.items()] + ([] if seed is None else [f"seed {seed}"]))
    return f"sweep point {p} ({where})"


def _tell(name: str, logged: Iterable[str], told: dict[str, list[str]]) -> None:
    """Warn each text of ``logged`` that no point has said yet, as ``name: text``, and keep the names of the points
    that said it again in ``told`` (text -> names), for :func:`_tell_others`: once per sweep, each naming its point."""
    for text in logged:
        if text in told:
            if name not in told[text]:
                told[text].append(name)
        else:
            told[text] = []
            log.warning("%s: %s", name, text)


def _tell_others(told: Mapping[str, list[str]]) -> None:
    """One line per text of :func:`_tell` that later points said too, naming them (the first said it alone)."""
    for text, names in told.items():
        if names:
            points = ", ".join(n.removeprefix("sweep point ") for n in names[:8]) + (" ..." if len(names) > 8 else "")
            log.warning("%s: also in sweep point%s %s", text, "s" * (len(names) > 1), points)


def _say(handed: Iterable[tuple[type[Warning], str]], said: set[str]) -> None:
    """Warn each text of ``handed`` not in ``said`` (then in it): once per sweep, in the sweep's process (the CLI
    writes it as one line)."""
    for category, text in handed:
        if text not in said:
            said.add(text)
            warnings.warn(text, category, stacklevel=2)


def _row(base: dict, out: dict) -> dict:
    """A table row: ``base`` (point, grid values, seed), the summary's scalars, timings, error."""
    row = dict(base)
    s = out["summary"] or {}
    for k, v in s.items():
        if k not in _STRUCTURED and k not in _PREFIXED and (v is None or isinstance(v, (bool, numbers.Number, str))):
            row[k] = v
    for k in _PREFIXED:
        for name, v in (s.get(k) or {}).items():
            if v is None or isinstance(v, (bool, numbers.Number, str)):
                row[f"{k}_{name}"] = v
    if s.get("swarm_energy"):  # what the MRF methods minimize, at the final configuration
        row["swarm_energy_final"] = s["swarm_energy"][-1]
    for k, v in (s.get("flight_quality") or {}).items():  # makespan over its lower bound, stops, speed
        if v is None or isinstance(v, (bool, numbers.Number, str)):
            row[k] = v
    for k, v in (s.get("simulation") or {}).items():  # the flown metrics
        if v is None or isinstance(v, (bool, numbers.Number, str)):
            row[f"simulation_{k}"] = v
    for stage, t in (s.get("mrf_step_time_s") or {}).items():  # mean seconds per MRF step, by stage
        row[f"mrf_step_time_{stage}_s"] = t
    for stage, t in (s.get("timings_s") or {}).items():  # seconds per pipeline stage
        row[f"time_{stage}_s"] = t
    row["wall_s"] = out["wall_s"]
    row["error"] = out["error"]
    return row


def _point_json(out: dict) -> dict:
    """The point's ``result.json``: the run's as ``mrfswarm run`` writes it (the summary, ``"complete": true``;
    with figures it replaces that very file), plus ``error`` when it failed."""
    if out["summary"] is None:
        return {"error": out["error"], "config": out["config"]}
    data = {**out["summary"], "complete": True}
    if out["error"] is not None:
        data["error"] = out["error"]
    return data


# --- executors -----------------------------------------------------------------------------


def _run_in_process(tasks: list[_Task], done: Callable[[int, dict], None]) -> None:
    for i, t in enumerate(tasks):
        done(i, _run_point(t))


def _run_local(tasks: list[_Task], workers: int, done: Callable[[int, dict], None]) -> None:
    import concurrent.futures as cf
    import multiprocessing

    # spawn, not fork: the caller may hold threads (a progress bar, a Dask client, a GUI)
    ctx = multiprocessing.get_context("spawn")
    with process_pool(workers, ctx) as pool:  # an error or Ctrl-C stops the points still running too
        futures = {pool.submit(_run_point, t): i for i, t in enumerate(tasks)}
        for f in cf.as_completed(futures):
            try:
                out = f.result()
            except cf.process.BrokenProcessPool as e:
                raise cf.process.BrokenProcessPool(
                    f"a sweep worker process died ({e}); it was killed (out of memory?) or crashed, or the script "
                    "that started the sweep lacks `if __name__ == \"__main__\":` (worker processes are spawned "
                    "and import the main script)") from e
            done(futures[f], out)


def _run_dask(tasks: list[_Task], client: Any, done: Callable[[int, dict], None]) -> None:
    from distributed import as_completed

    tag = uuid.uuid4().hex[:8]
    futures = [client.submit(_run_point, t, key=f"mrfswarm-sweep-{tag}-{i}", pure=False) for i, t in enumerate(tasks)]
    index = {f.key: i for i, f in enumerate(futures)}
    try:
        for f in as_completed(futures):
            done(index[f.key], f.result())
    except BaseException:
        client.cancel(futures)
        raise


def connect(scheduler: Any, timeout: float = 10.0) -> tuple[Any, bool]:
    """A Dask client for ``scheduler`` (an address, a ``Client``, or a cluster); and whether we own it.

    Raises
    ------
    SchedulerError
        Dask is not installed, or nothing answers at the address within ``timeout`` seconds.
    """
    try:
        import distributed
    except ModuleNotFoundError as e:
        if e.name not in ("distributed", "dask") and not (e.name or "").startswith(("distributed.", "dask.")):
            raise
        raise SchedulerError('--scheduler needs Dask distributed, which is not installed: pip install "mrfswarm[dask]"'
                             ) from e
    if isinstance(scheduler, distributed.Client):
        return scheduler, False
    if not isinstance(scheduler, str):
        if hasattr(scheduler, "scheduler_address"):  # a cluster object (LocalCluster, ...)
            return distributed.Client(scheduler, timeout=timeout), True
        raise TypeError(f"scheduler must be an address, a dask Client or a cluster, got {type(scheduler).__name__}")
    if not scheduler.strip():  # Client("") would start a new local cluster instead
        raise ConfigError("--scheduler: empty address")
    try:
        return distributed.Client(scheduler, timeout=timeout), True
    except (OSError, TimeoutError, ValueError) as e:
        msg = str(e).splitlines()[0] if str(e) else type(e).__name__
        raise SchedulerError(f"cannot reach the Dask scheduler at {scheduler!r}: {msg}") from e


# --- the table -----------------------------------------------------------------------------


def _columns(rows: list[dict], lead: list[str]) -> list[str]:
    cols = list(lead)
    seen = set(cols)
    for r in rows:
        for k in r:
            if k not in seen:
                seen.add(k)
                cols.append(k)
    tail = [c for c in cols if is_timing_column(c) and c != "wall_s"] + ["wall_s", "error"]
    return [c for c in cols if c not in tail] + [c for c in tail if c in seen]


def _cell(v: Any) -> str:
    if v is None:
        return ""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (list, tuple, dict)):
        return toml_literal(v)
    if isinstance(v, numbers.Real) and not isinstance(v, numbers.Integral):
        return repr(float(v))
    return str(v)


def _write_table(out_dir: Path, rows: list[dict], columns: list[str], meta: dict) -> None:
    import csv

    from mrfswarm.atomic import atomic_write
    from mrfswarm.outputs import write_json

    def write(p: Path) -> None:
        with open(p, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(columns)
            for r in rows:
                w.writerow([_cell(r.get(c)) for c in columns])

    atomic_write(out_dir / "sweep.csv", write)
    write_json(out_dir / SWEEP_MARKER, {**meta, "finished": len(rows), "columns": columns, "rows": rows})


# --- the sweep -----------------------------------------------------------------------------


def run_sweep(config: str | Path, grid: Mapping[str, Sequence], out_dir: str | Path, *, scheduler: Any = None,
              workers: int | None = None, progress: bool | None = None, seeds: Sequence[int] | None = None,
              overrides: Sequence[str] = (), figures: bool = False, connect_timeout: float = 10.0,
              overwrite: bool = False) -> SweepResult:
    """Plan every point of ``grid`` (and every seed) and tabulate the results.

    Parameters
    ----------
    config
        Path to a TOML experiment config. A point's config is
        ``load_config(config, overrides + ["key=value" for each grid key])``.
    grid
        Config key (dotted, as ``--set``) -> values; the points are the Cartesian product,
        row-major in the order of the keys (see :func:`grid_points`). A renamed key
        (``mrf.optimizer``) is swept, and tabulated, under its current name.
    out_dir
        Output folder: ``points/<index>_<slug>/result.json``, ``sweep.csv``, ``sweep.json``.
    scheduler
        ``None``: local processes. An address (``"tcp://host:8786"``), a
        ``distributed.Client`` or a cluster object: that Dask cluster.
    workers
        Local processes (default ``os.cpu_count()``); 1 runs the points in this process.
        The processes are spawned, so a script that starts a sweep must do it under
        ``if __name__ == "__main__":``. Ignored with a scheduler (the cluster decides).
    progress
        Show a progress bar on stderr (default: when stderr is a terminal).
    seeds
        If given (distinct integers >= 0), each point is planned once per seed, ``plan(cfg, seed=s)``: one row per
        (point, seed), seeds varying fastest, with the grid point's index in ``point`` and the
        seed in ``seed``.
    overrides
        ``--set`` items applied to every point, before the grid's.
    figures
        Also write each point's figures and paths (as ``mrfswarm run``) into its folder.
    connect_timeout
        Seconds to wait for the scheduler.
    overwrite
        Replace the sweep ``out_dir`` holds (a folder with ``sweep.json``): it is set aside when this one starts
        and deleted when this one completes (an interrupted sweep leaves it beside, in ``.<name>.old-*``).
        Without it a folder that holds anything is refused, as is one that is not a sweep's in any case.

    Returns
    -------
    SweepResult
        The rows, in the order of the points. The times of the first point a process plans include that process's
        warm-up (imports, first-call work): 0.2-0.5 s on the paper corridor (docs/contracts.md, ``mrfswarm sweep``'s
        output), so compare small points' times from the second row a process planned on. A point that failed with a
        :class:`MrfswarmError` (a scenario the planner rejects, e.g. ``k >= N``, a goal in an
        obstacle) is a row with ``error`` set and whatever the run computed before failing.
        A point whose config is invalid (Morse parameters with ``k_a <= k_r`` included)
        stops the sweep before anything runs.

    Raises
    ------
    ConfigError
        A bad grid, or a point whose config is invalid (unknown key, wrong type, out of
        range): raised before any point runs and before anything is written.
    ExportError
        ``out_dir`` holds files and is not a sweep's, or is one and ``overwrite`` is false, or is the current
        folder (:func:`~mrfswarm.outputs.check_output_dir`); before any point runs.
    SchedulerError
        An unreachable scheduler, or Dask not installed.
    """
    config = Path(config)
    overrides = list(overrides)
    grid = current_grid(grid)  # the table's columns carry the current names
    points = grid_points(grid)
    keys = list(grid)
    if seeds is not None:
        seeds = list(seeds)
        if not seeds:
            raise ConfigError("--seeds: empty list")
        for s in seeds:
            if isinstance(s, bool) or not isinstance(s, numbers.Integral) or s < 0:
                raise ConfigError(f"--seeds: {s!r} is not an integer >= 0")
        seeds = [int(s) for s in seeds]
        twice = next((s for i, s in enumerate(seeds) if s in seeds[:i]), None)
        if twice is not None:  # the point's two runs of it would share a folder, the second's result.json kept
            raise ConfigError(f"--seeds: {twice} is given twice")
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise ConfigError(f"--workers {workers!r}: must be an integer >= 1")
    if isinstance(connect_timeout, bool) or not isinstance(connect_timeout, numbers.Real) \
            or not (math.isfinite(connect_timeout) and connect_timeout > 0):
        raise ConfigError(f"--connect-timeout {connect_timeout!r}: must be a positive finite number of seconds")

    from mrfswarm.pipeline import resolve_config

    out_dir = Path(out_dir)
    width = max(3, len(str(len(points) - 1)))
    tasks: list[_Task] = []
    bases: list[dict] = []
    added = solvers.registry.added()
    said: set[str] = set()
    for p, values in enumerate(points):
        items = overrides + [f"{k}={toml_literal(v)}" for k, v in values.items()]
        handed: list[tuple[type[Warning], str]] = []
        try:
            with _handing(handed):
                cfg = resolve_config(load_config(config, items))  # checks the optimizer and backends too
        except SolversError as e:
            raise type(e)(f"{_point_name(p, values)}: {e}") from e
        finally:
            _say(handed, said)
        for s in [None] if seeds is None else seeds:
            base = {"point": p, **values} | ({} if s is None else {"seed": s})
            d = out_dir / "points" / f"{p:0{width}d}_{_slug(values, s)}"
            tasks.append(_Task(cfg, s, str(d.resolve()), figures, added))
            bases.append(base)

    if scheduler is not None or ((workers or os.cpu_count() or 1) > 1 and len(tasks) > 1):
        check_shippable(added, "the sweep's worker processes", "sweep with workers=1")
    from mrfswarm.outputs import check_output_dir

    check_output_dir(out_dir, overwrite, marker=SWEEP_MARKER, what="sweep")
    client, owned = (None, False) if scheduler is None else connect(scheduler, connect_timeout)
    try:
        return _sweep(config, grid, seeds, overrides, out_dir, tasks, bases, keys, client, workers, progress, said)
    finally:
        if owned:
            client.close()


def _drop_partial_points(out_dir: Path) -> None:
    """Delete the hidden ``.NAME.partial-*`` folders of the points a stopped local sweep's workers were writing
    (``figures``): the pool stops them outright (:func:`mrfswarm.pools.stop`), before their own clean-up, and the
    folders stayed in ``points/`` (a tour's ``.001_method=gibbs.partial-weywbyc8``). The sweep's folder is its own,
    so nothing else there is named so. A ``points/`` left empty goes too: stopped before any point finished, the
    sweep leaves an empty folder, which a new sweep takes (an empty ``points/`` in it was refused as "not an
    mrfswarm sweep's", even with ``--overwrite``)."""
    points = out_dir / "points"
    if points.is_dir():
        for d in points.glob(".*.partial-*"):
            shutil.rmtree(d, ignore_errors=True)
        if not any(points.iterdir()):
            points.rmdir()


def _sweep(config: Path, grid: dict, seeds: list[int] | None, overrides: list[str], out_dir: Path, tasks: list[_Task],
           bases: list[dict], keys: list[str], client: Any, workers: int | None, progress: bool | None,
           said: set[str]) -> SweepResult:
    from tqdm import tqdm

    from mrfswarm.outputs import set_aside, write_json

    earlier = set_aside(out_dir)  # the sweep --overwrite replaces (check_output_dir let nothing else through)
    out_dir.mkdir(parents=True, exist_ok=True)
    lead = ["point", *keys] + ([] if seeds is None else ["seed"])
    meta = {"config": str(config.resolve()), "overrides": overrides, "grid": {k: list(v) for k, v in grid.items()},
            "seeds": seeds, "runs": len(tasks)}
    rows: dict[int, dict] = {}
    last_write = [0.0]

    def table() -> tuple[list[dict], list[str]]:
        ordered = [rows[i] for i in sorted(rows)]
        return ordered, _columns(ordered, lead)

    show = sys.stderr.isatty() if progress is None else progress
    bar = tqdm(total=len(tasks), desc="sweep", unit="point", disable=not show, file=sys.stderr)

    told: dict[str, list[str]] = {}

    def done(i: int, out: dict) -> None:
        _say(out.get("warnings", ()), said)
        values = {k: bases[i][k] for k in keys}
        _tell(_point_name(bases[i]["point"], values, bases[i].get("seed")), out.get("logged", ()), told)
        write_json(Path(tasks[i].point_dir) / "result.json", _point_json(out))
        rows[i] = _row(bases[i], out)
        if out["error"] is not None:
            log.info("sweep point %s failed: %s", bases[i], out["error"])
        bar.set_postfix(failed=sum(r["error"] is not None for r in rows.values()), refresh=False)
        bar.update(1)
        now = time.monotonic()
        if now - last_write[0] >= 1.0:  # the table, as points finish (at most once a second)
            _write_table(out_dir, *table(), meta | {"complete": False})
            last_write[0] = now

    complete = False
    try:
        if client is not None:
            if workers is not None:
                log.info("--workers is ignored with a Dask scheduler")
            _run_dask(tasks, client, done)
        elif (workers or os.cpu_count() or 1) == 1 or len(tasks) == 1:
            _run_in_process(tasks, done)
        else:
            _run_local(tasks, min(workers or os.cpu_count() or 1, len(tasks)), done)
        complete = True
    finally:
        bar.close()
        _tell_others(told)
        ordered, columns = table()
        if ordered or complete:
            _write_table(out_dir, ordered, columns, meta | {"complete": complete})
        if not complete and client is None:
            _drop_partial_points(out_dir)
        if ordered and not complete:  # Ctrl-C, a bug: the finished points are tabulated, which the error line omits
            log.warning("the sweep stopped after %d of %d runs; their rows are in %s (sweep.json: \"complete\": "
                        "false)", len(ordered), len(tasks), out_dir / "sweep.csv")
        if earlier is not None:
            if complete:
                shutil.rmtree(earlier, ignore_errors=True)
            else:
                log.warning("the sweep this one replaces is kept in %s", earlier / out_dir.name)
    return SweepResult(rows=ordered, csv_path=out_dir / "sweep.csv", out_dir=out_dir, columns=columns,
                       grid={k: list(v) for k, v in grid.items()})
