#!/usr/bin/env bash
# Installs furrow from this working tree into a FRESH virtual environment (pip install, not
# editable) outside the tree, then runs the installed CLI from an empty folder, so nothing of the
# source checkout is on sys.path: `furrow bench render --help`, `furrow eval --help`, and
# synth -> model -> render of a small fur ball (shaders, env maps and bench modules must come
# from the installed package).
#   usage: scripts/check_install.sh [VENV_DIR]   (default: a new temporary folder, removed after)
# Needs network access to the package index (or its cache) and the Debian packages of `make setup`.
set -euo pipefail
SRC=$(cd "$(dirname "$0")/.." && pwd)
TMP=$(mktemp -d /tmp/furrow-install.XXXXXX)
VENV=${1:-$TMP/venv}
cleanup() { rm -rf "$TMP"; }
trap cleanup EXIT

# Copy the tracked + untracked-not-ignored files only: a stale build/ or .venv never leaks in.
mkdir -p "$TMP/src"
(cd "$SRC" && git ls-files -co --exclude-standard -z | xargs -0 tar -cf - 2>/dev/null) | tar -xf - -C "$TMP/src"

echo "== python3 -m venv $VENV && pip install $TMP/src (not editable)"
python3 -m venv "$VENV"
"$VENV/bin/python" -m pip install -q --upgrade pip
"$VENV/bin/python" -m pip install -q "$TMP/src"
rm -rf "$TMP/src"

mkdir -p "$TMP/run"
cd "$TMP/run"
export OMP_WAIT_POLICY=passive
F="$VENV/bin/furrow"
echo "== furrow comes from: $("$VENV/bin/python" -c 'import furrow, render; print(furrow.__file__, render.__file__)')"
"$VENV/bin/python" - <<'PY'
import furrow, render, furrow.bench, sys
site = [p for p in sys.path if p.endswith("site-packages")]
for m in (furrow, render, furrow.bench):
    assert any(m.__file__.startswith(s) for s in site), f"{m.__name__} not from site-packages: {m.__file__}"
PY
echo "== furrow bench render --help"
"$F" bench render --help | head -3
echo "== furrow bench (unknown name lists the installed benchmarks)"
"$F" bench nosuch 2>&1 | tail -1 || true
echo "== furrow eval --help"
"$F" eval --help | head -3
echo "== furrow synth furball --small"
"$F" synth furball --small -o scan
echo "== furrow model"
"$F" model scan -o model --max-res 32 --mesh-faces 5000 --quorum 2
echo "== furrow render (microfacet) and --env sunset --ground"
"$F" render model --cameras scan --frames 0,1 -o frames
"$F" render model --cameras scan --frames 0 -o frames_env --env sunset --ground
n=$(find frames frames_env -name '*.png' | wc -l)
echo "rendered PNGs: $n"
test "$n" -ge 3
echo "check_install: OK"
