// splatconv's renderer draws without instancing, the same inputs worked out from
// gl_VertexID: Mesa's llvmpipe runs every instance as a draw of its own, which
// cost a third of a frame of 1M splats. Vertex 4k + c is corner c of the k-th
// splat drawn from u_first on; an element buffer gives each splat the triangles
// (0, 1, 2) and (0, 2, 3), the viewer's triangle fan. u_order is the draw order,
// 4096 splat indices a row.
uniform highp isampler2D u_order;
uniform int u_first;

const vec2 CORNERS[4] = vec2[4](vec2(-2.0, -2.0), vec2(2.0, -2.0), vec2(2.0, 2.0), vec2(-2.0, 2.0));

#define DRAWN ((gl_VertexID >> 2) + u_first)
#define index (texelFetch(u_order, ivec2(DRAWN & 4095, DRAWN >> 12), 0).x)
#define position (CORNERS[gl_VertexID & 3])
