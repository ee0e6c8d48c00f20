"""The window attempts as they were before they followed the window before's first step."""

from __future__ import annotations

import pytest

from mrfswarm.continuous.receding_horizon import RecedingHorizon


def unfollowed(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every attempt with the profiles' own first step (``RecedingHorizon._follow`` made the identity): the
    default's inserted attempt is then the fast one itself, which fails where it does."""
    monkeypatch.setattr(RecedingHorizon, "_follow", staticmethod(lambda attempts, previous: attempts))
