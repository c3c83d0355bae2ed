// Normal-mapped and multiple surfaces (normals/material.py): Fournier 1992 and the single-lobe baselines.
//   MODE_POINT      the base level: the bilinearly interpolated normal, its Phong lobe n0, the horizon
//                   slopes interpolated bilinearly and tested as a step (each pass of the reference)
//   MODE_NAIVE      the MIP-averaged normal (trilinear, 16x anisotropic) with lobe n0; horizon means
//   MODE_TOKSVIG    one lobe: direction of the averaged normal N̄, exponent n0 |N̄| / (|N̄| + n0 (1 − |N̄|))
//                   (Toksvig 2005); soft horizon from the MIP-averaged slope moments
//   MODE_LEAN       one anisotropic Gaussian lobe in slope space from MIP-averaged first and second slope
//                   moments plus the base lobe's 1/n0 (Olano & Baker 2010); soft horizon as TOKSVIG
//   MODE_MULTILOBE  Fournier: the peaks of 2 levels x 4 texels, amplitudes times interpolation weights,
//                   per-peak soft shadowing and masking (§2.4, §5)
//   MODE_PEAK_COUNT diagnostic: peaks shaded per pixel / (56 x footprint samples)
//   MODE_FLAT       diagnostic, "no texture" of Fournier's timing table: the geometric normal, lobe n0
// ND_CONSTANT: a multiple surface (§4): one texel of peaks everywhere, no map; point = multilobe = them;
// the baselines see the moments of their distribution.
// ND_SHADOWING: horizon visibility on (the map has heights).

#include "glsl/common/shading.glsl"
#include "normals/phong_peaks.glsl"
#include "normals/normal_pyramid.glsl"

in vec3 v_normal;
in vec4 v_tangent;
in vec3 v_toEye;
in vec2 v_uv;

uniform vec2 u_uvScale;
uniform vec3 u_albedo;
uniform float u_specular;  // k_s
uniform float u_exponent;  // n0, the base normals' Phong exponent

uniform sampler2D nd_meanNormal;     // MIP map of N (xyz)
uniform sampler2D nd_slopeMoments;   // MIP map of (m_x, m_y, m_x², m_y²), m = N.xy / N.z
uniform sampler2D nd_slopeCross;     // MIP map of m_x m_y
uniform sampler2D nd_horizonMean;    // MIP map of the horizon slopes (+X, -X, +Y, -Y)
uniform sampler2D nd_horizonSquare;  // ... and of their squares

out vec4 o_colour;

// Per-fragment lighting in the tangent frame, shared by every peak. ND_LIGHTS lights (the scene's count,
// SH_LIGHT_COUNT, at least 1 so that arrays are legal), unrolled at compile time.
#if defined(SH_LIGHT_COUNT) && SH_LIGHT_COUNT > 0
#define ND_LIGHTS SH_LIGHT_COUNT
#else
#define ND_LIGHTS 1
#endif
vec3 g_light[ND_LIGHTS];
vec3 g_half[ND_LIGHTS];
vec3 g_view;

// The shading is linear in the peaks (phong_peaks.glsl), so they are summed into scalars per light and
// turned into a colour once: Σ a M (ambient), Σ a M V max(d·l, 0) and Σ a M V lobe(d·h) per light.
float g_ambient;
float g_diffuse[ND_LIGHTS];
float g_specular[ND_LIGHTS];
float g_peaks;

void nd_clear() {
    g_ambient = 0.0;
    g_peaks = 0.0;
    for (int i = 0; i < ND_LIGHTS; ++i) {
        g_diffuse[i] = 0.0;
        g_specular[i] = 0.0;
    }
}

void nd_addPeak(vec3 d, float a, float n, vec4 mean, vec4 deviation) {
    g_peaks += 1.0;
#ifdef ND_SHADOWING
    a *= nd_visibility(g_view, mean, deviation);
#endif
    g_ambient += a;
    for (int i = 0; i < ND_LIGHTS; ++i) {
#ifdef ND_SHADOWING
        float visible = a * nd_visibility(g_light[i], mean, deviation);
#else
        float visible = a;
#endif
        g_diffuse[i] += visible * max(dot(d, g_light[i]), 0.0);
        g_specular[i] += visible * nd_lobe(dot(d, g_half[i]), n);
    }
}

vec3 nd_colour() {
    float masked = g_view.z > 0.0 ? 1.0 : 0.0;  // the macro surface seen from below
    vec3 colour = u_albedo * sh_ambient * g_ambient;
    for (int i = 0; i < ND_LIGHTS; ++i) {
        if (i >= sh_lightCount) break;
        float lit = g_light[i].z > 0.0 ? 1.0 : 0.0;
        colour += lit * sh_lightColour[i] *
                  (u_albedo * g_diffuse[i] + vec3(u_specular * g_specular[i] *
                                                  nd_specularGeometry(g_light[i], g_view)));
    }
    return masked * colour;
}

// All the peaks of one texel, amplitudes times `weight`.
void nd_addTexel(int level, ivec2 texel, float weight) {
    ivec3 at = nd_atlasTexel(level, texel, 0);
    for (int k = 0; k < 16; ++k) {
        if (k >= nd_maxPeaks) break;
        vec4 p = texelFetch(nd_peaks, at + ivec3(0, 0, k), 0);
        if (p.z <= 0.0) break;
        vec4 mean = vec4(0.0), deviation = vec4(0.0);
#ifdef ND_SHADOWING
        mean = texelFetch(nd_peaks, at + ivec3(0, 0, nd_maxPeaks + k), 0);
        deviation = texelFetch(nd_peaks, at + ivec3(0, 0, 2 * nd_maxPeaks + k), 0);
#endif
        nd_addPeak(nd_direction(p), weight * p.z, p.w, mean, deviation);
    }
}

// The unfiltered base level: bilinear normal and horizon of the 4 nearest texels.
void nd_addPoint(vec2 uv, float weight) {
    ivec2 t0;
    vec2 f;
    nd_bilinear(uv, 0, t0, f);
    vec3 normal = vec3(0.0);
    vec4 mean = vec4(0.0);
    for (int c = 0; c < 4; ++c) {
        ivec2 texel = t0 + ivec2(c % 2, c / 2);
        float w = nd_bilinearWeight(f, c);
        normal += w * nd_direction(nd_fetch(0, texel, 0));
#ifdef ND_SHADOWING
        mean += w * nd_fetch(0, texel, nd_maxPeaks);
#endif
    }
    nd_addPeak(normalize(normal), weight, u_exponent, mean, vec4(0.0));
}

void nd_addLevel(vec2 uv, int level, float weight) {
    ivec2 t0;
    vec2 f;
    nd_bilinear(uv, level, t0, f);
    for (int c = 0; c < 4; ++c) {
        nd_addTexel(level, t0 + ivec2(c % 2, c / 2), weight * nd_bilinearWeight(f, c));
    }
}

// Soft horizon statistics from the MIP maps (single-lobe baselines).
void nd_horizonMoments(vec2 uv, out vec4 mean, out vec4 deviation) {
    mean = texture(nd_horizonMean, uv);
    deviation = sqrt(max(texture(nd_horizonSquare, uv) - mean * mean, vec4(0.0)));
}

// One anisotropic Gaussian lobe over slopes m = N.xy / N.z (LEAN mapping): density over solid angle at h.
float nd_leanLobe(vec3 h, vec2 meanSlope, mat2 covariance) {
    if (h.z <= 0.0) return 0.0;
    vec2 e = h.xy / h.z - meanSlope;
    float det = max(determinant(covariance), 1e-12);
    mat2 inverseCov = mat2(covariance[1][1], -covariance[0][1], -covariance[1][0], covariance[0][0]) / det;
    float p = exp(-0.5 * dot(e, inverseCov * e)) / (2.0 * ND_PI * sqrt(det));
    return p / (h.z * h.z * h.z);
}

void main() {
    vec3 n = normalize(gl_FrontFacing ? v_normal : -v_normal);
    vec3 t = normalize(v_tangent.xyz - dot(v_tangent.xyz, n) * n);
    vec3 b = (gl_FrontFacing ? 1.0 : -1.0) * v_tangent.w * cross(n, t);
    mat3 tangentFromWorld = transpose(mat3(t, b, n));
    g_view = tangentFromWorld * normalize(v_toEye);
    for (int i = 0; i < ND_LIGHTS; ++i) {
        g_light[i] = tangentFromWorld * sh_lightDirection[i];
        g_half[i] = normalize(g_light[i] + g_view);
    }
    nd_clear();
    vec2 uv = v_uv * u_uvScale;
    vec3 colour;
#if defined(MODE_FLAT)
    nd_addPeak(vec3(0.0, 0.0, 1.0), 1.0, u_exponent, vec4(0.0), vec4(0.0));
    colour = nd_colour();
#elif defined(ND_CONSTANT) && (defined(MODE_POINT) || defined(MODE_MULTILOBE) || defined(MODE_PEAK_COUNT))
    nd_addTexel(0, ivec2(0), 1.0);  // a multiple surface is its peaks
    colour = nd_colour();
#elif defined(MODE_POINT)
    nd_addPoint(uv, 1.0);
    colour = nd_colour();
#elif defined(MODE_MULTILOBE) || defined(MODE_PEAK_COUNT)
    // magnified (footprint under a texel): the base level itself, blended into level 0 up to lod 0
    NdFootprint footprint = nd_footprint(dFdx(uv), dFdy(uv));
    if (footprint.magnification > 0.0) nd_addPoint(uv, footprint.magnification);
    int level0;
    vec2 weights;
    nd_levelWeights(footprint.lod, level0, weights);
    weights *= (1.0 - footprint.magnification) / float(footprint.count);
    // a level whose texels are all alike (a tiling map's period within one texel) is shaded once
    bool alike0 = nd_levelAlike[level0] > 0.5;
    bool alike1 = weights.y > 0.0 && nd_levelAlike[min(level0 + 1, ND_MAX_LEVELS - 1)] > 0.5;
    for (int s = 0; s < ND_ANISOTROPY; ++s) {
        if (s >= footprint.count || footprint.magnification >= 1.0) break;
        vec2 at = uv + footprint.start + float(s) * footprint.step;
        if (!alike0) nd_addLevel(at, level0, weights.x);
        if (weights.y > 0.0 && !alike1) nd_addLevel(at, level0 + 1, weights.y);
    }
    if (footprint.magnification < 1.0) {
        float samples = float(footprint.count);
        if (alike0) nd_addTexel(level0, ivec2(0), samples * weights.x);
        if (alike1) nd_addTexel(level0 + 1, ivec2(0), samples * weights.y);
    }
    colour = nd_colour();
#elif defined(MODE_NAIVE)
    vec4 mean = vec4(0.0), deviation = vec4(0.0);
#ifdef ND_SHADOWING
    mean = texture(nd_horizonMean, uv);
#endif
    nd_addPeak(normalize(texture(nd_meanNormal, uv).xyz), 1.0, u_exponent, mean, deviation);
    colour = nd_colour();
#elif defined(MODE_TOKSVIG)
    vec4 mean = vec4(0.0), deviation = vec4(0.0);
#ifdef ND_SHADOWING
    nd_horizonMoments(uv, mean, deviation);
#endif
    vec3 average = texture(nd_meanNormal, uv).xyz;
    float len = clamp(length(average), 1e-4, 1.0);
    float exponent = u_exponent * len / (len + u_exponent * (1.0 - len));
    nd_addPeak(average / len, 1.0, exponent, mean, deviation);
    colour = nd_colour();
#elif defined(MODE_LEAN)
    vec4 mean = vec4(0.0), deviation = vec4(0.0);
#ifdef ND_SHADOWING
    nd_horizonMoments(uv, mean, deviation);
#endif
    vec4 moments = texture(nd_slopeMoments, uv);
    float crossMoment = texture(nd_slopeCross, uv).x;
    vec2 m = moments.xy;
    float base = 1.0 / u_exponent;
    mat2 covariance = mat2(moments.z - m.x * m.x + base, crossMoment - m.x * m.y,
                           crossMoment - m.x * m.y, moments.w - m.y * m.y + base);
    // the Lambertian part at the mean normal, the specular part from the Gaussian of slopes
    nd_addPeak(normalize(vec3(m, 1.0)), 1.0, 0.0, mean, deviation);
    for (int i = 0; i < ND_LIGHTS; ++i) {
        float visible = 1.0;
#ifdef ND_SHADOWING
        visible = nd_visibility(g_view, mean, deviation) * nd_visibility(g_light[i], mean, deviation);
#endif
        g_specular[i] = visible * nd_leanLobe(g_half[i], m, covariance);
    }
    colour = nd_colour();
#else
#error "unknown MODE_ define"
#endif
#ifdef MODE_PEAK_COUNT
    colour = vec3(g_peaks / (56.0 * float(ND_ANISOTROPY)));
#endif
    o_colour = vec4(colour, 1.0);
}
