// Colour map over a tabulated driver image (colormap/tabulated.py): Heitz et al. §4.2.
//   MODE_POINT     c(f) with f reconstructed bilinearly at level 0 (each pass of the reference)
//   MODE_NAIVE     c(E[f]) with E[f] from the trilinear, anisotropic MIP map (today's renderers)
//   MODE_GAUSSIAN  C̄(E[f], sqrt(E[f²] − E[f]²)) from the MIP map of (f, f²) and the preconvolved map
// u_driver: RG32F (f, f²) with exact block-mean levels, LINEAR_MIPMAP_LINEAR, 16x anisotropy.

#include "colormap/colormap.glsl"
#include "glsl/common/shading.glsl"

in vec3 v_normal;
in vec2 v_uv;

uniform sampler2D u_driver;
uniform sampler2D u_tablePoint;
uniform sampler2D u_tableGaussian;
uniform vec3 u_gaussianRange;
uniform vec2 u_uvScale;
uniform int u_wrap;

out vec4 o_colour;

void main() {
    vec2 uv = v_uv * u_uvScale;
    vec4 albedo;
#if defined(MODE_POINT)
    albedo = cm_point(u_tablePoint, textureLod(u_driver, uv, 0.0).x, u_wrap);
#elif defined(MODE_NAIVE)
    albedo = cm_point(u_tablePoint, texture(u_driver, uv).x, u_wrap);
#elif defined(MODE_GAUSSIAN)
    vec2 moments = texture(u_driver, uv).xy;
    float sigma = sqrt(max(moments.y - moments.x * moments.x, 0.0));
    albedo = cm_gaussian(u_tableGaussian, moments.x, sigma, u_wrap, u_gaussianRange);
#else
#error "unknown MODE_ define"
#endif
    o_colour = sh_shade(albedo, v_normal, gl_FrontFacing);
}
