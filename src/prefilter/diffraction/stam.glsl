// Stam's diffraction BRDF from a height field (Stam 1999; Single 2013 §2.3-2.4), prefix df_.
//
// Tangent frame: +x across the grooves (light disperses along x), +y along them, +z the normal.
// k1 = -wi is the incident propagation direction, k2 = wo the direction towards the eye,
// (u, v, w) = k1 - k2 (Stam eq. (6): v), G = (1 - k1·k2) / (cos θ1 cos θ2) (eq. (7)).
//
// Relative reflectance (DESIGN.md erratum): the BRDF divided by that of a flat mirror in the specular
// direction for the same incidence, so a mirror shows the light's colour there:
//   R = F_R(cos θ_h) · (G / w²) · 2 cos²θ1 · |P̃(k u, k v; k w)|²,
// where P̃ is the transform of exp(i k w h) through the Gaussian coherence window, normalised to 1 at
// the origin for a flat surface (diffraction/transform.py), and F_R is Schlick's reflectance.
//
// P̃ is the Taylor sum of Single §2.4: Σ_n (k w)^n Σ_bins c_n[bin] exp(-σ² |(α, β) - bin|² / 2), with c_n
// the Fourier-series coefficients of (i h)^n / n! (mean-subtracted h): the complex terms are summed first
// (by Horner's rule in k w), then squared. The window is carried by the 2R x 2R DFT bins around the cell
// that holds (α, β), R = DF_STENCIL (transform.py `stencil_radius`: R σ Δ ≥ 3.5; R = 1, the 2 x 2 nearest
// bins, when the window is narrow next to the bin spacing Δ, as at the default σ).
//
// df_terms: RG32F texture array, layer n = c_n in NumPy FFT order; df_bins = (2π / (W dx), 2π / (H dy),
// W, H); df_sigma (µm); df_order N. df_spectrum: RGBA32F, texel j = (XYZ weight, wavelength µm) with the
// weights of D65 x CIE 1931 normalised to a white Y of 1 (diffraction/spectrum.py).

const float DF_PI = 3.14159265358979;

uniform sampler2DArray df_terms;  // @table the Taylor/FFT terms of the nanostructure patch (Single 2013 §2.4): layer n = 0..df_order holds c_n = fft2((i h)^n / n!)/(W H), h the mean-subtracted height in µm of one W x H patch; texel (x, y) = the DFT bin of frequency (x df_bins.x, y df_bins.y) rad/µm in NumPy FFT order (indices >= W/2 or H/2 are the negative frequencies; the shader wraps bin indices), df_bins = (2π/(W dx), 2π/(H dy), W, H), x across the grooves; RG: (real, imaginary); read with texelFetch (NEAREST, no MIP); not colours
uniform vec4 df_bins;
uniform float df_sigma;
uniform int df_order;
uniform sampler2D df_spectrum;  // @table one row of df_wavelengths texels, wavelengths evenly spaced over 380-780 nm: texel j = (X, Y, Z weight, wavelength in µm), the weights being the CIE 1931 2° colour matching functions times D65, normalised so that a flat reflectance of 1 sums to Y = 1; read with texelFetch (NEAREST, no MIP); not premultiplied
uniform int df_wavelengths;
uniform float df_f0;  // @param 0..1 Fresnel F0: Schlick F0 (1: no Fresnel fall-off); a per-pixel gain in every mode (the fast table does not include it)

// linear sRGB from XYZ (IEC 61966-2-1, D65), column-major
const mat3 DF_SRGB_FROM_XYZ = mat3(3.2404542, -0.9692660, 0.0556434,
                                   -1.5371385, 1.8760108, -0.2040259,
                                   -0.4985314, 0.0415560, 1.0572252);

vec2 df_term(ivec2 bin, int n) {
    ivec2 size = ivec2(df_bins.zw);
    ivec2 wrapped = ivec2(bin.x - size.x * int(floor(float(bin.x) / df_bins.z)),
                          bin.y - size.y * int(floor(float(bin.y) / df_bins.w)));
    return texelFetch(df_terms, ivec3(wrapped, n), 0).xy;
}

#ifndef DF_STENCIL
#define DF_STENCIL 1
#endif

// Σ_n (k w)^n c_n[bin] by Horner's rule. llvmpipe stops a shader invocation's loops after 65535 iterations
// in all (counted over its SIMD group, every loop together) without an error, which a loop over the terms
// inside the stencil and the spectral loops exceeds. So the material defines DF_HORNER(bin, kw), the same
// sum unrolled for its structure's order (material.py `horner_macro`); the loop is the fallback.
vec2 df_termSum(ivec2 bin, float kw) {
#ifdef DF_HORNER
    return DF_HORNER(bin, kw);
#else
    vec2 acc = df_term(bin, df_order);
    for (int n = df_order - 1; n >= 0; --n) acc = acc * kw + df_term(bin, n);
    return acc;
#endif
}

// P̃(α, β; k w): complex (re, im).
vec2 df_transform(float alpha, float beta, float kw) {
    vec2 at = vec2(alpha, beta) / df_bins.xy;
    ivec2 b0 = ivec2(floor(at));
    vec2 sum = vec2(0.0);
    for (int j = 1 - DF_STENCIL; j <= DF_STENCIL; ++j) {
        for (int i = 1 - DF_STENCIL; i <= DF_STENCIL; ++i) {
            ivec2 bin = b0 + ivec2(i, j);
            vec2 d = (vec2(bin) - at) * df_bins.xy;
            float g = exp(-0.5 * df_sigma * df_sigma * dot(d, d));
            if (g < 1e-7) continue;
            sum += g * df_termSum(bin, kw);
        }
    }
    return sum;
}

// (u, v, w) and the wavelength-independent gain F_R (G / w²) 2 cos²θ1; wi, wo unit, tangent frame.
vec4 df_geometry(vec3 wi, vec3 wo) {
    vec3 k1 = -wi, k2 = wo;
    vec3 uvw = k1 - k2;
    float cos1 = max(wi.z, 1e-4), cos2 = max(wo.z, 1e-4);
    float g = (1.0 - dot(k1, k2)) / (cos1 * cos2);
    vec3 h = normalize(wi + wo);
    float fresnel = df_f0 + (1.0 - df_f0) * pow(1.0 - clamp(dot(h, wo), 0.0, 1.0), 5.0);
    float gain = fresnel * g / max(uvw.z * uvw.z, 1e-8) * 2.0 * cos1 * cos1;
    return vec4(uvw, gain);
}

#ifdef DF_TILING
// Single §2.7: instead of the coherence window, the patch repeated df_tiles = (Nx, Ny) times. The power is
// the patch's (its nearest DFT bin) times the periodic factor |Σ_n e^{-i α n T}|² / N² per axis, which is
// sin²(N φ / 2) / (N sin(φ / 2))² with φ = α T reduced to [-π, π) and its series near φ = 0 (the guard at
// the singular points φ = 2π j, where the factor is 1). Normalised so that a flat mirror gives 1.
uniform vec2 df_tiles;

float df_periodicFactor(float phase, float count) {
    float p = phase - 2.0 * DF_PI * floor(phase / (2.0 * DF_PI) + 0.5);
    if (abs(p) < 1e-3) return max(1.0 - (count * count - 1.0) * p * p / 12.0, 0.0);
    float r = sin(0.5 * count * p) / (count * sin(0.5 * p));
    return r * r;
}

float df_tiledPower(float alpha, float beta, float kw) {
    vec2 at = vec2(alpha, beta) / df_bins.xy;
    ivec2 bin = ivec2(floor(at + 0.5));
    vec2 acc = df_termSum(bin, kw);
    return dot(acc, acc) * df_periodicFactor(2.0 * DF_PI * at.x, df_tiles.x) *
           df_periodicFactor(2.0 * DF_PI * at.y, df_tiles.y);
}
#endif

// Σ_λ |P̃(k u, k v; k w)|² x (D65 x CIE 1931 weight): XYZ, before the gain (a function of u, v, w only).
vec3 df_spectralXYZ(vec3 uvw) {
    vec3 xyz = vec3(0.0);
    for (int j = 0; j < 1024; ++j) {
        if (j >= df_wavelengths) break;
        vec4 s = texelFetch(df_spectrum, ivec2(j, 0), 0);
        float k = 2.0 * DF_PI / s.w;
#ifdef DF_TILING
        xyz += df_tiledPower(k * uvw.x, k * uvw.y, k * uvw.z) * s.xyz;
#else
        vec2 p = df_transform(k * uvw.x, k * uvw.y, k * uvw.z);
        xyz += dot(p, p) * s.xyz;
#endif
    }
    return xyz;
}

// The accurate path: linear sRGB relative reflectance, spectral loop over df_wavelengths samples.
vec3 df_reflectance(vec3 wi, vec3 wo) {
    if (wi.z <= 0.0 || wo.z <= 0.0) return vec3(0.0);
    vec4 geometry = df_geometry(wi, wo);
    return max(DF_SRGB_FROM_XYZ * (geometry.w * df_spectralXYZ(geometry.xyz)), vec3(0.0));
}

// The fast path: df_spectralXYZ preintegrated into a 3D table over u, v in [-2, 2] and w in [-2, 0]
// (texel centres on the grid points; diffraction/fast_table.py), read with one trilinear lookup.
uniform sampler3D df_table;  // @table the fast path's spectrally integrated power over (u, v, w) = k1 - k2 = -wi - wo in the groove tangent frame (+x across the grooves, +y along them, +z the normal): s over u in [-2, 2], t over v in [-2, 2], r (slices) over w in [-2, 0], texel centres on the grid points (texel i at u = -2 + 4 i/(df_tableSize.x - 1), row j at v = -2 + 4 j/(df_tableSize.y - 1), slice k at w = -2 + 2 k/(df_tableSize.z - 1)); RGB: XYZ = Σ_λ |P̃(k u, k v; k w)|² x (D65 x CIE 1931 weight), before the per-pixel gain F G/w² 2 cos²θ1 (linear XYZ, not premultiplied), A = 1; baked for the scene's df_sigma (and df_tiles); LINEAR, CLAMP_TO_EDGE, no MIP
uniform vec3 df_tableSize;

vec3 df_fastReflectance(vec3 wi, vec3 wo) {
    if (wi.z <= 0.0 || wo.z <= 0.0) return vec3(0.0);
    vec4 geometry = df_geometry(wi, wo);
    vec3 grid = (geometry.xyz - vec3(-2.0, -2.0, -2.0)) / vec3(4.0, 4.0, 2.0);  // 0..1 over the grid
    vec3 coord = (grid * (df_tableSize - 1.0) + 0.5) / df_tableSize;
    vec3 xyz = texture(df_table, coord).xyz;
    return max(DF_SRGB_FROM_XYZ * (geometry.w * xyz), vec3(0.0));
}

// Dhillon et al. 2014's fast path: the spectrally integrated power as a polynomial in w, Σ_j (w − w₀)^j T_j(u, v),
// with 2N + 1 XYZ tables T_j of the Taylor series' cross terms (diffraction/dhillon.py), summed by Horner's
// rule: one bilinear lookup per table and no wavelength loop.
uniform sampler2DArray df_dhillon;  // @table Dhillon et al. 2014's wavelength-preintegrated cross terms of the Taylor series (diffraction/dhillon.py): layer j = 0..df_dhillonCount-1 holds T_j(u, v) with Σ_λ |P̃(k u, k v; k w)|² x (D65 x CIE 1931 weight) = Σ_j (w - df_dhillonW0)^j T_j(u, v), (u, v, w) = k1 - k2 = -wi - wo in the groove tangent frame (+x across the grooves, +y along them, +z the normal); s over u in [-2, 2], t over v in [-2, 2], texel centres on the grid points (texel i at u = -2 + 4 i/(width - 1)); RGB: T_j in XYZ before the per-pixel gain F G/w² 2 cos²θ1 (signed, float32: the sum cancels, do not store at lower precision), A = 0; baked for the scene's df_sigma; LINEAR, CLAMP_TO_EDGE, no MIP
uniform int df_dhillonCount;  // 2N + 1
uniform float df_dhillonW0;  // the expansion's centre w₀ (Dhillon: 0; ours by default: -1, the middle of w's range)

vec3 df_dhillonReflectance(vec3 wi, vec3 wo) {
    if (wi.z <= 0.0 || wo.z <= 0.0) return vec3(0.0);
    vec4 geometry = df_geometry(wi, wo);
    vec2 size = vec2(textureSize(df_dhillon, 0).xy);
    vec2 coord = ((geometry.xy + 2.0) / 4.0 * (size - 1.0) + 0.5) / size;
    float x = geometry.z - df_dhillonW0;
    vec3 xyz = vec3(0.0);
    for (int j = df_dhillonCount - 1; j >= 0; --j) xyz = xyz * x + texture(df_dhillon, vec3(coord, float(j))).xyz;
    return max(DF_SRGB_FROM_XYZ * (geometry.w * xyz), vec3(0.0));
}

// Baseline: Stam's analytic grating shader (GPU Gems ch. 8 style) for a grating of period d (µm): order
// m lights the wavelength λ = d |u| / |m| within 380-780 nm, every order taken 10 % efficient and spread
// along y by the coherence window; the zeroth order is a white mirror lobe. No height field is used.
vec3 df_analyticGrating(vec3 wi, vec3 wo, float period) {
    if (wi.z <= 0.0 || wo.z <= 0.0) return vec3(0.0);
    vec4 geometry = df_geometry(wi, wo);
    float u = geometry.x, v = geometry.y;
    float k0 = 2.0 * DF_PI / 0.55;
    vec3 xyz = vec3(exp(-df_sigma * df_sigma * k0 * k0 * (u * u + v * v)));
    xyz *= vec3(0.9504, 1.0, 1.0888);  // D65 white
    float first = texelFetch(df_spectrum, ivec2(0, 0), 0).w;
    float last = texelFetch(df_spectrum, ivec2(df_wavelengths - 1, 0), 0).w;
    for (int m = 1; m <= 8; ++m) {
        float lambda = period * abs(u) / float(m);
        if (lambda < first || lambda > last) continue;
        float j = (lambda - first) / (last - first) * float(df_wavelengths - 1);
        vec3 weight = texelFetch(df_spectrum, ivec2(int(j + 0.5), 0), 0).xyz;
        float k = 2.0 * DF_PI / lambda;
        xyz += 0.1 * weight * float(df_wavelengths) * exp(-df_sigma * df_sigma * k * k * v * v);
    }
    return max(DF_SRGB_FROM_XYZ * (geometry.w * xyz), vec3(0.0));
}
