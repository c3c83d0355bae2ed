// Colour map over a tabulated driver image (colormap/tabulated.py): Heitz et al. §4.2.
//   MODE_POINT     c(f) with f reconstructed bilinearly at level 0 (each pass of the reference;
//                  tb_driverAtBase, texelFetch: no anisotropic blur)
//   MODE_NAIVE     c(E[f]) with E[f] over the pixel's footprint from the MIP map (today's renderers)
//   MODE_GAUSSIAN  C̄(E[f], sqrt(E[f²] − E[f]²)) from the MIP map of (f, f²) and the preconvolved map
// The footprint's moments: TB_PROBES > 0 trilinear probes along its longer axis (tb_footprintMoments),
// or with TB_PROBES = 0 one read through the GL's 16x anisotropic filter.
// u_driver: RG32F (f, f²) with exact block-mean levels, LINEAR_MIPMAP_LINEAR; anisotropy 1 with probes.

#include "colormap/colormap.glsl"
#include "colormap/tabulated.glsl"
#include "glsl/common/shading.glsl"

in vec3 v_normal;
in vec2 v_uv;

uniform sampler2D u_driver;  // @table u, v: the mesh uv times u_uvScale (the driver image tiles: REPEAT), one texel per image pixel; RG: (f, f²) with f = value_offset + value_scale x the image's first channel (PNG scaled to [0, 1]); MIP level L: exact block means of f and f² (2x2 box means of the level below, computed on the CPU), so σ² = E[f²] - E[f]² after trilinear filtering; LINEAR_MIPMAP_LINEAR, anisotropy 1 when TB_PROBES > 0 (the shader's probes) and 16 when TB_PROBES = 0; not colours
uniform sampler2D u_tablePoint;  // @table u: the driver value f in table periods, n = width entries (a power of two), entry i covering f in [i/n, (i+1)/n); read with texelFetch at i = floor(n fract(f)) for TB_WRAP = 0 (modulo) or min(floor(n clamp(f, 0, 1)), n - 1) for TB_WRAP = 1 (clamp); one row, NEAREST, no MIP; RGBA: the colour table c(f) in linear RGB premultiplied by alpha, and alpha
uniform sampler2D u_tableGaussian;  // @table the preconvolved colour map C̄(μ, σ) = [clut * N(0, σ²)](μ) of Heitz et al. 2014 eq. 9 with u_gaussianRange = (mu_lo, mu_hi, sigma_max); u: μ = E[f] from u_driver, in table periods: u = fract(μ) for TB_WRAP = 0 (modulo: one period, REPEAT, u_gaussianRange.xy = (0, 1)) or (μ - mu_lo)/(mu_hi - mu_lo) for TB_WRAP = 1 (clamp: CLAMP_TO_EDGE, the edge columns beyond), texel i at μ = mu_lo + (i + 0.5)(mu_hi - mu_lo)/width; v: σ = sqrt(E[f²] - E[f]²) from u_driver, row j at σ = sigma_max j/(height - 1) (read at v = (σ/sigma_max (height - 1) + 0.5)/height; σ > sigma_max reads the last row; row 0 is the table itself); RGBA: the colour table convolved with N(0, σ²) at μ, in linear RGB premultiplied by alpha, and alpha; LINEAR, no MIP
uniform vec3 u_gaussianRange;
uniform vec2 u_uvScale;  // @param 0.25..64 log UV scale: repeats (su, sv) of the driver image over the mesh's uvs; every mode follows (the MIP footprint is measured in the scaled uvs)
// The table's wrap mode, CM_MODULO (0) or CM_CLAMP (1), a compile-time constant as in procedural/hart.frag.
#ifndef TB_WRAP
#define TB_WRAP 0
#endif
const int tb_wrap = TB_WRAP;

out vec4 o_colour;

vec2 tb_moments(vec2 uv) {
#if TB_PROBES > 0
    return tb_footprintMoments(u_driver, uv, dFdx(uv), dFdy(uv));
#else
    return texture(u_driver, uv).xy;
#endif
}

void main() {
    vec2 uv = v_uv * u_uvScale;
    vec4 albedo;
#if defined(MODE_POINT)
    albedo = cm_point(u_tablePoint, tb_driverAtBase(u_driver, uv), tb_wrap);
#elif defined(MODE_NAIVE)
    albedo = cm_point(u_tablePoint, tb_moments(uv).x, tb_wrap);
#elif defined(MODE_GAUSSIAN)
    vec2 moments = tb_moments(uv);
    float sigma = sqrt(max(moments.y - moments.x * moments.x, 0.0));
    albedo = cm_gaussian(u_tableGaussian, moments.x, sigma, tb_wrap, u_gaussianRange);
#else
#error "unknown MODE_ define"
#endif
    o_colour = sh_shade(albedo, v_normal, gl_FrontFacing);
}
