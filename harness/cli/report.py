"""`stereodyn report DIR`: re-render report.md, report.html and figures/ from DIR."""
from __future__ import annotations

from .common import _allow_partial, BadInput, _figures, output_folder, _path, warn


def add_parser(commands) -> None:
    report = commands.add_parser("report", help="re-render report.md, report.html and figures from DIR")
    report.add_argument("dir", type=_path)
    _allow_partial(report)
    report.add_argument("--self-contained", action="store_true",
                        help="embed the figures in report.html (one file to send; larger) instead of linking them")
    _figures(report)


def main(args) -> int:
    from ..report.build import write_reports

    from ..run.results import TableError
    from ..run.store import completeness, folder_lock

    results = args.dir / "results.csv"
    if not results.exists():  # a FIFO or a device is refused by read_results, naming what it is
        raise BadInput(f"{results}: file not found")
    output_folder(args.dir, "report DIR")
    with folder_lock(args.dir):
        warnings = completeness(args.dir, args.allow_partial)  # an unfinished folder: refused
        try:
            markdown, html = write_reports(args.dir, self_contained=args.self_contained,
                                           figures=args.figures)
        except (KeyError, ValueError, TypeError, IndexError, AttributeError) as exc:
            if isinstance(exc, TableError):
                raise
            # a table that read but does not hold what stereodyn writes (a column of text where numbers belong, ...)
            raise BadInput(f"{args.dir}: malformed tables, cannot render the report "
                           f"({type(exc).__name__}: {' '.join(str(exc).split())[:160]})") from None
    warn(warnings)  # once the tables read: a folder that cannot be read is one line, the error
    print(f"wrote {markdown} and {html}")
    return 0
