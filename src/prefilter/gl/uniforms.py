"""Setting uniforms and samplers by name, skipping those the GLSL compiler removed as unused.

NumPy arrays are written as raw float32 bytes, so matrices must already be column-major (pass M.T);
arrays of vectors or matrices are written whole (`name` without an index).
"""

from __future__ import annotations

import moderngl
import numpy as np


def set_uniforms(prog: moderngl.Program, values: dict[str, object]) -> None:
    for name, value in values.items():
        if name not in prog:
            continue
        if isinstance(value, np.ndarray):
            data = np.ascontiguousarray(value, dtype=np.float32).ravel()
            uniform = prog[name]
            # the compiler may shorten an array whose later elements are never read
            data = data[: uniform.array_length * uniform.dimension]
            uniform.write(data.tobytes())
        else:
            prog[name].value = value


def bind_samplers(prog: moderngl.Program, textures: dict[str, moderngl.Texture], first_unit: int = 0) -> None:
    """Bind each texture to its own unit (in dict order from first_unit) and point its sampler at it."""
    for unit, (name, texture) in enumerate(textures.items(), first_unit):
        if name in prog:
            texture.use(location=unit)
            prog[name].value = unit
            if isinstance(prog, BindingRecorder):
                prog.textures[name] = texture


class BindingRecorder:
    """Stands in for a program in a material's `bind`: records every uniform value and sampler texture.

    The exporter and the viewer bundle use it to learn a material's state without per-material code.
    Every name is accepted (`in` is always true), so the record is the union over all modes' programs.
    """

    def __init__(self) -> None:
        self.values: dict[str, object] = {}
        self.textures: dict[str, moderngl.Texture] = {}

    def __contains__(self, name: str) -> bool:
        return True

    def __getitem__(self, name: str) -> _RecordedUniform:
        return _RecordedUniform(self.values, name)


class _RecordedUniform:
    array_length = 1 << 20  # nothing is cut: the record keeps whole arrays
    dimension = 1

    def __init__(self, values: dict[str, object], name: str):
        self._values, self._name = values, name

    @property
    def value(self) -> object:
        return self._values[self._name]

    @value.setter
    def value(self, value: object) -> None:
        self._values[self._name] = value

    def write(self, data: bytes) -> None:
        self._values[self._name] = np.frombuffer(data, dtype=np.float32).copy()
