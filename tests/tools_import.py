"""The repository's ``tools/*.py`` scripts, imported by path for the tests that check them.

Why one loader: the tools are scripts, not a package (``python3 tools/x.py`` is how users run
them), so a test cannot ``import`` them; five test files had each written the same
``spec_from_file_location`` lines."""
from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType

TOOLS = Path(__file__).resolve().parents[1] / "tools"


def load_tool(name: str) -> ModuleType:
    """``tools/<name>.py`` as a module (executed once per call)."""
    spec = importlib.util.spec_from_file_location(name, TOOLS / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod
