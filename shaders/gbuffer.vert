#version 330 core
// The preview's G-buffer: world position and the face normal of what each pixel sees.
uniform mat4 u_view_proj;
in vec3 in_position;
in vec2 in_uv0;
out vec3 v_world;
out vec2 v_uv0;
void main() {
    v_world = in_position;
    v_uv0 = in_uv0;
    gl_Position = u_view_proj * vec4(in_position, 1.0);
}
