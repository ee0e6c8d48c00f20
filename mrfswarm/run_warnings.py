"""What a finished plan warns of, one line each: the texts ``mrfswarm run`` prints after its summary line and
:func:`mrfswarm.plan` issues as :class:`~mrfswarm.errors.PlanWarning`.

Each text is computed from the run's summary (``result.json``'s content), in the order the command prints them:
the discrete plan cut at ``mrf.max_steps``, the Crazyflie memory's advice, the simulated flight's warnings, windows
flown as their rest-to-rest witness, a QP backend without an iteration cap that failed attempts of many windows, the
NLP refinement's errors, and last the robots short of the goal. A Python caller of ``plan`` heard none of them: with
``smoothing.qp_options.max_iter = 1`` every window flew its witness (free5: 13.3 s of flight instead of 4.7 s) and
``plan`` said nothing.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import solvers.qp

if TYPE_CHECKING:
    from mrfswarm.pipeline import Result


def run_warnings(result: Result) -> list[str]:
    """The warnings of a finished run, one line each (without the command's ``mrfswarm: warning:`` prefix), in the
    order ``mrfswarm run`` prints them; empty for a run with nothing to say."""
    s = result.summary()
    cfg = result.config
    out = []
    over = [r for r in s["robots"] if r["stop_reason"] == "max_steps"]
    if over:  # a long way: the plan ends where the step budget does, not at the goal (a tour's city map, 0 of 30)
        left = max(r["goal_distance_m"] for r in over)
        more = math.ceil(left / result.scenario.grid.resolution)  # a cell a step (a diagonal step goes 1.4)
        out.append(f"the discrete plan ended at mrf.max_steps = {cfg.mrf.max_steps} with {len(over)} "
                   f"robot{'s' * (len(over) > 1)} on the way to the goal, the farthest {left:.1f} m from it (about "
                   f"{more} more steps at a cell a step): raise it, e.g. --set mrf.max_steps="
                   f"{100 * math.ceil((cfg.mrf.max_steps + more) / 100)}")
    crazyflie = s.get("crazyflie") or {}
    if crazyflie.get("advice"):  # a long flight fits no format: said here, not first by the scripts at the radio
        out.append(crazyflie["advice"])
    out.extend(flown_warnings(s["simulation"], cfg.scenario.robot_radius))
    witness = (s.get("window_attempts") or {}).get("witness", 0)
    if witness:  # safe, but slow: a window where every planned duration failed flies from rest to rest
        reasons = s.get("witness_reasons") or []
        because = f" (last rejected: {reasons[0]}{f'; {len(reasons) - 1} other reasons' if len(reasons) > 1 else ''})" \
            if reasons else ""
        out.append(f"{witness} of {s['windows']} smoothing windows had no solution at their planned durations and fly "
                   f"the rest-to-rest witness (slower, with stops){because}: see result.json's witness_reasons; "
                   "smoothing.qp_options or the QP backend may be too tight")
    failures = s.get("solve_failures") or {"windows": 0}
    # a backend with an iteration cap (piqp, proxsuite) fails the faster attempts that do not converge within it by
    # design (clutter40: 8 of 16 windows); one without fails where it solves inaccurately (SCS: 3 of 9 on the corridor)
    if failures["windows"] and 4 * failures["windows"] >= s["windows"] and \
            solvers.qp.BACKENDS.get(s["qp"]).capabilities.iteration_cap is None:
        status = f" (status {failures['statuses'][0]!r})" if failures["statuses"] else ""
        out.append(f"the QP backend {s['qp']} did not solve attempts of {failures['windows']} of {s['windows']} "
                   f"smoothing windows{status}: they fly slower attempts; see result.json's solve_failures")
    errors = s.get("refinement_errors") or []
    if errors:  # the refinement only shortens a certified flight: a backend that raised leaves the window as it was
        more_errors = f" ({len(errors) - 1} other errors in result.json's refinement_errors)" if len(errors) > 1 else ""
        out.append(f"the time refinement's NLP backend raised: {errors[0]}{more_errors}; those windows fly their QP's "
                   "durations or the best point it had evaluated")
    home = short_of_goal(s["robots"], cfg.goal_potential.distance)
    if home:  # last: what a user reads first of a run that did not bring the swarm home
        out.append(home)
    return out


def flown_warnings(flown: dict | None, radius: float) -> list[str]:
    """What a run's simulated flight (``result.json``'s ``simulation``) warns of: a flight that came closer than the
    plan (the plan is certified; the simulated tracking is not part of the proof, docs/guarantees.md), and a tracking
    bound past the robot radius, which guarantees no flown clearance or separation at all (negative guarantees)."""
    if flown is None:
        return []
    out = []
    safety = 2 * radius
    bound = flown["tracking_error_bound_m"]
    clearance = flown.get("min_obstacle_clearance_m")
    grazed = clearance is not None and clearance < radius and not flown["entered_obstacle"]
    if flown["min_separation_m"] < safety or flown["entered_obstacle"] or grazed:
        parts = []
        if flown["min_separation_m"] < safety:  # 2 r: the two bodies overlap
            parts.append(f"two robots {flown['min_separation_m']:.3f} m apart, less than twice the radius "
                         f"({safety:g} m): their bodies touch")
        if flown["entered_obstacle"]:
            parts.append("a robot inside an obstacle")
        elif grazed:  # a tour's arena flew 0.096 m from a wall at radius 0.1 without a word
            parts.append(f"a robot {clearance:.3f} m from an obstacle, less than its radius ({radius:g} m)")
        guarantee = ""
        if bound is not None:
            sep = flown["guaranteed_separation_m"]
            guarantee = f" (bound {bound * 100:.1f} cm, " + (f"flown separation guaranteed {sep:.3f} m)" if sep >= 0
                                                              else "no flown separation guaranteed)")
        out.append(f"the simulated flight came closer than the plan: {' and '.join(parts)}; tracking error "
                   f"{flown['max_tracking_error_m'] * 100:.1f} cm{guarantee}: see result.json's simulation")
    if bound is not None and (flown.get("guaranteed_clearance_m") or 0.0) < 0:
        out.append(f"the tracking bound of this flight ({bound * 100:.1f} cm) exceeds the robot radius ({radius:g} m): "
                   f"the simulation guarantees no flown clearance ({flown['guaranteed_clearance_m']:.3f} m) or "
                   f"separation ({flown['guaranteed_separation_m']:.3f} m), only what it measured (error "
                   f"{flown['max_tracking_error_m'] * 100:.1f} cm); a lower smoothing.j_max or v_max lowers the bound "
                   "(docs/guarantees.md)")
    return out


#: Why a robot (``result.json``'s ``robots[].stop_reason``) did not reach the goal, as the run's last line says it.
WHY_SHORT = {
    "trapped": "trapped (the goal field leads them to a local minimum short of the goal, or they queue behind one)",
    "stalled": "stalled (held where they are by the robots around them)",
    "unreachable": "unreachable (no free path to the goal)",
    "max_steps": "on their way at mrf.max_steps",
}


def short_of_goal(robots: list[dict], distance: str) -> str | None:
    """The run's last line when robots did not reach the goal for another reason than the step budget (whose line
    says which key to raise): how many, and why. A crowd behind a one-cell door under the paper's rules ended with
    0 of 20 at the goal, said only inside the summary line's parentheses, and exit code 0 as any plan written."""
    why: dict[str, int] = {}
    for r in robots:
        if r["stop_reason"] is not None:
            why[r["stop_reason"]] = why.get(r["stop_reason"], 0) + 1
    if set(why) <= {"max_steps"}:
        return None
    short = sum(why.values())
    line = (f"{short} of {len(robots)} robot{'s' * (len(robots) > 1)} did not reach the goal: "
            + ", ".join(f"{why[k]} {WHY_SHORT.get(k, k)}" for k in [*(k for k in WHY_SHORT if k in why),
                                                                      *(k for k in why if k not in WHY_SHORT)]))
    if "trapped" in why and distance == "euclidean":
        line += '; goal_potential.distance = "geodesic" (the default) leads around walls'
    return line + "; the plan is written as any other (see result.json's robots)"
