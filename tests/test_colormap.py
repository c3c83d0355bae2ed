"""Colour tables (prefilter.colormap.table) and their GLSL lookups (colormap/colormap.glsl), Hart et al. 1999.

Oracles: the IEC 61966-2-1 sRGB curve (and colour-science's eotf_sRGB); block means for the MIP map;
exact float64 integrals of the piecewise-constant table (`box_average`, cross-checked against an
independent per-texel CDF sum and dense sampling of eq. 2); the exact trapezoid average for two-axis
footprints. GLSL runs through transform feedback (glsl_eval) for the gl330 and es300 targets.
"""

from __future__ import annotations

import numpy as np
import pytest

from prefilter import PrefilterError
from prefilter.colormap.table import ColourTable, parse_srgb
from prefilter.gl.context import gl_context
from prefilter.gl.evaluate import glsl_eval
from prefilter.gl.program import build_program
from prefilter.images import srgb_to_linear

CM_GLSL = ("colormap/colormap.glsl",)
TARGETS = ("gl330", "es300")
N = 256
RNG_SEED = 20240611


def _smooth_entries(n: int = N) -> tuple[np.ndarray, float]:
    """A smooth periodic table g((i + 0.5)/n) and the Lipschitz constant of g per unit f."""
    centres = (np.arange(n) + 0.5) / n
    phase = np.array([0.0, 1.0, 2.0, 3.0])
    g = (
        0.5
        + 0.3 * np.sin(2 * np.pi * centres[:, None] + phase)
        + 0.1 * np.sin(4 * np.pi * centres[:, None] + 2 * phase)
    )
    return g.astype(np.float32), 0.3 * 2 * np.pi + 0.1 * 4 * np.pi


def _random_entries(n: int = N, seed: int = 1) -> np.ndarray:
    return np.random.default_rng(seed).random((n, 4)).astype(np.float32)


@pytest.fixture(scope="module")
def gl():
    return gl_context()


@pytest.fixture(scope="module")
def uploaded(gl):
    """{(kind, wrap): (table, textures)} for a random (sharp) and a smooth table, both wraps."""
    tables = {}
    for kind, entries in (("random", _random_entries()), ("smooth", _smooth_entries()[0])):
        for wrap in ("modulo", "clamp"):
            table = ColourTable(entries, wrap)
            tables[kind, wrap] = (table, table.upload(gl))
    yield tables
    for _, textures in tables.values():
        textures.release()


def _eval(expr, inputs, sampler, texture, target="gl330", defines=None):
    return glsl_eval(
        expr,
        {k: np.asarray(v, np.float32) for k, v in inputs.items()},
        4,
        includes=CM_GLSL,
        target=target,
        defines=defines,
        prelude=f"uniform sampler2D {sampler};",
        textures={sampler: texture},
    )


def _f32(*arrays):
    """Round inputs to float32 first: the oracle must see exactly what the shader sees."""
    return [np.asarray(a, np.float32).astype(np.float64) for a in arrays]


# --- baking --------------------------------------------------------------------------------------------


def test_srgb_decoding_matches_iec_61966_2_1():
    v = np.array([0.0, 0.01, 0.04045, 0.0405, 0.2, 0.5, 0.735, 1.0])
    iec = np.array([x / 12.92 if x <= 0.04045 else ((x + 0.055) / 1.055) ** 2.4 for x in v])
    np.testing.assert_allclose(srgb_to_linear(v), iec, rtol=0, atol=1e-15)
    np.testing.assert_allclose(srgb_to_linear(0.5), 0.21404114048223255, atol=1e-15)  # textbook value
    colour = pytest.importorskip("colour")
    grid = np.linspace(0.0, 1.0, 1001)
    np.testing.assert_allclose(srgb_to_linear(grid), colour.models.eotf_sRGB(grid), atol=1e-12)


def test_parse_srgb_hex_and_tuples():
    np.testing.assert_allclose(parse_srgb("#ffffff"), [1, 1, 1, 1])
    np.testing.assert_allclose(parse_srgb("#000000"), [0, 0, 0, 1])
    got = parse_srgb("#80402080")
    np.testing.assert_allclose(got[:3], srgb_to_linear(np.array([0x80, 0x40, 0x20]) / 255.0), atol=1e-15)
    assert got[3] == pytest.approx(0x80 / 255.0)  # alpha is not gamma-decoded
    np.testing.assert_allclose(parse_srgb((0.5, 0.25, 1.0, 0.3)), [*srgb_to_linear([0.5, 0.25, 1.0]), 0.3])
    np.testing.assert_allclose(parse_srgb([0.5, 0.5, 0.5]), [0.21404114048223255] * 3 + [1.0])


def test_from_stops_interpolates_in_linear_rgb_at_texel_centres():
    n = 8
    table = ColourTable.from_stops([(0.0, "#000000"), (1.0, "#ffffff")], n=n)
    centres = (np.arange(n) + 0.5) / n
    np.testing.assert_allclose(table.entries[:, 0], centres, atol=1e-7)  # linear in *linear* RGB
    np.testing.assert_allclose(table.entries[:, 3], 1.0)
    assert table.entries.dtype == np.float32 and table.entries.shape == (n, 4)

    red, blue = parse_srgb("#ff0000"), parse_srgb("#0000ff")
    table = ColourTable.from_stops([(0.25, "#ff0000"), (0.75, (0.0, 0.0, 1.0))], n=n, wrap="clamp")
    t = np.clip((centres - 0.25) / 0.5, 0.0, 1.0)
    np.testing.assert_allclose(table.entries, red + t[:, None] * (blue - red), atol=1e-7)  # ends hold

    step = ColourTable.from_stops([(0.0, "#ff0000"), (0.5, "#0000ff")], n=n, interpolation="step")
    np.testing.assert_allclose(step.entries[:4], np.tile(red, (4, 1)), atol=1e-7)
    np.testing.assert_allclose(step.entries[4:], np.tile(blue, (4, 1)), atol=1e-7)

    hard = ColourTable.from_stops(
        [(0.0, "#000000"), (0.5, "#000000"), (0.5, "#ffffff"), (1.0, "#ffffff")], n=n
    )
    np.testing.assert_allclose(hard.entries[:, 0], [0, 0, 0, 0, 1, 1, 1, 1], atol=1e-7)

    single = ColourTable.from_stops([(0.3, "#336699")], n=4)
    np.testing.assert_allclose(single.entries, np.tile(parse_srgb("#336699"), (4, 1)), atol=1e-7)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"stops": []}, "at least one colour stop"),
        ({"stops": [(0.0, "#000000")], "n": 100}, "power of two"),
        ({"stops": [(0.0, "#000000")], "n": 1}, "power of two"),
        ({"stops": [(0.0, "#000000")], "wrap": "mirror"}, "wrap must be one of"),
        ({"stops": [(0.0, "#000000")], "interpolation": "cubic"}, "interpolation must be one of"),
        ({"stops": [(0.5, "#000000"), (0.2, "#ffffff")]}, "stops[1]: positions must be sorted"),
        ({"stops": [(1.5, "#000000")]}, "stops[0]: position 1.5 is outside [0, 1]"),
        ({"stops": [(0.0, "#00000")]}, "stops[0]: expected an sRGB colour"),
        ({"stops": [(0.0, (0.0, 2.0, 0.0))]}, "outside [0, 1]"),
        ({"stops": [(0.0, (0.0, 0.0))]}, "stops[0]: expected an sRGB colour"),
        ({"stops": [(0.0,)]}, "stops[0]: expected (position, colour)"),
        ({"stops": [("a", "#000000")]}, "position must be a number"),
    ],
)
def test_from_stops_validation(kwargs, message):
    with pytest.raises(PrefilterError) as info:
        ColourTable.from_stops(**kwargs)
    assert message in str(info.value)
    assert "\n" not in str(info.value)


def test_premultiplied():
    entries = _random_entries(8)
    pre = ColourTable(entries, "clamp").premultiplied()
    np.testing.assert_allclose(pre.entries[:, :3], entries[:, :3] * entries[:, 3:], rtol=1e-7)
    np.testing.assert_array_equal(pre.entries[:, 3], entries[:, 3])
    assert pre.wrap == "clamp"


def test_mip_levels_are_block_means():
    table = ColourTable(_random_entries(64), "modulo")
    levels = table.mip_levels()
    assert [len(level) for level in levels] == [64, 32, 16, 8, 4, 2, 1]
    np.testing.assert_array_equal(levels[0], table.entries.astype(np.float64))
    for lev, level in enumerate(levels):
        block = 2**lev
        means = table.entries.astype(np.float64).reshape(-1, block, 4).mean(axis=1)
        np.testing.assert_allclose(level, means, atol=1e-15)
        # ... which is the exact box average of width 2^L texels at the level's texel centres
        centres = (np.arange(len(level)) + 0.5) * block / 64
        np.testing.assert_allclose(table.box_average(centres, block / 64), level, atol=1e-13)
    np.testing.assert_allclose(levels[-1][0], table.entries.mean(axis=0), atol=1e-7)


def test_summed_area_table():
    table = ColourTable(_random_entries(16), "modulo")
    sums = table.summed_area()
    assert sums.shape == (17, 4)
    np.testing.assert_array_equal(sums[0], 0.0)
    np.testing.assert_allclose(np.diff(sums, axis=0), table.entries, atol=1e-15)  # eq. (14)
    np.testing.assert_allclose(sums[-1], table.entries.astype(np.float64).sum(axis=0), atol=1e-12)


@pytest.mark.parametrize("wrap", ["modulo", "clamp"])
def test_upload_layout(gl, wrap):
    table = ColourTable(_random_entries(32), wrap)
    textures = table.upload(gl)
    try:
        assert (textures.n, textures.wrap_code) == (32, {"modulo": 0, "clamp": 1}[wrap])
        assert textures.point.size == (32, 1) and textures.sat.size == (35, 1)
        assert textures.mip.repeat_x == (wrap == "modulo")
        np.testing.assert_array_equal(
            np.frombuffer(textures.point.read(), np.float32).reshape(32, 4), table.entries
        )
        for level, want in enumerate(table.mip_levels()):
            got = np.frombuffer(textures.mip.read(level=level), np.float32).reshape(-1, 4)
            np.testing.assert_array_equal(got, want.astype(np.float32))
        texels = np.frombuffer(textures.sat.read(), np.float32).reshape(35, 4).astype(np.float64)
        np.testing.assert_allclose(texels[:33], table.summed_area(), rtol=1e-7, atol=0)  # float32 S
        np.testing.assert_array_equal(texels[33:], table.entries[[0, -1]])  # edge entries for clamp
    finally:
        textures.release()


# --- the float64 oracles themselves -------------------------------------------------------------------


@pytest.mark.parametrize("wrap", ["modulo", "clamp"])
def test_box_average_oracle(wrap):
    rng = np.random.default_rng(RNG_SEED)
    table = ColourTable(_random_entries(16), wrap)
    f = rng.uniform(-3.0, 4.0, 60)
    w = 10.0 ** rng.uniform(-3.0, 0.5, 60)
    exact = table.box_average(f, w)
    # an independent exact route: texel masses of the box CDF (trapezoid with a zero second width)
    np.testing.assert_allclose(table.trapezoid_average(f, w, 0.0), exact, atol=1e-12)
    # dense midpoint sampling of eq. (2) over the box converges to it
    u = (np.arange(20000) + 0.5) / 20000 - 0.5
    for fi, wi, ei in zip(f[:8], w[:8], exact[:8], strict=True):
        np.testing.assert_allclose(table.point(fi + wi * u).mean(axis=0), ei, atol=2e-3)
    if wrap == "modulo":
        np.testing.assert_allclose(
            table.box_average(f, 2.0), np.tile(table.entries.mean(0), (60, 1)), atol=1e-7
        )
        np.testing.assert_allclose(table.box_average(f + 5.0, w), exact, atol=1e-12)  # periodic
    else:
        np.testing.assert_allclose(table.box_average(-10.0, 0.5), table.entries[0], atol=1e-12)
        np.testing.assert_allclose(table.box_average(7.0, 3.0), table.entries[-1], atol=1e-12)


@pytest.mark.parametrize("wrap", ["modulo", "clamp"])
def test_trapezoid_average_oracle(wrap):
    rng = np.random.default_rng(RNG_SEED + 1)
    table = ColourTable(_random_entries(16), wrap)
    f = rng.uniform(-2.0, 3.0, 12)
    wa = rng.uniform(-0.6, 0.6, 12)
    wb = rng.uniform(-0.6, 0.6, 12)
    got = table.trapezoid_average(f, wa, wb)
    v = (np.arange(4000) + 0.5) / 4000 - 0.5  # mean over v of the exact box of width |wa|
    for i in range(12):
        want = table.box_average(f[i] + wb[i] * v, abs(wa[i])).mean(axis=0)
        np.testing.assert_allclose(got[i], want, atol=1e-5)
    np.testing.assert_allclose(
        table.trapezoid_average(f, wa, wb), table.trapezoid_average(f, wb, -wa), atol=1e-14
    )


# --- GLSL ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("target", ["gl330", "gl450", "es300"])
def test_colormap_glsl_compiles(gl, target):
    source = '#include "colormap/colormap.glsl"\nout vec4 result;\nvoid main() { result = vec4(0.0); }\n'
    fragment = "out vec4 fragColor;\nvoid main() { fragColor = vec4(0.0); }\n"
    build_program(gl, source, fragment, target=target, defines={"CM_PROBES": 3}).release()


@pytest.mark.parametrize("target", TARGETS)
@pytest.mark.parametrize("wrap", ["modulo", "clamp"])
def test_cm_point_is_eq2(uploaded, wrap, target):
    table, textures = uploaded["random", wrap]
    rng = np.random.default_rng(RNG_SEED + 2)
    k = np.arange(-2 * N, 3 * N)
    edges = np.concatenate([k / N, k / N + 1e-6, k / N - 1e-6])  # texel boundaries and either side
    specials = np.array([0.0, 1.0, -0.0, 1e-9, -1e-9, 1 - 1e-9, 0.999999, 1.000001, -37.25, 1e3, -1e3])
    (f,) = _f32(np.concatenate([rng.uniform(-5.0, 6.0, 4000), edges, specials]))
    got = _eval(f"cm_point(tab, f, {textures.wrap_code})", {"f": f}, "tab", textures.point, target)
    np.testing.assert_array_equal(got, table.point(f).astype(np.float32))


def _centres_and_widths(rng, count, w_max):
    f = np.concatenate(
        [
            rng.uniform(-0.1, 1.1, count // 2),
            rng.uniform(-60.0, 60.0, count // 4),
            rng.uniform(-3, 3, count // 4),
        ]
    )
    w = 10.0 ** rng.uniform(-4.0, np.log10(w_max), len(f))
    return _f32(f, w)


@pytest.mark.parametrize("target", TARGETS)
@pytest.mark.parametrize("wrap", ["modulo", "clamp"])
def test_cm_sat_is_the_exact_box_average(uploaded, wrap, target):
    table, textures = uploaded["random", wrap]
    rng = np.random.default_rng(RNG_SEED + 3)
    f, w = _centres_and_widths(rng, 6000, 3.0)
    got = _eval(f"cm_sat(sat, f, w, {textures.wrap_code})", {"f": f, "w": w}, "sat", textures.sat, target)
    # widths below one entry are widened to one entry (float32 sums; see colormap.glsl)
    want = table.box_average(f, np.maximum(w, 1.0 / N))
    if wrap == "modulo":  # Hart's rule: w >= one period gives the whole-table mean
        want[w >= 1.0] = table.entries.astype(np.float64).mean(axis=0)
    # float32 S reaches N = 256 (entries <= 1): ~3e-5 per end, divided by a width >= one entry
    np.testing.assert_allclose(got, want, rtol=0, atol=8e-5)
    # negative widths are |w|; exact texel-boundary centres and aligned ends
    f_edge, w_edge = _f32(np.arange(-N, 2 * N) / N, np.full(3 * N, 2.0 / N))
    got = _eval(
        f"cm_sat(sat, f, -w, {textures.wrap_code})", {"f": f_edge, "w": w_edge}, "sat", textures.sat, target
    )
    np.testing.assert_allclose(got, table.box_average(f_edge, w_edge), rtol=0, atol=8e-5)


@pytest.mark.parametrize("wrap", ["modulo", "clamp"])
def test_cm_sat_zero_width_is_a_one_entry_box(uploaded, wrap):
    """Below one entry the footprint is widened to one entry; centred on a texel that is the entry."""
    table, textures = uploaded["random", wrap]
    (f,) = _f32(np.random.default_rng(RNG_SEED + 4).uniform(-3.0, 4.0, 500))
    got = _eval(f"cm_sat(sat, f, 0.0, {textures.wrap_code})", {"f": f}, "sat", textures.sat)
    np.testing.assert_allclose(got, table.box_average(f, 1.0 / N), atol=8e-5)
    (centres,) = _f32((np.arange(-N, 2 * N) + 0.5) / N)
    got = _eval(f"cm_sat(sat, f, 0.0, {textures.wrap_code})", {"f": centres}, "sat", textures.sat)
    np.testing.assert_allclose(got, table.point(centres), atol=8e-5)


def test_cm_sat_whole_table_average_for_modulo(uploaded):
    table, textures = uploaded["random", "modulo"]
    rng = np.random.default_rng(RNG_SEED + 5)
    f, w = _f32(rng.uniform(-10.0, 10.0, 400), rng.uniform(1.0, 5.0, 400))
    w[:4] = [1.0, 2.0, 3.0, 1.0 + 2.0**-20]
    mean = table.entries.astype(np.float64).mean(axis=0)
    for expr in ("cm_sat(sat, f, w, 0)", "cm_sat2(sat, f, w, 0.5 * w, 0)"):
        got = _eval(expr, {"f": f, "w": w}, "sat", textures.sat)
        np.testing.assert_allclose(got, np.tile(mean, (len(f), 1)), atol=1e-6)
    # for whole numbers of periods Hart's rule is the exact box average
    np.testing.assert_allclose(table.box_average(f[:3], w[:3]), np.tile(mean, (3, 1)), atol=1e-12)
    got = _eval("cm_mip(mip, f, w, 0)", {"f": f, "w": w}, "mip", textures.mip)  # lod >= log2(n): top level
    np.testing.assert_allclose(got, np.tile(mean, (len(f), 1)), atol=1e-6)


@pytest.mark.parametrize("wrap", ["modulo", "clamp"])
def test_cm_mip_below_float_resolution_is_the_level_0_lookup(uploaded, wrap):
    """A footprint narrower than f's float spacing (a close-up, or a solid texture scaled to nearly nothing):
    f ± w/2 round to f, and the clamp table's weights were all 0 (NaN). The answer is level 0's linear
    interpolation of the entries at f, np.interp here."""
    table, textures = uploaded["random", wrap]
    (f,) = _f32(np.random.default_rng(RNG_SEED + 9).uniform(0.1, 0.9, 300))
    w = np.full_like(f, 1e-9)  # f's float32 spacing is 7.5e-9 to 6e-8 here
    x = f * N - 0.5
    want = np.stack([np.interp(x, np.arange(N), table.entries[:, c]) for c in range(4)], axis=-1)
    code = textures.wrap_code
    for expr in (f"cm_mip(mip, f, w, {code})", f"cm_mip2(mip, f, w, 0.5 * w, {code})"):
        got = _eval(expr, {"f": f, "w": w}, "mip", textures.mip)
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-5)


@pytest.mark.parametrize("target", TARGETS)
@pytest.mark.parametrize("wrap", ["modulo", "clamp"])
def test_cm_mip_is_exact_on_aligned_power_of_two_boxes(uploaded, wrap, target):
    table, textures = uploaded["random", wrap]
    rng = np.random.default_rng(RNG_SEED + 6)
    fs, ws = [], []
    for level in range(int(np.log2(N)) + 1):
        block = 2**level
        centres = (np.arange(N // block) + 0.5) * block / N  # this level's texel centres
        if wrap == "modulo":
            centres = centres + rng.integers(-4, 5, len(centres))  # whole periods away
        fs.append(centres)
        ws.append(np.full(len(centres), block / N))
    f, w = _f32(np.concatenate(fs), np.concatenate(ws))
    got = _eval(f"cm_mip(mip, f, w, {textures.wrap_code})", {"f": f, "w": w}, "mip", textures.mip, target)
    np.testing.assert_allclose(got, table.box_average(f, w), rtol=0, atol=1e-5)  # measured: 3e-8


@pytest.mark.parametrize("target", TARGETS)
@pytest.mark.parametrize("wrap", ["modulo", "clamp"])
def test_cm_mip_trilinear_equals_the_texture_units_filter(uploaded, wrap, target):
    """cm_mipTrilinear (texelFetch) against the driver's own LINEAR_MIPMAP_LINEAR textureLod."""
    _, textures = uploaded["random", wrap]
    rng = np.random.default_rng(RNG_SEED + 9)
    u, lod = _f32(rng.uniform(-2.0, 3.0, 2000), rng.uniform(0.0, np.log2(N) + 1.5, 2000))
    if wrap == "clamp":
        u = np.clip(u, 0.0, 1.0)  # cm_mip only reads a clamp table inside [0, 1]
    clamp = "true" if wrap == "clamp" else "false"
    got = _eval(
        f"cm_mipTrilinear(mip, u, lod, {float(N)}, {clamp})",
        {"u": u, "lod": lod},
        "mip",
        textures.mip,
        target,
    )
    unit = _eval("textureLod(mip, vec2(u, 0.5), lod)", {"u": u, "lod": lod}, "mip", textures.mip, target)
    assert np.abs(got - unit).max() < 4e-3  # the texture unit rounds its weights (8 bits on llvmpipe)
    assert np.median(np.abs(got - unit)) < 1e-3


@pytest.mark.parametrize("wrap", ["modulo", "clamp"])
def test_cm_mip_error_bound_on_a_smooth_table(uploaded, wrap):
    """|cm_mip - box| <= L (3.25 max(w, 1/n) + 0.5/n) for a table sampled from an L-Lipschitz g.

    A trilinear MIP lookup at lod = log2(w n) reads level floor(lod) and the next one, each with a tent
    (linear) reconstruction. Level L texels are means of blocks of B = 2^L texels, B <= max(w n, 1); a
    linear tap at f touches the two texels whose centres lie within B of f (clamp: of the clamped
    coordinate), so every entry averaged lies within 1.5 B of f at level L and 3 B at level L+1: the
    lookup is a convex combination of entries within R = 3 max(w, 1/n) of f (in f units). Entries are
    g at texel centres, so it is within L R of g(f). The exact box average is within L (w/4 + 1/(2n)) of
    g(f) (mean distance w/4, half a texel of sampling; the clamp extension of g stays L-Lipschitz).
    Hence |mip - box| <= L (3.25 max(w, 1/n) + 0.5/n): first order in the width, as a box of about the
    right width must be. Measured on llvmpipe: max error/bound 0.12 for both wraps.
    """
    table, textures = uploaded["smooth", wrap]
    lipschitz = _smooth_entries()[1]
    rng = np.random.default_rng(RNG_SEED + 7)
    f, w = _centres_and_widths(rng, 4000, 3.0)
    got = _eval(f"cm_mip(mip, f, w, {textures.wrap_code})", {"f": f, "w": w}, "mip", textures.mip)
    err = np.abs(got - table.box_average(f, w)).max(axis=1)
    bound = lipschitz * (3.25 * np.maximum(w, 1.0 / N) + 0.5 / N) + 1e-5
    assert np.all(err <= bound), f"worst error/bound {np.max(err / bound):.3f}"
    small = w < 8.0 / N  # the regime that matters in images: a few texels
    assert err[small].max() < 0.02  # measured 0.0055 for both wraps (clamp: edge entries beyond the ends)


@pytest.mark.parametrize("target", TARGETS)
@pytest.mark.parametrize("wrap", ["modulo", "clamp"])
@pytest.mark.parametrize("probes", [2, 8])
def test_two_axis_footprint(uploaded, wrap, target, probes):
    """cm_sat2 / cm_mip2 against the exact trapezoid average.

    The trapezoid average is the mean over s in [-m/2, m/2] of g(s) = box_W(f + s) (W = max(|wa|,|wb|),
    m = min). CM_PROBES = P lookups at the midpoints of P equal sub-intervals make the midpoint rule;
    g is Lipschitz with constant (max clut - min clut)/W (shifting a box of width W by d changes its mean
    by at most d/W of the range), and the midpoint rule on an interval of length h errs by at most
    Lip * h / 4 per sub-interval, so |cm_sat2 - trapezoid| <= range * m / (4 P W) (+ float32 noise). For
    cm_mip2, each probe adds the MIP error bound of test_cm_mip_error_bound_on_a_smooth_table.
    Measured (random table, llvmpipe): worst cm_sat2 error/bound 0.31 / 0.23 (P = 2, modulo / clamp),
    0.14 / 0.16 (P = 8); max error 0.028 (P = 2) and 0.0023 (P = 8).
    """
    modulo = wrap == "modulo"
    rng = np.random.default_rng(RNG_SEED + 8)
    count = 300
    f = rng.uniform(-3.0, 3.0, count)
    w_max = 0.99 if modulo else 3.0  # modulo: Hart's whole-table rule takes over at W >= 1
    # the wider axis spans at least one entry (narrower boxes are widened to one entry, see cm_sat)
    wa = 10.0 ** rng.uniform(np.log10(1.0 / N), np.log10(w_max), count) * rng.choice([-1.0, 1.0], count)
    wb = 10.0 ** rng.uniform(-4.0, np.log10(w_max), count) * rng.choice([-1.0, 1.0], count)
    f, wa, wb = _f32(f, wa, wb)
    big, small = np.maximum(np.abs(wa), np.abs(wb)), np.minimum(np.abs(wa), np.abs(wb))
    inputs = {"f": f, "wa": wa, "wb": wb}
    defines = {"CM_PROBES": probes}

    table, textures = uploaded["random", wrap]
    want = table.trapezoid_average(f, wa, wb)
    got = _eval(
        f"cm_sat2(sat, f, wa, wb, {textures.wrap_code})", inputs, "sat", textures.sat, target, defines
    )
    spread = (table.entries.max(axis=0) - table.entries.min(axis=0)).max()
    bound = spread * small / (4 * probes * big) + 8e-5
    err = np.abs(got - want).max(axis=1)
    assert np.all(err <= bound), f"cm_sat2: worst error/bound {np.max(err / bound):.3f}"

    table, textures = uploaded["smooth", wrap]
    want = table.trapezoid_average(f, wa, wb)
    got = _eval(
        f"cm_mip2(mip, f, wa, wb, {textures.wrap_code})", inputs, "mip", textures.mip, target, defines
    )
    spread = (table.entries.max(axis=0) - table.entries.min(axis=0)).max()
    lipschitz = _smooth_entries()[1]
    bound = (
        spread * small / (4 * probes * big) + lipschitz * (3.25 * np.maximum(big, 1.0 / N) + 0.5 / N) + 1e-5
    )
    err = np.abs(got - want).max(axis=1)
    assert np.all(err <= bound), f"cm_mip2: worst error/bound {np.max(err / bound):.3f}"


def test_sat2_is_exact_when_the_footprint_is_one_dimensional(uploaded):
    table, textures = uploaded["random", "clamp"]
    rng = np.random.default_rng(RNG_SEED + 9)
    f, w = _f32(rng.uniform(-1.0, 2.0, 500), 10.0 ** rng.uniform(-4.0, 0.0, 500))
    got = _eval("cm_sat2(sat, f, 0.0, -w, 1)", {"f": f, "w": w}, "sat", textures.sat)
    np.testing.assert_allclose(got, table.box_average(f, np.maximum(w, 1.0 / N)), atol=8e-5)
