// The .splatv texture: RGBA32UI, 4 texels per splat, 1024 splats per row.
uniform highp usampler2D u_texture;

uvec4 splatTexel(int i, uint k) {
    return texelFetch(u_texture, ivec2(((uint(i) & 0x3ffu) << 2) | k, uint(i) >> 10), 0);
}

Splat fetchSplat(int i) {
    uvec4 t0 = splatTexel(i, 0u), t1 = splatTexel(i, 1u), t2 = splatTexel(i, 2u), t3 = splatTexel(i, 3u);
    Splat s;
    s.center = uintBitsToFloat(t0.xyz);
    s.rot = vec4(unpackHalf2x16(t0.w).xy, unpackHalf2x16(t1.x).xy);
    s.scale = vec3(unpackHalf2x16(t1.y).xy, unpackHalf2x16(t1.z).x);
    uint c = t1.w;
    s.rgba = vec4(c & 0xffu, (c >> 8) & 0xffu, (c >> 16) & 0xffu, (c >> 24) & 0xffu) / 255.0;
    vec2 a = unpackHalf2x16(t2.x), b = unpackHalf2x16(t2.y), d = unpackHalf2x16(t2.z),
         e = unpackHalf2x16(t2.w), f = unpackHalf2x16(t3.x);
    s.vel = vec3(a.xy, b.x);
    s.acc = vec3(b.y, d.xy);
    s.jerk = vec3(e.xy, f.x);
    s.omega = vec4(unpackHalf2x16(t3.y).xy, unpackHalf2x16(t3.z).xy);
    s.trbf = unpackHalf2x16(t3.w);
    return s;
}
