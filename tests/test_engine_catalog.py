"""`stereodyn engines` (harness/engines/catalog.py) lists every engine without importing the optional SDKs: versions
come from the installed distributions' metadata, availability from importlib.util.find_spec (the adapters import their
SDK on their first prepare: base.require_modules), models and integrators from stereodyn's own declarations. With
every extra installed it went from 27 s (load 4; 1-2 min under load 10+) to 1.4 s."""
from __future__ import annotations

import subprocess
import sys

# The optional SDKs whose import cost seconds each (measured: mujoco.mjx 7.5 s, mujoco_warp 5 s, newton 4 s,
# genesis 16 s); pydrake and pybullet are still imported by their adapters (~1 s together).
HEAVY = ("jax", "mujoco.mjx", "mujoco_warp", "warp", "newton", "genesis", "torch")


def _listing(prelude: str = "") -> list[str]:
    code = (f"{prelude}\nimport sys\n"
            "from stereodyn.harness.engines.catalog import render, rows\n"
            "table = rows()\n"
            "print(render(table))\n"
            f"print('IMPORTED', [m for m in {HEAVY!r} if m in sys.modules])\n")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr[-2000:]
    return result.stdout.splitlines()


def test_the_listing_imports_no_optional_sdk_and_still_lists_what_each_engine_runs():
    lines = _listing()
    assert lines[-1] == "IMPORTED []"
    blocks: dict[str, list[str]] = {}
    for line in lines[:-1]:
        if not line.startswith(" "):
            blocks[line.split(":")[0]] = [line]
        else:
            blocks[next(reversed(blocks))].append(line)
    assert {"mujoco", "pinocchio", "reference"} <= set(blocks)
    for name, block in blocks.items():
        if "; installed" in block[0]:  # every installed engine lists its integrators (its own declarations)
            assert any(line.startswith("  integrators") for line in block), block
        else:
            assert "; not installed: " in block[0] and "install" in block[0], block


def test_a_missing_sdk_reads_not_installed_with_the_install_command():
    lines = _listing("import sys; sys.modules['newton'] = None")
    newton = next(line for line in lines if line.startswith("newton:"))
    from stereodyn.harness import install

    assert newton.endswith("not installed: newton engine unavailable: No module named 'newton'; install the extra: "
                           + install.hint("newton"))
