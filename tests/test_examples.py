"""Every example problem parses, validates and round-trips; its clutches build."""

from __future__ import annotations

import pytest

from kgarment.problem import (
    clutch_specs,
    example_files,
    load_problem,
    parse_problem,
    problem_to_dict,
)

EXAMPLES = example_files()


def test_there_is_an_example_per_experiment():
    names = {p.stem for p in EXAMPLES}
    assert {"arm_flexion", "arm_extension", "arms_forward", "arms_raise", "bend_forward",
            "sleeve_two_motions", "shirt_three_motions", "long_sleeve_five_motions"} <= names


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.stem)
def test_example_parses_and_round_trips(path, anny_body, tmp_path):
    p = load_problem(path)
    assert p.design.beso.target_area in (0.15, 0.20)
    specs = clutch_specs(p, anny_body)
    assert specs, "every experiment has clutches"
    from kgarment.clutch import save_clutches

    save_clutches(tmp_path / "c.toml", specs)
    again = parse_problem(problem_to_dict(p, tmp_path / "c.toml"), tmp_path)
    assert again.motions == p.motions and again.garment == p.garment and again.activation == p.activation
    assert again.design == p.design and again.solver == p.solver and again.materials == p.materials
    assert [s.name for s in clutch_specs(again, anny_body)] == [s.name for s in specs]
    from kgarment.case.setup import activation_vectors

    sets = activation_vectors(p, [s.name for s in specs])  # every set names clutches of the layout
    assert set(sets) == {m for m, _ in p.activation} and all(g.any() for g in sets.values())


@pytest.mark.parametrize("toml, message", [
    ("[design]\nobjective = 'maximal'\n", "objective = 'maximal'; allowed: active, passive, compliance"),
    ("[design]\ntarget_area = 1.5\n", "target_area = 1.5 is outside"),
    ("[design]\nwindow = 2.5\n", "must be an integer"),
    ("[materials]\npreset = 'steel'\n", "preset = 'steel'; allowed: paper, reference"),
    ("[solver]\nmethod = 'cg'\n", "method = 'cg'; allowed: newton, lbfgs"),
    ("[solver]\nevolution_tol = 2.0\n", "evolution_tol = 2.0 is outside"),
    ("[design]\nbudget = 0.2\n", "unknown field 'budget'"),
])
def test_bad_design_sections(toml, message):
    import tomllib

    from kgarment.errors import KgarmentError

    with pytest.raises(KgarmentError, match=message.replace("(", r"\(").replace(")", r"\)")):
        parse_problem(tomllib.loads(toml))


# shirt_selective runs the same code as sleeve_selective (activation sets, lockout) on the
# shirt's 12 states per iteration: its sets are checked above, its run left to the sleeve
# The same for the three-size shirt's 18 states (a minute and a half here): multi-body
# designs run end to end on the sleeve in test_design_wearers.py
RUN_EXAMPLES = [p for p in EXAMPLES if p.stem not in ("shirt_selective", "shirt_sizes")]


@pytest.mark.parametrize("path", RUN_EXAMPLES, ids=lambda p: p.stem)
def test_example_runs_at_the_smallest_size(path, anny_body, tmp_path, capsys):
    """Every example designs end to end at subdivision 0 for two iterations (the full
    garment, then one BESO update) from the command line, like a user's first try; the
    smallest also evaluates its final design (per-clutch loads; the others skip that, it
    is the same code and a minute for the long sleeve's 35 states)."""
    import json

    from kgarment.cli import main

    run = tmp_path / "run"
    skip = [] if path.stem == "arm_flexion" else ["--no-evaluation"]
    assert main(["design", str(path), "--subdivision", "0", "--max-iterations", "2", "--out", str(run), *skip]) == 0
    rows = json.loads((run / "metrics.json").read_text())
    p = load_problem(path)
    assert [r["iteration"] for r in rows] == [0, 1]
    assert rows[0]["area"] == pytest.approx(1.0) and rows[1]["area"] < 1.0
    keys = [f"{m}@{n}" for n in p.body.names for m in p.motions] or p.motions  # a size range: every wearer's
    for m in keys:  # rho of the fully reinforced garment is 1 by definition
        assert rows[0][f"rho[{m}:on]"] == pytest.approx(1.0) and rows[0][f"rho[{m}:off]"] == pytest.approx(1.0)
    assert (run / "final" / "design.png").is_file()
    assert (run / "final" / "evaluation.json").is_file() == (not skip)
    assert "2 iterations" in capsys.readouterr().out
