// Hart et al. 1999, "Antialiased parameterized solid texturing": the driver f of eq. (1) and its
// gradient (eqs. 10-12), the octave-clamped driver of today's renderers (the `naive` mode), and the
// Gaussian statistics of f over the pixel footprint for Heitz et al.'s preconvolved colour maps.
//
//   f(s)   = s^T Q s + sum_i a_i n(T_i s + o_i)                          (eqs. 1, 3, 4)
//   df/ds  = 2 (Q s)_xyz + sum_i a_i T_i^T DNoise(T_i s + o_i)           (eqs. 10-12)
//
// Defines: PT_TERM_COUNT (0..8, compile-time so loops unroll), PT_REDUCED (Hart §4.2 "100,000-gate"
// variant: linear instead of quintic fade, i.e. trilinear interpolation of the corner terms),
// PT_FIRST_ORDER (the filters' box centred on f at the pixel centre as printed, not on its pixel mean),
// PF_FINE_DERIVATIVES (set by the renderer when dFdx/dFdy are fine; see pt_meanCorrection).
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

// f(s), eq. (1).
float pt_driver(vec3 s) {
    vec4 s4 = vec4(s, 1.0);
    float f = dot(s4, pt_quadric * s4);
    for (int i = 0; i < PT_TERM_COUNT; ++i) {
        f += pt_noiseAmplitude[i] * pt_noise(pt_noiseMatrix[i] * s + pt_noiseOffset[i]);
    }
    return f;
}

// --- The box's centre: the pixel mean of f to second order (beyond the paper) -----------------------
// Hart centres the box on f at the pixel centre. Over a box pixel (offsets u, v uniform on [-1/2, 1/2])
// the mean of f is f + (f_xx + f_yy)/24 + O(4th derivatives): 1/2 tr(H Σ) with Σ = I/12, H the screen
// Hessian of f. Where f curves within the pixel (noise octaves a few pixels across) that shift is most
// of the error of the first-order filter (docs/hart.md).
// H is estimated in hart.frag's pt_meanCorrection (derivatives exist only in fragment shaders, and
// glsl_eval runs this file in a vertex shader) from the analytic screen gradient g and f of this pixel
// and of its neighbour in the 2x2 quad (dFdx/dFdy): with PF_FINE_DERIVATIVES (each quad row
// differences its own pixels; the renderer probes for it, gl/context.fine_derivatives) the cubic
// Hermite fit through (f, g) at both pixels gives
// f'' at this pixel, 6h(Δf - g) - 2Δg with h = +1 towards the right/upper neighbour and -1 otherwise
// (exact for cubics); without it the central difference Δg, f'' at the pair's midpoint.
// Only the resolved part of f enters: the quadric and each noise term with weight
// smoothstep(0, 1, -log2 ρ), ρ its footprint in lattice cells (1 below half a cell, 0 beyond a cell);
// differences of unresolved octaves across a pixel are not curvature but aliasing.
// PT_FIRST_ORDER restores the paper's centre.

// log2 of a term's footprint in its lattice cells: the longer screen axis, jx = T dsdx or jy = T dsdy.
float pt_footprintLog2(vec3 jx, vec3 jy) {
    return 0.5 * log2(max(max(dot(jx, jx), dot(jy, jy)), 1e-30));
}

float pt_resolvedWeight(vec3 jx, vec3 jy) {
    return smoothstep(0.0, 1.0, -pt_footprintLog2(jx, jy));
}

// (df/ds, f) of eqs. (10)-(12), and in `resolved` the same sum over the quadric and the resolved terms.
vec4 pt_driverGradSplit(vec3 s, vec3 dsdx, vec3 dsdy, out vec4 resolved) {
    vec4 s4 = vec4(s, 1.0);
    vec4 qs = pt_quadric * s4;
    vec4 result = vec4(2.0 * qs.xyz, dot(s4, qs));
    resolved = result;
    for (int i = 0; i < PT_TERM_COUNT; ++i) {
        mat3 t = pt_noiseMatrix[i];
        vec4 n = pt_noiseGrad(t * s + pt_noiseOffset[i]);
        // T^T dn: row-vector times matrix in GLSL
        vec4 term = pt_noiseAmplitude[i] * vec4(n.xyz * t, n.w);
        result += term;
        resolved += pt_resolvedWeight(t * dsdx, t * dsdy) * term;
    }
    return result;
}

// (df/ds, f), eqs. (10)-(12).
vec4 pt_driverGrad(vec3 s) {
    vec4 resolved;
    return pt_driverGradSplit(s, vec3(0.0), vec3(0.0), resolved);
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
// measured (β, γ, λ): a term a n(T s + o) adds a β n to the mean, a γ T^T ∇n to the gradient and
// a² λ σ_n² to the residual variance; the linear part over a box pixel has variance (g_x² + g_y²) / 12.
// noise_stats.glsl holds separable smoothstep fits of that table (a lookup per term cost 1.3x).
// Terms with β = γ = 0 (footprints over ~13 cells) are not evaluated: their noise only adds variance.

#include "procedural/noise_stats.glsl"

vec3 pt_noiseSplit(vec3 jx, vec3 jy) {
    vec2 l = 0.5 * log2(max(vec2(dot(jx, jx), dot(jy, jy)), vec2(1e-30)));
    vec2 b = 1.0 - smoothstep(NS_BETA_EDGES.x, NS_BETA_EDGES.y, l);
    vec2 g = 1.0 - smoothstep(NS_GAMMA_EDGES.x, NS_GAMMA_EDGES.y, l);
    vec2 h = 1.0 - smoothstep(NS_ONE_MINUS_LAMBDA_EDGES.x, NS_ONE_MINUS_LAMBDA_EDGES.y, l);
    return vec3(b.x * b.y, g.x * g.y, 1.0 - h.x * h.y);
}

// (μ, g_x, g_y, σ_res²): the mean of f over the footprint, the screen gradient of its linear part
// (variance (g_x² + g_y²) / 12 over a box pixel), and the variance the unresolved noise leaves;
// `resolved` is (df/ds, f) of the resolved part as in pt_driverGradSplit, for hart.frag's
// pt_meanCorrection.
vec4 pt_driverGaussian(vec3 s, vec3 dsdx, vec3 dsdy, out vec4 resolved) {
    vec4 s4 = vec4(s, 1.0);
    vec4 qs = pt_quadric * s4;
    float mu = dot(s4, qs);
    vec3 grad = 2.0 * qs.xyz;
    float residual = 0.0;
    resolved = vec4(grad, mu);
    for (int i = 0; i < PT_TERM_COUNT; ++i) {
        mat3 t = pt_noiseMatrix[i];
        float a = pt_noiseAmplitude[i];
        vec3 jx = t * dsdx;
        vec3 jy = t * dsdy;
        vec3 split = pt_noiseSplit(jx, jy);
        if (max(abs(split.x), abs(split.y)) > 0.01) {
            vec4 n = pt_noiseGrad(t * s + pt_noiseOffset[i]);
            vec4 term = a * vec4(n.xyz * t, n.w);
            mu += split.x * term.w;
            grad += split.y * term.xyz;
            resolved += pt_resolvedWeight(jx, jy) * term;
        }
        residual += a * a * split.z;
    }
    return vec4(mu, dot(grad, dsdx), dot(grad, dsdy), residual * NS_VARIANCE);
}
