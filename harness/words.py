"""Words for a reader, shared by every layer: a count with its noun in the right number; a text on one line."""
from __future__ import annotations


def plural(count: int, word: str, words: str | None = None) -> str:
    """'1 run', '2 runs' ('1 more reason', '3 more reasons')."""
    return f"{count} {word if count == 1 else words or word + 's'}"


def one_line(text: str) -> str:
    """text with each unprintable character (a newline, ESC) written as its escape (\\n, \\x1b): a name, a path or a
    plug-in's message stays one line of a listing, a table row or a warning (a raw one printed 50 lines in a run's
    summary and broke report.md's tables: issue 46)."""
    return "".join(c if c.isprintable() else ascii(c)[1:-1] for c in str(text))
