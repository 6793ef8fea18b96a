#version 330 core
// The preview's running mean on screen: emission + albedo / pi x (punctual + accumulated VPL light / draws),
// then tone.glsl's display transform (as the lightmap view).
uniform sampler2D u_accum;
uniform sampler2D u_albedo;
uniform sampler2D u_emission;
uniform sampler2D u_punctual;   // the punctual lights' irradiance, added once
uniform float u_draws;
uniform float u_exposure;
in vec2 v_uv;
out vec4 f_color;
const float PI = 3.14159265358979;
#include "tone.glsl"
void main() {
    vec3 L = texture(u_emission, v_uv).rgb + texture(u_albedo, v_uv).rgb / PI *
             (texture(u_punctual, v_uv).rgb + texture(u_accum, v_uv).rgb / max(u_draws, 1.0));
    f_color = vec4(tone(L, u_exposure), 1.0);
}
