#version 330 core
// A dynamic mesh lit by the bake's probes: L = emission + albedo E / pi, E interpolated between the
// vertices' (baker/probes/sample.py points_irradiance at each vertex and its normal); the albedo
// factor times the base colour texture where the material has one; alpha-masked texels cut out.
#ifndef TONEMAP
#define TONEMAP 1
#endif
#include "tone.glsl"
#ifndef TEXTURED
#define TEXTURED 0
#endif
uniform vec3 u_albedo;
uniform vec3 u_emission;
uniform float u_alpha;
uniform float u_cutoff;   // < 0: not masked
uniform float u_exposure;
#if TEXTURED
uniform sampler2D u_texture;   // RGBA: linear albedo, the mask's alpha
#endif
in vec2 v_uv;
in vec3 v_irradiance;
out vec4 f_color;

const float PI = 3.14159265358979;

void main() {
    vec3 albedo = u_albedo;
    float alpha = u_alpha;
#if TEXTURED
    vec4 t = texture(u_texture, v_uv);
    albedo *= t.rgb;
    alpha *= t.a;
#endif
    if (u_cutoff >= 0.0 && alpha < u_cutoff) discard;
    vec3 L = u_emission + albedo * max(v_irradiance, 0.0) / PI;
#if TONEMAP
    f_color = vec4(tone(L, u_exposure), 1.0);
#else
    f_color = vec4(L, 1.0);
#endif
}
