// heightfield.glsl -- procedural microsurface height fields (microsurface/heightfield.py), their split into
// real (ray-marched) geometry and Gaussian statistics over a pixel footprint, and the ray marcher that
// finds the visible point and traces shadows (Heitz et al. 2014 §5, §9: real microgeometry close up,
// filtered statistics far away, a continuous transition).
//
//   h(p) = Σ_k w_k a_k n(f_k R_lat p + o_k)   with w_k = 1 (point, reference) or β_k (coarse surface)
//
// Two fractals share the uniform arrays: octaves [0, 8) are the height field, [8, 16) the procedural
// texture that drives C₀ and the height perturbation r, present with the define MS_TEXTURE_FRACTAL (without
// it r = 0 and its octaves are not visited: llvmpipe ran a masked pass of their loops). Per fragment,
// ms_setWeights() fills the global ms_weight[] and the residual statistics (ms_heightVariance,
// ms_slopeVariance, ms_textureVariance), for the footprint that ms_reliefFootprint() puts on the visible
// relief.
// Macro surface: the xz-plane (y = 0, normal +y), or with MS_SPHERE a sphere of radius ms_radius.
// Uniforms: ms_octave[i] = (a, f), ms_octaveOffset[i], ms_heightOctaves, ms_textureOctaves,
// ms_latticeFromObject (mat3), ms_radius; with MS_TRANSFER the height is g(fractal) (microsurface/transfer).

#include "glsl/common/noise.glsl"
#include "procedural/noise_stats.glsl"

#define MS_MAX_OCTAVES 8
// Loops over the octaves run to a count given per material (at least 1) and test it at the end of their
// body, as the marchers test their exits: llvmpipe does not unroll them, and a test at the top ran one more
// body after the last octave, masked (a noise evaluation per march step and per fractal: every marching
// mode 1-7 % slower).
// The slots of ms_weight[]: the height octaves, and the texture's with MS_TEXTURE_FRACTAL.
#ifdef MS_TEXTURE_FRACTAL
#define MS_WEIGHT_SLOTS (2 * MS_MAX_OCTAVES)
#else
#define MS_WEIGHT_SLOTS MS_MAX_OCTAVES
#endif
#define MS_NOISE_BOUND 1.0
// Slope bound per unit a_k f_k used to size march steps: |∇n| < 3.2 always, but over 2.5 in < 0.1 % of
// points; an overshoot is caught (gap < 0) and refined, so the relaxed bound only risks clipping peaks
// thinner than one step (measured on the presets: see tests/test_microsurface.py).
#define MS_SLOPE_BOUND 2.5
// Over-relaxed steps (x1.5): 1.5x fewer steps; against a dense scan no first hit of 1600 rays at 3-60°
// elevation was missed (x2 missed 0.5 %).
#ifndef MS_RELAX
#define MS_RELAX 1.5
#endif
#define MS_NOISE_VARIANCE 0.0731
#define MS_GRADIENT_VARIANCE 0.50

uniform vec2 ms_octave[2 * MS_MAX_OCTAVES];
uniform vec3 ms_octaveOffset[2 * MS_MAX_OCTAVES];
uniform float ms_octaveMasking[MS_MAX_OCTAVES];  // the height octaves' masking weights (fractal_masking.py)
uniform int ms_heightOctaves;
uniform int ms_textureOctaves;
uniform mat3 ms_latticeFromObject;
uniform float ms_radius;

float ms_weight[MS_WEIGHT_SLOTS];
// γ_k of the height octaves (0 for the texture's slots): the share of an octave's gradient whose variation
// over the footprint is real (noise_stats.py); Σ γ_k ∇h_k is the height's linear part over the footprint
float ms_linearWeight[MS_WEIGHT_SLOTS];
// The weight of an octave's slope in the slopes that shade surface-filter's samples. Where the statistics
// carry the pixel it is the rendered surface's β₁, the footprint's mean correlation with its centre. Where
// the relief stands out of the pixel the gate gives the rendered surface β (ms_meanFraction): that is about
// what the pixel sees of the relief (silhouettes, far peaks, shadows), while a sample's slope colours and
// light are a prediction of the slopes over its footprint from its centre, which β₁ makes. The gate lifts
// the slopes' weight only MS_SLOPE_WEIGHT_GATE of the way from β₁ to β: 1 gives them the rendered surface's
// weights (until 2026-12-05); 0, β₁ throughout, darkened the heights terrain's near field (lower half
// -0.0015 -> -0.0033 in mean luminance at 256 px); 0.5 was best of 0, 0.25, 0.5 and 1 on the four terrains
// (a fit; microsurface.frag, MsSurface, has the figures). 0 for the texture's slots.
float ms_slopeWeight[MS_WEIGHT_SLOTS];
#ifndef MS_SLOPE_WEIGHT_GATE
#define MS_SLOPE_WEIGHT_GATE 0.5
#endif
float ms_heightVariance;   // σ_h² of the unresolved octaves
float ms_heightResidual;   // what is left of it beyond the expected variance of their linear part
float ms_slopeVariance;    // per tangent axis: Σ = ms_slopeVariance · I
float ms_shadingSlopeVariance;  // the same about the slopes of weights ms_slopeWeight (the rest of each octave's)
float ms_coarseHeightVariance;  // the same of the coarse (rendered) surface: Σ w² a² Var n
float ms_coarseSlopeVariance;
float ms_coarseFrequency;  // sqrt(Σ w² a² f⁴ / Σ w² a² f²): how fast the coarse surface's slopes change
// Smith's Λ for a fractal: the slope variance it sees, octave k's slopes weighted by ms_octaveMasking[k]
// = g(log2(f_k / f_0)) (microsurface/fractal_masking.py: G, fitted to ray casts)
float ms_maskingSlopeVariance;        // of the whole surface
float ms_coarseMaskingSlopeVariance;  // of the coarse (rendered) surface
float ms_textureVariance;  // σ² of the unresolved texture octaves
// The octaves up to the last one of non-zero weight, height and texture (ms_setWeightsAbove can leave the
// finest ones wholly to the statistics): the shading samples' loops over the rendered surface stop there.
int ms_weightedHeightOctaves = MS_MAX_OCTAVES;
int ms_weightedTextureOctaves = MS_MAX_OCTAVES;
float ms_heightBound;      // max |h_c|: the slab the marcher searches
float ms_slopeBound;       // step-size bound of |∇h_c|
int ms_steps = 0;          // march steps taken by this fragment (the march-steps diagnostic)

#ifdef MS_TRANSFER
// h = g(f) with g read from the transfer table (microsurface/transfer.glsl); row σ = 0 is g itself.
#include "microsurface/transfer.glsl"
uniform sampler2D u_transferTable;  // @table the transfer function's moments (Heitz et al. 2014 §7) with u_transferRange = (mu_lo, mu_hi, sigma_max) in driver units; u: the driver's mean μ over the footprint, (μ - mu_lo)/(mu_hi - mu_lo), texel i at μ = mu_lo + (i + 0.5)(mu_hi - mu_lo)/width (CLAMP_TO_EDGE: the edge columns beyond); v: the driver's standard deviation σ, row j at σ = sigma_max j/(height - 1) (read at v = (σ/sigma_max (height - 1) + 0.5)/height; σ > sigma_max reads the last row); RGBA: (E[g], E[g²], E[g'], E[g'²]) of g under N(μ, σ²), g in driver units (heights are u_transferScale g), row 0 holding (g, g², g', g'²) themselves; LINEAR, no MIP; not colours
uniform vec3 u_transferRange;
uniform float u_transferScale;  // h = scale · g(f): g in driver units, h in object units
uniform vec2 u_transferHeights; // (low, high): the least and greatest h over the driver range, each widened to include 0 (max |h| = max(-low, high))
uniform vec2 u_transferSlopes;  // (max |dh/df| over the driver range, the RMS of dh/df over the driver f ~ N(0, σ_f²) of all the octaves)
float ms_transferSigma;         // σ_f of the unresolved driver: the coarse surface is ḡ(f_c, σ_f)

// (E[h], E[h²], E[h'], E[h'²]) for h = scale · g(f), f ~ N(mu, sigma²).
vec4 ms_transfer(float mu, float sigma) {
    float s = u_transferScale;
    return ms_transferMoments(u_transferTable, mu, sigma, u_transferRange) * vec4(s, s * s, s, s * s);
}
#endif

float ms_reliefGate = 0.0;  // g of the last ms_reliefFootprint: 1 where the coarse relief stands out of the pixel
// The same ratio for the relief as the eye sees it, σ_c sin θ_o / P: its heights' extent across the ray (0 at
// a normal view, where relief taller than a pixel hides nothing). surface-filter marches the rows of its
// grid where it exceeds 1/rows (microsurface.frag, main()); 0 with MS_MACRO_FOOTPRINT.
float ms_reliefParallax = 0.0;

// The weight w of an octave in the coarse surface, for a box footprint with axes jx, jy in its lattice
// units (noise_stats.glsl fits). Where the statistics carry the pixel it is β₁, the footprint's mean
// correlation with its centre: the heights in the footprint then spread about β₁ n(c) with the variance
// (1 - β₁²) σ_n² that ms_setWeights leaves to the statistics (tests/test_microsurface.py). Where the relief
// stands out of the pixel (ms_reliefGate -> 1) it is β of the split with the curvature term, larger
// (0.86 against 0.58 at one cell), which keeps more of the relief as geometry. Measured (256 px, 64-spp
// references, surface-filter FLIP with β everywhere -> this): micro-heights-sphere 0.0513 -> 0.0474,
// micro-slopes-sphere 0.0832 -> 0.0728, micro-snake-sphere 0.0776 -> 0.0661; the terrains, moss and
// sponge within 0.0007. β₁ everywhere also took the slope sphere to 0.0729, but the grazing terrain's far
// field from 0.0501 to 0.0618 (its relief stands out of the pixel there, and the statistics render a
// smoother horizon than the reference's few visible peaks).
// fractions: ns_splitFractions' (β, β₁, γ) of the octave's footprint.
float ms_meanFraction(vec3 fractions) {
    return mix(fractions.y, fractions.x, ms_reliefGate);
}

// ns_splitFractions for footprint axes jx, jy in an octave's lattice cells.
vec3 ms_splitFractions(vec3 jx, vec3 jy) {
    return ns_splitFractions(dot(jx, jx), dot(jy, jy));
}

// full = true: every octave is real geometry (point mode and each reference pass). An octave whose weight
// w would be below floorWeight, and whose weighted variance w²a² below floorShare times the first octave's
// a₀², gets 0: all of its variance goes to the statistics, and its gradient to none of the linear or
// shading parts. With fade < 1 the weight is not cut there but faded out, times smoothstep(fade, 1, keep)
// with keep = max(w / floorWeight, w a / (√floorShare a₀)) (keep < 1 is under both floors), so that the
// surface is continuous as the footprint grows; fade = 1 is the hard cut.
void ms_setWeightsAbove(vec3 dpdx, vec3 dpdy, bool full, float floorWeight, float floorShare, float fade) {
    ms_heightVariance = 0.0;
    ms_heightResidual = 0.0;
    ms_slopeVariance = 0.0;
    ms_shadingSlopeVariance = 0.0;
    ms_coarseHeightVariance = 0.0;
    ms_coarseSlopeVariance = 0.0;
    ms_maskingSlopeVariance = 0.0;
    ms_coarseMaskingSlopeVariance = 0.0;
    ms_textureVariance = 0.0;
    ms_heightBound = 0.0;
    ms_slopeBound = 0.0;
    float curvatureMoment = 0.0;
    vec3 lx = ms_latticeFromObject * dpdx;
    vec3 ly = ms_latticeFromObject * dpdy;
    float footprint2 = dot(lx, lx) + dot(ly, ly);  // ρ1² + ρ2² in lattice units of frequency 1
    ms_weightedHeightOctaves = 0;
    ms_weightedTextureOctaves = 0;
    float heightFirst = ms_octave[0].x, textureFirst = ms_octave[MS_MAX_OCTAVES].x;  // a₀ of each fractal
    // The slots of octaves that a fractal does not have are cleared first, and the loop visits only the
    // fractals' own: it had run over every slot, skipping the empty ones with `continue`, which llvmpipe
    // runs masked at the cost of a whole octave (its split's fits and the bookkeeping below). Measured
    // (256 px, 7 round-robin rounds, time ÷ naive before -> after, the same images bit for bit):
    // micro-snake-sphere (7 of 16 slots its own) 1.48 -> 1.40, micro-heights-sphere (5 of 8) 1.69 -> 1.61,
    // micro-slopes-sphere 1.12 -> 1.05, micro-irradiance-terrain 1.39 -> 1.38; naive's frames the same
    // (what it does not read of the split is not computed).
    for (int i = 0; i < MS_WEIGHT_SLOTS; ++i) {
        ms_weight[i] = 0.0;
        ms_linearWeight[i] = 0.0;
        ms_slopeWeight[i] = 0.0;
    }
    int i = 0;  // the slot: height octaves from 0, the texture's from MS_MAX_OCTAVES
    for (int n = 0; n < MS_WEIGHT_SLOTS; ++n) {
        bool height = i < MS_MAX_OCTAVES;
        int k = height ? i : i - MS_MAX_OCTAVES;
        bool last = k + 1 >= (height ? ms_heightOctaves : ms_textureOctaves);
        vec2 af = ms_octave[i];
        vec3 fractions = ms_splitFractions(af.y * lx, af.y * ly);  // (β, β₁, γ), one evaluation
        float w = full ? 1.0 : ms_meanFraction(fractions);
        float first = height ? heightFirst : textureFirst;
        float keep = max(w / max(floorWeight, 1e-30), w * af.x / max(sqrt(floorShare) * first, 1e-30));
        float kept = fade < 1.0 ? smoothstep(fade, 1.0, keep) : step(1.0, keep);
        w *= kept;
        if (w > 0.0) {
            if (height) ms_weightedHeightOctaves = k + 1;
            else ms_weightedTextureOctaves = k + 1;
        }
        ms_weight[i] = w;
        float residual = (1.0 - w * w) * af.x * af.x;
        if (height) {
            ms_heightVariance += residual * MS_NOISE_VARIANCE;
            // the linear part's expected variance over a box footprint, γ² a² (ρ1² + ρ2²) Var(∂n) / 12, is
            // taken out of the residual (and given back per point by ms_fractalGradLinear's gradient)
            float gamma = full || w <= 0.0 ? 0.0 : fractions.z * kept;
            ms_linearWeight[i] = gamma;
            float linear = gamma * gamma * af.x * af.x * MS_GRADIENT_VARIANCE * af.y * af.y * footprint2 / 12.0;
            ms_heightResidual += max(residual * MS_NOISE_VARIANCE - linear, 0.0);
            ms_slopeVariance += residual * af.y * af.y * MS_GRADIENT_VARIANCE;
            float slopeWeight = full ? 1.0 : mix(fractions.y, fractions.x, MS_SLOPE_WEIGHT_GATE * ms_reliefGate);
            // under the weight floor the octave's slopes shade through the statistics alone, also where its
            // height is kept for its variance: a slope decorrelates over a shorter distance than the height
            // (far away on micro-snake-sphere, 64-spp references, FLIP at 10 units 0.0634 with the slope kept,
            // 0.0616 without; the height sphere at 24 units 0.0524 and 0.0518)
            if (w <= 0.0 || w < floorWeight) slopeWeight = 0.0;
            ms_slopeWeight[i] = slopeWeight;
            ms_shadingSlopeVariance += (1.0 - slopeWeight * slopeWeight) * af.x * af.x * af.y * af.y * MS_GRADIENT_VARIANCE;
            ms_coarseHeightVariance += w * w * af.x * af.x * MS_NOISE_VARIANCE;
            ms_coarseSlopeVariance += w * w * af.x * af.x * af.y * af.y * MS_GRADIENT_VARIANCE;
            curvatureMoment += w * w * af.x * af.x * af.y * af.y * af.y * af.y * MS_GRADIENT_VARIANCE;
            float masking = ms_octaveMasking[k] * af.x * af.x * af.y * af.y * MS_GRADIENT_VARIANCE;
            ms_maskingSlopeVariance += masking;
            ms_coarseMaskingSlopeVariance += w * w * masking;
            ms_heightBound += w * af.x * MS_NOISE_BOUND;
            ms_slopeBound += w * af.x * af.y * MS_SLOPE_BOUND;
        } else {
            ms_textureVariance += residual * MS_NOISE_VARIANCE;
        }
        if (last && (!height || MS_WEIGHT_SLOTS == MS_MAX_OCTAVES)) break;  // at the end of the body
        i = last ? MS_MAX_OCTAVES : i + 1;  // after the height octaves, the texture's
    }
    ms_coarseFrequency = sqrt(curvatureMoment / max(ms_coarseSlopeVariance, 1e-30));
#ifdef MS_TRANSFER
    ms_transferSigma = sqrt(ms_heightVariance);
    ms_heightBound = max(-u_transferHeights.x, u_transferHeights.y);
    ms_slopeBound *= u_transferSlopes.x;
#endif
}

// The rendered (marched) surface's split. Its octaves under a floor are faded out of the geometry into the
// statistics, as the shading samples' are (microsurface.frag, MS_SAMPLE_WEIGHT_FLOOR) but continuously, and
// the loops over the octaves (the march's gap, the shadow rays', the samples') stop at the last one kept
// (ms_weightedHeightOctaves): llvmpipe runs an octave whose weight is 0 masked, at the full cost of its
// noise, unless the loop ends before it. Far from the eye the finest octaves kept a few percent of
// their height (β₁ of a footprint 2-5 cells across), a fraction of a pixel, and their noise was most
// of what the march cost. Fading from keep 1 to 0.5 (β₁ 0.2 to 0.1 for a small octave) leaves no
// step in the rendered surface as the footprint grows. Measured (twenty-ninth session; 256 px, 64-spp
// references, round-robin in one process, 5 rounds, without -> with the floor; frame times of naive and
// surface-filter, FLIP of every filtered mode within 0.0006): micro-heights-sphere 80 -> 60 and 120 -> 102
// ms, micro-slopes-sphere 81 -> 61 and 88 -> 70 ms, micro-snake-sphere 74 -> 65 and 108 -> 98 ms; the
// terrains, whose near field is geometry, the moss and the sponge within 2 %. Both modes gain about the
// same milliseconds, so the ratio of surface-filter's frame to naive's rises (height sphere 1.50 -> 1.68,
// snake 1.45 -> 1.51, slope sphere 1.09 -> 1.15).
#ifndef MS_MARCH_WEIGHT_FLOOR
#define MS_MARCH_WEIGHT_FLOOR 0.2
#endif
#ifndef MS_MARCH_VARIANCE_FLOOR
#define MS_MARCH_VARIANCE_FLOOR 0.01
#endif
#ifndef MS_MARCH_FLOOR_FADE
#define MS_MARCH_FLOOR_FADE 0.5
#endif
void ms_setWeights(vec3 dpdx, vec3 dpdy, bool full) {
    ms_setWeightsAbove(dpdx, dpdy, full, MS_MARCH_WEIGHT_FLOOR, MS_MARCH_VARIANCE_FLOOR, MS_MARCH_FLOOR_FADE);
}

// What the marcher and the shadow rays read of a split (ms_setWeights): saved, a split is restored with
// register moves instead of a second pass of ms_setWeights over every octave.
struct MsSplit {
    float weight[MS_WEIGHT_SLOTS];
    ivec2 weightedOctaves;
    float heightBound;
    float slopeBound;
    float coarseSlopeVariance;  // the shadow profile's step bound (ms_shadowProfile)
    float transferSigma;
};

MsSplit ms_saveSplit() {
    float transferSigma = 0.0;
#ifdef MS_TRANSFER
    transferSigma = ms_transferSigma;
#endif
    return MsSplit(ms_weight, ivec2(ms_weightedHeightOctaves, ms_weightedTextureOctaves), ms_heightBound, ms_slopeBound,
                   ms_coarseSlopeVariance, transferSigma);
}

void ms_restoreSplit(MsSplit split) {
    ms_weight = split.weight;
    ms_weightedHeightOctaves = split.weightedOctaves.x;
    ms_weightedTextureOctaves = split.weightedOctaves.y;
    ms_heightBound = split.heightBound;
    ms_slopeBound = split.slopeBound;
    ms_coarseSlopeVariance = split.coarseSlopeVariance;
#ifdef MS_TRANSFER
    ms_transferSigma = split.transferSigma;
#endif
}

// Σ_k w_k a_k n(f_k R p + o_k) over octaves [first, first + count). The loops over octaves break at the end
// of their body, so a count of 0 (a split that keeps none: ms_weighted*Octaves) visits the first, whose
// weight is 0, and adds nothing.
float ms_fractal(vec3 p, int first, int count) {
    vec3 lp = ms_latticeFromObject * p;
    float value = 0.0;
    for (int k = 0; k < MS_MAX_OCTAVES; ++k) {
        int i = first + k;
        if (ms_weight[i] > 0.0) {
            value += ms_weight[i] * ms_octave[i].x * nz_noise(ms_octave[i].y * lp + ms_octaveOffset[i]);
        }
        if (k + 1 >= count) break;  // at the end of the body (MS_MAX_OCTAVES)
    }
    return value;
}

// (∇ in object space, value) of octave i, a_i n(f_i R p + o_i), unweighted; lp = R p.
vec4 ms_octaveGrad(vec3 lp, int i) {
    vec4 n = nz_noiseGrad(ms_octave[i].y * lp + ms_octaveOffset[i]);
    float a = ms_octave[i].x;
    return vec4(a * ms_octave[i].y * (n.xyz * ms_latticeFromObject), a * n.w);
}

// (∇ in object space, value) of the same sum, in `linear` Σ_k γ_k ∇(a_k n_k) (ms_linearWeight): the
// gradient whose variation over the footprint of the last split is its linear part, and in `shading`
// Σ_k ms_slopeWeight[k] ∇(a_k n_k): the slopes that shade a surface-filter sample.
vec4 ms_fractalGradLinear(vec3 p, int first, int count, out vec3 linear, out vec3 shading) {
    vec3 lp = ms_latticeFromObject * p;
    vec4 result = vec4(0.0);
    linear = vec3(0.0);
    shading = vec3(0.0);
    for (int k = 0; k < MS_MAX_OCTAVES; ++k) {
        int i = first + k;
        if (ms_weight[i] > 0.0) {
            vec4 octave = ms_octaveGrad(lp, i);
            result += ms_weight[i] * octave;
            linear += ms_linearWeight[i] * octave.xyz;
            shading += ms_slopeWeight[i] * octave.xyz;
        }
        if (k + 1 >= count) break;  // at the end of the body (MS_MAX_OCTAVES)
    }
    return result;
}

vec4 ms_fractalGrad(vec3 p, int first, int count) {
    vec3 linear, shading;
    return ms_fractalGradLinear(p, first, count, linear, shading);
}

// The slope (macro tangent frame) at p of the coarse surface that a footprint (dpdx, dpdy) keeps: the height
// octaves weighted as ms_setWeights would weight them for that footprint, without its floor (with a transfer
// function, times E[g'] at the current split's σ_f), without changing the current split; the footprint is to
// be no smaller than the current split's, whose last kept octave ends the loop. In `height`, from the same noise
// evaluations, the current split's surface height at p (ms_surfaceHeight), and in `driver` the driver f
// there and the footprint's ∇f (the same as height and slope without a transfer function).
vec2 ms_coarseSlope(vec3 p, mat3 frame, vec3 dpdx, vec3 dpdy, out float height, out vec3 driver) {
    vec3 lx = ms_latticeFromObject * dpdx;
    vec3 ly = ms_latticeFromObject * dpdy;
    vec3 lp = ms_latticeFromObject * p;
    vec4 fg = vec4(0.0);
    height = 0.0;
    for (int k = 0; k < MS_MAX_OCTAVES; ++k) {
        float f = ms_octave[k].y;
        vec4 octave = ms_octaveGrad(lp, k);
        fg += ms_meanFraction(ms_splitFractions(f * lx, f * ly)) * octave;
        height += ms_weight[k] * octave.w;
        if (k + 1 >= ms_weightedHeightOctaves) break;  // at the end of the body (MS_MAX_OCTAVES)
    }
    driver = vec3(height, dot(fg.xyz, frame[0]), dot(fg.xyz, frame[1]));
#ifdef MS_TRANSFER
    fg.xyz *= ms_transfer(fg.w, ms_transferSigma).z;  // ∇E[g(f)] = E[g'] ∇f
    height = ms_transfer(height, ms_transferSigma).x;
#endif
    return vec2(dot(fg.xyz, frame[0]), dot(fg.xyz, frame[1]));
}

// The standard deviation of the coarse surface's slope along any tangent direction (the current split; with a
// transfer function h = g(f), times the RMS of g' over the driver's heights: f and ∇f are independent at a
// point of a Gaussian field, so Var(∇h·δ) = E[g'²] Var(∇f·δ). Until the sixteenth session it was times the
// bound on |g'|, 1.8x (moss) and 1.7x (sponge) the RMS: the shadow profile's reach was 0.76 of the slab's
// half-height on the moss, and the profile 0.9x naive's frame there).
float ms_coarseSlopeDeviation() {
    float deviation = sqrt(ms_coarseSlopeVariance);
#ifdef MS_TRANSFER
    deviation *= u_transferSlopes.y;
#endif
    return deviation;
}

// --- the macro surface ----------------------------------------------------------------------------
#ifdef MS_SPHERE
vec3 ms_project(vec3 q) { return ms_radius * normalize(q); }
vec3 ms_macroNormal(vec3 q) { return normalize(q); }
float ms_altitude(vec3 q) { return length(q) - ms_radius; }
// (tangent, bitangent) completing the normal n to a right-handed frame (Duff et al. 2017).
mat3 ms_macroFrame(vec3 q) {
    vec3 n = normalize(q);
    float s = n.z >= 0.0 ? 1.0 : -1.0;
    float a = -1.0 / (s + n.z);
    float b = n.x * n.y * a;
    return mat3(vec3(1.0 + s * n.x * n.x * a, s * b, -s * n.x), vec3(b, s + n.y * n.y * a, -n.y), n);
}
#else
vec3 ms_project(vec3 q) { return vec3(q.x, 0.0, q.z); }
vec3 ms_macroNormal(vec3 q) { return vec3(0.0, 1.0, 0.0); }
float ms_altitude(vec3 q) { return q.y; }
// Tangent +x, bitangent -z, normal +y (the uv frame of geometry.plane).
mat3 ms_macroFrame(vec3 q) { return mat3(vec3(1.0, 0.0, 0.0), vec3(0.0, 0.0, -1.0), vec3(0.0, 1.0, 0.0)); }
#endif

// --- the footprint on the visible relief (beyond the paper) ----------------------------------------
// At a grazing view the screen derivatives of the macro surface point are long along the view: a pixel
// of size P across the ray spans P / cos θ_o on the macro surface. Where the relief is taller than a
// pixel, the pixel does not see that strip but a facet of the relief tilted towards the eye, on which its
// rays land P / (cos θ_o + m sin θ_o) apart for a facing slope m, so it resolves the octaves' silhouettes
// and shadows that the macro footprint would leave to the statistics. The footprint's component along
// the view (in the tangent plane) is scaled by
//     cos θ_o / (cos θ_o + g MS_FACING_SLOPE sin θ_o),   g = smoothstep(1/4, 1, σ_c / P),
// σ_c the height deviation of the coarse surface that the macro footprint keeps (weights β; for a height transfer
// function, times its bound on |dh/df|): the relief must stand out of the pixel. MS_FACING_SLOPE and the
// gate's edges were chosen on micro-heights-grazing and micro-heights-terrain against 64-spp ray-marched
// references (FLIP of every filtered mode down, surface-filter 0.085 -> 0.061 and 0.096 -> 0.092); a
// facing slope tied to the coarse slopes (the visible-slope mean, 1.25 σ_c at grazing) did worse.
// Spheres whose relief is below a pixel keep their macro footprint. MS_MACRO_FOOTPRINT turns it off.
#define MS_FACING_SLOPE 0.2

void ms_reliefFootprint(vec3 q, vec3 view, inout vec3 dpdx, inout vec3 dpdy) {
#ifndef MS_MACRO_FOOTPRINT
    vec3 n = ms_macroNormal(q);
    float cosine = abs(dot(view, n));
    vec3 along = view - dot(view, n) * n;
    float sine = length(along);
    if (sine < 1e-6) return;
    along /= sine;
    vec3 lx = ms_latticeFromObject * dpdx;
    vec3 ly = ms_latticeFromObject * dpdy;
    float coarseVariance = 0.0;
    for (int k = 0; k < MS_MAX_OCTAVES; ++k) {
        vec2 af = ms_octave[k];
        float w = ms_splitFractions(af.y * lx, af.y * ly).x;  // β, as the gate was chosen
        coarseVariance += w * w * af.x * af.x * MS_NOISE_VARIANCE;
        if (k + 1 >= ms_heightOctaves) break;  // at the end of the body (MS_MAX_OCTAVES)
    }
    float sigma = sqrt(coarseVariance);
#ifdef MS_TRANSFER
    sigma *= u_transferSlopes.x;
#endif
    float pixel = max(length(dpdx), length(dpdy)) * cosine;  // the pixel's size across the ray
    float gate = smoothstep(0.25, 1.0, sigma / max(pixel, 1e-30));
    ms_reliefGate = gate;
    ms_reliefParallax = sigma * sine / max(pixel, 1e-30);
    float scale = cosine / (cosine + gate * MS_FACING_SLOPE * sine);
    dpdx -= (1.0 - scale) * dot(dpdx, along) * along;
    dpdy -= (1.0 - scale) * dot(dpdy, along) * along;
#endif
}

#ifdef MS_TRANSFER
float ms_surfaceHeight(vec3 p) {
    float f = ms_fractal(p, 0, ms_heightOctaves);
    return ms_transfer(f, ms_transferSigma).x;
}
#else
float ms_surfaceHeight(vec3 p) { return ms_fractal(p, 0, ms_weightedHeightOctaves); }
#endif

// Altitude of q above the displaced surface (> 0 outside).
float ms_gap(vec3 q) { return ms_altitude(q) - ms_surfaceHeight(ms_project(q)); }

// A lower bound of ms_gap(q) that is exact wherever it is <= 0: octaves are summed from the coarsest and
// the sum stops as soon as the altitude clears it by more than twice the amplitude still to come. Far above
// the surface only the first octaves are evaluated (2-3x fewer noise evaluations per march).
float ms_gapBound(vec3 q) {
#ifdef MS_TRANSFER
    return ms_gap(q);
#else
    vec3 lp = ms_latticeFromObject * ms_project(q);
    float altitude = ms_altitude(q);
    float h = 0.0;
    float rest = ms_heightBound;
    for (int k = 0; k < MS_MAX_OCTAVES; ++k) {
        float wa = ms_weight[k] * ms_octave[k].x;
        if (wa > 0.0) {
            h += wa * nz_noise(ms_octave[k].y * lp + ms_octaveOffset[k]);
            rest -= wa * MS_NOISE_BOUND;
            float bound = altitude - h - max(rest, 0.0);
            if (bound > 2.0 * rest) return bound;
        }
        if (k + 1 >= ms_weightedHeightOctaves) break;  // at the end of the body (MS_MAX_OCTAVES)
    }
    return altitude - h;
#endif
}

// The altitudes (low, high) the relief can reach: ±ms_heightBound for the fBm; with a transfer function the
// range of h = g(f), one-sided on the moss (tufts above the macro surface) and the sponge (pits below it),
// so that rays do not march through the empty half of a symmetric slab (twentieth session). The sponge's
// shadow rays left its pits at altitude 0 and climbed on to max |h| in steps of its steep walls' slope
// bound. Measured (256 px, 64-spp references, 7 round-robin rounds, ms per frame symmetric -> one-sided):
// sponge naive 165 -> 90, surface-filter 254 -> 203 (FLIP 0.0841 -> 0.0838); moss naive 149 -> 149,
// surface-filter 246 -> 223 (FLIP 0.0795 -> 0.0791: its lights below the macro horizon, microsurface.frag's
// horizonDip, now end at its ground, altitude 0, not at -max |h|). The Gaussian reliefs keep ±ms_heightBound.
vec2 ms_reliefRange() {
#ifdef MS_TRANSFER
    return u_transferHeights;
#else
    return vec2(-ms_heightBound, ms_heightBound);
#endif
}

// Parameter range [t0, t1] of the ray o + t d inside the slab range.x <= altitude <= range.y (t1 < t0:
// none); z = 1 when t1 is where the ray reaches the slab's floor (so a primary ray surely meets the surface
// by then).
vec3 ms_slab(vec3 o, vec3 d, vec2 range) {
#ifdef MS_SPHERE
    float b = dot(o, d);
    float c = dot(o, o);
    float outer = b * b - c + (ms_radius + range.y) * (ms_radius + range.y);
    if (outer < 0.0) return vec3(1.0, -1.0, 0.0);
    float t0 = max(-b - sqrt(outer), 0.0);
    float inner = b * b - c + max(ms_radius + range.x, 0.0) * max(ms_radius + range.x, 0.0);
    bool floorHit = inner > 0.0 && -b - sqrt(inner) > 0.0;
    return floorHit ? vec3(t0, -b - sqrt(inner), 1.0) : vec3(t0, -b + sqrt(outer), 0.0);
#else
    if (abs(d.y) < 1e-8) return o.y >= range.x && o.y <= range.y ? vec3(0.0, 1e8, 0.0) : vec3(1.0, -1.0, 0.0);
    float ta = (range.y - o.y) / d.y;
    float tb = (range.x - o.y) / d.y;
    return vec3(max(min(ta, tb), 0.0), max(ta, tb), d.y < 0.0 ? 1.0 : 0.0);
#endif
}

// The least step of shadow rays (beyond the paper; set by the filtered modes): a shadow decides the light of
// a whole pixel, so its ray need not resolve the relief it grazes finer than a share of the pixel. Near
// the terminator a ray that skims the relief shrank its steps with the gap (2e-4 of the relief's height
// at least) and spent most of the frame there. A crossing is still caught; what a step can jump is a
// sliver of relief thinner than it. 0 (the point mode, the reference): the relief-relative floor alone.
float ms_shadowStep = 0.0;

// The least step of primary rays (beyond the paper; set by the modes that shade a pixel from one march:
// naive, texture-filter, surface-filter), as (a, b) for a least step a + b t in units of t (distance
// along the ray): a pixel shows the relief over its footprint, so its ray need not find a crossing finer
// than a share of the footprint's length along the ray. Near the surface a ray that skims the relief
// shrinks its steps with the gap, to 2e-4 of the relief's height at least, and at the terrains' low
// elevations that approach was most of the march (micro-irradiance-terrain: 66 steps a pixel, and a
// second sub-ray starting half a pixel above the first one's hit took 31 more). A crossing is still
// caught and refined; what a step can jump is a sliver of relief thinner than it. (0, 0): the point mode
// and the reference, every crossing to the relief-relative floor.
vec2 ms_primaryStep = vec2(0.0);

// A primary ray's least step at `distance` along it: ms_primaryStep's, at least minStep.
float ms_primaryLeastStep(float minStep, float distance) {
    return max(minStep, ms_primaryStep.x + ms_primaryStep.y * distance);
}

// A march step along dir (any length) from x where the gap is `gap`: the gap over the largest rate at
// which it can shrink per unit of t, |dir·n| + slopeBound |dir_tangent|.
float ms_marchStep(vec3 x, vec3 dir, float gap, float minStep) {
    vec3 n = ms_macroNormal(x);
    float dn = dot(dir, n);
    float rate = abs(dn) + ms_slopeBound * length(dir - dn * n);
    return max(MS_RELAX * gap / max(rate, 1e-6), minStep);
}

// A crossing bracketed by (a, gap a > 0, b, gap b <= 0): its secant estimate, and the bracket narrowed by
// the gap g found at t.
float ms_secant(vec4 bracket) {
    return bracket.x + (bracket.z - bracket.x) * bracket.y / max(bracket.y - bracket.w, 1e-12);
}
vec4 ms_narrow(vec4 bracket, float t, float g) {
    return g > 0.0 ? vec4(t, g, bracket.zw) : vec4(bracket.xy, t, g);
}

// First t in [t0, t1] = slab.xy where the ray o + t d (|d| = 1) meets the surface, or -1. Steps are the gap over
// the largest rate at which the gap can shrink, |d·n| + slopeBound |d_tangent|; a crossing is refined by
// five secant steps, and the last secant estimate is the hit (it was the bracket's far end, which regula
// falsi can leave where the crossing step landed: up to a least step past the crossing). After maxSteps
// without a crossing a primary ray returns its current t (just above the surface: a near miss rather than
// a hole) and a shadow ray -1 (unoccluded).
// Every iteration evaluates the relief once, a march step or a secant step: llvmpipe runs both sides of a
// branch, so five secant steps nested in the step loop had cost five evaluations at every step (naive
// took 1.4x its time on micro-heights-terrain and 1.6x on micro-heights-sphere; the same hits).
float ms_march(vec3 o, vec3 d, vec3 slab, int maxSteps, bool primary) {
    float t1 = slab.y;
    float minStep = 2e-4 * max(ms_heightBound, 1e-6);
    if (!primary) minStep = max(minStep, ms_shadowStep);
    float t = slab.x;
    float gap = ms_gapBound(o + t * d);
    if (gap <= 0.0) return t;
    int phase = 0;  // 0: march, 1: refine the crossing in `bracket`
    int refined = 0;
    vec4 bracket = vec4(0.0);
    for (int i = 0; i < maxSteps + 5; ++i) {
        float least = primary ? ms_primaryLeastStep(minStep, t) : minStep;
        float te = phase == 0 ? min(t + ms_marchStep(o + t * d, d, gap, least), t1) : ms_secant(bracket);
        ms_steps += phase == 0 ? 1 : 0;  // march steps, as the diagnostic counts them (not the refinement)
        float g = ms_gapBound(o + te * d);
        if (phase == 1) {
            bracket = ms_narrow(bracket, te, g);
            refined += 1;
            if (refined >= 5) return ms_secant(bracket);  // here, not at the top of the next pass (MS_MAX_OCTAVES)
        } else if (g <= 0.0) {
            phase = 1;
            bracket = vec4(t, gap, te, g);
        } else if (te >= t1) {
            return primary && slab.z > 0.5 ? t1 : -1.0;
        } else {
            t = te;
            gap = g;
        }
    }
    return phase == 1 ? ms_secant(bracket) : (primary ? t : -1.0);
}

// --- A column of sub-pixel rays (beyond the paper; surface-filter) ------------------------------------
// ms_slab of the column's sub-ray with offsets (a, b), o + a up + t (d + b up) (below), t in its own
// parametrisation.
vec3 ms_subRaySlab(vec3 o, vec3 d, vec3 up, vec2 offset) {
    vec3 dk = d + offset.y * up;
    float len = length(dk);
    vec3 slab = ms_slab(o + offset.x * up, dk / len, ms_reliefRange());
    return vec3(slab.xy / len, slab.z);
}

// Where the coarse relief stands out of the pixel, one ray decides which ridge the whole pixel shows, and
// the relief's edges alias (most of surface-filter's error on the terrains, the moss and the sponge).
// Sub-rays through the pixel above and below its centre, in the ray's vertical plane,
// o + a_k up + t (d + b_k up) with evenly spaced offsets (a_k, b_k) = lowest + k stride, ascending, pass
// over the same points of the macro surface at the same t as the centre ray, only higher or lower by a_k +
// t b_k. So sub-ray k+1 meets the relief no sooner than sub-ray k, and the column is marched as one ray:
// each step evaluates the gap of the lowest sub-ray still above the relief; when it crosses, its hit is
// refined (secant) and the next one starts in the same interval, where its gaps at both ends are the last
// one's plus the difference in altitude. A march step serves every sub-ray above the lowest, and each
// iteration (a march step or a secant step) evaluates the relief once, as ms_march does: llvmpipe runs both
// sides of a branch. On a plane (up = its normal) the shared points are exact; on a sphere up is the normal
// at the pixel centre, and the sub-rays' points drift apart by the normal's turn over t b_k, which each
// one's own evaluations take in.
// Until the fourteenth session a sub-ray's start evaluated its gap at the interval's end again (an iteration
// of its own, near the relief, where every octave is summed), and the sub-ray's offsets, exit and hit were
// read and written through the dynamic index j (arrays that llvmpipe keeps in memory). Without both (FLIP
// against 64-spp references unchanged to four decimals; 256 px, 7 round-robin rounds, time ÷ naive):
// micro-irradiance-terrain 1.57 -> 1.54, micro-heights-terrain 1.35 -> 1.33, micro-moss-sphere 2.02 -> 1.95-2.00.
// Since the fifteenth session the next sub-ray's offsets and slab exit are worked out when it starts (from
// `lowest` and `stride`), not kept in arrays for every sub-ray: less state through the loop, which every
// march step carries across its octave sum, and a finished sub-ray's hit is stored at its index, not
// by a loop over every slot: llvmpipe does not unroll these loops, so each ran as a loop, over arrays in
// memory, at every iteration. The same images, bit for bit; 256 px, time ÷ naive, medians of 9-15
// round-robin rounds: micro-irradiance-terrain 1.53-1.56 -> 1.47-1.51 (the slab exits, two runs) -> 1.44-1.46
// (the store), micro-slopes-terrain 1.33 -> 1.28 (the slab exits); within the noise on micro-heights-sphere
// (1.55 -> 1.53; its relief never asks for a column), micro-snake-sphere (1.65-1.70 -> 1.63-1.66),
// micro-moss-sphere (2.03 -> 2.00) and micro-heights-terrain.
// hits[k]: sub-ray k's t (in its own parametrisation, |d + b_k up| per unit), or -1 where it misses; as
// ms_march, a sub-ray that runs out of steps returns where it got to.
#ifndef MS_RELIEF_RAYS
#define MS_RELIEF_RAYS 1
#endif
void ms_marchColumn(vec3 o, vec3 d, vec3 up, vec2 lowest, vec2 stride, int count, int maxSteps,
                    out float hits[MS_RELIEF_RAYS]) {
    for (int k = 0; k < MS_RELIEF_RAYS; ++k) hits[k] = -1.0;
    vec2 offset = lowest;
    vec3 slab = ms_subRaySlab(o, d, up, offset);
    if (slab.y < slab.x) return;  // the lowest sub-ray misses the slab: so do the others
    float minStep = 2e-4 * max(ms_heightBound, 1e-6);
    // Sub-ray j is held in scalars (its offsets, its slab: the exit, and whether that is the slab's floor, where
    // a primary ray surely met the surface; and its hit until the next one starts).
    // phase 0: march sub-ray j; 1: refine its crossing in `bracket`; 2: sub-ray j is done, and the next one
    // starts where it crossed or left the slab: in the interval [tPrev, t], with its gaps at both ends
    // those of sub-ray j plus the difference in altitude (exact on a plane, where they pass over the same
    // points; the gap at t was evaluated already, and its evaluation again cost one more iteration)
    int j = 0;
    int phase = 0;
    int refined = 0;
    float hit = -1.0;
    float t = slab.x;
    float gap = ms_gapBound(o + offset.x * up + t * (d + offset.y * up));
    float tPrev = t, gapPrev = gap;
    float gapEnd = gap;  // sub-ray j's gap at t where it crossed or left the slab (exact where <= 0)
    vec4 bracket = vec4(t, gap, t, gap);
    if (gap <= 0.0) {  // starts inside: the hit is the entry itself
        hit = t;
        phase = 2;
    }
    for (int i = 0; i < maxSteps; ++i) {
        if (phase == 2) {
            hits[j] = hit;
            j += 1;
            if (j >= count) break;
            offset += stride;  // the sub-ray stride.x + t stride.y higher
            slab = ms_subRaySlab(o, d, up, offset);
            gapPrev += stride.x + tPrev * stride.y;
            gap = gapEnd + stride.x + t * stride.y;
            phase = gap <= 0.0 ? 1 : 0;
            refined = 0;
            bracket = vec4(tPrev, gapPrev, t, gap);
        }
        vec3 oj = o + offset.x * up;
        vec3 dj = d + offset.y * up;
        float lj = length(dj);
        float least = ms_primaryLeastStep(minStep, t * lj) / lj;
        float te = phase == 0 ? min(t + ms_marchStep(oj + t * dj, dj, gap, least), slab.y) : ms_secant(bracket);
        ms_steps += phase == 0 ? 1 : 0;
        float g = ms_gapBound(oj + te * dj);  // exact where <= 0
        if (phase == 1) {
            bracket = ms_narrow(bracket, te, g);
            refined += 1;
            if (refined >= (j == 0 ? 5 : 2)) {
                hit = ms_secant(bracket);
                phase = 2;
            }
        } else {
            tPrev = t;
            gapPrev = gap;
            t = te;
            if (g <= 0.0) {  // crossed in [tPrev, t]
                phase = 1;
                refined = 0;
                bracket = vec4(tPrev, gapPrev, t, g);
                gapEnd = g;
            } else if (t >= slab.y) {  // left the slab: float error at a thin slab's floor, or a miss
                hit = slab.z > 0.5 ? t : -1.0;
                gapEnd = g;
                phase = 2;
            } else {
                gap = g;
            }
        }
        if (phase == 2 && j + 1 >= count) break;  // at the end of the body (MS_MAX_OCTAVES)
    }
    // the last sub-ray done stores its hit; those not reached ran out of steps: a near miss rather than a hole
    float last = phase == 1 ? ms_secant(bracket) : t;
    for (int k = 0; k < MS_RELIEF_RAYS; ++k) {
        if (k >= j && k < count) hits[k] = k == j && phase == 2 ? hit : last;
    }
}

// Where a shadow ray from the surface point q starts: a little above the surface along the macro normal (the
// marcher's hit may lie just below it), by at least eps, float32's resolution at q.
vec3 ms_shadowOrigin(vec3 q, float eps) {
    return q + ms_macroNormal(q) * (max(-ms_gap(q), 0.0) + max(1e-3 * ms_heightBound, eps));
}

// 1 if the light direction l is unoccluded from the surface point q, else 0 (the ray from ms_shadowOrigin);
// below float32's resolution at q (a nearly flat coarse surface far away) there is nothing to shadow.
float ms_shadow(vec3 q, vec3 l, int maxSteps) {
    float eps = 2e-6 * (length(q) + 1.0);
    if (ms_heightBound <= 8.0 * eps) return 1.0;
    vec3 o = ms_shadowOrigin(q, eps);
    vec3 slab = ms_slab(o, l, ms_reliefRange());
    if (slab.y <= slab.x) return 1.0;
    slab.x = max(2e-3 * ms_heightBound, 2.0 * eps);
    return ms_march(o, l, slab, maxSteps, false) < 0.0 ? 1.0 : 0.0;
}

// The shadow ray towards l of a pixel's shading samples, from one ray (beyond the paper; surface-filter).
// A sample's ray leaves the coarse surface at q + δ, Δh above q, and runs parallel to the ray from q; where
// the ray from q passes the point x its clearance is c(x), and the sample's is c(x) + Δh - ∇h(x)·δ to
// first order in δ. The ray from q is marched as ms_march does but does not stop at an occluder: it goes
// on through it, in steps of at least reach / 2, until its clearance falls below -reach (no sample can
// pass then: reach stands for the largest |∇h·δ| over the samples; the caller sets it). Returns (least
// clearance c*, ∇h at its point x*) over the path beyond `skip` (nearer than the samples lie apart, the
// relief is each sample's own facet, which its Lambert term sees), or (1e30, 0) if nothing comes within
// reach; a sample at (δ, Δh) is lit when c* + Δh - ∇h(x*)·δ > 0. With reach = skip = 0 this is ms_shadow's
// answer, but for its steps' slope bound (below).
// Once the ray from q is blocked (c* < 0) its least step grows by MS_PROFILE_STEP_GROWTH a step: past that
// point only samples standing higher than q can still be lit, and near the terminator the ray skimmed the
// relief for up to 130 steps of a pixel's share each (the terminator band was most of what the profile cost
// over ms_shadow). Measured (256 px, 64-spp references, surface-filter FLIP and frame time, steps of
// constant floor -> growing by 1.3): micro-heights-sphere 0.0504 -> 0.0503 at 0.86-0.89x the time,
// micro-slopes-sphere 0.0724 -> 0.0726 at 0.90x, micro-snake-sphere 0.0654 -> 0.0653 at 0.94x. Not with a
// transfer function: the moss's tufts are narrower than its driver's features, and the growing steps
// jumped them (its band just below the macro horizon 9 -> 13 % too bright at 128 px against the
// reference, FLIP 0.0895 -> 0.0906; capping the step at 0.25 / κ, κ = ms_coarseFrequency, kept the band
// at 9 % and saved nothing on micro-heights-sphere, 0.5 / κ saved 6 % with the band at 11 %). Growth from
// the first step within reach, before the ray is blocked, raised the moss to 0.0999.
// The ray starts at `skip` (thirteenth session): what lies nearer is not the profile's, and the steps there
// were 1.3 of the height sphere's 5.9 a pixel and 2.9 of the snake's 8.3. Measured (256 px, 64-spp
// references, 5-9 round-robin rounds, FLIP and time ÷ naive, before -> after): snake 0.0653 -> 0.0651 at
// 1.82 -> 1.73, heights terrain 0.0647 -> 0.0644 at 1.39 -> 1.34, slope terrain 0.0742 -> 0.0739 at
// 1.37 -> 1.32, grazing terrain 0.0473 -> 0.0471 at 1.33 -> 1.31, height sphere 0.0503 -> 0.0506 at
// 1.67 -> 1.62. Not with a transfer function: there the first step from `skip`, over-relaxed on the exact
// gap, jumped tufts that the steps from q had met (the moss's band below the macro horizon 7.2 -> 8.9 %
// too bright at 128 px, the sponge's band above it 6.0 -> 7.3 %).
// Once blocked, the ray looks only for clearances below c* < 0: from a point clear by `gap` none lies nearer
// than (gap - c*) / rate, so that is its step (over-relaxed as every march step; before, gap / rate). It
// matters with a transfer function, whose steps do not grow: moss 2.07 -> 2.00 x naive, sponge 1.89 ->
// 1.81 x (7 rounds), FLIP and the moss's bands unchanged; the Gaussian presets within the noise.
// The steps take the coarse slope along the ray at MS_PROFILE_SLOPE_DEVIATIONS standard deviations, not at
// the hard bound ms_slopeBound where that is smaller (seventeenth session). The hard bound, 2.5 Σ w a f,
// has every octave's slope at its extreme and in line; at a point of the coarse surface the slope along a
// tangent direction is N(0, σ²), σ² = ms_coarseSlopeVariance, and with every octave weighted the hard
// bound is 7.9 σ on micro-heights-sphere's five octaves and 7.1 σ on four. With a transfer function h =
// g(f) the driver's slope is taken statistically and g' at its bound (4 σ_f max |g'| against 7.1 σ_f
// max |g'| on the moss and sponge): g makes the moss's tufts steep, and the RMS of g' in its place once
// the ray is blocked let the steps jump them (the moss's band below the macro horizon 4.1 -> 5.6 % too
// bright at 128 px). Tested against shadow rays from each nearby point (tests/test_microsurface.py).
// Measured (256 px, 64-spp references, 5-7 round-robin rounds, time ÷ naive; FLIP the same to four
// decimals, the height sphere's 0.0506 -> 0.0505): moss 1.76 -> 1.57-1.60, sponge 1.69 -> 1.53-1.54,
// heights terrain 1.30 -> 1.20, grazing terrain 1.26 -> 1.15, slope terrain 1.25 -> 1.14, height sphere
// 1.52 -> 1.47, snake 1.59 -> 1.54; the horizon bands (below / above) moss 4.1 / 2.4 -> 4.0 / 2.5 %,
// sponge 9.3 / 6.2 -> 8.8 / 6.1 %. naive's shadow ray (ms_shadow) keeps the hard bound: with this one its
// frame would take 0.91x the time on the moss and sponge and the same on the Gaussian spheres.
// On Gaussian reliefs 3 deviations since the twenty-eighth session (4 before; 4 with a transfer function).
// On micro-heights-sphere the profile was 0.36 of naive's frame (knocked out: 1.52 -> 1.16 x naive) and no
// other part of a sample over 0.05. Measured (256 px, 64-spp references, 7 round-robin rounds, time ÷ naive,
// 4 -> 3 -> 2.5 deviations; FLIP within 0.0003 of 4's on all nine presets): height sphere 1.55 -> 1.49 ->
// 1.48, snake 1.49 -> 1.46 -> 1.44, slope sphere 1.11 -> 1.10 -> 1.08, heights terrain 1.18 -> 1.14 -> 1.12,
// grazing terrain 1.14 -> 1.10 -> 1.08, slope terrain 1.14 -> 1.12 -> 1.08, irradiance terrain 1.41 ->
// 1.38 -> 1.40. Against the nearby points' own shadow rays (tests/test_microsurface.py) 3 deviations get
// 4.8 / 7.6 / 6.4 % wrong at 5 / 10 / 20 degrees (4: 4.7 / 7.4 / 6.0; 2.5: 5.4 / 8.0 / 6.8, over 3/4 of what
// q's own shadow gets wrong at 5 degrees). With a transfer function 3 deviations took the moss's band below
// the macro horizon from 3.7 to 5.2 % too bright (128 px, 16-spp reference), beyond the 5 % its test allows.
// The ray stops once no clearance ahead can fall below c* (twenty-first session): every clearance is at
// least the altitude less the relief's top (ms_reliefRange), and on a ray that climbs (on the sphere,
// once it does, as |x| is convex along a line) the altitude only grows; so where altitude - top >= c*
// the answer is final. Before, the ray climbed on to top + reach whatever c* was. The answer is the same
// bit for bit (the nine presets at 128 px; tested against dense scans of the moss and sponge); it saves
// most where the relief has a flat top, the sponge's: its profile steps 24 -> 13 a pixel (256 px), its
// frame 2.27 -> 1.92 x naive (5 rounds, 226 -> 189 ms); the other presets' times are unchanged.
#ifndef MS_PROFILE_SLOPE_DEVIATIONS
#ifdef MS_TRANSFER
#define MS_PROFILE_SLOPE_DEVIATIONS 4.0
#else
#define MS_PROFILE_SLOPE_DEVIATIONS 3.0
#endif
#endif
#ifndef MS_PROFILE_STEP_GROWTH
#define MS_PROFILE_STEP_GROWTH 1.3
#endif
vec4 ms_shadowProfile(vec3 q, vec3 l, int maxSteps, float reach, float skip) {
    vec4 none = vec4(1e30, 0.0, 0.0, 0.0);
    float eps = 2e-6 * (length(q) + 1.0);
    if (ms_heightBound <= 8.0 * eps) return none;
    vec3 o = ms_shadowOrigin(q, eps);
    vec2 range = ms_reliefRange();
    vec3 slab = ms_slab(o, l, range + vec2(0.0, reach));  // clearances below reach count
    if (slab.y <= slab.x) return none;
    float t = max(2e-3 * ms_heightBound, 2.0 * eps);
#ifndef MS_TRANSFER
    t = max(t, skip);
#endif
    float minStep = max(2e-4 * max(ms_heightBound, 1e-6), ms_shadowStep);
    // the coarse slope along the ray (above)
    float slopeBound = MS_PROFILE_SLOPE_DEVIATIONS * sqrt(ms_coarseSlopeVariance);
#ifdef MS_TRANSFER
    slopeBound *= u_transferSlopes.x;
#endif
    slopeBound = min(slopeBound, ms_slopeBound);
    float least = reach;
    vec3 at = vec3(0.0);
    for (int i = 0; i < maxSteps; ++i) {
        vec3 x = o + t * l;
        vec3 up = ms_macroNormal(x);
        if (ms_altitude(x) - range.y >= least && dot(l, up) >= 0.0) break;  // final (above)
        ms_steps += 1;
        float gap = ms_gapBound(x);  // exact where <= 0; where it is looser the ray is well clear
        if (t > skip && gap < least) {
            least = gap;
            at = x;
            if (least < -reach) break;
        }
#ifndef MS_TRANSFER
        if (least < 0.0) minStep *= MS_PROFILE_STEP_GROWTH;
#endif
        float dn = abs(dot(l, up));
        float rate = dn + slopeBound * sqrt(max(1.0 - dn * dn, 0.0));
        t += max((gap > 0.0 ? MS_RELAX * (gap - min(least, 0.0)) : max(-gap, 0.5 * reach)) / max(rate, 1e-6), minStep);
        if (t >= slab.y) break;
    }
    if (least >= reach) return none;
    vec4 fg = ms_fractalGrad(ms_project(at), 0, ms_weightedHeightOctaves);
#ifdef MS_TRANSFER
    fg.xyz *= ms_transfer(fg.w, ms_transferSigma).z;  // ∇E[g(f)] = E[g'] ∇f
#endif
    return vec4(least, fg.xyz);
}
