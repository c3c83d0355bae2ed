// smith.glsl -- Smith masking for Gaussian microsurfaces: Heitz, Nowrouzezahrai, Poulin & Neyret 2014,
// "Filtering non-linear transfer functions on surfaces", §3, eqs. (2), (3) and (12) (DESIGN.md errata).
// Twin of microsurface/smith.py (which documents the derivations and holds the float64 versions).
//
// Conventions
//   w: unit direction in the tangent frame of the coarse surface (normal = +z). Slopes s = grad h of the
//   height field z = h(x, y) are N(mean, Sigma), Sigma passed as cov = vec3(Sxx, Sxy, Syy). Heights are
//   N(0, sigmaH^2) (sigmaH in length units, > 0).
//
// Functions
//   float ms_erfcx(float x)    exp(x^2) erfc(x) for x >= 0 (x < 0 is taken as 0): t exp(P(t)),
//                              t = 1/(1 + x/2), P of degree 9 refitted in smith.py (fit error 9.8e-8).
//   float ms_erfc(float x)     erfc for any x; relative error <= 6.7e-7 on llvmpipe (float32) for
//                              x in [-6, 9.1]; 0 for x > 9.3 (erfc < 2e-39, below the normal floats).
//   float ms_normalPdf(float x), float ms_normalCdf(float x)   phi, Phi of the standard normal.
//   vec3  ms_millsRho(float x) (rho1, rho2, rho3)(x), x >= 0, rho_k = J_k / (k J_{k-1}) with
//                              J_k(x) = int_0^inf t^k exp(-x t - t^2/2) dt: forward recurrence from the
//                              Mills ratio for x < MS_CF_SWITCH, Laplace's continued fraction (depth
//                              MS_CF_DEPTH) above (also used by visible_slopes.glsl).
//   float ms_normalLossScaled(float x)   J_1(x) = (phi(x) - x Q(x)) / phi(x), x >= 0, no cancellation:
//                              1 - x J_0 below MS_LOSS_SWITCH, the continued fraction of depth
//                              MS_LOSS_CF_DEPTH above (relative error <= 7e-6 in float32 either way). It
//                              needs rho1 alone, and Smith's Lambda calls it for every sample and light,
//                              so its fraction is short: llvmpipe ran MS_CF_DEPTH's 22 iterations, masked,
//                              wherever a lane's nu passed MS_CF_SWITCH.
//   float ms_lambda(vec3 w, vec3 cov)    Smith's Lambda (eq. under 2) = G(nu)/nu, nu = w.z/sqrt(w_xy^T
//                              Sigma w_xy), G(nu) = phi(nu) - nu Q(nu). 0 at normal incidence and for
//                              Sigma = 0 (-> 0 without NaN as Sigma -> 0); nu is clamped to >= 1e-4 at
//                              grazing incidence (w.z <= 0 included): Lambda <= 3989.
//   float ms_heightCdf(float h, float sigmaH)              P_h(h) = Phi(h / sigmaH).
//   float ms_visibility(float h, float sigmaH, float lam)  P_h(h)^lam (eq. 2), 1 for lam = 0.
//   float ms_averageVisibility(float lamO, float lamI)     (1 + lamO) / (1 + lamO + lamI) (eq. 12).

const float MS_INV_SQRT_2PI = 0.3989422804;
const float MS_SQRT_HALF_PI = 1.2533141373;
const float MS_INV_SQRT2 = 0.7071067812;
const float MS_NU_MIN = 1e-4;
const float MS_CF_SWITCH = 1.5;
const int MS_CF_DEPTH = 24;
const float MS_LOSS_SWITCH = 4.0;
const int MS_LOSS_CF_DEPTH = 4;

float ms_erfcx(float x) {
    float t = 1.0 / (1.0 + 0.5 * max(x, 0.0));
    float p = 0.16876379;
    p = p * t - 0.8133392;
    p = p * t + 1.4732828;
    p = p * t - 1.12112952;
    p = p * t + 0.2713703;
    p = p * t - 0.18397321;
    p = p * t + 0.09638966;
    p = p * t + 0.37412486;
    p = p * t + 1.00002266;
    p = p * t - 1.26551222;
    return t * exp(p);
}

// exp(-x^2) for x >= 0, to a few ulp where it is a normal float (0 for x > 9.3): x = xh + xl with xh a
// multiple of 1/16, and the base-2 exponent split into an exact integer n and a small remainder (exp of a
// large rounded argument would lose ~x^2 ulp). 2^-n is built from its bits: the compiler would fuse
// exp2(-f) * exp2(-n) back into one exp2.
float ms_expNegSq(float x) {
    if (x > 9.3) {
        return 0.0;
    }
    float xh = floor(x * 16.0) / 16.0;
    float xl = x - xh;
    float a = xh * xh;        // exact: xh has at most 8 significant bits
    float b = a * 1.4453125;  // exact: log2(e) = 185/128 - 2.6174591e-3, 185 has 8 bits
    float n = floor(b);       // <= 125
    float f = (b - n) + (a * -2.6174591e-3 + xl * (x + xh) * 1.4426950409);
    return exp2(-f) * intBitsToFloat((127 - int(n)) << 23);
}

float ms_erfc(float x) {
    float ax = abs(x);
    float e = ms_erfcx(ax) * ms_expNegSq(ax);
    return x >= 0.0 ? e : 2.0 - e;
}

float ms_normalPdf(float x) {
    return MS_INV_SQRT_2PI * exp(-0.5 * x * x);
}

float ms_normalCdf(float x) {
    return 0.5 * ms_erfc(-x * MS_INV_SQRT2);
}

// (rho1, rho2, rho3)(x) by Laplace's continued fraction of the given depth: rho_{D+1} from the fixed point of
// rho = 1 / (x + (D + 2) rho), then down to rho_3
vec3 ms_millsRhoFraction(float x, int depth) {
    float r = 2.0 / (x + sqrt(x * x + 4.0 * float(depth + 2)));
    for (int j = depth; j >= 3; --j) {
        r = 1.0 / (x + float(j + 1) * r);
    }
    float r2 = 1.0 / (x + 3.0 * r);
    return vec3(1.0 / (x + 2.0 * r2), r2, r);
}

vec3 ms_millsRho(float x) {
    x = max(x, 0.0);
    if (x < MS_CF_SWITCH) {
        float j0 = MS_SQRT_HALF_PI * ms_erfcx(x * MS_INV_SQRT2);  // the Mills ratio Q(x) / phi(x)
        float j1 = 1.0 - x * j0;
        float j2 = j0 - x * j1;
        float j3 = 2.0 * j1 - x * j2;
        return vec3(j1 / j0, j2 / (2.0 * j1), j3 / (3.0 * j2));
    }
    return ms_millsRhoFraction(x, MS_CF_DEPTH);
}

float ms_normalLossScaled(float x) {
    x = max(x, 0.0);
    if (x < MS_LOSS_SWITCH) {
        return 1.0 - x * MS_SQRT_HALF_PI * ms_erfcx(x * MS_INV_SQRT2);
    }
    float r1 = ms_millsRhoFraction(x, MS_LOSS_CF_DEPTH).x;
    return r1 / (x + r1);  // R = 1 / (x + rho1), J_1 = R rho1
}

float ms_lambda(vec3 w, vec3 cov) {
    float q = w.x * w.x * cov.x + 2.0 * w.x * w.y * cov.y + w.y * w.y * cov.z;  // (sigma_s |w_xy|)^2
    if (!(q > 0.0)) {
        return 0.0;
    }
    float nu = max(w.z / sqrt(q), MS_NU_MIN);
    return ms_normalPdf(nu) * ms_normalLossScaled(nu) / nu;
}

float ms_heightCdf(float h, float sigmaH) {
    return ms_normalCdf(h / sigmaH);
}

float ms_visibility(float h, float sigmaH, float lam) {
    float p = ms_heightCdf(h, sigmaH);
    if (lam <= 0.0) {
        return 1.0;
    }
    return p > 0.0 ? exp2(lam * log2(p)) : 0.0;
}

float ms_averageVisibility(float lamO, float lamI) {
    return (1.0 + lamO) / (1.0 + lamO + lamI);
}

// Smith's shadowing over a sphere of radius R (curved_shadowing.py; beyond the paper): a ray's altitude over
// the macro surface grows by t²/2R, so relief of height deviation sigma sees its slope μ = ω.z / |ω.xy|
// raised to μ_e = (μ⁺ + sqrt(μ⁺² + 4kσ/R)) / 2 (k fitted to a ray cast over curving fBm). Returns ω with
// that slope (unit length).
vec3 ms_curvedLight(vec3 w, float sigma, float radius, float k) {
    float across = length(w.xy);
    if (across < 1e-6) return w;
    float mu = max(w.z / across, 0.0);
    float raised = 0.5 * (mu + sqrt(mu * mu + 4.0 * k * sigma / radius));
    return normalize(vec3(w.xy, raised * across));
}

// Below the horizon (μ < 0) the ray first dives μ²R/2 under its start before it climbs: the share of the
// light that clears the dive, exp(-μ²R / 2bσ); 1 at and above the horizon.
float ms_curvedDescent(vec3 w, float sigma, float radius, float b) {
    float mu = min(w.z / max(length(w.xy), 1e-6), 0.0);
    return exp(-mu * mu * radius / (2.0 * b * max(sigma, 1e-12)));
}
