"""The example problems (one per experiment of the paper), shipped inside the package so
an installed ``kgarment examples`` finds them outside a source checkout."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from kgarment.errors import unknown


def examples_dir() -> Path:
    """The folder holding the example problem files."""
    return Path(str(resources.files("kgarment") / "examples"))


def example_files() -> list[Path]:
    """Every example problem file, sorted by name."""
    return sorted(examples_dir().glob("*.toml"))


def example_path(name: str) -> Path:
    """The example problem file ``name`` (its stem, e.g. "shirt_three_motions")."""
    path = examples_dir() / f"{name}.toml"
    if not path.is_file():
        raise unknown("example", name, [p.stem for p in example_files()])
    return path


def example_title(path: Path) -> str:
    """The first line of an example file (its comment), without the '#'."""
    return path.read_text().splitlines()[0].lstrip("# ")
