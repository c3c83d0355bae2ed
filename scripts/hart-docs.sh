#!/usr/bin/env bash
# Regenerate the figures of docs/hart.md: `prefilter compare` on every Hart preset (1024 spp), then copy
# each strip into docs/images/hart/. Takes about ten minutes on two cores with llvmpipe.
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p docs/images/hart out/docs
for preset in zone-plate wood-teapot wood-torus marble-teapot marble-cube seascape fire planet moonrise; do
  .venv/bin/prefilter compare "$preset" -o "out/docs/$preset" | tee "out/docs/$preset.md"
  cp "out/docs/$preset/strip.png" "docs/images/hart/$preset.png"
done
cp out/docs/seascape/flip.png docs/images/hart/seascape-flip.png
cp out/docs/zone-plate/flip.png docs/images/hart/zone-plate-flip.png
cp out/docs/wood-torus/hart-width.png docs/images/hart/wood-torus-width.png
