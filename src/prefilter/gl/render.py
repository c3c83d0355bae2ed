"""Draw a scene in a mode: float32 render targets, multi-pass reference accumulation, GPU timings.

Modes (DESIGN.md "Judge"): `point` (one sample at the pixel centre, unfiltered), `naive` (today's
renderers), each material's filtered modes, diagnostic modes, and `reference`: N x N stratified,
jittered sub-pixel offsets of the projection, each pass the exact unfiltered (`point`) appearance,
accumulated on the GPU. The pixel filter is the box over one pixel everywhere.

Images are premultiplied RGBA, linear, top row first; alpha is coverage by the scene's surfaces and
`composite` puts them over the background. Errors are measured on fully covered pixels
(`Renderer.covered`): reference alpha 1, and, in scenes of several objects, every sample seeing the
same surfaces, so that the edges between objects (silhouettes: geometry aliasing) are left out too.
"""

from __future__ import annotations

import math
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass

import moderngl
import numpy as np

from prefilter import PrefilterError
from prefilter.geometry import VERTEX_LAYOUT, Mesh, MissingAsset, load_mesh, make_primitive
from prefilter.gl.context import gl_context
from prefilter.gl.program import build_program
from prefilter.gl.uniforms import set_uniforms
from prefilter.scene import Light, Scene, SceneError, SceneObject

BASE_MODES = ("point", "naive")
MAX_LIGHTS = 4  # SH_MAX_LIGHTS in glsl/common/shading.glsl
REFERENCE = "reference"
MIN_SAMPLE_MS = 20.0  # time_modes: the shortest timed batch ...
MAX_BATCH = 32  # ... in at most this many frames (tiny test images would otherwise draw hundreds)

FULLSCREEN_TRIANGLE_VERT = """
void main() {
    vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));
    gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}
"""
_SURFACE_ID_FRAG = """
uniform vec2 u_surfaceId;
out vec4 o_colour;
void main() { o_colour = vec4(u_surfaceId, 0.0, 1.0); }
"""
SURFACE_ID = "surface-id"  # internal mode: the object's vertex stage, _SURFACE_ID_FRAG
_ACCUMULATE_FRAG = """
uniform sampler2D u_pass;
out vec4 o_colour;
void main() { o_colour = texelFetch(u_pass, ivec2(gl_FragCoord.xy), 0); }
"""


@dataclass(frozen=True)
class RenderOptions:
    quant_bits: int | None = None  # Hart §4.3: solid coordinates quantised to this many bits
    reduced: bool = False  # Hart §4.2: the "100,000-gate" variant
    first_order: bool = False  # Hart §3 as printed: the box is centred on f at the pixel centre


def mode_define(mode: str) -> str:
    return "MODE_" + mode.upper().replace("-", "_")


def scene_modes(scene: Scene, diagnostics: bool = False) -> list[str]:
    """Every mode the scene renders in, scored ones first; `reference` is not included."""
    modes = list(BASE_MODES) + scene.technique_modes()
    if diagnostics:
        for obj in scene.objects:
            modes += [m for m in obj.material.diagnostic_modes() if m not in modes]
    return modes


def program_defines(
    obj: SceneObject, mode: str, light_count: int, options: RenderOptions
) -> dict[str, object]:
    """The #defines of an object's program in a mode (the exporter assembles with the same ones)."""
    return {
        mode_define(mode): True,
        "SH_LIGHT_COUNT": light_count,  # lets shaders unroll loops over the lights
        **obj.material.defines(options),
    }


def build_mesh(obj: SceneObject) -> Mesh:
    try:
        if obj.shape == "mesh":
            return load_mesh(obj.mesh_path)
        return make_primitive(obj.shape, **obj.shape_params)
    except PrefilterError as exc:
        if obj.source and not isinstance(exc, MissingAsset):  # the scene file's: name its file and key
            raise SceneError(f"{obj.source}.{'mesh' if obj.shape == 'mesh' else 'params'}: {exc}") from None
        raise PrefilterError(f"object '{obj.name}': {exc}") from None


class _GPUObject:
    """An object's mesh buffers, material resources and compiled program per mode."""

    def __init__(
        self,
        ctx: moderngl.Context,
        obj: SceneObject,
        mesh: Mesh,
        target: str,
        options: RenderOptions,
        light_count: int,
    ):
        self.ctx, self.obj, self.mesh, self.target, self.options = ctx, obj, mesh, target, options
        self.light_count = light_count
        self.vbo = ctx.buffer(np.ascontiguousarray(mesh.interleaved(), dtype=np.float32).tobytes())
        self.ibo = ctx.buffer(np.ascontiguousarray(mesh.indices, dtype=np.uint32).tobytes())
        self.resources = obj.material.upload(ctx, mesh)
        self.programs: dict[str, tuple[moderngl.Program, moderngl.VertexArray]] = {}

    def program(self, mode: str) -> tuple[moderngl.Program, moderngl.VertexArray]:
        if mode not in self.programs:
            vertex, fragment = self.obj.material.shader_sources()
            defines = program_defines(self.obj, mode, self.light_count, self.options)
            if mode == SURFACE_ID:
                fragment = _SURFACE_ID_FRAG
            prog = build_program(self.ctx, vertex, fragment, target=self.target, defines=defines)
            layout, names = [], []
            for name, n in VERTEX_LAYOUT:
                if name in prog:
                    layout.append(f"{n}f")
                    names.append(name)
                else:
                    layout.append(f"{4 * n}x")
            vao = self.ctx.vertex_array(
                prog, [(self.vbo, " ".join(layout), *names)], index_buffer=self.ibo, index_element_size=4
            )
            self.programs[mode] = (prog, vao)
        return self.programs[mode]

    def release(self) -> None:
        for prog, vao in self.programs.values():
            vao.release()
            prog.release()
        self.vbo.release()
        self.ibo.release()
        self.obj.material.release(self.resources)


class Renderer:
    """Renders one scene at one size; programs are compiled per (object, mode) on first use."""

    def __init__(
        self,
        scene: Scene,
        size: tuple[int, int] | None = None,
        target: str = "gl330",
        options: RenderOptions | None = None,
    ):
        self.ctx = ctx = gl_context()
        self.scene, self.options = scene, options or RenderOptions()
        self.size = size or scene.size
        lights = min(len(scene.lights), MAX_LIGHTS)
        self.objects = [
            _GPUObject(ctx, obj, build_mesh(obj), target, self.options, lights) for obj in scene.objects
        ]
        self.objects.sort(key=lambda g: g.obj.blend != "opaque")  # opaque first, then "over" in file order
        w, h = self.size
        self.colour = ctx.texture((w, h), 4, dtype="f4")
        self.depth = ctx.depth_renderbuffer((w, h))
        self.fbo = ctx.framebuffer([self.colour], self.depth)
        self.accum_tex = ctx.texture((w, h), 4, dtype="f4")
        self.accum = ctx.framebuffer([self.accum_tex])
        self.accumulate = build_program(ctx, FULLSCREEN_TRIANGLE_VERT, _ACCUMULATE_FRAG, target="gl330")
        self.accumulate_vao = ctx.vertex_array(self.accumulate, [])

    # -- drawing -------------------------------------------------------------------------------
    def draw(self, mode: str, t: float = 0.0, jitter_px: tuple[float, float] = (0.0, 0.0)) -> None:
        """Draw into self.fbo (premultiplied RGBA, cleared to transparent black)."""
        ctx, scene = self.ctx, self.scene
        w, h = self.size
        camera = scene.camera.at(t)
        clip_from_world = camera.projection_matrix(w / h) @ camera.view_matrix()
        self.fbo.use()
        ctx.viewport = (0, 0, w, h)
        ctx.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        ctx.enable(moderngl.DEPTH_TEST)
        jitter = (2.0 * jitter_px[0] / w, 2.0 * jitter_px[1] / h)
        for gpu in self.objects:
            obj = gpu.obj
            prog, vao = gpu.program(mode)
            set_uniforms(prog, frame_uniforms(scene, obj, clip_from_world, camera, t, jitter))
            obj.material.bind(prog, gpu.resources, t, self.options)
            if obj.double_sided:
                ctx.disable(moderngl.CULL_FACE)
            else:
                ctx.enable(moderngl.CULL_FACE)
            if obj.blend == "over":
                ctx.enable(moderngl.BLEND)
                ctx.blend_func = moderngl.ONE, moderngl.ONE_MINUS_SRC_ALPHA
                ctx.depth_mask = False
            else:
                ctx.disable(moderngl.BLEND)
                ctx.depth_mask = True
            vao.render(moderngl.TRIANGLES)
        ctx.depth_mask = True
        ctx.disable(moderngl.BLEND)

    def _read(self, texture: moderngl.Texture) -> np.ndarray:
        w, h = self.size
        data = np.frombuffer(texture.read(), dtype=np.float32).reshape(h, w, 4)
        return data[::-1].copy()

    def render(self, mode: str, t: float = 0.0) -> np.ndarray:
        """Premultiplied linear RGBA (H, W, 4), top row first."""
        if mode == REFERENCE:
            return self.reference()
        self.draw(mode, t)
        return self._read(self.colour)

    def reference(
        self,
        spp: int = 1024,
        t: float = 0.0,
        seed: int = 0,
        progress: Callable[[int, int], None] | None = None,
        jitter: bool = True,
    ) -> np.ndarray:
        """Mean of N x N stratified jittered passes of the `point` appearance (N = round(sqrt(spp))).

        jitter=False places each pass at its stratum's centre (regular supersampling; N = 1 is `point`).
        """
        offsets = sample_offsets(spp, seed, jitter)
        self.accum.use()
        self.ctx.clear(0.0, 0.0, 0.0, 0.0)
        for k, jitter in enumerate(offsets):
            self.draw("point", t, jitter)
            self.accum.use()
            self.ctx.viewport = (0, 0, *self.size)
            self.ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
            self.ctx.enable(moderngl.BLEND)
            self.ctx.blend_func = moderngl.ONE, moderngl.ONE
            self.colour.use(location=0)
            self.accumulate["u_pass"].value = 0
            self.accumulate_vao.render(moderngl.TRIANGLES, vertices=3)
            self.ctx.disable(moderngl.BLEND)
            if progress:
                progress(k + 1, len(offsets))
        return self._read(self.accum_tex) / len(offsets)

    def covered(self, reference_rgba: np.ndarray, spp: int, t: float = 0.0, seed: int = 0) -> np.ndarray:
        """Pixels the errors are measured on: fully covered (reference alpha 1) and, with several objects,
        seen as the same surfaces by every sample of the reference (`spp`, `seed`: the same offsets; the
        same opaque object in front and the same blended objects over it), so that the edges between
        objects are left out as silhouettes are."""
        mask = coverage_mask(reference_rgba)
        if len(self.objects) > 1:
            mask &= self._single_surface(sample_offsets(spp, seed, True), t)
        return mask

    def _single_surface(self, offsets: list[tuple[float, float]], t: float) -> np.ndarray:
        """Per sample, each pixel gets (id of the front opaque object, sum of 2^k over the blended objects
        k in front of it); the pixel is one surface when the min and max of that over all samples agree."""
        ctx, (w, h) = self.ctx, self.size
        camera = self.scene.camera.at(t)
        clip_from_world = camera.projection_matrix(w / h) @ camera.view_matrix()
        extremes = [ctx.texture((w, h), 4, dtype="f4") for _ in range(2)]
        targets = [ctx.framebuffer([tex]) for tex in extremes]
        try:
            for target, start in zip(targets, (1e30, -1e30), strict=True):
                target.use()
                ctx.clear(start, start, start, start)
            for offset in offsets:
                jitter = (2.0 * offset[0] / w, 2.0 * offset[1] / h)
                self.fbo.use()
                ctx.viewport = (0, 0, w, h)
                ctx.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
                ctx.enable(moderngl.DEPTH_TEST)
                blended = 0
                for k, gpu in enumerate(self.objects):  # opaque objects come first, as in draw()
                    prog, vao = gpu.program(SURFACE_ID)
                    uniforms = frame_uniforms(self.scene, gpu.obj, clip_from_world, camera, t, jitter)
                    set_uniforms(prog, uniforms)
                    if gpu.obj.double_sided:
                        ctx.disable(moderngl.CULL_FACE)
                    else:
                        ctx.enable(moderngl.CULL_FACE)
                    if gpu.obj.blend == "over":
                        ctx.enable(moderngl.BLEND)
                        ctx.blend_func = moderngl.ONE, moderngl.ONE
                        ctx.depth_mask = False
                        prog["u_surfaceId"].value = (0.0, float(2**blended))
                        blended += 1
                    else:
                        ctx.disable(moderngl.BLEND)
                        ctx.depth_mask = True
                        prog["u_surfaceId"].value = (float(k + 1), 0.0)
                    vao.render(moderngl.TRIANGLES)
                ctx.depth_mask = True
                ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
                ctx.enable(moderngl.BLEND)
                ctx.blend_func = moderngl.ONE, moderngl.ONE
                self.colour.use(location=0)
                self.accumulate["u_pass"].value = 0
                for target, equation in zip(targets, (moderngl.MIN, moderngl.MAX), strict=True):
                    target.use()
                    ctx.blend_equation = equation
                    self.accumulate_vao.render(moderngl.TRIANGLES, vertices=3)
                ctx.blend_equation = moderngl.FUNC_ADD
                ctx.disable(moderngl.BLEND)
            low, high = (self._read(tex)[..., :2] for tex in extremes)
            return np.all(low == high, axis=-1)
        finally:
            for thing in (*targets, *extremes):
                thing.release()

    # -- timing --------------------------------------------------------------------------------
    def time_modes(
        self, modes: list[str], frames: int = 7, t: float = 0.0, batch: int = 3
    ) -> dict[str, float]:
        """Median wall-clock time of one frame per mode, in milliseconds (time_rounds)."""
        rounds = self.time_rounds(modes, frames, t, batch)
        return {mode: statistics.median(values) for mode, values in rounds.items()}

    def time_rounds(
        self, modes: list[str], frames: int = 7, t: float = 0.0, batch: int = 3
    ) -> dict[str, list[float]]:
        """Wall-clock milliseconds of one frame per mode, one value per round (`frames` rounds).

        Modes are measured round-robin (`frames` rounds; each round draws every mode its batch of frames and
        ends each batch with glFinish), so that drifts of the machine's load hit every mode alike. A mode's
        batch (at least `batch`) grows so that its sample lasts at least MIN_SAMPLE_MS: frames of a
        millisecond (the 256² zone plate) varied by 10 % between two calls with a batch of 3. Each mode has
        its own batch: one set by the fastest mode made a slow mode of a tiny image draw MAX_BATCH frames
        a sample (the diffraction Taylor path at 48 x 32: 35 s of `compare`'s timing). GL timer queries are
        not used: on llvmpipe they return the time to queue commands, not to rasterise them (measured:
        0.02 ms for a frame that takes 3 ms of wall time).
        """
        batches: dict[str, int] = {}
        for mode in modes:  # compile and warm up, then one timed frame each
            self.draw(mode, t)
            self.ctx.finish()
            start = time.perf_counter()
            self.draw(mode, t)
            self.ctx.finish()
            first = 1000.0 * (time.perf_counter() - start)
            batches[mode] = max(batch, min(MAX_BATCH, math.ceil(MIN_SAMPLE_MS / max(first, 1e-3))))
        samples: dict[str, list[float]] = {mode: [] for mode in modes}
        for _ in range(frames):
            for mode in modes:
                start = time.perf_counter()
                for _ in range(batches[mode]):
                    self.draw(mode, t)
                self.ctx.finish()
                samples[mode].append(1000.0 * (time.perf_counter() - start) / batches[mode])
        return samples

    def time_reference(self, spp: int, t: float = 0.0) -> float:
        """Wall-clock milliseconds of one reference frame (all spp passes)."""
        self.ctx.finish()
        start = time.perf_counter()
        self.reference(spp, t)
        self.ctx.finish()
        return 1000.0 * (time.perf_counter() - start)

    def release(self) -> None:
        for gpu in self.objects:
            gpu.release()
        for obj in (
            self.fbo,
            self.colour,
            self.depth,
            self.accum,
            self.accum_tex,
            self.accumulate_vao,
            self.accumulate,
        ):
            obj.release()


def sample_offsets(spp: int, seed: int = 0, jitter: bool = True) -> list[tuple[float, float]]:
    """The reference's N x N (N = round(sqrt(spp))) stratified sub-pixel offsets in [-1/2, 1/2]², row by
    row; jitter=False puts each at its stratum's centre."""
    n = max(1, round(math.sqrt(spp)))
    rng = np.random.default_rng(seed)
    u = (lambda: rng.random()) if jitter else (lambda: 0.5)
    return [((i + u()) / n - 0.5, (j + u()) / n - 0.5) for j in range(n) for i in range(n)]


def frame_uniforms(
    scene: Scene,
    obj: SceneObject,
    clip_from_world: np.ndarray,
    camera,
    t: float,
    jitter: tuple[float, float] = (0.0, 0.0),
) -> dict[str, object]:
    """The renderer's per-frame uniforms of one object (docs/export.md lists them for engines)."""
    world_from_object = obj.world_from_object
    object_from_world = np.linalg.inv(world_from_object)
    if camera.projection == "orthographic":  # rays along the view direction (w = 0)
        eye = np.append(object_from_world[:3, :3] @ (camera.target - camera.eye), 0.0)
    else:
        eye = object_from_world @ np.append(camera.eye, 1.0)
    lights = [x.at(t) for x in scene.lights[:MAX_LIGHTS]]
    lights += [Light(np.zeros(3), np.zeros(3))] * (MAX_LIGHTS - len(lights))
    return {
        "u_clipFromObject": (clip_from_world @ world_from_object).T,  # column-major for GLSL
        "u_worldNormalFromObject": np.linalg.inv(world_from_object[:3, :3]),  # (M^-1)^T, transposed
        "u_jitter": jitter,
        "u_eyeObject": eye,  # ray-marched materials: the eye (w = 1) or view direction (w = 0)
        "u_objectFromWorld": object_from_world.T,
        "sh_lit": int(obj.lit),
        "sh_ambient": scene.ambient if scene.lights else 1.0,
        "sh_lightCount": len(scene.lights),
        "sh_lightDirection": np.stack([x.direction for x in lights]),
        "sh_lightColour": np.stack([x.colour for x in lights]),
    }


def composite(rgba: np.ndarray, background: np.ndarray) -> np.ndarray:
    """Premultiplied RGBA over a constant linear background -> linear RGB."""
    return rgba[..., :3] + (1.0 - rgba[..., 3:4]) * np.asarray(background, dtype=np.float32)


def coverage_mask(reference_rgba: np.ndarray, threshold: float = 1.0 - 1e-4) -> np.ndarray:
    """Pixels fully covered by the scene's surfaces (every reference sample hit an opaque surface)."""
    return reference_rgba[..., 3] >= threshold
