"""A mutation check over a declared list of mutants (issue 28 item 2; docs/mutants.md).

Each mutant of tools/mutants.toml is one textual edit of a module of the verdict machinery: an original text found
exactly once in the file, and its replacement (a comparison flipped, a bound moved, a condition dropped). For each
mutant the tool writes the edit into the checkout, runs the tests mapped to that module (`pytest -x -q`), and puts the
original back, byte for byte, in a `finally`. Killed: a test failed. Survived: every mapped test passed. Timeout: the
tests ran past the limit (a hang is caught too, by CI's own limit). Equivalent: listed with its argument in
tools/mutants_equivalent.toml, not run. The score is (killed + timeout + equivalent) / mutants; under --threshold the
exit is 1.

A script over a declared list rather than mutmut: the package maps stereodyn.harness to harness/ (setuptools
package-dir) and the tests import it through the editable install, which mutmut's copied tree does not see; and a
declared list is a chosen, stable sample (the lines that decide a user-visible answer) that a rerun repeats exactly.

    python tools/mutants.py --list                  # check that every mutant still applies; run nothing
    python tools/mutants.py                         # every module
    python tools/mutants.py --module gate --only gate-3
"""
from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import time
import tomllib
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CONFIG = Path("tools/mutants.toml")
EQUIVALENT = Path("tools/mutants_equivalent.toml")
KILLED, SURVIVED, TIMEOUT, EQUIV, ERROR = "killed", "survived", "timeout", "equivalent", "error"


@dataclass(frozen=True)
class Mutant:
    id: str          # "<module>-<n>", n from 1 in the file's order
    module: str
    file: Path       # relative to the root
    old: str
    new: str


@dataclass(frozen=True)
class Module:
    name: str
    file: Path
    tests: tuple[str, ...]   # pytest arguments: files or node ids, fastest first (-x stops at the first failure)
    mutants: tuple[Mutant, ...]


def load(root: Path, config: Path = CONFIG) -> list[Module]:
    data = tomllib.loads((root / config).read_text())
    modules = []
    for name, table in data["module"].items():
        file = Path(table["file"])
        mutants = tuple(Mutant(f"{name}-{i}", name, file, old, new) for i, (old, new) in enumerate(table["mutants"], 1))
        modules.append(Module(name, file, tuple(table["tests"]), mutants))
    return modules


def load_equivalent(root: Path, path: Path = EQUIVALENT) -> list[dict]:
    """The mutants argued equivalent: module, old, new and why (one line)."""
    if not (root / path).is_file():
        return []
    return tomllib.loads((root / path).read_text()).get("equivalent", [])


def problems(root: Path, modules: list[Module], equivalent: list[dict]) -> list[str]:
    """Why a declared mutant no longer applies (its original text not found exactly once, a replacement equal to it
    or not valid Python), a mapped test that is gone, or an equivalence argued for a mutant not declared."""
    out = []
    for module in modules:
        source = (root / module.file).read_text()
        for m in module.mutants:
            count = source.count(m.old)
            if count != 1:
                out.append(f"{m.id}: original found {count} times in {m.file}: {m.old!r}")
            elif m.old == m.new:
                out.append(f"{m.id}: the replacement is the original")
            else:
                try:
                    compile(source.replace(m.old, m.new), str(m.file), "exec")
                except SyntaxError as exc:
                    out.append(f"{m.id}: the mutant is not valid Python ({exc.msg}, line {exc.lineno})")
        for test in module.tests:
            path, _, name = test.partition("::")
            if not (root / path).is_file():
                out.append(f"{module.name}: mapped test file {path} not found")
            elif name and f"def {name.split('[')[0]}(" not in (root / path).read_text():
                out.append(f"{module.name}: mapped test {test} not found")
    declared = {(m.module, m.old, m.new) for module in modules for m in module.mutants}
    for entry in equivalent:
        if (entry.get("module"), entry.get("old"), entry.get("new")) not in declared:
            out.append(f"equivalent: no declared mutant {entry.get('module')}: {entry.get('old')!r} -> "
                       f"{entry.get('new')!r}")
        if not str(entry.get("why", "")).strip():
            out.append(f"equivalent: {entry.get('module')}: {entry.get('old')!r}: no argument (why)")
    return out


def line_of(source: str, old: str) -> int:
    return source[:source.find(old)].count("\n") + 1


def dirty(root: Path, files: list[Path]) -> list[str]:
    """The files among these with changes git does not have (a mutant must be undone to a committed state)."""
    out = subprocess.run(["git", "status", "--porcelain", "--", *map(str, files)], cwd=root, capture_output=True,
                         text=True, check=True).stdout
    return [line[3:] for line in out.splitlines()]


def _drop_bytecode(path: Path) -> None:
    """Remove the module's cached bytecode: a mutant and the original may share size and mtime second, and Python
    would then run the other one's .pyc."""
    for pyc in (path.parent / "__pycache__").glob(f"{path.stem}.*.pyc"):
        pyc.unlink(missing_ok=True)


def run_tests(root: Path, tests: tuple[str, ...], timeout: float) -> tuple[str, float, str]:
    """(KILLED | SURVIVED | TIMEOUT | ERROR, seconds, the output's tail) of pytest on the mapped tests."""
    env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1"}
    command = [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", "-p", "no:randomly", "-n", "0", *tests]
    start = time.monotonic()
    process = subprocess.Popen(command, cwd=root, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                               text=True, start_new_session=True)  # its own group: a timeout ends its workers too
    try:
        output, _ = process.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        process.communicate()
        return TIMEOUT, time.monotonic() - start, ""
    except BaseException:  # Ctrl-C: end the tests before the original is put back
        os.killpg(process.pid, signal.SIGKILL)
        process.wait()
        raise
    seconds = time.monotonic() - start
    tail = "\n".join(output.strip().splitlines()[-3:])
    # 1: tests failed. 0: all passed. Anything else (no tests collected, a usage or internal error) says nothing.
    return {0: SURVIVED, 1: KILLED}.get(process.returncode, ERROR), seconds, tail


def mutate_and_test(root: Path, mutant: Mutant, tests: tuple[str, ...], timeout: float) -> tuple[str, float, str]:
    path = root / mutant.file
    original = path.read_bytes()
    stat = path.stat()
    try:
        path.write_bytes(original.replace(mutant.old.encode(), mutant.new.encode(), 1))
        _drop_bytecode(path)
        return run_tests(root, tests, timeout)
    finally:
        path.write_bytes(original)
        os.utime(path, ns=(stat.st_atime_ns, stat.st_mtime_ns))
        _drop_bytecode(path)


def _terminate(signum, frame):  # SIGTERM: leave through the finally that puts the original back
    raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--list", action="store_true", help="check and list the mutants; run nothing")
    parser.add_argument("--module", action="append", help="only this module (repeatable)")
    parser.add_argument("--only", action="append", help="only this mutant id, e.g. gate-3 (repeatable)")
    parser.add_argument("--threshold", type=float, default=90.0, help="the lowest passing score, %% (default 90)")
    parser.add_argument("--timeout", type=float, help="s per mutant (default: 3x the mapped tests' clean run + 30)")
    parser.add_argument("--root", type=Path, default=ROOT, help=argparse.SUPPRESS)  # tests: a toy project
    args = parser.parse_args(argv)
    root = args.root.resolve()
    modules = load(root)
    equivalent = load_equivalent(root)
    wrong = problems(root, modules, equivalent)
    if wrong:
        print("\n".join(wrong), file=sys.stderr)
        return 2
    if args.module:
        unknown = set(args.module) - {m.name for m in modules}
        if unknown:
            print(f"--module: unknown {', '.join(sorted(unknown))}; valid: {', '.join(m.name for m in modules)}",
                  file=sys.stderr)
            return 2
        modules = [m for m in modules if m.name in args.module]
    argued = {(e["module"], e["old"], e["new"]): e["why"] for e in equivalent}
    if args.list:
        for module in modules:
            source = (root / module.file).read_text()
            print(f"{module.name}: {module.file}, {len(module.mutants)} mutants, tests: {' '.join(module.tests)}")
            for m in module.mutants:
                mark = "  (equivalent)" if (m.module, m.old, m.new) in argued else ""
                print(f"  {m.id:14} line {line_of(source, m.old):4}: {m.old!r} -> {m.new!r}{mark}")
        return 0
    changed = dirty(root, [m.file for m in modules])
    if changed:
        print(f"refusing to mutate files with uncommitted changes: {', '.join(changed)}", file=sys.stderr)
        return 2
    signal.signal(signal.SIGTERM, _terminate)
    try:
        return _run(root, modules, argued, args)
    except KeyboardInterrupt:
        print("interrupted: every mutated file was put back", file=sys.stderr)
        return 130


def _run(root: Path, modules: list[Module], argued: dict, args: argparse.Namespace) -> int:
    started = time.monotonic()
    totals: dict[str, int] = {}
    survivors = []
    for module in modules:
        chosen = [m for m in module.mutants if not args.only or m.id in args.only]
        if not chosen:
            continue
        outcome, seconds, tail = run_tests(root, module.tests, 3600)
        if outcome != SURVIVED:
            print(f"{module.name}: the mapped tests do not pass on the unmutated code ({outcome}):\n{tail}",
                  file=sys.stderr)
            return 2
        limit = args.timeout or 3 * seconds + 30
        source = (root / module.file).read_text()
        counts = dict.fromkeys((KILLED, SURVIVED, EQUIV, TIMEOUT, ERROR), 0)
        module_start = time.monotonic()
        for m in chosen:
            if (m.module, m.old, m.new) in argued:
                outcome, took = EQUIV, 0.0
            else:
                outcome, took, tail = mutate_and_test(root, m, module.tests, limit)
            counts[outcome] += 1
            where = f"{m.file}:{line_of(source, m.old)}"
            print(f"  {m.id:14} {outcome:10} {took:5.1f} s  {where}: {m.old!r} -> {m.new!r}", flush=True)
            if outcome in (SURVIVED, ERROR):
                survivors.append((m, outcome, where, tail))
        detected = counts[KILLED] + counts[TIMEOUT] + counts[EQUIV]
        print(f"{module.name}: {len(chosen)} mutants: {counts[KILLED]} killed, {counts[SURVIVED]} survived, "
              f"{counts[EQUIV]} equivalent, {counts[TIMEOUT]} timeout, {counts[ERROR]} error; score "
              f"{100 * detected / len(chosen):.0f}%; {time.monotonic() - module_start:.0f} s (clean run "
              f"{seconds:.0f} s)", flush=True)
        for key, value in counts.items():
            totals[key] = totals.get(key, 0) + value
    total = sum(totals.values())
    if not total:
        print("no mutants chosen", file=sys.stderr)
        return 2
    detected = totals[KILLED] + totals[TIMEOUT] + totals[EQUIV]
    score = 100 * detected / total
    print(f"total: {total} mutants: {totals[KILLED]} killed, {totals[SURVIVED]} survived, {totals[EQUIV]} "
          f"equivalent, {totals[TIMEOUT]} timeout, {totals[ERROR]} error; score {score:.1f}% (threshold "
          f"{args.threshold:g}%); {time.monotonic() - started:.0f} s")
    for m, outcome, where, tail in survivors:
        print(f"{outcome}: {m.id} {where}: {m.old!r} -> {m.new!r}" + (f"\n{tail}" if outcome == ERROR else ""))
    return 0 if score >= args.threshold and not totals[ERROR] else 1


if __name__ == "__main__":
    sys.exit(main())
