"""`stereodyn compare A B`: two runs side by side."""
from __future__ import annotations


def main(args) -> int:
    from ..report.compare import compare

    markdown, html, head = compare(args.a, args.b, args.out)
    print("\n".join(head))
    print(f"wrote {markdown} and {html}")
    return 0
