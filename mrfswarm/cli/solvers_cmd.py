"""``mrfswarm solvers``: every QP, NLP and MRF backend, installed or not, with the install hint; those added
(an entry point, a script's ``register``) say by what."""

from __future__ import annotations

import argparse
from typing import Any

import solvers
from solvers.registry import Registry


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("solvers", help="list every QP, NLP and MRF backend and how to install it")
    p.set_defaults(func=run)


def table() -> str:
    """The listing, one row per backend of each registry: state, summary and capabilities."""
    from mrfswarm.config import MrfConfig, SmoothingConfig

    lines = []
    registries: tuple[tuple[str, Registry[Any], str], ...] = (
        ("QP backends (--qp)", solvers.qp.BACKENDS, SmoothingConfig.backend),
        ("NLP backends (--nlp)", solvers.nlp.BACKENDS, SmoothingConfig.nlp),
        ("MRF methods (--mrf)", solvers.mrf.METHODS, MrfConfig.method))
    for title, registry, default in registries:
        lines.append(title)
        width = max(len(b.name) for b in registry)
        added = registry.added()
        states = []
        for b in registry:
            state = "installed" if b.is_available() else f"missing: {b.install_hint}"
            if b in added:  # an entry point's (its distribution) or a script's
                state += f", added by {b.distribution or 'register()'}"
            if b.name == default:
                state += ", the run's default"
            states.append(state)
        column = max([40, *(len(state) for state in states)])  # a plugin's install hint is longer than ours
        for b, state in zip(registry, states):
            lines.append(f"  {b.name:<{width}}  {state:<{column}}  {b.summary}")
            lines.append(f"  {'':<{width}}  {'':<{column}}  [{', '.join(b.capabilities.flags()) or 'none'}]")
        lines.append("")
    # solvers.qp.solve's own default differs from a run's (a solver tour read "the default" as the library's)
    lines.append(f"The run's default is the config's; on their own, solvers.qp.solve() uses "
                 f"{solvers.qp.DEFAULT_BACKEND!r}, solvers.nlp.minimize() {solvers.nlp.DEFAULT_BACKEND!r} and "
                 f"solvers.mrf.minimize() {solvers.mrf.DEFAULT_METHOD!r} unless given a backend.")
    return "\n".join(lines).rstrip() + "\n"


def run(args: argparse.Namespace) -> int:
    print(table(), end="")
    return 0
