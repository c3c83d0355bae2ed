"""prefilter command line: list | render | compare | bench | bake.

Errors the user can act on are printed as one line `prefilter: error: ...`; invalid scene files and
arguments exit 2, other failures 1. Nothing is written when a command fails.
"""

from __future__ import annotations

import argparse
import math
import re
import signal
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from prefilter import PrefilterError
from prefilter.outputs import check_writable
from prefilter.scene import SceneError

if TYPE_CHECKING:
    from prefilter.gl.render import RenderOptions


class UsageError(PrefilterError):
    """Arguments that do not fit the scene: exit 2, as argparse's own."""


_SIZE = re.compile(r"^(\d+)x(\d+)$")


def _size(text: str) -> tuple[int, int]:
    m = _SIZE.match(text)
    if not m or not (8 <= int(m.group(1)) <= 8192 and 8 <= int(m.group(2)) <= 8192):
        raise argparse.ArgumentTypeError(f"expected WxH with 8..8192 pixels per side, got {text!r}")
    return int(m.group(1)), int(m.group(2))


def _positive(text: str) -> int:
    if not text.isdigit() or int(text) < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return int(text)


def _port(text: str) -> int:
    if not text.isdigit() or int(text) > 65535:
        raise argparse.ArgumentTypeError(f"expected a TCP port 0..65535 (0: a free one), got {text!r}")
    return int(text)


def _scheduler(text: str) -> str:
    """A local Dask scheduler or a distributed one's address (normals/pyramid.py takes either)."""
    if text not in ("synchronous", "threads", "processes") and not text.startswith("tcp://"):
        raise argparse.ArgumentTypeError(
            f"expected synchronous, threads, processes or tcp://host:port, got {text!r}"
        )
    return text


def _square(text: str) -> int:
    """Reference samples per pixel: N x N stratified, so a square (√spp had been rounded silently)."""
    spp = _positive(text)
    n = math.isqrt(spp)
    if n * n != spp:
        raise argparse.ArgumentTypeError(
            f"expected a square (N x N stratified samples), got {text!r}; nearest {n * n} or {(n + 1) ** 2}"
        )
    return spp


# Hart §4.3's B bits over the object's extent: float32 solid coordinates hold 24
MAX_QUANT_BITS = 24


def _quant_bits(text: str) -> int:
    bits = _positive(text)
    if bits > MAX_QUANT_BITS:
        raise argparse.ArgumentTypeError(
            f"expected 1..{MAX_QUANT_BITS} bits (float32 solid coordinates hold that many), got {text!r}"
        )
    return bits


def _hart_options(args: argparse.Namespace, scene) -> RenderOptions:
    """The render options of Hart's model; refused when the scene has no Hart solid texture to apply them to
    (they had been ignored without a word)."""
    from prefilter.gl.render import RenderOptions
    from prefilter.procedural.hart import HartMaterial

    given = [
        flag
        for flag, on in (
            ("--quant-bits", args.quant_bits),
            ("--reduced", args.reduced),
            ("--first-order", args.first_order),
        )
        if on
    ]
    if given and not any(isinstance(obj.material, HartMaterial) for obj in scene.objects):
        raise UsageError(
            f"{given[0]}: {scene.name} has no Hart solid texture (the option applies to those only)"
        )
    return RenderOptions(quant_bits=args.quant_bits, reduced=args.reduced, first_order=args.first_order)


def cmd_list(args: argparse.Namespace) -> int:
    from rich.console import Console
    from rich.table import Table

    from prefilter.gl.render import scene_modes
    from prefilter.scene import preset_names, resolve_scene

    table = Table("preset", "modes", "description", box=None)
    for name in preset_names():
        scene = resolve_scene(name)
        table.add_row(name, " ".join(scene_modes(scene)), scene.description)
    Console(width=200).print(table)
    return 0


def cmd_render(args: argparse.Namespace) -> int:
    from prefilter.compare import progress_bar
    from prefilter.gl.render import REFERENCE, Renderer, composite, scene_modes
    from prefilter.images import IMAGE_EXTENSIONS, write_image
    from prefilter.scene import resolve_scene

    scene = resolve_scene(args.scene)
    out = Path(args.output)
    if out.suffix.lower() not in IMAGE_EXTENSIONS:
        raise PrefilterError(f"{out}: unsupported image extension; use one of {', '.join(IMAGE_EXTENSIONS)}")
    check_writable(out)
    valid = scene_modes(scene, diagnostics=True) + [REFERENCE]
    if args.mode not in valid:
        raise PrefilterError(f"--mode {args.mode}: not a mode of {scene.name} (valid: {', '.join(valid)})")
    frames = args.frames or 1
    options = _hart_options(args, scene)
    renderer = Renderer(scene, args.size, target=args.target, options=options)
    try:
        images = []
        for k in range(frames):
            t = k / (frames - 1) if frames > 1 else 0.0
            if args.mode == REFERENCE:
                rgba = renderer.reference(args.spp, t, progress=progress_bar(f"reference {k + 1}/{frames}"))
            else:
                rgba = renderer.render(args.mode, t)
            images.append(composite(rgba, scene.background))
    finally:
        renderer.release()
    meta = {"scene": scene.name, "mode": args.mode, "spp": args.spp if args.mode == REFERENCE else 1}
    if frames == 1:
        write_image(out, images[0], meta)
        print(out)
    else:
        written: list[Path] = []
        try:
            for k, image in enumerate(images):
                path = out.with_name(f"{out.stem}_{k:04d}{out.suffix}")
                write_image(path, image, {**meta, "frame": k, "t": k / (frames - 1)})
                written.append(path)
        except BaseException:  # a failed write (a full disk) leaves no partial sequence behind
            for path in written:
                path.unlink(missing_ok=True)
            raise
        for path in written:
            print(path)
    return 0


def cmd_compare(args: argparse.Namespace) -> int:
    from rich.console import Console

    from prefilter.compare import (
        check_replaceable,
        compare_scene,
        markdown_table,
        progress_bar,
        write_comparison,
    )
    from prefilter.scene import resolve_scene

    scene = resolve_scene(args.scene)
    check_writable(Path(args.output))
    check_replaceable(Path(args.output))
    options = _hart_options(args, scene)
    result = compare_scene(
        scene,
        args.size,
        args.spp,
        options=options,
        progress=progress_bar(f"{scene.name}: reference {args.spp} spp"),
    )
    out = write_comparison(result, args.output)
    Console().print(f"[bold]{scene.name}[/bold] -> {out}")
    print(markdown_table(result))
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    from prefilter.bench import run_bench

    if args.json:
        check_writable(Path(args.json))
    if args.plots:
        check_writable(Path(args.plots) / "plot.png")
    return run_bench(
        args.names,
        json_path=args.json,
        size=args.size,
        spp=args.spp,
        frames=args.frames,
        quick=args.quick,
        plots=args.plots,
    )


def cmd_bake(args: argparse.Namespace) -> int:
    """Bake the normal-distribution pyramids of a scene's normal-mapped objects (Fournier 1992 §2.4)."""
    import json
    import os
    from dataclasses import replace

    from prefilter.scene import resolve_scene

    scene = resolve_scene(args.scene)
    if args.json:
        check_writable(Path(args.json))
    objects = [obj for obj in scene.objects if getattr(obj.material, "surface", None) is not None]
    if not objects:
        raise PrefilterError(f"{scene.source}: no object has a normal-map material to bake")
    reports = {}
    for obj in objects:
        material = replace(obj.material, scheduler=args.scheduler, _pyramid=None)
        print(f"{scene.name}: {obj.name}: {material.surface.name}, {material.options.max_peaks} peaks")
        pyramid = material.pyramid(progress=True)
        for line in pyramid.report.lines():
            print("  " + line)
        reports[obj.name] = pyramid.report.as_dict()
    if args.json:
        path = Path(args.json)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.tmp")
        tmp.write_text(json.dumps(reports, indent=2) + "\n")
        os.replace(tmp, path)
    return 0


def cmd_export(args: argparse.Namespace) -> int:
    from prefilter.export import export_scene
    from prefilter.scene import resolve_scene

    scene = resolve_scene(args.scene)
    if args.size:
        scene.size = args.size
    check_writable(Path(args.output))
    options = _hart_options(args, scene)
    print(export_scene(scene, Path(args.output), options))
    return 0


def cmd_view(args: argparse.Namespace) -> int:
    from prefilter.viewer_server import serve

    serve(args.scene, port=args.port)
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="prefilter",
        description="Render non-linear appearance without aliasing, judged against supersampled truth.",
    )
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("list", help="list the built-in scene presets and their modes")
    p.set_defaults(func=cmd_list)

    def scene_args(p: argparse.ArgumentParser, reference: bool = True) -> None:
        p.add_argument("scene", help="a preset name (see `prefilter list`) or a scene .toml file")
        p.add_argument("--size", type=_size, default=None, help="image size WxH (default: the scene's)")
        if reference:
            p.add_argument(
                "--spp",
                type=_square,
                default=1024,
                help="reference samples per pixel, N x N stratified (default 1024 = 32 x 32)",
            )
        p.add_argument(
            "--quant-bits",
            type=_quant_bits,
            default=None,
            help="quantise solid texture coordinates to B bits over the object (Hart §4.3)",
        )
        p.add_argument(
            "--reduced",
            action="store_true",
            help="Hart's reduced 100,000-gate model: at most four noise terms, linear fade (§4.2)",
        )
        p.add_argument(
            "--first-order",
            action="store_true",
            help="Hart's filters centred on f at the pixel centre, as printed (§3), not on its pixel mean",
        )

    p = sub.add_parser("render", help="render one mode of a scene to PNG or EXR")
    scene_args(p)
    p.add_argument(
        "--mode", default="point", help="point, naive, a filtered mode, a diagnostic mode, or reference"
    )
    p.add_argument(
        "--frames",
        type=_positive,
        default=None,
        help="render K frames over animation time t = 0..1 (files NAME_0000.EXT, ...)",
    )
    p.add_argument("--target", choices=("gl330", "es300"), default="gl330", help="GLSL target to compile")
    p.add_argument("-o", "--output", required=True, help="output image (.png sRGB or .exr linear)")
    p.set_defaults(func=cmd_render)

    p = sub.add_parser("compare", help="every mode and the reference, side by side, with metrics")
    scene_args(p)
    p.add_argument("-o", "--output", required=True, help="output directory")
    p.set_defaults(func=cmd_compare)

    p = sub.add_parser("bench", help="errors and time ratios of every mode on every preset, in one run")
    p.add_argument("names", nargs="*", help="presets to bench (default: all)")
    p.add_argument("--json", default=None, help="also write the results as JSON to this file")
    p.add_argument("--size", type=_size, default=None, help="image size (default: each scene's)")
    p.add_argument(
        "--spp", type=_square, default=1024, help="reference samples per pixel, N x N (default 1024)"
    )
    p.add_argument("--frames", type=_positive, default=7, help="frames per timing median (default 7, min 5)")
    p.add_argument("--quick", action="store_true", help="small sizes and spp: a smoke run, not a measurement")
    p.add_argument("--plots", default="out/bench", help="directory for the error-vs-distance plot")
    p.set_defaults(func=cmd_bench)

    p = sub.add_parser("bake", help="bake the normal-distribution pyramids of a scene (tiles on Dask)")
    p.add_argument("scene", help="a preset name or a scene .toml file with normal-map materials")
    p.add_argument(
        "--scheduler",
        type=_scheduler,
        default=None,
        help="synchronous, threads, processes (local, 2 workers), or the address of a running Dask "
        "scheduler (tcp://host:8786); default: local processes for maps of 128x128 and more",
    )
    p.add_argument("--json", default=None, help="also write the bake reports as JSON to this file")
    p.set_defaults(func=cmd_bake)

    p = sub.add_parser(
        "export",
        help="write a scene's shaders (330 core, 300 es), baked tables, meshes and README for engines",
    )
    scene_args(p, reference=False)
    p.add_argument("-o", "--output", required=True, help="output directory (docs/export.md describes it)")
    p.set_defaults(func=cmd_export)

    p = sub.add_parser(
        "view", help="serve the WebGL2 viewer on 127.0.0.1 (prints the address; opens nothing)"
    )
    p.add_argument("scene", nargs="?", default=None, help="preset or scene .toml to open first")
    p.add_argument("--port", type=_port, default=0, help="port (default: a free one)")
    p.set_defaults(func=cmd_view)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    # SIGTERM unwinds like an exception, so staging directories and temporary files are removed
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    try:
        return args.func(args)
    except (SceneError, UsageError) as exc:
        print(f"prefilter: error: {exc}", file=sys.stderr)
        return 2
    except PrefilterError as exc:
        print(f"prefilter: error: {exc}", file=sys.stderr)
        return 1
    except OSError as exc:  # what check_writable cannot foresee (a full disk, a directory removed meanwhile)
        print(f"prefilter: error: {exc}", file=sys.stderr)
        return 1
    except MemoryError:  # an 8192 x 8192 render peaks at about 11 GiB
        print("prefilter: error: out of memory; try a smaller --size (or --spp)", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("prefilter: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
