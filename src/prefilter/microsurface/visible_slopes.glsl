// visible_slopes.glsl -- the view-dependent slope filtering distribution D_s of a Gaussian microsurface,
// Heitz, Nowrouzezahrai, Poulin & Neyret 2014 §5.2, eq. (18), and a 9-node Gauss-Hermite cubature over
// slopes. Twin of microsurface/visible_slopes.py, which holds the derivation (ours: the paper's is in its
// supplemental document):
//     D_s(s) ∝ max(o_z - dot(s, o_xy), 0) N(s; mean, Sigma)
// (projected facet area towards wo; Smith masking is independent of slope and cancels). With
// sigma_u^2 = o_xy^T Sigma o_xy, a = (o_z - dot(o_xy, mean)) / sigma_u and (zbar, var_z) the mean and
// variance of (a - z)^+ phi(z):
//     visMean = mean + Sigma o_xy zbar / sigma_u,   visCov = Sigma - (1 - var_z) Sigma o_xy o_xy^T Sigma / sigma_u^2.
//
// Conventions: wo unit view direction in the tangent frame (normal = +z); slopes s = grad h ~ N(mean,
// Sigma), cov = vec3(Sxx, Sxy, Syy).
//
// Functions
//   vec3  ms_visibleSlopeMoments1D(float a)   (zbar, var_z, m0) of (a - z)^+ phi(z), m0 its mass
//         a Phi(a) + phi(a); a < 0 through the Mills continued fraction of smith.glsl (no cancellation); a
//         clamped to [-1e4, 1e4].
//   float ms_visibleSlopes(vec3 wo, vec2 mean, vec3 cov, out vec2 visMean, out vec3 visCov)
//         mean and covariance (packed like cov) of D_s; D_s = p_s (visMean = mean, visCov = cov) when
//         sigma_u^2 <= 1e-30 (normal view, or no slope variance along o_xy). Returns E[max(o_z - dot(s,
//         o_xy), 0)], the projected area (integral of max(cos theta_o, 0) dA) per unit macro area, D_s's
//         normalisation: sigma_u m0(a) = c Phi(a) + sigma_u phi(a), c = o_z - dot(o_xy, mean); max(c, 0)
//         when sigma_u = 0. One evaluation of the normal functions serves both (the shading samples call
//         it for every sample; a separate area function cost a second one).
//   vec3  ms_lambertNode(vec2 mean, vec2 offset, float weight, vec3 wi)   one node of the cubature below:
//         weight L(mean + offset) and that times offset.
//   vec3  ms_lambertMoments(vec2 mean, vec3 cov, vec3 wi)   (E[L], Cov(s, L)) of Lambert's cosine
//         L(s) = max(n(s)·wi, 0), n(s) = normalize(-s, 1), for slopes N(mean, Sigma), by the 3x3
//         Gauss-Hermite cubature against N(mean, Sigma) (visible_slopes.py, gauss_hermite_2d): nodes
//         mean + L (z_i, z_j), L the lower Cholesky factor of Sigma (semidefinite allowed), z in {-sqrt(3),
//         0, sqrt(3)}, weights w_i w_j with w = (1/6, 2/3, 1/6); exact for polynomials of degree <= 5 in
//         each slope. The nine nodes are written out: as a loop (llvmpipe does not unroll it) the shading
//         samples paid 0.02-0.04x naive's frame more on micro-snake-sphere (one light, four samples; the
//         same image), and a loop with the Cholesky factor taken out of it saved nothing.

#include "microsurface/smith.glsl"

vec3 ms_visibleSlopeMoments1D(float a) {
    a = clamp(a, -1e4, 1e4);
    float pdf = ms_normalPdf(a);
    if (a >= 0.0) {
        float cdf = ms_normalCdf(a);
        float m0 = a * cdf + pdf;
        float zbar = -cdf / m0;
        return vec3(zbar, (a * cdf + 2.0 * pdf) / m0 - zbar * zbar, m0);
    }
    // t = a - z >= 0 has the density ∝ t exp(-x t - t^2 / 2), x = -a: mean 2 rho2, var 2 rho2 (3 rho3 - 2 rho2);
    // m0 = phi(a) J_1(x) with J_1 = rho1 / (x + rho1) (J_1 = 1 - x J_0 and rho1 = J_1 / J_0)
    vec3 rho = ms_millsRho(-a);
    return vec3(a - 2.0 * rho.y, 2.0 * rho.y * (3.0 * rho.z - 2.0 * rho.y), pdf * rho.x / (rho.x - a));
}

float ms_visibleSlopes(vec3 wo, vec2 mean, vec3 cov, out vec2 visMean, out vec3 visCov) {
    vec2 v = wo.xy;
    vec2 sv = vec2(cov.x * v.x + cov.y * v.y, cov.y * v.x + cov.z * v.y);  // Sigma o_xy
    float su2 = dot(v, sv);
    visMean = mean;
    visCov = cov;
    float c = wo.z - dot(v, mean);
    if (!(su2 > 1e-30)) {
        return max(c, 0.0);
    }
    float su = sqrt(su2);
    vec3 m = ms_visibleSlopeMoments1D(c / su);
    visMean = mean + sv * (m.x / su);
    float k = (1.0 - m.y) / su2;
    visCov = cov - k * vec3(sv.x * sv.x, sv.x * sv.y, sv.y * sv.y);
    return su * m.z;
}

// One node of the cubature: its weight times Lambert's cosine, and that times the node's offset from the mean.
vec3 ms_lambertNode(vec2 mean, vec2 offset, float weight, vec3 wi) {
    float cosine = weight * max(dot(normalize(vec3(-(mean + offset), 1.0)), wi), 0.0);
    return vec3(cosine, cosine * offset);
}

vec3 ms_lambertMoments(vec2 mean, vec3 cov, vec3 wi) {
    float l11 = sqrt(max(cov.x, 0.0));
    float l21 = l11 > 0.0 ? cov.y / l11 : 0.0;
    float l22 = sqrt(max(cov.z - l21 * l21, 0.0));
    const float Z = 1.7320508076;  // sqrt(3)
    const float W0 = 2.0 / 3.0, W1 = 1.0 / 6.0;
    vec2 a = Z * vec2(l11, l21), b = vec2(0.0, Z * l22);
    vec3 moments = ms_lambertNode(mean, -a - b, W1 * W1, wi);
    moments += ms_lambertNode(mean, -a, W1 * W0, wi);
    moments += ms_lambertNode(mean, -a + b, W1 * W1, wi);
    moments += ms_lambertNode(mean, -b, W0 * W1, wi);
    moments += ms_lambertNode(mean, vec2(0.0), W0 * W0, wi);
    moments += ms_lambertNode(mean, b, W0 * W1, wi);
    moments += ms_lambertNode(mean, a - b, W1 * W1, wi);
    moments += ms_lambertNode(mean, a, W1 * W0, wi);
    moments += ms_lambertNode(mean, a + b, W1 * W1, wi);
    return moments;
}
