#version 330 core
// One VPL's light at every pixel of the G-buffer, added to the accumulation buffer (docs/design.md
// section 7): power x V cos_l cos_p / (pi r^2 + A), the CPU's bounded near-field term; V from the
// VPL's cube of distances (six faces side by side in one texture).
uniform sampler2D u_position;
uniform sampler2D u_normal;
uniform sampler2D u_shadow;
uniform vec3 u_light;
uniform vec3 u_light_normal;
uniform vec3 u_power;
uniform float u_area;
uniform mat4 u_face[6];
uniform float u_bias;      // scene units, plus a fraction of the distance
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

void main() {
    vec4 p = texture(u_position, v_uv);
    if (p.w == 0.0) discard;
    vec3 n = texture(u_normal, v_uv).xyz;
    vec3 d = u_light - p.xyz;
    float r2 = dot(d, d);
    float r = sqrt(r2);
    vec3 w = d / r;
    float cp = dot(n, w);
    float cl = -dot(u_light_normal, w);
    if (cp <= COS_MIN || cl <= COS_MIN) discard;
    int f = face_of(-d);
    vec4 c = u_face[f] * vec4(p.xyz, 1.0);
    vec2 uv = clamp(c.xy / c.w * 0.5 + 0.5, 0.0, 1.0);
    float stored = texture(u_shadow, vec2((float(f) + uv.x) / 6.0, uv.y)).r;
    if (stored < r - u_bias - 0.01 * r) discard;
    f_color = vec4(u_power * (cl * cp / (PI * r2 + u_area)), 1.0);
}
