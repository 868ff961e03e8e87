"""Shared fixtures. The Anny body is built once per test run (and cached on disk)."""

from __future__ import annotations

import logging
import os
import shutil
import tempfile

import pytest

from kgarment.body import PAPER_MOTIONS, builtin_motions, load_anny_body

EXTRA_MOTIONS = ("arms_raise.left", "arms_raise.right", "arm_flexion.left", "arm_flexion.right",
                 "knee_flexion", "torso_twist_left")


def _session_body():
    lib = builtin_motions()
    return load_anny_body([lib[n] for n in PAPER_MOTIONS + EXTRA_MOTIONS])


def pytest_configure(config):
    """With pytest-xdist (``make test`` runs ``-n auto``), the controller builds the body's
    caches (Anny's own, ~2 minutes on a fresh machine, and kgarment's) before the workers
    start, so that they are built once and not by every worker at the same time.

    The fully reinforced garments' solves (``kgarment.case.store.shared_store``) go to a
    folder of this session's own (the workers inherit it), not to the machine's cache: every
    test run solves them once, as a fresh machine does, whatever ran before."""
    if getattr(config, "workerinput", None) is None:
        folder = tempfile.mkdtemp(prefix="kgarment-solves-")
        os.environ["KGARMENT_SOLVE_CACHE"] = folder
        config.add_cleanup(lambda: shutil.rmtree(folder, ignore_errors=True))
        if config.getoption("numprocesses", default=None):
            _session_body()


# Scheduling under pytest-xdist (``make test``: ``-n auto --dist loadscope
# --no-loadscope-reorder``): each module stays on one worker (its module fixtures are built
# once) and the modules are handed out in collection order, so the ones that take longest
# are collected first (longest first keeps the two workers' ends together: a 3-minute
# module handed out last leaves the other core idle for 3 minutes); the rest keep their
# order.  (xdist's ``loadgroup`` would let single tests spread, but with pytest 9 its groups
# are ignored: it renames ``item._nodeid``, which pytest 9 no longer reads.)
LONGEST_FIRST = ("test_reproduce", "test_sweep", "test_examples", "test_design_cli", "test_studio_browser",
                 "test_studio_app", "test_render_cli", "test_design_refine", "test_sim_shirt", "test_design_wearers")


def pytest_collection_modifyitems(config, items):
    def rank(item):
        name = item.module.__name__
        return LONGEST_FIRST.index(name) if name in LONGEST_FIRST else len(LONGEST_FIRST)

    items[:] = sorted(items, key=rank)  # stable: each module's own order kept


@pytest.fixture(scope="session")
def anny_body():
    """The default Anny body posed in the paper's motions and a few more (session-wide)."""
    logging.getLogger("kgarment").setLevel(logging.INFO)
    return _session_body()


@pytest.fixture(scope="session")
def shirt0(anny_body):
    from kgarment.garment import make_garment

    return make_garment(anny_body, "short_sleeve_shirt", 0)
