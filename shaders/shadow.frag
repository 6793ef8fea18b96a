#version 330 core
// Distances for shadows, both faces of every triangle (a caster seen from behind still casts):
// from the light's position (a cube face), or, for a direction (u_directional), how far the surface
// lies towards the light along it (an orthographic map: the largest value is the nearest caster).
uniform vec3 u_light;
uniform bool u_directional;
in vec3 v_world;
out float o_distance;
void main() {
    o_distance = u_directional ? dot(v_world, u_light) : length(v_world - u_light);
}
