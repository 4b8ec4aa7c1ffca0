"""`stereodyn compare A B`: two runs side by side."""
from __future__ import annotations

import os
from contextlib import ExitStack

from .common import _allow_partial, _path, output_folder, warn


def add_parser(commands) -> None:
    compare = commands.add_parser("compare", help="two runs side by side: environments, then every row's metrics as "
                                                   "ratios B/A, largest changes first (OUT/compare.md, OUT/compare.html)")
    compare.add_argument("a", type=_path, metavar="A", help="result directory or baseline file (the reference)")
    compare.add_argument("b", type=_path, metavar="B", help="result directory or baseline file (the new run)")
    compare.add_argument("--out", type=_path, default=None, metavar="DIR", help="where to write (default: B)")
    compare.add_argument("--format", choices=("pages", "pr"), default="pages",
                         help="pages (default): write compare.md, compare.html, compare.csv; pr: also print a "
                              "markdown summary of at most 60 lines for a pull request (OUT/compare-pr.md)")
    _allow_partial(compare)


def main(args) -> int:
    from ..report.compare import compare
    from ..run.store import STORE_DIR, completeness, folder_lock, reading

    if args.out is not None:  # a folder or a new path: /dev/null or a FIFO is refused naming the option
        output_folder(args.out, "--out", store=False)
    out = args.out if args.out is not None else args.b
    warnings: list[str] = []
    with ExitStack() as held:
        # The folder written (B or --out) is locked as `run` locks it, when it is a result folder; the folders read
        # are read only when no command writes them, and complete (or --allow-partial).
        written = (out / STORE_DIR).is_dir()
        if written:
            held.enter_context(folder_lock(out))
        for folder in dict.fromkeys(p for p in (args.a, args.b) if p.is_dir()):
            same = written and os.path.realpath(folder) == os.path.realpath(out)
            warnings += (completeness(folder, args.allow_partial) if same
                         else held.enter_context(reading(folder, args.allow_partial)))
        markdown, html, head = compare(args.a, args.b, args.out, pr=args.format == "pr")
    warn(warnings)  # once the tables read: a folder that cannot be read is one line, the error
    print("\n".join(head))
    if args.format != "pr":  # pr: standard output is the summary alone, to paste or redirect as it is
        print(f"wrote {markdown} and {html}")
    return 0
