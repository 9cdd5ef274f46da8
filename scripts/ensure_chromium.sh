#!/usr/bin/env bash
# Best effort: make a headless Chromium available for the report's browser test
# (tests/test_report.py). Installs the Debian package `chromium` when no browser is found,
# we are root and apt-get exists. Never fails: without a browser that test is skipped with
# the reason, and the rest of the suite runs.
set -u

have_browser() {
    command -v chromium >/dev/null 2>&1 || command -v chromium-browser >/dev/null 2>&1 \
        || [ -x /usr/bin/chromium ]
}

if have_browser; then
    exit 0
fi
if [ "$(id -u)" != "0" ]; then
    echo "ensure_chromium: no chromium found and not root; the browser test will be skipped" >&2
    exit 0
fi
if ! command -v apt-get >/dev/null 2>&1; then
    echo "ensure_chromium: no chromium found and no apt-get; the browser test will be skipped" >&2
    exit 0
fi
echo "ensure_chromium: installing the Debian package chromium (for the report's browser test)" >&2
export DEBIAN_FRONTEND=noninteractive
if ! { apt-get update -qq && apt-get install -y -qq --no-install-recommends chromium; } \
        >/tmp/ensure_chromium.log 2>&1; then
    echo "ensure_chromium: apt-get failed (see /tmp/ensure_chromium.log); the browser test" \
         "will be skipped" >&2
fi
exit 0
