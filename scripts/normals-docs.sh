#!/usr/bin/env bash
# Regenerate the figures of docs/normals.md: `prefilter compare` on the Fournier presets (SPP samples,
# default 256), the peak-count diagnostic, and the pyramid bake report of the cylinder preset.
set -euo pipefail
cd "$(dirname "$0")/.."
SPP="${SPP:-256}"
mkdir -p docs/images/normals out/docs
for preset in normals-cylinders-plane normals-cylinders-plane-shadowed normals-hemispheres-plane \
              normals-hemispheres-sphere-shadowed normals-denim-plane normals-denim-drape-shadowed \
              normals-velvet-sphere normals-silk-sphere normals-three-normal-sphere; do
  .venv/bin/prefilter compare "$preset" --spp "$SPP" -o "out/docs/$preset" | tee "out/docs/$preset.md"
  cp "out/docs/$preset/strip.png" "docs/images/normals/$preset.png"
  cp "out/docs/$preset/flip.png" "docs/images/normals/$preset-flip.png"
done
.venv/bin/prefilter render normals-denim-plane --mode peak-count -o docs/images/normals/peak-count.png
