// Shared shading: Lambertian directional lights + ambient applied to a filtered albedo, output
// premultiplied by alpha. Lighting is smooth at pixel scale, so filtering the albedo first is exact
// to first order; unlit objects (sky, fire, moonrise) output the texture colour itself.
// Uniforms: sh_lit (0/1), sh_ambient, sh_lightCount, sh_lightDirection[i] (world, towards the light),
// sh_lightColour[i] (linear RGB).

#define SH_MAX_LIGHTS 4
// SH_LIGHTS bounds every loop over the lights: the scene's count when the program is built for a scene
// (SH_LIGHT_COUNT, gl/render.py's program_defines), at least 1 so that arrays are legal, else SH_MAX_LIGHTS.
// llvmpipe runs the body of an unrolled loop for lights beyond the count, masked: three unused lights cost
// micro-heights-sphere's surface-filter 0.04x of a naive frame.
#ifdef SH_LIGHT_COUNT
#define SH_LIGHTS (SH_LIGHT_COUNT > 0 ? SH_LIGHT_COUNT : 1)
#else
#define SH_LIGHTS SH_MAX_LIGHTS
#endif

uniform int sh_lit;
uniform float sh_ambient;
uniform int sh_lightCount;
uniform vec3 sh_lightDirection[SH_MAX_LIGHTS];
uniform vec3 sh_lightColour[SH_MAX_LIGHTS];

// albedo: premultiplied RGBA; normal: world space (any length); frontFacing flips back faces.
vec4 sh_shade(vec4 albedo, vec3 normal, bool frontFacing) {
    if (sh_lit == 0) {
        return albedo;
    }
    vec3 n = normalize(frontFacing ? normal : -normal);
    vec3 irradiance = vec3(sh_ambient);
    for (int i = 0; i < SH_LIGHTS; ++i) {
        if (i >= sh_lightCount) break;
        irradiance += max(dot(n, sh_lightDirection[i]), 0.0) * sh_lightColour[i];
    }
    return vec4(albedo.rgb * irradiance, albedo.a);
}
