"""Closed-loop flight: every robot a RotorPy quadrotor tracking its trajectory.

Each robot is RotorPy's ``Multirotor`` with the Crazyflie parameters, controlled by
RotorPy's geometric ``SE3Control`` (Lee, Leok & McClamroch, "Geometric tracking control
of a quadrotor UAV on SE(3)", CDC 2010) that receives the trajectory's flat outputs
(position and its derivatives up to snap, yaw 0) at ``rate_hz``: a 3-D trajectory's own z
polynomial and its derivatives, a 2-D one's constant altitude (z derivatives 0); the vehicle integrates its full rigid-body and rotor dynamics between
control updates. Robots do not interact physically, so they are flown independently
and compared on a common time grid afterwards, by one of two backends:

- ``batched``: RotorPy's ``BatchedMultirotor`` and ``BatchedSE3Control`` (PyTorch, on the
  CPU) fly the whole swarm as one vectorized simulation, fixed-step RK4 at ``rate_hz``,
  in double precision, with the same controller gains as ``SE3Control``. Needs the
  optional extra ``pip install "mrfswarm[batched]"`` (torch, torchdiffeq, roma).
- ``processes``: one ``Multirotor`` + ``SE3Control`` per robot (scipy's adaptive RK45),
  in parallel processes; the fallback when torch is not installed.

``auto`` (the default) takes ``batched`` when it is installed.

Tracking bound. Linearized about hover, the SE(3) controller's horizontal loop is a PD
on position with acceleration feedforward (gains k_p, k_d), commanding a tilt that a PD
attitude loop (k_R, k_w, angular acceleration commanded directly) achieves through
rotors with a first-order lag tau_m. A disturbance acceleration d acts on the vehicle:
RotorPy's rotor drag, the "H force" of each spinning rotor, -omega_i k_d v per rotor, so
d = -c v with c = n_rotors omega_hover k_d / m (0.24 1/s for the Crazyflie; its
parasitic drag coefficients are zero, and a quadratic term is added if not). With
e = x_ref - x this gives, per axis,

    e(s) = H_j(s) jerk_ref(s) - H_d(s) d(s),
    H_j(s) = (D(s) - k_R) / (s P(s)),  H_d(s) = D(s) / P(s),
    D(s) = tau_m s^3 + s^2 + k_w s + k_R,  P(s) = s^2 D(s) + k_R (k_d s + k_p),

stable transfer functions whose impulse responses have finite L1 norms, so

    |e(t)| <= ||h_j||_1 max |jerk_ref| + ||h_d||_1 max |d|

for all t (a BIBO bound, from rest; d is evaluated at the reference's speed, which the
flown speed follows to within the bound's derivative). For the Crazyflie and RotorPy's
gains ||h_j||_1 = 0.033 s^3 and ||h_d||_1 = 0.19 s^2: at the planner's limits (jerk
4 m/s^3, speed 2 m/s) a flown robot stays within 23 cm of its trajectory (12 cm on the
corridor's trajectories, which reach 1 m/s^3 and 1.9 m/s), and two flown robots keep
their planned separation minus twice the bound.
:func:`tracking_gains` computes both norms from the parameters actually used;
:class:`SwarmFlight` reports the bound next to the measured error, and the clearance and
separation the bound guarantees (robot radius and safety distance minus the bound).

In 3-D the same loop acts on x and y; z is flown by the thrust alone, whose loop (a PD on z
with acceleration feedforward through the rotor lag) has the jerk-to-error transfer
tau_m / (tau_m s^3 + s^2 + k_d s + k_p): far faster than the tilt loop, so the horizontal
bound is the one reported. The flown error is measured per axis (:attr:`Flight.axis_error`,
:meth:`SwarmFlight.per_axis`) as well as in total.

RotorPy is imported only here (``pip install "mrfswarm[rotorpy]"``), torch only by the
batched backend.
"""

from __future__ import annotations

import importlib.util
import logging
import os
import sys
from concurrent.futures import as_completed
from dataclasses import dataclass

import numpy as np

from mrfswarm.errors import ConfigError, SolverNotFound
from mrfswarm.geometry import downwash_scale
from mrfswarm.maps import OccupancyGrid
from mrfswarm.metrics import min_pair_distances, obstacle_clearance
from mrfswarm.pools import process_pool, usable_workers
from mrfswarm.trajectory import PiecewisePolynomial

log = logging.getLogger(__name__)

#: vehicle name -> (module, attribute) of its RotorPy parameter dictionary
VEHICLES = {"crazyflie": ("rotorpy.vehicles.crazyflie_params", "quad_params")}
#: Seconds flown after the trajectory ends (to see the vehicle settle).
SETTLE_S = 1.0
#: Simulation backends; "auto" is the first one installed.
BACKENDS = ("batched", "processes")
#: Modules the batched backend needs (the extra ``mrfswarm[batched]``).
BATCHED_MODULES = ("torch", "torchdiffeq", "roma")
#: Control steps whose flat outputs the batched backend evaluates at once.
_BLOCK = 500


@dataclass(frozen=True)
class Flight:
    """One simulated robot: times (S,), flown positions (S, 3), commanded positions (S, 3)."""

    times: np.ndarray
    positions: np.ndarray
    desired: np.ndarray

    @property
    def tracking_error(self) -> np.ndarray:
        """(S,) distance between flown and commanded positions."""
        return np.linalg.norm(self.positions - self.desired, axis=1)

    @property
    def axis_error(self) -> np.ndarray:
        """(S, 3) absolute error on x, y and z."""
        return np.abs(self.positions - self.desired)


@dataclass(frozen=True)
class SwarmFlight:
    """All robots' flights and what they measure (metres).

    Attributes
    ----------
    flights
        One :class:`Flight` per robot, on the same time grid.
    max_tracking_error, rms_tracking_error
        Over all robots and times.
    min_separation
        Smallest distance between two flown robots (3-D; on a voxel map in the downwash-scaled metric).
    min_clearance
        Smallest distance from a flown robot to an occupied cell or the map's edge: horizontal on a 2-D map, in
        3-D on a voxel map (floor and ceiling included).
    in_obstacle
        True if some flown position lies in an occupied cell.
    tracking_bound
        The linear-model bound on tracking error (module docstring), metres.
    max_axis_error, rms_axis_error
        (3,) the same per axis, x, y, z (over all robots and times).
    """

    flights: list[Flight]
    max_tracking_error: float
    rms_tracking_error: float
    min_separation: float
    min_clearance: float | None
    in_obstacle: bool
    tracking_bound: float | None = None
    max_axis_error: tuple[float, float, float] = (np.nan, np.nan, np.nan)
    rms_axis_error: tuple[float, float, float] = (np.nan, np.nan, np.nan)
    backend: str = ""

    def per_axis(self) -> dict[str, dict[str, float]]:
        """The tracking error per axis for ``result.json``: ``{"max_tracking_error_axis_m": {"x": ..., "y": ...,
        "z": ...}, "rms_tracking_error_axis_m": {...}}``."""
        return {"max_tracking_error_axis_m": dict(zip("xyz", map(float, self.max_axis_error))),
                "rms_tracking_error_axis_m": dict(zip("xyz", map(float, self.rms_axis_error)))}


def _vehicle_params(vehicle: str) -> dict:

    mod, attr = VEHICLES[vehicle]
    return getattr(importlib.import_module(mod), attr)


def _loop(vehicle: str):
    """(D, P, params) of the linearized horizontal loop (module docstring)."""
    from rotorpy.controllers.quadrotor_control import SE3Control

    params = _vehicle_params(vehicle)
    ctrl = SE3Control(params)
    kp, kd = float(ctrl.kp_pos[0]), float(ctrl.kd_pos[0])
    kR, kw, tau = float(np.atleast_1d(ctrl.kp_att)[0]), float(np.atleast_1d(ctrl.kd_att)[0]), float(params["tau_m"])
    D = np.array([tau, 1.0, kw, kR])
    P = np.polyadd(np.polymul([1.0, 0.0, 0.0], D), kR * np.array([kd, kp]))
    if np.any(np.roots(P).real >= 0):
        raise ValueError(f"the linearized loop of {vehicle!r} is not stable")
    return D, P, params


def _l1_norm(num: np.ndarray, den: np.ndarray) -> float:
    from scipy import signal

    slowest = float(-np.max(np.roots(den).real))
    t = np.linspace(0.0, 40.0 / slowest, 400001)
    _, h = signal.impulse(signal.lti(num, den), T=t)
    return float(np.trapezoid(np.abs(h), t))


def tracking_gains(vehicle: str = "crazyflie") -> tuple[float, float]:
    """``(||h_j||_1, ||h_d||_1)``: L1 norms (s^3, s^2) from jerk and from a disturbance acceleration to the error."""
    D, P, _ = _loop(vehicle)
    num_j = np.polysub(D, [D[-1]])[:-1]  # (D - k_R) / s: its constant term is zero
    return _l1_norm(num_j, P), _l1_norm(D, P)


def tracking_gain(vehicle: str = "crazyflie") -> float:
    """||h_j||_1 (s^3): the jerk-to-error gain alone (see :func:`tracking_gains`)."""
    return tracking_gains(vehicle)[0]


def drag(vehicle: str = "crazyflie") -> tuple[float, float]:
    """``(c1, c2)``: the largest horizontal drag acceleration at speed v is ``c1 v + c2 v^2`` (hovering rotors)."""
    params = _vehicle_params(vehicle)
    m = float(params["mass"])
    hover = np.sqrt(m * 9.81 / (params["num_rotors"] * params["k_eta"]))
    c1 = params["num_rotors"] * hover * float(params.get("k_d", 0.0)) / m
    c2 = max(float(params.get("c_Dx", 0.0)), float(params.get("c_Dy", 0.0))) / m
    return float(c1), c2


def tracking_bound(jerk: float, speed: float, vehicle: str = "crazyflie") -> float:
    """The bound (metres) on a flown robot's distance from a trajectory of max ``jerk`` and ``speed``."""
    gj, gd = tracking_gains(vehicle)
    c1, c2 = drag(vehicle)
    return gj * jerk + gd * (c1 * speed + c2 * speed**2)


def batched_available() -> bool:
    """Whether the batched backend's modules (torch, torchdiffeq, roma) and RotorPy are installed."""
    return all(importlib.util.find_spec(m) is not None for m in ("rotorpy", *BATCHED_MODULES))


def resolve_backend(backend: str) -> str:
    """The backend ``backend`` names ("auto": batched when installed, else processes).

    Raises
    ------
    ConfigError
        An unknown name.
    SolverNotFound
        "batched" asked for without its modules.
    """
    if backend == "auto":
        return "batched" if batched_available() else "processes"
    if backend not in BACKENDS:
        raise ConfigError(f"simulation.backend = {backend!r}: must be one of auto, {', '.join(BACKENDS)}")
    if backend == "batched" and not batched_available():
        missing = [m for m in BATCHED_MODULES if importlib.util.find_spec(m) is None]
        raise SolverNotFound(f"the batched simulation needs {', '.join(missing)}: pip install \"mrfswarm[batched]\" "
                             "(or set simulation.backend = \"processes\")")
    return backend


def check_vehicle(vehicle: str) -> None:
    """Fail early on a vehicle that is not one of :data:`VEHICLES` (whether or not the simulation runs)."""
    if vehicle not in VEHICLES:
        raise ConfigError(f"simulation.vehicle = {vehicle!r}: must be one of {', '.join(VEHICLES)}")


def check_available(vehicle: str, backend: str = "auto") -> None:
    """Fail early: RotorPy installed, the vehicle known, the backend known and installed."""
    check_vehicle(vehicle)
    if importlib.util.find_spec("rotorpy") is None:
        raise SolverNotFound('the simulation needs RotorPy: pip install "mrfswarm[rotorpy]" '
                             "(or set simulation.enabled = false)")
    resolve_backend(backend)


def flat_outputs(traj: PiecewisePolynomial, t: np.ndarray | float, altitude: float) -> np.ndarray:
    """(5, ..., 3): position and its derivatives up to snap at times ``t``, in 3-D.

    A 3-D trajectory gives its own z; a 2-D one flies at ``altitude`` (z derivatives 0).
    """
    out = np.zeros((5,) + np.shape(t) + (3,))
    d = traj.dim
    for k in range(5):
        out[k, ..., :d] = traj.evaluate(t, derivative=k)
    if d == 2:
        out[0, ..., 2] = altitude
    return out


def _flat_outputs(traj: PiecewisePolynomial, t: float, altitude: float) -> dict:
    x = flat_outputs(traj, float(t), altitude)
    return {"x": x[0], "x_dot": x[1], "x_ddot": x[2], "x_dddot": x[3], "x_ddddot": x[4],
            "yaw": 0.0, "yaw_dot": 0.0, "yaw_ddot": 0.0}


def fly(traj: PiecewisePolynomial, altitude: float, rate_hz: float = 100.0, vehicle: str = "crazyflie",
        duration: float | None = None) -> Flight:
    """Fly one robot along ``traj`` (metres; a 2-D one at ``altitude``) from a hover at its start."""
    from rotorpy.controllers.quadrotor_control import SE3Control
    from rotorpy.vehicles.multirotor import Multirotor

    params = _vehicle_params(vehicle)
    dt = 1.0 / rate_hz
    T = traj.duration + SETTLE_S if duration is None else duration
    n = int(np.ceil(T / dt)) + 1
    times = np.arange(n) * dt
    start = flat_outputs(traj, 0.0, altitude)[0]
    hover = np.sqrt(params["mass"] * 9.81 / (params["num_rotors"] * params["k_eta"]))
    state = {"x": start, "v": np.zeros(3), "q": np.array([0.0, 0.0, 0.0, 1.0]),
             "w": np.zeros(3), "wind": np.zeros(3), "rotor_speeds": np.full(params["num_rotors"], hover)}
    vehicle_ = Multirotor(params, initial_state=state)
    ctrl = SE3Control(params)
    pos = np.empty((n, 3))
    des = np.empty((n, 3))
    for k, t in enumerate(times):
        flat = _flat_outputs(traj, t, altitude)
        pos[k], des[k] = state["x"], flat["x"]
        if k + 1 < n:
            state = vehicle_.step(state, ctrl.update(t, state, flat), dt)
    return Flight(times=times, positions=pos, desired=des)


def _fly_job(args):
    return fly(*args)


def _se3_gains(params: dict) -> dict:
    """The gains of RotorPy's ``SE3Control`` for these parameters (the batched controller gets the same)."""
    from rotorpy.controllers.quadrotor_control import SE3Control

    c = SE3Control(params)
    return {"kp_pos": np.asarray(c.kp_pos, float), "kd_pos": np.asarray(c.kd_pos, float),
            "kp_att": float(np.atleast_1d(c.kp_att)[0]), "kd_att": float(np.atleast_1d(c.kd_att)[0])}


def fly_batched(trajectories: list[PiecewisePolynomial], altitude: float, rate_hz: float = 100.0,
                vehicle: str = "crazyflie", duration: float | None = None, on_block=None) -> list[Flight]:
    """Fly every robot in one vectorized RotorPy simulation (``BatchedMultirotor``, torch on the CPU).

    Same vehicle parameters and controller gains as :func:`fly`, fixed-step RK4 at
    ``rate_hz`` in double precision. ``on_block(k)`` is called after every ``k`` control
    steps (progress).
    """
    import torch
    from rotorpy.controllers.quadrotor_control import BatchedSE3Control
    from rotorpy.vehicles.multirotor import BatchedMultirotor, BatchedMultirotorParams

    params = _vehicle_params(vehicle)
    N = len(trajectories)
    dt = 1.0 / rate_hz
    T = max(tr.duration for tr in trajectories) + SETTLE_S if duration is None else duration
    n = int(np.ceil(T / dt)) + 1
    times = np.arange(n) * dt
    device = torch.device("cpu")
    previous, threads = torch.get_default_dtype(), torch.get_num_threads()
    torch.set_default_dtype(torch.float64)  # RotorPy's batched model makes some buffers in the default dtype
    # the tensors are small: one thread, no contention with other processes (measured several times faster)
    torch.set_num_threads(1)
    try:
        bp = BatchedMultirotorParams([params] * N, N, device)
        g = _se3_gains(params)
        ctrl = BatchedSE3Control(bp, N, device, kp_pos=torch.tensor(g["kp_pos"]).repeat(N, 1),
                                 kd_pos=torch.tensor(g["kd_pos"]).repeat(N, 1),
                                 kp_att=torch.full((N, 1), g["kp_att"]), kd_att=torch.full((N, 1), g["kd_att"]))
        start = np.array([flat_outputs(tr, 0.0, altitude)[0] for tr in trajectories])
        hover = np.sqrt(params["mass"] * 9.81 / (params["num_rotors"] * params["k_eta"]))
        state = {"x": torch.tensor(start),
                 "v": torch.zeros(N, 3), "q": torch.tensor([[0.0, 0.0, 0.0, 1.0]]).repeat(N, 1),
                 "w": torch.zeros(N, 3), "wind": torch.zeros(N, 3),
                 "rotor_speeds": torch.full((N, params["num_rotors"]), float(hover))}
        quad = BatchedMultirotor(bp, N, state, device, control_abstraction="cmd_motor_speeds", integrator="rk4")
        pos = np.empty((n, N, 3))
        des = np.empty((n, N, 3))
        zeros = torch.zeros(N)
        every = torch.arange(N)  # as a tensor: RotorPy's default, a list, is converted at every use
        with torch.inference_mode():
            for a in range(0, n, _BLOCK):
                tb = times[a:a + _BLOCK]
                flat = np.zeros((5, len(tb), N, 3))  # derivative, time, robot, xyz
                for i, tr in enumerate(trajectories):
                    flat[:, :, i] = flat_outputs(tr, tb, altitude)
                flat_t = torch.from_numpy(flat)
                for j, t in enumerate(tb):
                    ref = {"x": flat_t[0, j], "x_dot": flat_t[1, j], "x_ddot": flat_t[2, j], "x_dddot": flat_t[3, j],
                           "x_ddddot": flat_t[4, j], "yaw": zeros, "yaw_dot": zeros, "yaw_ddot": zeros}
                    pos[a + j] = state["x"].numpy()
                    des[a + j] = flat[0, j]
                    if a + j + 1 < n:
                        state = quad.step(state, ctrl.update(float(t), state, ref, every), dt, every)
                if on_block is not None:
                    on_block(len(tb))
    finally:
        torch.set_default_dtype(previous)
        torch.set_num_threads(threads)
    return [Flight(times=times, positions=pos[:, i], desired=des[:, i]) for i in range(N)]  # views: no copy


def fly_swarm(trajectories: list[PiecewisePolynomial], altitude: float, grid: OccupancyGrid, rate_hz: float = 100.0,
              vehicle: str = "crazyflie", workers: int | None = None, jerk: float | None = None,
              speed: float | None = None, progress: bool | None = None, backend: str = "auto",
              downwash: float = 1.0) -> SwarmFlight:
    """Fly every robot and measure tracking, separation and clearance on the common time grid.

    ``downwash``: c of the separation's scaled metric on a voxel map (dz counts 1/c; a 2-D
    map's flights are measured in plain 3-D distance).

    ``jerk``, ``speed``: the trajectories' maximum jerk and speed, for the tracking bound
    (None: no bound).
    ``progress``: a progress bar on stderr (default: when it is a terminal).
    ``backend``: "batched", "processes" or "auto" (module docstring); ``workers`` is the
    number of processes of the "processes" backend.
    """
    check_available(vehicle, backend)
    backend = resolve_backend(backend)
    duration = max(tr.duration for tr in trajectories) + SETTLE_S
    from tqdm import tqdm

    jobs = [(tr, altitude, rate_hz, vehicle, duration) for tr in trajectories]
    workers = usable_workers(min(len(jobs), workers or os.cpu_count() or 1))
    show = sys.stderr.isatty() if progress is None else progress
    if backend == "batched":
        n_steps = int(np.ceil(duration * rate_hz)) + 1
        with tqdm(total=n_steps, desc=f"flying {len(jobs)} robots", unit="step", disable=not show, leave=False) as bar:
            flights = fly_batched(trajectories, altitude, rate_hz, vehicle, duration, on_block=bar.update)
        return _measure(flights, grid, vehicle, jerk, speed, downwash, backend)
    with tqdm(total=len(jobs), desc="flying", unit="robot", disable=not show, leave=False) as bar:
        if workers <= 1:
            flights = []
            for j in jobs:
                flights.append(_fly_job(j))
                bar.update(1)
        else:
            with process_pool(workers) as ex:  # Ctrl-C stops the flights still running
                futures = [ex.submit(_fly_job, j) for j in jobs]
                for f in as_completed(futures):
                    f.result()
                    bar.update(1)
                flights = [f.result() for f in futures]
    return _measure(flights, grid, vehicle, jerk, speed, downwash, backend)


def _measure(flights: list[Flight], grid: OccupancyGrid, vehicle: str, jerk: float | None,
             speed: float | None, downwash: float = 1.0, backend: str = "") -> SwarmFlight:
    """Tracking, separation and clearance of flights on one time grid (flown by ``backend``)."""
    err = np.concatenate([f.tracking_error for f in flights])
    axis = np.concatenate([f.axis_error for f in flights])  # (S N, 3)
    pts = np.stack([f.positions for f in flights], axis=1)  # (S, N, 3)
    scale = downwash_scale(3, downwash if grid.ndim == 3 else 1.0)
    d3 = float(min_pair_distances(pts * scale)[0].min()) if len(flights) > 1 else float("inf")  # exact, in 3-D
    p = pts[..., :grid.ndim].reshape(-1, grid.ndim)  # a 2-D map: the horizontal position; a voxel map: all of it
    cells = grid.world_to_cell(p)
    clr = obstacle_clearance(grid.occupied, (p - np.asarray(grid.origin)) / grid.resolution)
    return SwarmFlight(
        flights=flights,
        max_tracking_error=float(err.max()),
        rms_tracking_error=float(np.sqrt(np.mean(err**2))),
        max_axis_error=tuple(float(v) for v in axis.max(axis=0)),  # type: ignore[arg-type]
        rms_axis_error=tuple(float(v) for v in np.sqrt(np.mean(axis**2, axis=0))),  # type: ignore[arg-type]
        min_separation=float(d3),
        min_clearance=None if clr is None else clr * grid.resolution,
        in_obstacle=bool(np.any(~grid.is_free(cells))),
        tracking_bound=None if jerk is None or speed is None else tracking_bound(jerk, speed, vehicle),
        backend=backend,
    )
