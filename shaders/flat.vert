#version 330 core
// Position-only pass: world position through the view-projection matrix.
uniform mat4 u_view_proj;
in vec3 in_position;
in vec3 in_color;
out vec3 v_color;
void main() {
    v_color = in_color;
    gl_Position = u_view_proj * vec4(in_position, 1.0);
}
