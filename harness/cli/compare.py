"""`stereodyn compare A B`: two runs side by side."""
from __future__ import annotations

import os
from contextlib import ExitStack

from . import output_folder, warn


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
