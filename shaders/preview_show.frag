#version 330 core
// The preview's running mean on screen: emission + albedo / pi x (punctual + accumulated VPL light / draws),
// then exposure, ACES filmic, sRGB (as the lightmap view).
uniform sampler2D u_accum;
uniform sampler2D u_albedo;
uniform sampler2D u_emission;
uniform sampler2D u_punctual;   // the punctual lights' irradiance, added once
uniform float u_draws;
uniform float u_exposure;
in vec2 v_uv;
out vec4 f_color;
const float PI = 3.14159265358979;
vec3 aces(vec3 x) { return clamp((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0); }
vec3 to_srgb(vec3 x) {
    x = clamp(x, 0.0, 1.0);
    return mix(12.92 * x, 1.055 * pow(x, vec3(1.0 / 2.4)) - 0.055, step(0.0031308, x));
}
void main() {
    vec3 L = texture(u_emission, v_uv).rgb + texture(u_albedo, v_uv).rgb / PI *
             (texture(u_punctual, v_uv).rgb + texture(u_accum, v_uv).rgb / max(u_draws, 1.0));
    f_color = vec4(to_srgb(aces(L * u_exposure)), 1.0);
}
