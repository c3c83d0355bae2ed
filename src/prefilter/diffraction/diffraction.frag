// Diffraction from a nanostructure height field (diffraction/material.py): Stam 1999, Single 2013.
//   MODE_POINT        the accurate path at the pixel centre: Taylor/FFT transform, spectral loop over
//                     380-780 nm (each pass of the reference)
//   MODE_FAST         the wavelength-preintegrated table: one trilinear lookup (diffraction/fast_table.py)
//   MODE_DHILLON      Dhillon et al. 2014's 2N + 1 tables of cross terms, by powers of w (diffraction/dhillon.py)
//   MODE_NAIVE        Stam's analytic grating shader (GPU Gems style) with the structure's period
//   MODE_BLINN_PHONG  diagnostic: a Blinn-Phong highlight on the same mesh (the timing yardstick)
// DF_CIRCULAR: grooves follow circles around df_centre in uv (a CD); otherwise they run at df_angle
// (radians) from the mesh's bitangent, i.e. the across-groove axis is the tangent rotated by df_angle.

#include "glsl/common/shading.glsl"
#include "diffraction/stam.glsl"

in vec3 v_normal;
in vec4 v_tangent;
in vec3 v_toEye;
in vec2 v_uv;

uniform float df_angle;  // @param -3.14159..3.14159 Groove angle: radians from the mesh's bitangent (the across-groove axis is the tangent rotated by it); straight grooves only (unused with DF_CIRCULAR); every mode follows
uniform vec2 df_centre;  // @param -0.5..1.5 Groove centre: uv centre of circular grooves (DF_CIRCULAR only); every mode follows
uniform float df_period;  // µm, for the analytic baseline
uniform float u_exposure;  // @param 0.01..1000 log Exposure: multiplies the diffracted radiance in every mode (not the 0.02 ambient floor)

out vec4 o_colour;

void main() {
    vec3 n = normalize(gl_FrontFacing ? v_normal : -v_normal);
    vec3 t = normalize(v_tangent.xyz - dot(v_tangent.xyz, n) * n);
    vec3 b = (gl_FrontFacing ? 1.0 : -1.0) * v_tangent.w * cross(n, t);
#ifdef DF_CIRCULAR
    vec2 radial = v_uv - df_centre;
    radial = length(radial) > 1e-6 ? normalize(radial) : vec2(1.0, 0.0);
    vec3 across = normalize(radial.x * t + radial.y * b);
#else
    vec3 across = cos(df_angle) * t + sin(df_angle) * b;
#endif
    vec3 along = cross(n, across);
    mat3 tangentFromWorld = transpose(mat3(across, along, n));
    vec3 wo = tangentFromWorld * normalize(v_toEye);
    vec3 colour = vec3(0.0);
    for (int i = 0; i < SH_LIGHTS; ++i) {
        if (i >= sh_lightCount) break;
        vec3 wi = tangentFromWorld * sh_lightDirection[i];
#if defined(MODE_POINT)
        colour += sh_lightColour[i] * df_reflectance(wi, wo);
#elif defined(MODE_FAST)
        colour += sh_lightColour[i] * df_fastReflectance(wi, wo);
#elif defined(MODE_DHILLON)
        colour += sh_lightColour[i] * df_dhillonReflectance(wi, wo);
#elif defined(MODE_NAIVE)
        colour += sh_lightColour[i] * df_analyticGrating(wi, wo, df_period);
#elif defined(MODE_BLINN_PHONG)
        vec3 h = normalize(wi + wo);
        colour += sh_lightColour[i] * pow(max(h.z, 0.0), 200.0) * float(wi.z > 0.0);
#else
#error "unknown MODE_ define"
#endif
    }
    o_colour = vec4(u_exposure * colour + sh_ambient * vec3(0.02), 1.0);
}
