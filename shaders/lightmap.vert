#version 330 core
// The baked geometry: world positions (the bake file's are already in world space), texture
// coordinates (TEXCOORD_0) and lightmap coordinates (TEXCOORD_1).
uniform mat4 u_view_proj;
in vec3 in_position;
in vec2 in_uv0;
in vec2 in_uv1;
out vec2 v_uv0;
out vec2 v_uv1;
void main() {
    v_uv0 = in_uv0;
    v_uv1 = in_uv1;
    gl_Position = u_view_proj * vec4(in_position, 1.0);
}
