#!/usr/bin/env bash
# The viewer's browser tests drive Debian's Chromium through Playwright (no browser download).
# Installed with apt when missing and we are root, otherwise the command is printed.
set -u
if [ -x /usr/bin/chromium ]; then exit 0; fi
if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
  echo "Chromium is missing; installing Debian's chromium for the viewer tests"
  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null
  [ -x /usr/bin/chromium ] && exit 0
fi
echo "error: /usr/bin/chromium is missing (the viewer tests need it); run: sudo apt-get install -y chromium" >&2
exit 1
