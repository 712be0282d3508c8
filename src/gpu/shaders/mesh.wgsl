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

// The surface the camera pass (raster.wgsl) found at pixel px, whose ray runs along d, with its normal turned towards
// the viewer (Mesh::intersect).
fn camera_surface(px: u32, d: vec3<f32>) -> Hit {
    var hit = visible(textureLoad(visibility_target, vec2<u32>(px % rp.width, px / rp.width), 0));
    if dot(hit.n, d) > 0.0 {
        hit.n = -hit.n;
    }
    return hit;
}

// The surface point a visibility texel (triangle, b1, b2, covered) records; found = false where nothing is.
fn visible(texel: vec4<f32>) -> Hit {
    if texel.w == 0.0 {
        return Hit(false, vec3<f32>(0.0), vec3<f32>(0.0, 0.0, 1.0), vec3<f32>(1.0, 0.0, 0.0), vec2<f32>(0.0));
    }
    return surface(u32(texel.x), vec3<f32>(1.0 - texel.y - texel.z, texel.y, texel.z));
}
