#!/bin/bash
# The release observatory (reports/releases/, docs/ENGINES.md "Releases"): `stereodyn matrix` over the MuJoCo,
# Pinocchio and Drake releases a user meets, on the quick suite plus the cases with torque callbacks
# (constant-torque-uniform: qfrc_applied; self-excited-spinup, central-field-fixed: per-stage callbacks) and
# constraints (sliding-ladder). Run from the repository root with stereodyn installed with the matrix and drake extras:
#
#     bash tools/release_observatory.sh [WORK]      # WORK: where the matrices' run folders go (default ./observatory)
#
# then the light files (matrix.csv, orders.csv, the history pages and their step markers) are copied to
# reports/releases/ENGINE/. Measured on 2026-12-02, one job on a shared 2-core machine (load 2-9), uv's wheel cache
# warm: MuJoCo 946 s (17 environments built), Pinocchio 224 s (7, overlays), Drake 631 s (6; 2 fail to resolve).
# MuJoCo's releases run in isolated environments (each within pyproject's mujoco>=3.3.6,<5). Pinocchio's 3.x and
# Drake's below 1.51 are below pyproject's floors (pin>=4.1, drake>=1.51), which an isolated install refuses, so they
# are overlaid on this environment (--overlay) with the releases' own dependency closures pinned (uv pip compile
# 'pin==V'), and, for pin 3.4-3.9, cmeel-urdfdom 4.0.1 and cmeel-tinyxml2 10.0.0: their wheels link urdfdom 4 and
# tinyxml2 10 but declare cmeel-urdfdom>=4, and a resolver picks 6 (ImportError: liburdfdom_sensor.so.4.0;
# huggingface/lerobot#3755 reports the same).
set -euo pipefail
WORK=${1:-observatory}
RUN="free-asymmetric lagrange-top kovalevskaya heavy-asymmetric constant-torque-uniform self-excited-spinup
     central-field-fixed sliding-ladder --t-end 2 --dt 1e-2,3e-3 --no-figures --jobs 1"
PIN4="libpinocchio coal libcoal eigenpy cmeel cmeel-boost cmeel-urdfdom cmeel-assimp cmeel-octomap cmeel-qhull
      cmeel-console-bridge cmeel-tinyxml cmeel-tinyxml2 cmeel-zlib"
PIN4=$(echo $PIN4)

python -m stereodyn matrix --step-factor 10 --out "$WORK/mujoco" \
  mujoco==3.3.6 mujoco==3.3.7 mujoco==3.4.0 mujoco==3.5.0 mujoco==3.6.0 mujoco==3.7.0 mujoco==3.8.1 mujoco==3.9.0 \
  mujoco==3.10.0 mujoco==3.11.0 mujoco==3.12.0 mujoco==3.13.0 mujoco==3.14.0 mujoco==3.15.0 mujoco==3.16.0 \
  mujoco==3.17.0 mujoco==4.0.0 -- $RUN --engines mujoco
python -m stereodyn matrix --overlay --step-factor 10 --out "$WORK/pinocchio" \
  "pin==3.3.1 cmeel==0.62.0 cmeel-assimp==5.4.3.1 cmeel-boost==1.87.0.1 cmeel-console-bridge==1.0.2.3 cmeel-octomap==1.10.0 cmeel-qhull==8.0.2.1 cmeel-tinyxml==2.6.2.3 cmeel-urdfdom==3.1.1.1 cmeel-zlib==1.3.2 coal-library==3.0.1 eigenpy==3.10.3 numpy==2.3.5" \
  "pin==3.4.0 cmeel==0.62.0 cmeel-assimp==5.4.3.1 cmeel-boost==1.87.0.1 cmeel-console-bridge==1.0.2.3 cmeel-octomap==1.10.0 cmeel-qhull==8.0.2.1 cmeel-tinyxml2==10.0.0 cmeel-urdfdom==4.0.1 cmeel-zlib==1.3.2 coal-library==3.0.1 eigenpy==3.10.3 numpy==2.3.5" \
  "pin==3.7.0 cmeel==0.62.0 cmeel-assimp==5.4.3.1 cmeel-boost==1.87.0.1 cmeel-console-bridge==1.0.2.3 cmeel-octomap==1.10.0 cmeel-qhull==8.0.2.1 cmeel-tinyxml2==10.0.0 cmeel-urdfdom==4.0.1 cmeel-zlib==1.3.2 coal==3.0.1 eigenpy==3.10.3 numpy==2.3.5" \
  "pin==3.8.0 cmeel==0.62.0 cmeel-assimp==6.0.5 cmeel-boost==1.89.0 cmeel-console-bridge==1.0.2.3 cmeel-octomap==1.10.0 cmeel-qhull==8.0.2.1 cmeel-tinyxml2==10.0.0 cmeel-urdfdom==4.0.1 cmeel-zlib==1.3.2 coal==3.0.2 eigenpy==3.12.0 libcoal==3.0.2 libpinocchio==3.8.0 numpy==2.3.5" \
  "pin==3.9.0 cmeel==0.62.0 cmeel-assimp==6.0.5 cmeel-boost==1.89.0 cmeel-console-bridge==1.0.2.3 cmeel-octomap==1.10.0 cmeel-qhull==8.0.2.1 cmeel-tinyxml2==10.0.0 cmeel-urdfdom==4.0.1 cmeel-zlib==1.3.2 coal==3.0.2 eigenpy==3.12.0 libcoal==3.0.2 libpinocchio==3.9.0 numpy==2.3.5" \
  "pin==4.0.0 $PIN4" "pin==4.1.0 $PIN4" -- $RUN --engines pinocchio
python -m stereodyn matrix --overlay --step-factor 10 --out "$WORK/drake" \
  drake==1.47.0 drake==1.48.0 drake==1.49.0 drake==1.50.0 drake==1.51.0 drake==1.51.1 -- $RUN --engines drake

for engine in mujoco pinocchio drake; do
  mkdir -p "reports/releases/$engine"
  for file in matrix.csv orders.csv history.md history.html history_steps.csv history_points.csv; do
    [ -f "$WORK/$engine/$file" ] && cp "$WORK/$engine/$file" "reports/releases/$engine/"
  done
  [ -d "$WORK/$engine/figures" ] && cp -r "$WORK/$engine/figures" "reports/releases/$engine/"
done
