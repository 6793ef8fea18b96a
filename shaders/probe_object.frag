#version 330 core
// A moving object lit by the bake's irradiance probes, shaded from one irradiance map over its
// normals that the CPU made (viewer/objects.py), read bilinearly at the pixel's normal, the
// octahedral map's edges folded as the octahedron joins them: for an object no larger than a
// probe cell its probes blended at its centre (baker/probes/sample.py: object_map); for a larger
// sphere the eight-probe sum of probes/sample.py's interpolate at each of the map's normals'
// points on it (sphere_map: a sphere's point is a function of its normal). The eight-probe sum
// per pixel cost llvmpipe 14 ms for a sphere a sixth of the screen across. L = albedo E / pi.
#ifndef TONEMAP
#define TONEMAP 1
#endif
uniform sampler2D u_object_map;   // the object's irradiance map, u_map_size squared RGB32F
uniform int u_map_size;
uniform vec3 u_albedo;
uniform float u_exposure;
in vec3 v_world;
in vec3 v_normal;
out vec4 f_color;

const float PI = 3.14159265358979;
// the maps' frame (baker/probes/gather.py MAP_FRAME, by columns): a turn that keeps the scene's axes off the map's corners
const mat3 MAP_FRAME = mat3(vec3(0.3826834323650898, 0.9238795325112867, 0.0),
                            vec3(-0.9238795325112867, 0.3826834323650898, 0.0), vec3(0.0, 0.0, 1.0));

vec2 oct_uv(vec3 d) {
    d = MAP_FRAME * d;
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

void main() {
    vec3 E = max(object_irradiance(normalize(v_normal)), 0.0);
    vec3 L = u_albedo * E / PI;
#if TONEMAP
    vec3 x = L * u_exposure;
    x = clamp((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0);
    f_color = vec4(mix(12.92 * x, 1.055 * pow(x, vec3(1.0 / 2.4)) - 0.055, step(0.0031308, x)), 1.0);
#else
    f_color = vec4(L, 1.0);
#endif
}
