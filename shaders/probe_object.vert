#version 330 core
// A moving object (a sphere) lit by the bake's irradiance probes: world positions and normals.
uniform mat4 u_view_proj;
uniform vec3 u_center;
uniform float u_radius;
in vec3 in_position;   // the unit sphere's points (= its normals)
out vec3 v_world;
out vec3 v_normal;
void main() {
    v_normal = in_position;
    v_world = u_center + u_radius * in_position;
    gl_Position = u_view_proj * vec4(v_world, 1.0);
}
