// tabulated.glsl -- the driver image at its base level, as each pass of the reference sees it.
//
// tb_driverAtBase(driver, uv): f at uv (image repeats once per unit, REPEAT), reconstructed bilinearly from
// the four nearest texels of level 0 with texelFetch. Not textureLod(driver, uv, 0.0): the driver's
// sampler is 16x anisotropic for the naive and gaussian modes, and Mesa llvmpipe still filters a
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
