# Sourced by test.sh / demo.sh: create or refresh .venv and install curltrack
# (with the extras named in CURLTRACK_EXTRAS, e.g. "test").
# Works on a fresh machine (only python3 >= 3.11 needed; packages from the registry).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
PY="${PYTHON:-python3}"
VENV="$ROOT/.venv"
EXTRAS="${CURLTRACK_EXTRAS:-}"
if [ ! -x "$VENV/bin/python" ]; then
  echo "[curltrack] creating virtual environment in $VENV" >&2
  "$PY" -m venv "$VENV"
fi
STAMP="$VENV/.installed${EXTRAS:+-$EXTRAS}"
if [ ! -f "$STAMP" ] || [ "$ROOT/pyproject.toml" -nt "$STAMP" ]; then
  echo "[curltrack] installing curltrack${EXTRAS:+[$EXTRAS]} and its dependencies" >&2
  "$VENV/bin/python" -m pip install -q --upgrade pip >&2
  # editable_mode=compat: the clone's root on sys.path (a .pth), so `import curltrack` also
  # works from the folder that holds the clone (there, the clone's own folder "curltrack"
  # would otherwise be taken for an empty namespace package)
  "$VENV/bin/python" -m pip install -q -e "$ROOT${EXTRAS:+[$EXTRAS]}" \
    --config-settings editable_mode=compat >&2
  touch "$STAMP"
fi
export PATH="$VENV/bin:$PATH"
# Two cores: keep BLAS/OpenCV from oversubscribing when pytest-xdist runs 2 workers.
export OMP_NUM_THREADS="${OMP_NUM_THREADS:-1}" OPENBLAS_NUM_THREADS="${OPENBLAS_NUM_THREADS:-1}"
export MPLBACKEND=Agg
