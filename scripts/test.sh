#!/usr/bin/env bash
# Install curltrack with its test extras into .venv (if needed) and run the test suite.
# Extra arguments go to pytest, e.g. `scripts/test.sh -m slow` for the long cases.
set -euo pipefail
CURLTRACK_EXTRAS=test source "$(dirname "$0")/_venv.sh"
cd "$ROOT"
# The review page's browser test drives Debian's chromium (no browser download): install it
# when we can (root with apt, as on CI); without it that test is skipped and says why.
if ! command -v chromium >/dev/null 2>&1 && [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
  echo "[curltrack] installing chromium (apt) for the review page's browser test" >&2
  { apt-get install -y -q chromium || { apt-get update -q && apt-get install -y -q chromium; }; } \
    >/dev/null 2>&1 || echo "[curltrack] could not install chromium; its test will be skipped" >&2
fi
exec python -m pytest -q -n "${CURLTRACK_TEST_WORKERS:-2}" "$@"
