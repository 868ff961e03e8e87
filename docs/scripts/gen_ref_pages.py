"""Write one API reference page per module of src/kgarment (run by mkdocs-gen-files).

The pages follow whatever modules exist, so the reference needs no edit when modules are
added, moved or removed.  Each page is one ``::: kgarment.x.y`` directive for
mkdocstrings-python, which reads the source statically (griffe: nothing is imported).
"""

from pathlib import Path

import mkdocs_gen_files

ROOT = Path(__file__).resolve().parents[2]
SRC = ROOT / "src"

nav = mkdocs_gen_files.Nav()
for path in sorted((SRC / "kgarment").rglob("*.py")):
    parts = tuple(path.relative_to(SRC).with_suffix("").parts)
    if parts[-1] == "__main__" or any(p.startswith("_") and p != "__init__" for p in parts):
        continue
    doc = Path("api", *parts).with_suffix(".md")
    if parts[-1] == "__init__":
        parts = parts[:-1]
        doc = doc.with_name("index.md")
    nav[parts] = doc.relative_to("api").as_posix()
    with mkdocs_gen_files.open(doc, "w") as fd:
        fd.write(f"# `{'.'.join(parts)}`\n\n::: {'.'.join(parts)}\n")
    mkdocs_gen_files.set_edit_path(doc, path.relative_to(ROOT))

with mkdocs_gen_files.open("api/SUMMARY.md", "w") as fd:
    fd.writelines(nav.build_literate_nav())
