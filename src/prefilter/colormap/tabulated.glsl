// tabulated.glsl -- the driver image at its base level, as each pass of the reference sees it.
//
// tb_driverAtBase(driver, uv): f at uv (image repeats once per unit, REPEAT), reconstructed bilinearly from
// the four nearest texels of level 0 with texelFetch. Not textureLod(driver, uv, 0.0): the driver's
// sampler is 16x anisotropic with `probes = 0`, and Mesa llvmpipe still filters a
// textureLod along the fragment's footprint (the GLSL spec takes explicit-lod derivatives as 0). On the
// terrain-data preset that averaged each "point" sample over up to 16 texels along the view, so the
// reference's per-pixel deviation of f in the far field came out 0.013 where the texels under the
// pixel give 0.11 (docs/colormaps.md). Sizes are powers of two (tabulated.py), so `& (size - 1)` wraps.

float tb_driverAtBase(sampler2D driver, vec2 uv) {
    ivec2 size = textureSize(driver, 0);
    vec2 x = uv * vec2(size) - 0.5;
    vec2 corner = floor(x);
    vec2 w = x - corner;
    ivec2 i = ivec2(corner);
    ivec2 wrap = size - 1;
    float f00 = texelFetch(driver, i & wrap, 0).x;
    float f10 = texelFetch(driver, (i + ivec2(1, 0)) & wrap, 0).x;
    float f01 = texelFetch(driver, (i + ivec2(0, 1)) & wrap, 0).x;
    float f11 = texelFetch(driver, (i + ivec2(1, 1)) & wrap, 0).x;
    return mix(mix(f00, f10, w.x), mix(f01, f11, w.x), w.y);
}

// tb_footprintMoments(driver, uv, dx, dy): (E[f], E[f²]) over the pixel's footprint, the parallelogram
// spanned by the uv derivatives dx, dy (a box pixel filter, as the reference's passes), from TB_PROBES
// trilinear reads of the moment pyramid spaced evenly along the longer of dx and dy: the footprint
// assembling of Schilling, Knittel and Strasser 1996 ("Texram") and of the GL's own anisotropic
// filtering, in the shader. Each read is one level finer than the level whose texels are as wide as its
// share of that axis (or as the shorter axis, if wider). A read at level L spreads over the level's box
// and the bilinear tent of two of its texels, which in variance is a box √3 2^L texels wide (so −0.79
// levels); −1 came out closest to the footprint's brute-force moments (tests/test_tabulated.py).
// The probes' mean of E[f²] minus the square of their mean of E[f] is the variance over the union of
// their footprints, so the spread between probes counts in σ² as the spread within each.
// The driver's sampler must be isotropic (anisotropy 1): llvmpipe filters even textureLod along the
// fragment's footprint otherwise. Why not the GL's 16x filter: on llvmpipe it runs in software, at about
// 4.4 `point` frames on the tabulated terrains, where 4 probes cost about 2.4 and score lower
// (docs/colormaps.md).
#ifndef TB_PROBES
#define TB_PROBES 4
#endif
const float TB_LEVEL_SHIFT = -1.0;  // levels below the one as wide as a probe's share (see above)

vec2 tb_footprintMoments(sampler2D driver, vec2 uv, vec2 dx, vec2 dy) {
    vec2 size = vec2(textureSize(driver, 0));
    float lx = dot(dx * size, dx * size), ly = dot(dy * size, dy * size);
    vec2 major = lx > ly ? dx : dy;
    float count = float(TB_PROBES);
    float texels = max(sqrt(max(lx, ly)) / count, sqrt(min(lx, ly)));
    float lod = log2(max(texels, 1e-6)) + TB_LEVEL_SHIFT;
    vec2 sum = vec2(0.0);
    for (int i = 0; i < TB_PROBES; ++i) {
        sum += textureLod(driver, uv + ((float(i) + 0.5) / count - 0.5) * major, lod).xy;
    }
    return sum / count;
}
