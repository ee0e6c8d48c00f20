"""The window attempts as they were before they followed the window before's first step, or were bisected."""

from __future__ import annotations

import pytest

import mrfswarm.continuous.receding_horizon as rhm
from mrfswarm.continuous.receding_horizon import RecedingHorizon


def unfollowed(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every attempt with the profiles' own first step (``RecedingHorizon._follow`` made the identity): the
    default's inserted attempt is then the fast one itself, which fails where it does."""
    monkeypatch.setattr(RecedingHorizon, "_follow", staticmethod(lambda attempts, previous: attempts))


def unbisected(monkeypatch: pytest.MonkeyPatch) -> None:
    """The ladder's attempts alone, none bisected (``receding_horizon.BISECTIONS`` 0): for the tests of a rung
    or of what an attempt carries (holds, releases, the first step), written on flights from before the bisection
    and comparing two flights at the same durations (the bisection's own: tests/continuous/test_bisection.py)."""
    monkeypatch.setattr(rhm, "BISECTIONS", 0)


def unretimed(monkeypatch: pytest.MonkeyPatch) -> None:
    """The windows' flight as they planned it, the whole of it not re-timed (``receding_horizon.RETIME_HORIZONS``
    0): for the tests of a window's attempts, refinement or cache on a flight short enough to be re-timed, which
    compare flights or count solves that the re-timing changes (its own: tests/continuous/test_retime.py)."""
    monkeypatch.setattr(rhm, "RETIME_HORIZONS", 0)


def unled(monkeypatch: pytest.MonkeyPatch) -> None:
    """No leading attempt (``receding_horizon.LEAD_ROOM`` 0): for the tests of the other attempts (their order,
    the fast profile first, the creep rows and holds a flight needs without it), written on flights from before it
    (its own: tests/continuous/test_leading.py)."""
    monkeypatch.setattr(rhm, "LEAD_ROOM", 0.0)
