#version 330 core
// A dynamic mesh of the bake (voxbake bake --dynamic NODE) moved by u_offset, its vertices' irradiance
// from the probes made on the CPU when it moves (viewer/objects.py DynamicMeshes).
uniform mat4 u_view_proj;
uniform vec3 u_offset;
in vec3 in_position;     // world position where the mesh was baked
in vec2 in_uv;
in vec3 in_irradiance;   // W/m^2 at the vertex and its normal, where the mesh stands now
out vec2 v_uv;
out vec3 v_irradiance;
void main() {
    v_uv = in_uv;
    v_irradiance = in_irradiance;
    gl_Position = u_view_proj * vec4(in_position + u_offset, 1.0);
}
