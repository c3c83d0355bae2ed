// Shading a distribution of normals made of Phong peaks (Fournier 1992 §2.2, §4) with soft horizon
// visibility (§5). Directions are in the tangent frame (+z the geometric normal).
//
// A peak (d, a, n) is the density a (n+1)/(2π) max(ω·d, 0)^n over solid angle (normals/peaks.py); a is
// the fraction of area. One base normal N of the map is the peak (N, 1, n0). A set of peaks is shaded as
//   Σ_i a_i V_i(l) M_i(v) [ albedo max(d_i·l, 0) + k_s lobe_i(h) l_z / (4 max(l_z, v_z, 0.1)) ] E_light
// i.e. a Lambertian part at the peak's direction and a microfacet specular part that is LINEAR in the
// normal density D(h) = Σ a_i lobe_i(h): averaging base normals' shading over a footprint gives exactly
// the shading of their spread, which is what the pyramid's peaks fit. The denominator depends only on the
// geometric frame (Neumann's max(l_z, v_z)), so it does not break that linearity.
//
// Visibility (§5): a direction w passes the X axis test when its slope in the XZ plane, w_z / |w_x|, is
// above the horizon slope towards sign(w_x) (+X or -X); likewise for Y; the two are multiplied. With a
// mean μ and standard deviation σ of the limiting slopes the test is soft: 0 below μ − σ, 1 above μ + σ,
// linear between (σ = 0: a step). Masked area is dark (not re-ratioed): the unfiltered reference cannot
// tell which texel is seen instead, and both must agree.

const float ND_PI = 3.14159265358979;

// cos^n as exp2(n log2 cos) behind a select, not pow(): on llvmpipe the two give bit-identical images, but
// pow cost 17-19 % more of a `multilobe` frame on the unshadowed presets (2026-12-04, round-robin, ÷ `point`:
// denim plane 26.4 -> 21.9, cylinders 19.7 -> 16.4, hemisphere sphere 14.4 -> 11.8; shadowed ones unchanged).
float nd_lobe(float cosAlpha, float n) {
    return cosAlpha > 0.0 ? (n + 1.0) / (2.0 * ND_PI) * exp2(n * log2(max(cosAlpha, 1e-30))) : 0.0;
}

// The slopes of a unit direction w towards the horizons (+X, -X, +Y, -Y): w_z / |w_x| on the side w
// leans to, and "above every horizon" (1e18) on the other side or when w_x = 0; "below every horizon"
// (-1e18) when w is under the surface. Per pixel, so that each peak's test is a few vec4 operations.
vec4 nd_horizonSlopes(vec3 w) {
    vec4 run = vec4(w.x, -w.x, w.y, -w.y);
    vec4 slopes = mix(vec4(1e18), w.z / max(run, vec4(1e-30)), greaterThan(run, vec4(0.0)));
    return w.z > 0.0 ? slopes : vec4(-1e18);
}

// The soft test of those slopes against horizons of mean μ and deviation σ, given as low = μ − σ and
// inverseWidth = 1 / (2σ) (σ = 0: a step, via a tiny floor on 2σ), the four terms multiplied.
float nd_visibleSlopes(vec4 slopes, vec4 low, vec4 inverseWidth) {
    vec4 t = clamp((slopes - low) * inverseWidth, 0.0, 1.0);
    return t.x * t.y * t.z * t.w;
}

// mean/deviation: horizon slopes (+X, -X, +Y, -Y); w: unit tangent-space direction.
float nd_visibility(vec3 w, vec4 mean, vec4 deviation) {
    return nd_visibleSlopes(nd_horizonSlopes(w), mean - deviation, 1.0 / max(2.0 * deviation, vec4(1e-12)));
}

float nd_specularGeometry(vec3 l, vec3 v) {
    return max(l.z, 0.0) / (4.0 * max(max(l.z, v.z), 0.1));
}
