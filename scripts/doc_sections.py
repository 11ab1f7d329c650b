"""Write the generated sections of the docs: the commands tables (docs/commands/README.md and
the README's), rendered from the typer app, and the layout section of docs/extending.md,
rendered from the layers ``tests/test_layering.py`` checks.

    python scripts/doc_sections.py           # rewrite the sections in place
    python scripts/doc_sections.py --check   # exit 1 if a section is not what the code gives

Each section sits between ``<!-- generated: NAME (scripts/doc_sections.py) -->`` and
``<!-- end generated: NAME -->``; the text around it is written by hand.  ``tests/test_docs.py``
runs the check, so a command, option or layer added without regenerating fails the tests.
"""

from __future__ import annotations

import argparse
import importlib.util
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PAGES = {  # command -> its page (from the repository root)
    "fit": "docs/fit.md",
}


def page_of(name: str) -> str:
    return PAGES.get(name, f"docs/commands/{name}.md")


def cell(text: str) -> str:
    """A Markdown table cell: no pipes, no newlines, docstring roles as code."""
    text = re.sub(r":\w+:`~?\.?([^`]+)`", r"`\1`", str(text)).replace("``", "`")
    text = text[:-2] + "." if text.endswith("::") else text
    return " ".join(text.replace("|", "\\|").split())


def first_sentence(text: str) -> str:
    """The help's first sentence (up to the first '.  ', or its first paragraph)."""
    para = " ".join((text or "").strip().split("\n\n")[0].split())
    m = re.search(r"\.(\s|$)", para)
    return para[: m.start() + 1] if m else para


def commands():
    """``[(name, synopsis, option flags, help, short help)]`` of the typer app's commands, in its order."""
    import typer.main

    from vetica_cli.cli import app

    group = typer.main.get_command(app)
    out = []
    for name, cmd in group.commands.items():
        args, flags = [], []
        for p in cmd.params:
            if p.param_type_name == "argument":
                meta = p.name.upper() + ("…" if p.nargs == -1 else "")
                args.append(meta if p.required else f"[{meta}]")
            elif p.name != "help":
                long = [o for o in p.opts if o.startswith("--")] or p.opts
                flags.append(long[0] + (f"/{p.secondary_opts[0]}" if p.secondary_opts else ""))
        synopsis = " ".join(["vetica", name, *args, "[OPTIONS]" if flags else ""]).strip()
        out.append((name, synopsis, flags, cmd.help or "", cmd.short_help or first_sentence(cmd.help or "")))
    return out


def commands_page_table() -> str:
    rows = ["| command | what it does | options |", "|---|---|---|"]
    for name, synopsis, flags, help_, _ in commands():
        link = f"[{name}]({Path(page_of(name)).relative_to('docs/commands').as_posix()})" if page_of(name).startswith(
            "docs/commands/") else f"[{name}](../{Path(page_of(name)).relative_to('docs').as_posix()})"  # fmt: skip
        rows.append(f"| `{synopsis}` ({link}) | {cell(first_sentence(help_))} | {cell(', '.join(f'`{f}`' for f in flags))} |")
    return "\n".join(rows)


def readme_table() -> str:
    rows = ["| command | what it does | page |", "|---|---|---|"]
    for name, synopsis, _, _, short in commands():
        rows.append(f"| `{synopsis}` | {cell(short)} | [{name}]({page_of(name)}) |")
    return "\n".join(rows)


def layers():
    """The layers of ``tests/test_layering.py`` (top to bottom) and its foundation."""
    spec = importlib.util.spec_from_file_location("test_layering", ROOT / "tests" / "test_layering.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.LAYERS, mod.FOUNDATION


def summary_of(component: str) -> str:
    """The first sentence of a component's docstring (its package ``__init__`` or module)."""
    import ast

    pkg = ROOT / "vetica_cli" / component
    path = pkg / "__init__.py" if pkg.is_dir() else pkg.with_suffix(".py")
    if not path.is_file():
        return ""
    return first_sentence(ast.get_docstring(ast.parse(path.read_text())) or "")


def layout_section() -> str:
    layer_list, foundation = layers()
    rows = ["| layer | component | holds |", "|---|---|---|"]
    for i, names in enumerate(layer_list):
        for comp in sorted(names):
            if comp == "__main__":
                continue
            shown = f"`{comp}/`" if (ROOT / "vetica_cli" / comp).is_dir() else f"`{comp}.py`"
            rows.append(f"| {i} | {shown} | {cell(summary_of(comp))} |")
    for comp in sorted(foundation - {"__init__"}):
        rows.append(f"| foundation | `{comp}.py` | {cell(summary_of(comp))} |")
    head = ("Imports point one way only, from a layer to the layers below it (a higher number); the foundation "
            "is usable from anywhere. `tests/test_layering.py` checks it on the source, with no import cycle "
            "and no `_private` name used across modules (tests and scripts included).")  # fmt: skip
    return head + "\n\n" + "\n".join(rows)


SECTIONS = {  # (file, section name) -> renderer
    ("docs/commands/README.md", "commands"): commands_page_table,
    ("README.md", "commands"): readme_table,
    ("docs/extending.md", "layout"): layout_section,
}


def markers(name: str) -> tuple[str, str]:
    return f"<!-- generated: {name} (scripts/doc_sections.py) -->", f"<!-- end generated: {name} -->"


def rendered(path: str, name: str, text: str) -> str:
    """``text`` (the file) with section ``name`` replaced by what the code gives now."""
    start, end = markers(name)
    if start not in text or end not in text:
        raise SystemExit(f"{path}: no section {name!r} ({start} ... {end})")
    before, rest = text.split(start, 1)
    _, after = rest.split(end, 1)
    return f"{before}{start}\n{SECTIONS[(path, name)]()}\n{end}{after}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true", help="exit 1 if a section is stale")
    args = ap.parse_args(argv)
    stale = []
    for path, name in SECTIONS:
        text = (ROOT / path).read_text()
        new = rendered(path, name, text)
        if new != text:
            if args.check:
                stale.append(f"{path} ({name})")
            else:
                (ROOT / path).write_text(new)
                print(f"wrote {path} ({name})")
    if stale:
        print("stale: " + ", ".join(stale) + "; run python scripts/doc_sections.py", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
