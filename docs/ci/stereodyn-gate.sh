#!/usr/bin/env bash
# Gate a plug-in integrator (docs/CI.md): the sweep on the base revision (main) becomes the baseline, the same sweep
# on the pull request's revision is checked against it, and the pull-request summary is written beside it.
#
#   stereodyn-gate.sh BASE_SRC HEAD_SRC OUT
#
# BASE_SRC, HEAD_SRC: the plug-in's source tree at the base revision and at the pull request (two checkouts).
# OUT: the folder for base/ and head/ (the runs), baseline.json, junit.xml, compare/ and pr.md (the summary).
# Both sweeps run in this job, on this machine, with these library versions: the baseline is same-machine (a drift or
# error may grow 1.05x; docs/DESIGN.md §4, Baselines).
# Settings (environment):
#   STEREODYN_GATE_SWEEP    the arguments of both `stereodyn run` (default: the quick suite on every engine; name
#                           your integrator, e.g. "... --engines reference,pinocchio --integrators my_rk")
#   STEREODYN_GATE_INSTALL  the command that installs a source tree (default: python -m pip install --quiet
#                           --force-reinstall --no-deps)
#   GITHUB_STEP_SUMMARY     set by GitHub Actions: check's summary and pr.md are appended to it
# Exit status: check's (0 passed, 1 worse than the baseline), else the failing command's (2 bad input).
set -euo pipefail
if [ $# -ne 3 ]; then
  echo "usage: $0 BASE_SRC HEAD_SRC OUT" >&2
  exit 2
fi
base_src=$1 head_src=$2 out=$3
sweep=${STEREODYN_GATE_SWEEP:-free-asymmetric lagrange-top kovalevskaya heavy-asymmetric --t-end 2 --dt 1e-2,3e-3}
install=${STEREODYN_GATE_INSTALL:-python -m pip install --quiet --force-reinstall --no-deps}
mkdir -p "$out"
# $install and $sweep stay unquoted below: each is a list of words

$install "$base_src"
stereodyn run $sweep --quiet --out "$out/base"
stereodyn baseline "$out/base" --out "$out/baseline.json" --mode same-machine > /dev/null

$install "$head_src"
stereodyn run $sweep --quiet --out "$out/head"
status=0
stereodyn check "$out/head" --baseline "$out/baseline.json" --junit "$out/junit.xml" || status=$?
if [ "$status" -gt 1 ]; then
  exit "$status"  # bad input, or a bug (3): no verdict to summarise
fi
stereodyn compare "$out/base" "$out/head" --out "$out/compare" --format pr > "$out/pr.md"
if [ -n "${GITHUB_STEP_SUMMARY:-}" ]; then
  cat "$out/pr.md" >> "$GITHUB_STEP_SUMMARY"
fi
exit "$status"
