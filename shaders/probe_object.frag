#version 330 core
// Irradiance from the probe grid at a point of a moving object (baker/probes/sample.py is the
// reference, term by term): the eight probes of the point's grid cell, each weighted by its
// trilinear weight, Chebyshev's bound against its
// distance moments toward the point (lifted BIAS spacings along the normal), cubed and 0 below
// CRUSH, and the object's mask (valid, and seen from the object's centre: the CPU's exact test);
// its irradiance map read bilinearly at the normal, the octahedral map's edges folded as the
// octahedron joins them. L = albedo E / pi; no probe counting gives 0.
// BLENDED 1: the object is shaded from one irradiance map over normals that the CPU made, read once
// per pixel at its normal: for an object no larger than a probe cell its probes blended at its
// centre (probes/sample.py: object_map); for a larger sphere the sum above at each of the map's
// normals' points on it (sphere_map: a sphere's point is a function of its normal). llvmpipe drew
// a sphere a sixth of the screen across in 14 ms the per-pixel way.
#ifndef TONEMAP
#define TONEMAP 1
#endif
#ifndef BLENDED
#define BLENDED 0
#endif
uniform sampler2D u_object_map;   // BLENDED: the object's irradiance map, u_map_size squared RGB32F
uniform int u_map_size;
uniform vec3 u_origin;       // the first probe
uniform float u_spacing;
uniform ivec3 u_dims;
uniform sampler2D u_irradiance;   // RGB32F, probe-major rows of IRR x IRR texels, packed WIDTH texels a row
uniform sampler2D u_depth;        // RG32F, DEPTH x DEPTH texels a probe, packed the same way
uniform int u_irr_size;
uniform int u_depth_size;
uniform usampler3D u_mask;        // R8UI over probes u_mask_lo .. + size: 1 where the probe counts
uniform ivec3 u_mask_lo;
uniform vec3 u_albedo;
uniform float u_exposure;
in vec3 v_world;
in vec3 v_normal;
out vec4 f_color;

const float PI = 3.14159265358979;
const float BIAS = 0.05;
const float CRUSH = 0.05;
const float MIN_VAR = 1e-4;
const int WIDTH = 4096;

vec2 oct_uv(vec3 d) {
    d /= abs(d.x) + abs(d.y) + abs(d.z);
    vec2 p = d.xy;
    if (d.z < 0.0) p = (1.0 - abs(p.yx)) * vec2(p.x >= 0.0 ? 1.0 : -1.0, p.y >= 0.0 ? 1.0 : -1.0);
    return 0.5 * (p + 1.0);
}

ivec2 wrap(int row, int col, int size) {
    bool out_r = row < 0 || row >= size, out_c = col < 0 || col >= size;
    int r = (out_c && !out_r) ? size - 1 - row : row;
    int c = (out_r && !out_c) ? size - 1 - col : col;
    if (out_r) r = row < 0 ? 0 : size - 1;
    if (out_c) c = col < 0 ? 0 : size - 1;
    if (out_r && out_c) { r = row < 0 ? size - 1 : 0; c = col < 0 ? size - 1 : 0; }
    return ivec2(r, c);
}

vec4 fetch(sampler2D tex, int probe, int size, ivec2 rc) {
    int i = (probe * size + rc.x) * size + rc.y;
    return texelFetch(tex, ivec2(i % WIDTH, i / WIDTH), 0);
}

vec3 irradiance_at(int probe, vec3 n) {
    int size = u_irr_size;
    vec2 xy = oct_uv(n) * float(size) - 0.5;
    vec2 f = xy - floor(xy);
    int c0 = int(floor(xy.x)), r0 = int(floor(xy.y));
    vec3 a = fetch(u_irradiance, probe, size, wrap(r0, c0, size)).rgb;
    vec3 b = fetch(u_irradiance, probe, size, wrap(r0, c0 + 1, size)).rgb;
    vec3 c = fetch(u_irradiance, probe, size, wrap(r0 + 1, c0, size)).rgb;
    vec3 d = fetch(u_irradiance, probe, size, wrap(r0 + 1, c0 + 1, size)).rgb;
    return mix(mix(a, b, f.x), mix(c, d, f.x), f.y);
}

vec3 object_irradiance(vec3 n) {
    int size = u_map_size;
    vec2 xy = oct_uv(n) * float(size) - 0.5;
    vec2 f = xy - floor(xy);
    int c0 = int(floor(xy.x)), r0 = int(floor(xy.y));
    ivec2 a = wrap(r0, c0, size), b = wrap(r0, c0 + 1, size), c = wrap(r0 + 1, c0, size), d = wrap(r0 + 1, c0 + 1, size);
    vec3 ta = texelFetch(u_object_map, a.yx, 0).rgb, tb = texelFetch(u_object_map, b.yx, 0).rgb;
    vec3 tc = texelFetch(u_object_map, c.yx, 0).rgb, td = texelFetch(u_object_map, d.yx, 0).rgb;
    return mix(mix(ta, tb, f.x), mix(tc, td, f.x), f.y);
}

vec3 grid_irradiance(vec3 world, vec3 n) {   // the eight probes around world, per pixel
    vec3 g = (world - u_origin) / u_spacing;
    ivec3 hi = max(u_dims - 2, ivec3(0));
    ivec3 base = clamp(ivec3(floor(g)), ivec3(0), hi);
    vec3 frac = clamp(g - vec3(base), 0.0, 1.0);
    frac = mix(vec3(0.0), frac, greaterThan(u_dims, ivec3(1)));
    vec3 lifted = world + BIAS * u_spacing * n;
    vec3 total = vec3(0.0);
    float weight = 0.0;
    for (int corner = 0; corner < 8; ++corner) {
        ivec3 off = ivec3(corner & 1, (corner >> 1) & 1, (corner >> 2) & 1);
        ivec3 idx = min(base + off, u_dims - 1);
        vec3 t = mix(1.0 - frac, frac, vec3(off));
        float w = t.x * t.y * t.z;
        ivec3 m = idx - u_mask_lo;
        ivec3 msize = textureSize(u_mask, 0);
        if (any(lessThan(m, ivec3(0))) || any(greaterThanEqual(m, msize)) || texelFetch(u_mask, m, 0).r == 0u)
            continue;
        int probe = idx.x + u_dims.x * (idx.y + u_dims.y * idx.z);
        vec3 p = u_origin + u_spacing * vec3(idx);
        vec3 v = lifted - p;
        float dv = length(v);
        vec2 uv = oct_uv(v / max(dv, 1e-12));
        int ds = u_depth_size;
        ivec2 rc = clamp(ivec2(int(uv.y * float(ds)), int(uv.x * float(ds))), ivec2(0), ivec2(ds - 1));
        vec2 mom = fetch(u_depth, probe, ds, rc).rg;
        float var = max(mom.y - mom.x * mom.x, MIN_VAR * u_spacing * u_spacing);
        float cheb = dv <= mom.x ? 1.0 : var / (var + (dv - mom.x) * (dv - mom.x));
        cheb = cheb * cheb * cheb;
        if (cheb < CRUSH) cheb = 0.0;
        w *= cheb;
        total += w * irradiance_at(probe, n);
        weight += w;
    }
    return weight > 0.0 ? max(total / weight, 0.0) : vec3(0.0);
}

void main() {
    vec3 n = normalize(v_normal);
#if BLENDED
    vec3 E = max(object_irradiance(n), 0.0);
#else
    vec3 E = grid_irradiance(v_world, n);
#endif
    vec3 L = u_albedo * E / PI;
#if TONEMAP
    vec3 x = L * u_exposure;
    x = clamp((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0);
    f_color = vec4(mix(12.92 * x, 1.055 * pow(x, vec3(1.0 / 2.4)) - 0.055, step(0.0031308, x)), 1.0);
#else
    f_color = vec4(L, 1.0);
#endif
}
