"""Load a script of the repository (experiments/*.py, datasets/generate.py) as a module, the way tests use them:
in-process, without a subprocess's import and compile time."""

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def load_script(relpath: str, name: str | None = None):
    """The module of ``ROOT / relpath`` (executed once per call)."""
    path = ROOT / relpath
    spec = importlib.util.spec_from_file_location(name or path.stem.replace("-", "_"), path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
