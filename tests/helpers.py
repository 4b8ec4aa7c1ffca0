"""What many tests share: a tiny valid case file, the options of a fast sweep, the one-line error check, the store's
records and their times, a results table without its timings, and an optional engine without its SDK."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from stereodyn.harness.run.timing import DISTURBED

# The options of a fast sweep: one engine, one integrator, one process, no progress bar.
FAST = ["--engines", "mujoco", "--integrators", "rk4", "--jobs", "1", "--quiet"]
TIMINGS = ["wall_s", "us_per_step", "us_per_step_spread", "timing"]  # results.csv's timing columns (the noise too)


def tiny_case(name: str = "base", t_end: float = 0.1, dt: str = "1e-2", samples: int = 11, extra: str = "") -> str:
    """A case file's text: a free asymmetric top (principal moments 2, 1.5, 1), t_end / dt steps; dt is the TOML
    list's contents ("1e-2, 5e-3"); extra: TOML appended (an [expect] table, say). Tests edit it by str.replace, so
    its lines are stable: `name = "base"`, `t_end = 0.1`, `dt = [1e-2]`, `samples = 11`, `omega = [0.4, 0.1, 2.0]`."""
    return f"""name = "{name}"
[body]
mass = 1.0
com = [0.0, 0.0, 0.0]
principal_moments = [2.0, 1.5, 1.0]
[initial]
attitude = {{ euler_zxz = [0.3, 0.8, -0.5] }}
omega = [0.4, 0.1, 2.0]
[run]
t_end = {t_end}
dt = [{dt}]
samples = {samples}
""" + extra


def case_file(folder: Path, text: str, name: str = "case.toml") -> Path:
    """text written to folder/name (UTF-8)."""
    path = folder / name
    path.write_text(text, encoding="utf-8")
    return path


def one_line_error(code: int, capsys, *expected: str, exit_code: int = 2) -> str:
    """The command's stderr, checked: exit code exit_code (bad input: 2), one line, no traceback, each of `expected`
    in it."""
    err = capsys.readouterr().err
    assert code == exit_code, err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    for text in expected:
        assert text in err, err
    return err


def store_records(out: Path) -> dict[str, dict]:
    """file name -> record of every run in out's store."""
    return {p.name: json.loads(p.read_text()) for p in (out / "store").glob("*.json")}


def store_mtimes(out: Path) -> dict[str, int]:
    """file name -> modification time (ns) of every run in out's store: a run redone is a changed time."""
    return {p.name: p.stat().st_mtime_ns for p in (out / "store").glob("*.json")}


def without_timings(table: pd.DataFrame) -> pd.DataFrame:
    """A results table less its timings, and less the 'timing disturbed' marks the timing phase appends to a message
    (on a loaded machine they come and go from run to run: they are timings too)."""
    marks = table["message"].astype("string").str.replace(rf"(; )?{DISTURBED}:[^;]*", "", regex=True)
    return table.drop(columns=TIMINGS).assign(message=marks.replace("", pd.NA))


def installed_engine(name: str):
    """The registry's engine `name`, or the test skipped with the registry's reason (its extra is not installed)."""
    from stereodyn.harness.engines import UnavailableEngine, get_engine

    engine = get_engine(name)
    if isinstance(engine, UnavailableEngine):
        pytest.skip(engine.reason)
    return engine


def assert_skipped_without_sdk(engine: str, *modules: str, hide_specs: bool = False) -> None:
    """In a fresh process where `modules` cannot be imported (and, hide_specs, importlib.util.find_spec finds
    nothing), the registry gives `engine` as an UnavailableEngine whose reason (its rows' message) names its extra."""
    code = "import sys\n" + "".join(f"sys.modules[{name!r}] = None\n" for name in modules)
    if hide_specs:
        code += "import importlib.util; importlib.util.find_spec = lambda name, *a: None\n"
    code += ("from stereodyn.harness.engines import get_engine, UnavailableEngine\n"
             f"engine = get_engine({engine!r})\n"
             "print(isinstance(engine, UnavailableEngine)); print(engine.unsupported(None))")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr[-2000:]
    unavailable, reason = result.stdout.splitlines()
    assert unavailable == "True", reason
    from stereodyn.harness import install  # the hint matches the install: a checkout's '.[engine]' here

    assert reason.startswith(f"{engine} engine unavailable:") and install.hint(engine) in reason, reason
