// Fragment stage of Hart's model: one MODE_* define selects the unfiltered, naive or filtered look.
//   MODE_POINT          c(f) at the pixel centre, eq. (2) (also each pass of the reference)
//   MODE_NAIVE          c(f with unresolved noise terms dropped), what renderers do today
//   The hart-* and gaussian modes centre their filter on an estimate of the pixel mean of f
//   (pt_driverGradMean, beyond the paper); PT_FIRST_ORDER centres it on f at the pixel centre, as printed.
//   MODE_HART_MIP       colour-table MIP map over width |grad f| (section 3.3.1)
//   MODE_HART_SAT       summed-area colour table over width |grad f| (section 3.3.2, eq. 15)
//   MODE_HART_MIP_ANISO / MODE_HART_SAT_ANISO  the two screen axes of the footprint kept apart: the
//                       linearised f over a box pixel is box(|df/dx|) * box(|df/dy|), a trapezoid
//   MODE_HART_WIDTH     the filter width in table entries, log scale 1 (black) .. n (white), Fig. 9c
//   MODE_GAUSSIAN       Heitz et al.'s preconvolved colour map at the footprint's (μ, σ) of f. The linear
//                       part of f over a box pixel is box(|g_x|) * box(|g_y|), flat-topped: the map is
//                       read box-filtered over the major axis |g_major| (cm_gaussianBox, the summed rows of
//                       the bake) with the Gaussian's variance g_minor²/12 + σ_res², which follows it where
//                       the gradient dominates (zone plate, wood) and is C̄(μ, σ) where it does not.
//   MODE_GAUSSIAN_SIGMA diagnostic: (σ_lin, σ_res, 0), the linear (Hart) and unresolved-noise parts of σ
// u_quantStep > 0 quantises solid coordinates to that step (Hart section 4.3, Fig. 10).

#include "procedural/hart.glsl"
#include "colormap/colormap.glsl"
#include "glsl/common/shading.glsl"

in vec3 v_solid;
in vec3 v_normal;

uniform sampler2D u_tablePoint;  // @table u: the driver value f in table periods, n = width entries (a power of two), entry i covering f in [i/n, (i+1)/n); read with texelFetch at i = floor(n fract(f)) for PT_WRAP = 0 (modulo) or min(floor(n clamp(f, 0, 1)), n - 1) for PT_WRAP = 1 (clamp); one row, NEAREST, no MIP; RGBA: the colour table c(f) in linear RGB premultiplied by alpha, and alpha
uniform sampler2D u_tableMip;  // @table u: the driver value f in table periods, texel i centred at f = (i + 0.5)/n with n = width (REPEAT for PT_WRAP = 0, modulo; CLAMP_TO_EDGE for PT_WRAP = 1, clamp); one row; MIP level L: box averages of 2^L entries (Hart §3.3.1), read at lod = log2(filter width in table periods x n); RGBA: the colour table in linear RGB premultiplied by alpha, and alpha
uniform sampler2D u_tableSat;  // @table one row of n + 3 texels, n the colour table's size: texels 0..n hold the summed-area table S[i] = clut[0] + ... + clut[i-1] (S[0] = 0; sums of the premultiplied linear RGBA entries), texels n+1 and n+2 hold clut[0] and clut[n-1]; read LINEAR at u = (x + 0.5)/(n + 3) for x = n f texels of the driver f, which gives the exact integral of the table over [0, x] (Hart eqs. 13-15); PT_WRAP: 0 modulo (the table repeats), 1 clamp (the edge entries extend it); no MIP
uniform sampler2D u_tableGaussianBox;  // @table the preconvolved colour map C̄(μ, σ) = [clut * N(0, σ²)](μ) of Heitz et al. 2014 eq. 9, its rows integrated over μ for box-filtered reads (colormap/gaussian.py, PreconvolvedMap.box_data) with u_gaussianRange = (mu_lo, mu_hi, sigma_max) and n μ texels over [mu_lo, mu_hi]: 3n + 1 columns, column c holds S(c - n), the sum of C̄(μ, σ) over the μ texels between mu_lo and mu_lo + (c - n)(mu_hi - mu_lo)/n (negative below mu_lo), over three copies of the range: the table's periods for PT_WRAP = 0 (modulo), its edge columns extended for PT_WRAP = 1 (clamp); read LINEAR at u = (c + 0.5)/(3n + 1); v: the standard deviation σ of f over the footprint, row j at σ = sigma_max j/(height - 1) (read at v = (σ/sigma_max (height - 1) + 0.5)/height; σ > sigma_max reads the last row; row 0 integrates the table itself); RGBA: sums of linear premultiplied RGBA and alpha; CLAMP_TO_EDGE, no MIP
uniform vec3 u_gaussianRange;
// The table's wrap mode, CM_MODULO (0) or CM_CLAMP (1), fixed per material at compile time (PT_WRAP):
// with a uniform, llvmpipe evaluated both sides of every wrap test (for a modulo table, cm_sat's two edge
// fetches of the clamp case cost 0.17x of a zone-plate `point` frame).
#ifndef PT_WRAP
#define PT_WRAP 0
#endif
const int pt_wrap = PT_WRAP;
uniform float u_quantStep;

out vec4 o_colour;

void main() {
    vec3 s = v_solid;
    vec3 dsdx = dFdx(s);
    vec3 dsdy = dFdy(s);
    if (u_quantStep > 0.0) {
        s = floor(s / u_quantStep + 0.5) * u_quantStep;
    }
    vec4 albedo;
#if defined(MODE_POINT)
    albedo = cm_point(u_tablePoint, pt_driver(s), pt_wrap);
#elif defined(MODE_NAIVE)
    albedo = cm_point(u_tablePoint, pt_driverOctaveClamped(s, dsdx, dsdy), pt_wrap);
#elif defined(MODE_GAUSSIAN)
    vec4 stats = pt_driverGaussian(s, dsdx, dsdy);
    float major = max(abs(stats.y), abs(stats.z));
    float minor = min(abs(stats.y), abs(stats.z));
    albedo = cm_gaussianBox(u_tableGaussianBox, stats.x, major, sqrt(minor * minor / 12.0 + stats.w), pt_wrap,
                            u_gaussianRange);
#elif defined(MODE_GAUSSIAN_SIGMA)
    vec4 stats = pt_driverGaussian(s, dsdx, dsdy);
    o_colour = vec4(sqrt((stats.y * stats.y + stats.z * stats.z) / 12.0), sqrt(stats.w), 0.0, 1.0);
    return;
#else
    vec4 fg = pt_driverGradMean(s, dsdx, dsdy);  // (df/ds, the box's centre)
    float gx = dot(fg.xyz, dsdx);
    float gy = dot(fg.xyz, dsdy);
#if defined(MODE_HART_MIP)
    albedo = cm_mip(u_tableMip, fg.w, length(vec2(gx, gy)), pt_wrap);
#elif defined(MODE_HART_SAT)
    albedo = cm_sat(u_tableSat, fg.w, length(vec2(gx, gy)), pt_wrap);
#elif defined(MODE_HART_MIP_ANISO)
    albedo = cm_mip2(u_tableMip, fg.w, gx, gy, pt_wrap);
#elif defined(MODE_HART_SAT_ANISO)
    albedo = cm_sat2(u_tableSat, fg.w, gx, gy, pt_wrap);
#elif defined(MODE_HART_WIDTH)
    float entries = float(textureSize(u_tableSat, 0).x - 1);
    float level = clamp(log2(max(length(vec2(gx, gy)) * entries, 1.0)) / log2(entries), 0.0, 1.0);
    o_colour = vec4(vec3(level), 1.0);
    return;
#else
#error "unknown MODE_ define"
#endif
#endif
    o_colour = sh_shade(albedo, v_normal, gl_FrontFacing);
}
