#version 330 core
// Position (w = 1 where a surface is), flat normal from the derivatives (the bake's triangles are
// one-sided and culled from behind: it faces the camera), albedo, emission.
uniform vec3 u_albedo;
uniform vec3 u_emission;
uniform bool u_has_texture;
uniform sampler2D u_texture;
uniform bool u_has_emit_texture;
uniform sampler2D u_emit_texture;
in vec3 v_world;
in vec2 v_uv0;
layout(location = 0) out vec4 o_position;
layout(location = 1) out vec4 o_normal;
layout(location = 2) out vec4 o_albedo;
layout(location = 3) out vec4 o_emission;
void main() {
    vec3 n = normalize(cross(dFdx(v_world), dFdy(v_world)));
    vec3 albedo = u_albedo;
    if (u_has_texture) albedo *= texture(u_texture, v_uv0).rgb;
    o_position = vec4(v_world, 1.0);
    o_normal = vec4(n, 0.0);
    o_albedo = vec4(albedo, 1.0);
    vec3 emission = u_emission;
    if (u_has_emit_texture) emission *= texture(u_emit_texture, v_uv0).rgb;
    o_emission = vec4(emission, 1.0);
}
