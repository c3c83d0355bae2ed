"""Judge a scene: render every mode and the supersampled reference in one run, score and time them.

`compare_scene` returns the images, per-mode metrics on fully covered pixels (FLIP, ΔE2000, RMSE in
linear RGB) and median GPU frame times; `write_comparison` writes the labelled strip, FLIP maps,
report.md and report.json into a directory atomically (built beside it, then renamed into place).
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from prefilter import outputs
from prefilter.gl.render import REFERENCE, Renderer, RenderOptions, composite, scene_modes
from prefilter.images import false_colour, labelled_strip, write_image
from prefilter.metrics import compare
from prefilter.scene import Scene


@dataclass
class Comparison:
    scene: Scene
    size: tuple[int, int]
    spp: int
    images: dict[str, np.ndarray]  # linear RGB over the background, per mode and "reference"
    diagnostics: dict[str, np.ndarray]  # unscored visualisations (e.g. hart-width)
    mask: np.ndarray
    metrics: dict[str, dict[str, float]] = field(default_factory=dict)
    flip_maps: dict[str, np.ndarray] = field(default_factory=dict)

    def report(self) -> dict:
        return {
            "scene": self.scene.name,
            "size": list(self.size),
            "reference_spp": self.spp,
            "covered_fraction": float(self.mask.mean()),
            "modes": self.metrics,
        }


def progress_bar(description: str):
    """A rich progress callback (k, n) -> None; silent when not on a terminal."""
    from rich.progress import BarColumn, Progress, TaskProgressColumn, TextColumn, TimeRemainingColumn

    progress = Progress(
        TextColumn(description), BarColumn(), TaskProgressColumn(), TimeRemainingColumn(), transient=True
    )
    state: dict[str, int] = {}

    def update(done: int, total: int) -> None:
        if "task" not in state:
            progress.start()
            state["task"] = progress.add_task(description, total=total)
        progress.update(state["task"], completed=done)
        if done >= total:
            progress.stop()

    return update


def compare_scene(
    scene: Scene,
    size: tuple[int, int] | None = None,
    spp: int = 1024,
    t: float = 0.0,
    modes: list[str] | None = None,
    frames: int = 5,
    options: RenderOptions | None = None,
    renderer: Renderer | None = None,
    progress=None,
) -> Comparison:
    own = renderer is None
    renderer = renderer or Renderer(scene, size, options=options or RenderOptions())
    try:
        modes = modes or scene_modes(scene)
        # The reference is timed on the render that is scored: rendering it again only to time it
        # doubled the cost of the ray-marched presets. The point program is compiled before the clock.
        renderer.draw("point", t)
        renderer.ctx.finish()
        start = time.perf_counter()
        reference_rgba = renderer.reference(spp, t, progress=progress)
        reference_ms = 1000.0 * (time.perf_counter() - start)
        mask = renderer.covered(reference_rgba, spp, t)
        if not mask.any():
            raise ValueError(f"{scene.name}: no pixel is fully covered by a surface; nothing to score")
        background = scene.background
        images = {REFERENCE: composite(reference_rgba, background)}
        for mode in modes:
            images[mode] = composite(renderer.render(mode, t), background)
        diagnostics = {
            mode: composite(renderer.render(mode, t), background)
            for mode in scene_modes(scene, diagnostics=True)
            if mode not in modes
        }
        result = Comparison(scene, renderer.size, spp, images, diagnostics, mask)
        times = renderer.time_modes(modes, frames, t)
        for mode in modes:
            scores = compare(images[mode], images[REFERENCE], mask)
            result.flip_maps[mode] = scores.pop("flip_map")
            scores["ms"] = times[mode]
            result.metrics[mode] = {k: float(v) for k, v in scores.items()}
        result.metrics[REFERENCE] = {"flip": 0.0, "delta_e": 0.0, "rmse": 0.0, "ms": reference_ms}
        return result
    finally:
        if own:
            renderer.release()


def markdown_table(comparison: Comparison) -> str:
    rows = ["| mode | FLIP | ΔE2000 | RMSE | ms/frame |", "|---|---:|---:|---:|---:|"]
    for mode, m in comparison.metrics.items():
        rows.append(f"| {mode} | {m['flip']:.4f} | {m['delta_e']:.3f} | {m['rmse']:.4f} | {m['ms']:.2f} |")
    return "\n".join(rows)


def check_replaceable(out: Path) -> None:
    """`out` may be replaced by a comparison: absent, empty, or an earlier comparison (its report.json)."""
    outputs.check_replaceable(
        out,
        "report.json",
        lambda report: {"scene", "reference_spp", "modes"} <= set(report),
        "a comparison directory",
    )


def write_comparison(comparison: Comparison, out_dir: str | os.PathLike) -> Path:
    """Write the comparison to `out_dir` atomically: staged beside it, then renamed into place (an earlier
    comparison there is replaced; any other existing file or directory is refused, check_replaceable)."""
    out = Path(out_dir)
    check_replaceable(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        name = comparison.scene.name
        panels = [(REFERENCE, comparison.images[REFERENCE])]
        panels += [(mode, img) for mode, img in comparison.images.items() if mode != REFERENCE]
        write_image(staging / "strip.png", labelled_strip(panels))
        flips = [
            (f"FLIP {mode} {comparison.metrics[mode]['flip']:.3f}", false_colour(m))
            for mode, m in comparison.flip_maps.items()
        ]
        write_image(staging / "flip.png", labelled_strip(flips))
        for mode, img in {**comparison.images, **comparison.diagnostics}.items():
            write_image(staging / f"{mode}.png", img, {"scene": name, "mode": mode})
        write_image(
            staging / "reference.exr",
            comparison.images[REFERENCE],
            {"scene": name, "mode": REFERENCE, "spp": comparison.spp},
        )
        report = comparison.report()
        (staging / "report.json").write_text(json.dumps(report, indent=2) + "\n")
        md = [
            f"# {name}",
            "",
            comparison.scene.description,
            "",
            f"{comparison.size[0]}x{comparison.size[1]} pixels, reference {comparison.spp} spp, "
            f"{100 * report['covered_fraction']:.1f}% of pixels fully covered and scored.",
            "",
            markdown_table(comparison),
            "",
            "![modes](strip.png)",
            "",
            "![FLIP maps](flip.png)",
            "",
        ]
        for material in {id(obj.material): obj.material for obj in comparison.scene.objects}.values():
            extras = getattr(material, "comparison_figures", None)  # technique-specific studies
            if extras is not None:
                md += extras(staging)
        (staging / "report.md").write_text("\n".join(md))
        umask = os.umask(0)
        os.umask(umask)
        staging.chmod(0o777 & ~umask)  # mkdtemp makes it private; the result is an ordinary directory
        if out.exists():
            shutil.rmtree(out)
        os.replace(staging, out)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    return out
