"""The manual builds: ``mkdocs build --strict`` (every link, page and anchor checked, the API
reference generated from the docstrings), and the problem file reference is what its
generator writes from the specs.  About 10 s (the build: 6 s on 2 cores)."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOC_PACKAGES = ("mkdocs", "material", "mkdocstrings_handlers.python", "mkdocs_gen_files", "mkdocs_literate_nav",
                "mkdocs_section_index")


def _installed(name: str) -> bool:
    try:
        return importlib.util.find_spec(name) is not None
    except ModuleNotFoundError:
        return False


def _reference_module():
    spec = importlib.util.spec_from_file_location("problem_reference", ROOT / "docs/scripts/problem_reference.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_problem_reference_is_up_to_date():
    """docs/reference/problem-file.md is generated from kgarment.problem.spec and the
    constants; a new or changed field needs ``python docs/scripts/problem_reference.py``."""
    ref = _reference_module()
    assert ref.PAGE.read_text() == ref.render(), (
        "docs/reference/problem-file.md is out of date: run .venv/bin/python docs/scripts/problem_reference.py")


def test_problem_reference_covers_every_field():
    """Every field of the problem's specs has a row (render fails on a field without a meaning)."""
    from kgarment.problem import spec as S

    text = _reference_module().render()
    for cls in (S.BesoParams, S.DesignSpec, S.SolverSpec, S.MaterialSpec, S.ClutchHardware, S.GarmentSpec):
        for f in cls.__dataclass_fields__:
            if f not in ("beso",):
                assert f"| `{f}` |" in text, f"{cls.__name__}.{f} missing from the problem file reference"


@pytest.mark.skipif(not all(map(_installed, DOC_PACKAGES)),
                    reason="the manual's packages are not installed (pip install -e '.[dev]')")
def test_manual_builds_strict(tmp_path):
    env = {**os.environ, "DISABLE_MKDOCS_2_WARNING": "true", "NO_MKDOCS_2_WARNING": "1"}
    proc = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    warnings = [line for line in proc.stderr.splitlines() if "WARNING" in line or "ERROR" in line]
    assert proc.returncode == 0, "mkdocs build --strict failed:\n" + "\n".join(warnings or proc.stderr.splitlines()[-30:])
    assert (tmp_path / "site/method/index.html").is_file()
    assert (tmp_path / "site/api/kgarment/sim/newton/index.html").is_file()


def test_docs_point_inside_the_repository():
    """The README and the manual never send a reader to the method's specification outside
    the repository: the method is docs/method/index.md."""
    files = [ROOT / "README.md", ROOT / "mkdocs.yml", *sorted((ROOT / "docs").rglob("*.md"))]
    bad = [str(f.relative_to(ROOT)) for f in files if "method.md" in f.read_text() or "../shared" in f.read_text()]
    assert not bad, f"references to a method.md outside the repository in {bad}"


def test_readme_is_short_and_its_commands_are_the_makefiles():
    readme = (ROOT / "README.md").read_text()
    assert len(readme.splitlines()) <= 300
    makefile = (ROOT / "Makefile").read_text()
    for target in ("demo", "test"):
        assert f"make {target}" in readme and f"\n{target}:" in makefile
