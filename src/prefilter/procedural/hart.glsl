// Hart et al. 1999, "Antialiased parameterized solid texturing": the driver f of eq. (1) and its
// gradient (eqs. 10-12), the filters' centre (the pixel mean of f, beyond the paper), the octave-clamped
// driver of today's renderers (the `naive` mode), and the Gaussian statistics of f over the pixel
// footprint for Heitz et al.'s preconvolved colour maps.
//
//   f(s)   = s^T Q s + sum_i a_i n(T_i s + o_i)                          (eqs. 1, 3, 4)
//   df/ds  = 2 (Q s)_xyz + sum_i a_i T_i^T DNoise(T_i s + o_i)           (eqs. 10-12)
//
// Defines: PT_TERM_COUNT (0..8, compile-time so loops unroll), PT_REDUCED (Hart §4.2 "100,000-gate"
// variant: linear instead of quintic fade, i.e. trilinear interpolation of the corner terms),
// PT_FIRST_ORDER (the filters' box centred on f at the pixel centre as printed, not on its pixel mean).
// Uniforms: pt_quadric (mat4 Q, symmetric), pt_noiseMatrix[i] (T_i), pt_noiseOffset[i] (o_i at time t),
// pt_noiseAmplitude[i] (a_i). s is in solid-texture units.

#include "glsl/common/noise.glsl"

#ifndef PT_TERM_COUNT
#define PT_TERM_COUNT 0
#endif
#define PT_ARRAY_SIZE (PT_TERM_COUNT > 0 ? PT_TERM_COUNT : 1)

uniform mat4 pt_quadric;
uniform mat3 pt_noiseMatrix[PT_ARRAY_SIZE];
uniform vec3 pt_noiseOffset[PT_ARRAY_SIZE];
uniform float pt_noiseAmplitude[PT_ARRAY_SIZE];  // @param 0..2 Noise amplitude: a_i of noise term i in f(s) = s^T Q s + Σ a_i n(T_i s + o_i) (Hart eq. 1); every mode follows (no baked table depends on it)

float pt_noise(vec3 p) {
#ifdef PT_REDUCED
    return nz_linearNoise(p);
#else
    return nz_noise(p);
#endif
}

vec4 pt_noiseGrad(vec3 p) {
#ifdef PT_REDUCED
    return nz_linearNoiseGrad(p);
#else
    return nz_noiseGrad(p);
#endif
}

vec4 pt_noiseGradCurv(vec3 p, vec3 e1, vec3 e2, out float curvature) {
#ifdef PT_REDUCED
    return nz_linearNoiseGradCurv(p, e1, e2, curvature);
#else
    return nz_noiseGradCurv(p, e1, e2, curvature);
#endif
}

// f(s), eq. (1).
float pt_driver(vec3 s) {
    vec4 s4 = vec4(s, 1.0);
    float f = dot(s4, pt_quadric * s4);
    for (int i = 0; i < PT_TERM_COUNT; ++i) {
        f += pt_noiseAmplitude[i] * pt_noise(pt_noiseMatrix[i] * s + pt_noiseOffset[i]);
    }
    return f;
}

// --- The filters' centre: the pixel mean of f (beyond the paper) ------------------------------------
// Hart centres the box on f at the pixel centre. Most of the first-order filter's error is that choice
// (docs/hart.md): with the pixel's exact mean of f, the same box is 2-4x closer to the reference. Over a
// box pixel spanned by the screen derivatives dsdx, dsdy the mean of f is estimated term by term:
//   quadric: f_q + (dsdxᵀ Q dsdx + dsdyᵀ Q dsdy) / 12            (exact: ½ tr(H Σ), H = 2Q, Σ = ds dsᵀ/12)
//   noise term a n(T s + o), footprint axes jx = T dsdx, jy = T dsdy in its lattice:
//            a (β n + κ τ),  τ = (jxᵀ H jx + jyᵀ H jy) / 24          (H the analytic Hessian of n)
// n + τ is the second-order Taylor mean; β and κ (noise_stats, measured by least squares over random
// footprints) shrink it where the footprint spans a good part of a lattice cell and the Taylor series
// fails, down to 0 where the term is all spread. PT_FIRST_ORDER restores the paper's centre f.

// log2 of a term's footprint in its lattice cells: the longer screen axis, jx = T dsdx or jy = T dsdy.
float pt_footprintLog2(vec3 jx, vec3 jy) {
    return 0.5 * log2(max(max(dot(jx, jx), dot(jy, jy)), 1e-30));
}

#include "procedural/noise_stats.glsl"

// (β, κ, γ, λ) of noise_stats for a term whose footprint axes are jx, jy in its lattice cells.
vec4 pt_noiseSplit(vec3 jx, vec3 jy) {
    vec4 fall = ns_fall(dot(jx, jx), dot(jy, jy));
    return vec4(fall.xyz, 1.0 - fall.w);
}

// Noise term i at s with footprint axes jx, jy: (T^T dn, β n + κ τ) for weights = (β, κ). With
// PT_FIRST_ORDER τ is not computed: (T^T dn, β n).
vec4 pt_termGradMean(int i, vec3 s, vec3 jx, vec3 jy, vec2 weights) {
    mat3 t = pt_noiseMatrix[i];
    vec3 p = t * s + pt_noiseOffset[i];
#ifdef PT_FIRST_ORDER
    vec4 n = pt_noiseGrad(p);
    float mean = weights.x * n.w;
#else
    float curvature;
    vec4 n = pt_noiseGradCurv(p, jx, jy, curvature);
    float mean = weights.x * n.w + weights.y * curvature / 24.0;
#endif
    return vec4(n.xyz * t, mean);  // T^T dn: row-vector times matrix in GLSL
}

// The quadric's part: vec4(df/ds, f) at s, and in `shift` its exact second-order mean shift.
vec4 pt_quadricGradMean(vec3 s, vec3 dsdx, vec3 dsdy, out float shift) {
    vec4 s4 = vec4(s, 1.0);
    vec4 qs = pt_quadric * s4;
    mat3 q = mat3(pt_quadric);
    shift = (dot(dsdx, q * dsdx) + dot(dsdy, q * dsdy)) / 12.0;
    return vec4(2.0 * qs.xyz, dot(s4, qs));
}

// (df/ds of eqs. (10)-(12), the pixel mean of f as above; f itself with PT_FIRST_ORDER).
vec4 pt_driverGradMean(vec3 s, vec3 dsdx, vec3 dsdy) {
    float shift;
    vec4 result = pt_quadricGradMean(s, dsdx, dsdy, shift);
#ifndef PT_FIRST_ORDER
    result.w += shift;
#endif
    for (int i = 0; i < PT_TERM_COUNT; ++i) {
        vec3 jx = pt_noiseMatrix[i] * dsdx;
        vec3 jy = pt_noiseMatrix[i] * dsdy;
#ifdef PT_FIRST_ORDER
        vec2 weights = vec2(1.0, 0.0);  // f itself
#else
        vec2 weights = pt_noiseSplit(jx, jy).xy;
#endif
        result += pt_noiseAmplitude[i] * pt_termGradMean(i, s, jx, jy, weights);
    }
    return result;
}

// (df/ds, f), eqs. (10)-(12).
vec4 pt_driverGrad(vec3 s) {
    vec4 s4 = vec4(s, 1.0);
    vec4 qs = pt_quadric * s4;
    vec4 result = vec4(2.0 * qs.xyz, dot(s4, qs));
    for (int i = 0; i < PT_TERM_COUNT; ++i) {
        mat3 t = pt_noiseMatrix[i];
        vec4 n = pt_noiseGrad(t * s + pt_noiseOffset[i]);
        result += pt_noiseAmplitude[i] * vec4(n.xyz * t, n.w);
    }
    return result;
}

// The driver as renderers filter it today (pbrt's FBm, Unreal's noise): each noise term whose
// footprint in its own lattice units exceeds half a cell is dropped, the last one faded out
// (smoothstep(0.3, 0.7, -1 - log2 w), pbrt-v4 FBm), so only the quadric and resolved terms remain.
float pt_driverOctaveClamped(vec3 s, vec3 dsdx, vec3 dsdy) {
    vec4 s4 = vec4(s, 1.0);
    float f = dot(s4, pt_quadric * s4);
    for (int i = 0; i < PT_TERM_COUNT; ++i) {
        float log2Cells = pt_footprintLog2(pt_noiseMatrix[i] * dsdx, pt_noiseMatrix[i] * dsdy);
        float weight = smoothstep(0.3, 0.7, -1.0 - log2Cells);
        if (weight > 0.0) {
            f += weight * pt_noiseAmplitude[i] * pt_noise(pt_noiseMatrix[i] * s + pt_noiseOffset[i]);
        }
    }
    return f;
}

// --- Gaussian statistics of f over the footprint (Heitz et al. 2014 §4.2 + Hart's gradient) --------
// For a box footprint whose axes have lengths rho1, rho2 in lattice units, procedural/noise_stats.py
// measured (β, κ, γ, λ): a term a n(T s + o) adds a (β n + κ τ) to the mean (τ as for the Hart modes'
// centre), a γ T^T ∇n to the gradient and a² λ σ_n² to the residual variance; the linear part over a box
// pixel has variance (g_x² + g_y²) / 12. noise_stats.glsl holds separable rational fits of that table
// (a lookup per term cost 1.3x). Terms with β = κ = γ = 0 (footprints over ~13 cells) are not evaluated:
// their noise only adds variance. PT_FIRST_ORDER drops the curvature (κ = 0).

// (μ, g_x, g_y, σ_res²): the mean of f over the footprint, the screen gradient of its linear part
// (variance (g_x² + g_y²) / 12 over a box pixel), and the variance the unresolved noise leaves.
vec4 pt_driverGaussian(vec3 s, vec3 dsdx, vec3 dsdy) {
    float shift;
    vec4 quadric = pt_quadricGradMean(s, dsdx, dsdy, shift);
    vec3 grad = quadric.xyz;
    float mu = quadric.w;
#ifndef PT_FIRST_ORDER
    mu += shift;
#endif
    float residual = 0.0;
    for (int i = 0; i < PT_TERM_COUNT; ++i) {
        float a = pt_noiseAmplitude[i];
        vec3 jx = pt_noiseMatrix[i] * dsdx;
        vec3 jy = pt_noiseMatrix[i] * dsdy;
        vec4 split = pt_noiseSplit(jx, jy);
        if (max(split.x, split.z) > 0.01) {
            vec4 term = pt_termGradMean(i, s, jx, jy, split.xy);
            mu += a * term.w;
            grad += a * split.z * term.xyz;
        }
        residual += a * a * split.w;
    }
    return vec4(mu, dot(grad, dsdx), dot(grad, dsdy), residual * NS_VARIANCE);
}
