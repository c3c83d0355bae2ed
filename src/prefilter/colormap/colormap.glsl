// colormap.glsl -- colour-table lookups of Hart, Carr, Kameya, Tibbitts & Coleman, "Antialiased
// parameterized solid texturing simplified for consumer-level hardware implementation" (1999),
// §2.1.1 and §3.3.
//
// What it computes
//   The colour c(f) of a scalar index f through an n-entry colour table, unfiltered (eq. 2) or box
//   filtered over [f - w/2, f + w/2] (eq. 9: the mean of the table between the smallest and largest
//   index seen by the pixel), with the table's MIP map (§3.3.1) or its summed-area table (eqs. 13-15).
//
// Conventions (shared with colormap/table.py, which bakes the textures and holds the float64 oracles)
//   - f is in table periods: entry i covers f in [i/n, (i+1)/n). Widths w are in the same units
//     (w = 1 is the whole table, w * n is the width in texels); negative widths are taken as |w|.
//   - wrapMode: 0 = modulo (the table repeats), 1 = clamp (it holds clut[0] below 0, clut[n-1] above 1).
//   - Colours are linear and premultiplied by alpha (renderers upload ColourTable.premultiplied()).
//   - Textures (see TableTextures): point  n x 1 RGBA32F NEAREST;
//     mip    n x 1 RGBA32F, all levels from ColourTable.mip_levels(), LINEAR_MIPMAP_LINEAR, repeat in x
//            for modulo tables, clamp-to-edge for clamp tables (the wrap lives in the texture);
//     sat    (n+3) x 1 RGBA32F LINEAR: the summed-area table S (S[0] = 0, S[i+1] = S[i] + clut[i],
//            eq. 13 with a leading zero) in texels 0..n, then clut[0] and clut[n-1].
//
// Functions
//   vec4 cm_point(sampler2D table, float f, int wrapMode)      eq. (2), "round" read as nearest texel:
//        clut[min(floor(n * wrap(f)), n - 1)], wrap = fract (modulo) or clamp to [0, 1] (clamp).
//   vec4 cm_mip(sampler2D mipTable, float f, float width, int wrapMode)   §3.3.1: trilinear MIP lookup
//        at lod = log2(width * n) (level L holds box averages of 2^L texels; cm_mipTrilinear does GL's
//        LINEAR_MIPMAP_LINEAR filter by texelFetch, at a cost independent of the level). Approximate:
//        a box of about the right width with a tent reconstruction; exact when width * n is a power of
//        two and f sits on that level's texel centres. Clamp tables: the parts of the footprint beyond
//        the ends are weighted by clut[0] / clut[n-1] and only the part inside [0, 1] is looked up (a
//        coarse level alone would return the mean of the edge block, far from clut[n-1] when f is well
//        beyond 1).
//   vec4 cm_sat(sampler2D sat, float f, float width, int wrapMode)   eqs. (13)-(15): the mean of the
//        piecewise-constant table over [f - w/2, f + w/2] as a difference of S at the two ends (S is
//        piecewise linear, so the texture unit's linear filter between integer entries is its exact
//        integral), with the boundary cases of §3.3.2:
//          modulo: I(y) = floor(y/n) S[n] + S(y mod n) at both ends; Hart's rule w >= 1 (w * n >= N)
//                  returns the whole-table mean S[n] / n;
//          clamp:  the parts of the footprint beyond the ends weighted by clut[0] / clut[n-1]. For w >= 1
//                  this exact edge-extended integral is kept instead of Hart's whole-table mean: it is
//                  right when the footprint lies mostly off one end.
//        Widths below one entry are widened to one entry, as MIP level 0 does: a float32 S of a 256-entry
//        table has ~3e-5 absolute error, which a narrower footprint would divide by its width. The
//        result is then within ~3e-5 of the exact box mean over max(w, 1/n). No data-dependent branch
//        (wrapMode is uniform): llvmpipe runs both sides of a divergent branch, and an earlier exact
//        version with special cases cost 2.4x more than this one.
//   vec4 cm_mip2(sampler2D mipTable, float f, float wa, float wb, int wrapMode)
//   vec4 cm_sat2(sampler2D sat, float f, float wa, float wb, int wrapMode)
//        Two-axis footprint: over a square pixel with screen gradient (wa, wb) = (df/dx, df/dy), f is
//        distributed as box(|wa|) convolved with box(|wb|) (a trapezoid). Approximated by the mean of
//        CM_PROBES box lookups of width max(|wa|, |wb|) at offsets ((k + 0.5)/CM_PROBES - 0.5) * min(|wa|,
//        |wb|) (midpoint rule over the narrow box). Error bound (per channel, exact boxes):
//        (max clut - min clut) * min / (4 * CM_PROBES * max); exact for tables linear over the footprint.
//
// Defines: CM_PROBES (int, default 2), the number of box lookups in cm_mip2 / cm_sat2.

#ifndef CM_PROBES
#define CM_PROBES 2
#endif

const int CM_MODULO = 0;
const int CM_CLAMP = 1;

// An integer-valued float k reduced modulo n (a power of two) into [0, n), exactly. Periods are
// removed in texel units (floor(n f) mod n == floor(n fract(f))) because fract(f) of a small negative f
// rounds by up to 2^-25, i.e. 1.5e-5 texel of a 256-entry table.
float cm_modTexel(float k, float n) {
    return k - n * floor(k / n);
}

// --- point lookup (eq. 2) --------------------------------------------------------------------------

vec4 cm_point(sampler2D table, float f, int wrapMode) {
    int n = textureSize(table, 0).x;
    float fn = float(n);
    int i;
    if (wrapMode == CM_CLAMP) {
        i = min(int(floor(fn * clamp(f, 0.0, 1.0))), n - 1);
    } else {
        i = int(cm_modTexel(floor(fn * f), fn));
    }
    return texelFetch(table, ivec2(i, 0), 0);
}

// --- colour-table MIP map (§3.3.1) -----------------------------------------------------------------

// The texture unit's LINEAR_MIPMAP_LINEAR read at u (one row) and lod, done with texelFetch: two taps at
// each of the levels floor(lod) and floor(lod) + 1 (the top level alone beyond it). The same result as
// textureLod, but its cost does not depend on the level: llvmpipe's textureLod was 10-20 % dearer at fine
// levels than at coarse ones (bench's far/near), and this is also faster than it (1.36x against 1.50x
// `point` for hart-mip on the wood teapot).
vec4 cm_mipTrilinear(sampler2D mipTable, float u, float lod, float n, bool clampTable) {
    int top = int(log2(n) + 0.5);
    float level = min(floor(lod), float(top));
    float t = min(lod - level, 1.0);
    int levels[2] = int[2](int(level), min(int(level) + 1, top));
    vec4 taps[2];
    for (int k = 0; k < 2; ++k) {
        int size = max(int(n) >> levels[k], 1);  // not textureSize: llvmpipe takes one lane's level for all
        float x = u * float(size) - 0.5;
        float x0 = floor(x);
        int a = int(x0), b = a + 1;
        a = clampTable ? clamp(a, 0, size - 1) : a & (size - 1);  // sizes are powers of two
        b = clampTable ? clamp(b, 0, size - 1) : b & (size - 1);
        taps[k] = mix(texelFetch(mipTable, ivec2(a, 0), levels[k]), texelFetch(mipTable, ivec2(b, 0), levels[k]),
                      x - x0);
    }
    return mix(taps[0], taps[1], t);
}

vec4 cm_mip(sampler2D mipTable, float f, float width, int wrapMode) {
    float n = float(textureSize(mipTable, 0).x);
    float w = abs(width);
    bool clampTable = wrapMode == CM_CLAMP;
    // clamp: the parts of the footprint beyond the ends take the edge entries and the MIP map filters
    // only the part inside [0, 1]; a coarse level alone would mix the edge entry with its whole block.
    // The lookup itself stays outside any branch (llvmpipe samples slowly under divergent control flow).
    float ia = clampTable ? clamp(f - 0.5 * w, 0.0, 1.0) : f - 0.5 * w;
    float ib = clampTable ? clamp(f + 0.5 * w, 0.0, 1.0) : f + 0.5 * w;
    float inside = ib - ia;
    float centre = 0.5 * (ia + ib);
    centre = clampTable ? centre : centre - floor(centre);  // one period keeps coordinate precision
    vec4 mid = cm_mipTrilinear(mipTable, centre, log2(max(inside * n, 1.0)), n, clampTable);
    if (!clampTable || inside >= w) {
        return mid;
    }
    float below = clamp(0.5 * w - f, 0.0, w);
    float above = clamp(f + 0.5 * w - 1.0, 0.0, w);
    vec4 first = texelFetch(mipTable, ivec2(0, 0), 0);
    vec4 last = texelFetch(mipTable, ivec2(int(n) - 1, 0), 0);
    // a footprint narrower than f's float resolution: f ± w/2 round to f, and all three parts are 0
    float total = below + above + inside;
    return total > 0.0 ? (below * first + above * last + inside * mid) / total : mid;
}

vec4 cm_mip2(sampler2D mipTable, float f, float wa, float wb, int wrapMode) {
    float wMax = max(abs(wa), abs(wb));
    float wMin = min(abs(wa), abs(wb));
    vec4 sum = vec4(0.0);
    for (int k = 0; k < CM_PROBES; ++k) {
        float offset = ((float(k) + 0.5) / float(CM_PROBES) - 0.5) * wMin;
        sum += cm_mip(mipTable, f + offset, wMax, wrapMode);
    }
    return sum / float(CM_PROBES);
}

// --- summed-area colour table (eqs. 13-15) ---------------------------------------------------------

// S(x), the integral of the table over [0, x] texels, x in [0, n]: the texture unit's linear filter
// between S[i] and S[i+1] is exact for a piecewise-constant table.
vec4 cm_satAt(sampler2D sat, float x, float fn) {
    return textureLod(sat, vec2((x + 0.5) / (fn + 3.0), 0.5), 0.0);
}

vec4 cm_sat(sampler2D sat, float f, float width, int wrapMode) {
    float fn = float(textureSize(sat, 0).x - 3);
    float w = max(abs(width) * fn, 1.0);  // texels; never below one entry (float32 sums, as MIP level 0)
    float x = fn * f;                     // exact: n is a power of two
    bool clampTable = wrapMode == CM_CLAMP;
    x = clampTable ? x : x - fn * floor(x / fn);  // modulo: one period, for float32 precision
    float a = x - 0.5 * w;
    float b = x + 0.5 * w;
    // modulo: I(y) = floor(y / n) S[n] + S(y mod n), the integral of the periodic table;
    // clamp: S(clamp(y, 0, n)) plus the lengths beyond the ends weighted by clut[0] and clut[n-1].
    // The filtered fetches stay outside any branch (llvmpipe samples slowly under divergent flow).
    float qa = clampTable ? 0.0 : floor(a / fn);
    float qb = clampTable ? 0.0 : floor(b / fn);
    float ya = clampTable ? clamp(a, 0.0, fn) : a - qa * fn;
    float yb = clampTable ? clamp(b, 0.0, fn) : b - qb * fn;
    vec4 sum = cm_satAt(sat, yb, fn) - cm_satAt(sat, ya, fn);
    vec4 total = texelFetch(sat, ivec2(int(fn), 0), 0);
    if (clampTable) {
        float below = clamp(0.5 * w - x, 0.0, w);  // lengths beyond the ends, exact far from the table
        float above = clamp(x + 0.5 * w - fn, 0.0, w);
        vec4 first = texelFetch(sat, ivec2(int(fn) + 1, 0), 0);
        vec4 last = texelFetch(sat, ivec2(int(fn) + 2, 0), 0);
        sum += below * first + above * last;
    } else {
        sum = w >= fn ? total * (w / fn) : sum + (qb - qa) * total;  // Hart: w >= N, the table mean
    }
    return sum / w;
}

vec4 cm_sat2(sampler2D sat, float f, float wa, float wb, int wrapMode) {
    float wMax = max(abs(wa), abs(wb));
    float wMin = min(abs(wa), abs(wb));
    float base = wrapMode == CM_CLAMP ? f : f - round(f);  // exact reduction to [-1/2, 1/2]
    vec4 sum = vec4(0.0);
    for (int k = 0; k < CM_PROBES; ++k) {
        float offset = ((float(k) + 0.5) / float(CM_PROBES) - 0.5) * wMin;
        sum += cm_sat(sat, base + offset, wMax, wrapMode);
    }
    return sum / float(CM_PROBES);
}

// --- Gaussian-preconvolved colour map (Heitz et al. 2013/2014 §4.2, eq. 9) ---------------------------
// v of the σ row of a bake with `rows` rows up to sigmaMax (texel j at σ = sigmaMax j / (rows - 1)).
float cm_gaussianRow(float sigma, float sigmaMax, int rows) {
    return (clamp(sigma / sigmaMax, 0.0, 1.0) * float(rows - 1) + 0.5) / float(rows);
}

// pre: the bake of colormap/gaussian.py, C̄(μ, σ) = [C * N(0, σ²)](μ), μ along x, σ along y (texel j at
// σ = sigmaMax j / (rows - 1)); range = (lo, hi, sigmaMax): μ spans [lo, hi] (one period (0, 1) for
// modulo tables, whose texture repeats). σ beyond sigmaMax uses sigmaMax.
vec4 cm_gaussian(sampler2D pre, float mu, float sigma, int wrapMode, vec3 range) {
    float u = wrapMode == CM_CLAMP ? (mu - range.x) / (range.y - range.x) : mu - floor(mu);
    return textureLod(pre, vec2(u, cm_gaussianRow(sigma, range.z, textureSize(pre, 0).y)), 0.0);
}

// Box-filtered preconvolved map: the mean of C̄(·, σ) over [μ − w/2, μ + w/2], i.e. the table convolved
// with box(w) * N(0, σ²), as a difference of the integrated rows of colormap/gaussian.py
// (PreconvolvedMap.box_data: Hart's summed-area table over each σ row, eqs. 13-15). box: that texture,
// 3n + 1 columns holding S over [-n, 2n] μ texels (n over [lo, hi]), LINEAR; range as cm_gaussian. Widths
// below one μ texel are widened to one (as cm_sat: float32 sums); modulo: a width of a period or more
// gives the row mean (Hart's rule); clamp: a box beyond the stored copies is cut to them. No branch
// (llvmpipe samples under a divergent branch on every lane, and an if on u_wrap cost 6 % of a frame).
vec4 cm_gaussianBox(sampler2D box, float mu, float width, float sigma, int wrapMode, vec3 range) {
    ivec2 size = textureSize(box, 0);
    float columns = float(size.x);
    float n = (columns - 1.0) / 3.0;
    float v = cm_gaussianRow(sigma, range.z, size.y);
    float x = (mu - range.x) / (range.y - range.x) * n;
    float w = max(abs(width) / (range.y - range.x) * n, 1.0);
    bool modulo = wrapMode != CM_CLAMP;
    x = modulo ? x - n * floor(x / n) : x;  // one period: [x - w/2, x + w/2] stays within [-n, 2n]
    w = modulo ? min(w, n) : w;
    float a = clamp(x - 0.5 * w, -n, 2.0 * n - 1.0);
    float b = clamp(x + 0.5 * w, 1.0 - n, 2.0 * n);
    vec4 sb = textureLod(box, vec2((b + n + 0.5) / columns, v), 0.0);
    vec4 sa = textureLod(box, vec2((a + n + 0.5) / columns, v), 0.0);
    return (sb - sa) / (b - a);
}
