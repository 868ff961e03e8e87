"""``[clutches] buckle``: clutch strips that take no compression (sim.model, sim.slip)."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from test_sim_slip import _deformed, _sliders, check_slider_derivatives

from kgarment.errors import KgarmentError
from kgarment.sim import SimState, build_model
from kgarment.sim.materials import REFERENCE, lame_plane_stress
from kgarment.sim.serial import prepare_state
from kgarment.sim.slip import SMOOTH, SliderSet, slider_energy, slider_law
from kgarment.sim.synthetic import Tube


def test_a_pulling_slider_law_is_the_law_in_tension_and_nothing_in_compression():
    k, q = torch.tensor(1e4, dtype=torch.float64), torch.tensor(300.0, dtype=torch.float64)
    e_h = float(q / k)
    e = torch.linspace(-4 * e_h, 4 * e_h, 2001, dtype=torch.float64)
    psi, dpsi, ddpsi = slider_law(e, k, q, pull_only=True)
    full = slider_law(e, k, q)
    pull, push = e > 0, e < 0
    for a, b in zip((psi, dpsi, ddpsi), full):
        assert torch.equal(a[pull], b[pull]) and bool((a[push] == 0).all())
    de = 1e-7
    p1, d1, _ = slider_law(e + de, k, q, pull_only=True)
    p0, d0, _ = slider_law(e - de, k, q, pull_only=True)
    assert torch.allclose((p1 - p0) / (2 * de), dpsi, rtol=1e-6, atol=1e-6 * float(q))  # C1 through 0 too
    kink = ((e.abs() - (1 + SMOOTH) * e_h).abs() < 2 * de) | (e.abs() < 2 * de)
    assert torch.allclose(((d1 - d0) / (2 * de))[~kink], ddpsi[~kink], rtol=1e-5, atol=1e-5 * float(k))


def test_pulling_sliders_derivatives_match_finite_differences():
    """Half the sliders shortened, half stretched: the shortened store nothing, and the
    gradient and Hessian of the rest match finite differences."""
    rng = np.random.default_rng(7)
    rest, s0 = _sliders(rng)
    s = SliderSet(**{f: getattr(s0, f) for f in ("element", "tri", "coef", "area", "k", "cap")}, pull_only=True)
    e_h = (s.cap / s.k).numpy()
    sign = np.where(np.arange(len(e_h)) % 2 == 0, -1.0, 1.0)
    x = torch.as_tensor(_deformed(rest, s, rng, sign * e_h * rng.uniform(0.1, 3.0, len(e_h))))
    e, g, H = slider_energy(x, s, order=2, project=False)
    assert bool((e[sign < 0] == 0).all()) and bool((e[sign > 0] > 0).all())
    check_slider_derivatives(x, s, g, H, rng.choice(len(rest), 8, replace=False))


def _clutch_energy(strain: float, buckle: bool) -> tuple[float, float]:
    """A 14 x 1 cm clutch ON along a tube, at the start of a motion that moves the top ring
    by ``strain`` of the tube's length (the garment, and with it the strip, strained
    uniformly along the tube: F = diag(1, 1 + strain) in each strip element's frame).
    Returns (the strip elements' membrane energy J, what the neo-Hookean W of that F gives)."""
    tube = Tube(0.05, 0.0, 0.3, 48, 31)
    clutch = tube.clutch("c0", 0.3, 0.08, 0.22, 0.01, 28)
    model = build_model(tube.vertices, tube.faces, [clutch], preset="reference", clutch_buckle=buckle)
    state = SimState.create(tube.motion("m", strain, 0.0), [1.0])
    prob = prepare_state(model, np.ones(model.n_faces), state)
    _, per_element = prob.terms(torch.as_tensor(prob.initial_positions()))
    mu, lam = lame_plane_stress(REFERENCE.young_clutch_on, REFERENCE.poisson)
    s = 1.0 + strain
    w = mu / 2 * (s * s - 1) - mu * np.log(s) + lam / 2 * np.log(s) ** 2
    strip = model.elements.area[model.n_faces:].sum() * REFERENCE.thick_clutch_on
    return float(per_element[model.n_faces:].sum()), float(w * strip)


@pytest.mark.parametrize("strain", [-0.02, 0.03])
def test_a_buckling_clutch_stores_nothing_when_shortened_and_the_same_when_pulled(strain):
    """Shortened by 2% along its length, the paper's ON clutch stores the neo-Hookean energy
    of that compression and a buckling one nothing; stretched by 3% (taut: the relaxation
    does not apply) both store the same."""
    paper, expected = _clutch_energy(strain, False)
    buckled, _ = _clutch_energy(strain, True)
    assert paper == pytest.approx(expected, rel=1e-9) and expected > 0
    if strain < 0:
        assert abs(buckled) <= 1e-9 * paper
    else:
        assert buckled == pytest.approx(paper, rel=1e-12)


def test_buckle_in_the_problem_file():
    from kgarment.problem import parse_problem, problem_to_dict

    p = parse_problem({"clutches": {"buckle": True}})
    assert p.clutch_spec().hardware.buckle and p.clutch_spec().layout == "shirt"
    assert problem_to_dict(p)["clutches"]["buckle"] is True
    assert parse_problem(problem_to_dict(p)).clutch_spec() == p.clutch_spec()
    assert "clutches" not in problem_to_dict(parse_problem({}))  # the paper's model: nothing written
    with pytest.raises(KgarmentError, match=r"\[clutches\] buckle = 'yes'; allowed: true, false"):
        parse_problem({"clutches": {"buckle": "yes"}})


def test_buckle_on_the_command_line():
    """``--buckle`` / ``--no-buckle`` override the file's [clutches] buckle and keep the rest
    of its hardware (clutch model, holding force), so any run can be judged both ways."""
    import argparse

    from kgarment.cli.common import add_clutch_model, overrides
    from kgarment.problem import override, parse_problem

    sp = argparse.ArgumentParser()
    add_clutch_model(sp)
    file = parse_problem({"clutches": {"model": "slip", "holding_force": 40.0}})
    assert sp.parse_args([]).buckle is None and override(file, buckle=None).clutch_spec() == file.clutch_spec()
    on = override(file, **{k: v for k, v in overrides(sp.parse_args(["--buckle"])).items() if k == "buckle"})
    hw = on.clutch_spec().hardware
    assert hw.buckle and hw.model == "slip" and hw.holding_force == (("*", 40.0),)
    off = override(on, buckle=sp.parse_args(["--no-buckle"]).buckle)
    assert not off.clutch_spec().hardware.buckle and off.clutch_spec().hardware.holding_force == (("*", 40.0),)


def test_the_reference_is_the_stabler_of_its_two_starts(anny_body):
    """rho's denominator, the fully reinforced garment ON, is solved from the skin-tight
    garment and from its OFF equilibrium (the clutches switched on in the garment as worn),
    and the lower-energy one is kept. With buckling strips the two differed on the main job's
    shirt in arms forward while the skin-tight start lay on the body's mesh (2026-11-26: 50.0 J
    against 39.8 J of total energy); with it on the contact surface (SIM_MODEL 2) they end
    within 0.1% (30.73 and 30.74 J)."""
    from kgarment.evaluate import Evaluator
    from kgarment.problem import example_path, load_problem, override

    p = override(load_problem(example_path("shirt_three_motions")), subdivision=0, motions=["arms_forward"])
    assert p.clutch_spec().hardware.buckle  # the example's strips
    ev = Evaluator.from_problem(p, body=anny_body)
    keyed = dict(ev.keyed())
    on, off = keyed[("arms_forward", "on")], keyed[("arms_forward", "off")]
    ref_on, ref_off = ev.reference([(("arms_forward", "on"), on), (("arms_forward", "off"), off)])
    full = np.ones(ev.n_faces)
    (skin,) = ev.case.solve(full, [on])
    (worn,) = ev.case.solve(full, [on], warm_start=[ref_off.x])
    assert skin.converged and worn.converged
    # no higher than either start's equilibrium (these solves stop at the design tolerance,
    # the reference at the evaluation's: 1e-3 of the energy covers the difference)
    assert ref_on.total_energy <= min(skin.total_energy, worn.total_energy) * (1 + 1e-3)
    # asked for the ON state alone (the studio, one state at a time), the same equilibrium
    (alone,) = Evaluator.from_problem(p, body=anny_body).reference([(("arms_forward", "on"), on)])
    assert alone.total_energy == pytest.approx(ref_on.total_energy, rel=1e-9)
