#version 330 core
// The overlay's text image (RGBA, drawn by Pillow), blended over the frame.
uniform sampler2D u_text;
in vec2 v_uv;
out vec4 f_color;
void main() {
    f_color = texture(u_text, v_uv);
}
