"""The selective sleeve in the reproduction: its clutches, its all-ON comparison, its target."""

from __future__ import annotations

import json

import pytest
from cli_runner import run_cli


def _plan(rows):
    """A clutch-set table as kgarment plan writes it: rows (motion, clutches, resistance J)."""
    return {"clutches": ["a", "b"], "keep": 0.9, "motions": {},
            "sets": [{"motion": m, "clutches": c, "resistance_J": r, "fraction": None} for m, c, r in rows]}


def _exp(name, plan, rho, activation=None):
    return {"name": name, "group": "sleeve", "multi": True, "motions": ["flex", "ext"], "plan": plan,
            "activation": activation or {}, "evaluations": {"ours": {"rho": {m: {"on": v, "off": 0.1}
                                                                           for m, v in rho.items()}}}}


def test_the_selective_target_from_the_clutch_set_tables():
    """Own set resistance against the other set's and the all-ON design's (numbers chosen:
    flexion 4 J own, 1 J from extension's set (25%), all-ON design 4.5 J (89%))."""
    from kgarment.reproduce.targets import selective_targets

    base = _exp("sleeve_two_motions", _plan([("flex", ["a", "b"], 4.5), ("ext", ["a", "b"], 10.0)]),
                {"flex": 1.2, "ext": 1.5})
    sel = _exp("sleeve_selective", _plan([("flex", ["a"], 4.0), ("flex", ["b"], 1.0), ("ext", ["b"], 9.0),
                                          ("ext", ["a"], 0.5)]), {"flex": 1.1, "ext": 1.3},
               {"flex": {"a": 1.0}, "ext": {"b": 1.0}})
    (t,) = selective_targets({"sleeve_two_motions": base, "sleeve_selective": sel})
    assert t.ok and "flex: rho ON 1.10, other sets 25% of its own, 89% of the all-ON design" in t.detail
    sel["plan"]["sets"][1]["resistance_J"] = 2.5  # extension's clutch now stores 62% of flexion's own: a lock
    (t,) = selective_targets({"sleeve_two_motions": base, "sleeve_selective": sel})
    assert not t.ok and "other sets 62% of its own" in t.detail
    sel["clutch_model"] = "locked"  # a band locks where a cable is slack: the line says which was simulated
    (t,) = selective_targets({"sleeve_two_motions": base, "sleeve_selective": sel})
    assert t.detail.startswith("sleeve_selective (locked clutches): ")
    assert selective_targets({"sleeve_two_motions": base}) == []  # no activation sets, no target
    # the experiment's own all-ON design (the same clutches) is the comparison where it has one
    sel["plan"]["sets"][1]["resistance_J"] = 1.0
    sel["plan_all_on"] = _plan([("flex", ["a", "b"], 8.0), ("ext", ["a", "b"], 10.0)])
    (t,) = selective_targets({"sleeve_two_motions": base, "sleeve_selective": sel})
    assert not t.ok and "flex: rho ON 1.10, other sets 25% of its own, 50% of the all-ON design" in t.detail


def test_the_reproduction_keeps_the_papers_clutches_in_the_papers_experiments():
    """A paper's experiment whose example names another clutch model is made with the
    paper's locked clutches and stiff strips unless told a clutch model or holding force;
    the selective sleeve, ours and not the paper's, keeps its example's buckling cables."""
    import dataclasses

    from kgarment.problem import example_path, load_problem
    from kgarment.reproduce.catalog import BY_NAME, RESOLUTIONS
    from kgarment.reproduce.experiments import experiment_problem

    exp, res = BY_NAME["sleeve_selective"], RESOLUTIONS["tiny"]
    example = load_problem(example_path(exp.name)).clutch_spec().hardware
    assert example.model == "cable" and example.buckle and not exp.papers_model
    ours = experiment_problem(exp, res).clutch_spec().hardware
    assert ours == example  # the holding force included
    paper = experiment_problem(dataclasses.replace(exp, papers_model=True), res).clutch_spec().hardware
    assert paper.model == "locked" and not paper.buckle
    as_paper = dataclasses.replace(exp, papers_model=True)
    assert experiment_problem(as_paper, res, overrides={"clutch_model": "cable"}).clutch_spec().hardware.model == "cable"
    assert experiment_problem(as_paper, res, overrides={"holding_force": 50.0}).clutch_spec().hardware.model == "cable"
    assert experiment_problem(exp, res, overrides={"clutch_model": "locked"}).clutch_spec().hardware.model == "locked"
    assert all(e.papers_model for e in BY_NAME.values() if e.name != "sleeve_selective")


def test_the_all_on_problem_switches_every_clutch_on_in_every_motion():
    from kgarment.case.setup import activation_vectors
    from kgarment.reproduce.catalog import BY_NAME, RESOLUTIONS
    from kgarment.reproduce.experiments import all_on_problem, experiment_problem

    sel = experiment_problem(BY_NAME["sleeve_selective"], RESOLUTIONS["tiny"])
    names = ["elbow_outer.R", "elbow_inner.R"]
    assert sel.activation and sel.design.lockout > 0
    own = activation_vectors(sel, names)
    assert {m: list(v) for m, v in own.items()} == {"arm_flexion.right": [1.0, 0.0], "arm_extension.right": [0.0, 1.0]}
    every = all_on_problem(sel)
    assert every.activation == () and every.design.lockout == 0.0
    assert all(list(v) == [1.0, 1.0] for v in activation_vectors(every, names).values())
    assert every.clutch_spec() == sel.clutch_spec() and every.design.beso == sel.design.beso


def test_the_report_names_the_all_on_comparison():
    """Every clutch ON in the all-ON design against our own set, per motion (numbers chosen)."""
    from kgarment.reproduce.report import all_on_lines

    e = _exp("sleeve_selective", _plan([("flex", ["a"], 4.0), ("ext", ["b"], 9.0)]), {"flex": 1.1, "ext": 1.3},
             {"flex": {"a": 1.0}, "ext": {"b": 1.0}})
    e["plan"]["motions"] = {"flex": {}, "ext": {}}
    assert all_on_lines(e) == []  # no all-ON design: nothing said
    e["plan_all_on"] = _plan([("flex", ["a", "b"], 5.0), ("ext", ["b", "a"], 12.0)])
    e["all_on_run"] = {"reported_iteration": 7}
    (_, line, _) = all_on_lines(e)
    assert "iteration 7" in line
    assert "flex 5 J (ours with a: 4 J, 80%)" in line and "ext 12 J (ours with b: 9 J, 75%)" in line


@pytest.mark.timeout(900)
def test_reproduce_tiny_selective_sleeve(tmp_path, anny_body):
    """The selective sleeve end to end at the tiny resolution: made with its example's
    cables, its all-ON design made with the same clutches, both clutch-set tables, and the
    selective target computed from them."""
    rc, _, err = run_cli(["-q", "reproduce", "--resolution", "tiny", "--experiments", "sleeve_selective",
                            "--out", "rep"], tmp_path)
    assert rc == 0, err
    rep = tmp_path / "rep"
    e = json.loads((rep / "data.json").read_text())["experiments"]["sleeve_selective"]
    assert e["clutch_model"] == "cable" and e["clutch_buckle"]
    assert (rep / "runs" / "sleeve_selective-all-on" / "metrics.json").is_file()
    assert e["all_on_run"]["iterations"] == 3
    every = sorted(e["plan_all_on"]["clutches"])
    assert every == sorted(e["plan"]["clutches"]) == ["elbow_inner.R", "elbow_outer.R"]
    for plan in (e["plan"], e["plan_all_on"]):  # every subset in every motion
        assert sorted((r["motion"], tuple(sorted(r["clutches"]))) for r in plan["sets"]) == sorted(
            (m, c) for m in e["motions"] for c in (("elbow_inner.R",), ("elbow_outer.R",), tuple(every)))
    summary = json.loads((rep / "results.json").read_text())
    assert "selective" in summary["targets"]
    md = (rep / "report.md").read_text()
    line = next(x for x in md.splitlines() if x.startswith("- `selective`"))
    assert "sleeve_selective (cable clutches, skin friction 0.4)" in line
    assert e["skin_friction"] == 0.4 and ", skin friction 0.4 (README" in md
    for m, own in e["activation"].items():  # the target's share is the two tables' ratio
        mine = next(r["resistance_J"] for r in e["plan"]["sets"] if r["motion"] == m and r["clutches"] == list(own))
        theirs = next(r["resistance_J"] for r in e["plan_all_on"]["sets"]
                      if r["motion"] == m and sorted(r["clutches"]) == every)
        assert f"{100 * mine / theirs:.0f}% of the all-ON design" in line
    assert "The all-ON design (the same problem designed with every clutch ON" in md
    assert (rep / e["images"]["all_on"]).is_file()
