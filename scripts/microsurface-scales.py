"""A microsurface sphere across scales (Heitz et al. 2014 Figs. 1, 16) for docs/microsurface.md.

The camera moves along its view ray as in the bench's zoom study (1.35 to 24 units from the centre). Each
column is one distance: the ray-marched reference, `surface-filter` and `naive`, labelled with their FLIP
against the reference. Far away the sphere covers few pixels, so every panel is cropped to the sphere and
enlarged with nearest-neighbour sampling: what is shown is the pixels themselves.

Usage: .venv/bin/python scripts/microsurface-scales.py [OUT.png] [SPP] [PRESET]
(default docs/images/microsurface/across-scales.png, 64 spp, micro-heights-sphere; about 5 minutes on
llvmpipe)
"""

import sys
from pathlib import Path

import numpy as np

from prefilter.bench import zoomed
from prefilter.gl.render import Renderer, composite
from prefilter.images import labelled_strip, write_image
from prefilter.metrics import compare
from prefilter.scene import resolve_scene

DISTANCES = (1.35, 2.4, 4.24, 10.0, 24.0)  # 4.24: the height sphere's own camera
SIZE = 256
PANEL = 192
MODES = ("surface-filter", "naive")


def crop_to_object(image: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """The square around the covered pixels (with a margin), enlarged to PANEL x PANEL, nearest-neighbour."""
    ys, xs = np.nonzero(alpha > 0.0)
    h, w = alpha.shape
    if ys.size == 0 or (ys.min() == 0 and xs.min() == 0 and ys.max() == h - 1 and xs.max() == w - 1):
        y0, x0, side = 0, 0, min(h, w)
    else:
        side = int(max(ys.max() - ys.min(), xs.max() - xs.min()) * 1.1) + 4
        side = min(side, h, w)
        y0 = int(np.clip((ys.min() + ys.max() - side) // 2, 0, h - side))
        x0 = int(np.clip((xs.min() + xs.max() - side) // 2, 0, w - side))
    square = image[y0 : y0 + side, x0 : x0 + side]
    index = (np.arange(PANEL) * side) // PANEL
    return square[index][:, index]


def main() -> None:
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("docs/images/microsurface/across-scales.png")
    spp = int(sys.argv[2]) if len(sys.argv) > 2 else 64
    scene = resolve_scene(sys.argv[3] if len(sys.argv) > 3 else "micro-heights-sphere")
    rows = {name: [] for name in ("reference", *MODES)}
    for distance in DISTANCES:
        renderer = Renderer(zoomed(scene, distance), (SIZE, SIZE))
        try:
            reference = renderer.reference(spp)
            mask = renderer.covered(reference, spp)
            alpha = reference[..., 3]
            reference_rgb = composite(reference, scene.background)
            rows["reference"].append((f"reference, {distance:g} units", crop_to_object(reference_rgb, alpha)))
            for mode in MODES:
                image = composite(renderer.render(mode), scene.background)
                flip = compare(image, reference_rgb, mask)["flip"]
                rows[mode].append((f"{mode} {flip:.3f}", crop_to_object(image, alpha)))
                print(f"{distance:6.2f} units: {mode} FLIP {flip:.4f}", flush=True)
        finally:
            renderer.release()
    strips = [labelled_strip(panels) for panels in rows.values()]
    write_image(out, np.concatenate(strips, axis=0))
    print(out)


if __name__ == "__main__":
    main()
