#!/usr/bin/env bash
# hwid beside the oldest numba and numpy that pyproject.toml's lower bounds allow: a fresh virtual
# environment with exactly those two (read from the "numba>=" and "numpy>=" lines, so raising a bound
# moves the check with it), hwid installed in it with its test extra, then tests/test_noise.py (the
# noise stream against numpy's, through numba's public Generator support) and tests/test_simulate.py.
# Not part of CI: it downloads about 200 MB. numba keeps its cache in the environment, so the
# kernels cached for the developer's own numba are left alone.
#
# Usage: bash benchmarks/check_oldest.sh [VENV_DIR]    (default /tmp/hwid-oldest, recreated)
#        PY=/path/to/python3.11 bash benchmarks/check_oldest.sh
#        (default python3.11: requires-python's floor)
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PY:-python3.11}
VENV=${1:-${TMPDIR:-/tmp}/hwid-oldest}
bound() { sed -nE "s/^ *\"$1>=([0-9][0-9.]*)\".*/\1/p" pyproject.toml; }
NUMBA=$(bound numba)
NUMPY=$(bound numpy)
if [ -z "$NUMBA" ] || [ -z "$NUMPY" ]; then
  echo "check_oldest: pyproject.toml has no plain lower bound \"numba>=X\" and \"numpy>=Y\"" >&2
  exit 2
fi
if ! command -v "$PY" >/dev/null 2>&1; then
  echo "check_oldest: $PY not found; set PY=/path/to/python3.11" >&2
  exit 2
fi
if [ -e "$VENV" ] && [ ! -f "$VENV/pyvenv.cfg" ]; then
  echo "check_oldest: $VENV exists and is not a virtual environment; name another folder" >&2
  exit 2
fi
rm -rf "$VENV"
"$PY" -m venv "$VENV"
"$VENV/bin/python" -m pip install -q --upgrade pip
printf 'numba==%s\nnumpy==%s\n' "$NUMBA" "$NUMPY" > "$VENV/constraints.txt"
"$VENV/bin/python" -m pip install -q --prefer-binary -c "$VENV/constraints.txt" -e '.[test]'
"$VENV/bin/python" -c 'import sys, numba, numpy
print(f"Python {sys.version.split()[0]}, numba {numba.__version__}, numpy {numpy.__version__}")'
NUMBA_CACHE_DIR="$VENV/numba-cache" "$VENV/bin/python" -m pytest -q -n 0 -p no:cacheprovider \
  tests/test_noise.py tests/test_simulate.py
