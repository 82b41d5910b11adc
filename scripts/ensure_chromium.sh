#!/usr/bin/env bash
# Make sure a Chromium is on PATH for the real-browser test of `simcred report`
# (tests/report/test_html.py). If neither `chromium` nor `chromium-browser` is found, install Debian's
# `chromium` package with apt-get (non-interactive; as root, or through sudo when available).
# Exit 0 when a Chromium is available at the end, 1 otherwise.
set -uo pipefail

find_chromium() {
  command -v chromium 2>/dev/null || command -v chromium-browser 2>/dev/null
}

if found=$(find_chromium); then
  echo "ensure_chromium: found $found ($("$found" --version 2>/dev/null || echo 'version unknown'))"
  exit 0
fi

if ! command -v apt-get >/dev/null 2>&1; then
  echo "ensure_chromium: no chromium on PATH and no apt-get to install it;" \
       "install Chromium by hand (a 'chromium' or 'chromium-browser' on PATH)" >&2
  exit 1
fi

if [ "$(id -u)" -eq 0 ]; then
  as_root=()
elif command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then
  as_root=(sudo -n)
else
  echo "ensure_chromium: no chromium on PATH, and installing it needs root (run as root, or" \
       "allow passwordless sudo): apt-get install chromium" >&2
  exit 1
fi

export DEBIAN_FRONTEND=noninteractive
echo "ensure_chromium: no chromium on PATH; installing Debian's 'chromium' package with apt-get"
"${as_root[@]}" apt-get update -q || echo "ensure_chromium: apt-get update failed (continuing)" >&2
if ! "${as_root[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y -q \
     --no-install-recommends chromium; then
  echo "ensure_chromium: 'apt-get install chromium' failed" >&2
fi

if found=$(find_chromium); then
  echo "ensure_chromium: installed $found ($("$found" --version 2>/dev/null || echo 'version unknown'))"
  exit 0
fi
echo "ensure_chromium: Chromium is still not on PATH after the install attempt;" \
     "the browser test of the HTML report cannot run" >&2
exit 1
