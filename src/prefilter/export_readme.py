"""The README of an export bundle: uniforms, samplers, vertex layout and a minimal draw recipe.

Written from the bundle's own manifest (export.manifest) and the uniform declarations of its shaders,
so it names exactly what the files contain. docs/export.md documents the format in general.
"""

from __future__ import annotations

from prefilter.scene import Scene

_FRAME_UNIFORMS = (
    ("u_clipFromObject", "mat4", "clipFromCamera · cameraFromWorld · world_from_object"),
    ("u_worldNormalFromObject", "mat3", "inverse(world_from_object[0:3,0:3]), not transposed"),
    ("u_objectFromWorld", "mat4", "inverse(world_from_object)"),
    ("u_eyeObject", "vec4", "(object-space eye, 1); orthographic: (object-space view direction, 0)"),
    ("u_jitter", "vec2", "0 (sub-pixel offset in NDC, for supersampling passes)"),
    ("sh_lit", "int", "the object's `lit`"),
    ("sh_ambient", "float", "scene ambient (1 when the scene has no lights)"),
    ("sh_lightCount", "int", "number of lights"),
    ("sh_lightDirection[4]", "vec3[4]", "world directions towards the lights, zero-padded"),
    ("sh_lightColour[4]", "vec3[4]", "linear RGB light colours, zero-padded"),
)

_RECIPE = """\
```c
// once: for each object
vbo = upload(meshes/<object>.vertices.bin);  ibo = upload(meshes/<object>.indices.bin);
for each attribute a in scene.json mesh.attributes:           // skip names the program does not use
    loc = glGetAttribLocation(prog, a.name);
    glVertexAttribPointer(loc, a.size, GL_FLOAT, GL_FALSE, mesh.stride, (void*)a.offset);
for each sampler s (unit = its index in the table below):
    read tables/<object>/<s>.json; for each level L: glTexImage2D/3D(.., L, internal_format, w, h, [d],
        0, format, GL_FLOAT, rows of <s>.L.exr);  set GL_TEXTURE_MAX_LEVEL, filters, wraps, anisotropy
prog = compile(shaders/<object>/<mode>.gl330.vert, .frag)     // or .es300 for GLES / WebGL2

// every frame: render target RGBA32F (or RGBA16F) + depth; clear colour (0,0,0,0), depth 1
glEnable(GL_DEPTH_TEST);  cull back faces unless double_sided
for opaque objects first, then "over" objects in file order:
    "over": glEnable(GL_BLEND); glBlendFunc(GL_ONE, GL_ONE_MINUS_SRC_ALPHA); glDepthMask(GL_FALSE)
    glUseProgram(prog);  set the per-frame uniforms;  set the material uniforms of scene.json
    (matrices column-major, transpose = GL_FALSE);  point each sampler uniform at its unit
    glDrawElements(GL_TRIANGLES, index_count, GL_UNSIGNED_INT, 0);
// display: colour = premultiplied linear RGBA; show rgb + (1 - a) * background, then encode sRGB
```
"""


def _short(values: list, limit: int = 8) -> str:
    if len(values) > limit:
        return f"{len(values)} values (scene.json)"
    return ", ".join(f"{v:.6g}" if isinstance(v, float) else str(v) for v in values)


def bundle_readme(scene: Scene, data: dict, captured: list) -> str:
    w, h = scene.size
    modes = ", ".join(f"`{m['name']}` ({m['kind']})" for m in data["modes"])
    lines = [
        f"# {scene.name}: prefilter export bundle",
        "",
        scene.description,
        "",
        f"Drawn by `prefilter render {scene.name} --mode MODE` at {w}×{h}; every file here is described in",
        "prefilter's docs/export.md. Modes: " + modes + ".",
        "",
        "## Per-frame uniforms (every object, computed by your engine)",
        "",
        "| uniform | type | value |",
        "|---|---|---|",
        *(f"| `{n}` | {t} | {v} |" for n, t, v in _FRAME_UNIFORMS),
        "",
        "`view` in scene.json holds their values for the scene's own camera at t = 0, to check your",
        "camera code.",
        "",
    ]
    for obj, c in zip(data["objects"], captured, strict=True):
        mesh = obj["mesh"]
        layout = ", ".join(f"`{a['name']}` {a['size']}×float @ {a['offset']}" for a in mesh["attributes"])
        lines += [
            f"## Object `{obj['name']}`",
            "",
            f"- Shaders: `shaders/{obj['directory']}/<mode>.gl330|es300.vert|frag`.",
            f"- Mesh: {mesh['vertex_count']} vertices, {mesh['index_count'] // 3} triangles; "
            f"stride {mesh['stride']} bytes: {layout}.",
            f"- Blend `{obj['blend']}`, double-sided {str(obj['double_sided']).lower()}, "
            f"lit {str(obj['lit']).lower()}.",
            "",
        ]
        if obj["samplers"]:
            lines += [
                "| unit | sampler | table | filter (min/mag) | what it holds |",
                "|---|---|---|---|---|",
            ]
            for unit, (name, table) in enumerate(c.tables.items()):
                meta = table.metadata("", {})
                size = f"{meta['width']}×{meta['height']}" + (
                    f"×{meta['depth']}" if meta["kind"] != "2d" else ""
                )
                u = c.declarations.get(name)
                text = u.comment[len("@table") :].strip() if u and u.comment.startswith("@table") else ""
                lines.append(
                    f"| {unit} | `{name}` | {meta['kind']} {size} {meta['internal_format']}, "
                    f"{len(table.levels)} level(s) | {table.filter[0]}/{table.filter[1]} | {text} |"
                )
            lines.append("")
        lines += ["| material uniform | type | value |", "|---|---|---|"]
        for name, entry in obj["uniforms"].items():
            u = c.declarations.get(name)
            if u is None:
                continue  # set by the material but read by none of this scene's shaders
            kind = u.type + (f"[{u.array}]" if u.array else "")
            moving = " (moves with t: see `end`)" if "end" in entry else ""
            lines.append(f"| `{name}` | {kind} | {_short(entry['value'])}{moving} |")
        lines.append("")
        if obj["parameters"]:
            lines += ["Tunable parameters (`@param` in the GLSL):", ""]
            for p in obj["parameters"]:
                lines.append(
                    f"- `{p['uniform']}` {p['label']} in [{p['min']:g}, {p['max']:g}]: {p['description']}"
                )
            lines.append("")
    lines += ["## Minimal draw recipe", "", _RECIPE]
    return "\n".join(lines)
