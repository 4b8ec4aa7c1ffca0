"""The command line's layout (issue 47 item 3, asv's): each command's module declares its arguments beside its body,
and harness/cli/__init__.py only assembles them."""
import argparse
import ast
from pathlib import Path

from stereodyn.harness import cli

CLI = Path(__file__).resolve().parents[1] / "harness" / "cli"


def test_the_package_only_assembles_the_commands():
    source = (CLI / "__init__.py").read_text()
    assert len(source.splitlines()) <= 80
    # no argument is declared here: every add_argument is in a command's module (or common.py's option groups)
    assert "add_argument" not in source


def test_each_command_module_declares_its_parser_and_its_body():
    for name in cli.COMMANDS:
        functions = {node.name for node in ast.parse((CLI / f"{name}.py").read_text()).body
                     if isinstance(node, ast.FunctionDef)}
        assert {"add_parser", "main"} <= functions, name
    commands = argparse.ArgumentParser().add_subparsers()
    cli.command("run").add_parser(commands)  # one command's parser, alone
    assert list(commands.choices) == ["run"]
    assert commands.choices["run"].parse_args(["--no-ladder", "--jobs", "1"]).jobs == 1


def test_the_parser_has_every_command_in_order():
    (sub,) = [a for a in cli.parser()._actions if isinstance(a, argparse._SubParsersAction)]
    assert tuple(sub.choices) == cli.COMMANDS
