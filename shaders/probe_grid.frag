#version 330 core
// A probe of the probe view: the radiance a white diffuse sphere would reflect under the probe's
// order-2 SH (what the bake file gives other clients, probes/gather.py's basis and bands),
// E(n) / pi, clamped at 0; an invalid probe (inside a wall, outside a closed building) flat red.
#ifndef TONEMAP
#define TONEMAP 1
#endif
#include "tone.glsl"
uniform sampler2D u_sh;   // RGB32F: 10 texels a probe (its 9 coefficients, then (valid, 0, 0)), WIDTH a row
uniform float u_exposure;
in vec3 v_normal;
flat in int v_probe;
out vec4 f_color;

const float PI = 3.14159265358979;
const int WIDTH = 4096;

vec3 coef(int k) {
    int i = v_probe * 10 + k;
    return texelFetch(u_sh, ivec2(i % WIDTH, i / WIDTH), 0).rgb;
}

void main() {
    if (coef(9).r == 0.0) {
#if TONEMAP
        f_color = vec4(0.8, 0.05, 0.05, 1.0);
#else
        f_color = vec4(0.6, 0.0, 0.0, 1.0);
#endif
        return;
    }
    vec3 n = normalize(v_normal);
    float x = n.x, y = n.y, z = n.z;
    vec3 E = PI * 0.28209479177387814 * coef(0)
           + (2.0 * PI / 3.0) * 0.4886025119029199 * (y * coef(1) + z * coef(2) + x * coef(3))
           + (PI / 4.0) * (1.0925484305920792 * (x * y * coef(4) + y * z * coef(5) + x * z * coef(7))
                           + 0.31539156525252005 * (3.0 * z * z - 1.0) * coef(6)
                           + 0.5462742152960396 * (x * x - y * y) * coef(8));
    vec3 L = max(E, 0.0) / PI;
#if TONEMAP
    f_color = vec4(tone(L, u_exposure), 1.0);
#else
    f_color = vec4(L, 1.0);
#endif
}
