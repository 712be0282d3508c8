// A triangle mesh on the GPU, mirroring render/mesh.rs: per-vertex rows (position, normal, uv, tangent: 11 floats)
// and triangles (3 vertex indices). `surface` is Mesh::surface; raster.wgsl rasterizes the mesh into visibility
// targets (triangle, barycentrics) that the kernels read back with it. Composed after optics.wgsl and scene.wgsl.

@group(2) @binding(0) var<storage, read> vertices: array<f32>;
@group(2) @binding(1) var<storage, read> triangles: array<u32>;
// The visibility target of a pass in uv space or through the camera (raster.wgsl), for the kernels.
@group(2) @binding(2) var visibility_target: texture_2d<f32>;

const VERTEX: u32 = 11u;

fn vertex_vec3(v: u32, at: u32) -> vec3<f32> {
    let k = VERTEX * v + at;
    return vec3<f32>(vertices[k], vertices[k + 1u], vertices[k + 2u]);
}

fn vertex_uv(v: u32) -> vec2<f32> {
    return vec2<f32>(vertices[VERTEX * v + 6u], vertices[VERTEX * v + 7u]);
}

// Mesh::surface: triangle k's point at barycentrics b, with its normal, tangent (Gram–Schmidt against the normal;
// ŷ × n where the tangents vanish) and uv, interpolated.
fn surface(k: u32, b: vec3<f32>) -> Hit {
    let v = vec3<u32>(triangles[3u * k], triangles[3u * k + 1u], triangles[3u * k + 2u]);
    let p = b.x * vertex_vec3(v.x, 0u) + b.y * vertex_vec3(v.y, 0u) + b.z * vertex_vec3(v.z, 0u);
    let n = normalize(b.x * vertex_vec3(v.x, 3u) + b.y * vertex_vec3(v.y, 3u) + b.z * vertex_vec3(v.z, 3u));
    let t0 = b.x * vertex_vec3(v.x, 8u) + b.y * vertex_vec3(v.y, 8u) + b.z * vertex_vec3(v.z, 8u);
    var t = t0 - dot(t0, n) * n;
    if dot(t, t) > 1e-20 {
        t = normalize(t);
    } else {
        t = cross(vec3<f32>(0.0, 1.0, 0.0), n);
        t = select(orthonormal_basis(n)[0], normalize(t), dot(t, t) > 1e-20);
    }
    let uv = b.x * vertex_uv(v.x) + b.y * vertex_uv(v.y) + b.z * vertex_uv(v.z);
    return Hit(true, p, n, t, uv);
}

// The surface the camera pass (raster.wgsl) found at pixel px, whose ray runs from o along d, with its normal turned
// towards the viewer (Mesh::intersect). The pass gives the triangle; its barycentrics come from the ray, as on the
// CPU: a rasterizer's interpolated ones are only as precise as its hardware (NVIDIA's: 1e-3 off in shading).
fn camera_surface(px: u32, o: vec3<f32>, d: vec3<f32>) -> Hit {
    var texel = textureLoad(visibility_target, vec2<u32>(px % rp.width, px / rp.width), 0);
    if texel.w != 0.0 {
        let k = u32(texel.x);
        let v = vec3<u32>(triangles[3u * k], triangles[3u * k + 1u], triangles[3u * k + 2u]);
        let b = ray_triangle(o, d, vertex_vec3(v.x, 0u), vertex_vec3(v.y, 0u), vertex_vec3(v.z, 0u));
        texel = select(texel, vec4<f32>(texel.x, b.x, b.y, 1.0), b.z > 0.0);
    }
    var hit = visible(texel);
    if dot(hit.n, d) > 0.0 {
        hit.n = -hit.n;
    }
    return hit;
}

// Mesh::ray_triangle (Möller and Trumbore 1997) for a triangle the ray is known to hit: (b1, b2, 1), clamped into
// the triangle (the pixel centre may lie a rounding error outside it), or z = 0 where the ray runs in its plane.
fn ray_triangle(o: vec3<f32>, d: vec3<f32>, p0: vec3<f32>, p1: vec3<f32>, p2: vec3<f32>) -> vec3<f32> {
    let e1 = p1 - p0;
    let e2 = p2 - p0;
    let q = cross(d, e2);
    let det = dot(e1, q);
    if abs(det) < 1e-14 {
        return vec3<f32>(0.0);
    }
    let r = o - p0;
    var b = clamp(vec2<f32>(dot(r, q), dot(d, cross(r, e1))) / det, vec2<f32>(0.0), vec2<f32>(1.0));
    b = b / max(1.0, b.x + b.y);
    return vec3<f32>(b, 1.0);
}

// The surface point a visibility texel (triangle, b1, b2, covered) records; found = false where nothing is.
fn visible(texel: vec4<f32>) -> Hit {
    if texel.w == 0.0 {
        return Hit(false, vec3<f32>(0.0), vec3<f32>(0.0, 0.0, 1.0), vec3<f32>(1.0, 0.0, 0.0), vec2<f32>(0.0));
    }
    return surface(u32(texel.x), vec3<f32>(1.0 - texel.y - texel.z, texel.y, texel.z));
}
