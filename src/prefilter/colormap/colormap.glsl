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
//     sat    (n+1) x 2 RGBA32F NEAREST: the summed-area table S (S[0] = 0, S[i+1] = S[i] + clut[i],
//            eq. 13 with a leading zero) split as row 0 = float32(S), row 1 = float32(S - row 0).
//
// Functions
//   vec4 cm_point(sampler2D table, float f, int wrapMode)      eq. (2), "round" read as nearest texel:
//        clut[min(floor(n * wrap(f)), n - 1)], wrap = fract (modulo) or clamp to [0, 1] (clamp).
//   vec4 cm_mip(sampler2D mipTable, float f, float width)       §3.3.1: trilinear MIP lookup at
//        lod = log2(width * n) (level L holds box averages of 2^L texels). Approximate: a box of about
//        the right width with a tent reconstruction; exact when width * n is a power of two and f sits on
//        that level's texel centres. Beyond the ends of a clamp table the coarse levels return the mean
//        of the last block, not clut[0] / clut[n-1] (a limit of MIP-mapping). For modulo tables with a
//        large |f|, pass f - round(f) to keep texture-coordinate precision.
//   vec4 cm_sat(sampler2D sat, float f, float width, int wrapMode)   eqs. (13)-(15): the exact mean of
//        the piecewise-constant table over [f - w/2, f + w/2] (S is piecewise linear, so interpolating S
//        between integer entries is its exact integral), with the boundary cases of §3.3.2:
//          modulo: whole periods counted plus partial sums; Hart's rule w >= 1 (w * n >= N) returns the
//                  whole-table mean S[n] / n;
//          clamp:  the parts of the footprint beyond the ends weighted by clut[0] / clut[n-1]. For w >= 1
//                  this exact edge-extended integral is kept instead of Hart's whole-table mean: it is
//                  right when the footprint lies mostly off one end.
//        Float32: the ends are placed relative to the texel of f (whole periods removed in texel units),
//        so the fractions of the two end texels keep ~1e-7 precision; complete texels come from
//        double-float differences of S and the end texels from their entries (eq. 14). All weights are
//        non-negative, so the result is a convex combination of entries: ~1e-6 absolute for w down to
//        1e-4 and any f. Cost: about 10 texel fetches.
//   vec4 cm_mip2(sampler2D mipTable, float f, float wa, float wb)
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

vec4 cm_mip(sampler2D mipTable, float f, float width) {
    float n = float(textureSize(mipTable, 0).x);
    float lod = log2(max(abs(width) * n, 1.0));  // below one texel: level 0, magnified
    return textureLod(mipTable, vec2(f, 0.5), lod);
}

vec4 cm_mip2(sampler2D mipTable, float f, float wa, float wb) {
    float wMax = max(abs(wa), abs(wb));
    float wMin = min(abs(wa), abs(wb));
    vec4 sum = vec4(0.0);
    for (int k = 0; k < CM_PROBES; ++k) {
        float offset = ((float(k) + 0.5) / float(CM_PROBES) - 0.5) * wMin;
        sum += cm_mip(mipTable, f + offset, wMax);
    }
    return sum / float(CM_PROBES);
}

// --- summed-area colour table (eqs. 13-15) ---------------------------------------------------------

vec4 cm_satHi(sampler2D sat, int i) {
    return texelFetch(sat, ivec2(i, 0), 0);
}

vec4 cm_satLo(sampler2D sat, int i) {
    return texelFetch(sat, ivec2(i, 1), 0);
}

// Entry i (0 <= i < n) recovered from the table, eq. (14): clut[i] = S[i+1] - S[i].
vec4 cm_satEntry(sampler2D sat, int i) {
    return (cm_satHi(sat, i + 1) - cm_satHi(sat, i)) + (cm_satLo(sat, i + 1) - cm_satLo(sat, i));
}

// Integral of the table over the texel interval [ka + ta, kb + tb] (ka <= kb, ta and tb in [0, 1],
// kb - ka <= n + 1), texel indices taken modulo n; `weight` receives the interval's length. The two end
// texels contribute (1 - ta) and tb of their entries, the complete texels between them
// P(kb) - P(ka + 1) with P(k) = q S[n] + S[r] for k = q n + r (eq. 15 with the modulo case of §3.3.2).
vec4 cm_satSpan(sampler2D sat, int n, int ka, float ta, int kb, float tb, out float weight) {
    int qa = int(floor(float(ka) / float(n)));
    int qb = int(floor(float(kb) / float(n)));
    int ra = ka - qa * n;
    int rb = kb - qb * n;
    vec4 ca = cm_satEntry(sat, ra);
    if (ka == kb) {
        weight = tb - ta;
        return weight * ca;
    }
    vec4 cb = cm_satEntry(sat, rb);
    vec4 hi;
    vec4 lo;
    if (qb == qa) {
        hi = cm_satHi(sat, rb) - cm_satHi(sat, ra + 1);
        lo = cm_satLo(sat, rb) - cm_satLo(sat, ra + 1);
    } else {  // wraps: the rest of ka's period, whole periods, the start of kb's period
        float periods = float(qb - qa - 1);
        hi = (cm_satHi(sat, n) - cm_satHi(sat, ra + 1)) + cm_satHi(sat, rb) + periods * cm_satHi(sat, n);
        lo = (cm_satLo(sat, n) - cm_satLo(sat, ra + 1)) + cm_satLo(sat, rb) + periods * cm_satLo(sat, n);
    }
    weight = (1.0 - ta) + tb + float(kb - ka - 1);
    return (1.0 - ta) * ca + tb * cb + (hi + lo);
}

vec4 cm_sat(sampler2D sat, float f, float width, int wrapMode) {
    int n = textureSize(sat, 0).x - 1;
    float fn = float(n);
    float h = 0.5 * abs(width) * fn;  // half-width in texels
    float weight;
    vec4 sum;
    int k;
    if (wrapMode != CM_CLAMP) {
        if (2.0 * h >= fn) {  // Hart: w >= N returns the average of the entire table
            return (cm_satHi(sat, n) + cm_satLo(sat, n)) / fn;
        }
        float x = fn * f;  // exact (n is a power of two)
        float kf = floor(x);
        float t = x - kf;  // in [0, 1]; exact unless |x| < 1/2, then within 2^-24 texel
        k = int(cm_modTexel(kf, fn));  // the texel of f in one period
        float ya = t - h;  // the ends relative to texel k: rounded to ~1e-7 texel near t
        float yb = t + h;
        float fa = floor(ya);
        float fb = floor(yb);
        sum = cm_satSpan(sat, n, k + int(fa), ya - fa, k + int(fb), yb - fb, weight);
    } else {
        float x = fn * f;
        float kf = clamp(floor(x), 0.0, fn - 1.0);
        k = int(kf);
        float t = x - kf;
        float ya = t - h;
        float yb = t + h;
        float left = -kf;       // texel 0 relative to k
        float right = fn - kf;  // texel n relative to k
        float wl = max(min(yb, left) - ya, 0.0);   // length below the table: clut[0]
        float wr = max(yb - max(ya, right), 0.0);  // length above it: clut[n-1]
        float ia = clamp(ya, left, right);
        float ib = clamp(yb, left, right);
        float fa = floor(ia);
        float fb = floor(ib);
        sum = cm_satSpan(sat, n, k + int(fa), ia - fa, k + int(fb), ib - fb, weight);
        sum += wl * cm_satEntry(sat, 0) + wr * cm_satEntry(sat, n - 1);
        weight += wl + wr;
    }
    return weight > 0.0 ? sum / weight : cm_satEntry(sat, k);  // zero width: the point value
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
