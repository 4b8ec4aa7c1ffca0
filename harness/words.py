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


# The longest text cell stereodyn writes (a row's message, an environment value, a reason): a plug-in's 5 MB message
# made a results.csv whose field every csv reader refuses (Python's csv: 131072 characters; issue 46's fourth attack,
# F4). A reader needs the first words of a reason; the cut says how much is gone.
TEXT_MAX = 2000


def clipped(text: str, limit: int = TEXT_MAX) -> str:
    """text, or its first `limit` characters and how many more there were."""
    text = str(text)
    return text if len(text) <= limit else f"{text[:limit]} … ({len(text) - limit} more characters)"
