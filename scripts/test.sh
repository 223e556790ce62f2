#!/usr/bin/env bash
# Install curltrack with its test extras into .venv (if needed) and run the test suite.
# Extra arguments go to pytest, e.g. `scripts/test.sh -m slow` for the long cases.
set -euo pipefail
CURLTRACK_EXTRAS=test source "$(dirname "$0")/_venv.sh"
cd "$ROOT"
exec python -m pytest -q -n "${CURLTRACK_TEST_WORKERS:-2}" "$@"
