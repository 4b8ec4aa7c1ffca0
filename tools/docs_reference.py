"""The documentation site's reference pages, generated from the code so they cannot drift (issue 32): every command and
flag from the argparse parser (harness/cli: each command's module declares its arguments), every case key from the case schema and the checks that
validate it (harness/scenes/cases.py, the torque models, the sliding ladder's scene), every column of every CSV from
the constant that declares it.

As a mkdocs hook (mkdocs.yml `hooks:`) the pages are added to the build in memory, beside docs/'s own; run as a script,
`python tools/docs_reference.py DIR` writes them to DIR to read.
"""
from __future__ import annotations

import argparse
import ast
import importlib
import inspect
import re
import sys
from pathlib import Path

# page file (at the top of the site, beside DESIGN.md, so that links between them are plain names) -> title; the nav
# of mkdocs.yml names these files
PAGES = {"cli.md": "Command line", "case-keys.md": "Case keys", "tables.md": "Result tables"}

# The CSV files and the constants that declare their columns, in the order a run writes them.
TABLES = (
    ("results.csv", "stereodyn.harness.run.results", "COLUMNS", "one row per run (DESIGN §4)"),
    ("verdicts.csv", "stereodyn.harness.analysis.verdicts", "COLUMNS", "one row per verdict"),
    ("answers.csv", "stereodyn.harness.analysis.answers", "ANSWER_COLUMNS",
     "what to use: per case, scope and accuracy target, the one answer the report and the terminal show"),
    ("pareto.csv", "stereodyn.harness.analysis.pareto", "PARETO_COLUMNS",
     "per case, scope and accuracy target, the cheapest of the runs listed that reaches it (the frontier)"),
    ("advice.csv", "stereodyn.harness.analysis.step_advice", "ADVICE_COLUMNS",
     "per laddered family and target, the largest checked dt or tolerance"),
    ("convergence.csv", "stereodyn.harness.analysis.fitting", "CONVERGENCE_COLUMNS", "one row per fitted run family"),
    ("ladder.csv", "stereodyn.harness.analysis.ladders", "LADDER_COLUMNS", "every point of the dt ladders"),
    ("tolerance.csv", "stereodyn.harness.analysis.ladders", "TOLERANCE_COLUMNS",
     "every point of the tolerance ladders"),
    ("tolerance_fit.csv", "stereodyn.harness.analysis.fitting", "TOLERANCE_FIT_COLUMNS", "one row per adaptive method"),
    ("checks.csv", "stereodyn.harness.scenes.checks", "COLUMNS", "one row per run and quantity against theory"),
    ("agreement.csv", "stereodyn.harness.analysis.agreement", "COLUMNS", "pairs of engines running one method"),
    ("DIR/trajectories/index.csv", "stereodyn.harness.run.store", "TRAJECTORY_INDEX_COLUMNS",
     "`run --save-trajectories`: each saved run's file"),
    ("history.csv", "stereodyn.harness.analysis.history", "COLUMNS",
     "`stereodyn history`: each metric over the folders"),
    ("history_steps.csv", "stereodyn.harness.analysis.history", "STEP_COLUMNS", "`stereodyn history`: the steps found"),
)
# CSVs whose columns follow the data (no constant declares them): named so the page is complete.
UNDECLARED = (("compare.csv", "`stereodyn compare`: the row's key columns, then each metric of A and B and B / A"),
              ("history_points.csv", "`stereodyn history`: the folders in order with their labels"))

# The case format: the modules whose validation the case-key page reads, and the reader's value checks.
CASE_MODULES = ("stereodyn.harness.scenes.cases", "stereodyn.harness.scenes.sliding_ladder",
                "stereodyn.reference.torque_models.body_torque", "stereodyn.reference.torque_models.central_field",
                "stereodyn.reference.torque_models.precession")
KINDS = {"number": "number", "positive": "number > 0", "vector": "list of numbers", "unit": "unit vector",
         "string": "string", "steps": "a dt or a list of dt", "inertia_matrix": "3x3 symmetric matrix",
         "table": "table"}


# --------------------------------------------------------------------------------------------- command line

def _parser() -> argparse.ArgumentParser:
    from stereodyn.harness import cli

    return cli.parser()


def commands(parser: argparse.ArgumentParser | None = None) -> dict[str, argparse.ArgumentParser]:
    """{command: its subparser}, in the parser's order."""
    parser = parser or _parser()
    (sub,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return dict(sub.choices)


def _cell(text) -> str:
    """Text for a table cell: one line, `|` escaped, and `<`, `>` as entities (Markdown would take <key> for a tag
    and drop it)."""
    return " ".join(str(text).split()).replace("|", "\\|").replace("<", "&lt;").replace(">", "&gt;")


def _flag(action: argparse.Action) -> str:
    if not action.option_strings:
        return f"`{action.metavar or action.dest.upper()}`" + (" ..." if action.nargs in ("*", "+") else "")
    names = ", ".join(f"`{name}`" for name in action.option_strings)
    if action.nargs == 0:
        return names
    metavar = action.metavar or ("{" + ",".join(action.choices) + "}" if action.choices else action.dest.upper())
    return f"{names} `{metavar}`"


def cli_page(parser: argparse.ArgumentParser | None = None) -> str:
    parser = parser or _parser()
    (sub,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    helps = {choice.dest: choice.help for choice in sub._choices_actions}
    lines = ["# Command line", "",
             "Generated from the parser itself (`harness/cli/`, each command's module), so it lists every command and flag as "
             "`stereodyn` accepts them. Exit codes: 0 done (failed runs are data, rows with their reason), 1 `check` "
             "or `run --strict` failed, 2 bad input (one line naming the file or option, the key and the rule), 3 a "
             "bug in stereodyn (a traceback), 130 interrupted.", ""]
    for name, command in commands(parser).items():
        lines += [f"## stereodyn {name}", "", _cell(helps.get(name, "")), "", "```",
                  " ".join(command.format_usage().split()).removeprefix("usage: "), "```", ""]
        actions = [a for a in command._actions if not isinstance(a, argparse._HelpAction)]
        if not actions:
            continue
        lines += ["| argument | default | meaning |", "|---|---|---|"]
        for action in actions:
            default = "" if action.default in (None, False, [], argparse.SUPPRESS) or action.required \
                or action.nargs == 0 else f"`{action.default}`"
            meaning = _cell(action.help or "")
            if action.required and action.option_strings:
                meaning = "required. " + meaning
            lines.append(f"| {_flag(action)} | {default} | {meaning} |")
        lines.append("")
    return "\n".join(lines)


# --------------------------------------------------------------------------------------------- case keys

def _render(node: ast.AST, module) -> str:
    """A rule's text from its expression: literal parts as written, a module constant by its value, anything
    computed from the file's contents as <expression>."""
    if isinstance(node, ast.Constant):
        return str(node.value)
    if isinstance(node, ast.JoinedStr):
        return "".join(_render(value, module) for value in node.values)
    if isinstance(node, ast.FormattedValue):
        inner = node.value
        if isinstance(inner, ast.Name) and isinstance(getattr(module, inner.id, None), (int, float)):
            spec = _render(node.format_spec, module) if node.format_spec else ""
            return format(getattr(module, inner.id), spec)
        return _value(inner)
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Add):
        return _render(node.left, module) + _render(node.right, module)
    return _value(node)


def _value(node: ast.AST) -> str:
    """A value the rule quotes from the file: <name> where the code names it plainly, <...> where it computes it."""
    if isinstance(node, (ast.Name, ast.Attribute)):
        return f"<{ast.unparse(node)}>"
    return "<...>"


def _literal_key(node: ast.AST) -> str | None:
    return node.value if isinstance(node, ast.Constant) and isinstance(node.value, str) else None


def case_checks() -> tuple[dict[str, list[str]], dict[str, list[str]]]:
    """({key: its kinds and rules}, {value kind: its rules}), read from the validation code: every reader call with a
    literal key (parser.positive(x, "body.mass"), self.fail("run.samples", rule), ...) and every rule inside the
    reader's value checks (_Parser.number, .positive, ...)."""
    by_key: dict[str, list[str]] = {}
    by_kind: dict[str, list[str]] = {}
    for name in CASE_MODULES:
        module = importlib.import_module(name)
        tree = ast.parse(inspect.getsource(module))
        for function in [n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef)]:
            for call in [n for n in ast.walk(function) if isinstance(n, ast.Call)]:
                method = call.func.attr if isinstance(call.func, ast.Attribute) else None
                if method not in {"fail", *KINDS} or len(call.args) < 2:
                    continue
                key = _literal_key(call.args[1] if method != "fail" else call.args[0])
                if method == "fail":
                    rule = _render(call.args[1], module)
                    if key is not None:
                        by_key.setdefault(key, []).append(rule)
                    elif function.name in KINDS and name.endswith(".cases"):
                        by_kind.setdefault(function.name, []).append(rule)
                elif key is not None and method != "table":
                    by_key.setdefault(key, []).append(f"[{KINDS[method]}](#value-checks)")
    return ({key: list(dict.fromkeys(rules)) for key, rules in by_key.items()},
            {kind: list(dict.fromkeys(rules)) for kind, rules in by_kind.items()})


def schema() -> list[tuple[str, str, list[str], set[str]]]:
    """(scene, table, allowed keys, required keys) of every table a case file may hold."""
    from stereodyn.harness.scenes import cases, sliding_ladder
    from stereodyn.reference.torque_models import models

    found = []
    for table, (allowed, required) in cases._TABLES.items():
        extra = {model.key for model in models()} if table == "" else set()
        found.append(("rigid body", table, sorted(allowed | extra), set(required)))
    for model in models():
        allowed, required = model.schema
        found.append(("rigid body", model.key, sorted(allowed), set(required)))
    for table, (allowed, required) in (("", sliding_ladder.TOP), ("ladder", sliding_ladder.LADDER)):
        found.append(("sliding ladder", table, sorted(allowed), set(required)))
    return found


def case_keys_page() -> str:
    by_key, by_kind = case_checks()
    lines = ["# Case keys", "",
             "Generated from the case schema and the code that validates it (`harness/scenes/cases.py`, the torque "
             "models of `reference/torque_models/`, `harness/scenes/sliding_ladder.py`). A file breaking a rule is "
             "refused with one line, `FILE: KEY: RULE`, exit 2. The format with an example of every key: "
             "[DESIGN §3](DESIGN.md#3-case-file-toml); the numeric ranges: [limits](limits.md). "
             "`<...>` in a rule is the value found in the file.", ""]
    tables = schema()
    for scene, table, allowed, required in tables:
        title = f"[{table}]" if table else "top level"
        lines += [f"## {scene}: {title}", "", "| key | required | checks |", "|---|---|---|"]
        for key in allowed:
            full = f"{table}.{key}" if table else key
            rules = by_key.get(full, [])
            if table == "" and key in {t for _, t, _, _ in tables if t}:
                # the table's own section, else (the sliding ladder's [run]) the rigid body's
                owner = scene if (scene, key) in {(s, t) for s, t, _, _ in tables} else "rigid body"
                rules = [f"a table, [{'below' if owner == scene else owner}](#{_anchor(owner, key)})"] + rules
            lines.append(f"| `{key}` | {'yes' if key in required else 'no'} | {_cell('; '.join(rules))} |")
        lines.append("")
    lines += ["## Value checks", "", "Every number, vector and dt the tables above name is checked so:", "",
              "| check | rules |", "|---|---|"]
    for kind, rules in by_kind.items():
        lines.append(f"| {KINDS.get(kind, kind)} (`{kind}`) | {_cell('; '.join(rules))} |")
    lines.append("")
    return "\n".join(lines)


def _anchor(scene: str, table: str) -> str:
    """The id mkdocs gives the heading "SCENE: [TABLE]" (Python-Markdown's toc slugify)."""
    return re.sub(r"[-\s]+", "-", re.sub(r"[^\w\s-]", "", f"{scene}: [{table}]").strip().lower())


# --------------------------------------------------------------------------------------------- result tables

def table_columns() -> list[tuple[str, str, tuple[str, ...], str]]:
    """(file, declared at, columns, what a row is) of every CSV with declared columns."""
    found = []
    for file, module, constant, what in TABLES:
        columns = tuple(getattr(importlib.import_module(module), constant))
        found.append((file, f"{module.removeprefix('stereodyn.').replace('.', '/')}.py: {constant}", columns, what))
    return found


def _design_meanings() -> dict[str, str]:
    """results.csv's column meanings from DESIGN §4's table (`col`, `col` | meaning)."""
    text = (Path(__file__).resolve().parents[1] / "docs" / "DESIGN.md").read_text(encoding="utf-8")
    section = text.split("### results.csv", 1)[1].split("\n### ", 1)[0]
    meanings = {}
    for row in re.findall(r"^\| (`[^|]+`) \| (.+) \|$", section, flags=re.M):
        for column in re.findall(r"`(\w+)`", row[0]):
            meanings[column] = row[1]
    return meanings


def tables_page() -> str:
    meanings = _design_meanings()
    lines = ["# Result tables", "",
             "Every CSV stereodyn writes, with its columns in order, generated from the constant that declares them. "
             "What each column means: [DESIGN §4](DESIGN.md#4-result-tables) (results.csv's meanings are "
             "repeated here). Each output folder's own `README.md` says which of these files it holds.", ""]
    for file, declared, columns, what in table_columns():
        lines += [f"## {file}", "", f"{what}. Declared in `{declared}`.", ""]
        if file == "results.csv":  # columns that share a meaning share a row, as in DESIGN §4
            groups: list[tuple[list[str], str]] = []
            for column in columns:
                meaning = meanings.get(column, "")
                if groups and meaning and groups[-1][1] == meaning:
                    groups[-1][0].append(column)
                else:
                    groups.append(([column], meaning))
            lines += ["| column | meaning |", "|---|---|"]
            lines += [f"| {', '.join(f'`{c}`' for c in names)} | {meaning or '(not described in DESIGN §4 yet)'} |"
                      for names, meaning in groups]
        else:
            lines += [", ".join(f"`{c}`" for c in columns)]
        lines.append("")
    lines += ["## Tables whose columns follow the data", ""]
    lines += [f"- `{file}`: {what}" for file, what in UNDECLARED]
    lines.append("")
    return "\n".join(lines)


def pages() -> dict[str, str]:
    """{path under docs/: text} of every generated page."""
    return dict(zip(PAGES, (cli_page(), case_keys_page(), tables_page())))


# --------------------------------------------------------------------------------------------- mkdocs hook

def on_files(files, config):
    """mkdocs hook: add the generated pages to the site (in memory; nothing is written under docs/)."""
    from mkdocs.structure.files import File

    for path, text in pages().items():
        files.append(File.generated(config, path, content=text))
    return files


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description="Write the documentation site's generated reference pages to DIR.")
    parser.add_argument("dir", metavar="DIR", type=Path)
    args = parser.parse_args(argv)  # `--help` is help, not a folder named "--help"
    for path, text in pages().items():
        target = args.dir / path
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text(text, encoding="utf-8")
        print(target)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
