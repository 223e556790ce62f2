#!/usr/bin/env bash
# Install curltrack with its test extras into .venv (if needed) and run the test suite.
# Extra arguments go to pytest, e.g. `scripts/test.sh -m slow` for the long cases.
set -euo pipefail
source "$(dirname "$0")/_venv.sh" test
cd "$ROOT"
exec python -m pytest -q -n "${CURLTRACK_TEST_WORKERS:-2}" "$@"
