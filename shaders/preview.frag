#version 330 core
// One light's irradiance at every pixel of the G-buffer, added to an accumulation buffer
// (docs/design.md section 7), the same formulas as the CPU:
//   KIND_AREA, a VPL:           power x V cos_l cos_p / (pi r^2 + A)  (the bounded near-field term)
//   KIND_DIRECTIONAL:           power x V cos_p                        (the sky's VPLs, a sun)
//   KIND_POINT:                 power x V cos_p / r^2                  (KIND_SPOT: times glTF's falloff)
// V: for points from the light's cube of distances (six faces side by side in one texture); for
// directions from one orthographic map of distances along the direction (face 0). The KIND_ codes are
// defined by the program's builder (viewer/context.py), from baker.scene.model.LightKind.
uniform sampler2D u_position;
uniform sampler2D u_normal;
uniform sampler2D u_shadow;
uniform int u_kind;
uniform vec3 u_light;        // position (KIND_DIRECTIONAL: unused)
uniform vec3 u_light_normal; // the VPL's normal; KIND_DIRECTIONAL: towards the light; KIND_SPOT: the axis
uniform vec3 u_power;
uniform float u_area;
uniform vec2 u_cones;        // spot: cos of the inner and outer cone
uniform mat4 u_face[6];
uniform float u_bias;        // scene units, plus a fraction of the distance
in vec2 v_uv;
out vec4 f_color;
const float PI = 3.14159265358979;
const float COS_MIN = 1e-6;

int face_of(vec3 d) {
    vec3 a = abs(d);
    if (a.x >= a.y && a.x >= a.z) return d.x >= 0.0 ? 0 : 1;
    if (a.y >= a.z) return d.y >= 0.0 ? 2 : 3;
    return d.z >= 0.0 ? 4 : 5;
}

float shadow_distance(int f, vec3 p) {
    vec4 c = u_face[f] * vec4(p, 1.0);
    vec2 uv = clamp(c.xy / c.w * 0.5 + 0.5, 0.0, 1.0);
    return texture(u_shadow, vec2((float(f) + uv.x) / 6.0, uv.y)).r;
}

void main() {
    vec4 p = texture(u_position, v_uv);
    if (p.w == 0.0) discard;
    vec3 n = texture(u_normal, v_uv).xyz;
    if (u_kind == KIND_DIRECTIONAL) {
        float cp = dot(n, u_light_normal);
        if (cp <= COS_MIN) discard;
        // the map stores each texel's nearest surface along the direction, measured towards the light
        float along = dot(p.xyz, u_light_normal);
        if (shadow_distance(0, p.xyz) > along + u_bias / max(cp, 0.1)) discard;
        f_color = vec4(u_power * cp, 1.0);
        return;
    }
    vec3 d = u_light - p.xyz;
    float r2 = dot(d, d);
    float r = sqrt(r2);
    vec3 w = d / r;
    float cp = dot(n, w);
    if (cp <= COS_MIN) discard;
    float g;
    if (u_kind == KIND_AREA) {
        float cl = -dot(u_light_normal, w);
        if (cl <= COS_MIN) discard;
        g = cl * cp / (PI * r2 + u_area);
    } else {
        g = cp / r2;
        if (u_kind == KIND_SPOT) {
            float a = clamp((-dot(w, u_light_normal) - u_cones.y) / max(u_cones.x - u_cones.y, 1e-4), 0.0, 1.0);
            g *= a * a;
        }
    }
    if (shadow_distance(face_of(-d), p.xyz) < r - u_bias - 0.01 * r) discard;
    f_color = vec4(u_power * g, 1.0);
}
