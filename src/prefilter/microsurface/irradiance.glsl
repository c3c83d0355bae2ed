// irradiance.glsl -- irradiance environment maps in 9 spherical-harmonic coefficients (Ramamoorthi &
// Hanrahan 2001, eqs. 7-9 and 13), filtered over the slopes of a microsurface (Heitz, Nowrouzezahrai,
// Poulin & Neyret 2014, §5.3).
//
// What it computes
//   E(n) = sum_{l<=2} sum_m A_l L_lm Y_lm(n), A_0 = pi, A_1 = 2 pi / 3, A_2 = pi / 4: the (unshadowed)
//   irradiance of a surface with unit world normal n under distant lighting with SH9 radiance
//   coefficients L_lm. A Lambertian surface of albedo rho reflects radiance rho * E / pi. Not clamped:
//   it can be slightly negative facing away from a strong sun (see irradiance.py for measured errors).
//   The filtered irradiance on a Gaussian microsurface is E_s[E(n(s))] over micro-slopes
//   s ~ N(mean, cov) (the view-dependent visible-slope distribution, computed by the caller), with
//   n(s) = normalize(worldFromTangent * vec3(-s, 1)), by 3 x 3 Gauss-Hermite cubature through the
//   Cholesky factor of cov (nodes 0, +-sqrt(3); weights 2/3, 1/6 per axis).
//
// Conventions (shared with microsurface/irradiance.py, which projects the maps and holds the oracles)
//   - coeffs[k], k = l*l + l + m, in the order (0,0) (1,-1) (1,0) (1,1) (2,-2) (2,-1) (2,0) (2,1) (2,2);
//     RGB linear radiance; real SH of RH2001 eq. 3 without Condon-Shortley phase (Y_11 = +0.488603 x).
//     Upload from Python with sh_uniform(coeffs) to a `uniform vec3 name[9]` and pass the array here.
//   - World +z is up; equirect maps have row 0 at the zenith, longitude 0 at +x increasing towards +y.
//   - worldFromTangent: columns are the tangent, bitangent and macro-normal in world space.
//   - cov = vec3(var_x, cov_xy, var_y) of the slopes (dimensionless); cov = 0 gives E at the mean normal.
//
// Functions
//   vec3 ms_irradianceSH(vec3 coeffs[9], vec3 n)
//   vec3 ms_irradianceSHMoments(vec3 coeffs[9], float w, vec3 n, vec3 sq, vec3 products): E summed
//     over normals, from their weighted monomials
//   vec3 ms_filteredIrradianceSH(vec3 coeffs[9], mat3 worldFromTangent, vec2 mean, vec3 cov)
//   vec3 ms_filteredIrradianceMomentsSH(..., vec2 direction, out vec3 covariance): also Cov(s·d, E)

// A_l times the constant of Y_lm (RH2001 eq. 13: 2 c2, 2 c1, c4, c5, c1).
const float MS_SH_K0 = 0.886226925;   // pi * 0.282095
const float MS_SH_K1 = 1.023326708;   // (2 pi / 3) * 0.488603
const float MS_SH_K2 = 0.858085531;   // (pi / 4) * 1.092548 (xy, yz, xz)
const float MS_SH_K20 = 0.247707956;  // (pi / 4) * 0.315392 (3 z^2 - 1)
const float MS_SH_K22 = 0.429042765;  // (pi / 4) * 0.546274 (x^2 - y^2)

// E is a quadratic polynomial in n, so it is linear in n's monomials: given the weighted moments of a set of
// normals (w = sum of the weights, n = sum of w n, sq = sum of w (x², y², z²), products = sum of
// w (xy, yz, zx)) this is the weighted sum of E over them. One normal of weight 1 gives E(n).
vec3 ms_irradianceSHMoments(vec3 coeffs[9], float w, vec3 n, vec3 sq, vec3 products) {
    return MS_SH_K0 * w * coeffs[0]
        + MS_SH_K1 * (n.y * coeffs[1] + n.z * coeffs[2] + n.x * coeffs[3])
        + MS_SH_K2 * (products.x * coeffs[4] + products.y * coeffs[5] + products.z * coeffs[7])
        + MS_SH_K20 * (3.0 * sq.z - w) * coeffs[6]
        + MS_SH_K22 * (sq.x - sq.y) * coeffs[8];
}

vec3 ms_irradianceSH(vec3 coeffs[9], vec3 n) {
    return ms_irradianceSHMoments(coeffs, 1.0, n, n * n, n * n.yzx);
}

// Ē and, in `covariance`, Cov(s·d, E(n(s))) per channel for a slope direction d (the same nodes): what a
// colour tied to the slope along d adds where it correlates with the irradiance (microsurface.frag).
// The nodes' normals are summed as monomials and E is evaluated once on the sums (ms_irradianceSHMoments):
// the same cubature as evaluating E at every node, for much less work.
vec3 ms_filteredIrradianceMomentsSH(vec3 coeffs[9], mat3 worldFromTangent, vec2 mean, vec3 cov, vec2 direction,
                                    out vec3 covariance) {
    // Cholesky factor [l11 0; l21 l22] of [[xx, xy], [xy, yy]], clamped to positive semi-definite.
    float l11 = sqrt(max(cov.x, 0.0));
    float l21 = l11 > 0.0 ? cov.y / l11 : 0.0;
    float l22 = sqrt(max(cov.z - l21 * l21, 0.0));
    // the nodes' weighted monomials, and the same weighted by (s - mean)·d; the weights' own sums are 1 and
    // 0 (they sum to 1, and the nodes are symmetric about the mean)
    vec3 n1 = vec3(0.0), sq = vec3(0.0), products = vec3(0.0);
    vec3 nd = vec3(0.0), sqd = vec3(0.0), productsd = vec3(0.0);
    for (int i = 0; i < 3; ++i) {
        float xi = 1.7320508 * float(i - 1);
        float wi = i == 1 ? 0.6666667 : 0.16666667;
        for (int j = 0; j < 3; ++j) {
            float xj = 1.7320508 * float(j - 1);
            float wj = j == 1 ? 0.6666667 : 0.16666667;
            vec2 offset = vec2(l11 * xi, l21 * xi + l22 * xj);
            vec3 n = normalize(worldFromTangent * vec3(-(mean + offset), 1.0));
            float w = wi * wj;
            vec3 wn = w * n, wsq = wn * n, wproducts = wn * n.yzx;
            n1 += wn;
            sq += wsq;
            products += wproducts;
            float along = dot(offset, direction);
            nd += along * wn;
            sqd += along * wsq;
            productsd += along * wproducts;
        }
    }
    covariance = ms_irradianceSHMoments(coeffs, 0.0, nd, sqd, productsd);
    return ms_irradianceSHMoments(coeffs, 1.0, n1, sq, products);
}

vec3 ms_filteredIrradianceSH(vec3 coeffs[9], mat3 worldFromTangent, vec2 mean, vec3 cov) {
    vec3 unused;
    return ms_filteredIrradianceMomentsSH(coeffs, worldFromTangent, mean, cov, vec2(0.0), unused);
}
