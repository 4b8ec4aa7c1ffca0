"""Install hints that match how stereodyn was installed (issue 32): from a checkout (the source tree has its
pyproject.toml), `pip install '.[EXTRA]'` in that folder; from a distribution, `pip install 'stereodyn[EXTRA]'`."""
from __future__ import annotations

import functools
import os
from pathlib import Path


@functools.lru_cache(maxsize=1)
def checkout() -> Path | None:
    """The source tree stereodyn runs from, or None for an installed distribution: the folder above the package
    holding a pyproject.toml that names the project (an editable install or a checkout on sys.path)."""
    root = Path(__file__).resolve().parents[1]  # harness/ sits at the top of the tree (pyproject's package-dir)
    project = root / "pyproject.toml"
    try:
        return root if project.is_file() and 'name = "stereodyn"' in project.read_text() else None
    except OSError:
        return None


def hint(extra: str) -> str:
    """The command that installs an extra: `pip install '.[extra]'` in a checkout (the checkout's path when the
    working directory is elsewhere), `pip install 'stereodyn[extra]'` otherwise."""
    root = checkout()
    if root is None:
        return f"pip install 'stereodyn[{extra}]'"
    try:
        here = Path(os.getcwd()).resolve() == root
    except OSError:
        here = False
    return f"pip install '{'.' if here else root}[{extra}]'"
