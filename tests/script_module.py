"""A script of ``scripts/`` imported as a module by the tests that check it (the scripts are not a
package: each is run as ``python scripts/NAME.py``)."""

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def script(name: str):
    """``scripts/<name>.py``, executed as a fresh module."""
    spec = importlib.util.spec_from_file_location(name, ROOT / "scripts" / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod
