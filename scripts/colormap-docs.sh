#!/usr/bin/env bash
# Regenerate the figures of docs/colormaps.md: `prefilter compare` on the Gaussian presets (1024 spp) and
# the error-against-distance plot of `prefilter bench noise-plane`.
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p docs/images/colormaps out/docs
for preset in noise-plane seascape marble-cube terrain-contours terrain-data; do
  .venv/bin/prefilter compare "$preset" -o "out/docs/$preset" | tee "out/docs/$preset.md"
  cp "out/docs/$preset/strip.png" "docs/images/colormaps/$preset.png"
  cp "out/docs/$preset/flip.png" "docs/images/colormaps/$preset-flip.png"
done
.venv/bin/prefilter render seascape --mode gaussian-sigma -o docs/images/colormaps/seascape-sigma.png
.venv/bin/prefilter bench noise-plane terrain-contours terrain-data --json out/docs/bench-colormaps.json \
  --plots out/docs/bench | tee out/docs/bench-colormaps.txt
cp out/docs/bench/error-vs-distance.png docs/images/colormaps/error-vs-distance.png
