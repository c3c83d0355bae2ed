#!/usr/bin/env bash
# Fetch the Utah teapot mesh (Newell 1975, public domain) from the npm registry package utah-teapot.
set -eu
dest=${1:-.cache/assets}
mkdir -p "$dest"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
if ! command -v npm >/dev/null; then
  echo "error: npm is needed once to fetch the Utah teapot (apt-get install -y npm)" >&2
  exit 1
fi
(cd "$tmp" && npm pack --silent utah-teapot@1.0.2 >/dev/null 2>&1 && tar xzf utah-teapot-1.0.2.tgz)
cp "$tmp/package/teapot.obj" "$dest/teapot.obj.part"
mv "$dest/teapot.obj.part" "$dest/teapot.obj"
