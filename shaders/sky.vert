#version 330 core
// The sky behind everything: one triangle over the whole viewport, at the far plane; the
// fragment shader turns each pixel back into its view direction.
out vec2 v_ndc;
void main() {
    vec2 p = vec2(float((gl_VertexID & 1) << 2) - 1.0, float((gl_VertexID & 2) << 1) - 1.0);
    v_ndc = p;
    gl_Position = vec4(p, 1.0, 1.0);
}
