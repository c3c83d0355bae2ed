"""GLSL assembler: one source for desktop GLSL 3.30 core and GLSL ES 3.00 (WebGL2).

A program is assembled as: target preamble, stage define, user #defines, then the body with every
`#include "path"` flattened recursively (each file once, like #pragma once). Include paths resolve
relative to the including file, then to the package root (src/prefilter). The assembler keeps a
source map (output line -> file, line) so that a compile error is reported as `file.glsl:LINE: message`
of the real source file. Mesa ignores the source-string number of `#line L S` (STACK-NOTES (a) 7), so the
runtime compiles without #line and maps through the source map; exports ask for `line_directives=True`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import moderngl

from prefilter import PrefilterError

PACKAGE_ROOT = Path(__file__).resolve().parent.parent

PREAMBLES = {
    "gl330": "#version 330 core\n#define TARGET_GL 1\n",
    "gl450": "#version 450 core\n#define TARGET_GL 1\n#define TARGET_GL450 1\n",
    "es300": (
        "#version 300 es\n"
        "precision highp float;\nprecision highp int;\nprecision highp sampler2D;\n"
        "precision highp sampler3D;\nprecision highp sampler2DArray;\nprecision highp usampler2D;\n"
        "precision highp isampler2D;\n"
        "#define TARGET_GLES 1\n"
    ),
}
TARGETS = tuple(PREAMBLES)

_INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"\s*$')
_MESA_ERROR = re.compile(r"^\s*(\d+):(\d+)\((\d+)\):\s*(.*)$")  # 0:LINE(COL): error: ...
_NVIDIA_ERROR = re.compile(r"^\s*(\d+)\((\d+)\)\s*:\s*(.*)$")  # 0(LINE) : error ...


class ShaderError(PrefilterError):
    """A GLSL compile or link error, already mapped to the real source file and line."""


@dataclass
class Assembled:
    source: str
    source_map: list[tuple[str, int]] = field(default_factory=list)  # output line (1-based) -> (file, line)

    def locate(self, line: int) -> tuple[str, int]:
        if 1 <= line <= len(self.source_map):
            return self.source_map[line - 1]
        return ("<assembled>", line)


def resolve_include(name: str, including_dir: Path | None) -> Path:
    for base in (including_dir, PACKAGE_ROOT):
        if base is not None and (base / name).is_file():
            return (base / name).resolve()
    raise ShaderError(f"{name}: #include not found (searched {including_dir} and {PACKAGE_ROOT})")


def _display(path: Path | str) -> str:
    p = Path(path)
    try:
        return str(p.relative_to(PACKAGE_ROOT))
    except ValueError:
        return str(p)


def assemble(
    body: str | Path,
    target: str = "gl330",
    defines: dict[str, object] | None = None,
    stage: str | None = None,
    line_directives: bool = False,
) -> Assembled:
    """Assemble a shader from a file path (Path) or inline source text (str)."""
    if target not in PREAMBLES:
        raise ShaderError(f"unknown GLSL target {target!r}; expected one of {', '.join(TARGETS)}")
    out: list[str] = []
    smap: list[tuple[str, int]] = []

    def emit(text: str, origin: tuple[str, int]) -> None:
        out.append(text)
        smap.append(origin)

    for i, line in enumerate(PREAMBLES[target].splitlines(), 1):
        emit(line, ("<preamble>", i))
    if stage:
        emit(f"#define {stage.upper()}_SHADER 1", ("<preamble>", 0))
    for key, value in (defines or {}).items():
        emit(
            f"#define {key} {_glsl_literal(value)}" if value is not True else f"#define {key} 1",
            ("<defines>", 0),
        )

    seen: set[Path] = set()
    file_ids: dict[str, int] = {}

    def include(text: str, name: str, directory: Path | None) -> None:
        file_id = file_ids.setdefault(name, len(file_ids) + 1)
        if line_directives:
            emit(f"#line 1 {file_id}", (name, 0))
        for number, line in enumerate(text.splitlines(), 1):
            match = _INCLUDE.match(line)
            if not match:
                emit(line, (name, number))
                continue
            try:
                path = resolve_include(match.group(1), directory)
            except ShaderError as exc:
                raise ShaderError(f"{name}:{number}: {exc}") from None
            if path in seen:  # each file once, which also ends include cycles
                continue
            seen.add(path)
            include(path.read_text(), _display(path), path.parent)
            if line_directives:
                emit(f"#line {number + 1} {file_id}", (name, number))

    if isinstance(body, Path):
        path = body if body.is_absolute() else resolve_include(str(body), None)
        seen.add(path.resolve())
        include(path.read_text(), _display(path), path.parent)
    else:
        include(body, "<inline>", None)
    if line_directives:  # file table for readers of exported shaders
        out.insert(1, "// source files: " + ", ".join(f"{i}={n}" for n, i in file_ids.items()))
        smap.insert(1, ("<preamble>", 0))
    return Assembled("\n".join(out) + "\n", smap)


def _glsl_literal(value: object) -> str:
    if isinstance(value, bool):
        return "1" if value else "0"
    if isinstance(value, float):
        text = repr(value)
        return text if any(c in text for c in ".eE") else text + ".0"
    return str(value)


def map_errors(message: str, assembled: Assembled, stage: str) -> str:
    """Rewrite driver error lines (`0:LINE(COL): msg`) into `file.glsl:LINE: msg` lines."""
    mapped: list[str] = []
    for raw in message.splitlines():
        m = _MESA_ERROR.match(raw)
        if m:
            path, line = assembled.locate(int(m.group(2)))
            mapped.append(f"{path}:{line}: {m.group(4)} ({stage} shader)")
            continue
        m = _NVIDIA_ERROR.match(raw)
        if m:
            path, line = assembled.locate(int(m.group(2)))
            mapped.append(f"{path}:{line}: {m.group(3)} ({stage} shader)")
    return "\n".join(mapped)


def build_program(
    ctx: moderngl.Context,
    vertex: str | Path,
    fragment: str | Path | None = None,
    target: str = "gl330",
    defines: dict[str, object] | None = None,
    varyings: tuple[str, ...] = (),
) -> moderngl.Program:
    """Assemble and link a program; compile errors come back as ShaderError naming file and line."""
    stages = {"vertex": assemble(vertex, target, defines, stage="vertex")}
    if fragment is not None:
        stages["fragment"] = assemble(fragment, target, defines, stage="fragment")
    try:
        return ctx.program(
            vertex_shader=stages["vertex"].source,
            fragment_shader=stages["fragment"].source if "fragment" in stages else None,
            varyings=list(varyings),
        )
    except moderngl.Error as exc:
        raise ShaderError(_explain(str(exc), stages)) from None


def _explain(message: str, stages: dict[str, Assembled]) -> str:
    """moderngl's message names the failing stage in a header (`vertex_shader` / `fragment_shader`)."""
    for name, assembled in stages.items():
        if f"{name}_shader" in message:
            mapped = map_errors(message, assembled, name)
            if mapped:
                return mapped
    lines = [line for line in message.splitlines() if "error" in line.lower()]
    return "link error: " + (lines[0].strip() if lines else message.strip())
