"""Per-clutch load: the share of the ON - OFF energy and the tension (docs/method/index.md, "Judging a design as a garment")."""

from __future__ import annotations

import numpy as np
import pytest

from kgarment.case import Case
from kgarment.evaluate import Evaluator
from kgarment.evaluate.loads import load_chart
from kgarment.sim import SolverOptions, build_model
from kgarment.sim.synthetic import Tube


@pytest.fixture(scope="module")
def tube():
    """A tube (30 cm long, 5 cm radius) stretched 5% along its axis, with two 14 cm clutches
    on opposite sides, ``paper`` materials (cloth 0.5 MPa, reinforcement 0.5 GPa, clutch ON
    3 GPa).  Reinforced: two bands 2.6 cm wide along the first clutch, from the held bottom
    ring to its start and from its end to the pulled top ring, so that this clutch is the
    only stiff link in series between them: switching it on alone must give all the ON -
    OFF energy (share 1).  The second clutch sits on plain cloth, 1/6000 of its stiffness:
    its ends cannot hold it, so switching it on changes almost nothing (share 0)."""
    tube = Tube(0.05, 0.0, 0.3, 48, 31)
    clutches = [tube.clutch("linked", 0.0, 0.08, 0.22, 0.01, 28), tube.clutch("loose", np.pi, 0.08, 0.22, 0.01, 28)]
    model = build_model(tube.vertices, tube.faces, clutches, preset="paper")
    motion = tube.motion("pull", 0.05, 0.0)
    c = tube.vertices[tube.faces].mean(axis=1)
    theta = np.arctan2(c[:, 1], c[:, 0])
    band = np.abs(theta) < 0.26  # 2.6 cm of arc
    reinforced = band & ((c[:, 2] < 0.095) | (c[:, 2] > 0.205))
    design = np.where(reinforced, 1.0, 1e-3)
    setup = Case.build(model, {"pull": motion}, "active", SolverOptions(tol=1e-5, max_iter=300))
    return Evaluator(setup), design


@pytest.fixture(scope="module")
def tube_loads(tube):
    evaluator, design = tube
    return evaluator.evaluate(design, loads=True)


def test_the_only_load_path_carries_everything_and_a_loose_clutch_nothing(tube_loads):
    loads = tube_loads.loads
    linked, loose = loads.get("pull", "linked"), loads.get("pull", "loose")
    assert linked.share == pytest.approx(1.0, abs=0.05) and linked.loaded
    assert abs(loose.share) < 0.03 and not loose.loaded
    # with two clutches, switching one off leaves the other alone ON: needed = 1 - the other's share
    assert linked.needed == pytest.approx(1.0 - loose.share, abs=1e-9)
    assert loose.needed == pytest.approx(1.0 - linked.share, abs=1e-9) and abs(loose.needed) < 0.05
    assert loads.unloaded() == ["loose"]
    (g,) = loads.garment
    assert g.energy_on_J > 3 * g.energy_off_J > 0  # switching the linked clutch on resists the pull
    assert linked.tension_N > 10 * abs(loose.tension_N)


def test_loads_in_json_and_chart(tube_loads, tmp_path):
    doc = tube_loads.to_json()
    assert {c["clutch"] for c in doc["clutches"]} == {"linked", "loose"}
    assert set(doc["clutches"][0]) == {"motion", "clutch", "share", "needed", "tension_N", "loaded"}
    assert set(doc["garment"][0]) == {"motion", "energy_on_J", "energy_off_J"}
    assert "linked" in tube_loads.loads.table()
    png = load_chart(tube_loads.loads, tmp_path / "loads.png", "tube")
    assert png.stat().st_size > 5000


def test_the_control_plan_switches_the_linked_clutch_alone(tube, tube_loads):
    """Every subset evaluated: {linked} keeps the whole resistance, {loose} none of it, so
    the recommended set is {linked}; the all-ON and OFF energies are the evaluator's; the
    greedy search (exhaustive limit 0) finds the same set first."""
    from kgarment.evaluate.plan import make_plan, plan_markdown

    evaluator, design = tube
    plan = make_plan(evaluator, design)
    assert plan.exhaustive and len(plan.sets("pull")) == 3
    (g,) = tube_loads.loads.garment
    assert plan.all_on("pull").energy_J == pytest.approx(g.energy_on_J, rel=1e-6)
    assert plan.energy_off_J["pull"] == pytest.approx(g.energy_off_J, rel=1e-6)
    assert plan.get("pull", ["linked"]).fraction == pytest.approx(1.0, abs=0.05)
    assert abs(plan.get("pull", ["loose"]).fraction) < 0.03
    assert plan.smallest("pull").clutches == ("linked",) and plan.locks(plan.smallest("pull")) == []
    assert plan.get("pull", ["linked"]).tension_N["linked"] > 10
    assert "| pull | linked |" in plan_markdown(plan, "tube")
    greedy = make_plan(evaluator, design, exhaustive_up_to=0)
    assert not greedy.exhaustive and greedy.smallest("pull").clutches == ("linked",)


@pytest.fixture(scope="module")
def series_loads():
    """The tube of :func:`tube` with two 8 cm clutches one after the other on the same side
    and a third on the other side, on plain cloth.  Reinforced (2.6 cm bands): the held
    bottom ring to the first clutch's start, a bridge from its end to the second's start,
    and the second's end to the pulled top ring.  The two are in series on the one load
    path: either alone ON leaves the other a soft cloth link (share ~0), either alone OFF
    breaks the path (needed ~1); the third changes nothing either way."""
    tube = Tube(0.05, 0.0, 0.3, 48, 31)
    clutches = [tube.clutch("lower", 0.0, 0.06, 0.14, 0.01, 16), tube.clutch("upper", 0.0, 0.16, 0.24, 0.01, 16),
                tube.clutch("loose", np.pi, 0.11, 0.19, 0.01, 16)]
    model = build_model(tube.vertices, tube.faces, clutches, preset="paper")
    c = tube.vertices[tube.faces].mean(axis=1)
    z, band = c[:, 2], np.abs(np.arctan2(c[:, 1], c[:, 0])) < 0.26
    reinforced = band & ((z < 0.075) | ((z > 0.125) & (z < 0.175)) | (z > 0.225))
    setup = Case.build(model, {"pull": tube.motion("pull", 0.05, 0.0)}, "active", SolverOptions(tol=1e-5, max_iter=300))
    return Evaluator(setup).evaluate(np.where(reinforced, 1.0, 1e-3), loads=True).loads


def test_clutches_in_series_are_each_needed(series_loads):
    lower, upper, loose = (series_loads.get("pull", n) for n in ("lower", "upper", "loose"))
    for c in (lower, upper):
        assert abs(c.share) < 0.05 and c.needed == pytest.approx(1.0, abs=0.05) and c.loaded
        assert c.effect == c.needed
    assert abs(loose.share) < 0.03 and abs(loose.needed) < 0.03 and not loose.loaded
    assert series_loads.unloaded() == ["loose"]
    # the one path carries one force: the two clutches' tensions agree, far above the loose one's
    assert lower.tension_N == pytest.approx(upper.tension_N, rel=0.1)
    assert lower.tension_N > 10 * abs(loose.tension_N)
    assert "needed" in series_loads.table()


@pytest.mark.skipif(not __import__("torch").cuda.is_available(), reason="needs a CUDA device")
def test_loads_on_cuda_match_the_cpu(tube, tube_loads):
    """The same evaluation with the energies on the GPU (``--device cuda``): the per-clutch
    states start from the nearer of the all-ON and all-OFF equilibria, which must be
    evaluated on the state's device (a CPU tensor there failed on the H200, 2026-11-26)."""
    import dataclasses

    evaluator, design = tube
    s = evaluator.case
    gpu = Case.build(s.model, s.motions, "active", dataclasses.replace(s.solver, device="cuda"))
    loads = Evaluator(gpu).evaluate(design, loads=True).loads
    for name in ("linked", "loose"):
        a, b = tube_loads.loads.get("pull", name), loads.get("pull", name)
        assert b.share == pytest.approx(a.share, abs=0.01)
        assert b.tension_N == pytest.approx(a.tension_N, rel=0.01, abs=0.5)


def test_the_control_plan_keeps_a_lower_known_equilibrium(tube, tube_loads):
    """``known`` (the motion from rest's ends) competes by the evaluator's rule: an ON
    equilibrium given 10% below the two starts' is kept (the plan's all-ON energy is its
    energy and the plan says so); one 10% above leaves the plan as it is."""
    import dataclasses

    from kgarment.evaluate.plan import make_plan, plan_markdown

    evaluator, design = tube
    (g,) = tube_loads.loads.garment
    on = next(s.result for s in tube_loads.states if s.key == ("pull", "on"))

    def scaled(f):
        return dataclasses.replace(on, energy={k: f * v for k, v in on.energy.items()})

    lower = make_plan(evaluator, design, known={("pull", "on"): scaled(0.9)})
    assert lower.from_path == ("pull:on",) and "from rest" in plan_markdown(lower, "tube")
    assert lower.all_on("pull").energy_J == pytest.approx(0.9 * on.total_energy, rel=1e-9)
    higher = make_plan(evaluator, design, known={("pull", "on"): scaled(1.1)})
    assert higher.from_path == () and higher.to_json()["from_path"] == []
    assert higher.all_on("pull").energy_J == pytest.approx(g.energy_on_J, rel=1e-6)


def test_a_design_already_solved_in_a_state_is_not_solved_again(tube, monkeypatch):
    """The evaluator keeps its design equilibria by content (``kgarment evaluate --path``
    solves the target's equilibria for the force over the motion, then evaluates there):
    the same design in the same states costs no solve and gives the same numbers; another
    design or another activation is solved."""
    evaluator, design = tube
    ev = Evaluator(evaluator.case)
    first = ev.evaluate(design)
    calls = []
    real = Case.solve
    monkeypatch.setattr(Case, "solve", lambda self, *a, **k: calls.append(len(a[1])) or real(self, *a, **k))
    again = ev.evaluate(design)
    assert calls == []
    assert [s.energy for s in again.states] == [s.energy for s in first.states]
    assert [s.result.name for s in again.states] == [s.result.name for s in first.states]
    other = design.copy()
    other[np.flatnonzero(design < 0.5)[0]] = 1.0
    ev.evaluate(other)
    assert sum(calls) == 2 * len(first.states)  # two starts per state
    half = ev.activation_states([0.5, 0.0], label="half")
    ev.reference(half)  # the fully reinforced garment under the new activation first
    calls.clear()
    ev.equilibria(design, half)
    assert calls == [2]


def _cut_load_state(tube, tube_loads):
    """The tube's state with the linked clutch alone ON, solved from its nearer start to
    ``LOAD_TOL`` without a limit, and an evaluator whose solves stop one iteration short of
    that: (short evaluator, design, keyed, known ON / OFF equilibria, the unlimited solve)."""
    import dataclasses

    from kgarment.constants import LOAD_TOL
    from kgarment.evaluate.loads import nearer_start

    evaluator, design = tube
    known = {(s.motion, s.state): s.result for s in tube_loads.states}
    keyed = evaluator.activation_states([1.0, 0.0], ["pull"], "only linked")
    setup = evaluator.case
    start = nearer_start(setup, design, keyed[0][1], [known[("pull", "on")].x, known[("pull", "off")].x])
    free = dataclasses.replace(setup.solver, tol=LOAD_TOL, rescue_shifts=0)
    (full,) = setup.solve_now(design, [keyed[0][1]], [start], free)
    n = full.convergence.iterations
    assert full.converged and n >= 3  # a state that takes a few iterations from its start
    short = Evaluator(dataclasses.replace(setup, solver=dataclasses.replace(setup.solver, max_iter=n - 1)))
    return short, design, keyed, known, full


def test_a_load_state_that_needs_more_iterations_goes_on_from_where_it_stopped(tube, tube_loads, monkeypatch):
    """A one-clutch state cut off by the solver's iteration limit one iteration short of
    convergence goes on from where it stopped (a second round of as many), not from the
    evaluator's two starts, and ends at the equilibrium an unlimited solve reaches."""
    from kgarment.evaluate.loads import activation_equilibria

    short, design, keyed, known, full = _cut_load_state(tube, tube_loads)
    monkeypatch.setattr(Evaluator, "equilibria", lambda *a, **k: pytest.fail("fell back to the two starts"))
    (r,) = activation_equilibria(short, design, keyed, known).values()
    assert r.converged
    assert r.total_energy == pytest.approx(full.total_energy, rel=1e-6)


def test_a_load_state_still_sliding_after_going_on_is_switched_on_in_steps(tube, tube_loads, monkeypatch):
    """A one-clutch state that has converged neither from its start nor going on from where
    it stopped (here: ``go_on`` hands back where it stopped, a slide that has not finished) is
    switched on in steps from the motion's OFF equilibrium at ``LOAD_TOL``, not solved through
    the evaluator's two starts (which would first solve the fully reinforced garment in its
    activation).  It ends at an equilibrium (checked independently of the solver) within 1% of
    the one an unlimited solve from the nearer start reaches: the state has two, 0.3% apart in
    energy, and the path through the steps reaches the higher one (at 1e-6 as at 1e-3)."""
    import torch

    from kgarment.constants import LOAD_TOL
    from kgarment.evaluate.loads import activation_equilibria
    from kgarment.sim.solve import prepare_state

    short, design, keyed, known, full = _cut_load_state(tube, tube_loads)
    monkeypatch.setattr(Case, "go_on", lambda self, design, states, stopped, options=None: list(stopped))
    monkeypatch.setattr(Evaluator, "equilibria", lambda *a, **k: pytest.fail("fell back to the two starts"))
    (r,) = activation_equilibria(short, design, keyed, known).values()
    assert r.converged and r.convergence.tolerance == LOAD_TOL
    prob = prepare_state(short.case.model, design, keyed[0][1], short.case.solver)
    _, grad, _ = prob.evaluate(torch.as_tensor(r.x), order=1)
    assert prob.residual(grad) <= LOAD_TOL
    assert r.total_energy == pytest.approx(full.total_energy, rel=1e-2)


def test_a_state_converged_from_neither_start_goes_on_from_the_nearer_end(tube):
    """The evaluator's two starts both cut off one iteration short of convergence: the state
    goes on from the end nearer convergence and reaches the equilibrium the unlimited solves
    reach (the tube has one), instead of being reported unconverged."""
    import dataclasses

    from kgarment.case.starts import solve_two_starts

    evaluator, design = tube
    setup = evaluator.case
    keyed = [(k, s) for k, s in evaluator.keyed() if k[1] == "off"]
    (ref,) = evaluator.reference(keyed)
    free = dataclasses.replace(setup.solver, rescue_shifts=0)
    (a,), (b,) = solve_two_starts(setup, design, [keyed[0][1]], [ref.x], options=free)
    n = min(a.convergence.iterations, b.convergence.iterations)
    assert a.converged and b.converged and n >= 3
    assert a.total_energy == pytest.approx(b.total_energy, rel=1e-6)
    short = Evaluator(dataclasses.replace(setup, solver=dataclasses.replace(free, max_iter=n - 1)))
    (cut,), (cut2,) = solve_two_starts(short.case, design, [keyed[0][1]], [ref.x])
    assert not cut.converged and not cut2.converged  # what the evaluator had before going on
    (e,) = short.solve_design(design, keyed, starts=[ref.x])
    assert e.result.converged
    assert e.result.total_energy == pytest.approx(a.total_energy, rel=1e-6)
