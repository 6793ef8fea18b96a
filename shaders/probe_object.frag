#version 330 core
// A moving object lit by the bake's irradiance probes, shaded from one irradiance map over its
// normals that the CPU made (viewer/objects.py), read bilinearly at the pixel's normal across a
// border that folds the octahedral map's edges as the octahedron joins them: for an object no larger than a
// probe cell its probes blended at its centre (baker/probes/sample.py: object_map); for a larger
// sphere the eight-probe sum of probes/sample.py's interpolate at each of the map's normals'
// points on it (sphere_map: a sphere's point is a function of its normal). The eight-probe sum
// per pixel cost llvmpipe 14 ms for a sphere a sixth of the screen across. L = albedo E / pi.
#ifndef TONEMAP
#define TONEMAP 1
#endif
#include "tone.glsl"
uniform sampler2D u_object_map;   // the object's irradiance map, (u_map_size + 2) squared RGB32F, bordered
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

vec3 object_irradiance(vec3 n) {
    // the map has a one-texel border across its folds (viewer/objects.py bordered): the GPU's bilinear
    // read is the octahedron's, one fetch where four with the folds worked out here cost llvmpipe more
    float size = float(u_map_size);
    return texture(u_object_map, (oct_uv(n) * size + 1.0) / (size + 2.0)).rgb;
}

void main() {
    vec3 E = max(object_irradiance(normalize(v_normal)), 0.0);
    vec3 L = u_albedo * E / PI;
#if TONEMAP
    f_color = vec4(tone(L, u_exposure), 1.0);
#else
    f_color = vec4(L, 1.0);
#endif
}
