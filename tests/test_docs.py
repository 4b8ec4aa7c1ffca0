"""The repository documents itself (issue 12): every citation of docs/DESIGN.md, docs/FORMULARY.md, docs/ENGINES.md
and of the seeds in the code's comments, docstrings and strings resolves to a heading or identifier in docs/, and no
such text names a file the repository does not have."""
from __future__ import annotations

import ast
import io
import re
import tokenize
from functools import cache
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
SCANNED = ("harness", "reference", "stereodyn", "tests", "tools")

# A formula id (G15, T5, F1, C4, H2) or a section (§0); a range "G12–G15" or "F1-F13" counts both ends.
_ITEM = r"(?:§\s?\d+(?:\.\d+)?|[A-Z]\d{1,2})(?:\s?[–-]\s?(?:[A-Z])?\d{1,2})?"
_LIST = rf"{_ITEM}(?:\s*(?:,|and)\s*{_ITEM})*"
CITATION = re.compile(rf"\b(DESIGN|FORMULARY|ENGINES)(?:\.md)?(?:'s)?(?:,?\s+({_LIST}))?(?![\w-])")
SEED = re.compile(r"\bseeds?\s+(\d{3})\b|\((\d{3})(?=[,\s]+(?:eq\.|§|Example))|\b(\d{3})\s+(?:eq\.|§)")
# Paths to check: a relative path with a folder and a file extension, or a bare NAME.md.
PATH = re.compile(r"(?<![\w/.~<$-])((?:\.\./|\./)*(?:[\w.-]+/)+[\w.-]+\.(?:py|md|toml|txt|json|csv|cfg|ini|yml|yaml))"
                  r"|(?<![\w/.-])([A-Z][A-Z_]+\.md)\b")


def _sources() -> list[Path]:
    files = [p for folder in SCANNED for p in sorted((ROOT / folder).rglob("*.py"))]
    files += sorted((ROOT / "cases").rglob("*.toml"))
    return files + [ROOT / "README.md", *sorted(DOCS.glob("*.md"))]


@cache
def texts(path: Path) -> list[tuple[int, str]]:
    """(line, text) of every comment and string constant (docstrings included) of a Python file; the whole text of
    any other file."""
    source = path.read_text(encoding="utf-8")
    if path.suffix != ".py":
        return list(enumerate(source.splitlines(), 1))
    found = [(tok.start[0], tok.string) for tok in tokenize.generate_tokens(io.StringIO(source).readline)
             if tok.type == tokenize.COMMENT]
    found += [(node.lineno, node.value) for node in ast.walk(ast.parse(source))
              if isinstance(node, ast.Constant) and isinstance(node.value, str)]
    return found


def _headings(doc: str) -> dict[str, str]:
    """Section number -> the section's text, from '## N. Title' headings."""
    parts = re.split(r"^## (\d+)\.", (DOCS / doc).read_text(encoding="utf-8"), flags=re.M)
    return {parts[i]: parts[i + 1] for i in range(1, len(parts) - 1, 2)}


def formula_ids() -> set[str]:
    """Every identifier defined in the formulary: a bold 'F1', 'G15', 'T5' at the head of an entry."""
    return set(re.findall(r"\*\*([A-Z]\d{1,2})\b", (DOCS / "FORMULARY.md").read_text(encoding="utf-8")))


def seed_entries() -> set[str]:
    """The seeds the bibliography (FORMULARY §7) lists: '* **000** — ...'."""
    return set(re.findall(r"^\* \*\*(\d{3})\*\* —", _headings("FORMULARY.md")["7"], flags=re.M))


def _expand(item: str) -> list[str]:
    """'G12–G15' -> ['G12', 'G15'] (both ends must exist), '§6.4' -> ['§6.4'], 'T5' -> ['T5']."""
    item = re.sub(r"\s", "", item)
    if item.startswith("§"):
        return [item]
    first, _, last = item.replace("–", "-").partition("-")
    if not last:
        return [first]
    return [first, last if last[0].isalpha() else first[0] + last]


def unresolved(doc: str, items: list[str]) -> list[str]:
    """The cited items of doc that docs/ does not define."""
    sections, ids, bad = _headings(f"{doc}.md"), formula_ids(), []
    for item in items:
        if item.startswith("§"):
            number, _, sub = item[1:].partition(".")
            if number not in sections or (sub and not re.search(rf"^{sub}\. ", sections[number], flags=re.M)):
                bad.append(item)
        elif doc != "FORMULARY" or item not in ids:
            bad.append(item)
    return bad


def citations() -> list[tuple[str, int, str, list[str]]]:
    """(file, line, document, items) of every citation of a document in the scanned texts."""
    found = []
    for path in _sources():
        for line, text in texts(path):
            for match in CITATION.finditer(text):
                items = [part for item in re.split(r"\s*(?:,|and)\s*", match[2] or "") if item
                         for part in _expand(item)]
                found.append((str(path.relative_to(ROOT)), line, match[1], items))
    return found


def test_the_documents_exist_and_define_what_the_code_cites():
    assert {p.name for p in DOCS.glob("*.md")} >= {"README.md", "DESIGN.md", "FORMULARY.md", "ENGINES.md"}
    assert set(_headings("DESIGN.md")) >= {"1", "2", "3", "4", "5", "6"}
    assert set(_headings("FORMULARY.md")) >= {"0", "5", "6", "7"}
    # the identifiers of the formulary: Ferrarese F1-F13, Canarutto C1-C5, the textbook T1-T9, Grioli G1-G15
    expected = {f"F{i}" for i in range(1, 14)} | {f"C{i}" for i in range(1, 6)} | {f"T{i}" for i in range(1, 10)} \
        | {f"G{i}" for i in range(1, 16)}
    assert expected <= formula_ids()
    assert seed_entries() == {"000", "001", "002", "003"}


def test_every_citation_resolves():
    found = citations()
    # the code cites the documents about 120 times (counted on main before 0.2.0): a scanner that found few would be
    # broken, not clean
    assert len(found) >= 100, len(found)
    bad = [f"{file}:{line}: {doc} {', '.join(items)}" for file, line, doc, items in found
           if (missing := unresolved(doc, items))]
    assert not bad, "citations that resolve to nothing in docs/:\n" + "\n".join(bad)


def test_every_seed_citation_resolves_to_the_bibliography():
    entries, bad, count = seed_entries(), [], 0
    for path in _sources():
        for line, text in texts(path):
            for match in SEED.finditer(text):
                count += 1
                seed = next(group for group in match.groups() if group)
                if seed not in entries:
                    bad.append(f"{path.relative_to(ROOT)}:{line}: seed {seed}")
    assert count >= 5, count  # "seed 000", "(002, eq. 30)", "002 §III", ... exist today
    assert not bad, "\n".join(bad)


def _exists(path: str, cited_in: Path) -> bool:
    """A cited path exists relative to the repository root, the citing file's folder, docs/, or as a package path
    (stereodyn/harness/x.py is harness/x.py)."""
    candidates = [ROOT / path, cited_in.parent / path, DOCS / path]
    for package, folder in (("stereodyn/harness/", "harness/"), ("stereodyn/reference/", "reference/"),
                            ("stereodyn/cases/", "cases/")):
        if path.startswith(package):
            candidates.append(ROOT / folder / path[len(package):])
    return any(candidate.resolve().is_relative_to(ROOT) and candidate.exists() for candidate in candidates)


# A file named alone in backquotes (`gate.py`, `quick.toml`): some file of the repository must have that name.
NAMED_FILE = re.compile(r"`([A-Za-z_][\w.-]*\.(?:py|md|toml))`")

# Output folders named in the text (DIR/results.csv, out/report.md): what a run writes, not files of the repository.
OUTPUT_FOLDERS = re.compile(r"^(?:[A-Z_]+|out|out_dir|tmp)/")


def test_no_text_cites_a_file_the_repository_lacks():
    bad = []
    for path in _sources():
        if path == Path(__file__).resolve():  # this file names missing paths on purpose
            continue
        for line, text in texts(path):
            for match in PATH.finditer(text):
                cited = match[1] or match[2]
                if not OUTPUT_FOLDERS.match(cited) and not _exists(cited, path):
                    bad.append(f"{path.relative_to(ROOT)}:{line}: {cited}")
    names = {p.name for p in ROOT.rglob("*") if ".git" not in p.parts}
    for path in _sources():
        if path == Path(__file__).resolve():
            continue
        for line, text in texts(path):
            bad += [f"{path.relative_to(ROOT)}:{line}: {name}" for name in NAMED_FILE.findall(text)
                    if name not in names]
    assert not bad, "files cited but not in the repository:\n" + "\n".join(bad)


@pytest.mark.parametrize("text, doc, items", [
    ("(FORMULARY G12–G15)", "FORMULARY", ["G12", "G15"]),
    ("(FORMULARY T8, T9, G5, G10)", "FORMULARY", ["T8", "T9", "G5", "G10"]),
    ("(DESIGN §3, §4)", "DESIGN", ["§3", "§4"]),
    ("(DESIGN §6.4): best of N", "DESIGN", ["§6.4"]),
    ("(FORMULARY G5-G8), NaN", "FORMULARY", ["G5", "G8"]),
    ("as ENGINES.md says", "ENGINES", []),
    ("FORMULARY G11's exactly representable body", "FORMULARY", ["G11"]),
])
def test_the_scanner_reads_the_citation_forms_in_use(text, doc, items):
    (match,) = CITATION.finditer(text)
    assert match[1] == doc
    assert [part for item in re.split(r"\s*(?:,|and)\s*", match[2] or "") if item for part in _expand(item)] == items


def test_unresolved_citations_and_missing_files_are_caught():
    assert unresolved("FORMULARY", ["G16", "G15", "§9"]) == ["G16", "§9"]
    assert unresolved("DESIGN", ["§4", "§6.9", "§8"]) == ["§6.9", "§8"]
    assert unresolved("ENGINES", ["§1"]) == ["§1"]  # ENGINES.md has no numbered sections
    assert not _exists("../shared/DESIGN.md", ROOT / "harness" / "x.py")
    assert not _exists("shared/FORMULARY.md", ROOT / "harness" / "x.py")
    assert _exists("harness/cli/__init__.py", ROOT / "README.md") and _exists("DESIGN.md", ROOT / "harness" / "x.py")
