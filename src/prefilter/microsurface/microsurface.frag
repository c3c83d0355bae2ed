// Fragment stage of microsurface materials (microsurface/material.py): colours tied to the heights and
// slopes of a procedural microsurface, Heitz et al. 2014 §5–§7. The rasterised mesh is the macro surface;
// each fragment ray-marches the displaced height field (heightfield.glsl) from the eye.
//   MODE_POINT           every octave is real geometry; colour C(h + r), C_s(s), C₀(r) at the visible
//                        point, Lambert at the micro-normal, a shadow ray to each light (each reference pass)
//   MODE_NAIVE           the coarse surface h_c only (octaves resolved by the footprint), its colour and
//                        normal: today's renderers (mip-mapped displacement and normals, C(E h))
//   MODE_TEXTURE_FILTER  the coarse surface, colours filtered view-independently against the unresolved
//                        statistics (p_h, p_s: §4's filter applied to heights and slopes, no visibility)
//   MODE_MARCH_STEPS     diagnostic: march steps of the point mode's primary and shadow rays / 256 (red)
//   MODE_SURFACE_FILTER  Heitz et al.: Λ_o, Λ_i (eq. 2 ff.; of the fractal's effective slopes, beyond the
//                        paper: microsurface/fractal_masking.py), V̄ (eq. 12), D_h (eqs. 13–17, exact table),
//                        the visible-slope distribution D_s (§5.2), Lambert averaged over D_s, combinations (§6)
// Lighting: directional lights sh_lightDirection/Colour (world) with shadows, plus unshadowed ambient;
// or, with MS_IRRADIANCE, an environment's irradiance in 9 SH coefficients (§5.3) and nothing else.
// Colour maps (defines MS_HEIGHT_MAP, MS_SLOPE_MAP, MS_TEXTURE_MAP): argument = scale·x + offset with
// x = h + ρ r (height), s·d (slope along the tangent direction d), r (texture); combined as
// κ₀C₀ + κ₁C_h + κ₂C_s, or with u_slopeOver = 1 as the premultiplied slope layer over κ₀C₀ + κ₁C_h.

#include "microsurface/heightfield.glsl"
#include "microsurface/smith.glsl"
#include "microsurface/height_filtering.glsl"
#include "microsurface/visible_slopes.glsl"
#include "colormap/colormap.glsl"
#include "glsl/common/shading.glsl"
#ifdef MS_IRRADIANCE
#include "microsurface/irradiance.glsl"
uniform vec3 u_sh[9];
// Environment maps are z-up (irradiance.py), scenes y-up: env (x, y, z) = world (x, -z, y).
const mat3 MS_ENV_FROM_WORLD = mat3(vec3(1.0, 0.0, 0.0), vec3(0.0, 0.0, 1.0), vec3(0.0, -1.0, 0.0));
#endif

#ifndef MS_MAX_STEPS
#if defined(MODE_POINT) || defined(MODE_MARCH_STEPS)
#define MS_MAX_STEPS 768  // the full geometry at grazing angles needs long marches
#else
#define MS_MAX_STEPS 192
#endif
#endif
#define MS_PI 3.14159265

in vec3 v_solid;  // object-space position on the macro surface

uniform vec4 u_eyeObject;  // (eye, 1) for perspective cameras, (direction of view, 0) for orthographic
uniform mat4 u_objectFromWorld;
uniform mat3 u_worldNormalFromObject;

uniform sampler2D u_heightPoint;  // @table the height colour table C_h for the point and naive modes: u: f = u_heightMap.x (h + u_perturb r) + u_heightMap.y (h the micro height in object units, r the texture fractal) in table periods, n = width entries, entry i covering [i/n, (i+1)/n); read with texelFetch at floor(n fract(f)) for u_heightWrap = 0 (modulo) or min(floor(n clamp(f, 0, 1)), n - 1) for u_heightWrap = 1 (clamp); one row, NEAREST, no MIP; RGBA: the colour table in linear RGB premultiplied by alpha, and alpha
uniform sampler2D u_heightGaussian;  // @table the preconvolved height colour map C̄_h(μ, σ) for the filtered modes with u_heightRange = (mu_lo, mu_hi, sigma_max); u: μ = u_heightMap.x E[h + u_perturb r] + u_heightMap.y (h the micro height in object units, r the texture fractal), in table periods: u = fract(μ) for u_heightWrap = 0 (modulo: one period, REPEAT, u_heightRange.xy = (0, 1)) or (μ - mu_lo)/(mu_hi - mu_lo) for u_heightWrap = 1 (clamp: CLAMP_TO_EDGE, the edge columns beyond), texel i at μ = mu_lo + (i + 0.5)(mu_hi - mu_lo)/width; v: σ = |u_heightMap.x| x the standard deviation of h + u_perturb r, row j at σ = sigma_max j/(height - 1) (read at v = (σ/sigma_max (height - 1) + 0.5)/height; σ > sigma_max reads the last row; row 0 is the table itself); RGBA: the colour table convolved with N(0, σ²) at μ, in linear RGB premultiplied by alpha, and alpha; LINEAR, no MIP
uniform vec3 u_heightRange;
uniform int u_heightWrap;
uniform vec2 u_heightMap;  // @param -100..100 Height map: (scale, offset), the height colour table's argument f = scale (h + ρ r) + offset with h in object units; every mode follows; for clamp tables the filtered modes are exact while f stays within u_heightRange.xy and |scale| times the deviation stays below u_heightRange.z (the preconvolved bake's range)
uniform float u_perturb;   // @param -1..1 Perturbation: ρ in C(h + ρ r), the texture fractal r added to the height colour's argument (needs a height colour map and a texture fractal); every mode follows
uniform sampler2D u_slopePoint;  // @table the slope colour table C_s for the point and naive modes: u: f = u_slopeMap.x (s·d) + u_slopeMap.y (s the micro slope in the macro tangent frame, d = u_slopeDirection) in table periods, n = width entries, entry i covering [i/n, (i+1)/n); read with texelFetch at floor(n fract(f)) for u_slopeWrap = 0 (modulo) or min(floor(n clamp(f, 0, 1)), n - 1) for u_slopeWrap = 1 (clamp); one row, NEAREST, no MIP; RGBA: the colour table in linear RGB premultiplied by alpha, and alpha
uniform sampler2D u_slopeGaussian;  // @table the preconvolved slope colour map C̄_s(μ, σ) for the filtered modes with u_slopeRange = (mu_lo, mu_hi, sigma_max); u: μ = u_slopeMap.x E[s·d] + u_slopeMap.y (s the micro slope, visible slopes in surface-filter, d = u_slopeDirection), in table periods: u = fract(μ) for u_slopeWrap = 0 (modulo: one period, REPEAT, u_slopeRange.xy = (0, 1)) or (μ - mu_lo)/(mu_hi - mu_lo) for u_slopeWrap = 1 (clamp: CLAMP_TO_EDGE, the edge columns beyond), texel i at μ = mu_lo + (i + 0.5)(mu_hi - mu_lo)/width; v: σ = |u_slopeMap.x| x the standard deviation of s·d, row j at σ = sigma_max j/(height - 1) (read at v = (σ/sigma_max (height - 1) + 0.5)/height; σ > sigma_max reads the last row; row 0 is the table itself); RGBA: the colour table convolved with N(0, σ²) at μ, in linear RGB premultiplied by alpha, and alpha; LINEAR, no MIP
uniform vec3 u_slopeRange;
uniform int u_slopeWrap;
uniform vec2 u_slopeMap;  // @param -4..4 Slope map: (scale, offset), the slope colour table's argument f = scale (s·d) + offset, d = u_slopeDirection; every mode follows; for clamp tables the filtered modes are exact while f stays within u_slopeRange.xy and |scale| times the deviation stays below u_slopeRange.z (the preconvolved bake's range)
uniform vec2 u_slopeDirection;  // @param -1..1 Slope direction: d in the macro tangent frame (x the tangent, y the bitangent) of the slope colour C_s(s·d); unit in the presets (a longer d scales the argument); every mode follows
uniform sampler2D u_texturePoint;  // @table the texture colour table C_0 for the point and naive modes: u: f = u_textureMap.x r + u_textureMap.y (r the texture fractal) in table periods, n = width entries, entry i covering [i/n, (i+1)/n); read with texelFetch at floor(n fract(f)) for u_textureWrap = 0 (modulo) or min(floor(n clamp(f, 0, 1)), n - 1) for u_textureWrap = 1 (clamp); one row, NEAREST, no MIP; RGBA: the colour table in linear RGB premultiplied by alpha, and alpha
uniform sampler2D u_textureGaussian;  // @table the preconvolved texture colour map C̄_0(μ, σ) for the filtered modes with u_textureRange = (mu_lo, mu_hi, sigma_max); u: μ = u_textureMap.x E[r] + u_textureMap.y (r the texture fractal), in table periods: u = fract(μ) for u_textureWrap = 0 (modulo: one period, REPEAT, u_textureRange.xy = (0, 1)) or (μ - mu_lo)/(mu_hi - mu_lo) for u_textureWrap = 1 (clamp: CLAMP_TO_EDGE, the edge columns beyond), texel i at μ = mu_lo + (i + 0.5)(mu_hi - mu_lo)/width; v: σ = |u_textureMap.x| x the standard deviation of the unresolved octaves of r, row j at σ = sigma_max j/(height - 1) (read at v = (σ/sigma_max (height - 1) + 0.5)/height; σ > sigma_max reads the last row; row 0 is the table itself); RGBA: the colour table convolved with N(0, σ²) at μ, in linear RGB premultiplied by alpha, and alpha; LINEAR, no MIP
uniform vec3 u_textureRange;
uniform int u_textureWrap;
uniform vec2 u_textureMap;  // @param -4..4 Texture map: (scale, offset), the texture colour table's argument f = scale r + offset, r the texture fractal; every mode follows; for clamp tables the filtered modes are exact while f stays within u_textureRange.xy and |scale| times the deviation stays below u_textureRange.z (the preconvolved bake's range)
uniform vec3 u_kappa;  // @param 0..2 Weights: (κ₀, κ₁, κ₂) of the texture, height and slope colours in κ₀C₀ + κ₁C_h + κ₂C_s (κ₂ unused when the slope layer is over the rest); every mode follows
uniform int u_slopeOver;
uniform sampler2D u_heightFilteringTable;  // @table the moments of D_h (Heitz et al. 2014 eqs. 14-17): one row of n = width texels, texel i at t = i/(n - 1) with t = log(1 + L)/log(1 + 10000) (MS_HF_LMAX), L = Λ_o + Λ_i (Smith), read LINEAR at u = (t (n - 1) + 0.5)/n (CLAMP_TO_EDGE: L > 10000 reads the last texel); RG: (μ_d/σ_h, σ_d/σ_h), the mean and standard deviation of the heights that are seen and lit, in units of the height deviation σ_h; no MIP; not colours

out vec4 o_colour;

vec4 ms_combine(vec4 c0, vec4 ch, vec4 cs) {
    vec4 base = u_kappa.x * c0 + u_kappa.y * ch;
    return u_slopeOver == 1 ? cs + (1.0 - cs.a) * base : base + u_kappa.z * cs;
}

vec4 ms_mapPoint(sampler2D table, vec2 map, float x, int wrap) { return cm_point(table, map.x * x + map.y, wrap); }

vec4 ms_mapGaussian(sampler2D table, vec2 map, float mean, float variance, int wrap, vec3 range) {
    return cm_gaussian(table, map.x * mean + map.y, abs(map.x) * sqrt(max(variance, 0.0)), wrap, range);
}

vec2 ms_heightFilteringMoments(float lambdaSum) {
#ifdef MS_HEIGHT_FIT
    return ms_heightFilteringFit(lambdaSum);
#else
    return ms_heightFiltering(u_heightFilteringTable, lambdaSum);
#endif
}

// (shift, variance) of the micro heights at the rendered coarse point for L = Λ_o + Λ_i of the whole
// surface (lt) and of the coarse surface (lc), σ_t and σ_c their height deviations.
vec2 ms_microHeights(float lt, float lc, float sigmaT, float sigmaC) {
    vec2 t = ms_heightFilteringMoments(lt);
    vec2 c = ms_heightFilteringMoments(lc);
    return vec2(t.x * sigmaT - c.x * sigmaC, max(t.y * t.y * sigmaT * sigmaT - c.y * c.y * sigmaC * sigmaC, 0.0));
}

void main() {
    vec3 p0 = v_solid;
    vec3 dpdx = dFdx(p0);
    vec3 dpdy = dFdy(p0);
    vec3 d = u_eyeObject.w > 0.5 ? normalize(p0 - u_eyeObject.xyz) : normalize(u_eyeObject.xyz);
#if defined(MODE_POINT) || defined(MODE_MARCH_STEPS)
    ms_setWeights(dpdx, dpdy, true);
#else
    ms_reliefFootprint(p0, d, dpdx, dpdy);
    ms_setWeights(dpdx, dpdy, false);
#endif
    vec3 o = u_eyeObject.w > 0.5 ? u_eyeObject.xyz : p0 - d * (4.0 * (ms_radius + ms_heightBound) + 1.0);
    vec3 slab = ms_slab(o, d, ms_heightBound);
    if (slab.y < slab.x) discard;
    float t = ms_march(o, d, slab, MS_MAX_STEPS, true);
    if (t < 0.0) discard;
    vec3 q = o + t * d;
    vec3 p = ms_project(q);
    mat3 frame = ms_macroFrame(q);  // columns: tangent, bitangent, normal (object space)

    // Height and slope of the rendered surface (all octaves, or the coarse ones).
    vec4 fg = ms_fractalGrad(p, 0, ms_heightOctaves);
    float h = fg.w;
    vec2 slope = vec2(dot(fg.xyz, frame[0]), dot(fg.xyz, frame[1]));
    float heightVariance = ms_heightVariance;
    vec3 slopeCov = vec3(ms_slopeVariance, 0.0, ms_slopeVariance);
#ifdef MS_TRANSFER
    vec4 transferMoments = ms_transfer(fg.w, ms_transferSigma);  // one lookup, also used by surface-filter
    {
        float hMean;
        vec2 slopeMean;
        ms_transferStats(transferMoments, slope, slopeCov, hMean, heightVariance, slopeMean, slopeCov);
        h = hMean;
        slope = slopeMean;
    }
#endif
    float r = ms_fractal(p, MS_MAX_OCTAVES, ms_textureOctaves);
    vec3 normal = normalize(frame * vec3(-slope, 1.0));  // object space
    vec3 worldNormal = normalize(u_worldNormalFromObject * normal);
    vec3 wo = -d * frame;  // view direction in the macro tangent frame
#ifdef MS_IRRADIANCE
    mat3 worldFrame = mat3(normalize(u_worldNormalFromObject * frame[0]), normalize(u_worldNormalFromObject * frame[1]),
                           normalize(u_worldNormalFromObject * frame[2]));
#endif
    vec2 dir = u_slopeDirection;

    vec4 c0 = vec4(0.0), ch = vec4(0.0), cs = vec4(0.0);
#if defined(MODE_POINT) || defined(MODE_NAIVE) || defined(MODE_MARCH_STEPS)
#ifdef MS_TEXTURE_MAP
    c0 = ms_mapPoint(u_texturePoint, u_textureMap, r, u_textureWrap);
#endif
#ifdef MS_HEIGHT_MAP
    ch = ms_mapPoint(u_heightPoint, u_heightMap, h + u_perturb * r, u_heightWrap);
#endif
#ifdef MS_SLOPE_MAP
    cs = ms_mapPoint(u_slopePoint, u_slopeMap, dot(slope, dir), u_slopeWrap);
#endif
    vec4 albedo = ms_combine(c0, ch, cs);
#ifdef MS_IRRADIANCE
    vec3 radiance = albedo.rgb * ms_irradianceSH(u_sh, MS_ENV_FROM_WORLD * worldNormal) / MS_PI;
#else
    vec3 radiance = albedo.rgb * sh_ambient;
    for (int j = 0; j < SH_MAX_LIGHTS; ++j) {
        if (j >= sh_lightCount) break;
        vec3 l = normalize(mat3(u_objectFromWorld) * sh_lightDirection[j]);
        float cosine = max(dot(normal, l), 0.0);
        if (cosine > 0.0) cosine *= ms_shadow(q, l, MS_MAX_STEPS);
        radiance += albedo.rgb * cosine * sh_lightColour[j];
    }
#endif

#else  // filtered modes
    float textureVariance = ms_textureVariance;
    float sigmaH = sqrt(max(heightVariance, 0.0));
#if defined(MODE_TEXTURE_FILTER)
    // view-independent: p_h = N(h_c, σ_h²), p_s = N(s_c, Σ)
#ifdef MS_TEXTURE_MAP
    c0 = ms_mapGaussian(u_textureGaussian, u_textureMap, r, textureVariance, u_textureWrap, u_textureRange);
#endif
#ifdef MS_HEIGHT_MAP
    ch = ms_mapGaussian(u_heightGaussian, u_heightMap, h + u_perturb * r,
                        heightVariance + u_perturb * u_perturb * textureVariance, u_heightWrap, u_heightRange);
#endif
#ifdef MS_SLOPE_MAP
    float slopeVarDir = dir.x * dir.x * slopeCov.x + 2.0 * dir.x * dir.y * slopeCov.y + dir.y * dir.y * slopeCov.z;
    cs = ms_mapGaussian(u_slopeGaussian, u_slopeMap, dot(slope, dir), slopeVarDir, u_slopeWrap, u_slopeRange);
#endif
    vec4 albedo = ms_combine(c0, ch, cs);
#ifdef MS_IRRADIANCE
    vec3 radiance = albedo.rgb * ms_filteredIrradianceSH(u_sh, MS_ENV_FROM_WORLD * worldFrame, slope, slopeCov) / MS_PI;
#else
    vec3 radiance = albedo.rgb * sh_ambient;
    for (int j = 0; j < SH_MAX_LIGHTS; ++j) {
        if (j >= sh_lightCount) break;
        vec3 l = normalize(mat3(u_objectFromWorld) * sh_lightDirection[j]);
        float cosine = max(dot(normal, l), 0.0);
        if (cosine > 0.0) cosine *= ms_shadow(q, l, MS_MAX_STEPS);
        radiance += albedo.rgb * cosine * sh_lightColour[j];
    }
#endif

#elif defined(MODE_SURFACE_FILTER)
    // Heitz et al. 2014 §5–§6 with Smith's statistics of the whole surface (coarse + micro: Λ_t, σ_t) and of
    // the coarse part that is rendered (Λ_c, σ_c). The ray march already shows the coarse surface's own
    // masking and shadows; the micro part supplies the rest, matched in the mean over the footprint:
    //   D_h shift μ_d(L_t)σ_t − μ_d(L_c)σ_c, variance σ_d(L_t)²σ_t² − σ_d(L_c)²σ_c², V̄ = V̄_t / V̄_c.
    // (Smith's visibility depends on the total height and slopes: coarse valleys are hidden by micro bumps
    // on coarse hills. Using the micro statistics alone under-estimates the shift by up to σ_t/σ_m.)
    vec3 coarseCov = vec3(ms_coarseSlopeVariance, 0.0, ms_coarseSlopeVariance);
    float coarseVariance = ms_coarseHeightVariance;
#ifdef MS_TRANSFER
    coarseCov *= transferMoments.w;
    coarseVariance *= transferMoments.z * transferMoments.z;
#endif
    // Λ sees the fractal's effective slopes (fractal_masking.py): the same covariances scaled by the
    // ratio of the effective to the actual slope variance of the driver, whole and coarse.
    vec3 totalCov = (slopeCov + coarseCov) * ms_maskingSlopeVariance
                  / max(ms_slopeVariance + ms_coarseSlopeVariance, 1e-30);
    coarseCov *= ms_coarseMaskingSlopeVariance / max(ms_coarseSlopeVariance, 1e-30);
    float sigmaC = sqrt(coarseVariance);
    float sigmaT = sqrt(heightVariance + coarseVariance);
    float lambdaOT = ms_lambda(wo, totalCov);
    float lambdaOC = ms_lambda(wo, coarseCov);
    vec2 visMean;
    vec3 visCov;
    ms_visibleSlopes(wo, slope, slopeCov, visMean, visCov);
#ifdef MS_TEXTURE_MAP
    c0 = ms_mapGaussian(u_textureGaussian, u_textureMap, r, textureVariance, u_textureWrap, u_textureRange);
#endif
#ifdef MS_SLOPE_MAP
    float visVarDir = dir.x * dir.x * visCov.x + 2.0 * dir.x * dir.y * visCov.y + dir.y * dir.y * visCov.z;
    cs = ms_mapGaussian(u_slopeGaussian, u_slopeMap, dot(visMean, dir), visVarDir, u_slopeWrap, u_slopeRange);
#endif
    float perturbVariance = u_perturb * u_perturb * textureVariance;
    // The view alone (ambient, environment light): Λ_i = 0, V̄ = 1.
#ifdef MS_HEIGHT_MAP
    vec2 dh = ms_microHeights(lambdaOT, lambdaOC, sigmaT, sigmaC);
    ch = ms_mapGaussian(u_heightGaussian, u_heightMap, h + dh.x + u_perturb * r, dh.y + perturbVariance,
                        u_heightWrap, u_heightRange);
#endif
    vec4 albedoView = ms_combine(c0, ch, cs);
#ifdef MS_IRRADIANCE
    vec3 radiance = albedoView.rgb * ms_filteredIrradianceSH(u_sh, MS_ENV_FROM_WORLD * worldFrame, visMean, visCov) / MS_PI;
#else
    vec3 radiance = albedoView.rgb * sh_ambient;
    vec2 nodes[9];
    float weights[9];
    ms_slopeNodes3(visMean, visCov, nodes, weights);
    for (int j = 0; j < SH_MAX_LIGHTS; ++j) {
        if (j >= sh_lightCount) break;
        vec3 l = normalize(mat3(u_objectFromWorld) * sh_lightDirection[j]);
        vec3 wi = l * frame;
        float cosine = 0.0;  // Lambert averaged over the visible slopes D_s
        for (int k = 0; k < 9; ++k) {
            cosine += weights[k] * max(dot(normalize(vec3(-nodes[k], 1.0)), wi), 0.0);
        }
        if (cosine <= 0.0) continue;
        cosine *= ms_shadow(q, l, MS_MAX_STEPS);  // shadows of the coarse surface, binary
        float lambdaIT = ms_lambda(wi, totalCov);
        float lambdaIC = ms_lambda(wi, coarseCov);
        float visibility = ms_averageVisibility(lambdaOT, lambdaIT) / ms_averageVisibility(lambdaOC, lambdaIC);
#ifdef MS_HEIGHT_MAP
        vec2 dhl = ms_microHeights(lambdaOT + lambdaIT, lambdaOC + lambdaIC, sigmaT, sigmaC);
        ch = ms_mapGaussian(u_heightGaussian, u_heightMap, h + dhl.x + u_perturb * r, dhl.y + perturbVariance,
                            u_heightWrap, u_heightRange);
#endif
        vec4 albedo = visibility * ms_combine(c0, ch, cs);
        radiance += albedo.rgb * cosine * sh_lightColour[j];
    }
#endif
#else
#error "unknown MODE_ define"
#endif
#endif
#ifdef MODE_MARCH_STEPS
    radiance = vec3(float(ms_steps) / 256.0, 0.0, 0.0);  // steps of the primary and shadow rays, /256
#endif
    o_colour = vec4(radiance, 1.0);
}
