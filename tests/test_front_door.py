"""The front door (issue 32): a short README that opens with the two commands, a committed screenshot, three paths
whose commands run as written, and a documentation site whose reference pages (tools/docs_reference.py) list every
command, flag, case key and column the code declares."""
import argparse
import importlib.util
import os
import re
import shlex
import struct
import subprocess
from pathlib import Path

import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
SCREENSHOT = "docs/img/report.png"
PATHS = ("### Choose an integrator and dt for my body in my engine", "### Gate my integrator in CI",
         "### Add my engine")


def _reference():
    spec = importlib.util.spec_from_file_location("docs_reference", ROOT / "tools" / "docs_reference.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _text() -> str:
    return README.read_text(encoding="utf-8")


def _section(heading: str) -> str:
    return _text().split(heading + "\n", 1)[1].split("\n#", 1)[0]


def _blocks(text: str, language: str) -> list[str]:
    return re.findall(rf"```{language}\n(.*?)```", text, flags=re.S)


def test_the_readme_is_short_and_opens_with_the_two_commands_and_their_times():
    lines = _text().splitlines()
    assert len(lines) <= 160, len(lines)
    head = "\n".join(lines[:30])
    assert _blocks(head, "sh") == ["pip install '.[drake]' && stereodyn run\n",
                                   "pip install -e '.[test]' && pytest\n"]
    times = re.findall(r"\d+ min \d+ s on 2 idle cores \(measured 20\d\d-\d\d-\d\d\)", " ".join(head.split()))
    assert len(times) == 2, times  # beside each command, dated
    assert "python3 -m venv" in head and "Python >= 3.11" in head


def test_the_screenshot_is_committed_and_referenced():
    data = (ROOT / SCREENSHOT).read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    width, height = struct.unpack(">II", data[16:24])  # IHDR: the window it was taken in
    assert (width, height) == (1400, 900)
    assert f"]({SCREENSHOT})" in _text()


def test_every_stereodyn_command_of_the_readme_parses():
    """Every `stereodyn ...` line of the README's shell blocks is accepted by the parser itself (a renamed or removed
    flag fails here at once; the slow test below runs the three paths)."""
    from stereodyn.harness import cli

    parser = cli.parser()
    commands = [line for block in _blocks(_text(), "sh") for line in block.splitlines()
                if line.strip().startswith(("stereodyn", "pip install")) and "stereodyn " in line]
    assert len(commands) >= 9, commands  # the two commands and the three paths' commands
    for line in commands:
        argv = shlex.split(line.split("&&")[-1], comments=True)
        try:
            parser.parse_args(argv[1:])
        except SystemExit:
            pytest.fail(f"the README's command does not parse: {line}")


def test_the_three_paths_each_have_commands():
    for heading in PATHS:
        assert _blocks(_section(heading), "sh"), heading
    assert _blocks(_section(PATHS[0]), "toml")


def test_the_cli_reference_lists_every_command_and_every_flag_of_run():
    reference = _reference()
    parser = reference._parser()
    page = reference.cli_page(parser)
    commands = reference.commands(parser)
    assert [m for m in re.findall(r"^## stereodyn (\S+)$", page, flags=re.M)] == list(commands)
    run_section = page.split("## stereodyn run\n", 1)[1].split("\n## ", 1)[0]
    flags = [name for action in commands["run"]._actions for name in action.option_strings
             if not isinstance(action, argparse._HelpAction)]
    assert len(flags) >= 25, flags  # run has 27 option strings today: a parser read wrong would list few
    assert [flag for flag in flags if f"`{flag}`" not in run_section] == []
    for name, command in commands.items():  # every flag of every command too
        section = page.split(f"## stereodyn {name}\n", 1)[1].split("\n## ", 1)[0]
        missing = [o for a in command._actions for o in a.option_strings
                   if not isinstance(a, argparse._HelpAction) and f"`{o}`" not in section]
        assert not missing, (name, missing)


def test_the_case_key_reference_lists_every_key_and_its_rules():
    reference = _reference()
    page = reference.case_keys_page()
    tables = reference.schema()
    assert {table for _, table, _, _ in tables} >= {"", "body", "run", "body_torque", "central_field", "ladder"}
    for scene, table, allowed, _ in tables:
        section = page.split(f"## {scene}: {f'[{table}]' if table else 'top level'}\n", 1)[1].split("\n## ", 1)[0]
        assert [key for key in allowed if f"| `{key}` |" not in section] == [], (scene, table)
    # rules come from the validation code, constants by value; a value quoted from the file is an entity, not a tag
    # Markdown would drop
    assert "must be &lt;= 100000 (docs/limits.md)" in page and "must be in (0, pi/2) rad" in page
    assert "unknown scene kind &lt;kind&gt;" in page


def test_the_tables_reference_lists_every_declared_column():
    reference = _reference()
    page = reference.tables_page()
    found = reference.table_columns()
    assert {file for file, *_ in found} >= {"results.csv", "pareto.csv", "advice.csv", "verdicts.csv", "ladder.csv"}
    for file, _, columns, _ in found:
        section = page.split(f"## {file}\n", 1)[1].split("\n## ", 1)[0]
        assert [c for c in columns if f"`{c}`" not in section] == [], file


def test_the_site_navigation_names_only_pages_that_exist():
    nav = re.findall(r":\s+(\S+\.md)\s*$", (ROOT / "mkdocs.yml").read_text(encoding="utf-8"), flags=re.M)
    generated = set(_reference().PAGES)
    assert generated <= set(nav)
    assert [page for page in nav if page not in generated and not (ROOT / "docs" / page).is_file()] == []


# slow: 45 s of CPU, 130 s wall on 2 shared cores, measured (each `stereodyn run` starts a pool of workers, as the
# README's commands do); the fast test above parses every one of these commands with the parser
@pytest.mark.slow
def test_the_three_paths_run_as_written(tmp_path):
    env = {**os.environ, "STEREODYN_FIGURES": "0"}
    (tmp_path / "my-body.toml").write_text(_blocks(_section(PATHS[0]), "toml")[0], encoding="utf-8")
    for heading in PATHS:
        for block in _blocks(_section(heading), "sh"):
            result = subprocess.run(["bash", "-euo", "pipefail", "-c", block], cwd=tmp_path, env=env,
                                    capture_output=True, text=True, timeout=600)
            assert result.returncode == 0, (heading, block, result.stderr[-2000:])
    # the check of the advice: the run at the advised dt reaches the target the README asks for
    rows = pd.read_csv(tmp_path / "out" / "my-body" / "results.csv")
    run = rows[rows.engine == "mujoco"]
    assert list(run.status) == ["ok"] and float(run.attitude_err.iloc[0]) <= 1e-6
    assert 'timestep="0.0039"' in (tmp_path / "my-body.xml").read_text()
    assert (tmp_path / "baseline.json").is_file()


def test_the_reference_pages_script_takes_help_as_help_not_as_a_folder(tmp_path, monkeypatch, capsys):
    """`python tools/docs_reference.py --help` once wrote the pages into a folder named "--help" (committed by
    mistake); it prints its usage and writes nothing. With a folder it writes the three pages there."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as exit_:
        _reference().main(["--help"])
    assert exit_.value.code == 0 and "DIR" in capsys.readouterr().out and not list(tmp_path.iterdir())
    assert _reference().main([str(tmp_path / "pages")]) == 0
    assert sorted(p.name for p in (tmp_path / "pages").iterdir()) == ["case-keys.md", "cli.md", "tables.md"]
