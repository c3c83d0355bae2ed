// noise.glsl -- Perlin's improved gradient noise in 3D, its analytic gradient, and linear noise.
//
// nz_noise(p)            Perlin, "Improving Noise", SIGGRAPH 2002: the function of his reference Java
//                        ImprovedNoise.noise(x, y, z) -- the same 256-entry permutation, the 12 edge
//                        gradients (padded to 16) chosen by hash & 15, the quintic fade
//                        6t^5 - 15t^4 + 10t^3 and lerp. Evaluated in float32 here; the float64 twin is
//                        prefilter.procedural.noise.perlin_noise. Range |n| <= 1.5 (about +-1 in practice),
//                        zero on integer lattice points, period 256 lattice units along each axis.
// nz_noiseGrad(p)        vec4(dn/dx, dn/dy, dn/dz, n): the analytic gradient, the function DNoise of
//                        Hart et al. 1999, "Antialiased parameterized solid texturing simplified for
//                        consumer-level hardware implementation", eq. (12). It shares the hashing and the
//                        corner dot products with the value, and its .w equals nz_noise(p).
// nz_noiseGradCurv(p, e1, e2, out curvature)
//                        the same vec4, and e1^T H e1 + e2^T H e2 with H the analytic Hessian of the noise at
//                        p (quintic fade: the noise is C2). Over a box footprint spanned by e1, e2 (lattice
//                        units) the mean of n is n(p) + curvature / 24 to second order; procedural/hart.glsl
//                        centres its filters with it. Tested against central differences of the float64 twin
//                        (prefilter.procedural.noise.footprint_curvature).
// nz_linearNoise(p)      the same corner contributions blended trilinearly (fade(t) = t): the reduced noise of
// nz_linearNoiseGrad(p)  Hart's "100,000-gate" implementation (section 4.2, Fig. 11). It is only C0, so the
// nz_linearNoiseGradCurv lattice is visible and the gradient jumps across cell faces (its curvature is
//                        that of the interior of the cell: only the cross terms of the trilinear weights).
//
// Parameters: p, a point in lattice units (one cell = 1). Scale and offset it (Hart's T_i) before the call
// and chain-rule the gradient. float32 keeps about 24 - log2|p| bits for the position inside the cell, so
// keep |p| well below 2^16 (the lattice repeats every 256 units; wrap p with mod(p, 256.0) if need be).
//
// The permutation lives in a const int array indexed with `& 255`: it needs no sampler binding and on Mesa
// llvmpipe (LLVM 15, 256-bit, 2 cores) it is 2.5x faster than a 256x1 texture read with texelFetch.
// A 512x512 fragment shader with 8 nz_noise calls per pixel took 11.5 ms with the const array, 29 ms with
// an R32I and 36 ms with an R8UI texture; 8 nz_noiseGrad calls took 14.2 ms (const array). Selecting the
// gradient vector arithmetically (nz_gradCorner) beat a const vec3[16] table (22.6 ms for nz_noiseGrad).
// Needs `precision highp int` on GLSL ES (32-bit two's complement ints).
//
// Entry i of the array holds the pair P[i] | P[(i + 1) & 255] << 8, P Perlin's permutation: the hash always
// reads P[k] and P[k + 1] together, so a cell's 8 corner hashes take 7 gathers instead of 14. Bit-identical
// images, and faster noise-driven frames (2026-12-05, round-robin in one process, new / old time: `point`
// 0.85 on marble-teapot, 0.87 on planet, 0.88 on fire, 0.96 on wood-teapot; every mode of
// micro-heights-sphere 0.85-0.86). The hashes are checked against Perlin's table in tests/test_noise.py.
const int NZ_PERM_PAIRS[256] = int[256](
    41111, 35232, 23433, 23131, 3930, 33551, 3459, 51469, 24521, 24671, 13664, 49717, 59842, 2025, 57607, 36065,
    9356, 26404, 7783, 17694, 36421, 2190, 25352, 9571, 61477, 5616, 2581, 5898, 48663, 1726, 37894, 63380,
    30967, 60024, 19434, 75, 6656, 50458, 16069, 24126, 64606, 56316, 52187, 30155, 9077, 2851, 8203, 14624,
    45369, 8625, 22561, 60760, 38381, 14485, 22328, 44631, 5294, 32020, 34941, 43912, 43179, 17576, 44868, 19119,
    42314, 18341, 34375, 35718, 12427, 6960, 42523, 19878, 37453, 40594, 59294, 21479, 28499, 58735, 31461, 15482,
    54076, 34259, 59013, 56550, 27100, 23657, 10588, 14121, 11831, 62766, 10485, 62504, 26356, 36710, 13967, 16694,
    6465, 16153, 41279, 417, 55297, 20696, 18768, 53577, 19665, 33868, 48004, 53435, 22992, 4697, 43282, 51369,
    50376, 34756, 33415, 29826, 48244, 40892, 22175, 42070, 25764, 28004, 50797, 44486, 47789, 954, 16387, 13376,
    55604, 58073, 64226, 31994, 31612, 1403, 51717, 9930, 37670, 30355, 32374, 65406, 21247, 21842, 54357, 53204,
    52943, 15310, 58171, 12259, 4143, 14864, 4410, 46609, 48566, 7357, 10780, 57130, 47071, 43703, 54698, 30677,
    63607, 39160, 664, 11266, 39468, 41882, 18083, 56646, 39389, 26009, 39781, 42907, 11175, 44075, 2476, 33033,
    5761, 10006, 64807, 5117, 25107, 27746, 28268, 20334, 29007, 57457, 59616, 45800, 47538, 28857, 26736, 55912,
    63194, 25078, 58465, 64484, 8955, 61986, 49650, 61121, 53998, 37074, 3216, 48908, 46015, 41651, 61858, 20977,
    13137, 37171, 60305, 63979, 3833, 61198, 27631, 12651, 49201, 54976, 8150, 46367, 51125, 27335, 40298, 47261,
    21688, 52308, 45260, 29616, 31091, 12921, 11570, 32557, 1151, 38404, 65174, 35582, 60554, 52716, 24013, 56925,
    29406, 17266, 7491, 6173, 18456, 62280, 36339, 32909, 50048, 20163, 16974, 55106, 15831, 39997, 46236, 38836);

// Hashes of the 8 corners of the cell whose lower corner is the lattice point `cell` (any integer values):
// lo = (h000, h100, h010, h110), hi = (h001, h101, h011, h111), h_ijk = P[P[P[X+i] + Y+j] + Z+k].
void nz_hash(ivec3 cell, out ivec4 lo, out ivec4 hi) {
    ivec3 c = cell & 255;
    int x = NZ_PERM_PAIRS[c.x];                                  // P[X], P[X + 1]
    int a = (x & 255) + c.y;
    int b = (x >> 8) + c.y;
    int pa = NZ_PERM_PAIRS[a & 255], pb = NZ_PERM_PAIRS[b & 255];  // P[A], P[A + 1]; P[B], P[B + 1]
    ivec4 l = ivec4(pa & 255, pb & 255, pa >> 8, pb >> 8) + c.z;  // AA, BA, AB, BB
    ivec4 z = ivec4(NZ_PERM_PAIRS[l.x & 255], NZ_PERM_PAIRS[l.y & 255], NZ_PERM_PAIRS[l.z & 255],
                    NZ_PERM_PAIRS[l.w & 255]);
    lo = z & 255;
    hi = z >> 8;
}

// Perlin's grad(hash, x, y, z): the dot product of gradient number hash & 15 with d.
float nz_grad(int h, vec3 d) {
    int k = h & 15;
    float u = k < 8 ? d.x : d.y;
    float v = k < 4 ? d.y : ((k == 12 || k == 14) ? d.x : d.z);
    return ((k & 1) == 0 ? u : -u) + ((k & 2) == 0 ? v : -v);
}

// vec4(g, g . d) for gradient number hash & 15 (the same vectors as nz_grad, built from its selects).
vec4 nz_gradCorner(int h, vec3 d) {
    int k = h & 15;
    float su = (k & 1) == 0 ? 1.0 : -1.0;
    float sv = (k & 2) == 0 ? 1.0 : -1.0;
    bool vx = k == 12 || k == 14;
    vec3 g = vec3(k < 8 ? su : (vx ? sv : 0.0), k < 8 ? (k < 4 ? sv : 0.0) : su, (k < 4 || vx) ? 0.0 : sv);
    return vec4(g, dot(g, d));
}

vec3 nz_fade(vec3 t) {
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
}

vec3 nz_fadeDerivative(vec3 t) {
    return 30.0 * t * t * (t * (t - 2.0) + 1.0);
}

// Value: blend of the 8 corner contributions with weights w (fade(f) or f), f = position in the cell.
float nz_blend(ivec4 lo, ivec4 hi, vec3 f, vec3 w) {
    vec3 e = f - 1.0;
    vec4 c0 = vec4(nz_grad(lo.x, f), nz_grad(lo.y, vec3(e.x, f.y, f.z)),
                   nz_grad(lo.z, vec3(f.x, e.y, f.z)), nz_grad(lo.w, vec3(e.x, e.y, f.z)));
    vec4 c1 = vec4(nz_grad(hi.x, vec3(f.x, f.y, e.z)), nz_grad(hi.y, vec3(e.x, f.y, e.z)),
                   nz_grad(hi.z, vec3(f.x, e.y, e.z)), nz_grad(hi.w, e));
    vec4 a = mix(vec4(c0.x, c0.z, c1.x, c1.z), vec4(c0.y, c0.w, c1.y, c1.w), w.x);  // a00, a10, a01, a11
    vec2 b = mix(a.xz, a.yw, w.y);                                                  // b0, b1
    return mix(b.x, b.y, w.z);
}

// vec4(g_k, g_k . (f - k)) of the 8 corners k of the cell (hashes lo, hi as nz_hash orders them).
struct NzCorners {
    vec4 g000, g100, g010, g110, g001, g101, g011, g111;
};

NzCorners nz_corners(ivec4 lo, ivec4 hi, vec3 f) {
    vec3 e = f - 1.0;
    return NzCorners(nz_gradCorner(lo.x, f), nz_gradCorner(lo.y, vec3(e.x, f.y, f.z)),
                     nz_gradCorner(lo.z, vec3(f.x, e.y, f.z)), nz_gradCorner(lo.w, vec3(e.x, e.y, f.z)),
                     nz_gradCorner(hi.x, vec3(f.x, f.y, e.z)), nz_gradCorner(hi.y, vec3(e.x, f.y, e.z)),
                     nz_gradCorner(hi.z, vec3(f.x, e.y, e.z)), nz_gradCorner(hi.w, e));
}

// Value and gradient. Corner k carries vec4(g_k, c_k) with c_k = g_k . (f - k); one chain of vec4 mixes
// gives both the trilinear blend of the gradients (.xyz) and the value (.w, the same mixes as nz_blend);
// the differences of the c_k along each axis, times dw = weight'(f), add the slope of the weights.
vec4 nz_blendGrad(ivec4 lo, ivec4 hi, vec3 f, vec3 w, vec3 dw) {
    NzCorners c = nz_corners(lo, hi, f);
    vec4 g000 = c.g000, g100 = c.g100, g010 = c.g010, g110 = c.g110;
    vec4 g001 = c.g001, g101 = c.g101, g011 = c.g011, g111 = c.g111;
    vec4 a00 = mix(g000, g100, w.x);
    vec4 a10 = mix(g010, g110, w.x);
    vec4 a01 = mix(g001, g101, w.x);
    vec4 a11 = mix(g011, g111, w.x);
    vec4 b0 = mix(a00, a10, w.y);
    vec4 b1 = mix(a01, a11, w.y);
    vec4 n = mix(b0, b1, w.z);
    vec4 dx = vec4(g100.w, g110.w, g101.w, g111.w) - vec4(g000.w, g010.w, g001.w, g011.w);
    vec2 dxy = mix(dx.xz, dx.yw, w.y);
    vec3 slope = vec3(mix(dxy.x, dxy.y, w.z), mix(a10.w - a00.w, a11.w - a01.w, w.z), b1.w - b0.w);
    return vec4(n.xyz + dw * slope, n.w);
}

float nz_noise(vec3 p) {
    vec3 cell = floor(p);
    vec3 f = p - cell;
    ivec4 lo, hi;
    nz_hash(ivec3(cell), lo, hi);
    return nz_blend(lo, hi, f, nz_fade(f));
}

vec4 nz_noiseGrad(vec3 p) {
    vec3 cell = floor(p);
    vec3 f = p - cell;
    ivec4 lo, hi;
    nz_hash(ivec3(cell), lo, hi);
    return nz_blendGrad(lo, hi, f, nz_fade(f), nz_fadeDerivative(f));
}

float nz_linearNoise(vec3 p) {
    vec3 cell = floor(p);
    vec3 f = p - cell;
    ivec4 lo, hi;
    nz_hash(ivec3(cell), lo, hi);
    return nz_blend(lo, hi, f, f);
}

vec4 nz_linearNoiseGrad(vec3 p) {
    vec3 cell = floor(p);
    vec3 f = p - cell;
    ivec4 lo, hi;
    nz_hash(ivec3(cell), lo, hi);
    return nz_blendGrad(lo, hi, f, f, vec3(1.0));
}

vec3 nz_fadeSecondDerivative(vec3 t) {
    return 60.0 * t * (t * (2.0 * t - 3.0) + 1.0);
}

// Value, gradient and the footprint curvature tr(M H) = e1^T H e1 + e2^T H e2, H the Hessian of the noise
// at p, M = e1 e1^T + e2 e2^T. With W_k the product of corner k's weights and (g_k, c_k) its gradient and
// c_k = g_k . (f - k): H = sum_k c_k d2W_k + dW_k g_k^T + g_k dW_k^T. Along axis a, dW is w'(f_a) times
// the difference of the corner data across a (blended along the other axes), D_a; d2W is w''(f_a) D_a on
// the diagonal and w'(f_a) w'(f_b) D_ab (the difference across both axes) off it. So
//   tr(M H) = sum_a M_aa w''_a D_a[c] + 2 sum_{a<b} M_ab w'_a w'_b D_ab[c] + 2 sum_a w'_a (M D_a[g])_a.
vec4 nz_blendGradCurv(ivec4 lo, ivec4 hi, vec3 f, vec3 w, vec3 dw, vec3 d2w, vec3 e1, vec3 e2,
                      out float curvature) {
    NzCorners c = nz_corners(lo, hi, f);
    vec4 g000 = c.g000, g100 = c.g100, g010 = c.g010, g110 = c.g110;
    vec4 g001 = c.g001, g101 = c.g101, g011 = c.g011, g111 = c.g111;
    vec4 x00 = g100 - g000, x10 = g110 - g010, x01 = g101 - g001, x11 = g111 - g011;  // across x
    vec4 a00 = g000 + w.x * x00, a10 = g010 + w.x * x10, a01 = g001 + w.x * x01, a11 = g011 + w.x * x11;
    vec4 b0 = mix(a00, a10, w.y);
    vec4 b1 = mix(a01, a11, w.y);
    vec4 n = mix(b0, b1, w.z);
    vec4 y0 = a10 - a00, y1 = a11 - a01;  // across y
    vec4 dx = mix(mix(x00, x10, w.y), mix(x01, x11, w.y), w.z);
    vec4 dy = mix(y0, y1, w.z);
    vec4 dz = b1 - b0;
    float dxy = mix(x10.w - x00.w, x11.w - x01.w, w.z);
    float dxz = mix(x01.w, x11.w, w.y) - mix(x00.w, x10.w, w.y);
    float dyz = y1.w - y0.w;
    mat3 m = outerProduct(e1, e1) + outerProduct(e2, e2);
    vec3 slope = vec3(dx.w, dy.w, dz.w);
    curvature = dot(vec3(m[0][0], m[1][1], m[2][2]) * d2w, slope)
              + 2.0 * dot(vec3(m[1][0], m[2][0], m[2][1]), vec3(dw.x * dw.y * dxy, dw.x * dw.z * dxz, dw.y * dw.z * dyz))
              + 2.0 * dot(dw, vec3(dot(m[0], dx.xyz), dot(m[1], dy.xyz), dot(m[2], dz.xyz)));
    return vec4(n.xyz + dw * slope, n.w);
}

vec4 nz_noiseGradCurv(vec3 p, vec3 e1, vec3 e2, out float curvature) {
    vec3 cell = floor(p);
    vec3 f = p - cell;
    ivec4 lo, hi;
    nz_hash(ivec3(cell), lo, hi);
    return nz_blendGradCurv(lo, hi, f, nz_fade(f), nz_fadeDerivative(f), nz_fadeSecondDerivative(f), e1, e2,
                            curvature);
}

vec4 nz_linearNoiseGradCurv(vec3 p, vec3 e1, vec3 e2, out float curvature) {
    vec3 cell = floor(p);
    vec3 f = p - cell;
    ivec4 lo, hi;
    nz_hash(ivec3(cell), lo, hi);
    return nz_blendGradCurv(lo, hi, f, f, vec3(1.0), vec3(0.0), e1, e2, curvature);
}
