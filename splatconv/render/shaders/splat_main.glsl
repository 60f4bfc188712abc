void main() {
    // Culled splats leave the quad outside the clip volume.
    gl_Position = vec4(0.0, 0.0, 2.0, 1.0);

    Splat s = fetchSplat(index);
    float dt = time - s.trbf.x;
    float topacity = exp(-1.0 * pow(dt / s.trbf.y, 2.0));
    if (topacity < 0.02) return;

    vec3 tpos = s.vel * dt + s.acc * dt * dt + s.jerk * dt * dt * dt;
    vec4 cam = view * vec4(s.center + tpos, 1);
    vec4 pos = projection * cam;

    float clip = 1.2 * pos.w;
    if (pos.z < -clip || pos.x < -clip || pos.x > clip || pos.y < -clip || pos.y > clip) return;

    vec4 rot = s.rot + s.omega * dt;
    rot /= sqrt(dot(rot, rot));

    mat3 S = mat3(s.scale.x, 0.0, 0.0, 0.0, s.scale.y, 0.0, 0.0, 0.0, s.scale.z);
    mat3 R = mat3(
        1.0 - 2.0 * (rot.z * rot.z + rot.w * rot.w), 2.0 * (rot.y * rot.z - rot.x * rot.w),
        2.0 * (rot.y * rot.w + rot.x * rot.z),
        2.0 * (rot.y * rot.z + rot.x * rot.w), 1.0 - 2.0 * (rot.y * rot.y + rot.w * rot.w),
        2.0 * (rot.z * rot.w - rot.x * rot.y),
        2.0 * (rot.y * rot.w - rot.x * rot.z), 2.0 * (rot.z * rot.w + rot.x * rot.y),
        1.0 - 2.0 * (rot.y * rot.y + rot.z * rot.z));
    mat3 M = S * R;
    mat3 Vrk = 4.0 * transpose(M) * M;
    mat3 J = mat3(
        focal.x / cam.z, 0., -(focal.x * cam.x) / (cam.z * cam.z),
        0., -focal.y / cam.z, (focal.y * cam.y) / (cam.z * cam.z),
        0., 0., 0.);
    mat3 T = transpose(mat3(view)) * J;
    mat3 cov2d = transpose(T) * Vrk * T;

    float mid = (cov2d[0][0] + cov2d[1][1]) / 2.0;
    float radius = length(vec2((cov2d[0][0] - cov2d[1][1]) / 2.0, cov2d[0][1]));
    float lambda1 = mid + radius, lambda2 = mid - radius;
    if (lambda2 < 0.0) return;
    vec2 diagonalVector = normalize(vec2(cov2d[0][1], lambda1 - cov2d[0][0]));
    vec2 majorAxis = min(sqrt(2.0 * lambda1), 1024.0) * diagonalVector;
    vec2 minorAxis = min(sqrt(2.0 * lambda2), 1024.0) * vec2(diagonalVector.y, -diagonalVector.x);

    vColor = clamp(pos.z / pos.w + 1.0, 0.0, 1.0) * vec4(1.0, 1.0, 1.0, topacity) * s.rgba;

    vec2 vCenter = vec2(pos) / pos.w;
    gl_Position = vec4(vCenter + position.x * majorAxis / viewport + position.y * minorAxis / viewport,
                       0.0, 1.0);
    vPosition = position;
}
