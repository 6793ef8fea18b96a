// The display transform every tone-mapped view shares: exposure, the ACES filmic curve (Narkowicz
// 2015), then the sRGB transfer curve. Its power 1/2.4 is taken as a sum of three nested square
// roots, within 0.25 of an 8-bit level of the exact curve (tests/test_viewer.py): pow() on every
// channel of every pixel is one of the dearest things llvmpipe does, a square root one of the cheapest.
vec3 aces(vec3 x) {
    return clamp((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0);
}

vec3 to_srgb(vec3 x) {
    x = clamp(x, 0.0, 1.0);
    vec3 s1 = sqrt(x), s2 = sqrt(s1), s3 = sqrt(s2);
    vec3 curve = 0.662002687 * s1 + 0.684122060 * s2 - 0.323583601 * s3 - 0.0225411470 * x;
    return mix(12.92 * x, curve, step(0.0031308, x));
}

vec3 tone(vec3 L, float exposure) {
    return to_srgb(aces(L * exposure));
}
