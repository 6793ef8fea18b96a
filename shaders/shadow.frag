#version 330 core
// The distance from the VPL to the nearest surface, both faces of every triangle (a shadow caster
// seen from behind still casts).
uniform vec3 u_light;
in vec3 v_world;
out float o_distance;
void main() {
    o_distance = length(v_world - u_light);
}
