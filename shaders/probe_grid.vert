#version 330 core
// The probe grid drawn as small spheres (voxview's probe view): instance i is probe i, at
// u_origin + u_spacing (x, y, z), x fastest, as the bake stores the grid.
uniform mat4 u_view_proj;
uniform vec3 u_origin;
uniform float u_spacing;
uniform ivec3 u_dims;
uniform float u_radius;
in vec3 in_position;   // the unit sphere's points (= its normals)
out vec3 v_normal;
flat out int v_probe;
void main() {
    int i = gl_InstanceID;
    ivec3 k = ivec3(i % u_dims.x, (i / u_dims.x) % u_dims.y, i / (u_dims.x * u_dims.y));
    v_normal = in_position;
    v_probe = i;
    gl_Position = u_view_proj * vec4(u_origin + u_spacing * vec3(k) + u_radius * in_position, 1.0);
}
