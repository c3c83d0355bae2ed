// Hart et al. 1999, "Antialiased parameterized solid texturing": the driver f of eq. (1) and its
// gradient (eqs. 10-12), plus the octave-clamped driver of today's renderers (the `naive` mode).
//
//   f(s)   = s^T Q s + sum_i a_i n(T_i s + o_i)                          (eqs. 1, 3, 4)
//   df/ds  = 2 (Q s)_xyz + sum_i a_i T_i^T DNoise(T_i s + o_i)           (eqs. 10-12)
//
// Defines: PT_TERM_COUNT (0..8, compile-time so loops unroll), PT_REDUCED (Hart §4.2 "100,000-gate"
// variant: linear instead of quintic fade, i.e. trilinear interpolation of the corner terms).
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
uniform float pt_noiseAmplitude[PT_ARRAY_SIZE];

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

// (df/ds, f), eqs. (10)-(12).
vec4 pt_driverGrad(vec3 s) {
    vec4 s4 = vec4(s, 1.0);
    vec4 qs = pt_quadric * s4;
    vec4 result = vec4(2.0 * qs.xyz, dot(s4, qs));
    for (int i = 0; i < PT_TERM_COUNT; ++i) {
        vec4 n = pt_noiseGrad(pt_noiseMatrix[i] * s + pt_noiseOffset[i]);
        // T^T dn: row-vector times matrix in GLSL
        result += pt_noiseAmplitude[i] * vec4(n.xyz * pt_noiseMatrix[i], n.w);
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
        float w = max(length(pt_noiseMatrix[i] * dsdx), length(pt_noiseMatrix[i] * dsdy));
        float weight = smoothstep(0.3, 0.7, -1.0 - log2(max(w, 1e-30)));
        if (weight > 0.0) {
            f += weight * pt_noiseAmplitude[i] * pt_noise(pt_noiseMatrix[i] * s + pt_noiseOffset[i]);
        }
    }
    return f;
}
