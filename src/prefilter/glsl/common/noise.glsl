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

const int NZ_PERM[256] = int[256](
    151, 160, 137, 91, 90, 15, 131, 13, 201, 95, 96, 53, 194, 233, 7, 225, 140, 36, 103, 30,
    69, 142, 8, 99, 37, 240, 21, 10, 23, 190, 6, 148, 247, 120, 234, 75, 0, 26, 197, 62,
    94, 252, 219, 203, 117, 35, 11, 32, 57, 177, 33, 88, 237, 149, 56, 87, 174, 20, 125, 136,
    171, 168, 68, 175, 74, 165, 71, 134, 139, 48, 27, 166, 77, 146, 158, 231, 83, 111, 229, 122,
    60, 211, 133, 230, 220, 105, 92, 41, 55, 46, 245, 40, 244, 102, 143, 54, 65, 25, 63, 161,
    1, 216, 80, 73, 209, 76, 132, 187, 208, 89, 18, 169, 200, 196, 135, 130, 116, 188, 159, 86,
    164, 100, 109, 198, 173, 186, 3, 64, 52, 217, 226, 250, 124, 123, 5, 202, 38, 147, 118, 126,
    255, 82, 85, 212, 207, 206, 59, 227, 47, 16, 58, 17, 182, 189, 28, 42, 223, 183, 170, 213,
    119, 248, 152, 2, 44, 154, 163, 70, 221, 153, 101, 155, 167, 43, 172, 9, 129, 22, 39, 253,
    19, 98, 108, 110, 79, 113, 224, 232, 178, 185, 112, 104, 218, 246, 97, 228, 251, 34, 242, 193,
    238, 210, 144, 12, 191, 179, 162, 241, 81, 51, 145, 235, 249, 14, 239, 107, 49, 192, 214, 31,
    181, 199, 106, 157, 184, 84, 204, 176, 115, 121, 50, 45, 127, 4, 150, 254, 138, 236, 205, 93,
    222, 114, 67, 29, 24, 72, 243, 141, 128, 195, 78, 66, 215, 61, 156, 180);

int nz_perm(int i) {
    return NZ_PERM[i & 255];
}

// Hashes of the 8 corners of the cell whose lower corner is the lattice point `cell` (any integer values):
// lo = (h000, h100, h010, h110), hi = (h001, h101, h011, h111), h_ijk = P[P[P[X+i] + Y+j] + Z+k].
void nz_hash(ivec3 cell, out ivec4 lo, out ivec4 hi) {
    ivec3 c = cell & 255;
    int a = nz_perm(c.x) + c.y;
    int b = nz_perm(c.x + 1) + c.y;
    ivec4 l = ivec4(nz_perm(a), nz_perm(b), nz_perm(a + 1), nz_perm(b + 1)) + c.z;  // AA, BA, AB, BB
    lo = ivec4(nz_perm(l.x), nz_perm(l.y), nz_perm(l.z), nz_perm(l.w));
    hi = ivec4(nz_perm(l.x + 1), nz_perm(l.y + 1), nz_perm(l.z + 1), nz_perm(l.w + 1));
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
