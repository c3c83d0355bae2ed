#!/usr/bin/env bash
# Regenerate the figures of docs/microsurface.md: `prefilter compare` on the microsurface presets
# (256 px, SPP samples, default 64: every reference pass ray-marches the explicit microgeometry), the
# march-steps diagnostic, the height sphere and the sponge across scales (scripts/microsurface-scales.py),
# and the plots that `prefilter bench` writes (zoom sweeps, Gaussian-approximation error) copied from
# out/bench if they exist.
set -euo pipefail
cd "$(dirname "$0")/.."
SPP="${SPP:-64}"
mkdir -p docs/images/microsurface out/docs
for preset in micro-heights-terrain micro-heights-grazing micro-heights-sphere micro-slopes-sphere micro-snake-sphere \
              micro-irradiance-terrain micro-moss-sphere micro-sponge-sphere; do
  size=256x256
  case "$preset" in *terrain*) size=256x192 ;; esac
  .venv/bin/prefilter compare "$preset" --size "$size" --spp "$SPP" -o "out/docs/$preset" | tee "out/docs/$preset.md"
  cp "out/docs/$preset/strip.png" "docs/images/microsurface/$preset.png"
  cp "out/docs/$preset/flip.png" "docs/images/microsurface/$preset-flip.png"
done
.venv/bin/prefilter render micro-heights-sphere --mode march-steps --size 256x256 -o docs/images/microsurface/march-steps.png
.venv/bin/python scripts/microsurface-scales.py docs/images/microsurface/across-scales.png "$SPP"
.venv/bin/python scripts/microsurface-scales.py docs/images/microsurface/sponge-across-scales.png "$SPP" micro-sponge-sphere
for plot in microsurface-zoom.png microsurface-zoom-sponge.png gaussian-approximation-error.png; do
  if [ -f "out/bench/$plot" ]; then cp "out/bench/$plot" docs/images/microsurface/; fi
done
