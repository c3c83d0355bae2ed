// Fragment stage of Hart's model: one MODE_* define selects the unfiltered, naive or filtered look.
//   MODE_POINT          c(f) at the pixel centre, eq. (2) (also each pass of the reference)
//   MODE_NAIVE          c(f with unresolved noise terms dropped), what renderers do today
//   MODE_HART_MIP       colour-table MIP map over width |grad f| (section 3.3.1)
//   MODE_HART_SAT       summed-area colour table over width |grad f| (section 3.3.2, eq. 15)
//   MODE_HART_MIP_ANISO / MODE_HART_SAT_ANISO  the two screen axes of the footprint kept apart: the
//                       linearised f over a box pixel is box(|df/dx|) * box(|df/dy|), a trapezoid
//   MODE_HART_WIDTH     the filter width in table entries, log scale 1 (black) .. n (white), Fig. 9c
//   MODE_GAUSSIAN       Heitz et al.'s preconvolved colour map at the footprint's (μ, σ) of f. The linear
//                       part of f over a box pixel is box(|g_x|) * box(|g_y|), flat-topped; two Gaussians
//                       at μ ± g_major/4, each with the variance of its half (g_major²/48 + g_minor²/12
//                       + σ_res²), follow it better than one where the gradient dominates (zone plate).
//   MODE_GAUSSIAN_SIGMA diagnostic: (σ_lin, σ_res, 0), the linear (Hart) and unresolved-noise parts of σ
// u_quantStep > 0 quantises solid coordinates to that step (Hart section 4.3, Fig. 10).

#include "procedural/hart.glsl"
#include "colormap/colormap.glsl"
#include "glsl/common/shading.glsl"

in vec3 v_solid;
in vec3 v_normal;

uniform sampler2D u_tablePoint;
uniform sampler2D u_tableMip;
uniform sampler2D u_tableSat;
uniform sampler2D u_tableGaussian;
uniform vec3 u_gaussianRange;
uniform int u_wrap;
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
    albedo = cm_point(u_tablePoint, pt_driver(s), u_wrap);
#elif defined(MODE_NAIVE)
    albedo = cm_point(u_tablePoint, pt_driverOctaveClamped(s, dsdx, dsdy), u_wrap);
#elif defined(MODE_GAUSSIAN)
    vec4 stats = pt_driverGaussian(s, dsdx, dsdy);
    float major = max(abs(stats.y), abs(stats.z));
    float minor = min(abs(stats.y), abs(stats.z));
    float sigma = sqrt(major * major / 48.0 + minor * minor / 12.0 + stats.w);
    albedo = 0.5 * (cm_gaussian(u_tableGaussian, stats.x - 0.25 * major, sigma, u_wrap, u_gaussianRange)
                  + cm_gaussian(u_tableGaussian, stats.x + 0.25 * major, sigma, u_wrap, u_gaussianRange));
#elif defined(MODE_GAUSSIAN_SIGMA)
    vec4 stats = pt_driverGaussian(s, dsdx, dsdy);
    o_colour = vec4(sqrt((stats.y * stats.y + stats.z * stats.z) / 12.0), sqrt(stats.w), 0.0, 1.0);
    return;
#else
    vec4 fg = pt_driverGrad(s);
    float gx = dot(fg.xyz, dsdx);
    float gy = dot(fg.xyz, dsdy);
#if defined(MODE_HART_MIP)
    albedo = cm_mip(u_tableMip, fg.w, length(vec2(gx, gy)), u_wrap);
#elif defined(MODE_HART_SAT)
    albedo = cm_sat(u_tableSat, fg.w, length(vec2(gx, gy)), u_wrap);
#elif defined(MODE_HART_MIP_ANISO)
    albedo = cm_mip2(u_tableMip, fg.w, gx, gy, u_wrap);
#elif defined(MODE_HART_SAT_ANISO)
    albedo = cm_sat2(u_tableSat, fg.w, gx, gy, u_wrap);
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
