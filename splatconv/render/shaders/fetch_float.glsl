// Float reference path: RGBA32F, 8 texels per splat, 512 splats per row, holding
// the attributes as float32 with no half or 8-bit quantization.
uniform highp sampler2D u_ftexture;

vec4 floatTexel(int i, int k) {
    return texelFetch(u_ftexture, ivec2(((i & 0x1ff) << 3) | k, i >> 9), 0);
}

Splat fetchSplat(int i) {
    vec4 t0 = floatTexel(i, 0), t1 = floatTexel(i, 1), t2 = floatTexel(i, 2), t3 = floatTexel(i, 3),
         t4 = floatTexel(i, 4), t5 = floatTexel(i, 5), t6 = floatTexel(i, 6), t7 = floatTexel(i, 7);
    Splat s;
    s.center = t0.xyz;
    s.trbf = vec2(t0.w, t2.w);
    s.rot = t1;
    s.scale = t2.xyz;
    s.rgba = t3;
    s.vel = t4.xyz;
    s.acc = vec3(t4.w, t5.xy);
    s.jerk = vec3(t5.zw, t6.x);
    s.omega = vec4(t6.yzw, t7.x);
    return s;
}
