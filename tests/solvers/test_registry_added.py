"""Backends added from outside the package: ``Registry.register`` and entry points, checked as they join."""

import dataclasses
import logging
import sys
import textwrap

import numpy as np
import pytest

from solvers import mrf, qp
from solvers import registry as registry_module
from solvers.errors import SolverNotFound
from solvers.mrf import icm
from solvers.mrf.capabilities import MRFCapabilities
from solvers.mrf.synthetic import random_mrf
from solvers.qp import piqp_
from solvers.qp.capabilities import QPCapabilities
from solvers.registry import Backend, Registry, added, restore

CAPS = MRFCapabilities(optimal=False, lower_bound=False, exact_on_trees=False, monotone=True, stochastic=False)


def twin(name="icm_twin"):
    """ICM under another name: a real method, added the way a user adds one."""
    return Backend(name=name, entry=icm.minimize, capabilities=CAPS, summary="ICM, added")


@pytest.fixture
def public(monkeypatch):
    """An empty table of public registries, so that the registries a test builds leave no trace."""
    monkeypatch.setattr(registry_module, "_PUBLIC", {})


def test_registered_method_is_dispatched_and_removed():
    record = twin()
    try:
        mrf.METHODS.register(record)
        assert mrf.METHODS.names()[-1] == "icm_twin" and added()["solvers.mrf"] == (record,)
        mrf.METHODS.register(record)  # the same record again: nothing (a forked worker repeating its parent)
        problem = random_mrf(np.random.default_rng(1), 12, 4)
        assert mrf.minimize(problem, "icm_twin").labels.tolist() == mrf.minimize(problem, "icm").labels.tolist()
    finally:
        mrf.METHODS.unregister("icm_twin")
    assert "icm_twin" not in mrf.METHODS and "solvers.mrf" not in added()
    with pytest.raises(SolverNotFound, match="unknown MRF method 'icm_twin'"):
        mrf.METHODS.get("icm_twin")


@pytest.mark.parametrize("record, message", [
    ("icm", "must be a solvers.registry.Backend, got str"),
    (twin("ICM-2"), "name 'ICM-2': lower-case letters"),
    (twin("2icm"), "name '2icm'"),
    (dataclasses.replace(twin(), entry="icm.minimize"), "entry 'icm.minimize' is not callable"),
    (dataclasses.replace(twin(), capabilities=QPCapabilities(inequalities=True, warm_start=False, detects_infeasibility=True, sparse=True)),
     "capabilities must be a MRFCapabilities, got QPCapabilities"),
    (dataclasses.replace(twin(), requires="numpy"), "requires must be a tuple of module names"),
    (twin("icm"), "'icm' is built in"),
])
def test_a_wrong_record_is_refused_naming_itself(record, message):
    n = len(mrf.METHODS)
    with pytest.raises(ValueError, match=message):
        mrf.METHODS.register(record)
    assert len(mrf.METHODS) == n


def _solves_with_piqp(problem, options):  # a function, as an NLP backend's entry is
    return qp.solve(problem, "piqp", options)


class PiqpCopy(piqp_.PiqpQP):
    name = "piqp_copy"


@pytest.mark.parametrize("entry, name, message", [
    (_solves_with_piqp, "my_qp", r"^QP backend 'my_qp': entry <function _solves_with_piqp .*> is not a subclass of "
                                 r"solvers\.qp\.base\.PreparedQP$"),
    (piqp_.PiqpQP, "piqp_twin", r"^QP backend 'piqp_twin': its entry PiqpQP is named 'piqp'; subclass it with "
                                r"name = 'piqp_twin'$"),
])
def test_a_qp_record_whose_entry_is_not_its_own_prepared_class_is_refused(entry, name, message):
    """A function as a QP backend's entry joined, and every solve failed with "AttributeError: 'Solution' object has
    no attribute 'solve'" (a tour's plugin, a traceback from mrfswarm.plan); piqp's class under another record name
    solved as "piqp" in its solutions and errors."""
    record = dataclasses.replace(piqp_.BACKEND, name=name, entry=entry)
    with pytest.raises(ValueError, match=message):
        qp.BACKENDS.register(record)
    assert name not in qp.BACKENDS
    copy = dataclasses.replace(piqp_.BACKEND, name="piqp_copy", entry=PiqpCopy)
    try:
        qp.BACKENDS.register(copy)  # its own subclass: taken
        assert qp.solve(qp.QPProblem(P=np.eye(2), q=[-1, -1], A=[[1, 1]], l=[-np.inf], u=[1]), "piqp_copy").backend \
            == "piqp_copy"
    finally:
        qp.BACKENDS.unregister("piqp_copy")


def test_a_second_record_under_a_registered_name_is_refused():
    try:
        mrf.METHODS.register(twin())
        with pytest.raises(ValueError, match=r"'icm_twin' is registered already, by a register\(\) call "
                                             r"\(solvers\.mrf\.icm:minimize\)"):
            mrf.METHODS.register(dataclasses.replace(twin(), summary="another"))
    finally:
        mrf.METHODS.unregister("icm_twin")


def test_built_in_records_cannot_be_removed():
    with pytest.raises(ValueError, match="'osqp' is built in"):
        qp.BACKENDS.unregister("osqp")
    with pytest.raises(ValueError, match="no added QP backend 'nothing'"):
        qp.BACKENDS.unregister("nothing")


def test_restore_adds_what_is_missing_and_keeps_what_is_there():
    record = twin()
    try:
        restore({"solvers.mrf": (record,)})
        assert mrf.METHODS.get("icm_twin") is record
        restore({"solvers.mrf": (record,)})  # already there: kept
        assert mrf.METHODS.added() == (record,)
    finally:
        mrf.METHODS.unregister("icm_twin")


def test_one_registry_per_group(public):
    Registry("MRF", [], capabilities=MRFCapabilities, group="test.one")
    with pytest.raises(ValueError, match="second registry for the entry-point group 'test.one'"):
        Registry("MRF", [], capabilities=MRFCapabilities, group="test.one")


def _distribution(root, name, entry_points, modules):
    """An installed distribution under ``root`` (a dist-info folder and its modules), put on sys.path."""
    info = root / f"{name}-1.0.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text(textwrap.dedent(entry_points))
    for module, source in modules.items():
        (root / f"{module}.py").write_text(textwrap.dedent(source))


PLUGIN = """
    from solvers.mrf import icm
    from solvers.mrf.capabilities import MRFCapabilities
    from solvers.registry import Backend

    BACKEND = Backend(name="icm_plugin", entry=icm.minimize, extra="fast", requires=("numpy",),
                      capabilities=MRFCapabilities(optimal=False, lower_bound=False, exact_on_trees=False,
                                                   monotone=True, stochastic=False))
    MISNAMED = BACKEND
    NOT_A_RECORD = 42
"""


@pytest.fixture
def installed(tmp_path, monkeypatch, public):
    """A distribution ``mrf-plugins`` declaring four entry points of the group ``test.mrf``: one good, one naming a
    module that raises, one misnamed, one not a record."""
    _distribution(tmp_path, "mrf_plugins", """
        [test.mrf]
        icm_plugin = plugin_good:BACKEND
        broken = plugin_broken:BACKEND
        other_name = plugin_good:MISNAMED
        number = plugin_good:NOT_A_RECORD
    """, {"plugin_good": PLUGIN, "plugin_broken": "raise ImportError('no native library here')\n"})
    monkeypatch.syspath_prepend(str(tmp_path))
    yield
    for m in ("plugin_good", "plugin_broken"):
        sys.modules.pop(m, None)


def test_entry_points_join_when_first_read_and_broken_ones_say_why(installed, caplog):
    reg = Registry("MRF", [icm.BACKEND], noun="method", capabilities=MRFCapabilities, group="test.mrf")
    with caplog.at_level(logging.WARNING, logger="solvers.registry"):
        assert reg.names() == ["icm", "icm_plugin"]
    record = reg.get("icm_plugin")
    assert record.distribution == "mrf_plugins" and reg.added() == (record,)
    assert record.install_hint == 'pip install "mrf_plugins[fast]"'  # its own distribution's extra, not ours
    warned = "\n".join(r.getMessage() for r in caplog.records)
    assert "broken = plugin_broken:BACKEND of mrf_plugins failed to load: ImportError: no native library" in warned
    assert "the record is named 'icm_plugin', not 'other_name'" in warned
    assert "must be a solvers.registry.Backend, got int" in warned
    with pytest.raises(SolverNotFound, match="MRF method 'broken': entry point .* ImportError: no native library"):
        reg.get("broken")
    reg.unregister("icm_plugin")
    assert reg.names() == ["icm"]


def test_a_worker_process_does_not_warn_again(installed, caplog, monkeypatch):
    """A sweep's or a pool's worker loads the entry points again: its parent warned once, the worker only informs
    (a tour's sweep of 2 workers printed each broken entry point three times)."""
    monkeypatch.setattr(registry_module.multiprocessing, "parent_process", lambda: object())
    reg = Registry("MRF", [], noun="method", capabilities=MRFCapabilities, group="test.mrf")
    with caplog.at_level(logging.INFO, logger="solvers.registry"):
        assert reg.names() == ["icm_plugin"]
    assert caplog.records and all(r.levelno == logging.INFO for r in caplog.records)
    with pytest.raises(SolverNotFound, match="failed to load"):  # asking for it still says why
        reg.get("broken")


def test_entry_points_are_read_once(installed):
    reg = Registry("MRF", [], noun="method", capabilities=MRFCapabilities, group="test.mrf")
    assert len(reg) == 1
    sys.modules.pop("plugin_good")  # a second load would import it again, a new record: "registered already"
    assert len(reg) == 1 and reg.names() == ["icm_plugin"]


@pytest.mark.parametrize("cap", [0, -5, 2.5, True, "120"])
def test_an_iteration_cap_that_is_not_a_count_is_refused(cap):
    """A plugin's record with iteration_cap = 0 joined: every attempt got a budget of one iteration and the corridor
    flew 27.9 s instead of 20.5, without a word."""
    with pytest.raises(ValueError, match=r"^QPCapabilities\.iteration_cap = .*: must be None \(no cap\) or a whole "
                                         r"number >= 1$"):
        QPCapabilities(inequalities=True, warm_start=False, detects_infeasibility=True, sparse=True, iteration_cap=cap)
    assert QPCapabilities(inequalities=True, warm_start=False, detects_infeasibility=True, sparse=True,
                          iteration_cap=1).iteration_budget(50) == 1
