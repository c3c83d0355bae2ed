// transfer.glsl -- height transfer functions h = g(f) over Gaussian drivers, Heitz, Nowrouzezahrai,
// Poulin & Neyret 2014, §7, eqs. (19)-(28) (Figs. 11-12).
//
// What it computes
//   A microsurface height h = g(f) of a driver f (a Perlin-noise sum) through a 1D transfer function g.
//   Over a pixel footprint f ~ N(fMean, fSigma^2) and grad f has mean gradMean (resolved) and covariance
//   gradCov (unresolved). The table baked by microsurface/transfer.py holds the moments
//   (E[g], E[g^2], E[g'], E[g'^2]) under N(mu, sigma^2); from them (eqs. 21-28, grad h = g'(f) grad f
//   with g'(f) and grad f independent for a Gaussian process):
//     p_h ~ N(E[g], E[g^2] - E[g]^2),
//     p_s ~ N(E[g'] gradMean, E[g'^2] gradCov + (E[g'^2] - E[g']^2) gradMean gradMean^T).
//   Covariances are vec3(xx, xy, yy).
//
// Functions (no file-scope uniforms; samplers are parameters)
//   vec4 ms_transferMoments(sampler2D table, float mu, float sigma, vec3 range)
//        (E[g], E[g^2], E[g'], E[g'^2]) for the driver N(mu, sigma^2), bilinear. table: the RGBA32F bake
//        (PreconvolvedTransfer.upload: n_mu x n_sigma, LINEAR, clamp-to-edge), mu along x over
//        range.xy = (lo, hi) with texel i at lo + (i + 0.5)(hi - lo)/n_mu, sigma along y with row j at
//        range.z j / (n_sigma - 1), range.z = sigma_max (PreconvolvedTransfer.range_uniform).
//        mu beyond [lo, hi] reads the edge column; sigma > sigma_max reads sigma_max.
//   void ms_transferStats(vec4 moments, vec2 gradMean, vec3 gradCov, out float hMean, out float hVar,
//        out vec2 slopeMean, out vec3 slopeCov)     the Gaussian height and slope distributions above
//        (variances clamped at 0, so slopeCov stays positive semi-definite if gradCov is).
//   float ms_transferValue(int kind, vec2 params, float v)        g(v), unfiltered (point / reference)
//   float ms_transferDerivative(int kind, vec2 params, float v)   g'(v)
//        kind: MS_TRANSFER_LINEAR / _MOSS / _SPONGE (TransferFunction.code), params = (threshold,
//        softness) in driver units (TransferFunction.param_vector). With e(z) = s ln(1 + e^z):
//        linear g = v; moss g = sqrt(e((v - t)/s)) (rounded tufts on a flat ground);
//        sponge g = -sqrt(e((t - v)/s)) (rounded pits in a flat top). float32: ~3e-6 relative.

const int MS_TRANSFER_LINEAR = 0;
const int MS_TRANSFER_MOSS = 1;
const int MS_TRANSFER_SPONGE = 2;

vec4 ms_transferMoments(sampler2D table, float mu, float sigma, vec3 range) {
    float rows = float(textureSize(table, 0).y);
    float u = (mu - range.x) / (range.y - range.x);
    float v = (clamp(sigma / range.z, 0.0, 1.0) * (rows - 1.0) + 0.5) / rows;
    return textureLod(table, vec2(u, v), 0.0);
}

void ms_transferStats(vec4 moments, vec2 gradMean, vec3 gradCov, out float hMean, out float hVar,
                      out vec2 slopeMean, out vec3 slopeCov) {
    hMean = moments.x;
    hVar = max(moments.y - moments.x * moments.x, 0.0);
    slopeMean = moments.z * gradMean;
    vec3 outer = vec3(gradMean.x * gradMean.x, gradMean.x * gradMean.y, gradMean.y * gradMean.y);
    slopeCov = moments.w * gradCov + max(moments.w - moments.z * moments.z, 0.0) * outer;
}

// ln(1 + x) for x in (0, 1]: float32 1 + x loses x's low bits, so small x take the series.
float ms_transferLog1p(float x) {
    return x < 0.01 ? x * (1.0 - x * (0.5 - x * (1.0 / 3.0 - 0.25 * x))) : log(1.0 + x);
}

// The soft ramp: x = softplus(z) = ln(1 + e^z) and y = sigmoid(z) = d softplus / dz, z >= -60 (beyond,
// both are below 1e-26 and the callers' results below 1e-13).
vec2 ms_transferSoftRamp(float z) {
    float zc = max(z, -60.0);
    float a = exp(-abs(zc));
    float softplus = max(zc, 0.0) + ms_transferLog1p(a);
    float sigmoid = zc >= 0.0 ? 1.0 / (1.0 + a) : a / (1.0 + a);
    return vec2(softplus, sigmoid);
}

float ms_transferZ(int kind, vec2 params, float v) {
    return kind == MS_TRANSFER_MOSS ? (v - params.x) / params.y : (params.x - v) / params.y;
}

float ms_transferValue(int kind, vec2 params, float v) {
    if (kind == MS_TRANSFER_LINEAR) {
        return v;
    }
    float h = sqrt(params.y * ms_transferSoftRamp(ms_transferZ(kind, params, v)).x);
    return kind == MS_TRANSFER_MOSS ? h : -h;
}

float ms_transferDerivative(int kind, vec2 params, float v) {
    if (kind == MS_TRANSFER_LINEAR) {
        return 1.0;
    }
    vec2 ramp = ms_transferSoftRamp(ms_transferZ(kind, params, v));
    return ramp.y / (2.0 * sqrt(params.y * ramp.x));
}
