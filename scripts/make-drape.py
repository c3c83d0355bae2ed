"""Write src/prefilter/scenes/data/drape.obj: a hanging curtain with folds, for the denim-on-drapery preset.

Fournier 1992 Fig. 8 drapes denim over "a model of drapery" (an 11x40 grid by F. Taillefer, not
published). This is our own stand-in: a sheet hanging from a rail, x in [-1, 1], y in [0, 2], folding in
z with an amplitude that grows towards the hem, on a (cols x rows) grid with uvs along the sheet's arc
length, exported through trimesh. Usage: python scripts/make-drape.py [output.obj]
"""

import sys
from pathlib import Path

import numpy as np
import trimesh


def drape(cols: int = 49, rows: int = 33) -> trimesh.Trimesh:
    s = np.linspace(0.0, 1.0, cols)  # across the rail
    t = np.linspace(0.0, 1.0, rows)  # from the hem (0) up to the rail (1)
    S, T = np.meshgrid(s, t)
    amplitude = 0.06 + 0.16 * (1.0 - T) ** 1.5
    x = (S - 0.5) * 2.0 * (0.86 + 0.14 * T)  # gathered a little at the rail
    z = amplitude * np.sin(2 * np.pi * (4.0 * S + 0.15 * np.sin(3.0 * np.pi * T)))
    y = 2.0 * T
    vertices = np.stack([x, y, z], axis=-1).reshape(-1, 3)
    # uv along the cloth: u = arc length across (so the weave is not stretched in the folds), v = height
    seg = np.sqrt(np.diff(x, axis=1) ** 2 + np.diff(z, axis=1) ** 2)
    u = np.concatenate([np.zeros((rows, 1)), np.cumsum(seg, axis=1)], axis=1) / 2.0
    uv = np.stack([u, T], axis=-1).reshape(-1, 2)
    idx = np.arange(rows * cols).reshape(rows, cols)
    a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, 1:], idx[1:, :-1]
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    visual = trimesh.visual.TextureVisuals(uv=uv)
    return trimesh.Trimesh(vertices, faces, visual=visual, process=False)


if __name__ == "__main__":
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("src/prefilter/scenes/data/drape.obj")
    mesh = drape()
    text = trimesh.exchange.obj.export_obj(mesh, include_normals=True, include_texture=True, digits=5)
    # uvs only: no material library to ship
    text = "\n".join(x for x in text.splitlines() if not x.startswith(("mtllib", "usemtl"))) + "\n"
    out.write_text(text)
    print(f"{out}: {len(mesh.vertices)} vertices, {len(mesh.faces)} faces")
