"""Documentation annotations on GLSL uniform declarations (docs/export.md, "Annotations").

    uniform float u_exposure;      // @param 0..16 log Exposure: multiplies the diffracted radiance
    uniform sampler2D u_tableMip;  // @table u: the driver value mapped to [0, 1) ...

`@param` uniforms become controls in the viewer and rows in an export's README; `@table` text becomes a
table's JSON `description`. Annotations are read from assembled sources, whose source map names the
real file and line of a malformed one.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from prefilter.gl.program import Assembled, ShaderError

_DECLARATION = re.compile(
    r"^\s*uniform\s+(?:(?:highp|mediump|lowp)\s+)?(\w+)\s+(\w+)\s*(?:\[\s*(\w+)\s*\])?\s*;(.*)$"
)
_PARAM = re.compile(
    r"^@param\s+(?P<lo>[-+0-9.eE]+)\s*\.\.\s*(?P<hi>[-+0-9.eE]+)(?P<flags>(?:\s+(?:log|colour))*)\s+"
    r"(?P<label>[^:]+?)\s*(?::\s*(?P<description>.*))?$"
)
PARAM_TYPES = {"float": 1, "int": 1, "vec2": 2, "vec3": 3, "vec4": 4}


@dataclass(frozen=True)
class Uniform:
    """One `uniform` declaration: GLSL type, name, array size (text, may be a macro) and its comment."""

    type: str
    name: str
    array: str | None
    comment: str
    origin: tuple[str, int]


@dataclass(frozen=True)
class Parameter:
    uniform: str
    type: str
    label: str
    lo: float
    hi: float
    log: bool
    colour: bool
    description: str

    def as_json(self) -> dict:
        return {
            "uniform": self.uniform,
            "type": self.type,
            "label": self.label,
            "min": self.lo,
            "max": self.hi,
            "log": self.log,
            "colour": self.colour,
            "description": self.description,
        }


def uniform_declarations(assembled: Assembled) -> dict[str, Uniform]:
    found: dict[str, Uniform] = {}
    for number, line in enumerate(assembled.source.splitlines(), 1):
        m = _DECLARATION.match(line)
        if m:
            comment = m.group(4).strip()
            comment = comment[2:].strip() if comment.startswith("//") else ""
            found[m.group(2)] = Uniform(m.group(1), m.group(2), m.group(3), comment, assembled.locate(number))
    return found


def _where(u: Uniform) -> str:
    return f"{u.origin[0]}:{u.origin[1]}"


def parameter(u: Uniform) -> Parameter | None:
    """The uniform's `@param` annotation, or None; a malformed one raises ShaderError naming file:line."""
    if not u.comment.startswith("@param"):
        return None
    m = _PARAM.match(u.comment)
    if not m:
        expected = "'@param MIN..MAX [log] [colour] Label: text'"
        raise ShaderError(f"{_where(u)}: malformed @param on {u.name} (expected {expected})")
    if u.type not in PARAM_TYPES:
        raise ShaderError(f"{_where(u)}: @param on {u.name}: type {u.type} cannot be a parameter")
    try:
        lo, hi = float(m.group("lo")), float(m.group("hi"))
    except ValueError:
        raise ShaderError(f"{_where(u)}: @param on {u.name}: range is not two numbers") from None
    flags = m.group("flags").split()
    if not lo < hi or ("log" in flags and lo <= 0.0):
        raise ShaderError(
            f"{_where(u)}: @param on {u.name}: need MIN < MAX (and MIN > 0 for log), got {lo}..{hi}"
        )
    if "colour" in flags and u.type != "vec3":
        raise ShaderError(f"{_where(u)}: @param on {u.name}: 'colour' needs a vec3, got {u.type}")
    return Parameter(
        u.name, u.type, m.group("label").strip(), lo, hi, "log" in flags, "colour" in flags,
        (m.group("description") or "").strip(),
    )  # fmt: skip


def table_description(u: Uniform) -> str | None:
    if not u.comment.startswith("@table"):
        return None
    text = u.comment[len("@table") :].strip()
    if not text:
        raise ShaderError(f"{_where(u)}: empty @table annotation on {u.name}")
    return text


def referenced_uniforms(text: str, names: set[str]) -> list[str]:
    """Names of uniforms that a description mentions (as whole words), in order of first mention."""
    words = re.findall(r"\b\w+\b", text)
    return list(dict.fromkeys(w for w in words if w in names))
