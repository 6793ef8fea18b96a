#version 330 core
// The uniform sky the bake was lit by (baker.scene.Sky), where no surface is drawn: its radiance
// from every direction, or from those above the horizon (hemisphere), through the same exposure and
// tone curve as lightmap.frag; linear radiance for snapshots (TONEMAP 0).
#ifndef TONEMAP
#define TONEMAP 1
#endif
uniform mat4 u_inv_view_proj;
uniform vec3 u_sky;
uniform vec3 u_up;
uniform bool u_hemisphere;
uniform float u_exposure;
in vec2 v_ndc;
out vec4 f_color;
#include "tone.glsl"
void main() {
    vec4 a = u_inv_view_proj * vec4(v_ndc, -1.0, 1.0);
    vec4 b = u_inv_view_proj * vec4(v_ndc, 1.0, 1.0);
    vec3 dir = b.xyz / b.w - a.xyz / a.w;
    vec3 L = (u_hemisphere && dot(dir, u_up) <= 0.0) ? vec3(0.0) : u_sky;
#if TONEMAP
    f_color = vec4(tone(L, u_exposure), 1.0);
#else
    f_color = vec4(L, 1.0);
#endif
}
