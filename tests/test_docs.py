"""The documentation holds what it promises: a README a newcomer reads in minutes, generated
tables that match the registries, links that resolve, and no reference to a document that is
not in the repository.

References: the README's size limit (12 KB) is the documentation's own rule; the generated page is
compared with what ``scripts/doc_tables.py`` renders from the registries now."""

from __future__ import annotations

import os
import re
import subprocess

import pytest
from pathlib import Path

from script_module import script

ROOT = Path(__file__).resolve().parent.parent

# a document outside the repository: the physics reference's sections, issue numbers, a sibling folder
OUTSIDE = re.compile(r"\bSPEC\b|SPEC\.md|STYLE\.md|\b[Ii]ssues? ?#?\d|\.\./shared|/work/shared")
# outputs rewritten whenever they are regenerated (their text comes from the configs and the code)
GENERATED = re.compile(r"^results/.*\.(parquet|config\.yaml|json|png)$")
LINK = re.compile(r"\]\(([^)#\s]*)(?:#([^)\s]*))?\)")
HEADING = re.compile(r"^#+ (.*)$", re.M)


def slug(heading: str) -> str:
    """The anchor GitHub gives a Markdown heading."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def tracked() -> list[str]:
    out = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True).stdout
    return [p for p in out.splitlines() if (ROOT / p).is_file()]


def test_readme_is_short():
    """A README a newcomer reads in five minutes: at most 12 KB, the rest in docs/."""
    size = (ROOT / "README.md").stat().st_size
    assert size <= 12 * 1024, f"README.md is {size} bytes; move detail into docs/"


def test_readme_keeps_the_two_setup_commands_ci_runs():
    """The README's test command is the one .ci/run executes, and the main-job command is there."""
    readme = (ROOT / "README.md").read_text()
    ci = (ROOT / ".ci" / "run").read_text()
    assert 'pip install -e ".[test,dask,formats,export]" && python -m pytest' in readme
    assert 'pip install -q -e ".[test,dask,formats,export]" && python -m pytest' in ci  # the same, quiet
    assert "pip install -e . && vetica sweep configs/dashpot.yaml" in readme


def test_generated_registry_tables_are_current():
    """docs/registries.md is what scripts/doc_tables.py renders from the registries now."""
    mod = script("doc_tables")
    page = (ROOT / "docs" / "registries.md").read_text()
    assert page == mod.render(), "docs/registries.md is stale: run python scripts/doc_tables.py"


def _script(name: str):
    return script(name)


@pytest.mark.parametrize("path, name", [("docs/commands/README.md", "commands"), ("README.md", "commands"),
                                        ("docs/extending.md", "layout")])  # fmt: skip
def test_generated_doc_sections_are_current(path, name):
    """The commands tables are what the typer app has now (every command, its arguments, its
    options, its help), and the layout section of docs/extending.md is the layers
    tests/test_layering.py checks: scripts/doc_sections.py renders both."""
    mod = _script("doc_sections")
    text = (ROOT / path).read_text()
    assert text == mod.rendered(path, name, text), f"{path} ({name}) is stale: run python scripts/doc_sections.py"


def test_every_docs_page_is_indexed():
    """Every page under docs/ is linked from the index that lists its kind: a topic page from
    docs/README.md, a command page from docs/commands/README.md (itself linked from the index)."""
    index = (ROOT / "docs" / "README.md").read_text()
    commands = (ROOT / "docs" / "commands" / "README.md").read_text()
    missing = []
    for page in sorted((ROOT / "docs").rglob("*.md")):
        rel = page.relative_to(ROOT / "docs").as_posix()
        if rel == "README.md":
            continue
        if rel.startswith("commands/"):
            own = rel.removeprefix("commands/")
            if own != "README.md" and f"]({own})" not in commands and f"]({own}#" not in commands:
                missing.append(f"{rel} (from docs/commands/README.md)")
            continue
        if f"]({rel})" not in index and f"]({rel}#" not in index:
            missing.append(f"{rel} (from docs/README.md)")
    assert "](commands/README.md)" in index
    assert not missing, "pages not indexed: " + ", ".join(missing)


def test_no_reference_to_documents_outside_the_repository():
    """Code, scripts, tests, configs and docs say the thing itself, not 'SPEC 3' or 'issue 6'."""
    bad = []
    for path in tracked():
        if GENERATED.match(path) or path == "tests/test_docs.py":
            continue
        try:
            text = (ROOT / path).read_text()
        except UnicodeDecodeError:
            continue
        lines = enumerate(text.splitlines(), 1)
        bad += [f"{path}:{i}: {line.strip()[:80]}" for i, line in lines if OUTSIDE.search(line)]
    assert not bad, "references to documents outside the repository:\n" + "\n".join(bad)


def test_relative_links_in_markdown_resolve():
    """Every relative link of every tracked Markdown file points at a file or folder that exists,
    and a link to a heading (``page.md#anchor``) at a heading of that page."""
    broken = []
    for path in tracked():
        if not path.endswith(".md"):
            continue
        for target, anchor in LINK.findall((ROOT / path).read_text()):
            if re.match(r"^[a-z]+:", target):
                continue
            resolved = Path(os.path.normpath((ROOT / path).parent / target)) if target else ROOT / path
            if not resolved.exists():
                broken.append(f"{path}: {target}")
            elif anchor and resolved.suffix == ".md" and resolved.exists():
                if anchor not in {slug(h) for h in HEADING.findall(resolved.read_text())}:
                    broken.append(f"{path}: {target}#{anchor}")
    assert not broken, "broken links:\n" + "\n".join(broken)
