#!/usr/bin/env bash
# CI for the Python package (python/): a venv under <target>/py-venv with maturin, pytest, numpy
# and OpenEXR (an EXR reader we did not write), the nephele CLI and the abi3 wheel built in
# release into <target> ($CARGO_TARGET_DIR if set, else the repository's target/), the wheel
# installed, then pytest.
# Skips (exit 0, said plainly) only when the Python package index cannot be reached; under
# NEPHELE_REQUIRE_READERS=1 (as .ci/run sets: CI reaches the index) it fails (exit 1) then.
# Usage: bash python/ci.sh [pytest args]   (from anywhere; needs cargo and python3 >= 3.9 with venv)
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
PY=${PYTHON:-python3}
export CARGO_TARGET_DIR=${CARGO_TARGET_DIR:-$ROOT/target}
TARGET=$CARGO_TARGET_DIR
VENV=$TARGET/py-venv
start=$(date +%s)

if ! "$PY" -c 'import sys; sys.exit(sys.version_info < (3, 9))'; then
  echo "python/ci.sh: $PY is older than 3.9; the package needs 3.9+" >&2
  exit 1
fi
if [ ! -x "$VENV/bin/python" ]; then
  "$PY" -m venv "$VENV" || {
    apt-get update -qq && apt-get install -y -qq python3-venv && "$PY" -m venv "$VENV"
  }
fi
if ! "$VENV/bin/python" -c 'import maturin, pytest, numpy, OpenEXR' 2>/dev/null; then
  if ! "$VENV/bin/pip" install -q --disable-pip-version-check "maturin>=1.5,<2" pytest numpy "OpenEXR>=3.2"; then
    # Tell an unreachable index (skip) from a real install failure (fail).
    if ! "$VENV/bin/pip" download -q --no-deps --disable-pip-version-check -d "$TARGET/py-probe" pip >/dev/null 2>&1; then
      why="the Python package index is unreachable, so maturin, pytest, numpy and OpenEXR cannot be installed; the Python bindings were not tested"
      if [ "${NEPHELE_REQUIRE_READERS:-}" = 1 ]; then
        echo "FAILED python/ci.sh: $why (NEPHELE_REQUIRE_READERS=1)" >&2
        exit 1
      fi
      echo "SKIPPED python/ci.sh: $why"
      exit 0
    fi
    echo "python/ci.sh: pip could not install maturin, pytest, numpy, OpenEXR (see above)" >&2
    exit 1
  fi
fi

echo "== building the nephele CLI (release) and the abi3 wheel"
cargo build --release --quiet
rm -f "$TARGET"/wheels/nephele-*.whl
"$VENV/bin/maturin" build --release --quiet -m python/Cargo.toml -o "$TARGET/wheels"
wheel=$(ls "$TARGET"/wheels/nephele-*-abi3-*.whl)
"$VENV/bin/pip" install -q --disable-pip-version-check --force-reinstall --no-deps "$wheel"
echo "== installed $(basename "$wheel")"

echo "== pytest python/tests"
cd "$ROOT/python/tests"
NEPHELE_BIN=$TARGET/release/nephele "$VENV/bin/python" -m pytest -q -p no:cacheprovider . "$@"
echo "python/ci.sh: done in $(( $(date +%s) - start )) s"
