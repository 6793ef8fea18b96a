#version 330 core
// One face of a VPL's cube of distances (90-degree frustum).
uniform mat4 u_view_proj;
in vec3 in_position;
out vec3 v_world;
void main() {
    v_world = in_position;
    gl_Position = u_view_proj * vec4(in_position, 1.0);
}
