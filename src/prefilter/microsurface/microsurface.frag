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
//                        the visible-slope distribution D_s (§5.2), Lambert averaged over D_s, combinations (§6);
//                        under a transfer function (§7) D_h and the colour over the driver, and the slopes as
//                        two nodes of g' (ms_driverNodes; beyond the paper, driver_colour.py)
// Lighting: directional lights sh_lightDirection/Colour (world) with shadows, plus unshadowed ambient;
// or, with MS_IRRADIANCE, an environment's irradiance in 9 SH coefficients (§5.3) and nothing else.
// Colour maps (defines MS_HEIGHT_MAP, MS_SLOPE_MAP, MS_TEXTURE_MAP; _CONSTANT for a one-colour map):
// argument = scale·x + offset with x = h + ρ r (height), s·d (slope along the tangent direction d), r
// (texture); combined as κ₀C₀ + κ₁C_h + κ₂C_s, or with u_slopeOver = 1 as the premultiplied slope layer over
// κ₀C₀ + κ₁C_h.

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

// Shading samples of surface-filter: an MS_GRID_X x MS_GRID_Y grid of sub-pixel points, its longer side along
// the longer screen axis of the footprint (shading_samples 6 = 3 x 2; 2 = 1 x 2, one sample on each of the
// column's two rows where the relief stands out of the pixel; 1, 4, 9, 16 are square), or with MS_TRIANGLE
// (shading_samples 3, MS_GRID_X 3) three points on a circle of MS_TRIANGLE_RADIUS pixels about the centre:
// MS_TRIANGLE_OFFSETS, one of them on the footprint's longer screen axis, the triangle turned by half a turn
// in every other pixel (a checkerboard) so that neighbouring pixels' samples interleave. The radius √2/4
// gives each screen axis the 2 x 2 grid's second moment (r²/2 = 1/16); each sample's sub-box has the side
// of the samples' spacing, √3 r (the grid's sub-box is its spacing too). Measured on micro-snake-sphere
// (256 px, 64-spp reference, FLIP and time ÷ naive, 5 round-robin rounds; 2 x 2: 0.0630 at 1.49-1.54, the
// 2-sample column 0.0743 at 1.34): 0.0675 at 1.37-1.41. Of the triangle's variants the checkerboard and a
// vertex on the longer axis were best on the snake (0.0690 without either) and within 0.0004 of the best on
// the height sphere and the irradiance terrain; a sub-box of 1/√3 (equal area) gave 0.0690, of 0.75 0.0676
// on the snake but 0.0577 against 0.0540 on the height sphere; radius 0.41 (the box's own second moment)
// 0.0723.
#ifdef MS_TRIANGLE
#define MS_TRIANGLE_RADIUS 0.35355339
const vec2 MS_TRIANGLE_OFFSETS[3] = vec2[3](vec2(1.0, 0.0), vec2(-0.5, -0.8660254), vec2(-0.5, 0.8660254));
#endif
#ifndef MS_GRID_X
#define MS_GRID_X 1
#endif
#ifndef MS_GRID_Y
#define MS_GRID_Y MS_GRID_X
#endif
#define MS_SHADING_SAMPLES (MS_GRID_X * MS_GRID_Y)
// Shadow rays near the terminator graze the relief over long paths; one that runs out of steps counts as
// unoccluded, so every mode gives them the point mode's budget.
#ifndef MS_SHADOW_STEPS
#define MS_SHADOW_STEPS 768
#endif
// Primary rays at grazing angles need long marches, in every mode: the filtered modes had 192 steps, and at
// the far end of micro-heights-grazing their rays ran out above the relief (surface-filter FLIP 0.050, naive
// 0.065 against 64-spp references; 0.040 and 0.051 with 384 or 768 steps, at the same frame time).
#ifndef MS_MAX_STEPS
#define MS_MAX_STEPS 768
#endif
// Shadow rays of the filtered modes take steps of at least this share of the pixel's radius at the shaded
// point (heightfield.glsl, ms_shadowStep); 0 in the point mode and the reference.
#ifndef MS_SHADOW_STEP
#define MS_SHADOW_STEP 0.5
#endif
#define MS_PI 3.14159265
// The reach of the shading samples' shadow profile in standard deviations of the coarse slope (ms_shade).
#define MS_REACH_DEVIATIONS 4.0
// How far surface-filter's shading samples close up where the coarse relief stands out of the pixel
// (ms_shade's gate = MS_RELIEF_CLOSING x ms_reliefGate): at gate 1 they keep 80 % of their offsets. They
// collapsed onto the centre until 2026-12-05 and kept 65 % until their weights below (later that day);
// docs/microsurface-history.md ("Shading samples") has the measurements.
#ifndef MS_RELIEF_CLOSING
#define MS_RELIEF_CLOSING 0.2
#endif
// The primary rays' least step in the modes other than point, a share of the pixel's footprint along the
// ray (main(); heightfield.glsl, ms_primaryStep), and the least rate of descent that sizes the footprint.
#ifndef MS_PRIMARY_STEP
#define MS_PRIMARY_STEP 0.125
#endif
#ifndef MS_PRIMARY_STEP_FLOOR
#define MS_PRIMARY_STEP_FLOOR 0.05
#endif
// How fast a shading sample's coarse slope decorrelates from the marched point's, in units of the coarse
// surface's RMS frequency ms_coarseFrequency times the sample's distance from it (ms_shade's weights).
#ifndef MS_SLOPE_DECORRELATION
#define MS_SLOPE_DECORRELATION 6.5
#endif
// A shading sample's split (ms_shade) leaves an octave wholly to the statistics where the sample's footprint
// would keep less than this weight of it, a quarter of its variance (heightfield.glsl, ms_setWeightsAbove):
// the samples' loops over the octaves then stop before it, and the statistics carry it as well as the
// samples did. Measured (fourteenth session; 256 px, 64-spp references, surface-filter FLIP with the floor
// 0 -> 0.5 -> 0.65 -> 0.8): micro-heights-sphere 0.0506 -> 0.0506 -> 0.0511 -> 0.0561, micro-snake-sphere
// 0.0651 -> 0.0632 -> 0.0630 -> 0.0646, micro-heights-terrain 0.0644 -> 0.0644 -> 0.0646 -> 0.0653,
// micro-irradiance-terrain 0.0314 -> 0.0312 -> 0.0311 -> 0.0312, the grazing terrain, slope terrain, moss
// and sponge within 0.0004 up to 0.5; time ÷ naive (7-9 round-robin rounds, floor 0 -> 0.5): height sphere
// 1.62-1.64 -> 1.51-1.54, snake 1.73-1.75 -> 1.65-1.68, irradiance terrain 1.53-1.56 -> 1.50-1.55.
// Not with a transfer function: there a sample's tufts are g of its driver, and the driver's octaves moved
// to the statistics made the moss's band below the macro horizon 4.3 -> 5.3 % too bright against the
// reference (test_tall_relief_on_a_sphere_takes_light_from_below_the_macro_horizon, 128 px).
#ifndef MS_SAMPLE_WEIGHT_FLOOR
#ifdef MS_TRANSFER
#define MS_SAMPLE_WEIGHT_FLOOR 0.0
#else
#define MS_SAMPLE_WEIGHT_FLOOR 0.5
#endif
#endif
// ... unless the octave is large: one whose kept variance w²a² is at least MS_SAMPLE_VARIANCE_FLOOR of the
// first octave's a₀² keeps its height with the samples, whatever its weight (its slopes still go to the
// statistics: heightfield.glsl). Far away the first octaves are the ones under the weight floor, and without
// them the samples of a pixel all saw the same statistics: the height sphere at 24 units came out smooth
// where the reference's pixel means vary with the few cells of the first octave that each pixel spans
// (luminance less its 5 x 5 mean, standard deviation where n·l > 0.4: reference 0.038, surface-filter
// 0.002 -> 0.028). Measured (2026-12-07; 256 px, 64-spp references, surface-filter FLIP, the weight floor
// alone -> with this): micro-heights-sphere at 24 units 0.0552 -> 0.0518, at 15.9 0.0527 -> 0.0502, at 10
// 0.0527 -> 0.0507, at 6 0.0510 -> 0.0502, at the preset's 4.24 0.0503 -> 0.0502, at 2.4 the same;
// micro-snake-sphere at 24 units 0.0589 -> 0.0585, at 10 0.0613 -> 0.0616, at its own distance the same;
// the terrains within 0.0001 (their fine octaves are small beside their first); time the same (round-robin,
// 7 rounds: height sphere 1.531 -> 1.529, snake 1.451 -> 1.455). With the rescued octaves' slopes kept too,
// a floor of 0.003 cost the height sphere 0.02 x naive's frame, and 0.03 raised its FLIP to 0.0508.
#ifndef MS_SAMPLE_VARIANCE_FLOOR
#define MS_SAMPLE_VARIANCE_FLOOR 0.01
#endif

in vec3 v_solid;  // object-space position on the macro surface

uniform vec4 u_eyeObject;  // (eye, 1) for perspective cameras, (direction of view, 0) for orthographic
uniform mat4 u_objectFromWorld;
uniform mat3 u_worldNormalFromObject;

uniform sampler2D u_heightPoint;  // @table the height colour table C_h for the point and naive modes: u: f = u_heightMap.x (h + u_perturb r) + u_heightMap.y (h the micro height in object units, r the texture fractal) in table periods, n = width entries, entry i covering [i/n, (i+1)/n); read with texelFetch at floor(n fract(f)) for u_heightWrap = 0 (modulo) or min(floor(n clamp(f, 0, 1)), n - 1) for u_heightWrap = 1 (clamp); one row, NEAREST, no MIP; RGBA: the colour table in linear RGB premultiplied by alpha, and alpha
uniform sampler2D u_heightGaussian;  // @table the preconvolved height colour map C̄_h(μ, σ) for the filtered modes with u_heightRange = (mu_lo, mu_hi, sigma_max); u: μ = u_heightMap.x E[h + u_perturb r] + u_heightMap.y (h the micro height in object units, r the texture fractal), in table periods: u = fract(μ) for u_heightWrap = 0 (modulo: one period, REPEAT, u_heightRange.xy = (0, 1)) or (μ - mu_lo)/(mu_hi - mu_lo) for u_heightWrap = 1 (clamp: CLAMP_TO_EDGE, the edge columns beyond), texel i at μ = mu_lo + (i + 0.5)(mu_hi - mu_lo)/width; v: σ = |u_heightMap.x| x the standard deviation of h + u_perturb r, row j at σ = sigma_max j/(height - 1) (read at v = (σ/sigma_max (height - 1) + 0.5)/height; σ > sigma_max reads the last row; row 0 is the table itself); RGBA: the colour table convolved with N(0, σ²) at μ, in linear RGB premultiplied by alpha, and alpha; LINEAR, no MIP
uniform vec3 u_heightRange;
uniform sampler2D u_heightGaussianBox;  // @table u_heightGaussian's rows integrated over μ for box-filtered reads (colormap/gaussian.py, PreconvolvedMap.box_data; cm_gaussianBox) with u_heightRange: 3n + 1 columns for the n μ texels of u_heightGaussian, column c holding the sum of C̄_h(μ, σ) over the μ texels from mu_lo to mu_lo + (c - n)(mu_hi - mu_lo)/n, over three copies of the range (periods for u_heightWrap = 0, the edge columns extended for 1); read LINEAR at u = (c + 0.5)/(3n + 1); v: σ as u_heightGaussian; RGBA: sums of linear premultiplied RGBA and alpha; CLAMP_TO_EDGE, no MIP
uniform int u_heightWrap;
uniform vec2 u_heightMap;  // @param -100..100 Height map: (scale, offset), the height colour table's argument f = scale (h + ρ r) + offset with h in object units; every mode follows; for clamp tables the filtered modes are exact while f stays within u_heightRange.xy and |scale| times the deviation stays below u_heightRange.z (the preconvolved bake's range)
uniform float u_perturb;   // @param -1..1 Perturbation: ρ in C(h + ρ r), the texture fractal r added to the height colour's argument (needs a height colour map and a texture fractal); every mode follows
uniform sampler2D u_slopePoint;  // @table the slope colour table C_s for the point and naive modes: u: f = u_slopeMap.x (s·d) + u_slopeMap.y (s the micro slope in the macro tangent frame, d = u_slopeDirection) in table periods, n = width entries, entry i covering [i/n, (i+1)/n); read with texelFetch at floor(n fract(f)) for u_slopeWrap = 0 (modulo) or min(floor(n clamp(f, 0, 1)), n - 1) for u_slopeWrap = 1 (clamp); one row, NEAREST, no MIP; RGBA: the colour table in linear RGB premultiplied by alpha, and alpha
uniform sampler2D u_slopeGaussian;  // @table the preconvolved slope colour map C̄_s(μ, σ) for the filtered modes with u_slopeRange = (mu_lo, mu_hi, sigma_max); u: μ = u_slopeMap.x E[s·d] + u_slopeMap.y (s the micro slope, visible slopes in surface-filter, d = u_slopeDirection), in table periods: u = fract(μ) for u_slopeWrap = 0 (modulo: one period, REPEAT, u_slopeRange.xy = (0, 1)) or (μ - mu_lo)/(mu_hi - mu_lo) for u_slopeWrap = 1 (clamp: CLAMP_TO_EDGE, the edge columns beyond), texel i at μ = mu_lo + (i + 0.5)(mu_hi - mu_lo)/width; v: σ = |u_slopeMap.x| x the standard deviation of s·d, row j at σ = sigma_max j/(height - 1) (read at v = (σ/sigma_max (height - 1) + 0.5)/height; σ > sigma_max reads the last row; row 0 is the table itself); RGBA: the colour table convolved with N(0, σ²) at μ, in linear RGB premultiplied by alpha, and alpha; LINEAR, no MIP
uniform sampler2D u_slopeGaussianDerivative;  // @table ∂C̄_s/∂μ of u_slopeGaussian per unit of its μ (colormap/gaussian.py, PreconvolvedMap.derivative_data: central differences over neighbouring μ texels), laid out and read as u_slopeGaussian with u_slopeRange and u_slopeWrap; RGBA: derivatives of linear premultiplied RGB and of alpha; LINEAR, no MIP
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
// A constant colour map (MS_HEIGHT_CONSTANT, MS_SLOPE_CONSTANT, MS_TEXTURE_CONSTANT instead of its _MAP define):
// its colour, linear RGB premultiplied by alpha, and alpha; every mode uses it as it is.
uniform vec4 u_heightConstant;
uniform vec4 u_slopeConstant;
uniform vec4 u_textureConstant;
#if defined(MS_DRIVER_NODES) && !defined(MS_DRIVER_COLOUR)
#undef MS_DRIVER_NODES  // the nodes read their colours over the driver
#endif
#ifdef MS_DRIVER_COLOUR
uniform sampler2D u_driverColour;  // @table surface-filter's height colour under a transfer function h = s g(f), read over the driver f (driver_colour.py): the composite K(f) = C_h(u_heightMap.x s g(f) + u_heightMap.y) (the scene's u_heightMap, baked in) preconvolved as u_heightGaussian is, clamp layout with u_driverRange = (mu_lo, mu_hi, sigma_max); u: μ = u_driverMap.x f + u_driverMap.y, read at (μ - mu_lo)/(mu_hi - mu_lo) (CLAMP_TO_EDGE); v: σ = |u_driverMap.x| x the standard deviation of the driver, row j at σ = sigma_max j/(height - 1) (read at v = (σ/sigma_max (height - 1) + 0.5)/height); RGBA: linear RGB premultiplied by alpha, and alpha; LINEAR, no MIP
uniform vec2 u_driverMap;
uniform vec3 u_driverRange;
#ifdef MS_DRIVER_NODES
uniform sampler2D u_driverSlopeColour;  // @table the transfer function's slope gain over the driver (driver_colour.py, driver_slope_table): (K(f).rgb q(f), q(f)) with q = g'(f)/G, G = max g' over the table, preconvolved and read as u_driverColour; RGBA: K premultiplied as in u_driverColour; LINEAR, no MIP; not colours in alpha
uniform float u_driverSlopeUnit;        // u_transferScale G: q's unit in dh/df
#endif
#endif
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

// The slope colour where a light falls (beyond the paper): Lambert's cosine L and the slope colour C_s both
// vary with the slope s, so what the light shows is E[C_s L]/E[L], not C̄_s = E[C_s]: facets turned to the
// light are brighter, and on micro-slopes-sphere they are the red ones. For Gaussian slopes and L linear over
// their spread, Stein's lemma gives Cov(C_s(s·d), L) = E[C_s'] Cov(s·d, L) with E[C_s'] = ∂C̄_s/∂μ, so
//     E[C_s L]/E[L] = C̄_s + ∂C̄_s/∂μ · Cov(s·d, L)/E[L]
// (exact for any L when C̄_s is linear over the spread). cs = C̄_s at the mean μ = E[s·d] with the variance
// varDir of s·d; covOverMean = Cov(s·d, L)/E[L] (ms_lambertMoments). ∂C̄_s/∂μ is read from the bake's own
// derivative map (u_slopeGaussianDerivative), one read. Until the eighteenth session it was a central
// difference of two reads of C̄_s over ±h, h half the deviation: the derivative of C̄_s smoothed by that box
// (256 px, 64-spp references, 7 round-robin rounds, before -> after: micro-snake-sphere FLIP 0.0632 ->
// 0.0630 at 1.549 -> 1.535 x naive, micro-slopes-sphere 0.0915 -> 0.0911 at 1.077 -> 1.072).
// Measured (256 px, 64-spp references; FLIP of surface-filter before -> after): micro-slopes-sphere
// 0.0904 -> 0.0832, micro-snake-sphere 0.0837 -> 0.0776; presets without a slope colour map are unchanged.
// Under an environment's irradiance E (MS_IRRADIANCE) the same holds per channel: E[C_s E] = C̄_s Ē +
// ∂C̄_s/∂μ Cov(s·d, E), with Cov from the irradiance's own cubature nodes (ms_filteredIrradianceMomentsSH).
#ifdef MS_SLOPE_MAP
vec4 ms_slopeColourDerivative(float mean, float varDir) {
    return u_slopeMap.x * ms_mapGaussian(u_slopeGaussianDerivative, u_slopeMap, mean, varDir, u_slopeWrap, u_slopeRange);
}

// derivative = ms_slopeColourDerivative at the sample, computed once for all its lights and the environment.
vec4 ms_slopeColourUnderLight(vec4 cs, vec4 derivative, float covOverMean) {
    return clamp(cs + derivative * covOverMean, 0.0, 1.0);
}
#endif

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

// The rendered surface at the macro point p (octave weights ms_weight[] as set last): its height and slopes in
// the macro tangent frame, the unresolved height variance and slope covariance, and the texture fractal r.
// With a transfer function h = g(f): E[g] and the slope moments of §7, and g's moments. In surface-filter (no
// transfer function) the slopes that shade are the octaves' of weights ms_slopeWeight (heightfield.glsl:
// between β₁ and the rendered surface's β where the relief stands out of the pixel), about which the rest of
// their variance spreads. Smith's Λ keeps the rendered surface's residual: ms_shade builds its masking from
// the unresolved statistics, not from these. Measured (256 px, 64-spp references, surface-filter FLIP with the
// rendered surface's slopes -> MS_SLOPE_WEIGHT_GATE 0.5 and 0): micro-irradiance-terrain 0.0410 -> 0.0387 and
// 0.0386, micro-slopes-terrain (9 samples) 0.0864 -> 0.0841 and 0.0850, micro-heights-terrain 0.0806 -> 0.0801
// and 0.0814, micro-heights-grazing 0.0516 -> 0.0513 and 0.0519; the spheres within 0.0001, their relief gate
// about 0. texture-filter keeps the rendered surface's slopes: with β₁'s it went 0.140 -> 0.165 on the
// irradiance terrain and 0.142 -> 0.158 on the heights terrain. docs/microsurface-history.md, "The slopes that
// shade".
struct MsSurface {
    float h;
    vec2 slope;
    float heightVariance;
    vec3 slopeCov;
    float r;
    vec4 transferMoments;  // (E[h], E[h²], E[h'], E[h'²]) with MS_TRANSFER, else (0, 0, 1, 1)
    vec3 linear;           // the gradient (object space) of the height's linear part over the footprint
    float heightResidual;  // heightVariance less the expected variance of that linear part
    float driver;          // the coarse surface's driver f at the point (its height without a transfer function)
};

#ifdef MS_TRANSFER
// The current split's unresolved statistics about a coarse driver (f, ∇f in the macro tangent frame), as
// ms_surfaceAt gives them at a point of that driver (g(f) is not linear: its heights stay a Gaussian of all
// their variance), without evaluating the fractal.
MsSurface ms_unresolvedAbout(vec3 driver) {
    MsSurface s;
    s.transferMoments = ms_transfer(driver.x, ms_transferSigma);
    ms_transferStats(s.transferMoments, driver.yz, ms_slopeVariance * vec3(1.0, 0.0, 1.0), s.h, s.heightVariance,
                     s.slope, s.slopeCov);
    s.r = 0.0;
    s.linear = vec3(0.0);
    s.heightResidual = s.heightVariance;
    s.driver = driver.x;
    return s;
}
#endif

MsSurface ms_surfaceAt(vec3 p, mat3 frame) {
    MsSurface s;
    vec3 shading;
    vec4 fg = ms_fractalGradLinear(p, 0, ms_weightedHeightOctaves, s.linear, shading);
#if defined(MODE_SURFACE_FILTER) && !defined(MS_TRANSFER)
    vec3 grad = shading;
    float slopeVariance = ms_shadingSlopeVariance;
#else
    vec3 grad = fg.xyz;
    float slopeVariance = ms_slopeVariance;
#endif
    s.h = fg.w;
    s.driver = fg.w;
    s.slope = vec2(dot(grad, frame[0]), dot(grad, frame[1]));
    s.heightVariance = ms_heightVariance;
    s.heightResidual = ms_heightResidual;
    s.slopeCov = vec3(slopeVariance, 0.0, slopeVariance);
    s.transferMoments = vec4(0.0, 0.0, 1.0, 1.0);
#ifdef MS_TRANSFER
    s = ms_unresolvedAbout(vec3(fg.w, s.slope));  // about this point's driver and its gradient (grad above)
#endif
#ifdef MS_TEXTURE_FRACTAL
    s.r = ms_fractal(p, MS_MAX_OCTAVES, ms_weightedTextureOctaves);
#else
    s.r = 0.0;
#endif
    return s;
}

// Shading samples: where the sub-pixel ray through the macro surface point x0 (from the eye for perspective
// cameras, along the view direction d for orthographic ones) meets the plane through the marched point q with
// normal n (main(): the coarse surface's tilt over twice the pixel): the parallax of the marched relief to
// first order (on a facet that faces a grazing eye the points close up). Kept within twice |shift| of q;
// where the ray runs along the facet, q + shift (the point on the macro surface's tangent plane).
vec3 ms_subpixelPoint(vec3 x0, vec3 d, vec3 q, vec3 n, vec3 shift) {
    vec3 dk = u_eyeObject.w > 0.5 ? normalize(x0 - u_eyeObject.xyz) : d;
    float den = dot(dk, n);
    if (den > -0.05) return q + shift;
    vec3 dq = x0 + dot(q - x0, n) / den * dk - q;
    return q + dq * min(1.0, 2.0 * length(shift) / max(length(dq), 1e-30));
}

// The whole footprint's split, as the shading samples see it: the marched (coarse) surface's slope
// covariance and height variance in driver units, the ratios of the fractal's effective to its actual slope
// variance (fractal_masking.py: what Λ sees), whole and coarse, and what the 1/N footprint resolves beyond
// the whole one (0 with one sample).
struct MsFootprint {
    vec3 marchedCov;
    float marchedVariance;
    float maskingScale;
    float marchedMaskingScale;
    float sampledHeightVariance;
    float sampledSlopeVariance;
};

// Smith's masking towards the eye at a sample s. Without a transfer function it is the same for every
// sample, and so is each light's part (MsLight).
struct MsMasking {
    vec3 totalCov;      // slopes of the whole surface (coarse + micro), as Λ sees them
    vec3 coarseCov;     // slopes of the coarse (marched) surface, as Λ sees them
    float sigmaT;       // height deviations, whole and coarse
    float sigmaC;
    float microVariance;  // the height variance beyond the coarse surface (the samples' and the unresolved)
#ifdef MS_DRIVER_COLOUR
    float sigmaFT;      // the driver's deviations, whole and coarse
    float sigmaFC;
    float driverUnresolved;  // the share of the driver's variance beyond the coarse surface that no sample shows
#endif
    float lambdaOT;     // Λ(ω_o), whole and coarse
    float lambdaOC;
    vec2 viewHeights;   // D_h's (shift, variance) for the view alone (Λ_i = 0); with MS_HEIGHT_MAP (with
                        // MS_DRIVER_COLOUR the driver's, in driver units)
};

// The slope and height statistics of the masking at s, without Λ(ω_o) and D_h (ms_masking adds them): all that
// the micro relief's visibility below the horizon needs (ms_facetMicroVisibility).
MsMasking ms_maskingStatistics(MsSurface s, MsFootprint f) {
    // (E[h'], E[h'²]) scale driver variances to height variances (1, 1 without a transfer function)
    vec2 gain = s.transferMoments.zw;
    vec3 coarseCov = f.marchedCov * gain.y;
    float coarseVariance = f.marchedVariance * gain.x * gain.x;
    // the micro part of the whole footprint: the sample's unresolved part plus what the samples resolve
    vec3 microCov = s.slopeCov + gain.y * f.sampledSlopeVariance * vec3(1.0, 0.0, 1.0);
    float microVariance = s.heightVariance + gain.x * gain.x * f.sampledHeightVariance;
    MsMasking m;
    m.totalCov = (microCov + coarseCov) * f.maskingScale;
    m.coarseCov = coarseCov * f.marchedMaskingScale;
    m.sigmaC = sqrt(coarseVariance);
    m.sigmaT = sqrt(microVariance + coarseVariance);
    m.microVariance = microVariance;
#ifdef MS_DRIVER_COLOUR
    // the driver's split as the heights' above, in driver units: the coarse (marched) variance, and beyond it
    // the sample's unresolved part (ms_transferSigma of the current split) and what the samples resolve
    float driverMicroVariance = ms_transferSigma * ms_transferSigma + f.sampledHeightVariance;
    m.driverUnresolved = ms_transferSigma * ms_transferSigma / max(driverMicroVariance, 1e-30);
    m.sigmaFC = sqrt(f.marchedVariance);
    m.sigmaFT = sqrt(driverMicroVariance + f.marchedVariance);
#endif
    return m;
}

MsMasking ms_masking(vec3 wo, MsSurface s, MsFootprint f) {
    MsMasking m = ms_maskingStatistics(s, f);
    m.lambdaOT = ms_lambda(wo, m.totalCov);
    m.lambdaOC = ms_lambda(wo, m.coarseCov);
    m.viewHeights = vec2(0.0);
#ifdef MS_DRIVER_COLOUR
    m.viewHeights = ms_microHeights(m.lambdaOT, m.lambdaOC, m.sigmaFT, m.sigmaFC);
#elif defined(MS_HEIGHT_MAP)
    m.viewHeights = ms_microHeights(m.lambdaOT, m.lambdaOC, m.sigmaT, m.sigmaC);
#endif
    return m;
}

#ifdef MS_DRIVER_COLOUR
// D_h (shift, variance) `heights` of the driver, about the sample's coarse driver and scaled to the part of
// the variance that no sample resolves, as a read of the tables over the driver: (μ, σ) in their units.
vec2 ms_driverAt(MsSurface s, MsMasking m, vec2 heights) {
    return vec2(u_driverMap.x * (s.driver + heights.x) + u_driverMap.y,
                abs(u_driverMap.x) * sqrt(heights.y * m.driverUnresolved));
}
#endif

#ifdef MS_DRIVER_NODES
// The slopes of h = s g(f) at a shading sample as two nodes of the slope gain g' (beyond the paper; the
// header of driver_colour.py derives it). ∇h = g'(f) ∇f: for one driver value the slopes are Gaussian, g'
// times the driver's, but over the driver they are a mixture (the sponge: a flat top, g' = 0, and steep
// walls), and §7's one Gaussian of their whole covariance shades them as if every facet had the average
// slope spread. The nodes g'± = E[g'] ± sd(g') of the sample's driver N(f_c, σ_f) (its transfer moments)
// keep E[g'] and E[g'²]; node ± has the slopes N(g'± ∇f̄, g'±² Σ_∇f) (∇f̄ the coarse driver's gradient, Σ_∇f
// the unresolved driver's covariance), its own visible slopes D_s and projected area towards the eye, and
// the colour K± = K̄ ± Cov(K, g')/sd(g') (K the height colour over the driver, read over the view's D_h), so
// the flat top's colour goes with the flat top's share of the view and of the light.
struct MsNodes {
    vec2 meanUp, meanDown;  // D_s of node + and node −
    vec3 covUp, covDown;
    float share;       // node +'s share of the visible area
    float area;        // the sample's projected area towards the eye, the nodes' mean
    vec4 slopeColour;  // (E[K g'] rgb, E[g']) over the view's D_h
    float spread;      // sd(g')
};

MsNodes ms_driverNodes(vec3 wo, MsSurface s, MsMasking m, float lean) {
    vec2 at = ms_driverAt(s, m, m.viewHeights);
    MsNodes nodes;
    nodes.slopeColour = u_driverSlopeUnit * cm_gaussian(u_driverSlopeColour, at.x, at.y, CM_CLAMP, u_driverRange);
    vec2 gain = s.transferMoments.zw;  // E[h'], E[h'²]
    nodes.spread = sqrt(max(gain.y - gain.x * gain.x, 0.0));
    float up = gain.x + nodes.spread, down = gain.x - nodes.spread;
    vec2 gradient = s.slope / max(gain.x, 1e-30);  // ∇f̄ (s.slope = E[h'] ∇f̄)
    vec2 meanUp = up * gradient, meanDown = max(down, 0.0) * gradient;
    vec3 cov = ms_slopeVariance * vec3(1.0, 0.0, 1.0);
    float areaUp = ms_visibleSlopes(wo, meanUp, up * up * cov, nodes.meanUp, nodes.covUp);
    float areaDown = ms_visibleSlopes(wo, meanDown, down * down * cov, nodes.meanDown, nodes.covDown);
    nodes.meanUp += lean * (nodes.meanUp - meanUp);
    nodes.meanDown += lean * (nodes.meanDown - meanDown);
    nodes.share = areaUp / max(areaUp + areaDown, 1e-30);
    nodes.area = 0.5 * (areaUp + areaDown);
    return nodes;
}

// Cov(K, g')/sd(g') for the colour K̄ read over the same D_h: K± = K̄ ± this
vec4 ms_nodeColourShift(MsNodes nodes, vec4 colour) {
    vec3 covariance = nodes.slopeColour.rgb - colour.rgb * nodes.slopeColour.a;
    return vec4(nodes.spread > 1e-6 ? covariance / nodes.spread : vec3(0.0), 0.0);
}
#endif

#ifdef MS_HEIGHT_MAP
// A shading sample's height colour C̄_h (§5.1) for D_h's (shift, variance) `heights` under masking m. Over
// the sample's footprint (axes boxX, boxY) the octaves it resolves spread its heights by their linear part
// as box(|g·boxX|) * box(|g·boxY|), g = s.linear, flat-topped like Hart's first-order width, and by the
// rest (s.heightResidual) as a Gaussian: the map is read box-filtered over the larger of the two
// (cm_gaussianBox, as the gaussian mode of Hart's model reads it) with the other's variance added to the
// Gaussian's. The part of that spread that is seen (and lit) is D_h's variance over the micro variance; it
// scales both. Without a linear part (far away, or a transfer function) this is C̄_h(h + shift, σ²) with
// σ² D_h's variance times the share of the micro variance that no sample resolves, as the paper has it.
// Measured (256 px, 64-spp references, surface-filter FLIP, the Gaussian of all the variance -> this):
// micro-heights-sphere 0.0520 -> 0.0509 (0.0737 -> 0.0708 with one sample), the same sphere under ambient
// light alone 0.0815 -> 0.0772; the terrains unchanged (their relief's linear part spans less than a texel
// of the map).
vec4 ms_heightColour(MsSurface s, MsMasking m, vec2 heights, vec3 boxX, vec3 boxY, float perturbVariance) {
#ifdef MS_DRIVER_COLOUR
    // Under a transfer function, over the driver (driver_colour.py; beyond the paper): D_h's (shift,
    // variance) of the driver, about the sample's coarse driver, its variance scaled to the part that no
    // sample resolves. Measured (256 px, 64-spp references, surface-filter FLIP, §7's Gaussian of the
    // heights -> this; time 1.92 -> 1.87 x naive, one texture read for two): micro-sponge-sphere at 24 units
    // 0.2136 -> 0.1473, at 14 0.1582 -> 0.1372, at 11 0.1348 -> 0.1320, at 8 0.1049 -> 0.1084, at 6 0.0975
    // -> 0.0982, at the preset's 4.24 0.0838 -> 0.0839; micro-moss-sphere at 24 units 0.1108 -> 0.0958, at 14
    // 0.1034 -> 0.1020, at 8 0.0979 -> 0.0993, at 4.24 0.0791 -> 0.0792. At 6-8 units the sponge's rim
    // comes out too yellow (green +0.018 where r/R > 0.95 at 8 units): at a grazing view Smith's D_h of
    // the driver sees the flat top, where the reference also sees the pits' walls that face the eye.
    // Weighting each driver by its facets' projected area, E[(o_z - s g'(f) ∇f·o_xy)⁺] ≈ o_z + 0.4 s g'(f)
    // σ_∇f |o_xy| (a second table of K g'), fixed the rim (8 units 0.1045) but took the far sphere back
    // (24 units 0.1739; the moss at 14 units 0.1079), and the light's cosine weighted alike (a third
    // table) further (0.1970): not kept (docs/microsurface-history.md).
    vec2 at = ms_driverAt(s, m, heights);
    return cm_gaussian(u_driverColour, at.x, at.y, CM_CLAMP, u_driverRange);
#else
    float seen = heights.y / max(m.microVariance, 1e-30);
    vec2 g = abs(vec2(dot(s.linear, boxX), dot(s.linear, boxY))) * sqrt(seen);
    float major = max(g.x, g.y), minor = min(g.x, g.y);
    float variance = seen * s.heightResidual + minor * minor / 12.0 + perturbVariance;
    float scale = abs(u_heightMap.x);
    return cm_gaussianBox(u_heightGaussianBox, u_heightMap.x * (s.h + heights.x + u_perturb * s.r) + u_heightMap.y,
                          scale * major, scale * sqrt(max(variance, 0.0)), u_heightWrap, u_heightRange);
#endif
}
#endif

// One light's share under masking m: V̄ = V̄_t / V̄_c and D_h's (shift, variance) for Λ_o + Λ_i.
struct MsLight {
    float visibility;
    vec2 heights;
    float lambdaIC;  // Λ_i of the coarse surface
};

#ifdef MS_SPHERE
// Smith's shadowing over a sphere (smith.glsl ms_curvedLight, curved_shadowing.py; beyond the paper).
// Measured (micro-heights-sphere, 256 px, 64-spp references, surface-filter FLIP; time unchanged): 0.0596 ->
// 0.0552 at 24 units, 0.0549 -> 0.0527 at 10, 0.0502 -> 0.0501 at the preset's 4.24; micro-snake-sphere
// 0.0675 -> 0.0669, micro-slopes-sphere 0.0911 -> 0.0909. With a transfer function only the micro relief's
// light below the macro horizon takes it (ms_facetMicroVisibility), not Λ_i above it (ms_light): the
// curve's constants were fitted on fBm, and on the moss and sponge the raised Λ_i cost 0.02-0.06 x naive's
// frame for little (curved everywhere -> below the horizon only, FLIP at 24 / 14 units: moss 0.0865 ->
// 0.0867, 0.1027 -> 0.1017; sponge 0.0911 -> 0.0944, 0.0936 -> 0.0941).
vec3 ms_curvedLight(vec3 w, float sigma) {
    return ms_curvedLight(w, sigma, ms_radius, MS_CURVED_ELEVATION);
}
float ms_curvedDescent(vec3 w, float sigma) {
    return ms_curvedDescent(w, sigma, ms_radius, MS_CURVED_DESCENT);
}
#endif

MsLight ms_light(MsMasking m, vec3 wi) {
#if defined(MS_SPHERE) && !defined(MS_TRANSFER)
    float lambdaIT = ms_lambda(ms_curvedLight(wi, m.sigmaT), m.totalCov);
    float lambdaIC = ms_lambda(ms_curvedLight(wi, m.sigmaC), m.coarseCov);
#else
    float lambdaIT = ms_lambda(wi, m.totalCov);
    float lambdaIC = ms_lambda(wi, m.coarseCov);
#endif
    MsLight light;
    light.visibility = ms_averageVisibility(m.lambdaOT, lambdaIT) / ms_averageVisibility(m.lambdaOC, lambdaIC);
    light.heights = vec2(0.0);
    light.lambdaIC = lambdaIC;
#ifdef MS_DRIVER_COLOUR
    light.heights = ms_microHeights(m.lambdaOT + lambdaIT, m.lambdaOC + lambdaIC, m.sigmaFT, m.sigmaFC);
#elif defined(MS_HEIGHT_MAP)
    light.heights = ms_microHeights(m.lambdaOT + lambdaIT, m.lambdaOC + lambdaIC, m.sigmaT, m.sigmaC);
#endif
    return light;
}

#ifdef MS_SPHERE
// A light at or below the macro horizon: Smith's G1 of a plane is 0 there, but on a sphere of radius R a
// point standing h above it sees down to about sqrt(2h/R) below its tangent plane. The coarse surface's
// shadow ray decides whether the coarse relief lets the light through; the micro relief then shadows as a
// plane tangent to the coarse facet (slope s): V̄ (eq. 12) of the micro statistics, ω_o and ω_i
// measured from the facet's normal (their in-plane parts taken along the first axis: the micro slopes are
// isotropic); the light's slope over the facet is the curved one (ms_curvedLight), times the share that
// clears the dive below the facet's horizon (ms_curvedDescent). ms_horizonVisibility
// blends it into V̄_t / V̄_c over 0 < ω_i.z < sqrt(2σ_t/R), so light is continuous across the horizon.
// Measured (micro-moss-sphere, 256 px, 64 spp): the band within 0.15 below the horizon was 40 % too dark
// with no light there; it is now within 4 % (FLIP 0.120 -> 0.111 with the shadow budget).
float ms_facetMicroVisibility(MsMasking m, vec3 wo, vec3 wi, vec2 slope) {
    vec3 n = normalize(vec3(-slope, 1.0));
    float iz = dot(wi, n);
    float oz = dot(wo, n);
    vec3 microCov = max(m.totalCov - m.coarseCov, vec3(0.0));
    float lambdaO = ms_lambda(vec3(length(wo - oz * n), 0.0, oz), microCov);
    vec3 light = vec3(length(wi - iz * n), 0.0, iz);
    float sigma = sqrt(m.microVariance);  // the micro relief's height deviation over the facet
    float visibility = ms_averageVisibility(lambdaO, ms_lambda(ms_curvedLight(light, sigma), microCov));
    return visibility * ms_curvedDescent(light, sigma);
}

// A light's V̄ (visibility = V̄_t / V̄_c) with the horizon band above: the facet's micro visibility `facet`
// below the horizon, blended into V̄ over the band of the whole relief's deviation σ_t.
float ms_horizonBlend(float visibility, float facet, float sigmaT, vec3 wi) {
    float band = sqrt(2.0 * sigmaT / ms_radius);
    return wi.z >= band ? visibility : mix(facet, wi.z > 0.0 ? visibility : 0.0, smoothstep(0.0, band, wi.z));
}
float ms_horizonVisibility(float visibility, MsMasking m, vec3 wo, vec3 wi, vec2 slope) {
    return ms_horizonBlend(visibility, ms_facetMicroVisibility(m, wo, wi, slope), m.sigmaT, wi);
}

// Where the masking is the same for every sample (no transfer function), the band is worked out once per
// light, on the coarse facet of the samples' placement plane (its tilt over twice the pixel), not on each
// sample's: llvmpipe ran it for every sample and light, masked, whether a light was in the band or not.
// Measured (256 px, 64-spp references, surface-filter FLIP per sample -> per pixel): height sphere
// 0.0514 -> 0.0515, snake 0.0659 -> 0.0662, slope sphere 0.0730 -> 0.0731; 0.02-0.03x naive's time less.
// With a transfer function the masking is each sample's; the band is blended per sample (its σ_t), but the
// facet's micro visibility below the horizon is worked out once per light too, on the same placement facet,
// with the masking of the samples' split about q's coarse driver (ms_unresolvedAbout). Per sample it had
// cost 0.05 x naive's frame on the moss and sponge. Measured (256 px, 64-spp references, surface-filter FLIP
// and time ÷ naive, 7-9 round-robin rounds, per sample -> per pixel): moss 0.0792 -> 0.0793 at 1.486 ->
// 1.460, at 24 and 14 units 0.0867 -> 0.0866 and 0.1017 -> 0.1022; sponge 0.0838 -> 0.0838 at 1.970 ->
// 1.915. On each sample's own coarse slope (finer octaves than the placement's) the moss's bands next to the
// macro horizon had come out 9.5 % (below) and 9.9 % (above) too bright against the reference (128 px,
// 16 spp; 1.1 % and 2.5 % on the placement facet).
#if MS_SHADING_SAMPLES > 1
#ifdef MS_TRANSFER
#define MS_HORIZON_FACET_PER_PIXEL
#else
#define MS_HORIZON_PER_PIXEL
#endif
#endif
#endif

// The rows of surface-filter's grid as marched sub-rays (main(); beyond the paper): where the coarse relief
// stands out of the pixel as the eye sees it, the grid's MS_GRID_Y rows are the hits of a column of sub-rays
// (ms_marchColumn), and each row's MS_GRID_X samples are placed across the column through its own hit, on a
// plane with the tilt of q's placement plane (each row's own tilt, one more ms_coarseSlope per row, lowered
// FLIP by 0.3-3 % and cost about 0.07x naive's frame on every pixel: llvmpipe ran its loop masked where
// there was no column). ms_rows rows were hit (the others passed the silhouette): ms_rowPoint[r] is row r's
// hit, ms_rowMacro[r] the macro point its sub-ray passes through. Row 0 is q: the pixel's statistics, split
// and shadow profile are taken there, and the profile's reach spans the rows (their samples read it).
// MS_RELIEF_RAYS (heightfield.glsl): the column's sub-rays, the grid's rows (material.py).
bool ms_column = false;
int ms_rows = 1;
vec3 ms_rowPoint[MS_RELIEF_RAYS];
vec3 ms_rowMacro[MS_RELIEF_RAYS];

// The pixel's radiance from its visible point q = o + t d (|d| = 1) on the marched coarse surface (with
// ms_column, row 0 of the column). gate: how far the shading samples close up on q (ms_reliefGate).
vec3 ms_shade(vec3 o, vec3 d, float t, vec3 p0, vec3 dpdxMacro, vec3 dpdyMacro, vec3 dpdx, vec3 dpdy, float gate) {
    vec3 q = o + t * d;
#if !defined(MODE_POINT) && !defined(MODE_MARCH_STEPS)
    // the pixel's radius across the ray at q
    float pixelRadius = 0.5 * max(length(dpdxMacro - dot(dpdxMacro, d) * d), length(dpdyMacro - dot(dpdyMacro, d) * d));
    if (u_eyeObject.w > 0.5) pixelRadius *= t / length(p0 - o);
    ms_shadowStep = MS_SHADOW_STEP * pixelRadius;
#endif
    vec3 p = ms_project(q);
    mat3 frame = ms_macroFrame(q);  // columns: tangent, bitangent, normal (object space)
    vec3 wo = -d * frame;  // view direction in the macro tangent frame
#ifdef MS_IRRADIANCE
    mat3 worldFrame = mat3(normalize(u_worldNormalFromObject * frame[0]), normalize(u_worldNormalFromObject * frame[1]),
                           normalize(u_worldNormalFromObject * frame[2]));
#endif
    vec2 dir = u_slopeDirection;
    vec4 c0 = vec4(0.0), ch = vec4(0.0), cs = vec4(0.0);
#ifdef MS_TEXTURE_CONSTANT
    c0 = u_textureConstant;
#endif
#ifdef MS_HEIGHT_CONSTANT
    ch = u_heightConstant;
#endif
#ifdef MS_SLOPE_CONSTANT
    cs = u_slopeConstant;
#endif

#if !defined(MODE_SURFACE_FILTER)
    MsSurface s = ms_surfaceAt(p, frame);
    vec3 normal = normalize(frame * vec3(-s.slope, 1.0));  // object space
#if defined(MODE_POINT) || defined(MODE_NAIVE) || defined(MODE_MARCH_STEPS)
#ifdef MS_TEXTURE_MAP
    c0 = ms_mapPoint(u_texturePoint, u_textureMap, s.r, u_textureWrap);
#endif
#ifdef MS_HEIGHT_MAP
    ch = ms_mapPoint(u_heightPoint, u_heightMap, s.h + u_perturb * s.r, u_heightWrap);
#endif
#ifdef MS_SLOPE_MAP
    cs = ms_mapPoint(u_slopePoint, u_slopeMap, dot(s.slope, dir), u_slopeWrap);
#endif
    vec4 albedo = ms_combine(c0, ch, cs);
#ifdef MS_IRRADIANCE
    vec3 radiance = albedo.rgb * ms_irradianceSH(u_sh, MS_ENV_FROM_WORLD * normalize(u_worldNormalFromObject * normal)) / MS_PI;
#endif
#elif defined(MODE_TEXTURE_FILTER)
    // view-independent: p_h = N(h_c, σ_h²), p_s = N(s_c, Σ)
    float textureVariance = ms_textureVariance;
#ifdef MS_TEXTURE_MAP
    c0 = ms_mapGaussian(u_textureGaussian, u_textureMap, s.r, textureVariance, u_textureWrap, u_textureRange);
#endif
#ifdef MS_HEIGHT_MAP
    ch = ms_mapGaussian(u_heightGaussian, u_heightMap, s.h + u_perturb * s.r,
                        s.heightVariance + u_perturb * u_perturb * textureVariance, u_heightWrap, u_heightRange);
#endif
#ifdef MS_SLOPE_MAP
    vec3 sc = s.slopeCov;
    float slopeVarDir = dir.x * dir.x * sc.x + 2.0 * dir.x * dir.y * sc.y + dir.y * dir.y * sc.z;
    cs = ms_mapGaussian(u_slopeGaussian, u_slopeMap, dot(s.slope, dir), slopeVarDir, u_slopeWrap, u_slopeRange);
#endif
    vec4 albedo = ms_combine(c0, ch, cs);
#ifdef MS_IRRADIANCE
    vec3 radiance = albedo.rgb * ms_filteredIrradianceSH(u_sh, MS_ENV_FROM_WORLD * worldFrame, s.slope, s.slopeCov) / MS_PI;
#endif
#else
#error "unknown MODE_ define"
#endif
#ifndef MS_IRRADIANCE
    // Lambert at the (coarse) normal, a shadow ray to each light
    vec3 radiance = albedo.rgb * sh_ambient;
    for (int j = 0; j < SH_LIGHTS; ++j) {
        if (j >= sh_lightCount) break;
        vec3 l = normalize(mat3(u_objectFromWorld) * sh_lightDirection[j]);
        float cosine = max(dot(normal, l), 0.0);
        if (cosine > 0.0) cosine *= ms_shadow(q, l, MS_SHADOW_STEPS);
        radiance += albedo.rgb * cosine * sh_lightColour[j];
    }
#endif

#else  // MODE_SURFACE_FILTER
    // Heitz et al. 2014 §5–§6 with Smith's statistics of the whole surface (coarse + micro: Λ_t, σ_t) and of
    // the coarse part that is rendered (Λ_c, σ_c). The ray march already shows the coarse surface's own
    // masking and shadows; the micro part supplies the rest, matched in the mean over the footprint:
    //   D_h shift μ_d(L_t)σ_t − μ_d(L_c)σ_c, variance σ_d(L_t)²σ_t² − σ_d(L_c)²σ_c², V̄ = V̄_t / V̄_c.
    // (Smith's visibility depends on the total height and slopes: coarse valleys are hidden by micro bumps
    // on coarse hills. Using the micro statistics alone under-estimates the shift by up to σ_t/σ_m.)
    //
    // Shading samples (beyond the paper): the octaves that the footprint half resolves are neither
    // geometry nor noise; one sample of them at the pixel centre misses their pixel mean by a random amount,
    // which was most of the error left (per-pixel noise, not bias). With an N x M grid (MS_GRID_X, MS_GRID_Y)
    // the pixel is shaded at its N x M sub-pixel points with the octaves split for the sub-boxes' footprint,
    // and the radiances are averaged, each weighted by its facets' expected area projected towards the eye
    // (the share of the pixel's rays it catches; below). A sub-pixel point is where the sub-pixel
    // ray meets a plane through the marched point (ms_subpixelPoint, below); no ray is
    // marched again. Where the relief stands out of the pixel (gate) it is geometry already and
    // the samples close up towards the centre, their footprint's split towards the whole one's. The
    // march, the coarse surface's shadows (once per light, below) and the masking statistics stay those
    // of the whole footprint: the samples resolve what the 1/N footprint adds (sampled*Variance), and
    // D_h's variance keeps only the part they leave unresolved (ms_heightColour). Measured (256 px,
    // 256-spp reference): micro-heights-sphere 0.079 FLIP with one sample, 0.064 with 2 x 2 and 0.061 with
    // 3 x 3 (the default: 1.28x naive's frame time); micro-slopes-sphere (64 spp) 0.133, 0.108, 0.095.
    // Tried and not kept (micro-heights-sphere, 2 x 2 samples, 0.068 before the horizon rule below):
    // re-marching the four sub-pixel rays (0.050 but 3.7x the frame time); Newton steps from the
    // tangent plane onto the sampled surface; weights by Smith's masking of the samples' mid-octave
    // heights; the half footprint's masking statistics (none better than 0.068).
    //
    // Each sample's shadow (2026-12-03): one ray per light is traced from the marched point (binary for the
    // whole pixel before), and each sample reads its own shadow off that ray's least clearance
    // (ms_shadowProfile: the sample's height and offset shift the clearance by Δh - ∇h·δ). Its own shadow
    // ray per sample costs 4x the frame (0.050 FLIP on micro-heights-sphere); the profile's answer is
    // within 0.002 of it at the cost of the single ray (64-spp references, before -> after, frame time ÷
    // naive unchanged within the timing noise): micro-heights-sphere 0.0598 -> 0.0517, micro-snake-sphere
    // 0.0859 -> 0.0830, micro-slopes-sphere 0.0940 -> 0.0897; the terrains, moss and sponge, where the
    // samples close up on the centre, are unchanged.
    // the farthest sample's offset from the centre, and the most its clearance can differ from the centre's
#if MS_SHADING_SAMPLES > 1
    // the grid's axes: its longer side along the footprint's longer screen axis (they matter only for an
    // N x M grid); the column's: X across it, Y along
    bool swapAxes = !ms_column && ((length(dpdy) > length(dpdx)) != (MS_GRID_Y > MS_GRID_X));
    vec3 gridX = swapAxes ? dpdy : dpdx, gridY = swapAxes ? dpdx : dpdy;
    vec3 gridXMacro = swapAxes ? dpdyMacro : dpdxMacro, gridYMacro = swapAxes ? dpdxMacro : dpdyMacro;
#ifdef MS_TRIANGLE
    float spacing = 0.0;
    for (int k = 0; k < 3; ++k) {
        vec2 vertex = (1.0 - gate) * MS_TRIANGLE_RADIUS * MS_TRIANGLE_OFFSETS[k];
        spacing = max(spacing, length(vertex.x * gridX + vertex.y * gridY));
    }
#else
    vec2 reach = (1.0 - gate) * vec2(MS_GRID_X - 1, ms_column ? 0 : MS_GRID_Y - 1) / vec2(2 * MS_GRID_X, 2 * MS_GRID_Y);
    float spacing = max(length(reach.x * gridX + reach.y * gridY), length(reach.x * gridX - reach.y * gridY));
#endif
#if MS_RELIEF_RAYS > 1
    // the column's rows are as far from q as their hits (their samples are traced from q's shadow profile)
    for (int r = 1; r < MS_RELIEF_RAYS; ++r) {
        if (r >= ms_rows) break;
        vec3 apart = ms_rowPoint[r] - q;
        spacing = max(spacing, length(apart - dot(apart, frame[2]) * frame[2]) + length(reach.x * gridX));
    }
#endif
#else
    float spacing = 0.0;
#endif
    // The first-order clearance holds while the samples lie closer than the coarse slopes change: it (and
    // the spacing that sets skip and reach) is faded out as the spacing grows from 0.5 to 2 over the coarse
    // frequency, back to the centre's shadow
    // (far away it had raised FLIP 0.052 -> 0.060 on micro-heights-sphere at 24 units; now 0.049).
    float linearity = 1.0 - smoothstep(0.5, 2.0, spacing * ms_coarseFrequency);
    spacing *= linearity;
    // The profile's reach: how far a sample's clearance can lie from the centre's, MS_REACH_DEVIATIONS standard
    // deviations of ∇h·δ for the farthest sample (the coarse slopes are Gaussian: a hard bound on |∇h| was
    // 2-3x wider, and the profile marched on through occluders for it).
    float shadowReach = MS_REACH_DEVIATIONS * ms_coarseSlopeDeviation() * spacing;
    // The whole footprint's split: the coarse (marched) surface and the driver's unresolved variances.
    MsFootprint footprint;
    footprint.marchedCov = vec3(ms_coarseSlopeVariance, 0.0, ms_coarseSlopeVariance);
    footprint.marchedVariance = ms_coarseHeightVariance;
    footprint.maskingScale = ms_maskingSlopeVariance / max(ms_slopeVariance + ms_coarseSlopeVariance, 1e-30);
    footprint.marchedMaskingScale = ms_coarseMaskingSlopeVariance / max(ms_coarseSlopeVariance, 1e-30);
    float footprintHeightVariance = ms_heightVariance;
    float footprintSlopeVariance = ms_slopeVariance;
#if MS_SHADING_SAMPLES > 1
    // Where the relief stands out of the pixel it is geometry already: the samples close up towards the
    // centre.
#ifdef MS_TRIANGLE
    vec2 sub = mix(vec2(sqrt(3.0) * MS_TRIANGLE_RADIUS), vec2(1.0), gate);  // the sub-box, in pixel axes
#else
    vec2 sub = mix(1.0 / vec2(MS_GRID_X, MS_GRID_Y), vec2(1.0), gate);  // the sub-box, in pixel axes
#endif
    if (ms_column) sub.y = 1.0 / float(MS_GRID_Y);  // a row's share of the pixel, whatever the gate
    // The plane the samples are placed on (ms_subpixelPoint) carries the coarse surface's tilt over the
    // region they can reach, twice the pixel (a sample may lie up to twice its offset from q), not the tilt
    // at q: q is a visible point, so the slope there of octaves about a pixel across leans towards the eye,
    // and tilting the whole pattern by it counted that preference a second time, on top of the samples'
    // projected-area weights (micro-snake-sphere's grazing rows were too red, +0.0031 per pixel). Measured
    // (256 px, 64-spp references, surface-filter FLIP, tilt at q -> over twice the pixel; time unchanged):
    // snake 0.0698 -> 0.0659, slope sphere 0.0767 -> 0.0730, height sphere 0.0499 -> 0.0514 (its samples'
    // heights followed q's facet better); the macro plane itself gave 0.0695, 0.0755 and 0.0569.
    float qHeight;  // the marched surface's height at q (q is off it by the march's tolerance)
    vec3 qDriver;   // its driver there, and the driver's slope over the placement's region
    vec2 placementSlope = ms_coarseSlope(p, frame, 2.0 * dpdx, 2.0 * dpdy, qHeight, qDriver);
    vec3 placementNormal = normalize(frame * vec3(-placementSlope, 1.0));
    MsSplit marched = ms_saveSplit();
    vec3 boxX = sub.x * gridX, boxY = sub.y * gridY;  // a sample's footprint
    ms_setWeightsAbove(boxX, boxY, false, MS_SAMPLE_WEIGHT_FLOOR, MS_SAMPLE_VARIANCE_FLOOR, 1.0);
#else
    float qHeight = ms_surfaceHeight(p);
    vec3 boxX = dpdx, boxY = dpdy;
#endif
    // What the 1/N footprint resolves beyond the whole one (0 with one sample): the samples show it.
    footprint.sampledHeightVariance = footprintHeightVariance - ms_heightVariance;
    footprint.sampledSlopeVariance = footprintSlopeVariance - ms_slopeVariance;
#ifndef MS_TRANSFER
    // The same for every sample: their unresolved variances are the 1/N footprint's, E[h'] = E[h'²] = 1.
    MsSurface unresolved = MsSurface(0.0, vec2(0.0), ms_heightVariance, vec3(ms_slopeVariance, 0.0, ms_slopeVariance),
                                     0.0, vec4(0.0, 0.0, 1.0, 1.0), vec3(0.0), ms_heightResidual, 0.0);
    MsMasking m = ms_masking(wo, unresolved, footprint);
    MsLight lights[SH_LIGHTS];  // each light's share under m, the same for every sample
#endif
    // how far below the macro horizon a light can still reach the marched point (0 on a plane; below)
#ifdef MS_SPHERE
    float horizonDip = sqrt(2.0 * max(ms_altitude(q) - ms_reliefRange().x, 0.0) / ms_radius);
#else
    float horizonDip = 0.0;
#endif
#ifndef MS_IRRADIANCE
    // The coarse surface's shadows: one profile per light above the horizon, traced from q before the samples
    // (traced inside their loop when first needed, its set-up ran for every sample: llvmpipe runs both sides
    // of a branch).
    vec4 shadows[SH_LIGHTS];
#ifdef MS_HORIZON_FACET_PER_PIXEL
    // the micro relief's light below the horizon, once per light (the band is blended per sample, below),
    // with the samples' split's statistics
    float facetVisibility[SH_LIGHTS];
    MsMasking facetMasking = ms_maskingStatistics(ms_unresolvedAbout(qDriver), footprint);
#endif
#if MS_SHADING_SAMPLES > 1
    MsSplit sampled = ms_saveSplit();
    ms_restoreSplit(marched);  // the marched surface casts them
#endif
    for (int j = 0; j < SH_LIGHTS; ++j) {
        shadows[j] = vec4(1e30, 0.0, 0.0, 0.0);
        if (j >= sh_lightCount) break;
        vec3 l = normalize(mat3(u_objectFromWorld) * sh_lightDirection[j]);
        vec3 wi = l * frame;
#ifndef MS_TRANSFER
        lights[j] = ms_light(m, wi);
#endif
#ifdef MS_HORIZON_PER_PIXEL
        lights[j].visibility = ms_horizonVisibility(lights[j].visibility, m, wo, wi, placementSlope);
#endif
#ifdef MS_HORIZON_FACET_PER_PIXEL
        facetVisibility[j] = ms_facetMicroVisibility(facetMasking, wo, wi, placementSlope);
#endif
        if (wi.z > -horizonDip) {
            shadows[j] = ms_shadowProfile(q, l, MS_SHADOW_STEPS, shadowReach, spacing / max(length(wi.xy), 0.1));
        }
    }
#if MS_SHADING_SAMPLES > 1
    ms_restoreSplit(sampled);
#endif
#endif
    // Each row's samples are averaged with their weights, and the rows with equal ones: a column's row is
    // the share of the pixel that its sub-ray stands for (on the plane, one row holds every sample).
    vec3 radiance = vec3(0.0), rowRadiance = vec3(0.0);
    float weightSum = 0.0;
#if MS_SHADING_SAMPLES > 1
    int sampleCount = ms_column ? MS_GRID_X * ms_rows : MS_SHADING_SAMPLES;  // a column's hit rows, or the grid
    int rowLength = ms_column ? MS_GRID_X : MS_SHADING_SAMPLES;
#else
    int sampleCount = 1;
    int rowLength = 1;
#endif
    for (int k = 0; k < MS_SHADING_SAMPLES; ++k) {
        vec3 sampleRadiance = vec3(0.0);
#if MS_SHADING_SAMPLES > 1
        vec2 offset = (vec2(k % MS_GRID_X, k / MS_GRID_X) + 0.5 - 0.5 * vec2(MS_GRID_X, MS_GRID_Y))
                    * (1.0 - gate) / vec2(MS_GRID_X, MS_GRID_Y);
#ifdef MS_TRIANGLE
        bool turned = ((int(gl_FragCoord.x) + int(gl_FragCoord.y)) & 1) == 1;  // every other pixel
        offset = (turned ? gate - 1.0 : 1.0 - gate) * MS_TRIANGLE_RADIUS * MS_TRIANGLE_OFFSETS[k];
#endif
        int row = ms_column ? min(k / MS_GRID_X, MS_RELIEF_RAYS - 1) : 0;
        if (ms_column) offset.y = 0.0;  // the row's sub-ray is at its height already
        vec3 rowMacro = ms_column ? ms_rowMacro[row] : p0;
        vec3 pk = ms_subpixelPoint(rowMacro + offset.x * gridXMacro + offset.y * gridYMacro, d,
                                   ms_column ? ms_rowPoint[row] : q, placementNormal, offset.x * gridX + offset.y * gridY);
        MsSurface s = ms_surfaceAt(ms_project(pk), frame);
        vec3 lag = pk - q;
        lag -= dot(lag, frame[2]) * frame[2];  // the sample's offset from q along the macro surface
#else
        MsSurface s = ms_surfaceAt(p, frame);
        vec3 lag = vec3(0.0);
#endif
        float textureVariance = ms_textureVariance;
#ifdef MS_TRANSFER
        MsMasking m = ms_masking(wo, s, footprint);
#endif
        vec2 visMean;
        vec3 visCov;
        // The fBm's visible slopes lean further towards the eye than D_s (Smith's) says: on it a fine facet on
        // the far side of a coarse hill is masked by the hill more often. Ray cast, D_s's shift is short by
        // 10 % at grazing views and right at 40° elevation (fractal_masking.py, slope_lean: its constants).
        // Where the coarse hills are geometry their masking is rendered, so the lean is scaled by the share
        // of the height variance that the statistics carry (1 far away).
        float statisticalShare = ms_heightVariance / max(ms_heightVariance + ms_coarseHeightVariance, 1e-30);
        float lean = statisticalShare * MS_SLOPE_LEAN * max(1.0 - wo.z / MS_SLOPE_LEAN_FADE, 0.0);
#ifdef MS_DRIVER_NODES
        MsNodes nodes = ms_driverNodes(wo, s, m, lean);
        float area = nodes.area;
        // D_s of the whole: the nodes' mixture
        visMean = mix(nodes.meanDown, nodes.meanUp, nodes.share);
        vec2 apart = nodes.meanUp - nodes.meanDown;
        visCov = mix(nodes.covDown, nodes.covUp, nodes.share)
               + nodes.share * (1.0 - nodes.share) * vec3(apart.x * apart.x, apart.x * apart.y, apart.y * apart.y);
#else
        float area = ms_visibleSlopes(wo, s.slope, s.slopeCov, visMean, visCov);  // and the sample's share, below
        visMean += lean * (visMean - s.slope);
#endif
#ifdef MS_TEXTURE_MAP
        c0 = ms_mapGaussian(u_textureGaussian, u_textureMap, s.r, textureVariance, u_textureWrap, u_textureRange);
#endif
#ifdef MS_SLOPE_MAP
        float visVarDir = dir.x * dir.x * visCov.x + 2.0 * dir.x * dir.y * visCov.y + dir.y * dir.y * visCov.z;
        cs = ms_mapGaussian(u_slopeGaussian, u_slopeMap, dot(visMean, dir), visVarDir, u_slopeWrap, u_slopeRange);
        vec4 csDerivative = ms_slopeColourDerivative(dot(visMean, dir), visVarDir);  // ∂C̄_s/∂μ, for lit colours
#endif
        float perturbVariance = u_perturb * u_perturb * textureVariance;
        // The view alone (ambient, environment light): Λ_i = 0, V̄ = 1.
#ifdef MS_HEIGHT_MAP
        ch = ms_heightColour(s, m, m.viewHeights, boxX, boxY, perturbVariance);
#endif
#ifdef MS_DRIVER_NODES
        vec4 colourShift = ms_nodeColourShift(nodes, ch);
        ch = max(ch + (2.0 * nodes.share - 1.0) * colourShift, 0.0);  // the nodes' colours, by their visible areas
#endif
        vec4 albedoView = ms_combine(c0, ch, cs);
#ifdef MS_IRRADIANCE
#ifdef MS_SLOPE_MAP
        // The slope colour where the environment's light falls (as ms_slopeColourUnderLight, per channel):
        // ms_combine is affine in C_s, so the term enters through its slope part.
        vec3 irradianceCov;
        vec3 irradiance = ms_filteredIrradianceMomentsSH(u_sh, MS_ENV_FROM_WORLD * worldFrame, visMean, visCov, dir,
                                                         irradianceCov);
        vec4 slopePart = ms_combine(c0, ch, cs + csDerivative) - albedoView;
        sampleRadiance += max(albedoView.rgb * irradiance + slopePart.rgb * irradianceCov, 0.0) / MS_PI;
#else
        sampleRadiance += albedoView.rgb * ms_filteredIrradianceSH(u_sh, MS_ENV_FROM_WORLD * worldFrame, visMean, visCov) / MS_PI;
#endif
#else
        sampleRadiance += albedoView.rgb * sh_ambient;
        for (int j = 0; j < SH_LIGHTS; ++j) {
            if (j >= sh_lightCount) break;
            vec3 l = normalize(mat3(u_objectFromWorld) * sh_lightDirection[j]);
            vec3 wi = l * frame;
            // At or below the macro horizon Smith's shadowing G1(wi) of the whole surface is 0; the ratio
            // V̄_t / V̄_c below of two vanishing visibilities is not. A plane takes no light from there, a
            // sphere the light that its tall points see (ms_facetMicroVisibility): a ray leaving the
            // marched point's altitude h at slope -μ dives μ²R/2 and meets the coarse relief (whose lowest
            // altitude is ms_reliefRange().x = -b) unless μ < sqrt(2(h + b)/R).
            if (wi.z <= -horizonDip) continue;
            float clearance = shadows[j].x + linearity * ((s.h - qHeight) - dot(shadows[j].yzw, lag));
            float lit = clearance > 0.0 ? 1.0 : 0.0;
#ifdef MS_TRANSFER
            MsLight light = ms_light(m, wi);
#if MS_SHADING_SAMPLES > 1
            // A marched row far from q (its offset times κ, ms_coarseFrequency of the samples' split, from
            // 0.5 to 2) is shadowed by Smith's statistics of the coarse surface, Φ(f/σ_c)^Λ_c(ω_i) at the
            // row's driver f (g is monotonic), not by q's profile: the tufts are narrower than the driver's
            // features, and the profile's first-order clearance does not reach that far (thirteenth session,
            // 128 px against 16-spp references: the moss's band below the macro horizon 7.2 -> 4.3 % too
            // bright, the sponge's bands 11.6 / 9.7 / 6.0 -> 9.4 / 6.4 / 5.0 %; 256 px, 64 spp: FLIP moss
            // 0.0794 -> 0.0791, sponge 0.0853 -> 0.0841, time within the noise). Not on Gaussian reliefs: the
            // grazing terrain's rows lost the per-pixel shadows that q's profile gets right (0.0473 ->
            // 0.0484).
            float own = row == 0 ? 1.0 : 1.0 - smoothstep(0.5, 2.0, length(lag) * ms_coarseFrequency);
            lit = mix(ms_visibility(s.driver, sqrt(footprint.marchedVariance), light.lambdaIC), lit, own);
#endif
#else
            MsLight light = lights[j];
#endif
            if (lit <= 0.0) continue;
#ifdef MS_DRIVER_NODES
            vec3 lambertUp = ms_lambertMoments(nodes.meanUp, nodes.covUp, wi);
            vec3 lambertDown = ms_lambertMoments(nodes.meanDown, nodes.covDown, wi);
            vec3 lambert = mix(lambertDown, lambertUp, nodes.share);
#else
            vec3 lambert = ms_lambertMoments(visMean, visCov, wi);  // Lambert averaged over D_s, Cov(s, L)
#endif
            float cosine = lambert.x;
            if (cosine <= 0.0) continue;
#ifdef MS_SLOPE_MAP
            vec4 csLit = ms_slopeColourUnderLight(cs, csDerivative, dot(dir, lambert.yz) / cosine);
#else
            vec4 csLit = cs;
#endif
#ifdef MS_HEIGHT_MAP
            ch = ms_heightColour(s, m, light.heights, boxX, boxY, perturbVariance);
#endif
#if defined(MS_SPHERE) && !defined(MS_HORIZON_PER_PIXEL)
#ifdef MS_HORIZON_FACET_PER_PIXEL
            // the facet's visibility as per pixel above, blended over this sample's band (a transfer
            // function's varies with the sample's statistics)
            light.visibility = ms_horizonBlend(light.visibility, facetVisibility[j], m.sigmaT, wi);
#else
            light.visibility = ms_horizonVisibility(light.visibility, m, wo, wi, s.slope);
#endif
#endif
#ifdef MS_DRIVER_NODES
            // each node's colour under its own light
            ch = max(ch + colourShift * (nodes.share * lambertUp.x - (1.0 - nodes.share) * lambertDown.x) / cosine, 0.0);
#endif
            vec4 albedo = light.visibility * ms_combine(c0, ch, csLit);
            sampleRadiance += lit * albedo.rgb * cosine * sh_lightColour[j];
        }
#endif
        // the sample's share of the pixel: its facets' area projected towards the eye, E[(o_z - s·o_xy)⁺] over
        // the sample's slopes N(s̄, Σ) (ms_visibleSlopes' normalisation). Only the coarse slope's
        // (o_z - s̄·o_xy)⁺ gave no share to samples whose coarse facet turns away while their micro-facets
        // still show, so at grazing views
        // the facets that face the eye, red on the snake, were over-weighted (its top rows +0.0044 red per
        // pixel; now +0.0031). Measured (256 px, 64-spp references, surface-filter FLIP before -> after, time
        // unchanged): height sphere 0.0509 -> 0.0499, slope sphere 0.0775 -> 0.0767, snake 0.0705 -> 0.0698.
        // That share is right for a sample whose slope is independent of the marched point q's. But q is a
        // point the eye sees, so its facet already leans towards the eye, and a sample close to q lies on
        // that facet: weighting it by the area again counted the preference twice, and where the relief
        // stands out of the pixel the samples, which close up towards q there, made the terrains' near
        // field 3 % too dark (luminance -0.005 on micro-heights-terrain). The weight is area^(1 - ρ), ρ the
        // correlation of the sample's coarse slope with q's, exp(-(c κ |δ|)² / 2) for the sample's offset δ
        // along the macro surface and the coarse RMS frequency κ: 1 on q's facet, the area for a sample
        // independent of q. c = MS_SLOPE_DECORRELATION; docs/microsurface-history.md has the measurements.
        float decorrelation = MS_SLOPE_DECORRELATION * ms_coarseFrequency * length(lag);
        float correlation = exp(-0.5 * decorrelation * decorrelation);  // 1 with one sample: its weight cancels
        // (every sample's facets facing away from the eye, area 0: a near miss of the march; their plain mean)
        float weight = pow(max(area, 1e-30), 1.0 - correlation);
        rowRadiance += weight * sampleRadiance;
        weightSum += weight;
        if ((k + 1) % rowLength == 0 || k + 1 >= sampleCount) {  // the row's last sample
            radiance += rowRadiance / weightSum;
            rowRadiance = vec3(0.0);
            weightSum = 0.0;
        }
        if (k + 1 >= sampleCount) break;  // at the end of the body, as heightfield.glsl's octave loops
    }
    radiance /= float(ms_column ? ms_rows : 1);
#endif
    return radiance;
}

void main() {
    vec3 p0 = v_solid;
    vec3 dpdxMacro = dFdx(p0);
    vec3 dpdyMacro = dFdy(p0);
    vec3 dpdx = dpdxMacro;
    vec3 dpdy = dpdyMacro;
    vec3 d = u_eyeObject.w > 0.5 ? normalize(p0 - u_eyeObject.xyz) : normalize(u_eyeObject.xyz);
#if defined(MODE_POINT) || defined(MODE_MARCH_STEPS)
    ms_setWeights(dpdx, dpdy, true);
#else
    ms_reliefFootprint(p0, d, dpdx, dpdy);
    ms_setWeights(dpdx, dpdy, false);
#endif
    vec3 o = u_eyeObject.w > 0.5 ? u_eyeObject.xyz : p0 - d * (4.0 * (ms_radius + ms_heightBound) + 1.0);
    vec3 slab = ms_slab(o, d, ms_reliefRange());
    if (slab.y < slab.x) discard;
#if !defined(MODE_POINT) && !defined(MODE_MARCH_STEPS)
    vec3 up = ms_macroNormal(p0);
    vec3 upAcross = up - dot(up, d) * d;  // what an offset along up moves the ray across itself
    float across2 = max(dot(upAcross, upAcross), 1e-6);
    bool perspective = u_eyeObject.w > 0.5;
    vec3 ex = dpdxMacro - dot(dpdxMacro, d) * d, ey = dpdyMacro - dot(dpdyMacro, d) * d;
    // the pixel's extent across the ray along upAcross, in offsets along up: of the direction (perspective,
    // per unit distance) or of the origin (orthographic)
    float extent = (abs(dot(ex, upAcross)) + abs(dot(ey, upAcross))) / across2;
    if (perspective) extent /= length(p0 - o);
    // The primary rays' least step (heightfield.glsl, ms_primaryStep): MS_PRIMARY_STEP of the pixel's
    // footprint along the ray, its extent along up over the ray's rate of descent along up (at most
    // 1 / MS_PRIMARY_STEP_FLOOR times the extent, at grazing views and silhouettes).
    ms_primaryStep = MS_PRIMARY_STEP * (perspective ? vec2(0.0, extent) : vec2(extent, 0.0))
                   / max(abs(dot(d, up)), MS_PRIMARY_STEP_FLOOR);
#endif
#if defined(MODE_SURFACE_FILTER) && MS_RELIEF_RAYS > 1
    // Where the relief's heights span more of the pixel, as the eye sees them, than the grid's rows lie apart
    // (ms_reliefParallax > 1/rows), one ray would decide which ridge the whole pixel shows, and its plane where
    // every sample lies: the grid's MS_GRID_Y rows are then sub-rays spread over the pixel's extent along the
    // macro normal, marched as one column (ms_marchColumn), each row's samples placed across the column
    // through its own hit and weighted among themselves (ms_shade), and the rows averaged. Elsewhere the
    // column is the centre ray, and the whole grid lies on the plane through its hit. Measured (256 px,
    // 64-spp references, surface-filter FLIP and frame time ÷ naive round-robin, the grid on the plane ->
    // marched rows): micro-heights-terrain 0.0813 -> 0.0647 (1.25 -> 1.43), micro-heights-grazing 0.0528 ->
    // 0.0473 (1.20 -> 1.38), micro-irradiance-terrain 0.0389 -> 0.0314 (1.29 -> 1.55), micro-moss-sphere
    // 0.0890 -> 0.0793, micro-sponge-sphere 0.0967 -> 0.0853 (1.62 -> 1.9-2.0); micro-slopes-terrain 0.0845
    // with 3 x 3 samples on the plane -> 0.0742 with 2 x 2 and marched rows (1.42 -> 1.43). The textured
    // spheres keep their images (their relief spans less than half a pixel) and pay 0.03-0.06 x for the
    // column's code. A column wherever the relief gate is open (also at near-normal views, where the rows
    // fall on one point) took micro-heights-sphere 0.0503 -> 0.0548; one weighting over all the rows'
    // samples (as on the plane) took the terrains back up (irradiance 0.0414): a marched row is a visible
    // point already, so its facets' projected area is not a weight again.
    int rays = ms_reliefParallax > 1.0 / float(MS_RELIEF_RAYS) ? MS_RELIEF_RAYS : 1;
    // sub-ray k's (origin, direction) offsets along up: lowest + k stride, spread evenly over the extent
    vec2 across = perspective ? vec2(0.0, extent) : vec2(extent, 0.0);
    vec2 lowest = (0.5 / float(rays) - 0.5) * across, stride = across / float(rays);
    float hits[MS_RELIEF_RAYS];
    ms_marchColumn(o, d, up, lowest, stride, rays, MS_MAX_STEPS, hits);
    float distance = perspective ? length(p0 - o) : 1.0;  // offsets of the direction move the macro point by this
    ms_rows = 0;
    vec3 firstOrigin = o, firstDirection = d;  // row 0's sub-ray, and its hit
    float firstHit = -1.0;
    for (int k = 0; k < MS_RELIEF_RAYS; ++k) {
        if (hits[k] >= 0.0) {  // else a sub-ray past the silhouette
            vec2 offset = lowest + float(k) * stride;
            vec3 ok = o + offset.x * up, dk = d + offset.y * up;
            ms_rowPoint[ms_rows] = ok + hits[k] * dk;
            ms_rowMacro[ms_rows] = p0 + (offset.x + distance * offset.y) * up;
            if (ms_rows == 0) {
                firstOrigin = ok;
                firstDirection = dk;
                firstHit = hits[k];
            }
            ms_rows += 1;
        }
        if (k + 1 >= rays) break;  // at the end of the body, as heightfield.glsl's octave loops
    }
    if (ms_rows == 0) discard;
    ms_column = rays > 1;
    // the screen axes of ms_shade's grid (per pixel: macro, and on the relief footprint); for a column X
    // across it and Y along it, the column's screen direction c being up's, in the basis (ex, ey)
    vec3 axisXMacro = dpdxMacro, axisYMacro = dpdyMacro, axisX = dpdx, axisY = dpdy;
    if (ms_column) {
        mat2 gram = mat2(dot(ex, ex), dot(ex, ey), dot(ex, ey), dot(ey, ey));
        vec2 c = inverse(gram) * vec2(dot(ex, upAcross), dot(ey, upAcross));
        c = dot(c, c) > 1e-24 ? normalize(c) : vec2(0.0, 1.0);
        axisXMacro = -c.y * dpdxMacro + c.x * dpdyMacro;
        axisYMacro = c.x * dpdxMacro + c.y * dpdyMacro;
        axisX = -c.y * dpdx + c.x * dpdy;
        axisY = c.x * dpdx + c.y * dpdy;
    }
    float len = length(firstDirection);
    vec3 radiance = ms_shade(firstOrigin, firstDirection / len, firstHit * len, p0, axisXMacro, axisYMacro, axisX,
                             axisY, MS_RELIEF_CLOSING * ms_reliefGate);
#else
    // One ray: the column's code marched for one sub-ray cost micro-snake-sphere 1.56 -> 1.51 and
    // micro-slopes-sphere 1.14 -> 1.11 x naive's frame (7 round-robin rounds), with the same images to 6e-5.
    float t = ms_march(o, d, slab, MS_MAX_STEPS, true);
    if (t < 0.0) discard;
    vec3 radiance = ms_shade(o, d, t, p0, dpdxMacro, dpdyMacro, dpdx, dpdy, MS_RELIEF_CLOSING * ms_reliefGate);
#endif
#ifdef MODE_MARCH_STEPS
    radiance = vec3(float(ms_steps) / 256.0, 0.0, 0.0);  // steps of the primary and shadow rays, /256
#endif
    o_colour = vec4(radiance, 1.0);
}
