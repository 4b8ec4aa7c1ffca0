"""Install hints that match how stereodyn was installed (issue 32): from a checkout (the source tree has its
pyproject.toml), `pip install '.[EXTRA]'` in that folder; from a distribution, `pip install 'stereodyn[EXTRA]'`."""
from __future__ import annotations

import functools
import os
from pathlib import Path


@functools.lru_cache(maxsize=1)
def checkout() -> Path | None:
    """The source tree stereodyn was installed from, or None for a distribution: the folder above the package holding
    a pyproject.toml that names the project (an editable install, a checkout on sys.path), or the local folder a
    plain `pip install .` recorded (the README's main command)."""
    for root in (Path(__file__).resolve().parents[1], _installed_from()):  # harness/ tops the tree (package-dir)
        try:
            if root is not None and 'name = "stereodyn"' in (root / "pyproject.toml").read_text():
                return root
        except OSError:
            continue
    return None


def _installed_from() -> Path | None:
    """The local folder a non-editable `pip install .` took stereodyn from (PEP 610's direct_url.json), or None."""
    import json
    from importlib import metadata
    from urllib.parse import unquote, urlparse

    try:
        url = json.loads(metadata.distribution("stereodyn").read_text("direct_url.json") or "{}").get("url", "")
    except (metadata.PackageNotFoundError, ValueError, AttributeError):
        return None
    parsed = urlparse(url)
    return Path(unquote(parsed.path)) if parsed.scheme == "file" else None


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
