#version 300 es
// splaTV's splat program, written out for splatconv: the same inputs, uniforms and
// arithmetic as the viewer's vertex shader, with the texture fetch split off into
// a function so a float reference path can feed unquantized attributes. The
// viewer's two inputs, `position` (the quad's corner) and `index` (the splat
// drawn), follow in splat_instanced.glsl (the page, as the viewer: one instance
// a splat) or splat_indexed.glsl (splatconv's renderer).
precision highp float;
precision highp int;

uniform mat4 projection, view;
uniform vec2 focal;
uniform vec2 viewport;
uniform float time;

out vec4 vColor;
out vec2 vPosition;

struct Splat {
    vec3 center;
    vec4 rot;
    vec3 scale;
    vec4 rgba;     // colour and opacity in [0, 1]
    vec3 vel;      // motion_0..2
    vec3 acc;      // motion_3..5
    vec3 jerk;     // motion_6..8
    vec4 omega;
    vec2 trbf;     // centre, linear scale
};
