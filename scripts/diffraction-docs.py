"""Figures and tables of docs/diffraction.md: the grating-equation plot, the blazed grating's order
efficiencies against sinc², and the preset images and BRDF slices against the direct reference
(`prefilter compare`, 16 samples per pixel).

Usage: .venv/bin/python scripts/diffraction-docs.py   (writes docs/images/diffraction/, prints the table)
"""

import subprocess
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from prefilter.diffraction.nanostructure import generate  # noqa: E402
from prefilter.diffraction.transform import grating_peaks, order_powers, taylor_terms  # noqa: E402

OUT = Path("docs/images/diffraction")


def grating_equation_plot() -> None:
    """Peak angles found in the baked transform against sin θ_r = mλ/d − sin θ_i, d = 1.6 µm."""
    structure = generate("sinusoidal", period=1.6, amplitude=0.1, periods=16, pixel=0.02)
    terms = taylor_terms(structure.heights, structure.pixel)
    fig, ax = plt.subplots(figsize=(6.4, 4.0), dpi=110)
    lambdas = np.linspace(0.4, 0.76, 10)
    for theta_i, colour in ((0.0, "tab:blue"), (45.0, "tab:orange")):
        for m in range(-4, 5):
            s = m * lambdas / 1.6 - np.sin(np.radians(theta_i))
            ok = np.abs(s) < 1
            if m:
                ax.plot(lambdas[ok], np.degrees(np.arcsin(s[ok])), "-", color=colour, lw=0.8)
        found_l, found_a = [], []
        for lam in lambdas:
            angles, powers = grating_peaks(terms, lam, theta_i, threshold=1e-4)
            for a in angles:
                if abs(a + theta_i) > 0.5:  # not the mirror
                    found_l.append(lam)
                    found_a.append(a)
        ax.plot(found_l, found_a, "o", ms=3, color=colour, label=f"θ_i = {theta_i:g}°: peaks of the bake")
    ax.set_xlabel("wavelength (µm)")
    ax.set_ylabel("θ_r of the diffraction peaks (°)")
    ax.set_title("d = 1.6 µm: sin θ_r = mλ/d − sin θ_i (lines, m = −4 … 4) and the bake (dots)", fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(OUT / "grating-equation.png")
    plt.close(fig)


def blazed_table() -> str:
    structure = generate("blazed", period=2.5, height=0.246, periods=10, pixel=0.01)
    lam = 0.5
    kw = 2 * np.pi / lam * -2.0  # normal incidence: w = -(cos θ_i + cos θ_r) = -2
    orders = np.arange(-3, 4)
    powers = order_powers(structure.heights, structure.pixel, kw, -orders, period=2.5)  # m = -j
    height = float(np.ptp(structure.heights)) + 0.246 / 250  # the sampled sawtooth's full height
    rows = ["| order m | bake | sinc²(2H/λ − m) |", "|---:|---:|---:|"]
    for m, p in zip(orders, powers, strict=True):
        rows.append(f"| {m:+d} | {p:.4f} | {np.sinc(2 * height / lam - m) ** 2:.4f} |")
    return "\n".join(rows)


def preset_images() -> None:
    for preset in ("diffraction-grating-plane", "diffraction-cd", "diffraction-snake-cylinder"):
        out = Path("out/docs") / preset
        subprocess.run(
            [sys.executable, "-m", "prefilter.cli", "compare", preset, "--spp", "16", "-o", str(out)],
            check=True,
        )
        (OUT / f"{preset}.png").write_bytes((out / "strip.png").read_bytes())
        slices = preset.removeprefix("diffraction-").removesuffix("-plane").removesuffix("-cylinder")
        (OUT / f"brdf-slices-{slices}.png").write_bytes((out / "brdf-slices.png").read_bytes())


if __name__ == "__main__":
    OUT.mkdir(parents=True, exist_ok=True)
    grating_equation_plot()
    print(blazed_table())
    preset_images()
