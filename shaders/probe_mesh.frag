#version 330 core
// A dynamic mesh lit by the bake's probes: L = emission + albedo E / pi, E interpolated between the
// vertices' (baker/probes/sample.py points_irradiance at each vertex and its normal); the albedo
// factor times the base colour texture where the material has one; alpha-masked texels cut out.
#ifndef TONEMAP
#define TONEMAP 1
#endif
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
    vec3 x = L * u_exposure;
    x = clamp((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0);
    f_color = vec4(mix(12.92 * x, 1.055 * pow(x, vec3(1.0 / 2.4)) - 0.055, step(0.0031308, x)), 1.0);
#else
    f_color = vec4(L, 1.0);
#endif
}
