// Lookups in the pyramid of Phong peaks (normals/pyramid.py, Fournier 1992 §2.4).
//
// Storage: one RGBA32F 2D texture array, every level in one atlas (level 0 at (0, 0), the others in a
// column to its right), so any map size works and WebGL2 needs nothing special. nd_level[l] = (atlas x,
// atlas y, width, height) of level l. Layer k holds peak k of K: (d.x, d.y, amplitude, exponent), or with
// shadowing the same and its horizon statistics bit-packed into the texel's four words
// (normals/peak_texels.py), so that a shaded peak costs one fetch. Unused peaks have amplitude 0 and come
// last.
//
// Filtering: the level comes from the footprint (the pixel's Jacobian in base texels: lod = log2 of its
// longer axis, as MIP mapping does, or, with ND_ANISOTROPY = N > 1, of 1/n of it at each of n <= N
// samples along that axis, as anisotropic texture units do), plus nd_lodBias (0 unless the material sets
// lod_bias; docs/normals.md measures what a finer level trades); within a level, bilinear weights over 4
// texels; between levels, linear weights over 2 levels. The peaks of all contributing texels are used,
// each with its amplitude multiplied by its interpolation weight (up to 8 texels x K peaks per sample) —
// never averaged. A level whose texels are all alike (the map tiles with a period that fits in one
// texel) gives the same peaks whatever the weights, so it is shaded once per pixel.

#define ND_MAX_LEVELS 16
#ifndef ND_ANISOTROPY
#define ND_ANISOTROPY 1
#endif

uniform sampler2DArray nd_peaks;  // @table Fournier's pyramid of Phong peaks, every level in one atlas: level l is the texel box nd_level[l] = (x, y, width, height) (level 0 at (0, 0), the others in a column to its right; nd_levelCount levels), and texel (i, j) of level l covers base texels [i 2^l, (i+1) 2^l) x [j 2^l, (j+1) 2^l) of the tiling map, whose repeat is one unit of mesh uv x u_uvScale; layer k < K = nd_maxPeaks holds peak k, sorted by decreasing amplitude (amplitude 0 = unused), direction d in the tangent frame (+x along u, +y along v, +z the normal, d.z = sqrt(1 - d.x² - d.y²)); without shadowing the texel is (d.x, d.y, amplitude, Phong exponent); with shadowing its four float32 words are bit fields read with floatBitsToUint (normals/peak_texels.py): word w has A = w & 2047, B = (w >> 11) & 2047, C = (w >> 22) & 127 (bit 29 set so every word is a normal float); A of words 0..3 = (d.x, amplitude, mean horizon slope +X, mean +Y), B = (d.y, exponent, mean -X, mean -Y), C = horizon slope deviations (+X, -X, +Y, -Y); d.x = A0 / 1023 - 1, d.y = B0 / 1023 - 1, amplitude = A1 nd_peakScales.w, 1 + exponent = the float32 with bits (B1 << 16) + 0x3F800000, means = nd_peakScales.x + code nd_peakScales.y, deviations = C nd_peakScales.z; nd_levelAlike[l] = 1 where every texel of level l holds the same peaks; read with texelFetch (NEAREST, no MIP); a multiple surface is a 1x1 atlas of its peaks; not colours
uniform vec4 nd_peakScales;  // packed texels' steps (peak_texels.PeakScales): (mean lo, mean step, deviation step, amplitude step)
uniform vec4 nd_level[ND_MAX_LEVELS];
uniform float nd_levelAlike[ND_MAX_LEVELS];  // 1: every texel of the level holds the same peaks
uniform int nd_levelCount;
uniform int nd_maxPeaks;
uniform float nd_lodBias;  // @param -3..1 LOD bias: levels added to multilobe's level choice (negative: finer levels, cheaper, sharper; fine weaves alias); the baselines keep the GL's choice

// Wrapped (tiling) texel of a level.
ivec3 nd_atlasTexel(int level, ivec2 texel, int layer) {
    vec4 box = nd_level[level];
    ivec2 size = ivec2(box.zw);
    ivec2 wrapped = ivec2(texel.x - size.x * int(floor(float(texel.x) / box.z)),
                          texel.y - size.y * int(floor(float(texel.y) / box.w)));
    return ivec3(ivec2(box.xy) + wrapped, layer);
}

vec4 nd_fetch(int level, ivec2 texel, int layer) {
    return texelFetch(nd_peaks, nd_atlasTexel(level, texel, layer), 0);
}

// A peak of the atlas (peak_texels.py, whose `decode` is this function in NumPy). Without shadowing the
// texel is (d.x, d.y, amplitude, exponent). With shadowing its four words w0..w3 each hold the fields
// A (bits 0-10), B (11-21) and C (22-28): A = (d.x, amplitude, mean +X, mean +Y), B = (d.y, 1 + exponent
// as a float's bits 16-26, mean -X, mean -Y), C = deviations (+X, -X, +Y, -Y).
struct NdPeak {
    vec3 direction;
    float amplitude;
    float exponent;
    vec4 mean;       // horizon slopes +X, -X, +Y, -Y
    vec4 deviation;
};

NdPeak nd_unpackPeak(vec4 texel) {
    NdPeak peak;
#ifdef ND_SHADOWING
    uvec4 q = floatBitsToUint(texel);
    vec4 a = vec4(q & 2047u);
    vec4 b = vec4((q >> 11u) & 2047u);
    vec2 d = vec2(a.x, b.x) / 1023.0 - 1.0;
    peak.amplitude = a.y * nd_peakScales.w;
    peak.exponent = uintBitsToFloat((((q.y >> 11u) & 2047u) << 16u) + 0x3F800000u) - 1.0;  // 1 + n
    peak.mean = nd_peakScales.x + vec4(a.z, b.z, a.w, b.w) * nd_peakScales.y;
    peak.deviation = vec4((q >> 22u) & 127u) * nd_peakScales.z;
#else
    vec2 d = texel.xy;
    peak.amplitude = texel.z;
    peak.exponent = texel.w;
    peak.mean = vec4(0.0);
    peak.deviation = vec4(0.0);
#endif
    peak.direction = vec3(d, sqrt(max(1.0 - dot(d, d), 0.0)));
    return peak;
}

// The footprint (uv Jacobian, uv in units of one repeat of the map) as `count` samples spread along its
// longer axis (uv offsets start + i step), each with the lod of a 1/count share of that axis; count is at
// most ND_ANISOTROPY and no more than the axes' length ratio (count = 1: isotropic MIP mapping).
struct NdFootprint {
    vec2 start;
    vec2 step;
    int count;
    float lod;
    float magnification;  // weight of the unfiltered base level: 1 below lod -1, 0 above lod 0
};

NdFootprint nd_footprint(vec2 dUVdx, vec2 dUVdy) {
    vec2 base = nd_level[0].zw;
    float lx = length(dUVdx * base), ly = length(dUVdy * base);
    vec2 major = lx >= ly ? dUVdx : dUVdy;
    float longer = max(lx, ly), shorter = max(min(lx, ly), 1e-8);
    NdFootprint f;
    f.count = int(clamp(ceil(longer / shorter - 0.01), 1.0, float(ND_ANISOTROPY)));
    f.step = major / float(f.count);
    f.start = -0.5 * major + 0.5 * f.step;
    float lod = log2(max(longer / float(f.count), 1e-8)) + nd_lodBias;
    f.lod = clamp(lod, 0.0, float(nd_levelCount - 1));
    f.magnification = clamp(-lod, 0.0, 1.0);
    return f;
}

// The two levels and their weights for a lod (the second weight is 0 at the top level).
void nd_levelWeights(float lod, out int level0, out vec2 weights) {
    level0 = min(int(floor(lod)), nd_levelCount - 1);
    float t = lod - float(level0);
    if (level0 + 1 >= nd_levelCount) t = 0.0;
    weights = vec2(1.0 - t, t);
}

// Lower-left texel of the bilinear 2x2 at `level` and the fractional position within it.
void nd_bilinear(vec2 uv, int level, out ivec2 texel0, out vec2 f) {
    vec2 p = uv * nd_level[level].zw - 0.5;
    vec2 i0 = floor(p);
    texel0 = ivec2(i0);
    f = p - i0;
}

float nd_bilinearWeight(vec2 f, int corner) {
    vec2 w = vec2(corner % 2 == 1 ? f.x : 1.0 - f.x, corner / 2 == 1 ? f.y : 1.0 - f.y);
    return w.x * w.y;
}
