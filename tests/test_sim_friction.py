"""Skin-garment friction (sim.friction): derivatives, the Coulomb law, and the capstan
equation for a band pulled round a cylinder."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from kgarment.constants import X_MIN
from kgarment.sim import Motion, SimState, SolverOptions, build_model, solve_states
from kgarment.sim.friction import friction, normal_forces
from kgarment.sim.materials import PAPER
from kgarment.sim.synthetic import cylinder_body


def _random_slips(seed=0, p=60, scale=2e-3):
    g = torch.Generator().manual_seed(seed)
    x = torch.randn(p, 3, generator=g, dtype=torch.float64) * scale
    anchor = torch.randn(p, 3, generator=g, dtype=torch.float64) * scale * 0.1
    n = torch.randn(p, 3, generator=g, dtype=torch.float64)
    n = n / n.norm(dim=1, keepdim=True)
    bound = torch.rand(p, generator=g, dtype=torch.float64) + 0.1
    return x, anchor, n, bound


def test_friction_gradient_and_hessian_match_finite_differences():
    eps = 2e-3
    x, a, n, b = _random_slips()  # slips on both sides of eps
    _, g, H = friction(x, a, n, b, eps, order=2)
    h = 1e-8
    for k in range(3):
        d = torch.zeros_like(x)
        d[:, k] = h
        ep, gp, _ = friction(x + d, a, n, b, eps, order=1)
        em, gm, _ = friction(x - d, a, n, b, eps, order=1)
        assert torch.allclose((ep - em) / (2 * h), g[:, k], rtol=1e-6, atol=1e-9 * float(g.abs().max()))
        assert torch.allclose((gp - gm) / (2 * h), H[:, :, k], rtol=1e-5, atol=1e-6 * float(H.abs().max()))
    # positive semi-definite everywhere (no projection needed), and blind to the normal
    assert float(torch.linalg.eigvalsh(H).min()) > -1e-9 * float(H.abs().max())
    assert torch.allclose(torch.einsum("pij,pj->pi", H, n), torch.zeros_like(n), atol=1e-9 * float(H.abs().max()))


def test_friction_is_coulomb_beyond_the_slip_and_continuous_at_it():
    eps = 3e-3
    x, a, n, b = _random_slips(seed=1, scale=2e-3)
    d = x - a
    u = d - (d * n).sum(1, keepdim=True) * n
    y = u.norm(dim=1)
    _, g, _ = friction(x, a, n, b, eps, order=1)
    slide = y > eps
    assert slide.sum() > 10 and (~slide).sum() > 0
    # sliding: the force has the bound's magnitude, lies in the tangent plane, opposes the slip
    assert torch.allclose(g.norm(dim=1)[slide], b[slide], rtol=1e-12)
    assert torch.allclose((g * n).sum(1), torch.zeros_like(b), atol=1e-12)
    assert bool(((g * u).sum(1)[slide] > 0).all())
    # sticking: less than the bound, growing to it at y = eps
    assert bool((g.norm(dim=1)[~slide] < b[~slide]).all())
    tangent = u / y[:, None]
    for s in (eps * (1 - 1e-9), eps * (1 + 1e-9)):
        _, gs, _ = friction(a + s * tangent, a, n, b, eps, order=1)
        assert torch.allclose(gs.norm(dim=1), b, rtol=1e-6)


def test_normal_forces_push_into_the_body_only_near_it():
    n = np.array([[0.0, 0, 1], [0, 0, 1], [0, 0, 1]])
    g = np.array([[1.0, 2, 3], [0, 0, -2], [0, 0, 5]])  # dE/dx: into the body, away, into
    f = np.array([0.0, -1e-4, 0.01])  # on it, inside, 1 cm off it
    assert np.allclose(normal_forces(g, n, f, near=1e-3), [3.0, 0.0, 0.0])


def _band(radius, width, n_phi, n_z):
    """An open band over half a cylinder (phi in [0, pi], z in [0, width]): vertices, faces,
    the vertex grid (n_phi + 1, n_z + 1) of indices."""
    phi = np.linspace(0.0, np.pi, n_phi + 1)
    z = np.linspace(0.0, width, n_z + 1)
    P, Z = np.meshgrid(phi, z, indexing="ij")
    v = np.stack([radius * np.cos(P), radius * np.sin(P), Z], -1).reshape(-1, 3)
    idx = np.arange(v.shape[0]).reshape(n_phi + 1, n_z + 1)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return v, faces, idx


def _pulled_band(R: float, w: float = 0.01):
    """The band of :func:`_band` (48 x 2 cells) on a cylinder of radius R: (vertices,
    faces, the vertex grid, pull(name, by) -> the sim Motion with the end at phi = 0 held
    and the one at phi = pi pulled ``by`` metres along its tangent)."""
    v, faces, idx = _band(R, w, n_phi=48, n_z=2)
    held = np.arange(len(faces))[np.isin(faces, idx[:2].ravel()).all(1)]
    pulled = np.arange(len(faces))[np.isin(faces, idx[-2:].ravel()).all(1)]
    attach = np.concatenate([held, pulled])
    bv, bn, bf = cylinder_body(R, -0.05, 0.06, 180, 12)

    def pull(name: str, by: float):
        targets = v[faces[attach]].mean(1)
        targets[len(held):] += [0.0, -by, 0.0]  # at phi = pi the tangent (towards larger phi) is -y
        return Motion.create(name, v, bv, bn, attach, targets, bf, garment_faces=faces)

    return v, faces, idx, pull


def _uniaxial_tension(stretch, mu, lam):
    """dW/dlambda of the relaxed (uniaxial) neo-Hookean membrane (docs/method/index.md, "Energies"):
    C = diag(l^2, 1/l), J = sqrt(l), W = mu/2 (l^2 + 1/l - 2) - mu ln J + lam/2 (ln J)^2."""
    s = stretch
    return mu / 2 * (2 * s - 1 / s**2) - mu / (2 * s) + lam / 4 * np.log(s) / s


@pytest.mark.parametrize("mu", [0.0, 0.3])
def test_a_band_pulled_round_a_cylinder_follows_the_capstan_equation(mu):
    """A cloth band wrapped half round a cylinder (radius 5 cm), held at one end and pulled
    2 cm along the tangent at the other: where it slides, its tension falls towards the held
    end as exp(-mu phi) over the angle it wraps (the capstan equation: pressure = tension /
    radius); frictionless it is the same everywhere."""
    R = 0.05
    v, faces, idx, pull = _pulled_band(R)
    motion = pull("pull", 0.02)
    model = build_model(v, faces, preset="paper", friction=mu)
    model = dataclasses.replace(model, friction_slip=2e-5)  # a stiff skin: sliding where the band moves
    state = SimState.create(motion, (), name="pull")
    opts = SolverOptions(tol=1e-7, max_iter=400, friction_lags=12)
    (res,) = solve_states(model, np.full(len(faces), X_MIN), [state], options=opts)
    assert res.converged
    x = res.x
    mid = idx[:, 1]  # the band's centre line, phi = 0 .. pi
    seg = np.linalg.norm(x[mid[1:]] - x[mid[:-1]], axis=1) / (R * np.pi / 48)
    m_lame = PAPER.young_cloth / (2 * (1 + PAPER.poisson))
    l_lame = PAPER.young_cloth * PAPER.poisson / (1 - PAPER.poisson**2)
    tension = _uniaxial_tension(seg, m_lame, l_lame)  # N per metre of rest width
    c = 0.5 * (x[mid[1:]] + x[mid[:-1]])
    phi = np.unwrap(np.arctan2(c[:, 1], c[:, 0]))  # where the segments are now (stretched round)
    a, b = np.argmin(np.abs(phi - np.pi / 2)), np.argmin(np.abs(phi - 0.8 * np.pi))
    assert tension[b] > 0
    assert tension[a] / tension[b] == pytest.approx(np.exp(-mu * (phi[b] - phi[a])), rel=0.02)


def test_skin_friction_in_the_problem_file():
    from kgarment.errors import KgarmentError
    from kgarment.problem import override
    from kgarment.problem.parse import parse_problem, problem_to_dict

    p = parse_problem({"materials": {"skin_friction": 0.4}})
    assert p.materials.skin_friction == 0.4
    assert problem_to_dict(p)["materials"]["skin_friction"] == 0.4
    # a problem without it is written as before (its run files and hashes unchanged)
    assert "skin_friction" not in problem_to_dict(parse_problem({}))["materials"]
    assert override(parse_problem({}), friction=0.6).materials.skin_friction == 0.6
    for bad in (-0.1, 3.0, "high"):
        with pytest.raises(KgarmentError, match=r"\[materials\] skin_friction"):
            parse_problem({"materials": {"skin_friction": bad}})


def test_a_strip_slides_freely_along_itself_and_with_friction_across():
    """With ``along`` (a strip's direction) the potential ignores the slip along it: the
    derivatives still match finite differences, the Hessian annihilates the normal and the
    strip's direction, and a vertex sliding across it meets the full Coulomb force."""
    eps = 2e-3
    x, a, n, b = _random_slips(seed=2)
    g0 = torch.Generator().manual_seed(3)
    t = torch.randn(n.shape, generator=g0, dtype=torch.float64)
    t = t - (t * n).sum(1, keepdim=True) * n
    t = t / t.norm(dim=1, keepdim=True)
    t[::4] = 0.0  # vertices on no strip
    _, g, H = friction(x, a, n, b, eps, order=2, along=t)
    h = 1e-8
    for k in range(3):
        d = torch.zeros_like(x)
        d[:, k] = h
        ep, gp, _ = friction(x + d, a, n, b, eps, order=1, along=t)
        em, gm, _ = friction(x - d, a, n, b, eps, order=1, along=t)
        assert torch.allclose((ep - em) / (2 * h), g[:, k], rtol=1e-6, atol=1e-9 * float(g.abs().max()))
        assert torch.allclose((gp - gm) / (2 * h), H[:, :, k], rtol=1e-5, atol=1e-6 * float(H.abs().max()))
    scale = float(H.abs().max())
    assert float(torch.linalg.eigvalsh(H).min()) > -1e-9 * scale
    assert torch.allclose(torch.einsum("pij,pj->pi", H, t), torch.zeros_like(t), atol=1e-9 * scale)
    # sliding 5 cm along the strip costs nothing more; 5 mm across it costs the Coulomb force
    e0, _, _ = friction(x, a, n, b, eps, along=t)
    e1, _, _ = friction(x + 0.05 * t, a, n, b, eps, along=t)
    assert torch.allclose(e1[t.norm(dim=1) > 0], e0[t.norm(dim=1) > 0], rtol=1e-12, atol=1e-15)
    across = torch.linalg.cross(n, t)
    on = t.norm(dim=1) > 0
    _, gs, _ = friction(a + 5e-3 * across, a, n, b, eps, order=1, along=t)
    assert torch.allclose(gs.norm(dim=1)[on], b[on], rtol=1e-12)


def test_a_taut_cable_round_the_body_presses_its_own_vertices_into_friction():
    """A cable clutch wrapped half round a cylinder and pulled taut (prestrain) presses on
    the body with its own vertices, not through the garment's: the friction bounds the lag
    gives its vertices add up to mu T theta (a string of tension T wrapped over theta presses
    with T / R per unit length), and each of its vertices slides freely round the hoop (its
    direction) but not along the tube's axis."""
    from kgarment.sim import clutch_tensions
    from kgarment.sim.serial import prepare_state
    from kgarment.sim.synthetic import Tube

    mu, R, theta = 0.4, 0.05, np.pi
    tube = Tube(R, 0.0, 0.2, 64, 21)
    clutch = tube.hoop("hoop", 0.1, 0.0, theta, 0.01, 32, prestrain=0.9)
    model = build_model(tube.vertices, tube.faces, [clutch], preset="reference", clutch_cable=True,
                        holding_force=[1e4], friction=0.0)
    state = SimState.create(tube.motion("rest", 0.0, 0.0), [1.0])
    design = np.ones(model.n_faces)
    (r,) = solve_states(model, design, [state], options=SolverOptions(tol=1e-7, max_iter=400))
    assert r.converged
    (tension,) = clutch_tensions(model, design, state, r.x)
    assert tension > 1.0
    with_mu = build_model(tube.vertices, tube.faces, [clutch], preset="reference", clutch_cable=True,
                          holding_force=[1e4], friction=mu)
    prob = prepare_state(with_mu, design, state)
    bound, normal, along = prob.friction_lag(torch.as_tensor(r.x))
    n = with_mu.n_garment
    # the cable's pressure: mu T times the angle its path turns (sim.cable: from the start
    # anchors' centroid through the centre line to the end anchors'), plus a few percent
    # from the strip's own guide membrane, stretched with it, and its ties to the garment
    xc = r.x[n:]
    path = np.concatenate([xc[clutch.anchors[:3]].mean(0)[None], xc[clutch.centerline[1:-1]],
                           xc[clutch.anchors[3:]].mean(0)[None]])
    u = np.diff(path, axis=0)
    u /= np.linalg.norm(u, axis=1)[:, None]
    turn = np.arccos(np.clip((u[1:] * u[:-1]).sum(1), -1.0, 1.0)).sum()
    assert turn == pytest.approx(theta, rel=0.1)
    assert mu * tension * turn <= bound[n:].sum() <= 1.1 * mu * tension * turn
    # the clutch's directions run round the hoop (across the axis, tangent to the body)
    on = np.linalg.norm(along[n:], axis=1) > 0
    assert on.all() and np.abs(along[n:, 2]).max() < 0.02  # within about a degree
    assert np.abs((along[n:] * normal[n:]).sum(1)).max() < 1e-9
    assert not np.linalg.norm(along[:n], axis=1).any()


def test_what_slipped_stays_slipped_where_friction_holds_the_frame_before():
    """The capstan band pulled 2 cm, then let back to 1 cm.  Anchored at the skin-tight
    garment (no memory) it is the band pulled 1 cm straight away: its tension falls from the
    pulled end as exp(-mu phi) everywhere it slid.  Held where the 2 cm pull left it (a
    motion's next frame: ``sim.held_after`` as ``SimState.anchor``), the cloth near the
    pulled end slides back, its tension now rising inwards as exp(mu phi); near the held
    end it sticks where it was, with the 2 cm pull's tension (Coulomb hysteresis).  Holding
    the 2 cm pose for another frame does not move it (no creep), where anchoring at the
    equilibrium itself lets the stuck cloth give way by the skin's give.  The anchor is part
    of the state's digest (``design.store``)."""
    from kgarment.case.store import state_digest
    from kgarment.sim import held_after

    R = 0.05
    v, faces, idx, pull = _pulled_band(R)
    model = dataclasses.replace(build_model(v, faces, preset="paper", friction=0.3), friction_slip=2e-5)
    design = np.full(len(faces), X_MIN)
    opts = SolverOptions(tol=1e-7, max_iter=400, friction_lags=12)
    first = SimState.create(pull("2 cm", 0.02), (), name="2 cm")
    (two,) = solve_states(model, design, [first], options=opts)
    assert two.converged
    anchor = held_after(model, design, first, two.x, opts)
    back = pull("1 cm", 0.01)
    fresh = SimState.create(back, (), name="1 cm")
    kept_state = SimState.create(back, (), name="1 cm after 2", anchor=anchor)
    forgot, kept = solve_states(model, design, [fresh, kept_state], options=opts, warm_start=[two.x] * 2)
    assert forgot.converged and kept.converged
    mid = idx[:, 1]
    m_lame = PAPER.young_cloth / (2 * (1 + PAPER.poisson))
    l_lame = PAPER.young_cloth * PAPER.poisson / (1 - PAPER.poisson**2)

    def tension(x):
        return _uniaxial_tension(np.linalg.norm(x[mid[1:]] - x[mid[:-1]], axis=1) / (R * np.pi / 48), m_lame, l_lame)

    t2, t_forgot, t_kept = tension(two.x), tension(forgot.x), tension(kept.x)
    inner = slice(2, 10)  # phi about 0.05 pi to 0.2 pi, near the held end: slid under 2 cm, not back
    assert t2[inner].min() > 0 and t_kept[inner] == pytest.approx(t2[inner], rel=0.03)
    assert (t_forgot[inner] < 0.8 * t2[inner]).all()
    # towards the pulled end it slid back: friction reversed, the tension rising inwards
    c = 0.5 * (kept.x[mid[1:]] + kept.x[mid[:-1]])
    phi = np.unwrap(np.arctan2(c[:, 1], c[:, 0]))
    a, b = 20, 40
    assert t_kept[a] / t_kept[b] == pytest.approx(np.exp(0.3 * (phi[b] - phi[a])), rel=0.02)
    assert kept.garment_energy.sum() < two.garment_energy.sum()  # J in the cloth: unloading
    assert state_digest(kept_state) != state_digest(fresh)
    assert state_digest(SimState.create(back, (), name="other")) == state_digest(fresh)
    with pytest.raises(ValueError, match="friction anchor"):
        solve_states(model, design, [SimState.create(back, (), anchor=two.x[:5])], options=opts)


def test_a_pose_held_frame_after_frame_does_not_creep():
    """The capstan band pulled 2 cm and held there for 6 more frames, each anchored where
    the frame before left it (``sim.held_after``): it stays (its cloth's energy within
    0.5%), where anchoring each frame at the equilibrium before lets the stuck cloth give
    way by the skin's give every frame, so that the band creeps and its energy keeps
    falling."""
    from kgarment.sim import held_after

    v, faces, _, pull = _pulled_band(0.05)
    motion = pull("2 cm", 0.02)
    model = dataclasses.replace(build_model(v, faces, preset="paper", friction=0.3), friction_slip=1e-3)
    design = np.full(len(faces), X_MIN)
    opts = SolverOptions(tol=1e-7, max_iter=400, friction_lags=12)
    state = SimState.create(motion, (), name="frame 0")
    (r,) = solve_states(model, design, [state], options=opts)
    energy = {"held": [r.garment_energy.sum()], "at x": [r.garment_energy.sum()]}
    for how, series in energy.items():
        st, x = state, r.x
        for k in range(1, 7):
            anchor = held_after(model, design, st, x, opts) if how == "held" else x
            st = SimState.create(motion, (), name=f"frame {k}", anchor=anchor)
            (res,) = solve_states(model, design, [st], options=opts, warm_start=[x])
            assert res.converged
            x = res.x
            series.append(res.garment_energy.sum())
    held_e, crept = np.array(energy["held"]), np.array(energy["at x"])
    assert np.abs(held_e / held_e[0] - 1).max() < 5e-3
    assert (np.diff(crept) < 0).all() and crept[-1] < 0.95 * crept[0]


def test_the_return_map_keeps_what_stuck_and_moves_what_slid():
    """``sim.friction.slid_anchor``: an offset within the give is kept; one beyond it is cut
    to the give in its direction; the normal and strip components are free."""
    from kgarment.sim.friction import slid_anchor

    eps = 1e-3
    n = np.array([[0.0, 0, 1]] * 3)
    t = np.array([[0.0, 0, 0], [0, 0, 0], [1.0, 0, 0]])  # the third vertex on a strip along x
    anchor = np.zeros((3, 3))
    x = np.array([[5e-4, 0, 7e-3], [3e-3, 4e-3, 0], [9e-3, 2e-3, 0]])
    got = slid_anchor(x, anchor, n, t, eps)
    assert np.allclose(got[0], [0.0, 0, 7e-3])  # stuck: the tangential offset kept
    assert np.allclose(x[1] - got[1], [0.6e-3, 0.8e-3, 0])  # slid 5 mm: held 1 mm behind
    assert np.allclose(x[2] - got[2], [0.0, 1e-3, 0])  # across its strip 2 mm: held 1 mm behind
