"""Words for a reader, shared by every layer: a count with its noun in the right number."""
from __future__ import annotations


def plural(count: int, word: str, words: str | None = None) -> str:
    """'1 run', '2 runs' ('1 more reason', '3 more reasons')."""
    return f"{count} {word if count == 1 else words or word + 's'}"
