"""`stereodyn check`'s outputs for CI systems: JUnit XML (one test case per gated row and per fitted order, so a CI
shows a failure natively) and a markdown summary (GitHub's step summary, GITHUB_STEP_SUMMARY)."""
from __future__ import annotations

from xml.etree import ElementTree

from ..analysis import gate
from ..precision import FLOAT64
from .markdown import markdown_table, md_text

STEP_SUMMARY_ROWS = 30  # findings listed in the step summary; the log and the JUnit file have every one


def _name(key: tuple) -> str:
    """A row or order as a test case name: 'lagrange-top quaternion rk4 dt=0.01' ('order' for a fitted order)."""
    case, engine, formulation, integrator, precision = key[:5]
    tail = "order" if key[-1] == "order" else f"dt={key[5] or 'adaptive'}"
    return " ".join(x for x in (case, formulation, integrator, "" if precision == FLOAT64 else precision, tail) if x)


def _reason(finding: gate.Finding) -> str:
    return (f"{finding.what}: baseline {finding.baseline}, now {finding.current}, allowed {finding.allowed}"
            + (f" ({finding.message})" if finding.message else ""))


def junit(baseline: gate.Baseline, verdict: gate.Verdict, headline: str) -> str:
    """JUnit XML: a test suite `stereodyn check` of one test case per baseline row and per fitted order (class name
    `stereodyn.ENGINE`), each failed one carrying its findings; the failures are the rows and orders the headline
    counts."""
    failed: dict[tuple, list[gate.Finding]] = {}
    for finding in (*verdict.findings, *verdict.order_findings):
        failed.setdefault(finding.key, []).append(finding)
    keys = [gate._key(row) for row in baseline.rows] + [(*gate._order_key(row), "order") for row in baseline.orders]
    suites = ElementTree.Element("testsuites", name="stereodyn check")
    suite = ElementTree.SubElement(suites, "testsuite", name="stereodyn check", tests=str(len(keys)),
                                   failures=str(sum(key in failed for key in keys)), errors="0", skipped="0")
    for key in keys:
        case = ElementTree.SubElement(suite, "testcase", classname=f"stereodyn.{key[1]}", name=_name(key))
        if key in failed:
            reasons = [_reason(f) for f in failed[key]]
            failure = ElementTree.SubElement(case, "failure", message=reasons[0], type=failed[key][0].what)
            failure.text = "\n".join(reasons)
    ElementTree.SubElement(suite, "system-out").text = headline
    ElementTree.indent(suites)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ElementTree.tostring(suites, encoding="unicode") + "\n"


def step_summary(verdict: gate.Verdict, headline: str, context: list[str], groups: list[str]) -> str:
    """The markdown of a check for GitHub's step summary: the headline, the environment and mode lines, the grouped
    findings and the first STEP_SUMMARY_ROWS of them as a table."""
    # every value escaped as compare --format pr does (md_text): a case name or environment value holding <script>,
    # backticks or a link rendered as such in GitHub's page (issue 46's eighth attack)
    lines = [f"### stereodyn {md_text(headline)}", "", *(f"- {md_text(line)}" for line in context), ""]
    findings = [*verdict.findings, *verdict.order_findings]
    if findings:
        lines += [*(f"- {md_text(line)}" for line in groups), ""]
        rows = [[md_text(cell) for cell in (_name(f.key), f.key[1], f.what, f.baseline, f.current, f.allowed,
                                            f.message)] for f in findings[:STEP_SUMMARY_ROWS]]
        lines += markdown_table(["row", "engine", "what", "baseline", "now", "allowed", "message"], rows) + [""]
        if len(findings) > STEP_SUMMARY_ROWS:
            lines += [f"... and {len(findings) - STEP_SUMMARY_ROWS} more in the log.", ""]
    return "\n".join(lines) + "\n"
