"""The README's Python example runs as written: every name it uses is defined in it (a library tour copied it into a
fresh interpreter and stopped at ``result.continuous.positions(t)``, NameError: ``t``; its solver lines used
``problem`` and ``mrf``, defined nowhere), and its solver lines give what their comments say. The planning lines
(the corridor, tens of seconds) are run by the tour and the end-to-end tests, not here."""

from __future__ import annotations

import ast
import builtins
import re

import numpy as np
import pytest

from support.repository import ROOT


def readme_python() -> str:
    """The README's one ``python`` block (its "From Python" example)."""
    blocks = re.findall(r"```python\n(.*?)```", (ROOT / "README.md").read_text(), flags=re.S)
    assert len(blocks) == 1, "the README has one Python example; this test reads it"
    return blocks[0]


def test_every_name_the_example_uses_is_defined_in_it():
    tree = ast.parse(readme_python())
    bound = set(dir(builtins))
    missing = []
    for statement in tree.body:  # in order: a name must be bound before the statement that reads it
        for node in ast.walk(statement):
            if isinstance(node, ast.Name) and isinstance(node.ctx, ast.Load) and node.id not in bound:
                missing.append(node.id)
            if isinstance(node, ast.arg):
                bound.add(node.arg)
        for node in ast.walk(statement):
            if isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
                bound.add(node.id)
            elif isinstance(node, (ast.Import, ast.ImportFrom)):
                bound.update((a.asname or a.name).split(".")[0] for a in node.names)
    assert not missing, f"the README's example uses names it never defines: {sorted(set(missing))}"


@pytest.mark.parametrize("expression, expected", [
    ('solvers.qp.solve(qp, backend="piqp").x', [0.5, 0.5]),
    ('solvers.nlp.minimize(nlp, backend="ipopt").x', [0.5, 0.0]),
    ('solvers.mrf.minimize(mrf, method="trws").labels', [0, 0]),
])
def test_the_solver_lines_give_what_their_comments_say(expression, expected):
    """The example's lines from ``import numpy`` on (the solver layer alone) run as written."""
    code = readme_python()
    ns: dict = {}
    exec(code[code.index("import numpy as np"):], ns)  # noqa: S102 - the README's own code
    assert expression in code
    np.testing.assert_allclose(eval(expression, ns), expected, atol=1e-6)  # noqa: S307
