#version 330 core
// Walkthrough shading of a bake (docs/design.md section 9):
//   L = albedo * H / pi + L_e,
// H the lightmap irradiance (bilinear, or bicubic B-spline), then tone.glsl's display transform;
// or linear radiance for snapshots.
// Debug views: 1 lightmap only (H / pi), 2 albedo only, 3 texel-density checker, 4 pages.
// MODE, BICUBIC, TONEMAP, TEXTURED, GLASS (the glass pass) and EMIT_TEXTURE are compile-time constants
// (the renderer builds one program per combination it uses): no branch on them is left for the fragment
// loop (llvmpipe runs both sides of a uniform branch, on every pixel).
#ifndef MODE
#define MODE 0
#endif
#ifndef BICUBIC
#define BICUBIC 0
#endif
#ifndef TONEMAP
#define TONEMAP 1
#endif
#ifndef TEXTURED
#define TEXTURED 0
#endif
#ifndef GLASS
#define GLASS 0
#endif
#ifndef EMIT_TEXTURE
#define EMIT_TEXTURE 0
#endif
#include "tone.glsl"

uniform vec3 u_albedo;
uniform vec3 u_emission;
uniform float u_alpha;      // the base colour's alpha (an alpha-masked material's texture alpha times it)
uniform float u_cutoff;     // alpha below it is cut out (-1: not masked)
uniform vec3 u_glass;       // thin glass seen through (GLASS): its tint, multiplied into what lies behind
uniform sampler2D u_texture;
uniform sampler2D u_emit_texture;   // the emissive texture (EMIT_TEXTURE), times u_emission
uniform sampler2DArray u_pages;
uniform int u_page;
uniform float u_exposure;   // linear scale (TONEMAP 0: linear radiance out, for snapshots)
in vec2 v_uv0;
in vec2 v_uv1;
out vec4 f_color;

const float PI = 3.14159265358979;

vec4 cubic(float v) {  // uniform cubic B-spline weights
    vec4 n = vec4(1.0, 2.0, 3.0, 4.0) - v;
    vec4 s = n * n * n;
    float x = s.x;
    float y = s.y - 4.0 * s.x;
    float z = s.z - 4.0 * s.y + 6.0 * s.x;
    float w = 6.0 - x - y - z;
    return vec4(x, y, z, w) / 6.0;
}

vec3 bicubic(vec2 uv) {  // 4 bilinear taps (Sigg & Hadwiger 2005)
    vec2 size = vec2(textureSize(u_pages, 0).xy);
    vec2 t = uv * size - 0.5;
    vec2 f = fract(t);
    t -= f;
    vec4 xc = cubic(f.x), yc = cubic(f.y);
    vec4 c = t.xxyy + vec2(-0.5, 1.5).xyxy;
    vec4 s = vec4(xc.xz + xc.yw, yc.xz + yc.yw);
    vec4 o = (c + vec4(xc.yw, yc.yw) / s) / size.xxyy;
    vec3 s0 = texture(u_pages, vec3(o.xz, u_page)).rgb, s1 = texture(u_pages, vec3(o.yz, u_page)).rgb;
    vec3 s2 = texture(u_pages, vec3(o.xw, u_page)).rgb, s3 = texture(u_pages, vec3(o.yw, u_page)).rgb;
    float sx = s.x / (s.x + s.y), sy = s.z / (s.z + s.w);
    return mix(mix(s3, s2, sx), mix(s1, s0, sx), sy);
}

void main() {
#if GLASS  // drawn last, blended as dst * src (the renderer's glass pass)
#if TONEMAP
    f_color = vec4(pow(u_glass, vec3(1.0 / 2.2)), 1.0);  // near the sRGB curve's slope on what it filters
#else
    f_color = vec4(u_glass, 1.0);
#endif
#else
#if BICUBIC
    vec3 H = bicubic(v_uv1);
#else
    vec3 H = texture(u_pages, vec3(v_uv1, u_page)).rgb;
#endif
    H = max(H, 0.0);
    vec3 albedo = u_albedo;
#if TEXTURED
    vec4 tex = texture(u_texture, v_uv0);
    if (u_alpha * tex.a < u_cutoff) discard;
    albedo *= tex.rgb;
#endif
#if MODE == 1
    vec3 L = H / PI;
#elif MODE == 2
    vec3 L = albedo;
#elif MODE == 3
    ivec2 texel = ivec2(floor(v_uv1 * vec2(textureSize(u_pages, 0).xy)));
    float check = ((texel.x + texel.y) & 1) == 0 ? 1.0 : 0.55;
    vec3 L = vec3(check) * (0.25 + H / PI);
#elif MODE == 4
    vec3 hue = 0.5 + 0.5 * cos(6.2831853 * (float(u_page) * 0.618034 + vec3(0.0, 0.33, 0.67)));
    vec2 cell = fract(v_uv1 * vec2(textureSize(u_pages, 0).xy) / 8.0);
    float line = (min(cell.x, cell.y) < 0.06) ? 0.3 : 1.0;  // the quadtree's 8-texel grid
    vec3 L = hue * line * (0.25 + H / PI);
#else
    vec3 emission = u_emission;
#if EMIT_TEXTURE
    emission *= texture(u_emit_texture, v_uv0).rgb;
#endif
    vec3 L = albedo * H / PI + emission;
#endif
#if TONEMAP
    f_color = vec4(tone(L, u_exposure), 1.0);
#else
    f_color = vec4(L, 1.0);
#endif
#endif
}
