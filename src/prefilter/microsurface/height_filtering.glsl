// height_filtering.glsl -- the height filtering distribution of a Gaussian microsurface, Heitz,
// Nowrouzezahrai, Poulin & Neyret 2014 §5.1, eqs. (14)-(17): D_h(h) ∝ P_h(h)^L p_h(h), L = Lambda_o +
// Lambda_i >= 0 (ms_lambda in smith.glsl), approximated by N(mu_d, sigma_d^2). Twin of
// microsurface/height_filtering.py, which bakes the table and documents the accuracy.
//
// Functions (results in units of sigma_h: multiply by the height standard deviation)
//   vec2 ms_heightFiltering(sampler2D table, float L)   (mu_d / sigma_h, sigma_d / sigma_h), exact moments
//        (quadrature) linearly interpolated in t = log(1 + L) / log(1 + MS_HF_LMAX) from the n x 1 RG32F
//        table of height_filtering_table() (LINEAR, clamp-to-edge; entry i at t = i / (n - 1), read with
//        half-texel remapping u = (t (n - 1) + 0.5) / n). Within 5e-5 sigma_h of the quadrature for
//        L in [0, MS_HF_LMAX]; L > MS_HF_LMAX returns the last entry (see height_filtering.py).
//   vec2 ms_heightFilteringFit(float L)   the paper's log fits, eqs. (16)/(17), alpha_mu = 0.39,
//        beta_mu = 4.75, alpha_sigma = 0.26, beta_sigma = 1.13 (up to 0.13 sigma_h off in mu_d for
//        L in [0, 100]; for comparison only).
//
// Defines: MS_HF_LMAX (float, default 10000.0), the L_max the table was baked with.

#ifndef MS_HF_LMAX
#define MS_HF_LMAX 10000.0
#endif

vec2 ms_heightFiltering(sampler2D table, float L) {
    float n = float(textureSize(table, 0).x);
    float t = clamp(log(1.0 + max(L, 0.0)) / log(1.0 + MS_HF_LMAX), 0.0, 1.0);
    return textureLod(table, vec2((t * (n - 1.0) + 0.5) / n, 0.5), 0.0).xy;
}

vec2 ms_heightFilteringFit(float L) {
    L = max(L, 0.0);
    float mu = 0.39 * log(4.75 * L + 1.0);
    float sigma = 1.0 / (1.0 + 0.26 * log(1.13 * L + 1.0));
    return vec2(mu, sigma);
}
